// The extension module viscd._viscd (docs/python.md): Detector, Frame and Camera over the C++
// API. What crosses the boundary, and what it costs:
//  - inputs: an array already in viscd's layout (float32 (N, 4) spheres, (N, 6) boxes, uint32
//    filters and id maps, C-contiguous) is read where it lies (input_arrays.hpp); the frame runs
//    with the GIL released;
//  - outputs: Frame's arrays are views of a FrameResult the frame wrote, kept alive by the
//    arrays themselves (a capsule holding a shared_ptr), so nothing is copied; the Detector
//    reuses a FrameResult (and its buffers' capacity) once Python holds nothing of it.
// viscd's Status becomes an exception: invalid or unsupported input ValueError, pair_cap
// PairCapError, out_of_memory MemoryError, backend_failure BackendError.

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <array>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "busy_guard.hpp"
#include "config_keywords.hpp"
#include "input_arrays.hpp"
#include "viscd/viscd.hpp"

namespace py = pybind11;

namespace viscd::python {

namespace {

// The module's exception types (kept alive by the module's attributes; raw pointers, so that no
// destructor runs after the interpreter is gone).
PyObject* g_pair_cap_error = nullptr;  // viscd.PairCapError
PyObject* g_backend_error = nullptr;   // viscd.BackendError
struct PairCapTag {};
struct BackendTag {};

[[noreturn]] void raise_status(const Status& s) {
  PyObject* type = PyExc_ValueError;
  switch (s.kind()) {
    case ErrorKind::pair_cap:
      type = g_pair_cap_error;
      break;
    case ErrorKind::out_of_memory:
      type = PyExc_MemoryError;
      break;
    case ErrorKind::backend_failure:
    case ErrorKind::io_failure:
      type = g_backend_error;
      break;
    case ErrorKind::none:
    case ErrorKind::invalid_input:
    case ErrorKind::unsupported_input:
      break;
  }
  PyErr_SetString(type, s.error().c_str());
  throw py::error_already_set();
}

// An array over memory a FrameResult owns; the array keeps the FrameResult alive.
template <class T>
py::array result_view(const std::shared_ptr<FrameResult>& owner, const T* data, std::vector<py::ssize_t> shape) {
  if (data == nullptr) return py::array_t<T>(shape);  // an empty vector: a fresh empty array
  auto* keep = new std::shared_ptr<FrameResult>(owner);
  py::capsule base(keep, [](void* p) { delete static_cast<std::shared_ptr<FrameResult>*>(p); });
  return py::array_t<T>(shape, data, base);
}

py::array pair_view(const std::shared_ptr<FrameResult>& owner, const std::vector<Pair>& pairs) {
  static_assert(sizeof(Pair) == 2 * sizeof(std::uint32_t));
  return result_view(owner, pairs.empty() ? nullptr : &pairs.front().i,
                     {static_cast<py::ssize_t>(pairs.size()), py::ssize_t{2}});
}

// A copy of the pairs with (or without) a static object, as (i, j) or (i, static slot).
py::array pair_subset(const std::vector<Pair>& pairs, bool with_static) {
  std::size_t count = 0;
  for (const Pair& p : pairs) count += is_static_index(p.j) == with_static;
  py::array_t<std::uint32_t> out({static_cast<py::ssize_t>(count), py::ssize_t{2}});
  std::uint32_t* dst = out.mutable_data();
  for (const Pair& p : pairs) {
    if (is_static_index(p.j) != with_static) continue;
    *dst++ = p.i;
    *dst++ = with_static ? static_slot(p.j) : p.j;
  }
  return out;
}

py::dict stats_dict(const FrameStats& s, double detect_ms) {
  py::dict d;
  d["objects"] = s.objects;
  d["static_objects"] = s.static_objects;
  d["active"] = s.active;
  d["has_camera"] = s.has_camera;
  d["has_pixels"] = s.has_pixels;
  d["mean_pixels"] = s.mean_pixels;
  d["bits"] = s.bits;
  d["layout"] = format_layout(s.layout);
  d["layout_order"] = py::make_tuple(s.layout.order[0], s.layout.order[1], s.layout.order[2]);
  d["layout_axis_bits"] = py::make_tuple(s.layout.axis_bits[0], s.layout.axis_bits[1], s.layout.axis_bits[2]);
  d["pairs"] = s.pairs;
  d["order_kept"] = s.order_kept;
  d["followed_change"] = s.followed_change;
  d["moved"] = s.moved;
  d["replaced"] = s.replaced;
  py::dict stages;
  for (std::size_t k = 0; k < kStageCount; ++k) {
    const auto stage = static_cast<Stage>(k);
    stages[py::str(std::string(stage_name(stage)))] = s.ms(stage);
  }
  d["stage_ms"] = stages;
  d["total_ms"] = s.total_ms();
  d["detect_ms"] = detect_ms;
  return d;
}

/// One frame's results (Detector.detect()).
struct PyFrame {
  std::shared_ptr<FrameResult> result;
  bool input_copied = false;
  double detect_ms = 0;  // wall time of the C++ Detector::detect() call
};

// The Detector's "one call at a time" rule: a second thread's call raises instead of racing.
constexpr const char* kDetectorBusy =
    "viscd.Detector is running a frame in another thread; a Detector is not thread-safe: use one per thread";

Sphere sphere_of(py::handle obj, const char* name) {
  const auto v = float_values<4>(obj, name);
  return {v[0], v[1], v[2], v[3]};
}

Box box_of(py::handle obj, const char* name) {
  const auto v = float_values<6>(obj, name);
  return {{v[0], v[1], v[2]}, {v[3], v[4], v[5]}};
}

const Filter* optional_filter(py::handle obj, Filter& storage, const char* name) {
  if (obj.is_none()) return nullptr;
  storage = filter_value(obj, name);
  return &storage;
}

std::uint32_t slot_of(py::handle k) {
  return static_cast<std::uint32_t>(integer_value(k, "k", 0, std::numeric_limits<std::uint32_t>::max()));
}

Ray ray_of(py::handle origin, py::handle direction, double max_t) {
  Ray ray;
  const auto o = float_values<3>(origin, "origin");
  const auto d = float_values<3>(direction, "direction");
  for (int k = 0; k < 3; ++k) {
    ray.origin[k] = o[k];
    ray.dir[k] = d[k];
  }
  ray.max_t = static_cast<float>(max_t);
  return ray;
}

class PyDetector {
 public:
  PyDetector(const std::string& backend, const py::kwargs& keywords) {
    Config config;
    GlOptions gl;
    bool gl_given = false;
    apply_keywords(keywords, config, gl, gl_given);
    if (gl_given && backend != "gl")
      throw py::value_error("Detector: the gl_* keywords apply to backend='gl' only, not '" + backend + "'");
    Result<std::unique_ptr<Detector>> made =
        backend == "gl" ? make_gl_detector(config, gl) : make_detector(backend, config);
    if (!made) raise_status(made.status());
    detector_ = std::move(made).value();
  }

