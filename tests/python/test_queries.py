"""Ray and overlap queries against NumPy oracles."""

import numpy as np
import pytest

import viscd
from conftest import box_matrix, random_boxes, random_spheres, sphere_matrix


def sphere_box_overlaps(spheres, boxes):
    """viscd's sphere-box test: in double, per-axis distance to the interval, (ex^2 + ey^2) + ez^2 <= r^2."""
    s = np.asarray(spheres, np.float64).reshape(-1, 4)
    b = np.asarray(boxes, np.float64).reshape(-1, 6)
    e2 = []
    for k in range(3):
        c = s[:, None, k]
        e = np.maximum(np.maximum(b[None, :, k] - c, 0.0), c - b[None, :, 3 + k])
        e2.append(e * e)
    return (e2[0] + e2[1]) + e2[2] <= s[:, None, 3] ** 2


def ray_sphere_oracle(o, d, spheres):
    """(hit, t) per sphere in float64, and a flag for rays too close to tangent to decide."""
    o, d = np.float64(o), np.float64(d)
    c = spheres[:, :3].astype(np.float64)
    r = spheres[:, 3].astype(np.float64)
    oc = o - c
    a = d @ d
    b = 2 * oc @ d
    cc = np.einsum("ij,ij->i", oc, oc) - r * r
    disc = b * b - 4 * a * cc
    t1 = (-b - np.sqrt(np.maximum(disc, 0))) / (2 * a)
    inside = cc <= 0
    hit = inside | ((disc >= 0) & (t1 >= 0))
    t = np.where(inside, 0.0, t1)
    unsure = np.abs(disc) < 1e-6 * (b * b + 1)
    return hit, t, unsure


def test_ray_cast_matches_an_oracle(backend, rng):
    spheres = random_spheres(rng, 800, extent=30.0)
    det = viscd.Detector(backend)
    det.detect(spheres)
    for _ in range(40):
        o = rng.uniform(-40, 40, 3)
        d = rng.normal(size=3)
        hit, t, unsure = ray_sphere_oracle(o, d, spheres)
        idx, ts = det.ray_cast_all(o, d)
        assert idx.dtype == np.uint32 and ts.dtype == np.float32
        got = set(idx.tolist())
        expected = set(np.nonzero(hit)[0].tolist())
        undecided = set(np.nonzero(unsure)[0].tolist())
        assert got - undecided == expected - undecided
        np.testing.assert_allclose(ts, t[idx], rtol=1e-5, atol=1e-5)
        assert np.all(np.diff(ts) >= 0)  # sorted by t
        first = det.ray_cast(o, d)
        if len(idx):
            assert first == (int(idx[0]), float(ts[0]))
        else:
            assert first is None


def test_ray_cast_max_t_and_filter():
    det = viscd.Detector()
    det.detect(np.float32([[0, 0, 0, 1], [5, 0, 0, 1], [10, 0, 0, 1]]),
               filters=np.uint32([[1, ~0 & 0xFFFFFFFF], [2, 0xFFFFFFFF], [2, 0xFFFFFFFF]]))
    assert det.ray_cast((-5, 0, 0), (1, 0, 0)) == (0, 4.0)
    idx, t = det.ray_cast_all((-5, 0, 0), (1, 0, 0), max_t=10.0)
    np.testing.assert_array_equal(idx, [0, 1])
    np.testing.assert_array_equal(t, [4.0, 9.0])
    assert det.ray_cast((-5, 0, 0), (1, 0, 0), filter=(2, 2)) == (1, 9.0)
    assert det.ray_cast((-5, 0, 0), (1, 0, 0), max_t=3.0) is None
    assert det.ray_cast((0, 0, 0), (0, 0, 0)) is None  # a zero direction hits nothing
    assert det.ray_cast((0.5, 0, 0), (0, 1, 0)) == (0, 0.0)  # inside: t = 0


def test_overlap_matches_the_pair_test(backend, rng):
    spheres = random_spheres(rng, 1000, extent=30.0)
    det = viscd.Detector(backend)
    det.detect(spheres)
    queries = random_spheres(rng, 30, extent=30.0, r_max=6.0)
    boxes = random_boxes(rng, 30, extent=30.0, size_max=10.0)
    for q in queries:
        got = det.overlap(sphere=q)
        assert got.dtype == np.uint32
        np.testing.assert_array_equal(got, np.nonzero(sphere_matrix(q[None], spheres)[0])[0])
    for b in boxes:
        np.testing.assert_array_equal(det.overlap(box=b), np.nonzero(sphere_box_overlaps(spheres, b[None])[:, 0])[0])


def test_overlap_on_boxes(backend, rng):
    boxes = random_boxes(rng, 800, extent=30.0)
    det = viscd.Detector(backend)
    det.detect(boxes=boxes)
    for q in random_boxes(rng, 20, extent=30.0, size_max=10.0):
        np.testing.assert_array_equal(det.overlap(box=q), np.nonzero(box_matrix(q[None], boxes)[0])[0])
    for q in random_spheres(rng, 20, extent=30.0, r_max=6.0):
        np.testing.assert_array_equal(det.overlap(sphere=q), np.nonzero(sphere_box_overlaps(q[None], boxes)[0])[0])
    # A ray along x through the middle of a box hits it at its min x face.
    b = boxes[0]
    o = (b[0] - 5.0, (b[1] + b[4]) / 2, (b[2] + b[5]) / 2)
    idx, t = det.ray_cast_all(o, (1, 0, 0))
    assert 0 in idx.tolist()
    assert t[idx.tolist().index(0)] == pytest.approx(5.0, rel=1e-5)


def test_overlap_filter_and_invalid_shapes():
    det = viscd.Detector()
    det.detect(np.float32([[0, 0, 0, 1], [1, 0, 0, 1]]), filters=np.uint32([[1, 1], [2, 2]]))
    np.testing.assert_array_equal(det.overlap(sphere=(0, 0, 0, 5)), [0, 1])
    np.testing.assert_array_equal(det.overlap(sphere=(0, 0, 0, 5), filter=(2, 2)), [1])
    assert det.overlap(sphere=(0, 0, 0, -1)).shape == (0,)  # an invalid query overlaps nothing
    assert det.overlap(box=(1, 1, 1, 0, 0, 0)).shape == (0,)


def test_queries_before_any_frame():
    det = viscd.Detector()
    assert det.ray_cast((0, 0, 0), (1, 0, 0)) is None
    idx, t = det.ray_cast_all((0, 0, 0), (1, 0, 0))
    assert idx.shape == (0,) and t.shape == (0,)
    assert det.overlap(sphere=(0, 0, 0, 1)).shape == (0,)


def test_culled_objects_are_invisible_to_queries():
    det = viscd.Detector(lambda_=50)
    cam = viscd.Camera((0, 0, 20), (0, 0, 0), width=320, height=240)
    spheres = np.float32([[0, 0, 0, 3], [0, 0, -500, 0.01]])  # the second: far and tiny, culled
    frame = det.detect(spheres, camera=cam)
    np.testing.assert_array_equal(frame.state, [1, 0])
    np.testing.assert_array_equal(det.ray_cast_all((0, 0, 30), (0, 0, -1))[0], [0])
    assert det.overlap(sphere=(0, 0, -500, 1)).shape == (0,)
