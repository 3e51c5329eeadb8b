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
    "static_index",
    "static_slot",
]


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
