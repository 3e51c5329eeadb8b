#pragma once
#include <algorithm>
#include <atomic>
#include <mutex>
#include <vector>

#include "cpu/bucket_broadphase.hpp"
#include "cpu/grow.hpp"
#include "cpu/pipeline.hpp"
#include "cpu/raster.hpp"
#include "cpu/rest_set.hpp"
#include "cpu/static_tree.hpp"

namespace viscd::detail {

/// The fast CPU backend: a tiled sphere rasterizer (cpu/raster.hpp) and the bucket broadphase
/// (cpu/bucket_broadphase.hpp) on all cores (Config::executor).
///
/// Queries search the last frame's tree. Active objects that the filters left out of the tree
/// (they pair with nothing) are kept aside (a copy of their spheres, and of their boxes in box
/// frames) and get a tree of their own when the first query after the frame comes, so a frame
/// without queries never builds it.
class CpuDetector final : public PipelineDetector {
 public:
  explicit CpuDetector(const Config& config) : PipelineDetector(config) {}
  [[nodiscard]] std::string_view name() const override { return "cpu"; }
  [[nodiscard]] std::uint64_t backend_memory_bytes() const override {
    return raster_.memory_bytes() + box_raster_.memory_bytes() + broadphase_.memory_bytes() +
           unpaired_tree_.memory_bytes() + bytes_of(unpaired_spheres_) + bytes_of(unpaired_ids_) +
           bytes_of(unpaired_filters_) + bytes_of(iota_) + static_tree_.memory_bytes() + bytes_of(cross_) +
           bytes_of(merged_) + static_layer_.memory_bytes() + static_raster_.memory_bytes() +
           static_box_raster_.memory_bytes() + rest_.memory_bytes() + bytes_of(q_filters_) + bytes_of(unpaired_boxes_);
  }
  /// With FrameInput::moved while the rest set follows these objects: only the listed ones.
  [[nodiscard]] Status validate_frame_objects(const FrameInput& input) override;
  /// The broadphase of the last frame (its 16-wide tree over buckets, the sorted objects and codes),
  /// for tests.
  [[nodiscard]] const BucketBroadphase& bucket_broadphase() const { return broadphase_; }
  /// The rest set (Config::follow_change), for tests.
  [[nodiscard]] const RestSet& rest_set() const { return rest_; }

 protected:
  /// Every frame's queries search the trees (sphere or box lanes, as the frame's objects).
  [[nodiscard]] bool answers_queries() const override { return true; }
  /// The static set lives in static_tree_ (cpu/static_tree.hpp).
  [[nodiscard]] bool handles_static() const override { return true; }
  [[nodiscard]] bool query_ray_first(const Ray& ray, const Filter* filter, RayHit& hit) override;
  void query_ray_all(const Ray& ray, const Filter* filter, std::vector<RayHit>& hits) override;
  void query_ray_visit(const Ray& ray, const Filter* filter, RayVisitor& visitor) override;
  void query_sphere(const Sphere& sphere, const Filter* filter, std::vector<std::uint32_t>& indices) override;
  void query_box(const Box& box, const Filter* filter, std::vector<std::uint32_t>& indices) override;
  void query_sphere_visit(const Sphere& sphere, const Filter* filter, OverlapVisitor& visitor) override;
  void query_box_visit(const Box& box, const Filter* filter, OverlapVisitor& visitor) override;