  PyFrame detect(py::handle spheres, py::handle boxes, py::handle camera, py::handle filters, py::handle id_map,
                 py::handle always_active, py::handle moved) {
    BusyGuard busy(busy_, kDetectorBusy);
    FrameInput in;
    PyFrame frame;
    InputSpan<Sphere> sphere_in;
    InputSpan<Box> box_in;
    InputSpan<Filter> filter_in;
    InputSpan<std::uint32_t> map_in;
    InputSpan<std::uint8_t> flag_in;
    InputSpan<std::uint32_t> moved_in;
    if (!spheres.is_none()) {
      sphere_in = sphere_rows(spheres, "spheres");
      in.spheres = sphere_in.span;
    }
    if (!boxes.is_none()) {
      box_in = box_rows(boxes, "boxes");
      in.boxes = box_in.span;
    }
    if (!filters.is_none()) {
      filter_in = filter_rows(filters, "filters");
      in.filters = filter_in.span;
    }
    if (!id_map.is_none()) {
      map_in = id_map_pixels(id_map, "id_map", in.id_map_width, in.id_map_height);
      in.id_map = map_in.span;
    }
    if (!always_active.is_none()) {
      flag_in = flag_values(always_active, "always_active");
      in.always_active = flag_in.span;
    }
    if (!moved.is_none()) {
      moved_in = index_values(moved, "moved");
      in.moved = moved_in.span;
      in.moved_listed = true;
    }
    Camera cam;
    if (!camera.is_none()) {
      if (!py::isinstance<Camera>(camera))
        throw py::type_error("detect: camera must be a viscd.Camera or None, got " +
                             py::type::handle_of(camera).attr("__name__").cast<std::string>());
      cam = camera.cast<Camera>();
      in.camera = &cam;
    }
    frame.input_copied =
        sphere_in.copied || box_in.copied || filter_in.copied || map_in.copied || flag_in.copied || moved_in.copied;
    frame.result = take_result();
    Status status;
    {
      // The arrays above stay referenced (and so alive) while the GIL is released; another
      // Python thread that writes into them meanwhile races with the frame, as in C++.
      py::gil_scoped_release released;
      const auto t0 = std::chrono::steady_clock::now();
      status = detector_->detect(in, *frame.result);
      frame.detect_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    }
    if (!status) raise_status(status);
    return frame;
  }

