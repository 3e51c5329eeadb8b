#include "config_keywords.hpp"

#include <cmath>
#include <functional>
#include <limits>
#include <string>
#include <string_view>
#include <type_traits>
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
    PyObject* index = PyNumber_Index(v.ptr());  // new reference, or null with an exception set
    if (index == nullptr) throw py::error_already_set();
    const long long b = py::reinterpret_steal<py::int_>(index).cast<long long>();
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

// One keyword: the one place that names it. Its setter, its value for Detector.config (the gl
// ones are not in it), and its line in the docstring; the type stub (__init__.pyi) is checked
// against this table by a test (tests/python/test_threads_and_docs.py), through _keyword_table().
struct Keyword {
  std::string_view name;
  bool gl;
  std::string_view type;          // as the stub writes it
  std::string_view default_text;  // a Python literal
  std::string_view help;
  std::function<void(py::handle, const std::string&, Config&, GlOptions&)> set;
  std::function<py::object(const Config&, const GlOptions&)> get;
};

// Keywords that are one field of Config or GlOptions, of a plain type.
template <class Options, class Field>
Keyword field_keyword(std::string_view name, std::string_view type, std::string_view default_text,
                      std::string_view help, Field Options::*field, long long lo = 0,
                      long long hi = std::numeric_limits<int>::max()) {
  constexpr bool gl = std::is_same_v<Options, GlOptions>;
  auto set = [=](py::handle v, const std::string& k, Config& c, GlOptions& g) {
    Options& o = [&]() -> Options& {
      if constexpr (gl)
        return g;
      else
        return c;
    }();
    if constexpr (std::is_same_v<Field, bool>)
      o.*field = bool_value(v, k);
    else if constexpr (std::is_same_v<Field, float>)
      o.*field = float_value(v, k);
    else
      o.*field = static_cast<Field>(int_value(v, k, lo, hi));
  };
  auto get = [=](const Config& c, const GlOptions& g) -> py::object {
    if constexpr (gl)
      return py::cast(g.*field);
    else
      return py::cast(c.*field);
  };
  return {name, gl, type, default_text, help, set, get};
}

