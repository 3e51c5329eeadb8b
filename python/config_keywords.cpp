#include "config_keywords.hpp"

#include <cmath>
#include <functional>
#include <limits>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "input_arrays.hpp"

namespace viscd::python {

namespace {

std::string repr_text(py::handle v) { return py::repr(v).cast<std::string>(); }

bool bool_value(py::handle v, const std::string& key) {
  // Python's bool and NumPy's bool_ (whose type is named "bool_", or "bool" in NumPy 2).
  if (PyBool_Check(v.ptr())) return v.ptr() == Py_True;
  const std::string type = py::type::handle_of(v).attr("__name__").cast<std::string>();
  if ((type == "bool_" || type == "bool") && py::hasattr(v, "dtype")) return v.cast<bool>();
  throw py::value_error("Detector: " + key + " must be True or False, got " + repr_text(v));
}

float float_value(py::handle v, const std::string& key) {
  if (PyBool_Check(v.ptr()) || !(PyFloat_Check(v.ptr()) || PyIndex_Check(v.ptr()) || py::hasattr(v, "__float__")))
    throw py::value_error("Detector: " + key + " must be a number, got " + repr_text(v));
  const double d = py::float_(py::reinterpret_borrow<py::object>(v)).cast<double>();
  if (std::isnan(d)) throw py::value_error("Detector: " + key + " must not be NaN");
  return static_cast<float>(d);
}

long long int_value(py::handle v, const std::string& key, long long lo, long long hi) {
  const std::string name = "Detector: " + key;
  return integer_value(v, name.c_str(), lo, hi);
}

// One of `names`, as a string; returns its position.
std::size_t choice_value(py::handle v, const std::string& key, const std::vector<std::string_view>& names) {
  std::string expected;
  for (std::string_view n : names) expected += (expected.empty() ? "" : ", ") + ("'" + std::string(n) + "'");
  if (py::isinstance<py::str>(v)) {
    const std::string s = v.cast<std::string>();
    for (std::size_t k = 0; k < names.size(); ++k)
      if (s == names[k]) return k;
  }
  throw py::value_error("Detector: " + key + " must be one of " + expected + ", got " + repr_text(v));
}

Bits bits_value(py::handle v, const std::string& key) {
  if (!py::isinstance<py::str>(v) && !PyBool_Check(v.ptr()) && PyIndex_Check(v.ptr())) {
    const long long b = py::reinterpret_steal<py::int_>(PyNumber_Index(v.ptr())).cast<long long>();
    if (b == 16) return Bits::b16;
    if (b == 32) return Bits::b32;
    if (b == 64) return Bits::b64;
    throw py::value_error("Detector: " + key + " must be 'adaptive', 16, 32 or 64, got " + repr_text(v));
  }
  static constexpr Bits kBits[] = {Bits::adaptive, Bits::b16, Bits::b32, Bits::b64};
  try {
    return kBits[choice_value(v, key, {"adaptive", "16", "32", "64"})];
  } catch (const py::value_error&) {
    throw py::value_error("Detector: " + key + " must be 'adaptive', 16, 32 or 64, got " + repr_text(v));
  }
}

struct Keyword {
  std::string_view name;
  bool gl;
  std::function<void(py::handle, const std::string&, Config&, GlOptions&)> set;
};

const std::vector<Keyword>& keywords() {
  constexpr long long kIntMax = std::numeric_limits<int>::max();
  static const std::vector<Keyword> table = {
      {"lambda_", false,
       [](py::handle v, const std::string& k, Config& c, GlOptions&) { c.lambda = float_value(v, k); }},
      {"pixels_for_32_bits", false,
       [](py::handle v, const std::string& k, Config& c, GlOptions&) { c.pixels_for_32_bits = float_value(v, k); }},
      {"pixels_for_64_bits", false,
       [](py::handle v, const std::string& k, Config& c, GlOptions&) { c.pixels_for_64_bits = float_value(v, k); }},
      {"bits", false, [](py::handle v, const std::string& k, Config& c, GlOptions&) { c.bits = bits_value(v, k); }},
      {"layout", false,
       [](py::handle v, const std::string& k, Config& c, GlOptions&) {
         c.layout = choice_value(v, k, {"extended", "plain"}) == 0 ? Layout::extended : Layout::plain;
       }},
      {"culling", false,
       [](py::handle v, const std::string& k, Config& c, GlOptions&) { c.culling = bool_value(v, k); }},
      {"map_width", false,
       [=](py::handle v, const std::string& k, Config& c, GlOptions&) {
         c.map_width = static_cast<int>(int_value(v, k, 0, kIntMax));
       }},
      {"map_height", false,
       [=](py::handle v, const std::string& k, Config& c, GlOptions&) {
         c.map_height = static_cast<int>(int_value(v, k, 0, kIntMax));
       }},
      {"shade", false, [](py::handle v, const std::string& k, Config& c, GlOptions&) { c.shade = bool_value(v, k); }},
      {"report_pixels", false,
       [](py::handle v, const std::string& k, Config& c, GlOptions&) { c.report_pixels = bool_value(v, k); }},
      {"contact_events", false,
       [](py::handle v, const std::string& k, Config& c, GlOptions&) { c.contact_events = bool_value(v, k); }},
      {"pair_memory_cap", false,
       [](py::handle v, const std::string& k, Config& c, GlOptions&) {
         c.pair_memory_cap = static_cast<std::size_t>(int_value(v, k, 0, std::numeric_limits<long long>::max()));
       }},
      {"threads", false,
       [=](py::handle v, const std::string& k, Config& c, GlOptions&) {
         c.threads = static_cast<int>(int_value(v, k, 0, kIntMax));
       }},
      {"keep_order", false,
       [](py::handle v, const std::string& k, Config& c, GlOptions&) { c.keep_order = bool_value(v, k); }},
      {"follow_change", false,
       [](py::handle v, const std::string& k, Config& c, GlOptions&) { c.follow_change = bool_value(v, k); }},
      {"rest_margin", false,
       [](py::handle v, const std::string& k, Config& c, GlOptions&) { c.rest_margin = float_value(v, k); }},
      {"simd", false,
       [](py::handle v, const std::string& k, Config& c, GlOptions&) {
         static constexpr Simd kSimd[] = {Simd::best, Simd::sse2, Simd::scalar};
         c.simd = kSimd[choice_value(v, k, {"best", "sse2", "scalar"})];
       }},
      {"gl_geometry", true,
       [](py::handle v, const std::string& k, Config&, GlOptions& g) {
         const std::size_t choice = choice_value(v, k, {"impostor", "mesh", "splat"});
         g.geometry = choice == 0 ? GlGeometry::impostor : choice == 1 ? GlGeometry::mesh : GlGeometry::splat;
       }},
      {"gl_counter", true,
       [](py::handle v, const std::string& k, Config&, GlOptions& g) {
         g.counter = choice_value(v, k, {"ssbo", "atomic_uint"}) == 0 ? GlCounter::ssbo : GlCounter::atomic_uint;
       }},
      {"gl_debug", true, [](py::handle v, const std::string& k, Config&, GlOptions& g) { g.debug = bool_value(v, k); }},
      {"gl_initial_pair_capacity", true,
       [](py::handle v, const std::string& k, Config&, GlOptions& g) {
         g.initial_pair_capacity =
             static_cast<std::uint32_t>(int_value(v, k, 1, std::numeric_limits<std::uint32_t>::max()));
       }},
      {"gl_sync_layout", true,
       [](py::handle v, const std::string& k, Config&, GlOptions& g) { g.sync_layout = bool_value(v, k); }},
  };
  return table;
}

}  // namespace

void apply_keywords(const py::kwargs& given, Config& config, GlOptions& gl, bool& gl_given) {
  Config c = config;
  GlOptions g = gl;
  bool any_gl = false;
  for (const auto& [key_obj, value] : given) {
    std::string key = key_obj.cast<std::string>();
    if (key == "lambda") key = "lambda_";  // Detector(**{"lambda": 50}); `lambda` is a Python keyword
    const Keyword* found = nullptr;
    for (const Keyword& k : keywords())
      if (k.name == key) found = &k;
    if (!found) {
      std::string names;
      for (const Keyword& k : keywords()) names += (names.empty() ? "" : ", ") + std::string(k.name);
      throw py::type_error("Detector: unexpected keyword argument '" + key + "' (the keywords are " + names + ")");
    }
    found->set(value, key, c, g);
    any_gl = any_gl || found->gl;
  }
  if ((c.map_width == 0) != (c.map_height == 0))
    throw py::value_error(
        "Detector: map_width and map_height must both be 0 (the screen's size) or both positive, got " +
        std::to_string(c.map_width) + " x " + std::to_string(c.map_height));
  config = c;
  gl = g;
  gl_given = gl_given || any_gl;
}

py::dict config_dict(const Config& c) {
  py::dict d;
  d["lambda_"] = c.lambda;
  d["pixels_for_32_bits"] = c.pixels_for_32_bits;
  d["pixels_for_64_bits"] = c.pixels_for_64_bits;
  if (c.bits == Bits::adaptive)
    d["bits"] = "adaptive";
  else
    d["bits"] = static_cast<int>(c.bits);
  d["layout"] = c.layout == Layout::extended ? "extended" : "plain";
  d["culling"] = c.culling;
  d["map_width"] = c.map_width;
  d["map_height"] = c.map_height;
  d["shade"] = c.shade;
  d["report_pixels"] = c.report_pixels;
  d["contact_events"] = c.contact_events;
  d["pair_memory_cap"] = c.pair_memory_cap;
  d["threads"] = c.threads;
  d["keep_order"] = c.keep_order;
  d["follow_change"] = c.follow_change;
  d["rest_margin"] = c.rest_margin;
  d["simd"] = c.simd == Simd::best ? "best" : c.simd == Simd::sse2 ? "sse2" : "scalar";
  return d;
}

const char* keywords_doc() {
  return R"(Keywords (viscd::Config; every one optional, defaults are the paper's setup):
    lambda_: float = 200.0        culling threshold in screen pixels (also "lambda" via **dict)
    pixels_for_32_bits: float = 100.0   adaptive Morton width: m = 16 below this mean pixel count,
    pixels_for_64_bits: float = 400.0   32 below this one, else 64
    bits: "adaptive" | 16 | 32 | 64 = "adaptive"   Morton code width (pairs are exact for each)
    layout: "extended" | "plain" = "extended"      Morton bit layout over the axes
    culling: bool = True          cull objects below lambda_ pixels (with a camera or an id map)
    map_width: int = 0, map_height: int = 0        visibility map size; 0 x 0 = the camera's screen
    shade: bool = False           produce Frame.image (needs a camera)
    report_pixels: bool = False   count pixels (Frame.pixels) even when no stage needs them
    contact_events: bool = False  fill Frame.began / Frame.ended
    pair_memory_cap: int = 0      bytes pairs may take (8 per pair); 0 = no cap; beyond: PairCapError
    threads: int = 0              cpu worker threads; 0 = all hardware threads, 1 = serial
    keep_order: bool = True       cpu: keep the last frame's object order while it stays good
    follow_change: bool = True    cpu: keep resting objects in trees across frames (cost follows change)
    rest_margin: float = 0.0      cpu: how far an object may stray and still rest (0: bit for bit)
    simd: "best" | "sse2" | "scalar" = "best"      widest SIMD kernels the cpu backend may use
  backend="gl" only (viscd::GlOptions):
    gl_geometry: "impostor" | "mesh" | "splat" = "impostor", gl_counter: "ssbo" | "atomic_uint" = "ssbo",
    gl_debug: bool = False, gl_initial_pair_capacity: int = 65536, gl_sync_layout: bool = False
An unknown keyword raises TypeError; a bad value raises ValueError.)";
}

}  // namespace viscd::python
