#pragma once
#include "cpu/bucket_broadphase.hpp"
#include "cpu/pipeline.hpp"
#include "cpu/raster.hpp"

namespace viscd::detail {

/// The fast CPU backend: tiled rasterizer + bucketed LBVH broadphase on all cores (Config::executor).
class CpuDetector final : public PipelineDetector {
 public:
  explicit CpuDetector(const Config& config) : PipelineDetector(config) {}
  [[nodiscard]] std::string_view name() const override { return "cpu"; }
  [[nodiscard]] std::uint64_t backend_memory_bytes() const override {
    return raster_.memory_bytes() + broadphase_.memory_bytes();
  }
  /// The broadphase of the last frame (tree, codes), for tests.
  [[nodiscard]] const BucketBroadphase& lbvh() const { return broadphase_; }

 private:
  void rasterize(const CameraRig& cam, std::span<const Sphere> spheres, int threads) override {
    raster_.run(cam, spheres, threads, map_);
  }
  Status broadphase(std::span<const Sphere> spheres, std::span<const std::uint32_t> active, int bits, int threads,
                    std::vector<Pair>& pairs, FrameStats& stats) override {
    return broadphase_.run(spheres, active, bits, config_.layout, threads, config_.pair_memory_cap, pairs, stats);
  }

  TiledRasterizer raster_;
  BucketBroadphase broadphase_;
};

}  // namespace viscd::detail
