"""The Python module against brute force (python/run_tests.sh runs these; docs/python.md)."""
import os
import sys
import threading
from pathlib import Path

import numpy as np
import pytest

import mktree

DATA = Path(os.environ.get("MKTREE_SHARED_DATA", Path(__file__).resolve().parents[2] / ".." / "shared" / "data"))
DUPLEX = DATA / "buildings" / "duplex.obj"

# A cube's 12 triangles over its corners (bit 0: x, bit 1: y, bit 2: z), outward.
CUBE_FACES = np.array([[0, 2, 3], [0, 3, 1], [4, 5, 7], [4, 7, 6], [0, 1, 5], [0, 5, 4],
                       [2, 6, 7], [2, 7, 3], [0, 4, 6], [0, 6, 2], [1, 3, 7], [1, 7, 5]], dtype=np.uint32)


def first_use_order(vertices, faces):
    """Renumbers vertices in the order the faces first use them, as the OBJ reader does."""
    order, new_index = [], {}
    for v in faces.ravel():
        if int(v) not in new_index:
            new_index[int(v)] = len(order)
            order.append(int(v))
    remap = np.array([new_index[i] for i in range(len(vertices))], dtype=np.uint32)
    return vertices[order], remap[faces]


def random_boxes(n, seed):
    """Axis-aligned cubes with coordinates in multiples of 1/8 (exact in float32): each solid is its
    AABB, so brute force needs no tolerance. Returns trimesh-style dicts and the (n, 2, 3) boxes."""
    rng = np.random.default_rng(seed)
    lo = rng.integers(0, 800, size=(n, 3)) / 8.0
    hi = lo + rng.integers(1, 40, size=(n, 3)) / 8.0
    corners = np.array([[(c >> a) & 1 for a in range(3)] for c in range(8)])
    objects = []
    for i in range(n):
        vertices = np.where(corners == 1, hi[i], lo[i]).astype(np.float64)
        vertices, faces = first_use_order(vertices, CUBE_FACES)
        objects.append({"vertices": vertices, "faces": faces, "name": f"cube_{i}",
                        "attributes": {"kind": "cube", "index": str(i)}})
    return objects, np.stack([lo, hi], axis=1)


def random_queries(n, seed, lo=-2.0, hi=105.0, side=12.0):
    rng = np.random.default_rng(seed)
    mins = rng.uniform(lo, hi, size=(n, 3))
    return np.hstack([mins, mins + rng.uniform(0, side, size=(n, 1))])


def brute_force(boxes, q):
    """Ids of the boxes ((n, 2, 3): min, max) meeting the closed box q (6 numbers)."""
    meets = np.all((boxes[:, 0] <= q[3:]) & (q[:3] <= boxes[:, 1]), axis=1)
    return np.flatnonzero(meets).astype(np.uint32)


def write_obj(objects, path):
    with open(path, "w") as out:
        base = 1
        for o in objects:
            out.write(f"o {o['name']}\n")
            for v in o["vertices"]:
                out.write("v %r %r %r\n" % tuple(float(c) for c in v))
            for f in o["faces"]:
                out.write("f %d %d %d\n" % tuple(int(i) + base for i in f))
            base += len(o["vertices"])


def read_obj(path):
    """A small OBJ reader (v, f, o; polygons as fans) that keeps objects with faces, their vertices in
    order of first use: what mktree's reader makes of buildings/duplex.obj."""
    vertices, objects, name, faces = [], [], None, []

    def flush():
        if faces:
            f = np.array(faces, dtype=np.int64)
            used, local = np.unique(f, return_inverse=True)
            v, lf = first_use_order(np.array(vertices)[used], local.reshape(-1, 3))
            objects.append({"vertices": v, "faces": lf, "name": name})

    for line in open(path):
        parts = line.split()
        if not parts:
            continue
        if parts[0] == "v":
            vertices.append([float(c) for c in parts[1:4]])
        elif parts[0] == "o":
            flush()
            name, faces = line[2:].strip(), []
        elif parts[0] == "f":
            idx = [int(p.split("/")[0]) for p in parts[1:]]
            idx = [i - 1 if i > 0 else len(vertices) + i for i in idx]
            faces.extend([idx[0], idx[k], idx[k + 1]] for k in range(1, len(idx) - 1))
    flush()
    return objects


