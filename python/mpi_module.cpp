// The extension module viscd._viscd_mpi (docs/python.md, docs/mpi.md): DistributedDetector over
// an mpi4py communicator. A module of its own, loaded the first time viscd.DistributedDetector is
// named, so that `import viscd` neither loads MPI nor starts it. Errors raise the exceptions
// viscd._viscd raises for the same kinds (ValueError, PairCapError, MemoryError, BackendError).
#include <mpi.h>
#include <mpi4py/mpi4py.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <memory>
#include <string>
#include <vector>

#include "busy_guard.hpp"
#include "config_keywords.hpp"
#include "input_arrays.hpp"
#include "viscd/mpi.hpp"

namespace py = pybind11;

namespace viscd::python {
namespace {

py::object g_viscd;  // viscd._viscd, for its exception types

[[noreturn]] void raise_status(const Status& s) {
  py::object type = py::reinterpret_borrow<py::object>(PyExc_ValueError);
  if (s.kind() == ErrorKind::pair_cap) type = g_viscd.attr("PairCapError");
  if (s.kind() == ErrorKind::out_of_memory) type = py::reinterpret_borrow<py::object>(PyExc_MemoryError);
  if (s.kind() == ErrorKind::backend_failure || s.kind() == ErrorKind::io_failure) type = g_viscd.attr("BackendError");
  PyErr_SetString(type.ptr(), s.error().c_str());
  throw py::error_already_set();
}

/// (N,) global ids: any integer dtype, every value >= 0, taken as uint64 (copied unless it is
/// already C-contiguous native uint64).
py::array_t<std::uint64_t, py::array::c_style> id_values(py::handle obj, std::size_t n) {
  py::array a = py::module_::import("numpy").attr("asarray")(obj);
  const char kind = a.dtype().kind();
  if (a.ndim() != 1 || (a.size() > 0 && kind != 'i' && kind != 'u'))
    throw py::value_error("ids: expected an (N,) array of integers, got shape " +
                          py::str(a.attr("shape")).cast<std::string>() + " of dtype " +
                          py::str(a.dtype()).cast<std::string>());
  if (kind == 'i' && a.size() > 0 && py::bool_(a.attr("min")() < py::int_(0)))
    throw py::value_error("ids: global ids are unsigned; a negative id was given");
  if (static_cast<std::size_t>(a.size()) != n)
    throw py::value_error("ids: " + std::to_string(a.size()) + " ids for " + std::to_string(n) +
                          " objects (one global id per object)");
  return py::array_t<std::uint64_t, py::array::c_style>::ensure(a.attr("astype")("uint64", py::arg("copy") = false));
}

/// The objects of one call: spheres or boxes, their ids, filters, flags, kept alive while used.
struct Objects {
  InputSpan<Sphere> spheres;
  InputSpan<Box> boxes;
  py::array_t<std::uint64_t, py::array::c_style> ids;
  InputSpan<Filter> filters;
  InputSpan<std::uint8_t> always_active;
};

Objects objects_of(py::handle spheres, py::handle boxes, py::handle ids, py::handle filters, py::handle always_active) {
  if (!spheres.is_none() && !boxes.is_none()) throw py::value_error("give spheres or boxes, not both");
  Objects o;
  if (!spheres.is_none()) o.spheres = sphere_rows(spheres, "spheres");
  if (!boxes.is_none()) o.boxes = box_rows(boxes, "boxes");
  const std::size_t n = o.spheres.span.size() + o.boxes.span.size();
  if (ids.is_none()) {
    if (n > 0) throw py::value_error("ids: one global id per object is needed");
    o.ids = py::array_t<std::uint64_t, py::array::c_style>(0);
  } else {
    o.ids = id_values(ids, n);
  }
  if (!filters.is_none()) o.filters = filter_rows(filters, "filters");
  if (!always_active.is_none()) o.always_active = flag_values(always_active, "always_active");
  return o;
}

std::span<const std::uint64_t> span_of(const py::array_t<std::uint64_t, py::array::c_style>& a) {
  return {a.data(), static_cast<std::size_t>(a.size())};
}

/// (M, 2) uint64 pairs over memory `owner` keeps.
template <class Owner>
py::array pair_array(const std::shared_ptr<Owner>& owner, const std::vector<mpi::GlobalPair>& pairs) {
  static_assert(sizeof(mpi::GlobalPair) == 2 * sizeof(std::uint64_t));
  const std::vector<py::ssize_t> shape{static_cast<py::ssize_t>(pairs.size()), 2};
  if (pairs.empty()) return py::array_t<std::uint64_t>(shape);
  auto* keep = new std::shared_ptr<Owner>(owner);
  py::capsule base(keep, [](void* p) { delete static_cast<std::shared_ptr<Owner>*>(p); });
  return py::array_t<std::uint64_t>(shape, &pairs.front().a, base);
}

py::dict rank_stats(const mpi::RankStats& r) {
  py::dict d;
  d["objects"] = r.objects;
  d["static_objects"] = r.static_objects;
  d["ghosts_received"] = r.ghosts_received;
  d["ghosts_sent"] = r.ghosts_sent;
  d["static_ghosts_received"] = r.static_ghosts_received;
  d["static_ghosts_sent"] = r.static_ghosts_sent;
  d["bytes_sent"] = r.bytes_sent;
  d["bytes_received"] = r.bytes_received;
  d["pairs"] = r.pairs;
  d["ids_checked"] = r.ids_checked;
  d["exchange_ms"] = r.exchange_ms;
  d["communication_ms"] = r.communication_ms;
  d["detect_ms"] = r.detect_ms;
  d["total_ms"] = r.total_ms;
  return d;
}

/// One rank's frame (DistributedDetector.detect()).
struct PyDistributedFrame {
  std::shared_ptr<mpi::DistributedResult> result;
};

/// Its calls are collectives, which one thread must make in order: a second thread's call raises
/// instead of interleaving MPI calls.
constexpr const char* kDistributedBusy =
    "viscd.DistributedDetector is running a call in another thread; its calls are collective: make them from one "
    "thread, in the same order on every rank";

class PyDistributedDetector {
 public:
  PyDistributedDetector(py::handle comm, const py::kwargs& keywords) {
    if (import_mpi4py() < 0) throw py::error_already_set();
    MPI_Comm* c = PyMPIComm_Get(comm.ptr());
    if (c == nullptr) throw py::error_already_set();
    Config config;
    GlOptions gl;
    bool gl_given = false;
    apply_keywords(keywords, config, gl, gl_given);
    if (gl_given) throw py::value_error("DistributedDetector: the gl_* keywords do not apply (its ranks run cpu)");
    detector_ = std::make_unique<mpi::DistributedDetector>(*c, config);
  }