 private:
  Status rasterize(const CameraRig& cam, const Shapes& objects, int threads) override {
    if (objects.is_box()) {
      box_raster_.run(cam, objects.boxes, threads, map_);
      return {};
    }
    rasterize_spheres(cam, objects.spheres, threads, nullptr);
    return {};
  }
  /// The spheres into map_, over `occluder`'s depth when given (TiledRasterizer::run()).
  void rasterize_spheres(const CameraRig& cam, std::span<const Sphere> spheres, int threads,
                         const VisibilityMap* occluder) {
    raster_.set_simd(simd_level_for(config_.simd));
    raster_.run(cam, spheres, threads, map_, occluder);
  }
  /// The static set's layer is drawn once per camera, map size and set version (static_layer_),
  /// and each frame's moving objects are drawn on their own. For a shaded image (or boxes) the
  /// two are merged pixel by pixel: the nearer wins, a tie goes to the moving object (its id is
  /// the smaller), so the map is the one a single pass over both would draw, bit for bit. For
  /// counts alone, the moving spheres are drawn over the layer's depth (TiledRasterizer's
  /// occluder), so that their counts are their visible pixels (the map keeps those alone).
  Status draw_frame(const CameraRig& cam, const Camera& camera, const FrameInput& in, int threads) override;
  Status follow_change(const FrameInput& in, const Shapes& objects, std::span<const std::uint32_t> active,
                       std::span<const Filter> filters, int bits, int threads, std::vector<Pair>& pairs,
                       FrameStats& stats, bool& done) override;
  [[nodiscard]] const std::uint64_t* followed_pair_bits() const override { return rest_.pair_bits(); }
  /// After a followed frame, before a tree query: the tree over its active objects (built on the
  /// first query after the frame).
  void prepare_queries();
  /// What the main tree's queries report: after a followed frame, the frame's filters by object.
  [[nodiscard]] BucketBroadphase::Objects main_objects() const {
    return followed_ ? BucketBroadphase::Objects{{}, q_filters_} : BucketBroadphase::Objects{};
  }
  Status broadphase(const Shapes& objects, std::span<const std::uint32_t> pairable,
                    std::span<const std::uint32_t> unpaired, std::span<const Filter> filters, std::uint32_t static_from,
                    int bits, int threads, std::vector<Pair>& pairs, FrameStats& stats) override;
  /// The pairs of the moving tree's objects with the static set, merged into `pairs`.
  Status static_pairs(int threads, std::vector<Pair>& pairs, FrameStats& stats);
  const BucketBroadphase& unpaired_tree();
  /// What the unpaired tree's queries report: its ids map to unpaired_ids_, with their filters.
  [[nodiscard]] BucketBroadphase::Objects unpaired_objects() const { return {unpaired_ids_, unpaired_filters_}; }

  TiledRasterizer raster_;
  BoxRasterizer box_raster_;
  StaticTree static_tree_;
  // The static set's map layer (ids: compact index + 1) and what it was drawn for.
  VisibilityMap static_layer_;
  TiledRasterizer static_raster_;
  BoxRasterizer static_box_raster_;
  struct LayerKey {
    Camera camera;
    int width = 0, height = 0;
    bool normals = false;
    std::uint64_t version = ~std::uint64_t{0};
  } layer_key_;
  std::vector<std::uint64_t> cross_;  // the frame's pairs with static objects (keys i << 32 | j)
  std::vector<Pair> merged_;
  BucketBroadphase broadphase_;
  // Active objects outside the tree (their reported indices, spheres (box frames: their proxies),
  // boxes (box frames), filters) and their tree, built lazily.
  std::vector<std::uint32_t> unpaired_ids_, iota_;
  std::vector<Sphere> unpaired_spheres_;
  std::vector<Box> unpaired_boxes_;
  std::vector<Filter> unpaired_filters_;
  BucketBroadphase unpaired_tree_;
  FrameStats unpaired_stats_;  // the lazy build's stats, unused
  // What the first query after a frame builds (the unpaired objects' tree; after a followed frame
  // the tree over its active objects): built once, under the mutex, so that queries may run from
  // many threads at once between frames.
  std::atomic<bool> unpaired_built_{false};
  std::mutex lazy_mutex_;
  // Cost follows change: the resting objects, whether the last frame was followed, its filters (by
  // object; empty without), and what its queries built.
  RestSet rest_;
  bool followed_ = false;
  bool defer_validation_ = false;  // validate_frame_objects() left the objects to follow_change()
  std::atomic<bool> query_tree_built_{false};
  std::vector<Filter> q_filters_;
  int q_bits_ = 32;
};

}  // namespace viscd::detail
