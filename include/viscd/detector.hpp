#pragma once
/// \file detector.hpp
/// The one interface every backend implements, and a factory per backend.

#include <memory>
#include <span>
#include <string>
#include <string_view>

#include "viscd/config.hpp"
#include "viscd/frame.hpp"
#include "viscd/result.hpp"
#include "viscd/types.hpp"

namespace viscd {

/// Finds every overlapping pair of spheres, frame after frame.
///
/// Threading: a Detector is not thread-safe; use one per thread. It may use worker threads
/// internally (Config::threads). Lifetime: `spheres` need only live for the call.
class Detector {
 public:
  virtual ~Detector() = default;
  Detector(const Detector&) = delete;
  Detector& operator=(const Detector&) = delete;

  /// Runs one frame. With `camera` == nullptr no visibility stages run and every object is
  /// active; with a camera and Config::culling, objects below lambda screen pixels are culled.
  /// Fails (and leaves `out` unspecified) on invalid spheres (non-finite, negative radius,
  /// beyond kMaxCoordinate), an invalid camera, a visibility map beyond kMaxMapSide or
  /// kMaxMapPixels, negative Config::threads, more than 2^31 - 1 objects, pairs beyond
  /// Config::pair_memory_cap, or when memory runs out (the message names the frame's size).
  /// No exception leaves detect().
  [[nodiscard]] virtual Status detect(std::span<const Sphere> spheres, const Camera* camera, FrameResult& out) = 0;

  /// Backend name: "reference", "cpu", "gl".
  [[nodiscard]] virtual std::string_view name() const = 0;

  /// Working memory the backend holds now, in bytes: visibility map, counts, codes, sort
  /// buffers, tree, pair buffers (GPU memory for gl; there the driver's own figure, from
  /// GL_NVX_gpu_memory_info, when it offers one). Grows with the largest frame seen so far.
  [[nodiscard]] virtual std::uint64_t memory_bytes() const = 0;

  /// Backends that time stages on a GPU report a frame's times one frame late, so that timing
  /// never stalls the pipeline. After a frame whose times are needed now (a single-frame run),
  /// call this: it waits until that frame's times are known and writes them into `stats`.
  /// CPU backends report times at once; for them this does nothing.
  virtual void wait_for_stage_times(FrameStats& stats) { (void)stats; }

  [[nodiscard]] const Config& config() const { return config_; }
  /// Changes settings; takes effect on the next detect().
  void set_config(const Config& config) { config_ = config; }

 protected:
  explicit Detector(const Config& config) : config_(config) {}
  Config config_;
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

/// Checks spheres for the input rules (finite, 0 <= r, magnitudes <= kMaxCoordinate) and the
/// object limit; the error names the first bad sphere by index.
[[nodiscard]] Status validate_spheres(std::span<const Sphere> spheres);
/// Checks a visibility map size against kMaxMapSide and kMaxMapPixels; the error names "WxH".
[[nodiscard]] Status validate_map_size(int width, int height);
/// Checks a camera (positive size, 0 < fov < 180, 0 < near < far, eye != target, up not parallel,
/// every coordinate and plane distance finite and at most kMaxCoordinate in magnitude).
[[nodiscard]] Status validate_camera(const Camera& camera);

}  // namespace viscd
