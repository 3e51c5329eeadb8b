"""Pairs equal a NumPy brute force, on random and degenerate scenes, spheres and boxes."""

import numpy as np
import pytest

import viscd
from conftest import (
    EMPTY_PAIRS,
    brute_box_pairs,
    brute_sphere_pairs,
    gl_available,
    random_boxes,
    random_spheres,
)


def check_frame(frame, expected, n):
    np.testing.assert_array_equal(frame.pairs, expected)
    assert frame.pairs.dtype == np.uint32 and frame.pairs.shape == (len(expected), 2)
    assert frame.state.dtype == np.uint8 and frame.state.shape == (n,)
    colliding = np.zeros(n, bool)
    colliding[expected.ravel()] = True
    np.testing.assert_array_equal(frame.state, np.where(colliding, 2, 1))
    assert frame.stats["objects"] == n and frame.stats["pairs"] == len(expected)


@pytest.mark.parametrize("n", [0, 1, 2, 3, 17, 500, 2000])
def test_random_spheres(backend, rng, n):
    spheres = random_spheres(rng, n, extent=20.0 if n < 100 else 60.0)
    frame = viscd.Detector(backend).detect(spheres)
    check_frame(frame, brute_sphere_pairs(spheres), n)


@pytest.mark.parametrize("n", [0, 1, 2, 3, 17, 500, 2000])
def test_random_boxes(backend, rng, n):
    boxes = random_boxes(rng, n, extent=20.0 if n < 100 else 60.0)
    frame = viscd.Detector(backend).detect(boxes=boxes)
    check_frame(frame, brute_box_pairs(boxes), n)


DEGENERATE_SPHERES = {
    "all_centres_equal": np.tile(np.float32([1.5, -2.0, 3.0, 0.5]), (40, 1)),
    "all_points_equal": np.zeros((30, 4), np.float32),
    "touching": np.float32([[0, 0, 0, 1], [2, 0, 0, 1], [4, 0, 0, 1], [0, 3, 0, 1.5], [10, 0, 0, 0]]),
    "just_apart": np.float32([[0, 0, 0, 1], [np.nextafter(np.float32(2), np.float32(3)), 0, 0, 1]]),
    "huge_radii": np.float32([[1e18, 0, 0, 1e18], [-1e18, 0, 0, 1e18], [0, 1e18, 0, 1], [0, 0, 0, 0]]),
    "huge_coordinates": np.float32([[1e18, 1e18, 1e18, 1], [1e18, 1e18, 1e18, 0], [-1e18, -1e18, -1e18, 5]]),
    "tiny_radii": np.float32([[0, 0, 0, 1e-30], [1e-30, 0, 0, 1e-30], [3e-30, 0, 0, 1e-30], [1, 1, 1, 1e-38]]),
    "mixed_scales": np.float32([[0, 0, 0, 1e6], [5e5, 0, 0, 1e-3], [2e6, 0, 0, 1e-6], [0, 0, 0, 0]]),
    "line_chain": np.column_stack([np.arange(50, dtype=np.float32), np.zeros((50, 2), np.float32),
                                   np.full(50, 0.5, np.float32)]),
}


@pytest.mark.parametrize("name", sorted(DEGENERATE_SPHERES))
def test_degenerate_spheres(backend, name):
    spheres = DEGENERATE_SPHERES[name]
    frame = viscd.Detector(backend).detect(spheres)
    check_frame(frame, brute_sphere_pairs(spheres), len(spheres))


def test_touching_counts():
    frame = viscd.Detector().detect(np.float32([[0, 0, 0, 1], [2, 0, 0, 1]]))
    np.testing.assert_array_equal(frame.pairs, [[0, 1]])
    apart = np.float32([[0, 0, 0, 1], [np.nextafter(np.float32(2), np.float32(3)), 0, 0, 1]])
    assert viscd.Detector().detect(apart).pairs.shape == (0, 2)


DEGENERATE_BOXES = {
    "all_equal": np.tile(np.float32([0, 0, 0, 1, 1, 1]), (30, 1)),
    "points": np.float32([[0, 0, 0, 0, 0, 0], [0, 0, 0, 0, 0, 0], [1, 0, 0, 1, 0, 0]]),
    "touching_faces_edges_corners": np.float32(
        [[0, 0, 0, 1, 1, 1], [1, 0, 0, 2, 1, 1], [1, 1, 0, 2, 2, 1], [1, 1, 1, 2, 2, 2], [3, 3, 3, 4, 4, 4]]),
    "huge": np.float32([[-1e18, -1e18, -1e18, 1e18, 1e18, 1e18], [0, 0, 0, 1, 1, 1], [5, 5, 5, 5, 5, 5]]),
    "flat": np.float32([[0, 0, 0, 10, 10, 0], [5, 5, 0, 6, 6, 0], [5, 5, 1e-30, 6, 6, 1]]),
}


