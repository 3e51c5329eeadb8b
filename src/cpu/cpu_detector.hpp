#pragma once
#include <algorithm>

#include "cpu/bucket_broadphase.hpp"
#include "cpu/grow.hpp"
#include "cpu/pipeline.hpp"
#include "cpu/raster.hpp"

namespace viscd::detail {

/// The fast CPU backend: a tiled sphere rasterizer (cpu/raster.hpp) and the bucket broadphase
/// (cpu/bucket_broadphase.hpp) on all cores (Config::executor).
///
/// Queries search the last frame's tree. Active objects that the filters left out of the tree
/// (they pair with nothing) are kept aside (a copy of their spheres) and get a tree of their own
/// when the first query after the frame comes, so a frame without queries never builds it.
class CpuDetector final : public PipelineDetector {
 public:
  explicit CpuDetector(const Config& config) : PipelineDetector(config) {}
  [[nodiscard]] std::string_view name() const override { return "cpu"; }
  [[nodiscard]] std::uint64_t backend_memory_bytes() const override {
    return raster_.memory_bytes() + broadphase_.memory_bytes() + unpaired_tree_.memory_bytes() +
           bytes_of(unpaired_spheres_) + bytes_of(unpaired_ids_) + bytes_of(iota_);
  }
  /// The broadphase of the last frame (its 16-wide tree over buckets, the sorted objects and codes),
  /// for tests.
  [[nodiscard]] const BucketBroadphase& bucket_broadphase() const { return broadphase_; }

 protected:
  [[nodiscard]] bool answers_queries() const override { return true; }
  [[nodiscard]] bool query_ray(const Ray& ray, RayHit& hit) override {
    bool found = broadphase_.ray_first(ray, {}, hit, false);
    if (!unpaired_ids_.empty()) found = unpaired_tree().ray_first(ray, unpaired_ids_, hit, found);
    return found;
  }
  void query_ray_all(const Ray& ray, std::vector<RayHit>& hits) override {
    broadphase_.ray_all(ray, {}, hits);
    if (!unpaired_ids_.empty()) unpaired_tree().ray_all(ray, unpaired_ids_, hits);
    std::sort(hits.begin(), hits.end(),
              [](const RayHit& a, const RayHit& b) { return a.t < b.t || (a.t == b.t && a.index < b.index); });
  }
  void query_overlap(const Sphere& sphere, std::vector<std::uint32_t>& indices) override {
    broadphase_.overlap(sphere, {}, indices);
    if (!unpaired_ids_.empty()) unpaired_tree().overlap(sphere, unpaired_ids_, indices);
    std::sort(indices.begin(), indices.end());
  }

 private:
  void rasterize(const CameraRig& cam, std::span<const Sphere> spheres, int threads) override {
    raster_.set_simd(simd_level_for(config_.simd));
    raster_.run(cam, spheres, threads, map_);
  }
  Status broadphase(std::span<const Sphere> spheres, std::span<const std::uint32_t> pairable,
                    std::span<const std::uint32_t> unpaired, std::span<const Filter> filters, int bits, int threads,
                    std::vector<Pair>& pairs, FrameStats& stats) override {
    // The objects left out of the tree, kept for queries (no copy without filters).
    unpaired_built_ = false;
    resize_with_headroom(unpaired_ids_, unpaired.size());
    std::copy(unpaired.begin(), unpaired.end(), unpaired_ids_.begin());
    resize_with_headroom(unpaired_spheres_, unpaired.size());
    for (std::size_t k = 0; k < unpaired.size(); ++k) unpaired_spheres_[k] = spheres[unpaired[k]];
    broadphase_.set_keep_order(config_.keep_order);
    broadphase_.set_simd(simd_level_for(config_.simd));
    return broadphase_.run(spheres, pairable, filters, bits, config_.layout, threads, config_.pair_memory_cap, pairs,
                           stats);
  }
  const BucketBroadphase& unpaired_tree();

  TiledRasterizer raster_;
  BucketBroadphase broadphase_;
  // Active objects outside the tree (ascending ids, their spheres) and their tree, built lazily.
  std::vector<std::uint32_t> unpaired_ids_, iota_;
  std::vector<Sphere> unpaired_spheres_;
  BucketBroadphase unpaired_tree_;
  FrameStats unpaired_stats_;  // the lazy build's stats, unused
  bool unpaired_built_ = false;
};

}  // namespace viscd::detail
