"""The static set: pairs with static objects (bit 31), add/move/remove/clear, queries, filters."""

import numpy as np
import pytest

import viscd
from conftest import box_matrix, brute_box_pairs, brute_sphere_pairs, random_boxes, random_spheres, sphere_matrix


def expected_with_static(moving_pairs, cross, slots):
    """Moving pairs plus (i, slot | bit) for each cross[i, k], sorted as viscd sorts (by (i, j))."""
    i, k = np.nonzero(cross)
    static = np.stack([i, np.asarray(slots, np.uint32)[k] | np.uint32(viscd.STATIC_BIT)], axis=1)
    allp = np.concatenate([moving_pairs.astype(np.uint64), static.astype(np.uint64)])
    order = np.lexsort((allp[:, 1], allp[:, 0]))
    return allp[order].astype(np.uint32).reshape(-1, 2)


def test_static_spheres(backend, rng):
    moving = random_spheres(rng, 400, extent=20.0)
    static = random_spheres(rng, 60, extent=20.0, r_max=4.0)
    det = viscd.Detector(backend)
    det.set_static(static)
    assert det.static_count == 60 and det.static_kind == "sphere"
    frame = det.detect(moving)
    cross = sphere_matrix(moving, static)
    expected = expected_with_static(brute_sphere_pairs(moving), cross, np.arange(60))
    np.testing.assert_array_equal(frame.pairs, expected)
    assert frame.stats["static_objects"] == 60
    # Conveniences.
    is_static = viscd.is_static(frame.pairs[:, 1])
    assert is_static.dtype == bool and is_static.sum() == cross.sum()
    np.testing.assert_array_equal(frame.static_pairs,
                                  np.stack([frame.pairs[is_static, 0], viscd.static_slot(frame.pairs[is_static, 1])], 1))
    np.testing.assert_array_equal(frame.moving_pairs, brute_sphere_pairs(moving))
    assert viscd.static_index(3) == 3 | 0x80000000 and viscd.is_static(viscd.static_index(3))
    assert viscd.static_slot(viscd.static_index(7)) == 7 and not viscd.is_static(7)


def test_static_boxes(backend, rng):
    moving = random_boxes(rng, 300, extent=20.0)
    static = random_boxes(rng, 40, extent=20.0, size_max=10.0)
    det = viscd.Detector(backend)
    det.set_static(boxes=static)
    assert det.static_kind == "box"
    frame = det.detect(boxes=moving)
    expected = expected_with_static(brute_box_pairs(moving), box_matrix(moving, static), np.arange(40))
    np.testing.assert_array_equal(frame.pairs, expected)


def test_add_move_remove_clear(backend):
    det = viscd.Detector(backend)
    moving = np.float32([[0, 0, 0, 1], [10, 0, 0, 1]])
    k0 = det.add_static_sphere((0, 1.5, 0, 1))
    k1 = det.add_static_sphere((50, 0, 0, 1))
    k2 = det.add_static_sphere((10, 0, 1.5, 1))
    assert (k0, k1, k2) == (0, 1, 2) and det.static_count == 3
    b = viscd.STATIC_BIT
    np.testing.assert_array_equal(det.detect(moving).pairs, [[0, 0 | b], [1, 2 | b]])
    det.move_static(k1, (0, -1.5, 0, 1))
    np.testing.assert_array_equal(det.detect(moving).pairs, [[0, 0 | b], [0, 1 | b], [1, 2 | b]])
    det.remove_static(k0)
    np.testing.assert_array_equal(det.detect(moving).pairs, [[0, 1 | b], [1, 2 | b]])
    assert det.add_static_sphere((100, 0, 0, 1)) == 0  # the smallest free slot
    with pytest.raises(ValueError, match="no object in slot"):
        det.remove_static(7)
    det.clear_static()
    assert det.static_count == 0
    assert det.detect(moving).pairs.shape == (0, 2)


def test_static_box_moves_and_filters():
    det = viscd.Detector()
    k = det.add_static_box((0, 0, 0, 1, 1, 1), filter=(2, 0xFFFFFFFF))
    moving = np.float32([[0, 0, 0, 1, 1, 1], [5, 5, 5, 6, 6, 6]])
    b = viscd.STATIC_BIT
    np.testing.assert_array_equal(det.detect(boxes=moving).pairs, [[0, k | b]])
    # A moving object whose mask leaves out group 2 no longer pairs with it.
    filters = np.uint32([[1, 1], [1, 0xFFFFFFFF]])
    assert det.detect(boxes=moving, filters=filters).pairs.shape == (0, 2)
    det.move_static(k, (5.5, 5.5, 5.5, 7, 7, 7))
    np.testing.assert_array_equal(det.detect(boxes=moving).pairs, [[1, k | b]])
    det.set_static(boxes=np.float32([[0, 0, 0, 1, 1, 1]]), filters=np.uint32([[4, 4]]))
    assert det.detect(boxes=moving).pairs.shape == (0, 2)  # group 4 vs masks ~0 / group 1 vs mask 4


def test_queries_see_static_objects():
    det = viscd.Detector()
    det.set_static(np.float32([[20, 0, 0, 1]]))
    det.detect(np.float32([[0, 0, 0, 1]]))
    idx, t = det.ray_cast_all((-5, 0, 0), (1, 0, 0))
    np.testing.assert_array_equal(idx, [0, viscd.static_index(0)])
    np.testing.assert_array_equal(det.overlap(sphere=(20, 0, 0, 0.5)), [viscd.static_index(0)])


def test_static_objects_never_culled_but_culled_moving_ones_do_not_pair():
    det = viscd.Detector(lambda_=50)
    cam = viscd.Camera((0, 0, 20), (0, 0, 0), width=320, height=240)
    det.set_static(np.float32([[0, 0, -400, 1], [0, 0, 0, 3]]))
    frame = det.detect(np.float32([[0, 0, -400, 0.05], [1, 0, 0, 3]]), camera=cam)
    np.testing.assert_array_equal(frame.state, [0, 2])
    np.testing.assert_array_equal(frame.pairs, [[1, viscd.static_index(1)]])