  void set_static(py::handle spheres, py::handle boxes, py::handle filters) {
    BusyGuard busy(busy_, kDetectorBusy);
    if (spheres.is_none() == boxes.is_none())
      throw py::value_error("set_static: give spheres or boxes (one of them); clear_static() empties the set");
    InputSpan<Filter> f;
    if (!filters.is_none()) f = filter_rows(filters, "filters");
    Status s;
    if (!spheres.is_none()) {
      const InputSpan<Sphere> in = sphere_rows(spheres, "spheres");
      s = detector_->set_static_spheres(in.span, f.span);
    } else {
      const InputSpan<Box> in = box_rows(boxes, "boxes");
      s = detector_->set_static_boxes(in.span, f.span);
    }
    if (!s) raise_status(s);
  }

  std::uint32_t add_static_sphere(py::handle sphere, py::handle filter) {
    BusyGuard busy(busy_, kDetectorBusy);
    Filter f;
    if (!filter.is_none()) f = filter_value(filter, "filter");
    const Result<std::uint32_t> r = detector_->add_static_sphere(sphere_of(sphere, "sphere"), f);
    if (!r) raise_status(r.status());
    return r.value();
  }

  std::uint32_t add_static_box(py::handle box, py::handle filter) {
    BusyGuard busy(busy_, kDetectorBusy);
    Filter f;
    if (!filter.is_none()) f = filter_value(filter, "filter");
    const Result<std::uint32_t> r = detector_->add_static_box(box_of(box, "box"), f);
    if (!r) raise_status(r.status());
    return r.value();
  }

  void move_static(py::handle k, py::handle shape) {
    BusyGuard busy(busy_, kDetectorBusy);
    const std::uint32_t slot = slot_of(k);
    const py::array a = py::array::ensure(shape);
    Status s;
    if (a && a.ndim() == 1 && a.size() == 4)
      s = detector_->move_static_sphere(slot, sphere_of(shape, "shape"));
    else if (a && a.ndim() == 1 && a.size() == 6)
      s = detector_->move_static_box(slot, box_of(shape, "shape"));
    else
      throw py::value_error(
          "move_static: shape must be a sphere (x, y, z, r) or a box (min x, y, z, max x, y, z), got " +
          py::repr(shape).cast<std::string>());
    if (!s) raise_status(s);
  }

  void remove_static(py::handle k) {
    BusyGuard busy(busy_, kDetectorBusy);
    if (Status s = detector_->remove_static(slot_of(k)); !s) raise_status(s);
  }

  void clear_static() {
    BusyGuard busy(busy_, kDetectorBusy);
    detector_->clear_static();
  }

  py::object ray_cast(py::handle origin, py::handle direction, double max_t, py::handle filter) {
    BusyGuard busy(busy_, kDetectorBusy);
    const Ray ray = ray_of(origin, direction, max_t);
    Filter storage;
    const Filter* f = optional_filter(filter, storage, "filter");
    RayHit hit;
    if (!detector_->ray_cast(ray, hit, f)) return py::none();
    return py::make_tuple(hit.index, hit.t);
  }

