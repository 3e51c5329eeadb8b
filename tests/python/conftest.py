"""Shared helpers for the viscd Python tests: NumPy brute-force oracles and backends.

Run with the build tree's package on PYTHONPATH (ctest does: tests/python is registered as the
test python.pytest):  PYTHONPATH=build/release/python python3 -m pytest tests/python
"""

import functools

import numpy as np
import pytest

import viscd

EMPTY_PAIRS = np.zeros((0, 2), np.uint32)


def pairs_from_matrix(overlaps):
    """(i, j) with i < j where the boolean matrix is true, sorted (row-major order)."""
    i, j = np.nonzero(np.triu(overlaps, 1))
    return np.stack([i, j], axis=1).astype(np.uint32) if len(i) else EMPTY_PAIRS


def sphere_matrix(a, b):
    """viscd's sphere test, bit for bit: float32, no FMA, ((dx^2 + dy^2) + dz^2) <= (ra + rb)^2."""
    a = np.asarray(a, np.float32)
    b = np.asarray(b, np.float32)
    with np.errstate(over="ignore", under="ignore"):
        dx = a[:, None, 0] - b[None, :, 0]
        dy = a[:, None, 1] - b[None, :, 1]
        dz = a[:, None, 2] - b[None, :, 2]
        s = a[:, None, 3] + b[None, :, 3]
        return dx * dx + dy * dy + dz * dz <= s * s


def box_matrix(a, b):
    """viscd's box test: closed boxes, min_a <= max_b and min_b <= max_a on every axis."""
    a = np.asarray(a, np.float32)
    b = np.asarray(b, np.float32)
    ok = np.ones((len(a), len(b)), bool)
    for k in range(3):
        ok &= (a[:, None, k] <= b[None, :, 3 + k]) & (b[None, :, k] <= a[:, None, 3 + k])
    return ok


def brute_sphere_pairs(spheres):
    spheres = np.asarray(spheres, np.float32).reshape(-1, 4)
    return pairs_from_matrix(sphere_matrix(spheres, spheres))


def brute_box_pairs(boxes):
    boxes = np.asarray(boxes, np.float32).reshape(-1, 6)
    return pairs_from_matrix(box_matrix(boxes, boxes))


def random_spheres(rng, n, extent=100.0, r_min=0.2, r_max=3.0):
    s = np.empty((n, 4), np.float32)
    s[:, :3] = rng.uniform(-extent, extent, (n, 3))
    s[:, 3] = rng.uniform(r_min, r_max, n)
    return s


def random_boxes(rng, n, extent=100.0, size_max=6.0):
    lo = rng.uniform(-extent, extent, (n, 3)).astype(np.float32)
    hi = lo + rng.uniform(0.0, size_max, (n, 3)).astype(np.float32)
    return np.concatenate([lo, hi], axis=1).astype(np.float32)


@functools.lru_cache(maxsize=None)
def gl_available():
    try:
        viscd.Detector("gl")
        return True
    except Exception:  # no OpenGL 4.5 context here
        return False


CPU_BACKENDS = ["reference", "cpu"]


@pytest.fixture(params=CPU_BACKENDS)
def backend(request):
    return request.param


@pytest.fixture
def rng():
    return np.random.default_rng(12345)
