"""Changes through the Python module (docs/python.md): a writer's commits and compaction against brute force
over the live boxes, snapshots by revision, the log, and bad batches that change nothing."""
import sys
import threading

import numpy as np
import pytest

import mktree
from test_mktree import brute_force, random_boxes, random_queries, write_obj


def live_answers(live, queries):
    """Brute force over the live objects (id -> (2, 3) box): sorted ids meeting each query box."""
    ids = np.array(sorted(live), dtype=np.uint32)
    boxes = np.stack([live[i] for i in ids]) if len(ids) else np.zeros((0, 2, 3))
    return [ids[brute_force(boxes, q)] for q in queries]


def assert_answers(db, live, queries):
    assert db.object_count == len(live)
    for got, want in zip(db.boxes(queries, threads=2), live_answers(live, queries)):
        np.testing.assert_array_equal(got, want)


@pytest.fixture
def store(tmp_path):
    objects, boxes = random_boxes(300, 5)
    path = tmp_path / "s.mkt"
    mktree.build(path, objects=objects, backend="pagefile", block_size=1024, blocks_per_page=1)
    return path, {i: boxes[i] for i in range(len(boxes))}


def test_commit_and_compact_against_brute_force(store):
    path, live = store
    queries = random_queries(300, 11)
    before = mktree.open(path)
    assert before.revision == 0
    new_objects, new_boxes = random_boxes(40, 6)
    for o in new_objects:
        o["name"] = "new_" + o["name"]
    removed = [3, 17, 250]
    by_id = [dict(o, id=i) for o, i in zip(new_objects[20:30], [5, 6, 7, 100, 101, 102, 200, 201, 202, 299])]
    by_name = [dict(o, name=n) for o, n in zip(new_objects[30:32], ["cube_40", "cube_41"])]
    with mktree.open_writer(path, compact_threshold=0) as w:
        assert w.revision == 0
        r = w.commit(add=new_objects[:20], remove=removed, remove_names=["cube_9", "cube_10"],
                     replace=by_id + by_name, message="first batch")
        assert (r["revision"], r["added"], r["removed"], r["replaced"]) == (1, 20, 5, 12)
        np.testing.assert_array_equal(r["added_ids"], np.arange(300, 320, dtype=np.uint32))
        assert r["objects"] == 315 and not r["compacted"] and r["compaction_error"] is None
        for i in removed + [9, 10]:
            del live[i]
        for k, i in enumerate(r["added_ids"]):
            live[int(i)] = new_boxes[k]
        for k, i in enumerate([5, 6, 7, 100, 101, 102, 200, 201, 202, 299]):
            live[i] = new_boxes[20 + k]
        live[40], live[41] = new_boxes[30], new_boxes[31]
        assert w.revision == 1

        now = mktree.open(path)
        assert now.revision == 1 and now.id_limit == 320
        assert_answers(now, live, queries)
        assert now.object(5)["name"] == "new_cube_20"
        assert now.object(40)["name"] == "cube_40"
        np.testing.assert_array_equal(now.object(40)["box"], new_boxes[30])
        with pytest.raises(mktree.Error, match="17"):
            now.object(17)
        # The Database opened before the commit, and revision 0 opened now, answer revision 0.
        for old in (before, mktree.open(path, revision=0)):
            assert old.revision == 0 and old.object_count == 300
            np.testing.assert_array_equal(old.box([0, 0, 0], [200, 200, 200]), np.arange(300, dtype=np.uint32))

        del before, old  # no reader holds revision 0 any more: compaction with keep=2 retires it
        c = w.compact(keep=2)
        assert c["revision"] == 2 and c["objects"] == 315 and c["folded"] >= 1
        assert_answers(mktree.open(path), live, queries)
        assert_answers(now, live, queries)  # the snapshot still answers revision 1
    log = mktree.log(path)
    assert [e["revision"] for e in log] == [1, 2]
    assert log[0]["message"] == "first batch" and log[0]["added"] == 20 and log[0]["removed"] == 5
    assert log[1]["compaction"] and log[1]["objects"] == 315