  py::tuple ray_cast_all(py::handle origin, py::handle direction, double max_t, py::handle filter) {
    BusyGuard busy(busy_, kDetectorBusy);
    const Ray ray = ray_of(origin, direction, max_t);
    Filter storage;
    const Filter* f = optional_filter(filter, storage, "filter");
    detector_->ray_cast_all(ray, hits_, f);
    const auto n = static_cast<py::ssize_t>(hits_.size());
    py::array_t<std::uint32_t> indices(n);
    py::array_t<float> t(n);
    for (py::ssize_t k = 0; k < n; ++k) {
      indices.mutable_data()[k] = hits_[static_cast<std::size_t>(k)].index;
      t.mutable_data()[k] = hits_[static_cast<std::size_t>(k)].t;
    }
    return py::make_tuple(indices, t);
  }

  py::array overlap(py::handle sphere, py::handle box, py::handle filter) {
    BusyGuard busy(busy_, kDetectorBusy);
    if (sphere.is_none() == box.is_none()) throw py::value_error("overlap: give sphere or box (one of them)");
    Filter storage;
    const Filter* f = optional_filter(filter, storage, "filter");
    if (!sphere.is_none())
      detector_->overlap(sphere_of(sphere, "sphere"), indices_, f);
    else
      detector_->overlap_box(box_of(box, "box"), indices_, f);
    py::array_t<std::uint32_t> out(static_cast<py::ssize_t>(indices_.size()));
    std::copy(indices_.begin(), indices_.end(), out.mutable_data());
    return out;
  }

  void set_config(const py::kwargs& keywords) {
    BusyGuard busy(busy_, kDetectorBusy);
    Config config = detector_->config();
    GlOptions gl;
    bool gl_given = false;
    apply_keywords(keywords, config, gl, gl_given);
    if (gl_given) throw py::value_error("set_config: the gl_* keywords are fixed when the Detector is made");
    detector_->set_config(config);
  }

  void wait_for_stage_times(PyFrame& frame) {
    BusyGuard busy(busy_, kDetectorBusy);
    py::gil_scoped_release released;
    detector_->wait_for_stage_times(frame.result->stats);
  }

  void reset_events() {
    BusyGuard busy(busy_, kDetectorBusy);
    detector_->reset_events();
  }

  [[nodiscard]] const Detector& detector() const { return *detector_; }

  // Reads of the detector's state (config, memory_bytes, static_count, static_kind) wait for no
  // frame: under the busy rule, a read while another thread's call runs (with the GIL released)
  // raises instead of racing with it.
  template <class Read>
  [[nodiscard]] auto read(Read&& f) {
    BusyGuard busy(busy_, kDetectorBusy);
    return f(static_cast<const Detector&>(*detector_));
  }

 private:
  // A FrameResult that Python holds nothing of (use_count 1: only this pool), to be written by
  // the next frame with its buffers' capacity kept; else a new one. Two slots suffice for the
  // usual loop `frame = detector.detect(...)`, which still holds the previous frame during the
  // call. Called with the GIL held: use counts change only under it.
  std::shared_ptr<FrameResult> take_result() {
    for (auto& r : pool_)
      if (r && r.use_count() == 1) return r;
    next_ = (next_ + 1) % pool_.size();
    pool_[next_] = std::make_shared<FrameResult>();
    return pool_[next_];
  }