  PyDistributedFrame detect(py::handle spheres, py::handle boxes, py::handle ids, py::handle filters,
                            py::handle always_active) {
    const BusyGuard busy(busy_, kDistributedBusy);
    const Objects o = objects_of(spheres, boxes, ids, filters, always_active);
    mpi::DistributedInput in;
    in.spheres = o.spheres.span;
    in.boxes = o.boxes.span;
    in.ids = span_of(o.ids);
    in.filters = o.filters.span;
    in.always_active = o.always_active.span;
    PyDistributedFrame f{std::make_shared<mpi::DistributedResult>()};
    Status s;
    {
      py::gil_scoped_release release;
      s = detector_->detect(in, *f.result);
    }
    if (!s) raise_status(s);
    return f;
  }

  void set_static(py::handle spheres, py::handle boxes, py::handle ids, py::handle filters) {
    const BusyGuard busy(busy_, kDistributedBusy);
    const Objects o = objects_of(spheres, boxes, ids, filters, py::none());
    const Status s = boxes.is_none() ? detector_->set_static_spheres(o.spheres.span, span_of(o.ids), o.filters.span)
                                     : detector_->set_static_boxes(o.boxes.span, span_of(o.ids), o.filters.span);
    if (!s) raise_status(s);
  }

  void clear_static() {
    const BusyGuard busy(busy_, kDistributedBusy);
    detector_->clear_static();
  }

  py::object gather_pairs(const PyDistributedFrame& frame, int root) {
    const BusyGuard busy(busy_, kDistributedBusy);
    auto all = std::make_shared<std::vector<mpi::GlobalPair>>();
    Status s;
    {
      py::gil_scoped_release release;
      s = detector_->gather_pairs(*frame.result, *all, root);
    }
    if (!s) raise_status(s);
    if (detector_->rank() != root) return py::none();
    return pair_array(all, *all);
  }

