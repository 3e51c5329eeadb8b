#pragma once
// The internal interface every backend implements. The public viscd::Detector is a handle on one
// Backend: detect() checks the input rules every backend shares (core/frame_rules.hpp), calls
// run_frame(), then computes the contact events and keeps what the queries need, so that every
// backend treats them alike. A backend adds only its own stages.
//
//   reference  cpu/reference_detector.cpp  brute force, the test oracle
//   cpu        cpu/cpu_detector.hpp        tiled rasterizer + bucket broadphase on all cores
//   gl         gl/gl_detector.hpp          OpenGL 4.5 compute shaders
//   cuda       cuda/cuda_detector.cpp      the CPU pipeline with stages 1-2 and 5-8 on an NVIDIA GPU
//
// (After Jolt's split of BroadPhase, what callers see, from BroadPhaseQuadTree, what implements it.)

#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <string_view>
#include <vector>

#include "core/brute_queries.hpp"
#include "core/static_set.hpp"
#include "viscd/config.hpp"
#include "viscd/detector.hpp"
#include "viscd/frame.hpp"
#include "viscd/result.hpp"
#include "viscd/types.hpp"

namespace viscd::detail {

class Backend {
 public:
  explicit Backend(const Config& config) : config_(config) {}
  virtual ~Backend() = default;
  Backend(const Backend&) = delete;
  Backend& operator=(const Backend&) = delete;

  /// "reference", "cpu", "gl".
  [[nodiscard]] virtual std::string_view name() const = 0;
  /// Detector::memory_bytes().
  [[nodiscard]] virtual std::uint64_t memory_bytes() const = 0;
  /// Detector::wait_for_stage_times(); backends that time stages on the host do nothing.
  virtual void wait_for_stage_times(FrameStats& stats) { (void)stats; }

  /// The frame's objects, as validate_spheres() / validate_boxes() check them (the same errors);
  /// Detector::detect() calls it after the other input rules. The cpu backend checks in parallel.
  [[nodiscard]] virtual Status validate_objects(const Shapes& objects);
  /// The frame's objects as Detector::detect() checks them: validate_objects() of them all, unless
  /// the backend knows that the objects FrameInput::moved leaves out are the ones it checked
  /// last frame (cpu, following change): then only the listed ones.
  [[nodiscard]] virtual Status validate_frame_objects(const FrameInput& input) {
    return validate_objects(Shapes::of(input));
  }

  /// One frame, after Detector::detect() checked the shared input rules (objects, camera, map
  /// sizes, filter count, id map size, Config::threads, the static set's kind): writes pairs,
  /// states, pixels, image and stats. Applies `input.filters` to the pairs. The static set
  /// (static_set_) takes part as Detector::set_static_spheres() describes. Returns ErrorKind::unsupported_input for
  /// input this backend does not take. detect() turns std::bad_alloc into ErrorKind::out_of_memory.
  [[nodiscard]] virtual Status run_frame(const FrameInput& input, FrameResult& out) = 0;

  /// Queries on the last successful frame (called only after one; the ray is valid: finite, a
  /// non-zero direction, max_t >= 0; the sphere passes validate_spheres; the box is finite with
  /// min <= max). Static objects are reported as static_index(k). `filter` is the query's filter or null (Detector).
  /// The results need not be sorted: Detector sorts the lists. A backend that answers them from structures of its own
  /// overrides them all; the others get brute force over query_objects().
  [[nodiscard]] virtual bool query_ray_first(const Ray& ray, const Filter* filter, RayHit& hit);
  virtual void query_ray_all(const Ray& ray, const Filter* filter, std::vector<RayHit>& hits);
  virtual void query_ray_visit(const Ray& ray, const Filter* filter, RayVisitor& visitor);
  virtual void query_sphere(const Sphere& sphere, const Filter* filter, std::vector<std::uint32_t>& indices);
  virtual void query_box(const Box& box, const Filter* filter, std::vector<std::uint32_t>& indices);
  virtual void query_sphere_visit(const Sphere& sphere, const Filter* filter, OverlapVisitor& visitor);
  virtual void query_box_visit(const Box& box, const Filter* filter, OverlapVisitor& visitor);

  /// Whether the backend keeps what queries need itself (answers_queries() true: gl reads its
  /// copy back from the GPU, cpu searches its tree); otherwise detect() keeps a copy of the active
  /// objects, ids and (in frames with filters) filters after each frame, the static set's with
  /// them, for query_objects().
  [[nodiscard]] virtual bool answers_queries() const { return false; }
  /// The objects the brute-force queries search: by default the copy detect() keeps.
  [[nodiscard]] virtual QueryObjects query_objects() {
    return {query_boxes_.empty() ? Shapes(query_spheres_) : Shapes(query_boxes_), query_ids_, query_filters_};
  }

  /// Runs f(begin, end) over chunks covering [0, n): on the frame's threads for backends that
  /// have them (the pipeline backends), in one call by default. Detector::detect() copies the
  /// queries' objects with it.
  virtual void for_chunks_of(std::size_t n, const std::function<void(std::size_t, std::size_t)>& f) {
    if (n) f(0, n);
  }

  [[nodiscard]] const Config& config() const { return config_; }
  void set_config(const Config& config) { config_ = config; }

 protected:
  Config config_;
  StaticSet static_set_;

 private:
  friend class viscd::Detector;
  std::vector<Pair> previous_pairs_;  // the contact events' previous frame (empty: none)
  bool queries_ready_ = false;        // the last detect() succeeded
  // The active objects of the last frame, for the brute-force queries, and their filters (empty
  // when the frame had none).
  std::vector<Sphere> query_spheres_;
  std::vector<Box> query_boxes_;
  std::vector<std::uint32_t> query_ids_;
  std::vector<Filter> query_filters_;
};

/// The one way from a backend to the public handle and back (factories, tests, tools).
struct DetectorAccess {
  [[nodiscard]] static std::unique_ptr<Detector> wrap(std::unique_ptr<Backend> backend) {
    return std::unique_ptr<Detector>(new Detector(std::move(backend)));
  }
  [[nodiscard]] static Backend& backend(Detector& d) { return *d.backend_; }
  [[nodiscard]] static const Backend& backend(const Detector& d) { return *d.backend_; }
};

/// A detector's backend as its concrete type (tests and tools that inspect a backend's stages);
/// the detector must run that backend.
template <class T>
[[nodiscard]] T& backend_as(Detector& d) {
  return dynamic_cast<T&>(DetectorAccess::backend(d));
}
template <class T>
[[nodiscard]] const T& backend_as(const Detector& d) {
  return dynamic_cast<const T&>(DetectorAccess::backend(d));
}

}  // namespace viscd::detail