  std::unique_ptr<Detector> detector_;
  bool busy_ = false;
  std::array<std::shared_ptr<FrameResult>, 2> pool_;
  std::size_t next_ = 0;
  std::vector<RayHit> hits_;
  std::vector<std::uint32_t> indices_;
};

// Shortest text that reads back as the same float ("0.1", not 0.10000000149011612).
std::string float_text(float v) {
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, r.ptr);
}

std::string camera_repr(const Camera& c) {
  const auto v3 = [](const float* v) {
    return "(" + float_text(v[0]) + ", " + float_text(v[1]) + ", " + float_text(v[2]) + ")";
  };
  return "viscd.Camera(eye=" + v3(c.eye) + ", target=" + v3(c.target) + ", up=" + v3(c.up) +
         ", fov_y_deg=" + float_text(c.fov_y_deg) + ", near=" + float_text(c.near_plane) +
         ", far=" + float_text(c.far_plane) + ", width=" + std::to_string(c.width) +
         ", height=" + std::to_string(c.height) + ")";
}

void set3(float* dst, py::handle v, const char* name) {
  const auto a = float_values<3>(v, name);
  for (int k = 0; k < 3; ++k) dst[k] = a[k];
}

constexpr const char* kDetectDoc =
    R"(detect(spheres=None, boxes=None, camera=None, filters=None, id_map=None, always_active=None, moved=None) -> Frame

Runs one frame: every overlapping pair among the active objects (all of them without a camera
and without an id map), plus each active object's pairs with the static set.

Arguments (every array may also be a list; N objects, one row each):
  spheres        (N, 4) float32: x, y, z, r. Or
  boxes          (N, 6) float32: min x, y, z, max x, y, z (axis-aligned). A frame holds spheres
                 or boxes, not both (both non-empty raises ValueError).
                 A C-contiguous float32 array is read where it lies, without a copy; any other
                 real dtype (float64, ints) or memory order is converted first: one copy of the
                 array, e.g. about 13 ms per 1e6 float64 spheres on a 2-core VM, a quarter of
                 the frame (Frame.input_copied tells which happened).
  camera         viscd.Camera: culls objects below lambda_ screen pixels (Detector keyword).
  filters        (N, 2) uint32: (group, mask) per object; i and j pair only when
                 group_i & mask_j and group_j & mask_i are both non-zero.
  id_map         (H, W) uint32: your own visibility map, object index + 1 per pixel, 0 background;
                 the detector then renders nothing and counts pixels from it.
  always_active  (N,) bool or uint8: objects never culled.
  moved          (M,) ascending indices of the objects whose bounds changed since the last frame
                 (unrepeated, below N; otherwise ValueError); an empty array: nothing moved. With
                 it the cpu backend compares and checks only these objects (follow_change): an
                 object that changed but is missing from the list is the caller's error. None
                 (default): the detector compares every object itself.

Returns a Frame:
  pairs    (P, 2) uint32, sorted, i < j; a static object k appears as j = k | 0x80000000
           (viscd.is_static(), viscd.static_slot(); Frame.static_pairs gives (i, k))
  state    (N,) uint8: 0 culled, 1 free, 2 colliding
  pixels   (N,) float32 screen pixels per object (empty without a camera or an id map)
  began, ended  (P, 2) uint32 contact events (with contact_events=True)
  image    (H, W, 4) uint8 RGBA (with shade=True and a camera), else None
  stats    dict: objects, active, bits, layout, pairs, stage_ms {stage: ms}, total_ms, ...
The arrays are views of the frame's own memory (no copy), valid as long as you keep them.

Raises ValueError for a bad shape, dtype or value (NaN, negative radius, a bad camera: viscd's
message), PairCapError beyond pair_memory_cap, MemoryError when memory runs out. The GIL is
released while the frame runs.

Example:
    >>> import numpy as np, viscd
    >>> det = viscd.Detector()
    >>> spheres = np.array([[0, 0, 0, 1], [1.5, 0, 0, 1], [5, 0, 0, 1]], np.float32)
    >>> det.detect(spheres).pairs
    array([[0, 1]], dtype=uint32)
)";

}  // namespace

}  // namespace viscd::python

