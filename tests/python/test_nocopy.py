"""The no-copy paths, proved two ways.

Input: NumPy reports every array allocation to tracemalloc (numpy's data allocator calls
PyTraceMalloc_Track), so a conversion of the input shows up as a traced allocation as large as
the converted array, while viscd's own C++ buffers do not. A float32 C-contiguous frame must
trace (almost) nothing; a float64 one must trace at least the float32 copy. Frame.input_copied
says the same from inside the module.

Output: the Frame's arrays are views of the frame's own buffers: two reads of frame.pairs share
memory, and their base is the capsule that keeps the buffers alive, not an array that owns data.
"""

import tracemalloc

import numpy as np
import pytest

import viscd
from conftest import brute_sphere_pairs, random_spheres

N = 1_000_000
FLOAT32_BYTES = N * 4 * 4


def traced_peak_of(call):
    tracemalloc.start()
    try:
        tracemalloc.reset_peak()
        start, _ = tracemalloc.get_traced_memory()
        result = call()
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    return result, peak - start


def test_float32_input_is_not_copied(rng):
    spheres = random_spheres(rng, N, extent=1000.0, r_min=0.01, r_max=0.2)
    det = viscd.Detector()
    det.detect(spheres)  # warm: the detector's own buffers
    frame, peak = traced_peak_of(lambda: det.detect(spheres))
    assert not frame.input_copied
    assert peak < 64 * 1024, f"a float32 frame traced {peak} bytes of Python allocations"
    # The control: the same frame from float64 converts, and the conversion is seen.
    spheres64 = spheres.astype(np.float64)
    frame64, peak64 = traced_peak_of(lambda: det.detect(spheres64))
    assert frame64.input_copied
    assert peak64 >= FLOAT32_BYTES
    np.testing.assert_array_equal(frame.pairs, frame64.pairs)


def test_which_inputs_are_copied(rng):
    det = viscd.Detector()
    s = random_spheres(rng, 64)
    assert not det.detect(s).input_copied
    assert not det.detect(s[10:20]).input_copied  # a row slice is still C-contiguous
    assert det.detect(s[::2]).input_copied
    assert det.detect(np.asfortranarray(s)).input_copied
    assert det.detect(s.astype(">f4")).input_copied
    assert det.detect(s.astype(np.float64)).input_copied
    filters = np.ones((64, 2), np.uint32)
    assert not det.detect(s, filters=filters).input_copied
    assert det.detect(s, filters=filters.astype(np.int64)).input_copied
    assert not det.detect(s, always_active=np.ones(64, bool)).input_copied
    assert not det.detect(s, always_active=np.ones(64, np.uint8)).input_copied
    assert det.detect(s, always_active=np.ones(64, np.int32)).input_copied
    # A float32 view at an odd byte offset is copied into aligned memory, and still right.
    raw = np.zeros(64 * 16 + 1, np.uint8)
    odd = np.frombuffer(raw.data, np.float32, count=64 * 4, offset=1).reshape(64, 4)
    odd[:] = s
    assert det.detect(odd).input_copied
    np.testing.assert_array_equal(det.detect(odd).pairs, brute_sphere_pairs(s))


def test_output_arrays_are_views(rng):
    det = viscd.Detector()
    frame = det.detect(random_spheres(rng, 2000, extent=30.0))
    a, b = frame.pairs, frame.pairs
    assert len(a) > 0
    assert np.shares_memory(a, b)
    assert not a.flags.owndata and type(a.base).__name__ == "PyCapsule"
    assert not frame.state.flags.owndata


def test_a_held_frame_is_never_overwritten(rng):
    det = viscd.Detector()
    s1 = random_spheres(rng, 500, extent=15.0)
    s2 = random_spheres(rng, 500, extent=15.0)
    pairs1 = det.detect(s1).pairs  # the Frame is gone; its pairs array keeps its buffers
    frames = [det.detect(s2) for _ in range(3)]
    np.testing.assert_array_equal(pairs1, brute_sphere_pairs(s1))
    for f in frames:
        np.testing.assert_array_equal(f.pairs, brute_sphere_pairs(s2))


def test_a_released_frame_is_reused(rng):
    # Steady state: once Python holds nothing of a frame, the next frame writes into its
    # buffers (same address, no allocation).
    det = viscd.Detector()
    s = random_spheres(rng, 3000, extent=40.0)
    frame = det.detect(s)
    address = frame.pairs.__array_interface__["data"][0]
    del frame
    frame = det.detect(s)
    assert frame.pairs.__array_interface__["data"][0] == address
    # The loop `frame = det.detect(...)` holds the previous frame during the call: two buffers alternate.
    addresses = set()
    for _ in range(6):
        frame = det.detect(s)
        addresses.add(frame.pairs.__array_interface__["data"][0])
    assert len(addresses) <= 2


class _Interface:
    """Only __array_interface__, NumPy's array interface (as other array libraries export it)."""

    def __init__(self, a):
        self._a = a
        self.__array_interface__ = a.__array_interface__


class _DLPack:
    """Only the DLPack protocol, as a torch or JAX CPU tensor offers it."""

    def __init__(self, a, device=(1, 0)):
        self._a = a
        self._device = device

    def __dlpack__(self, stream=None):
        return self._a.__dlpack__()

    def __dlpack_device__(self):
        return self._device


def test_buffer_protocol_array_interface_and_dlpack_are_read_in_place(rng):
    spheres = random_spheres(rng, 3000, extent=40.0)
    want = brute_sphere_pairs(spheres)
    det = viscd.Detector()
    n = len(spheres)
    views = {
        "memoryview (buffer protocol)": memoryview(spheres.tobytes()).cast("B").cast("f", shape=[n, 4]),
        "__array_interface__": _Interface(spheres),
        "DLPack": _DLPack(spheres),
    }
    for what, view in views.items():
        frame = det.detect(view)
        np.testing.assert_array_equal(frame.pairs, want, err_msg=what)
        assert not frame.input_copied, what
    strided = np.asfortranarray(spheres)
    frame = det.detect(_DLPack(spheres.astype(np.float64)))
    np.testing.assert_array_equal(frame.pairs, want)
    assert frame.input_copied  # float64 is converted
    assert det.detect(strided).input_copied


def test_dlpack_on_another_device_is_refused(rng):
    spheres = random_spheres(rng, 10, extent=5.0)
    det = viscd.Detector()
    before = det.detect(spheres).pairs.copy()
    with pytest.raises(ValueError, match="device type 2"):
        det.detect(_DLPack(spheres, device=(2, 0)))
    np.testing.assert_array_equal(det.detect(spheres).pairs, before)
