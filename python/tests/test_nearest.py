"""db.nearest and db.rays against brute force on axis-aligned cubes (each solid is its box, so the exact
distance is the point-box distance, 0 inside; a ray's first hit is where it enters a cube, or leaves the
one it starts in). docs/nearest_and_ray.md."""
import numpy as np
import pytest

import mktree

from test_mktree import random_boxes


@pytest.fixture(scope="module")
def cubes(tmp_path_factory):
    objects, boxes = random_boxes(800, 11)
    path = tmp_path_factory.mktemp("near") / "cubes.mkt"
    mktree.build(path, objects=objects, backend="pagefile", block_size=1024, blocks_per_page=1)
    return mktree.open(path, cache_pages=64), boxes


def box_distances(boxes, p):
    d = np.maximum(np.maximum(boxes[:, 0] - p, p - boxes[:, 1]), 0)
    return np.sqrt((d * d).sum(axis=1))


def first_hits(boxes, o, d):
    """(t, id) of the first surface hit of the ray o + t d / |d| among the boxes, or (inf, -1)."""
    u = d / np.linalg.norm(d)
    with np.errstate(divide="ignore", invalid="ignore"):
        t0 = (boxes[:, 0] - o) / u
        t1 = (boxes[:, 1] - o) / u
    lo = np.where(u == 0, np.where((o >= boxes[:, 0]) & (o <= boxes[:, 1]), -np.inf, np.inf), np.minimum(t0, t1))
    hi = np.where(u == 0, np.where((o >= boxes[:, 0]) & (o <= boxes[:, 1]), np.inf, -np.inf), np.maximum(t0, t1))
    enter, leave = lo.max(axis=1), hi.min(axis=1)
    t = np.where(enter >= 0, enter, leave)  # from inside: where it leaves
    t = np.where((enter <= leave) & (leave >= 0), t, np.inf)
    i = int(np.argmin(t))
    return (t[i], i) if np.isfinite(t[i]) else (np.inf, -1)


def test_nearest_matches_brute_force(cubes):
    db, boxes = cubes
    rng = np.random.default_rng(5)
    points = rng.uniform(-5, 110, size=(200, 3))
    for k in (1, 7):
        ids, dist, at = db.nearest(points, k=k, threads=2)
        assert ids.shape == (200, k) and dist.shape == (200, k) and at.shape == (200, k, 3)
        for i, p in enumerate(points):
            want = np.sort(box_distances(boxes, p))[:k]
            np.testing.assert_allclose(dist[i], want, rtol=0, atol=1e-9)
            np.testing.assert_allclose(box_distances(boxes[ids[i]], p), dist[i], rtol=0, atol=1e-9)
            np.testing.assert_allclose(np.linalg.norm(at[i] - p, axis=1), dist[i], rtol=0, atol=1e-9)


def test_nearest_inside_is_zero_and_k_past_the_limit_is_padded(cubes):
    db, boxes = cubes
    centres = boxes.mean(axis=1)[:50]
    ids, dist, at = db.nearest(centres, k=1)
    assert np.all(dist[:, 0] == 0)
    np.testing.assert_array_equal(at[:, 0], centres)
    ids, dist, _ = db.nearest(np.array([[-1000.0, -1000.0, -1000.0]]), k=3, max_distance=1.0)
    assert list(ids[0]) == [-1, -1, -1] and np.all(np.isinf(dist))


def test_rays_match_brute_force(cubes):
    db, boxes = cubes
    rng = np.random.default_rng(6)
    origins = rng.uniform(-5, 110, size=(200, 3))
    targets = boxes[rng.integers(0, len(boxes), size=200)].mean(axis=1)
    directions = targets - origins
    directions[::4] = rng.normal(size=(50, 3))  # some at random
    ids, t, points, normals = db.rays(origins, directions, threads=2)
    assert ids.shape == (200,) and points.shape == (200, 3) and normals.shape == (200, 3)
    hits = 0
    for i in range(200):
        want_t, want_id = first_hits(boxes, origins[i], directions[i])
        if not np.isfinite(want_t):
            assert ids[i] == -1 and np.isinf(t[i]) and np.all(np.isnan(points[i]))
            continue
        hits += 1
        assert t[i] == pytest.approx(want_t, abs=1e-9)
        assert np.abs(np.linalg.norm(normals[i]) - 1) < 1e-12
        u = directions[i] / np.linalg.norm(directions[i])
        np.testing.assert_allclose(points[i], origins[i] + t[i] * u, atol=1e-9)
    assert hits > 100


def test_bad_input_raises(cubes):
    db, _ = cubes
    with pytest.raises(mktree.Error, match="zero direction"):
        db.rays(np.zeros((2, 3)), np.array([[1.0, 0, 0], [0, 0, 0]]))
    with pytest.raises(mktree.Error, match="non-finite"):
        db.nearest(np.array([[np.nan, 0, 0]]))
    with pytest.raises(ValueError):
        db.nearest(np.zeros((3, 2)))
    with pytest.raises(ValueError):
        db.nearest(np.zeros((3, 3)), k=0)
    with pytest.raises(ValueError):
        db.rays(np.zeros((3, 3)), np.ones((2, 3)))
