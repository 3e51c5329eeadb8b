#pragma once
// The frame pipeline every CPU-side detector shares: validate, visibility (1), count (2),
// cull + mu + m (3), broadphase (4-8, backend specific), object states, shading (9).

#include <memory>
#include <span>
#include <vector>

#include "core/frame_rules.hpp"
#include "cpu/visibility.hpp"
#include "viscd/detector.hpp"

namespace viscd::detail {

class PipelineDetector : public Detector {
 public:
  [[nodiscard]] Status detect(std::span<const Sphere> spheres, const Camera* camera, FrameResult& out) final;
  [[nodiscard]] std::uint64_t memory_bytes() const final;
  /// The last frame's visibility map (empty without camera); for tests and tools.
  [[nodiscard]] const VisibilityMap& visibility_map() const { return map_; }

 private:
  Status detect_frame(std::span<const Sphere> spheres, const Camera* camera, FrameResult& out);

 protected:
  explicit PipelineDetector(const Config& config) : Detector(config) {}
  /// Stage 1 into map_ (already sized).
  virtual void rasterize(const CameraRig& cam, std::span<const Sphere> spheres, int threads) = 0;
  /// Bytes held by the backend's own stages (raster, broadphase).
  [[nodiscard]] virtual std::uint64_t backend_memory_bytes() const = 0;
  /// Stages 4-8 over the active set; writes sorted pairs and stats (bits, layout, stage times).
  [[nodiscard]] virtual Status broadphase(std::span<const Sphere> spheres, std::span<const std::uint32_t> active,
                                          int bits, int threads, std::vector<Pair>& pairs, FrameStats& stats) = 0;

  VisibilityMap map_;

 private:
  std::vector<std::uint32_t> counts_, active_;
  std::vector<std::vector<std::uint32_t>> count_scratch_;
};

}  // namespace viscd::detail
