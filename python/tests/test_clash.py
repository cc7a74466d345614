"""Clash, clash tests and collide from Python against brute force (python/run_tests.sh runs these)."""
import json
import sys
import threading

import numpy as np
import pytest

import mktree

from test_mktree import random_boxes

HARD, TOUCH = 0, 1


def brute_pairs(boxes, pick=lambda i, j: True):
    """Pairs (a, b, class) of axis-aligned cubes whose coordinates are multiples of 1/8: overlapping in
    volume is hard (depth >= 1/8 > 2 mm), meeting with zero overlap on an axis is a touch."""
    lo, hi = boxes[:, 0], boxes[:, 1]
    out = set()
    for i in range(len(boxes)):
        overlap = np.minimum(hi[i], hi[i + 1:]) - np.maximum(lo[i], lo[i + 1:])
        meet = (overlap >= 0).all(axis=1)
        for k in np.nonzero(meet)[0]:
            j = i + 1 + int(k)
            if pick(i, j):
                out.add((i, j, HARD if (overlap[k] > 0).all() else TOUCH))
    return out


@pytest.fixture(scope="module")
def cubes(tmp_path_factory):
    objects, boxes = random_boxes(2000, 5)
    for i, o in enumerate(objects):
        o["source"] = "models/a.ifc" if i % 2 else "models/b.ifc"
        o["attributes"] = {"ifc_global_id": f"G{i}", "zone": "north" if boxes[i, 0, 0] < 50 else "south"}
    path = tmp_path_factory.mktemp("clash") / "cubes.mkt"
    mktree.build(path, objects=objects, backend="pagefile", block_size=1024, blocks_per_page=1)
    return path, objects, boxes


def as_set(r):
    return set(zip(r["a"].tolist(), r["b"].tolist(), r["cls"].tolist()))


def test_self_clash_against_brute_force(cubes):
    path, _, boxes = cubes
    db = mktree.open(path)
    r = db.clash(threads=2)
    assert r["a"].dtype == np.uint32 and r["cls"].dtype == np.uint8
    assert r["point_a"].shape == (len(r["a"]), 3)
    want = brute_pairs(boxes)
    assert len(want) > 100
    assert as_set(r) == want
    assert r["stats"]["hard"] + r["stats"]["touch"] == len(want)
    # Touches counted, not reported.
    hard_only = db.clash(report_touch=False)
    assert as_set(hard_only) == {p for p in want if p[2] == HARD}


def test_clash_tests_against_brute_force(cubes, tmp_path):
    path, objects, boxes = cubes
    db = mktree.open(path)
    tests = {"tests": [
        {"name": "north-vs-b", "a": {"zone": ["north"]}, "b": {"source": ["*b.ifc"]}},
        {"name": "all", "a": {}, "group": {"proximity": 5.0}},
    ]}
    r = db.clash(tests=tests)
    zone = [o["attributes"]["zone"] for o in objects]
    src = [o["source"] for o in objects]

    def north_vs_b(i, j):
        return (zone[i] == "north" and src[j].endswith("b.ifc")) or (zone[j] == "north" and src[i].endswith("b.ifc"))

    got = {}
    for a, b, c, test in zip(r["a"].tolist(), r["b"].tolist(), r["cls"].tolist(), r["test"]):
        got.setdefault(test, set()).add((a, b, c))
    assert got["north-vs-b"] == brute_pairs(boxes, north_vs_b)
    assert got["all"] == brute_pairs(boxes)
    assert len(set(zip(r["test"], r["key"]))) == len(r["key"])  # one key per clash and test
    assert all(s == "" for s in r["status"])
    names = [t["name"] for t in r["tests"]]
    assert names == ["north-vs-b", "all"]
    assert sum(g["members"] for g in r["groups"]) == len(r["a"])
    assert {g["key"] for g in r["groups"]} == set(r["group"])
    # The same tests from a file; then compared with a previous run written as the command line does.
    test_file = tmp_path / "tests.json"
    test_file.write_text(json.dumps(tests))
    again = db.clash(tests=test_file)
    assert sorted(zip(again["test"], again["key"])) == sorted(zip(r["test"], r["key"]))
    lines = [json.dumps({"test": t["name"], "summary": True, "fingerprint": t["fingerprint"],
                         "selected_a": t["selected_a"], "selected_b": t["selected_b"],
                         "sources": ["models/a.ifc", "models/b.ifc"]}) for t in r["tests"]]
    lines += [json.dumps({"test": t, "key": k, "group": g}) for t, k, g in zip(r["test"], r["key"], r["group"])][1:]
    previous = tmp_path / "previous.jsonl"
    previous.write_text("\n".join(lines) + "\n")
    compared = db.clash(tests=tests, previous=previous)
    assert sorted(compared["status"]).count("new") == 1
    assert compared["status"].count("active") == len(r["key"]) - 1
    with pytest.raises(mktree.Error, match="not comparable"):
        db.clash(tests={"tests": [{"name": "other", "a": {}}]}, previous=previous)
    with pytest.raises(mktree.Error, match=r"<tests dict>:1: unknown key \"colour\""):
        db.clash(tests={"tests": [{"name": "x", "a": {}, "colour": 1}]})


def test_collide_against_brute_force(cubes):
    path, _, boxes = cubes
    db = mktree.open(path)
    corners = np.array([[(c >> a) & 1 for a in range(3)] for c in range(8)], dtype=np.float64)
    faces = np.array([[0, 2, 3], [0, 3, 1], [4, 5, 7], [4, 7, 6], [0, 1, 5], [0, 5, 4],
                      [2, 6, 7], [2, 7, 3], [0, 4, 6], [0, 6, 2], [1, 3, 7], [1, 7, 5]])
    vertices = corners * 30.0  # a 30 m cube at the origin, moved by the transform
    transform = np.eye(4)
    transform[:3, 3] = [30.125, 30.25, 30.5]
    r = db.collide(vertices, faces, transform)
    lo, hi = np.array([30.125, 30.25, 30.5]), np.array([60.125, 60.25, 60.5])
    overlap = np.minimum(hi, boxes[:, 1]) - np.maximum(lo, boxes[:, 0])
    want = {(i, HARD if (overlap[i] > 0).all() else TOUCH) for i in np.nonzero((overlap >= 0).all(axis=1))[0].tolist()}
    assert len(want) > 3
    assert set(zip(r["a"].tolist(), r["cls"].tolist())) == want
    assert (r["b"] == 2**32 - 1).all()
    with pytest.raises(ValueError):
        db.collide(vertices, faces, np.eye(3))
    with pytest.raises(mktree.Error, match="rotation"):
        db.collide(vertices, faces, np.diag([2.0, 1.0, 1.0, 1.0]))


def test_clash_releases_the_gil(cubes):
    """As test_queries_release_the_gil: the main thread gets to run while a worker clashes."""
    path, _, _ = cubes
    db = mktree.open(path)
    started, state = threading.Event(), {"done": False}
    expected = as_set(db.clash())

    def worker():
        started.set()
        for _ in range(5):
            db.clash(threads=1)
        state["done"] = True

    old = sys.getswitchinterval()
    sys.setswitchinterval(1000)
    try:
        t = threading.Thread(target=worker)
        t.start()
        started.wait()
        ran_while_worker_busy = not state["done"]
        mine = as_set(db.clash(threads=1))
        t.join()
    finally:
        sys.setswitchinterval(old)
    assert ran_while_worker_busy
    assert mine == expected
