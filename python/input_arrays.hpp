#pragma once
/// \file input_arrays.hpp
/// NumPy arrays (or anything numpy.asarray takes) as the spans viscd reads. An array already in
/// viscd's layout (C-contiguous, native byte order, aligned, the exact dtype) is read where it
/// lies, without a copy; any other real dtype or memory order is converted once (one copy of
/// the array, at NumPy's speed). Every shape or dtype error raises ValueError naming the
/// argument, the shape or dtype expected and the one given.

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <array>
#include <cstdint>
#include <span>

#include "viscd/types.hpp"

namespace viscd::python {

namespace py = pybind11;

/// The span viscd reads and the array that owns its memory: the caller's own array when it fit
/// (copied false) or the converted copy (copied true). Keep it alive while the span is used.
template <class T>
struct InputSpan {
  py::object owner;
  std::span<const T> span;
  bool copied = false;
};

/// (N, 4) spheres (x, y, z, r): float32 taken as is, other real dtypes converted. An empty
/// 1-d array (e.g. []) is N = 0.
[[nodiscard]] InputSpan<Sphere> sphere_rows(py::handle obj, const char* name);
/// (N, 6) boxes (min x, y, z, max x, y, z): float32 as is, other real dtypes converted.
[[nodiscard]] InputSpan<Box> box_rows(py::handle obj, const char* name);
/// (N, 2) filters (group, mask): uint32 as is; other integer dtypes converted when every value
/// lies in [0, 2^32 - 1].
[[nodiscard]] InputSpan<Filter> filter_rows(py::handle obj, const char* name);
/// (H, W) id map, object index + 1 per pixel (0 = background): uint32 as is, other integer
/// dtypes converted as for filters. Writes W and H.
[[nodiscard]] InputSpan<std::uint32_t> id_map_pixels(py::handle obj, const char* name, int& width, int& height);
/// (M,) object indices: uint32 as is, other integer dtypes converted when every value fits; an
/// empty array (any dtype) is M = 0.
[[nodiscard]] InputSpan<std::uint32_t> index_values(py::handle obj, const char* name);
/// (N,) flags: bool or uint8 as is; other real dtypes as value != 0.
[[nodiscard]] InputSpan<std::uint8_t> flag_values(py::handle obj, const char* name);

/// A sequence of `n` numbers (tuple, list, 1-d array) as floats, e.g. a camera's eye.
template <std::size_t n>
[[nodiscard]] std::array<float, n> float_values(py::handle obj, const char* name);
/// A Python integer (or NumPy integer) in [lo, hi]; anything else raises ValueError.
[[nodiscard]] long long integer_value(py::handle obj, const char* name, long long lo, long long hi);
/// (group, mask), two integers in [0, 2^32 - 1].
[[nodiscard]] Filter filter_value(py::handle obj, const char* name);

}  // namespace viscd::python