def float32_box(vertices):
    """The box a store keeps for these vertices (origin 0): the bounds rounded outward to float32."""
    lo, hi = vertices.min(axis=0), vertices.max(axis=0)
    lo32, hi32 = lo.astype(np.float32), hi.astype(np.float32)
    lo32 = np.where(lo32 > lo, np.nextafter(lo32, np.float32(-np.inf)), lo32)
    hi32 = np.where(hi32 < hi, np.nextafter(hi32, np.float32(np.inf)), hi32)
    return np.stack([lo32, hi32]).astype(np.float64)


@pytest.fixture(scope="module")
def cubes(tmp_path_factory):
    objects, boxes = random_boxes(1500, 3)
    path = tmp_path_factory.mktemp("cubes") / "cubes.mkt"
    stats = mktree.build(path, objects=objects, backend="pagefile", block_size=1024, blocks_per_page=1)
    return path, objects, boxes, stats


def test_build_stats(cubes):
    path, objects, _, stats = cubes
    assert stats["objects"] == len(objects)
    assert stats["triangles"] == 12 * len(objects)
    assert stats["page_bytes"] == 1024
    assert stats["pages"] >= stats["leaves"] > 10
    assert stats["store_bytes"] == os.path.getsize(path)
    assert stats["origin"] == (0.0, 0.0, 0.0)


@pytest.mark.parametrize("exact", [False, True])
def test_queries_against_brute_force(cubes, exact):
    path, objects, boxes, _ = cubes
    db = mktree.open(path, cache_pages=64)
    assert db.object_count == len(objects)
    assert np.array_equal(db.bounds, [boxes[:, 0].min(axis=0), boxes[:, 1].max(axis=0)])
    nonempty = point_hits = 0
    for q in random_queries(200, 5):
        expected = brute_force(boxes, q)
        nonempty += len(expected) > 0
        ids = db.box(q[:3], q[3:], exact=exact)
        assert ids.dtype == np.uint32
        assert np.array_equal(ids, expected)
        assert db.count(q[:3], q[3:], exact=exact) == len(expected)
        assert db.any(q[:3], q[3:], exact=exact) == (len(expected) > 0)
        p = q[:3]
        point_expected = brute_force(boxes, np.concatenate([p, p]))
        assert np.array_equal(db.point(*p, exact=exact), point_expected)
        point_hits += len(point_expected) > 0
        assert db.any(p, exact=exact) == (len(point_expected) > 0)
    for c in boxes[::50].mean(axis=1):  # points inside objects
        expected = brute_force(boxes, np.concatenate([c, c]))
        assert np.array_equal(db.point(*c, exact=exact), expected)
        point_hits += len(expected) > 0
    assert nonempty > 60 and point_hits > 30  # the queries do meet the scene
    for i in range(0, len(objects), 101):
        assert db.object_name(i) == objects[i]["name"]


def test_limit_and_stats(cubes):
    path, _, boxes, _ = cubes
    db = mktree.open(path)
    q = np.array([0, 0, 0, 60, 60, 60], dtype=float)
    expected = brute_force(boxes, q)
    assert len(expected) > 10
    ids, stats = db.box(q[:3], q[3:], limit=5, stats=True)
    assert len(ids) == 5 and set(ids) <= set(expected)
    assert stats["truncated"] and stats["hits"] == 5
    ids, stats = db.box(q[:3], q[3:], stats=True)
    assert stats["hits"] == len(expected) and not stats["truncated"]
    assert stats["pages_touched"] >= stats["leaves_with_hits"] > 0
    info = db.stats()
    assert info["object_count"] == db.object_count
    assert info["tree"]["leaves"] > 10


