#include "input_arrays.hpp"

#include <cstring>
#include <limits>
#include <string>
#include <vector>

namespace viscd::python {

namespace {

std::string shape_text(const py::array& a) {
  std::string s = "(";
  for (py::ssize_t k = 0; k < a.ndim(); ++k) {
    if (k) s += ", ";
    s += std::to_string(a.shape(k));
  }
  if (a.ndim() == 1) s += ",";
  return s + ")";
}

std::string dtype_text(const py::array& a) { return py::str(a.dtype()).cast<std::string>(); }

std::string type_text(py::handle obj) { return py::str(py::type::handle_of(obj).attr("__name__")).cast<std::string>(); }

// A DLPack producer (a torch, JAX or CuPy tensor...) as a NumPy view of its memory, without a
// copy; one on another device than the CPU is refused, naming the device type.
py::array from_dlpack(py::handle obj, const char* name) {
  if (py::hasattr(obj, "__dlpack_device__")) {
    const py::tuple device = obj.attr("__dlpack_device__")();
    const int type = device.size() > 0 ? device[0].cast<int>() : -1;
    if (type != 1)  // kDLCPU
      throw py::value_error(std::string(name) + ": a DLPack array on device type " + std::to_string(type) +
                            " (1 is the CPU); viscd reads host memory: copy it to the CPU first");
  }
  const py::module_ numpy = py::module_::import("numpy");
  try {
    return numpy.attr("from_dlpack")(obj);
  } catch (py::error_already_set& e) {
    throw py::value_error(std::string(name) + ": cannot read it through DLPack (" + e.what() + ")");
  }
}

// numpy.asarray(obj): the caller's array itself when it is one; anything with the buffer
// protocol or __array_interface__ is viewed where it lies (NumPy does that); a DLPack producer
// through numpy.from_dlpack.
py::array as_array(py::handle obj, const char* name) {
  if (py::isinstance<py::array>(obj)) return py::reinterpret_borrow<py::array>(obj);
  if (py::hasattr(obj, "__dlpack__") && !py::hasattr(obj, "__array_interface__") && !PyObject_CheckBuffer(obj.ptr()))
    return from_dlpack(obj, name);
  py::array a = py::array::ensure(obj);  // clears NumPy's error on failure and returns null
  if (!a) throw py::value_error(std::string(name) + ": expected an array of numbers, got " + type_text(obj));
  return a;
}

bool aligned(const void* p, std::size_t alignment) { return reinterpret_cast<std::uintptr_t>(p) % alignment == 0; }

// An (N, cols) array, or an empty 1-d one (N = 0). Returns N.
py::ssize_t row_count(const py::array& a, const char* name, py::ssize_t cols) {
  if (a.ndim() == 1 && a.size() == 0) return 0;
  if (a.ndim() != 2 || a.shape(1) != cols)
    throw py::value_error(std::string(name) + ": expected shape (N, " + std::to_string(cols) + "), got shape " +
                          shape_text(a));
  return a.shape(0);
}

// The array as C-contiguous, aligned, native float32: itself when it is one, else a converted copy.
py::array float32_array(const py::array& a, const char* name, bool& copied) {
  const char kind = a.dtype().kind();
  if (kind != 'f' && kind != 'i' && kind != 'u')
    throw py::value_error(std::string(name) + ": expected real numbers (float32 is read without a copy), got dtype " +
                          dtype_text(a));
  using Exact = py::array_t<float, py::array::c_style>;
  if (py::isinstance<Exact>(a) && aligned(a.data(), alignof(float))) {
    copied = false;
    return a;
  }
  copied = true;
  auto f = py::array_t<float, py::array::c_style | py::array::forcecast>::ensure(a);
  if (!f) throw py::value_error(std::string(name) + ": cannot convert dtype " + dtype_text(a) + " to float32");
  if (!aligned(f.data(), alignof(float))) {  // a view at an odd offset into a byte buffer
    py::array_t<float> fresh(std::vector<py::ssize_t>(f.shape(), f.shape() + f.ndim()));
    std::memcpy(fresh.mutable_data(), f.data(), static_cast<std::size_t>(f.nbytes()));
    return fresh;
  }
  return f;
}

// The array as C-contiguous, aligned, native uint32: itself when it is one, else a copy after
// checking that every value fits (a negative group or a value above 2^32 - 1 is an error, not
// a wrap-around).
py::array uint32_array(const py::array& a, const char* name, bool& copied) {
  const char kind = a.dtype().kind();
  if (kind != 'u' && kind != 'i')
    throw py::value_error(std::string(name) + ": expected integers (uint32 is read without a copy), got dtype " +
                          dtype_text(a));
  using Exact = py::array_t<std::uint32_t, py::array::c_style>;
  if (py::isinstance<Exact>(a) && aligned(a.data(), alignof(std::uint32_t))) {
    copied = false;
    return a;
  }
  copied = true;
  py::array_t<std::uint32_t> out(std::vector<py::ssize_t>(a.shape(), a.shape() + a.ndim()));
  std::uint32_t* dst = out.mutable_data();
  const auto bad = [&](py::ssize_t k, const std::string& value) {
    throw py::value_error(std::string(name) + ": value " + value + " at flat index " + std::to_string(k) +
                          " does not fit uint32 [0, 4294967295]");
  };
  if (kind == 'u') {
    auto u = py::array_t<std::uint64_t, py::array::c_style | py::array::forcecast>::ensure(a);
    if (!u) throw py::value_error(std::string(name) + ": cannot convert dtype " + dtype_text(a) + " to uint32");
    const std::uint64_t* src = u.data();
    for (py::ssize_t k = 0; k < u.size(); ++k) {
      if (src[k] > std::numeric_limits<std::uint32_t>::max()) bad(k, std::to_string(src[k]));
      dst[k] = static_cast<std::uint32_t>(src[k]);
    }
  } else {
    auto s = py::array_t<std::int64_t, py::array::c_style | py::array::forcecast>::ensure(a);
    if (!s) throw py::value_error(std::string(name) + ": cannot convert dtype " + dtype_text(a) + " to uint32");
    const std::int64_t* src = s.data();
    for (py::ssize_t k = 0; k < s.size(); ++k) {
      if (src[k] < 0 || src[k] > std::int64_t{std::numeric_limits<std::uint32_t>::max()})
        bad(k, std::to_string(src[k]));
      dst[k] = static_cast<std::uint32_t>(src[k]);
    }
  }
  return out;
}

template <class T>
InputSpan<T> float_rows(py::handle obj, const char* name, py::ssize_t cols) {
  static_assert(sizeof(T) == sizeof(float) * 6 || sizeof(T) == sizeof(float) * 4);
  const py::array a = as_array(obj, name);
  const py::ssize_t n = row_count(a, name, cols);
  InputSpan<T> in;
  const py::array f = float32_array(a, name, in.copied);
  in.owner = f;
  // A row of `cols` float32 is laid out as T (types.hpp asserts the sizes); the memory is NumPy's.
  in.span = {reinterpret_cast<const T*>(f.data()), static_cast<std::size_t>(n)};
  return in;
}

}  // namespace

InputSpan<Sphere> sphere_rows(py::handle obj, const char* name) { return float_rows<Sphere>(obj, name, 4); }

InputSpan<Box> box_rows(py::handle obj, const char* name) { return float_rows<Box>(obj, name, 6); }

InputSpan<Filter> filter_rows(py::handle obj, const char* name) {
  const py::array a = as_array(obj, name);
  const py::ssize_t n = row_count(a, name, 2);
  InputSpan<Filter> in;
  const py::array u = uint32_array(a, name, in.copied);
  in.owner = u;
  in.span = {reinterpret_cast<const Filter*>(u.data()), static_cast<std::size_t>(n)};
  return in;
}

InputSpan<std::uint32_t> id_map_pixels(py::handle obj, const char* name, int& width, int& height) {
  const py::array a = as_array(obj, name);
  if (a.ndim() != 2) throw py::value_error(std::string(name) + ": expected shape (H, W), got shape " + shape_text(a));
  constexpr py::ssize_t kMax = std::numeric_limits<int>::max();
  if (a.shape(0) > kMax || a.shape(1) > kMax)
    throw py::value_error(std::string(name) + ": shape " + shape_text(a) + " is too large");
  InputSpan<std::uint32_t> in;
  const py::array u = uint32_array(a, name, in.copied);
  in.owner = u;
  in.span = {static_cast<const std::uint32_t*>(u.data()), static_cast<std::size_t>(u.size())};
  height = static_cast<int>(a.shape(0));
  width = static_cast<int>(a.shape(1));
  return in;
}

InputSpan<std::uint32_t> index_values(py::handle obj, const char* name) {
  const py::array a = as_array(obj, name);
  if (a.ndim() != 1) throw py::value_error(std::string(name) + ": expected shape (M,), got shape " + shape_text(a));
  InputSpan<std::uint32_t> in;
  const py::array u = a.size() == 0 ? py::array_t<std::uint32_t>(0) : uint32_array(a, name, in.copied);
  in.owner = u;
  in.span = {static_cast<const std::uint32_t*>(u.data()), static_cast<std::size_t>(u.size())};
  return in;
}

InputSpan<std::uint8_t> flag_values(py::handle obj, const char* name) {
  py::array a = as_array(obj, name);
  if (a.ndim() != 1) throw py::value_error(std::string(name) + ": expected shape (N,), got shape " + shape_text(a));
  const char kind = a.dtype().kind();
  InputSpan<std::uint8_t> in;
  const bool bytes = kind == 'b' || (kind == 'u' && a.dtype().itemsize() == 1);
  if (bytes && (a.flags() & py::array::c_style) != 0) {
    in.owner = a;  // NumPy's bool is one byte holding 0 or 1
  } else if (kind == 'b' || kind == 'u' || kind == 'i' || kind == 'f') {
    in.copied = true;
    py::object numpy = py::module_::import("numpy");
    in.owner = numpy.attr("ascontiguousarray")(numpy.attr("not_equal")(a, 0));
    a = py::reinterpret_borrow<py::array>(in.owner);
  } else {
    throw py::value_error(std::string(name) + ": expected bool or uint8 values, got dtype " + dtype_text(a));
  }
  in.span = {static_cast<const std::uint8_t*>(a.data()), static_cast<std::size_t>(a.size())};
  return in;
}

template <std::size_t n>
std::array<float, n> float_values(py::handle obj, const char* name) {
  const py::array a = as_array(obj, name);
  const char kind = a.dtype().kind();
  if (a.ndim() != 1 || a.size() != static_cast<py::ssize_t>(n) || (kind != 'f' && kind != 'i' && kind != 'u'))
    throw py::value_error(std::string(name) + ": expected " + std::to_string(n) + " numbers, got " +
                          py::str(py::repr(obj)).cast<std::string>());
  auto d = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(a);
  if (!d) throw py::value_error(std::string(name) + ": expected " + std::to_string(n) + " numbers");
  std::array<float, n> out{};
  for (std::size_t k = 0; k < n; ++k) out[k] = static_cast<float>(d.data()[k]);
  return out;
}
template std::array<float, 3> float_values<3>(py::handle, const char*);
template std::array<float, 4> float_values<4>(py::handle, const char*);
template std::array<float, 6> float_values<6>(py::handle, const char*);

long long integer_value(py::handle obj, const char* name, long long lo, long long hi) {
  // operator.index(): Python and NumPy integers, not floats or bools.
  if (PyBool_Check(obj.ptr()) || !PyIndex_Check(obj.ptr()))
    throw py::value_error(std::string(name) + ": expected an integer, got " + type_text(obj));
  const py::object index = py::reinterpret_steal<py::object>(PyNumber_Index(obj.ptr()));
  if (!index) throw py::error_already_set();
  int overflow = 0;
  const long long v = PyLong_AsLongLongAndOverflow(index.ptr(), &overflow);
  if (overflow != 0 || v < lo || v > hi)
    throw py::value_error(std::string(name) + ": " + py::str(index).cast<std::string>() + " is out of range [" +
                          std::to_string(lo) + ", " + std::to_string(hi) + "]");
  return v;
}

Filter filter_value(py::handle obj, const char* name) {
  constexpr long long kMax = std::numeric_limits<std::uint32_t>::max();
  if (!py::isinstance<py::sequence>(obj) || py::isinstance<py::str>(obj) || py::len(obj) != 2)
    throw py::value_error(std::string(name) + ": expected (group, mask), two integers, got " +
                          py::str(py::repr(obj)).cast<std::string>());
  const py::sequence s = py::reinterpret_borrow<py::sequence>(obj);
  Filter f;
  f.group = static_cast<std::uint32_t>(integer_value(s[0], name, 0, kMax));
  f.mask = static_cast<std::uint32_t>(integer_value(s[1], name, 0, kMax));
  return f;
}

}  // namespace viscd::python