const std::vector<Keyword>& keywords() {
  using C = const Config&;
  using G = const GlOptions&;
  static const std::vector<Keyword> table = {
      field_keyword("lambda_", "float", "200.0", "culling threshold in screen pixels (also \"lambda\" via **dict)",
                    &Config::lambda),
      field_keyword("pixels_for_32_bits", "float", "100.0",
                    "adaptive Morton width: m = 16 below this mean pixel count,", &Config::pixels_for_32_bits),
      field_keyword("pixels_for_64_bits", "float", "400.0", "32 below this one, else 64", &Config::pixels_for_64_bits),
      {"bits", false, "\"adaptive\" | 16 | 32 | 64", "\"adaptive\"", "Morton code width (pairs are exact for each)",
       [](py::handle v, const std::string& k, Config& c, GlOptions&) { c.bits = bits_value(v, k); },
       [](C c, G) -> py::object {
         if (c.bits == Bits::adaptive) return py::str("adaptive");
         return py::int_(static_cast<int>(c.bits));
       }},
      {"layout", false, "\"extended\" | \"plain\"", "\"extended\"", "Morton bit layout over the axes",
       [](py::handle v, const std::string& k, Config& c, GlOptions&) {
         c.layout = choice_value(v, k, {"extended", "plain"}) == 0 ? Layout::extended : Layout::plain;
       },
       [](C c, G) { return py::str(c.layout == Layout::extended ? "extended" : "plain"); }},
      field_keyword("culling", "bool", "True", "cull objects below lambda_ pixels (with a camera or an id map)",
                    &Config::culling),
      field_keyword("map_width", "int", "0", "visibility map width; 0 x 0 = the camera's screen", &Config::map_width),
      field_keyword("map_height", "int", "0", "visibility map height", &Config::map_height),
      field_keyword("shade", "bool", "False", "produce Frame.image (needs a camera)", &Config::shade),
      field_keyword("report_pixels", "bool", "False", "count pixels (Frame.pixels) even when no stage needs them",
                    &Config::report_pixels),
      field_keyword("contact_events", "bool", "False", "fill Frame.began / Frame.ended", &Config::contact_events),
      field_keyword("pair_memory_cap", "int", "0",
                    "bytes pairs may take (8 per pair); 0 = no cap; beyond: PairCapError", &Config::pair_memory_cap, 0,
                    std::numeric_limits<long long>::max()),
      field_keyword("threads", "int", "0", "cpu worker threads; 0 = all hardware threads, 1 = serial",
                    &Config::threads),
      field_keyword("keep_order", "bool", "True", "cpu: keep the last frame's object order while it stays good",
                    &Config::keep_order),
      field_keyword("follow_change", "bool", "True",
                    "cpu: keep resting objects in trees across frames (cost follows change)", &Config::follow_change),
      field_keyword("rest_margin", "float", "0.0", "cpu: how far an object may stray and still rest (0: bit for bit)",
                    &Config::rest_margin),
      field_keyword("move_margin", "float", "8.0",
                    "cpu: margins of their own for moving objects, in moves (0: placed again every change)",
                    &Config::move_margin),
      {"simd", false, "\"best\" | \"sse2\" | \"scalar\"", "\"best\"", "widest SIMD kernels the cpu backend may use",
       [](py::handle v, const std::string& k, Config& c, GlOptions&) {
         static constexpr Simd kSimd[] = {Simd::best, Simd::sse2, Simd::scalar};
         c.simd = kSimd[choice_value(v, k, {"best", "sse2", "scalar"})];
       },
       [](C c, G) {
         return py::str(c.simd == Simd::best ? "best" : c.simd == Simd::sse2 ? "sse2" : "scalar");
       }},
      {"gl_geometry", true, "\"impostor\" | \"mesh\" | \"splat\"", "\"impostor\"", "how spheres are drawn into the map",
       [](py::handle v, const std::string& k, Config&, GlOptions& g) {
         const std::size_t choice = choice_value(v, k, {"impostor", "mesh", "splat"});
         g.geometry = choice == 0 ? GlGeometry::impostor : choice == 1 ? GlGeometry::mesh : GlGeometry::splat;
       },
       [](C, G g) {
         return py::str(g.geometry == GlGeometry::impostor ? "impostor"
                        : g.geometry == GlGeometry::mesh   ? "mesh"
                                                           : "splat");
       }},
      {"gl_counter", true, "\"ssbo\" | \"atomic_uint\"", "\"ssbo\"", "how pixels are counted",
       [](py::handle v, const std::string& k, Config&, GlOptions& g) {
         g.counter = choice_value(v, k, {"ssbo", "atomic_uint"}) == 0 ? GlCounter::ssbo : GlCounter::atomic_uint;
       },
       [](C, G g) { return py::str(g.counter == GlCounter::ssbo ? "ssbo" : "atomic_uint"); }},
      field_keyword("gl_debug", "bool", "False", "a debug context: any GL error fails detect()", &GlOptions::debug),
      field_keyword("gl_initial_pair_capacity", "int", "65536", "pairs the pair buffer holds before it first grows",
                    &GlOptions::initial_pair_capacity, 1, std::numeric_limits<std::uint32_t>::max()),
      field_keyword("gl_sync_layout", "bool", "False", "m and the layout from this frame (one mid-frame readback)",
                    &GlOptions::sync_layout),
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
  for (const Keyword& k : keywords())
    if (!k.gl) d[py::str(std::string(k.name))] = k.get(c, GlOptions{});
  return d;
}

const char* keywords_doc() {
  static const std::string doc = [] {
    std::string out = "Keywords (viscd::Config; every one optional, defaults are the paper's setup):\n";
    bool gl_heading = false;
    for (const Keyword& k : keywords()) {
      if (k.gl && !gl_heading) {
        out += "  backend=\"gl\" only (viscd::GlOptions):\n";
        gl_heading = true;
      }
      std::string line =
          "    " + std::string(k.name) + ": " + std::string(k.type) + " = " + std::string(k.default_text);
      if (line.size() < 44) line.resize(44, ' ');
      out += line + "  " + std::string(k.help) + "\n";
    }
    out += "An unknown keyword raises TypeError; a bad value raises ValueError.";
    return out;
  }();
  return doc.c_str();
}

py::list keyword_table() {
  py::list out;
  for (const Keyword& k : keywords())
    out.append(py::make_tuple(std::string(k.name), k.gl, std::string(k.type), std::string(k.default_text)));
  return out;
}

}  // namespace viscd::python