@pytest.mark.parametrize("exact", [False, True])
def test_batched_equals_single(cubes, exact):
    path, _, _, _ = cubes
    db = mktree.open(path)
    qs = random_queries(300, 9)
    pts = qs[:, :3]
    single_boxes = [db.box(q[:3], q[3:], exact=exact) for q in qs]
    single_points = [db.point(*p, exact=exact) for p in pts]
    for threads in (1, 2):
        got = db.boxes(qs, exact=exact, threads=threads)
        assert len(got) == len(qs) and all(np.array_equal(a, b) for a, b in zip(got, single_boxes))
        offsets, ids = db.boxes(qs, exact=exact, threads=threads, csr=True)
        assert offsets.dtype == np.int64 and ids.dtype == np.uint32 and len(offsets) == len(qs) + 1
        assert all(np.array_equal(ids[offsets[i]:offsets[i + 1]], single_boxes[i]) for i in range(len(qs)))
        got = db.points(pts, exact=exact, threads=threads)
        assert all(np.array_equal(a, b) for a, b in zip(got, single_points))
    assert sum(len(a) for a in single_boxes) > 300
    # Any array that converts to float64 rows will do (a list, float32).
    got = db.boxes(qs.astype(np.float32).tolist())
    assert len(got) == len(qs)
    empty_offsets, empty_ids = db.points(np.zeros((0, 3)), csr=True)
    assert list(empty_offsets) == [0] and len(empty_ids) == 0


def test_build_from_numpy_equals_build_from_obj(tmp_path):
    objects, boxes = random_boxes(800, 4)
    write_obj(objects, tmp_path / "cubes.obj")
    a = mktree.build(tmp_path / "a.mkt", objects=objects, block_size=1024, blocks_per_page=1)
    b = mktree.build(tmp_path / "b.mkt", files=str(tmp_path / "cubes.obj"), block_size=1024,
                     blocks_per_page=1)
    for key in ("objects", "triangles", "leaves", "pages", "height", "encoded_bytes", "raw_geometry_bytes"):
        assert a[key] == b[key], key
    da, db_ = mktree.open(tmp_path / "a.mkt"), mktree.open(tmp_path / "b.mkt")
    qs = random_queries(100, 11)
    for exact in (False, True):
        for x, y in zip(da.boxes(qs, exact=exact), db_.boxes(qs, exact=exact)):
            assert np.array_equal(x, y)
    assert [da.object_name(i) for i in range(0, 800, 37)] == [db_.object_name(i) for i in range(0, 800, 37)]


def test_real_file_against_brute_force_and_numpy_build(tmp_path):
    assert DUPLEX.exists(), f"{DUPLEX}: the real scenes of ../shared/data are needed"
    objects = read_obj(DUPLEX)
    assert len(objects) == 215
    from_file = mktree.build(tmp_path / "f.mkt", files=[DUPLEX], backend="pagefile")
    from_numpy = mktree.build(tmp_path / "n.mkt", objects=objects, backend="pagefile")
    assert from_file["origin"] == (0.0, 0.0, 0.0)  # the boxes below are in world coordinates
    for key in ("objects", "triangles", "leaves", "pages", "encoded_bytes"):
        assert from_file[key] == from_numpy[key], key
    boxes = np.stack([float32_box(o["vertices"]) for o in objects])
    db = mktree.open(tmp_path / "f.mkt")
    lo, hi = db.bounds
    qs = random_queries(300, 13, lo=float(lo.min()), hi=float(hi.max()), side=2.0)
    got = db.boxes(qs, threads=2)
    for q, ids in zip(qs, got):
        assert np.array_equal(ids, brute_force(boxes, q))
    assert sum(len(ids) for ids in got) > 100
    assert [db.object_name(i) for i in range(len(objects))] == [o["name"] for o in objects]


def test_trimesh_style_objects(tmp_path):
    """Objects with vertices/faces attributes (trimesh.Trimesh) and the name in metadata; int64 faces."""
    class Mesh:
        def __init__(self, vertices, faces, name):
            self.vertices, self.faces, self.metadata = vertices, faces, {"name": name}

    objects, boxes = random_boxes(50, 8)
    meshes = (Mesh(o["vertices"], o["faces"].astype(np.int64), o["name"]) for o in objects)  # a generator
    stats = mktree.build(tmp_path / "t.mkt", objects=meshes)
    assert stats["objects"] == 50
    db = mktree.open(tmp_path / "t.mkt")
    assert db.object_name(7) == "cube_7"
    q = np.array([0, 0, 0, 50, 50, 50], dtype=float)
    assert np.array_equal(db.box(q[:3], q[3:]), brute_force(boxes, q))


