"""viscd: visibility-based collision detection for very many moving spheres or boxes.

NumPy in, NumPy out::

    import numpy as np, viscd
    det = viscd.Detector()                      # backend="cpu"; keywords: viscd.Config's fields
    spheres = np.random.rand(10000, 4).astype(np.float32)
    spheres[:, 3] *= 0.01                       # x, y, z, r per row
    frame = det.detect(spheres)
    frame.pairs                                 # (P, 2) uint32, sorted, i < j

See help(viscd.Detector), help(viscd.Detector.detect) and docs/python.md.
"""

from __future__ import annotations

import numpy as _np

from ._viscd import (
    MAX_COORDINATE,
    STATIC_BIT,
    BackendError,
    Camera,
    Detector,
    Frame,
    PairCapError,
    __version__,
)

__all__ = [
    "BackendError",
    "Camera",
    "Detector",
    "Frame",
    "MAX_COORDINATE",
    "PairCapError",
    "STATIC_BIT",
    "is_static",
    "pairs_within",
    "static_index",
    "static_slot",
]


def pairs_within(points, r, *, threads=0):
    """Every pair of points closer than r: viscd's counterpart of ``cKDTree(points).query_pairs(r)``.

    ``points``: (N, 3) or (N, 2) coordinates, any real dtype (converted to float32; 2-d points lie
    at z = 0). ``r``: a distance (pairs with |p_i - p_j| <= r), or (N,) radii, one per point
    (pairs with |p_i - p_j| <= r_i + r_j: spheres that touch). ``threads``: 0 for every core.

    Returns a (P, 2) uint32 array, i < j in each row, rows sorted by (i, j): the same set as
    ``cKDTree.query_pairs(r, output_type="ndarray")`` (whose rows come in no stated order, int64),
    decided in float32 as viscd decides: (dx^2 + dy^2 + dz^2) <= (r_i + r_j)^2 with each point a
    sphere of radius r/2 (or r_i), so a pair within a float32 rounding of the distance may differ
    from SciPy's float64 test. Raises ValueError for a bad shape, a NaN or infinite coordinate, or
    a negative or non-finite r.
    """
    pts = _np.asarray(points)
    if pts.ndim != 2 or pts.shape[1] not in (2, 3):
        raise ValueError(f"pairs_within: points must have shape (N, 3) or (N, 2), got {pts.shape}")
    if not (_np.issubdtype(pts.dtype, _np.floating) or _np.issubdtype(pts.dtype, _np.integer)):
        raise TypeError(f"pairs_within: points must be real numbers, got dtype {pts.dtype}")
    n = pts.shape[0]
    radii = _np.asarray(r)
    if not (_np.issubdtype(radii.dtype, _np.floating) or _np.issubdtype(radii.dtype, _np.integer)):
        raise TypeError(f"pairs_within: r must be a real number or (N,) real radii, got dtype {radii.dtype}")
    spheres = _np.zeros((n, 4), _np.float32)
    spheres[:, : pts.shape[1]] = pts
    if radii.ndim == 0:
        value = float(radii)
        if not _np.isfinite(value) or value < 0:
            raise ValueError(f"pairs_within: r must be finite and >= 0, got {value}")
        spheres[:, 3] = _np.float32(value) / _np.float32(2)
    elif radii.shape == (n,):
        spheres[:, 3] = radii
    else:
        raise ValueError(f"pairs_within: r must be a number or have shape ({n},), got shape {radii.shape}")
    detector = Detector("cpu", culling=False, bits=32, threads=threads, follow_change=False)
    return detector.detect(spheres).pairs


def is_static(index):
    """Whether reported indices (pairs, events, query results) name static objects.

    ``index``: an int or an array of uint32 indices. Returns a bool, or a bool array of the same
    shape: True where bit 31 (STATIC_BIT) is set. Example: ``frame.pairs[is_static(frame.pairs[:, 1])]``.
    """
    a = _np.asarray(index, dtype=_np.uint32)
    result = (a & _np.uint32(STATIC_BIT)) != 0
    return bool(result) if result.ndim == 0 else result


def static_slot(index):
    """The static set's slot k of reported static indices (clears bit 31); an int or a uint32 array."""
    a = _np.asarray(index, dtype=_np.uint32)
    result = a & _np.uint32(~STATIC_BIT & 0xFFFFFFFF)
    return int(result) if result.ndim == 0 else result


def static_index(k):
    """The index under which pairs and queries report static slot k: k | STATIC_BIT (int or uint32 array)."""
    a = _np.asarray(k, dtype=_np.uint32)
    result = a | _np.uint32(STATIC_BIT)
    return int(result) if result.ndim == 0 else result


def __getattr__(name):
    """``viscd.DistributedDetector`` (docs/mpi.md), loaded on first use so that ``import viscd``
    neither loads MPI nor starts it. Needs viscd built with MPI and mpi4py (Debian: libopenmpi-dev,
    python3-mpi4py)."""
    if name in ("DistributedDetector", "DistributedFrame"):
        try:
            from . import _viscd_mpi
        except ImportError as e:
            raise ImportError(
                "viscd.DistributedDetector needs viscd built with MPI and mpi4py (Debian: libopenmpi-dev, "
                f"python3-mpi4py; docs/mpi.md): {e}"
            ) from e
        return getattr(_viscd_mpi, name)
    raise AttributeError(f"module 'viscd' has no attribute {name!r}")
