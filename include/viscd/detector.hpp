#pragma once
/// \file detector.hpp
/// The detector an engine calls, a factory per backend, and the rules every backend shares.

#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "viscd/config.hpp"
#include "viscd/frame.hpp"
#include "viscd/result.hpp"
#include "viscd/types.hpp"

namespace viscd {

namespace detail {
class Backend;  // what each backend implements (src/core/backend.hpp); not part of the API
struct DetectorAccess;
}  // namespace detail

/// Finds every overlapping pair of spheres, frame after frame, and answers ray and overlap
/// queries on the last frame. Made by a factory below (make_cpu_detector(), make_detector(),
/// make_gl_detector()); the backend it runs is fixed for its lifetime.
///
/// Threading: a Detector is not thread-safe; use one per thread. It may use worker threads
/// internally (Config::threads, Config::executor). Lifetime: the input's spans need only live
/// for the call.
class Detector {
 public:
  ~Detector();
  Detector(const Detector&) = delete;
  Detector& operator=(const Detector&) = delete;

  /// Runs one frame. Without a camera (and without an id map) no visibility stages run and every
  /// object is active; with a camera and Config::culling, objects below lambda screen pixels are
  /// culled. Fails (and leaves `out` unspecified) with ErrorKind::invalid_input on invalid
  /// spheres (non-finite, negative radius, beyond kMaxCoordinate), an invalid camera, a
  /// visibility map beyond kMaxMapSide or kMaxMapPixels, filters that are neither empty nor one
  /// per sphere, an id map whose size is not id_map_width x id_map_height or whose ids exceed the
  /// number of spheres, an id map and a gl texture together, negative Config::threads or more
  /// than 2^31 - 1 objects; with ErrorKind::unsupported_input on input this backend does not
  /// take (the message says which); with ErrorKind::pair_cap when the pairs exceed
  /// Config::pair_memory_cap; with ErrorKind::out_of_memory when memory runs out (the message
  /// names the frame's size); with ErrorKind::backend_failure when the backend fails (a GL
  /// error). A failed frame leaves the contact events' previous frame as it was, and queries see
  /// no objects until the next frame succeeds. No exception leaves detect().
  [[nodiscard]] Status detect(const FrameInput& input, FrameResult& out);
  /// detect() with spheres and a camera only (no filters, no id map).
  [[nodiscard]] Status detect(std::span<const Sphere> spheres, const Camera* camera, FrameResult& out);

  /// Forgets the previous frame of the contact events: the next frame's `began` holds all its
  /// pairs and its `ended` is empty.
  void reset_events();

  /// Queries on the last successful frame: they see its active objects (culled ones are
  /// invisible; filters do not apply) at the positions that frame was given. A ray hits a sphere
  /// by ray_hits_sphere(); a ray with a zero or non-finite direction, a non-finite origin, or a
  /// max_t that is negative or NaN hits nothing.
  /// ray_cast: the first hit (smallest t, ties to the smaller index); false when there is none.
  [[nodiscard]] bool ray_cast(const Ray& ray, RayHit& hit);
  /// Every hit, sorted by (t, index); `hits` is cleared first (its capacity is reused).
  void ray_cast_all(const Ray& ray, std::vector<RayHit>& hits);
  /// The active objects that overlap `sphere` by spheres_overlap(), sorted by index; cleared
  /// first. A sphere that validate_spheres() refuses overlaps nothing.
  void overlap(const Sphere& sphere, std::vector<std::uint32_t>& indices);

  /// Backend name: "reference", "cpu", "gl".
  [[nodiscard]] std::string_view name() const;

  /// Working memory the backend holds now, in bytes: visibility map, counts, codes, sort
  /// buffers, tree, pair buffers (GPU memory for gl; there the driver's own figure, from
  /// GL_NVX_gpu_memory_info, when it offers one). Grows with the largest frame seen so far.
  [[nodiscard]] std::uint64_t memory_bytes() const;

  /// Backends that time stages on a GPU report a frame's times one frame late, so that timing
  /// never stalls the pipeline. After a frame whose times are needed now (a single-frame run),
  /// call this: it waits until that frame's times are known and writes them into `stats`.
  /// CPU backends report times at once; for them this does nothing.
  void wait_for_stage_times(FrameStats& stats);

  [[nodiscard]] const Config& config() const;
  /// Changes settings; takes effect on the next detect().
  void set_config(const Config& config);

 private:
  friend struct detail::DetectorAccess;
  explicit Detector(std::unique_ptr<detail::Backend> backend);
  std::unique_ptr<detail::Backend> backend_;
};

/// Brute force O(N^2) pairs and a per-pixel ray cast visibility map: the test oracle.
[[nodiscard]] std::unique_ptr<Detector> make_reference_detector(const Config& config = {});
/// The fast CPU backend: LBVH and a tiled sphere rasterizer on all cores (or Config::executor).
[[nodiscard]] std::unique_ptr<Detector> make_cpu_detector(const Config& config = {});
/// A backend by name ("reference", "cpu", or "gl" when built with VISCD_ENABLE_GL).
[[nodiscard]] Result<std::unique_ptr<Detector>> make_detector(std::string_view backend, const Config& config = {});

/// Largest number of pairs N objects can produce, N(N-1)/2: the capacity that always suffices.
[[nodiscard]] constexpr std::uint64_t max_pairs_bound(std::uint64_t n) { return n < 2 ? 0 : n * (n - 1) / 2; }

/// The overlap test every backend uses, evaluated in float without FMA: |c_i - c_j| <= r_i + r_j
/// (touching counts; docs/architecture.md).
[[nodiscard]] bool spheres_overlap(const Sphere& a, const Sphere& b);

/// Whether objects with these filters may be reported as a pair:
/// `(a.group & b.mask) != 0 && (b.group & a.mask) != 0`.
[[nodiscard]] constexpr bool pair_passes_filter(const Filter& a, const Filter& b) {
  return (a.group & b.mask) != 0 && (b.group & a.mask) != 0;
}

/// The ray-sphere test every backend and query uses: true when a point origin + t * dir with
/// 0 <= t <= ray.max_t lies inside or on the sphere, with `t` the smallest such t rounded to float
/// (0 when the origin is inside or on it). Evaluated in double from the float inputs, the same
/// operations everywhere (docs/architecture.md, "Queries"), so that every backend's answer is the
/// same bit for bit. A zero direction hits nothing.
[[nodiscard]] bool ray_hits_sphere(const Ray& ray, const Sphere& sphere, float& t);

/// Checks spheres for the input rules (finite, 0 <= r, magnitudes <= kMaxCoordinate) and the
/// object limit; the error names the first bad sphere by index.
[[nodiscard]] Status validate_spheres(std::span<const Sphere> spheres);
/// Checks a visibility map size against kMaxMapSide and kMaxMapPixels; the error names "WxH".
[[nodiscard]] Status validate_map_size(int width, int height);
/// Checks a camera (positive size, 0 < fov < 180, 0 < near < far, eye != target, up not parallel,
/// every coordinate and plane distance finite and at most kMaxCoordinate in magnitude).
[[nodiscard]] Status validate_camera(const Camera& camera);

}  // namespace viscd