def test_bad_batches_change_nothing(store):
    path, live = store
    w = mktree.open_writer(path)
    w.commit(add=[dict(random_boxes(1, 9)[0][0], name="dup"), dict(random_boxes(1, 10)[0][0], name="dup")])
    log = mktree.log(path)
    cube = random_boxes(1, 12)[0][0]
    bad = [
        (dict(remove=[12345]), "12345"),
        (dict(remove=[4, 4]), "object 4"),
        (dict(remove_names=["nobody"]), "nobody"),
        (dict(replace=[dict(cube, name="missing")]), "missing"),
        (dict(replace=[dict(cube, name="dup")]), "2 objects"),
        (dict(replace=[dict(cube, id=99999)]), "99999"),
        (dict(add=[dict(cube, vertices=np.where(cube["vertices"] > 0, np.nan, cube["vertices"]))]), "add"),
    ]
    for batch, named in bad:
        with pytest.raises(mktree.Error, match=named):
            w.commit(**batch)
        assert mktree.log(path) == log
    with pytest.raises(mktree.Error, match=r"add\[0\]: vertices"):
        w.commit(add=[dict(cube, vertices=np.zeros((4, 2)))])
    with pytest.raises(mktree.Error):
        mktree.open_writer(path)  # one writer at a time, refused at once
    with pytest.raises(mktree.Error, match="revision 7"):
        mktree.open(path, revision=7)
    w.close()
    assert w.closed
    with pytest.raises(mktree.Error, match="closed"):
        w.commit(remove=[1])
    assert mktree.log(path) == log
    mktree.open_writer(path).close()  # the lock went with close()


def test_commit_releases_the_gil(store):
    """As test_queries_release_the_gil: the main thread runs while the worker is inside its commits."""
    path, _ = store
    objects, _ = random_boxes(3000, 21)
    w = mktree.open_writer(path, compact_threshold=0)
    started, state = threading.Event(), {"done": False}

    def worker():
        started.set()
        for k in range(3):
            w.commit(add=objects[1000 * k:1000 * (k + 1)])
        state["done"] = True

    old = sys.getswitchinterval()
    sys.setswitchinterval(1000)
    try:
        t = threading.Thread(target=worker)
        t.start()
        started.wait()
        ran_while_worker_busy = not state["done"]
        n = len(mktree.log(path))
        t.join()
    finally:
        sys.setswitchinterval(old)
    assert ran_while_worker_busy and n >= 1
    assert w.revision == 3
    w.close()


def test_sharded_store_takes_changes(tmp_path):
    """A sharded store (build(..., shards=K) from files) takes commits and compacts as a store does."""
    path = tmp_path / "s.mkts"
    mktree.build(path, files="tanker:400:3", backend="pagefile", block_size=1024, blocks_per_page=2, shards=3)
    db = mktree.open(path)
    built = {i: np.asarray(db.object(i)["box"]) for i in range(db.object_count)}
    rng = np.random.default_rng(13)
    mins = rng.uniform([-5, -30, -5], [300, 25, 30], size=(300, 3))
    queries = np.hstack([mins, mins + rng.uniform(0, 20, size=(300, 1))])
    assert_answers(db, built, queries)
    live = dict(built)
    new_objects, new_boxes = random_boxes(20, 7)
    with mktree.open_writer(path, compact_threshold=0) as w:
        r = w.commit(add=new_objects, remove=[0, 7, 399], message="sharded")
        assert (r["revision"], r["added"], r["removed"]) == (1, 20, 3)
        for i in (0, 7, 399):
            del live[i]
        for k, i in enumerate(r["added_ids"]):
            live[int(i)] = new_boxes[k]
        assert_answers(mktree.open(path), live, queries)
        c = w.compact()
        assert c["revision"] == 2 and c["objects"] == len(live)
    assert_answers(mktree.open(path), live, queries)
    assert_answers(db, built, queries)  # the snapshot opened before still answers revision 0
    assert [e["revision"] for e in mktree.log(path)] == [0, 1, 2]


def test_add_files_streams_objects_after_the_batch_ones(store, tmp_path):
    """add_files takes scene files as build's `files` does: their objects get the ids after `add`'s, in
    order; a malformed file commits nothing and names the file and line."""
    path, live = store
    objects, boxes = random_boxes(30, 21)
    obj = tmp_path / "more.obj"
    write_obj([dict(o, name="file_" + o["name"]) for o in objects[10:]], obj)
    bad = tmp_path / "bad.obj"
    bad.write_text("o a\nv 0 0 0\nv 1 0 0\nv nan 1 0\nf 1 2 3\n")
    with mktree.open_writer(path, compact_threshold=0) as w:
        with pytest.raises(mktree.Error, match=r"bad\.obj:4"):
            w.commit(add=objects[:10], add_files=[obj, bad])
        assert w.revision == 0
        r = w.commit(add=objects[:10], add_files=obj)
        assert r["added"] == 30 and r["warnings"] == []
        np.testing.assert_array_equal(r["added_ids"], np.arange(300, 330, dtype=np.uint32))
    for k in range(30):
        live[300 + k] = boxes[k]
    db = mktree.open(path)
    assert db.object(310)["name"] == "file_" + objects[10]["name"]
    assert_answers(db, live, random_queries(200, 23))