PYBIND11_MODULE(_viscd, m) {
  using namespace viscd;
  using namespace viscd::python;
  m.doc() = "viscd's C++ core; import viscd (the package) rather than this module.";
  // Each docstring starts with its Python signature (pybind11's would name py::handle types).
  py::options options;
  options.disable_function_signatures();

  auto pair_cap_error = py::exception<PairCapTag>(m, "PairCapError", PyExc_RuntimeError);
  g_pair_cap_error = pair_cap_error.ptr();
  pair_cap_error.attr("__doc__") =
      "A frame's pairs would exceed the Detector's pair_memory_cap (8 bytes per pair); the message says how many "
      "were found when the search stopped.";
  auto backend_error = py::exception<BackendTag>(m, "BackendError", PyExc_RuntimeError);
  g_backend_error = backend_error.ptr();
  backend_error.attr("__doc__") =
      "The backend itself failed (gl: no OpenGL 4.5 context, a GL error; cuda: no usable GPU, a CUDA error).";

  m.attr("STATIC_BIT") = kStaticBit;
  m.attr("MAX_COORDINATE") = kMaxCoordinate;
  m.def("_keyword_table", &keyword_table,
        "The Detector's keywords as (name, gl only, type, default literal): the table the docstring, "
        "Detector.config and the type stub follow.");
  m.attr("__version__") =
      std::to_string(kVersionMajor) + "." + std::to_string(kVersionMinor) + "." + std::to_string(kVersionPatch);

  py::class_<Camera>(m, "Camera",
                     "A pinhole camera: right-handed look-at, OpenGL clip space. width x height is the screen in "
                     "pixels; pixel counts are screen pixels.")
      .def(py::init([](py::handle eye, py::handle target, py::handle up, double fov_y_deg, double near, double far,
                       py::handle width, py::handle height) {
             Camera c;
             set3(c.eye, eye, "eye");
             set3(c.target, target, "target");
             set3(c.up, up, "up");
             c.fov_y_deg = static_cast<float>(fov_y_deg);
             c.near_plane = static_cast<float>(near);
             c.far_plane = static_cast<float>(far);
             c.width = static_cast<int>(integer_value(width, "width", 1, std::numeric_limits<int>::max()));
             c.height = static_cast<int>(integer_value(height, "height", 1, std::numeric_limits<int>::max()));
             if (Status s = validate_camera(c); !s) raise_status(s);
             return c;
           }),
           py::arg("eye"), py::arg("target"), py::arg("up") = py::make_tuple(0.0, 1.0, 0.0),
           py::arg("fov_y_deg") = 60.0, py::arg("near") = 0.1, py::arg("far") = 1000.0, py::arg("width") = 1280,
           py::arg("height") = 720,
           "Camera(eye, target, up=(0, 1, 0), fov_y_deg=60, near=0.1, far=1000, width=1280, height=720)\n\n"
           "eye and target are points, up a direction (any length, not parallel to target - eye); fov_y_deg in\n"
           "(0, 180); 0 < near < far, distances along the view direction; width x height the screen in pixels.\n"
           "Raises ValueError for an invalid camera.")
      .def_property(
          "eye", [](const Camera& c) { return py::make_tuple(c.eye[0], c.eye[1], c.eye[2]); },
          [](Camera& c, py::handle v) { set3(c.eye, v, "eye"); }, "Position, world units.")
      .def_property(
          "target", [](const Camera& c) { return py::make_tuple(c.target[0], c.target[1], c.target[2]); },
          [](Camera& c, py::handle v) { set3(c.target, v, "target"); }, "Point looked at, world units.")
      .def_property(
          "up", [](const Camera& c) { return py::make_tuple(c.up[0], c.up[1], c.up[2]); },
          [](Camera& c, py::handle v) { set3(c.up, v, "up"); }, "Up direction.")
      .def_readwrite("fov_y_deg", &Camera::fov_y_deg, "Vertical field of view, degrees.")
      .def_readwrite("near", &Camera::near_plane, "Near plane distance.")
      .def_readwrite("far", &Camera::far_plane, "Far plane distance.")
      .def_readwrite("width", &Camera::width, "Screen width, pixels.")
      .def_readwrite("height", &Camera::height, "Screen height, pixels.")
      .def("__repr__", &camera_repr);

  py::class_<PyFrame>(m, "Frame",
                      "One frame's results (Detector.detect()). Its arrays are views of the frame's own memory: "
                      "no copy, valid as long as they are referenced.")
      .def_property_readonly(
          "pairs", [](const PyFrame& f) { return pair_view(f.result, f.result->pairs); },
          "(P, 2) uint32: every overlapping pair (i, j), i < j, sorted; a static object k appears as j = k | "
          "STATIC_BIT.")
      .def_property_readonly(
          "state",
          [](const PyFrame& f) {
            const auto& s = f.result->state;
            return result_view(f.result, s.empty() ? nullptr : reinterpret_cast<const std::uint8_t*>(s.data()),
                               {static_cast<py::ssize_t>(s.size())});
          },
          "(N,) uint8 per object: 0 culled, 1 free, 2 colliding.")
      .def_property_readonly(
          "pixels",
          [](const PyFrame& f) {
            const auto& p = f.result->pixels;
            return result_view(f.result, p.empty() ? nullptr : p.data(), {static_cast<py::ssize_t>(p.size())});
          },
          "(N,) float32 screen pixels per object; empty when none were counted (no camera, no id map).")
      .def_property_readonly(
          "began", [](const PyFrame& f) { return pair_view(f.result, f.result->began); },
          "(B, 2) uint32: pairs the previous frame did not report (contact_events=True).")
      .def_property_readonly(
          "ended", [](const PyFrame& f) { return pair_view(f.result, f.result->ended); },
          "(E, 2) uint32: the previous frame's pairs this one does not report (contact_events=True).")
      .def_property_readonly(
          "image",
          [](const PyFrame& f) -> py::object {
            const FrameResult& r = *f.result;
            if (r.image.empty()) return py::none();
            return result_view(f.result, r.image.data(), {r.image_height, r.image_width, 4});
          },
          "(H, W, 4) uint8 RGBA, rows top to bottom (shade=True with a camera); None otherwise. Red colliding, "
          "blue free, yellow culled, grey static.")
      .def_property_readonly(
          "static_pairs", [](const PyFrame& f) { return pair_subset(f.result->pairs, true); },
          "(Q, 2) uint32 copy: the pairs of a moving object i with a static object, as (i, k) with k the static "
          "slot (STATIC_BIT cleared).")
      .def_property_readonly(
          "moving_pairs", [](const PyFrame& f) { return pair_subset(f.result->pairs, false); },
          "(P - Q, 2) uint32 copy: the pairs of two moving objects.")
      .def_property_readonly(
          "stats", [](const PyFrame& f) { return stats_dict(f.result->stats, f.detect_ms); },
          "dict: objects, static_objects, active, has_camera, has_pixels, mean_pixels, bits, layout (text), "
          "layout_order, layout_axis_bits, pairs, order_kept, followed_change, moved, replaced, stage_ms ({stage name: "
          "ms}), total_ms (sum of "
          "stages), detect_ms (wall time of the C++ detect call).")
      .def_readonly("input_copied", &PyFrame::input_copied,
                    "True when an input array had to be converted (copied) before the frame ran; False when every "
                    "array was read where it lies.")
      .def("__repr__", [](const PyFrame& f) {
        const FrameStats& s = f.result->stats;
        return "<viscd.Frame: " + std::to_string(s.objects) + " objects, " + std::to_string(s.active) + " active, " +
               std::to_string(s.pairs) + " pairs>";
      });

  const std::string detector_doc =
      std::string(
          "Detector(backend='cpu', **config)\n\n"
          "Finds every overlapping pair among moving spheres or boxes, frame after frame, and answers ray and\n"
          "overlap queries on the last frame. backend: 'cpu' (all cores), 'reference' (brute force), 'gl'\n"
          "(OpenGL 4.5, headless through EGL) or 'cuda' (an NVIDIA GPU, when viscd was built with CUDA).\n"
          "Not thread-safe: a call (or a read of config, memory_bytes, static_count, static_kind) while\n"
          "another thread's call runs raises RuntimeError; use one Detector per thread.\n\n") +
      keywords_doc();
  py::class_<PyDetector>(m, "Detector", detector_doc.c_str())
      .def(py::init([](const std::string& backend, const py::kwargs& kw) {
             return std::make_unique<PyDetector>(backend, kw);
           }),
           py::arg("backend") = "cpu", detector_doc.c_str())
      .def("detect", &PyDetector::detect, py::arg("spheres") = py::none(), py::arg("boxes") = py::none(),
           py::arg("camera") = py::none(), py::arg("filters") = py::none(), py::arg("id_map") = py::none(),
           py::arg("always_active") = py::none(), py::arg("moved") = py::none(), kDetectDoc)
      .def("set_static", &PyDetector::set_static, py::arg("spheres") = py::none(), py::arg("boxes") = py::none(),
           py::arg("filters") = py::none(),
           "set_static(spheres=None, boxes=None, filters=None)\n\n"
           "Replaces the static set (objects that do not move) with (K, 4) spheres or (K, 6) boxes, in slots\n"
           "0..K-1; filters (K, 2) uint32 or None. Every frame then also reports each active moving object's\n"
           "pair with each static object k it overlaps, as (i, k | STATIC_BIT). The set and the frames hold\n"
           "the same kind. Takes effect at the next detect().")
      .def("add_static_sphere", &PyDetector::add_static_sphere, py::arg("sphere"), py::arg("filter") = py::none(),
           "add_static_sphere(sphere, filter=None) -> int\n\nAdds (x, y, z, r) to the static set; returns its slot k.")
      .def("add_static_box", &PyDetector::add_static_box, py::arg("box"), py::arg("filter") = py::none(),
           "add_static_box(box, filter=None) -> int\n\nAdds (min x, y, z, max x, y, z); returns its slot k.")
      .def("move_static", &PyDetector::move_static, py::arg("k"), py::arg("shape"),
           "move_static(k, shape)\n\nMoves or reshapes the static object in slot k: shape is a sphere (4 numbers)\n"
           "or a box (6 numbers), of the set's kind. Its filter stays.")
      .def("remove_static", &PyDetector::remove_static, py::arg("k"),
           "remove_static(k)\n\nRemoves the static object in slot k; the slot is free for a later add.")
      .def("clear_static", &PyDetector::clear_static, "clear_static()\n\nEmpties the static set.")
      .def_property_readonly(
          "static_count", [](PyDetector& d) { return d.read([](const Detector& x) { return x.static_count(); }); },
          "Objects in the static set.")
      .def_property_readonly(
          "static_kind",
          [](PyDetector& d) {
            return d.read([](const Detector& x) { return x.static_kind() == ShapeKind::box ? "box" : "sphere"; });
          },
          "'sphere' or 'box': the static set's kind ('sphere' while empty).")
      .def("ray_cast", &PyDetector::ray_cast, py::arg("origin"), py::arg("direction"),
           py::arg("max_t") = std::numeric_limits<double>::infinity(), py::arg("filter") = py::none(),
           "ray_cast(origin, direction, max_t=inf, filter=None) -> (index, t) or None\n\n"
           "The first object (smallest t, ties to the smaller index) the ray origin + t * direction,\n"
           "0 <= t <= max_t, hits among the last frame's active objects and the static set; t = 0 when the\n"
           "origin is inside. filter: (group, mask) or None. A zero direction hits nothing.")
      .def("ray_cast_all", &PyDetector::ray_cast_all, py::arg("origin"), py::arg("direction"),
           py::arg("max_t") = std::numeric_limits<double>::infinity(), py::arg("filter") = py::none(),
           "ray_cast_all(origin, direction, max_t=inf, filter=None) -> (indices, t)\n\n"
           "Every hit, sorted by (t, index): (K,) uint32 indices and (K,) float32 t.")
      .def("overlap", &PyDetector::overlap, py::arg("sphere") = py::none(), py::arg("box") = py::none(),
           py::arg("filter") = py::none(),
           "overlap(sphere=None, box=None, filter=None) -> ndarray\n\n"
           "The last frame's active objects (and static objects) overlapping a query sphere (x, y, z, r) or box\n"
           "(min x, y, z, max x, y, z): a sorted (K,) uint32 array. An invalid query shape overlaps nothing.")
      .def("reset_events", &PyDetector::reset_events,
           "reset_events()\n\nForgets the previous frame of the contact events: the next frame's began holds all its "
           "pairs.")
      .def("wait_for_stage_times", &PyDetector::wait_for_stage_times, py::arg("frame"),
           "wait_for_stage_times(frame)\n\ngl: waits until the frame's stage times are known and writes them into "
           "frame.stats (the gl backend\n"
           "reports them one frame late). cpu and reference: does nothing.")
      .def_property_readonly(
          "config", [](PyDetector& d) { return config_dict(d.read([](const Detector& x) { return x.config(); })); },
          "The settings as a dict of the keywords Detector() takes.")
      .def("set_config", &PyDetector::set_config,
           "set_config(**config)\n\nChanges settings (the Detector's keywords, gl_* excepted); takes effect at the "
           "next detect().")
      .def_property_readonly(
          "backend", [](const PyDetector& d) { return std::string(d.detector().name()); },
          "'reference', 'cpu', 'gl' or 'cuda'.")
      .def_property_readonly(
          "memory_bytes", [](PyDetector& d) { return d.read([](const Detector& x) { return x.memory_bytes(); }); },
          "Working memory the backend holds now, in bytes.")
      .def("__repr__",
           [](const PyDetector& d) { return "<viscd.Detector backend='" + std::string(d.detector().name()) + "'>"; });
}