  [[nodiscard]] int rank() const { return detector_->rank(); }
  [[nodiscard]] int size() const { return detector_->size(); }

 private:
  std::unique_ptr<mpi::DistributedDetector> detector_;
  bool busy_ = false;
};

}  // namespace
}  // namespace viscd::python

PYBIND11_MODULE(_viscd_mpi, m) {
  using namespace viscd::python;
  m.doc() = "viscd's distributed detector over mpi4py; use viscd.DistributedDetector.";
  g_viscd = py::module_::import("viscd._viscd");
  // Dropped before the interpreter finalizes, so that no Python object outlives it.
  py::module_::import("atexit").attr("register")(py::cpp_function([] { g_viscd = py::object(); }));
  py::options options;
  options.disable_function_signatures();

  py::class_<PyDistributedFrame>(m, "DistributedFrame", "One rank's share of a frame (DistributedDetector.detect()).")
      .def_property_readonly(
          "pairs", [](const PyDistributedFrame& f) { return pair_array(f.result, f.result->pairs); },
          "(M, 2) uint64: the pairs this rank reports, by global id, a < b, sorted. Over all ranks every\n"
          "overlapping pair appears once (docs/mpi.md, \"Who reports a pair\").")
      .def_property_readonly(
          "state",
          [](const PyDistributedFrame& f) {
            const auto& s = f.result->state;
            py::array_t<std::uint8_t> a(static_cast<py::ssize_t>(s.size()));
            for (std::size_t i = 0; i < s.size(); ++i) a.mutable_data()[i] = static_cast<std::uint8_t>(s[i]);
            return a;
          },
          "(N,) uint8 per own object, in input order: 1 free, 2 colliding (with anything on any rank).")
      .def_property_readonly(
          "stats", [](const PyDistributedFrame& f) { return rank_stats(f.result->stats); },
          "This rank's numbers: objects, ghosts received and sent, bytes, pairs, exchange_ms, detect_ms, ...");

  py::class_<PyDistributedDetector>(
      m, "DistributedDetector",
      "DistributedDetector(comm, **config)\n\n"
      "Finds every overlapping pair among the objects of all ranks of an mpi4py communicator\n"
      "(docs/mpi.md). Each rank passes its own objects with global ids; every call but set_static and\n"
      "clear_static is collective: every rank calls it, in the same order. Keywords as Detector's.")
      .def(py::init(
               [](py::handle comm, const py::kwargs& kw) { return std::make_unique<PyDistributedDetector>(comm, kw); }),
           py::arg("comm"))
      .def("detect", &PyDistributedDetector::detect, py::arg("spheres") = py::none(), py::arg("boxes") = py::none(),
           py::arg("ids") = py::none(), py::arg("filters") = py::none(), py::arg("always_active") = py::none(),
           "detect(spheres=None, boxes=None, ids=None, filters=None, always_active=None) -> DistributedFrame\n\n"
           "Collective: one frame. This rank's (N, 4) spheres or (N, 6) boxes with (N,) integer global ids,\n"
           "unique over every rank's moving and static objects; filters (N, 2) and always_active (N,) as for\n"
           "Detector.detect (no culling across ranks: every object is active). Bad input on any rank raises\n"
           "the same error on every rank.")
      .def("set_static", &PyDistributedDetector::set_static, py::arg("spheres") = py::none(),
           py::arg("boxes") = py::none(), py::arg("ids") = py::none(), py::arg("filters") = py::none(),
           "set_static(spheres=None, boxes=None, ids=None, filters=None)\n\n"
           "This rank's static objects with their global ids; from the next detect().")
      .def("clear_static", &PyDistributedDetector::clear_static, "clear_static()\n\nEmpties this rank's static set.")
      .def("gather_pairs", &PyDistributedDetector::gather_pairs, py::arg("frame"), py::arg("root") = 0,
           "gather_pairs(frame, root=0) -> (M, 2) uint64 array on root, None elsewhere\n\n"
           "Collective: every rank's pairs of its frame, sorted: the frame's pairs as one process finds them.")
      .def_property_readonly("rank", &PyDistributedDetector::rank, "This rank in the detector's communicator.")
      .def_property_readonly("size", &PyDistributedDetector::size, "The number of ranks.");
}