@pytest.mark.parametrize("name", sorted(DEGENERATE_BOXES))
def test_degenerate_boxes(backend, name):
    boxes = DEGENERATE_BOXES[name]
    frame = viscd.Detector(backend).detect(boxes=boxes)
    check_frame(frame, brute_box_pairs(boxes), len(boxes))


def test_no_objects_at_all():
    frame = viscd.Detector().detect()
    np.testing.assert_array_equal(frame.pairs, EMPTY_PAIRS)
    assert frame.state.shape == (0,) and frame.pixels.shape == (0,) and frame.image is None


@pytest.mark.parametrize("empty", [[], np.zeros((0, 4), np.float32), np.zeros((0,), np.float64)])
def test_empty_inputs(empty):
    assert viscd.Detector().detect(empty).pairs.shape == (0, 2)


def test_lists_and_other_dtypes_give_the_same_pairs(rng):
    spheres = random_spheres(rng, 300, extent=15.0)
    expected = brute_sphere_pairs(spheres)
    det = viscd.Detector()
    for converted in (spheres.astype(np.float64), spheres.tolist(), np.asfortranarray(spheres),
                      spheres.astype(">f4"), np.repeat(spheres, 2, axis=0)[::2]):
        frame = det.detect(converted)
        assert frame.input_copied
        np.testing.assert_array_equal(frame.pairs, expected)
    ints = np.array([[0, 0, 0, 1], [2, 0, 0, 1], [5, 0, 0, 1]], np.int64)
    np.testing.assert_array_equal(det.detect(ints).pairs, [[0, 1]])


def test_filters(backend, rng):
    spheres = random_spheres(rng, 400, extent=12.0)
    filters = np.stack([1 << rng.integers(0, 3, 400), rng.integers(0, 8, 400)], axis=1).astype(np.uint32)
    frame = viscd.Detector(backend).detect(spheres, filters=filters)
    g, m = filters[:, 0], filters[:, 1]
    expected = brute_sphere_pairs(spheres)
    keep = ((g[expected[:, 0]] & m[expected[:, 1]]) != 0) & ((g[expected[:, 1]] & m[expected[:, 0]]) != 0)
    np.testing.assert_array_equal(frame.pairs, expected[keep])
    # Other integer dtypes convert when every value fits uint32.
    np.testing.assert_array_equal(viscd.Detector(backend).detect(spheres, filters=filters.astype(np.int64)).pairs,
                                  expected[keep])


@pytest.mark.parametrize("bits", ["adaptive", 16, 32, 64])
@pytest.mark.parametrize("layout", ["extended", "plain"])
def test_every_morton_setting_is_exact(rng, bits, layout):
    spheres = random_spheres(rng, 1500, extent=40.0)
    frame = viscd.Detector(bits=bits, layout=layout, keep_order=False, simd="scalar").detect(spheres)
    np.testing.assert_array_equal(frame.pairs, brute_sphere_pairs(spheres))


@pytest.mark.skipif(not gl_available(), reason="no OpenGL 4.5 context")
def test_gl_backend_agrees(rng):
    spheres = random_spheres(rng, 1000, extent=40.0)
    boxes = random_boxes(rng, 500, extent=30.0)
    det = viscd.Detector("gl")
    np.testing.assert_array_equal(det.detect(spheres).pairs, brute_sphere_pairs(spheres))
    frame = viscd.Detector("gl").detect(boxes=boxes)
    np.testing.assert_array_equal(frame.pairs, brute_box_pairs(boxes))


def test_moved_lists_the_changed_objects(rng):
    # A world at rest with a few movers a frame, told through moved=: the same pairs as a detector
    # that rebuilds every frame, the frames followed, and a bad list refused with viscd's message.
    spheres = random_spheres(rng, 4000, extent=60.0)
    listed = viscd.Detector(threads=1)
    rebuilt = viscd.Detector(threads=1, follow_change=False)
    followed = 0
    for frame in range(12):
        movers = np.sort(rng.choice(len(spheres), 20, replace=False)).astype(np.uint32)
        if frame:
            spheres[movers, :3] += rng.normal(0, 0.3, (20, 3)).astype(np.float32)
        got = listed.detect(spheres, moved=movers if frame else None)
        np.testing.assert_array_equal(got.pairs, rebuilt.detect(spheres).pairs)
        followed += got.stats["followed_change"]
        if frame >= 3 and got.stats["followed_change"]:  # past the frames where the set is built
            assert got.stats["moved"] <= 20, got.stats["moved"]
    assert followed >= 8
    for bad, message in [([3, 2], "moved"), ([0, 0], "moved"), ([len(spheres)], "moved"), ([[1, 2]], "shape")]:
        with pytest.raises(ValueError, match=message):
            listed.detect(spheres, moved=np.array(bad))
    nothing = listed.detect(spheres, moved=[])
    np.testing.assert_array_equal(nothing.pairs, rebuilt.detect(spheres).pairs)
