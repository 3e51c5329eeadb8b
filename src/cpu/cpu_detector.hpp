#pragma once
#include <algorithm>
#include <vector>

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
           bytes_of(unpaired_spheres_) + bytes_of(unpaired_ids_) + bytes_of(unpaired_filters_) + bytes_of(iota_);
  }
  /// The broadphase of the last frame (its 16-wide tree over buckets, the sorted objects and codes),
  /// for tests.
  [[nodiscard]] const BucketBroadphase& bucket_broadphase() const { return broadphase_; }

 protected:
  [[nodiscard]] bool answers_queries() const override { return true; }
  [[nodiscard]] bool query_ray_first(const Ray& ray, const Filter* filter, RayHit& hit) override;
  void query_ray_all(const Ray& ray, const Filter* filter, std::vector<RayHit>& hits) override;
  void query_ray_visit(const Ray& ray, const Filter* filter, RayVisitor& visitor) override;
  void query_sphere(const Sphere& sphere, const Filter* filter, std::vector<std::uint32_t>& indices) override;
  void query_box(const Box& box, const Filter* filter, std::vector<std::uint32_t>& indices) override;
  void query_sphere_visit(const Sphere& sphere, const Filter* filter, OverlapVisitor& visitor) override;
  void query_box_visit(const Box& box, const Filter* filter, OverlapVisitor& visitor) override;

 private:
  void rasterize(const CameraRig& cam, std::span<const Sphere> spheres, int threads) override {
    raster_.set_simd(simd_level_for(config_.simd));
    raster_.run(cam, spheres, threads, map_);
  }
  Status broadphase(std::span<const Sphere> spheres, std::span<const std::uint32_t> pairable,
                    std::span<const std::uint32_t> unpaired, std::span<const Filter> filters, int bits, int threads,
                    std::vector<Pair>& pairs, FrameStats& stats) override {
    // The objects left out of the tree, kept for queries with their filters (the tree's own
    // filters are kept in sorted order by the broadphase); no copy without filters.
    unpaired_built_ = false;
    resize_with_headroom(unpaired_ids_, unpaired.size());
    std::copy(unpaired.begin(), unpaired.end(), unpaired_ids_.begin());
    resize_with_headroom(unpaired_spheres_, unpaired.size());
    resize_with_headroom(unpaired_filters_, unpaired.size());
    for (std::size_t k = 0; k < unpaired.size(); ++k) {
      unpaired_spheres_[k] = spheres[unpaired[k]];
      unpaired_filters_[k] = filters[unpaired[k]];
    }
    broadphase_.set_keep_order(config_.keep_order);
    broadphase_.set_simd(simd_level_for(config_.simd));
    return broadphase_.run(spheres, pairable, filters, bits, config_.layout, threads, config_.pair_memory_cap, pairs,
                           stats);
  }
  const BucketBroadphase& unpaired_tree();
  /// What the unpaired tree's queries report: its ids map to unpaired_ids_, with their filters.
  [[nodiscard]] BucketBroadphase::Objects unpaired_objects() const { return {unpaired_ids_, unpaired_filters_}; }

  TiledRasterizer raster_;
  BucketBroadphase broadphase_;
  // Active objects outside the tree (ascending ids, their spheres) and their tree, built lazily.
  std::vector<std::uint32_t> unpaired_ids_, iota_;
  std::vector<Sphere> unpaired_spheres_;
  std::vector<Filter> unpaired_filters_;
  BucketBroadphase unpaired_tree_;
  FrameStats unpaired_stats_;  // the lazy build's stats, unused
  bool unpaired_built_ = false;
};

}  // namespace viscd::detail