def test_build_from_step(tmp_path):
    """A STEP assembly (tests/data/step): one object per leaf solid, named by its assembly path, with its
    product and colour; the chord tolerance reaches the tessellation."""
    step = Path(__file__).resolve().parents[2] / "tests" / "data" / "step" / "engine_assembly.step"
    fine = mktree.build(tmp_path / "f.mkt", files=step, chord_tolerance=0.0001)
    coarse = mktree.build(tmp_path / "c.mkt", files=step, chord_tolerance=0.003, angular_deflection=3.0)
    assert fine["objects"] == coarse["objects"] == 11
    assert fine["triangles"] > coarse["triangles"]
    rec = mktree.open(tmp_path / "f.mkt").object(0)
    assert rec["name"] == "engine/block" and rec["source"] == str(step)
    assert ("step_product", "block") in rec["attributes"] and ("step_colour", "#cc2020") in rec["attributes"]
    assert np.allclose(rec["box"], [[0, 0, 0], [0.2, 0.1, 0.08]], atol=1e-6)
    with pytest.raises(mktree.Error, match="chord_tolerance"):
        mktree.build(tmp_path / "x.mkt", files=step, chord_tolerance=0.0)


def test_object_records_and_geometry(tmp_path):
    """Names, sources and attributes (any text, a repeated key) come back by id with the stored box and mesh."""
    objects, boxes = random_boxes(40, 11)
    for i, o in enumerate(objects):
        o["source"] = f"deck_{i % 3}.obj"
        o["attributes"] = [("tag", f"P-{i}"), ("group", "pipes"), ("group", "deck \u00e9\n")] if i % 2 else {}
    mktree.build(tmp_path / "r.mkt", objects=objects, backend="pagefile", block_size=1024, blocks_per_page=1)
    db = mktree.open(tmp_path / "r.mkt", cache_pages=0)
    for i, o in enumerate(objects):
        rec = db.object(i)
        assert rec["id"] == i and rec["name"] == o["name"] and rec["source"] == o["source"]
        assert rec["attributes"] == (list(o["attributes"]) if i % 2 else [])
        assert np.array_equal(rec["box"], float32_box(o["vertices"]))
        vertices, faces = db.geometry(i)
        assert faces.dtype == np.uint32 and faces.shape == o["faces"].shape
        # The stored mesh: float32 in the object's local frame, so within 2^-22 of its size of the input.
        tri_in = np.sort(o["vertices"][o["faces"]].reshape(-1, 9), axis=0)
        tri_out = np.sort(vertices[faces].reshape(-1, 9), axis=0)
        assert np.allclose(tri_in, tri_out, atol=1e-5)
    with pytest.raises(mktree.Error, match="id"):
        db.object(len(objects))
    with pytest.raises(mktree.Error):
        db.geometry(len(objects))


def assert_nothing_left(tmp_path, before):
    assert sorted(os.listdir(tmp_path)) == sorted(before)


