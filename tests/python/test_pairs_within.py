"""viscd.pairs_within: cKDTree.query_pairs's set, sorted; the per-point radius form; bad input."""

import numpy as np
import pytest
from scipy.spatial import cKDTree

import viscd
from conftest import EMPTY_PAIRS, pairs_from_matrix, sphere_matrix


def kdtree_pairs(points, r):
    """SciPy's pairs (float64 distances) as viscd orders them: rows sorted by (i, j), uint32."""
    found = cKDTree(np.asarray(points, np.float64)).query_pairs(r, output_type="ndarray")
    if len(found) == 0:
        return EMPTY_PAIRS
    found = np.sort(found, axis=1)
    return found[np.lexsort((found[:, 1], found[:, 0]))].astype(np.uint32)


@pytest.mark.parametrize("dims", [3, 2])
@pytest.mark.parametrize("n", [0, 1, 2, 257, 3000])
def test_same_set_as_ckdtree(rng, dims, n):
    points = rng.uniform(0, 30, (n, dims)).astype(np.float32)
    got = viscd.pairs_within(points, 1.5)
    np.testing.assert_array_equal(got, kdtree_pairs(points, 1.5))
    assert got.dtype == np.uint32 and got.shape[1] == 2


def test_float64_and_integer_points_are_converted(rng):
    points = rng.uniform(0, 10, (500, 3))
    np.testing.assert_array_equal(viscd.pairs_within(points, 1.0), viscd.pairs_within(points.astype(np.float32), 1.0))
    grid = np.array([[x, y, 0] for x in range(10) for y in range(10)], np.int64)
    got = viscd.pairs_within(grid, 1)  # neighbours at distance exactly 1 count
    assert len(got) == 2 * 10 * 9
    np.testing.assert_array_equal(got, kdtree_pairs(grid, 1))


def test_per_point_radii_are_spheres(rng):
    points = rng.uniform(0, 20, (800, 3)).astype(np.float32)
    radii = rng.uniform(0.1, 1.0, 800).astype(np.float32)
    spheres = np.column_stack([points, radii]).astype(np.float32)
    np.testing.assert_array_equal(viscd.pairs_within(points, radii), pairs_from_matrix(sphere_matrix(spheres, spheres)))


def test_touching_and_coincident_points():
    np.testing.assert_array_equal(viscd.pairs_within([[0, 0, 0], [2, 0, 0]], 2.0), [[0, 1]])
    assert len(viscd.pairs_within([[0, 0, 0], [2.001, 0, 0]], 2.0)) == 0
    same = np.zeros((40, 3), np.float32)
    assert len(viscd.pairs_within(same, 0.0)) == 40 * 39 // 2


@pytest.mark.parametrize(
    "points, r, error",
    [
        (np.zeros((5, 4)), 1.0, ValueError),
        (np.zeros(5), 1.0, ValueError),
        (np.zeros((5, 3)), -1.0, ValueError),
        (np.zeros((5, 3)), float("nan"), ValueError),
        (np.zeros((5, 3)), np.ones(4), ValueError),
        (np.array([[0, 0, np.nan]] * 3), 1.0, ValueError),
        (np.array([["a", "b", "c"]]), 1.0, TypeError),
        (np.zeros((5, 3)), "wide", TypeError),
    ],
)
def test_bad_input_raises(points, r, error):
    with pytest.raises(error):
        viscd.pairs_within(points, r)