def test_errors(tmp_path, cubes):
    path = cubes[0]
    with pytest.raises(mktree.Error, match="no such file"):
        mktree.open(tmp_path / "missing.mkt")
    (tmp_path / "junk.mkt").write_bytes(b"not a store" * 100)
    with pytest.raises(mktree.Error, match="junk.mkt"):
        mktree.open(tmp_path / "junk.mkt")
    db = mktree.open(path)
    with pytest.raises(mktree.Error, match="invalid argument"):
        db.box([0, 0, 0], [float("nan"), 1, 1])
    with pytest.raises(mktree.Error, match="query 1: "):
        db.points(np.array([[0, 0, 0], [np.inf, 0, 0]]))
    with pytest.raises(ValueError, match=r"shape \(n, 6\)"):
        db.boxes(np.zeros((4, 3)))
    with pytest.raises(mktree.Error):
        db.object_name(10**6)

    before = sorted(os.listdir(tmp_path))
    store = tmp_path / "s.mkt"
    objects, _ = random_boxes(20, 1)
    bad_index = [dict(o) for o in objects]
    bad_index[12]["faces"] = bad_index[12]["faces"].copy()
    bad_index[12]["faces"][3, 1] = 8
    with pytest.raises(mktree.Error, match="object 12 'cube_12': triangle 3 refers to vertex 8 of 8"):
        mktree.build(store, objects=bad_index)
    bad_shape = [dict(o) for o in objects]
    bad_shape[5]["vertices"] = np.zeros((4, 2))
    with pytest.raises(mktree.Error, match=r"objects\[5\]: vertices must be a float array of shape \(n, 3\)"):
        mktree.build(store, objects=bad_shape)
    bad_faces = [dict(o) for o in objects]
    bad_faces[2]["faces"] = bad_faces[2]["faces"].astype(np.float64)
    with pytest.raises(mktree.Error, match=r"objects\[2\]: faces must be an integer array"):
        mktree.build(store, objects=bad_faces)
    negative = [dict(o) for o in objects]
    negative[0]["faces"] = negative[0]["faces"].astype(np.int64) - 1
    with pytest.raises(mktree.Error, match=r"objects\[0\]: face 0 has vertex index -1"):
        mktree.build(store, objects=negative)
    with pytest.raises(mktree.Error, match="empty scene"):
        mktree.build(store, objects=[])

    def failing():
        yield objects[0]
        raise KeyError("from the caller")
    with pytest.raises(KeyError, match="from the caller"):
        mktree.build(store, objects=failing())

    def stop(stage, done, total):
        if stage == "build tree":
            raise InterruptedError("stopped by progress")
    with pytest.raises(InterruptedError):
        mktree.build(store, objects=objects, progress=stop)

    (tmp_path / "bad.obj").write_text("o a\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 9\n")
    with pytest.raises(mktree.Error, match="bad.obj:6"):
        mktree.build(store, files=tmp_path / "bad.obj")
    with pytest.raises(mktree.Error, match="tanker:N"):
        mktree.build(store, files="tanker:x")
    with pytest.raises(mktree.Error, match="balance_r"):
        mktree.build(store, objects=objects, balance_r=0.5)
    with pytest.raises(ValueError, match="backend"):
        mktree.build(store, objects=objects, backend="sqlite")
    with pytest.raises(ValueError, match="either objects or files"):
        mktree.build(store)
    assert_nothing_left(tmp_path, before + ["bad.obj"])


def test_progress(tmp_path):
    seen = []
    mktree.build(tmp_path / "p.mkt", files="tanker:3000:2", progress=lambda s, d, t: seen.append(s))
    stages = [s for i, s in enumerate(seen) if i == 0 or seen[i - 1] != s]
    assert stages == ["read", "build tree", "write pages", "write object table"]


def test_queries_release_the_gil(cubes):
    """With a switch interval of 1000 s a thread holding the GIL keeps it until it blocks; the main thread
    waits for the worker to start, then runs only when the worker gives the GIL up. It must get to run,
    and query, while the worker is still inside its batches: only a query that released the GIL lets it."""
    path, _, _, _ = cubes
    db = mktree.open(path)
    qs = random_queries(20000, 17)
    started, state = threading.Event(), {"done": False}
    expected = db.boxes(qs[:100])

    def worker():
        started.set()
        for _ in range(5):
            db.boxes(qs, threads=1)
        state["done"] = True

    old = sys.getswitchinterval()
    sys.setswitchinterval(1000)
    try:
        t = threading.Thread(target=worker)
        t.start()
        started.wait()
        ran_while_worker_busy = not state["done"]
        mine = db.boxes(qs[:100], threads=1)
        t.join()
    finally:
        sys.setswitchinterval(old)
    assert ran_while_worker_busy
    assert all(np.array_equal(a, b) for a, b in zip(mine, expected))
