#include "cpu/cpu_detector.hpp"

#include <algorithm>
#include <utility>

#include "core/brute_queries.hpp"
#include "core/frame_rules.hpp"
#include "core/geometry.hpp"
#include "core/stopwatch.hpp"
#include "cpu/parallel.hpp"
#include "viscd/assert.hpp"

namespace viscd {
namespace detail {

Status CpuDetector::draw_frame(const CameraRig& cam, const Camera& camera, const FrameInput& in, int threads) {
  const Shapes moving = Shapes::of(in);
  if (static_set_.empty()) return rasterize(cam, moving, threads);
  // The static layer, redrawn only when the camera, the map or the set changed.
  const bool normals = !map_.normal.empty();
  if (layer_key_.camera != camera || layer_key_.width != map_.width || layer_key_.height != map_.height ||
      layer_key_.normals != normals || layer_key_.version != static_set_.version()) {
    static_layer_.resize(map_.width, map_.height, normals);
    const Shapes st = static_set_.compact().shapes;
    if (st.is_box()) {
      static_box_raster_.run(cam, st.boxes, threads, static_layer_);
    } else {
      static_raster_.set_simd(simd_level_for(config_.simd));
      static_raster_.run(cam, st.spheres, threads, static_layer_);
    }
    layer_key_ = {camera, map_.width, map_.height, normals, static_set_.version()};
  }
  if (!moving.is_box() && !normals) {
    // Counts only (no image): the moving spheres are drawn over the static layer's depth (a tie
    // to the moving one), so that the map and the counts hold their visible pixels alone and the
    // cost follows the moving objects. The map keeps no static id, which nothing reads without an
    // image.
    rasterize_spheres(cam, moving.spheres, threads, &static_layer_);
    return {};
  }
  if (Status s = rasterize(cam, moving, threads); !s) return s;
  const auto n = static_cast<std::uint32_t>(moving.size());
  const std::size_t w = static_cast<std::size_t>(map_.width);
  // Merge: per pixel the nearer of the two, a tie to the moving object (the smaller id); the
  // static ids move up by N. The counts are taken afterwards, from the merged ids (keeping the
  // rasterizer's and subtracting the hidden pixels with atomics over every pixel was slower:
  // 4.6 against 2.9 ms).
  map_.has_counts = false;
  map_.stamp = 0;
  parallel_for(static_cast<std::size_t>(map_.height), threads, [&](std::size_t y) {
    for (std::size_t i = y * w; i < (y + 1) * w; ++i) {
      const std::uint32_t s = static_layer_.ids[i];
      if (s == 0) continue;
      const std::uint32_t m = map_.ids[i];
      if (m != 0 && !(static_layer_.depth[i] < map_.depth[i])) continue;
      map_.ids[i] = s + n;
      map_.depth[i] = static_layer_.depth[i];
      if (normals)
        for (int c = 0; c < 3; ++c) map_.normal[3 * i + c] = static_layer_.normal[3 * i + c];
    }
  });
  return {};
}

Status CpuDetector::follow_change(const FrameInput& in, const Shapes& objects, std::span<const std::uint32_t> active,
                                  std::span<const Filter> filters, int bits, int threads, std::vector<Pair>& pairs,
                                  FrameStats& stats, bool& done) {
  done = false;
  followed_ = false;
  const bool unvalidated = std::exchange(defer_validation_, false);
  if (!config_.follow_change) {
    rest_.reset();
    return unvalidated ? validate_objects(objects) : Status{};
  }
  static_tree_.update(static_set_, config_.layout, threads);
  RestSet::Input ri;
  ri.objects = objects;
  ri.active = active;
  ri.filters = filters;
  ri.moved = in.moved;
  ri.moved_listed = in.moved_listed;
  ri.verify_moved = config_.verify_moved;
  ri.margin = config_.rest_margin;
  ri.move_margin = config_.move_margin;
  ri.layout = config_.layout;
  ri.bits = bits;
  ri.pair_memory_cap = config_.pair_memory_cap;
  ri.simd = simd_level_for(config_.simd);
  ri.unvalidated = unvalidated;
  if (Status s = rest_.run(ri, static_set_, static_tree_, threads, pairs, stats, done); !s) return s;
  if (!done && rest_.needs_validation()) {
    // The set did not follow the frame before it checked every object: they are checked here,
    // and the frame runs again (or rebuilds) as it would have.
    if (Status s = validate_objects(objects); !s) return s;
    if (rest_.run_again()) {
      ri.unvalidated = false;
      if (Status s = rest_.run(ri, static_set_, static_tree_, threads, pairs, stats, done); !s) return s;
    }
  }
  if (!done) return {};
  // Queries after the frame: its objects are the rest set's copy; their tree comes on demand.
  followed_ = true;
  query_tree_built_.store(false);
  q_bits_ = bits;
  unpaired_ids_.clear();
  unpaired_spheres_.clear();
  unpaired_boxes_.clear();
  unpaired_filters_.clear();
  unpaired_built_.store(false);
  q_filters_.assign(filters.begin(), filters.end());
  return {};
}

Status CpuDetector::validate_frame_objects(const FrameInput& in) {
  const Shapes objects = Shapes::of(in);
  defer_validation_ = false;
  if (config_.follow_change && rest_.follows(objects) && in.camera == nullptr && in.id_map.empty() &&
      !(in.moved_listed && config_.verify_moved)) {
    // The rest set compares every object (or every listed one) with its copy from the last frame
    // (valid then) and checks each that changed (cpu/rest_set.hpp, needs_validation());
    // follow_change() checks them all when it does not. Nothing reads them before it: no map is
    // drawn.
    defer_validation_ = true;
    return {};
  }
  if (!in.moved_listed || !config_.follow_change || !rest_.follows(objects) || config_.verify_moved)
    return validate_objects(objects);
  // The others are the objects the last frame checked, bit for bit (the list's promise).
  bool ok = true;
  for (const std::uint32_t k : in.moved) {  // validate_frame_input() checked the entries
    ok &= objects.is_box() ? boxes_all_valid(objects.boxes.subspan(k, 1))
                           : spheres_all_valid(objects.spheres.subspan(k, 1));
  }
  return ok ? Status{} : validate_objects(objects);  // names the first bad object
}

void CpuDetector::prepare_queries() {
  if (!followed_ || query_tree_built_.load(std::memory_order_acquire)) return;
  const std::lock_guard<std::mutex> lock(lazy_mutex_);
  if (query_tree_built_.load(std::memory_order_relaxed)) return;
  const ExecutorScope scope(config_.executor);
  const int threads = frame_threads();
  FrameStats unused;
  const Shapes objects = rest_.objects();
  const std::span<const std::uint32_t> active = last_active();
  if (objects.is_box()) {
    BucketBroadphase::Extras extras;
    extras.boxes = objects.boxes;
    broadphase_.build({}, active, q_bits_, config_.layout, threads, unused, extras);  // it makes the proxies
  } else {
    broadphase_.build(objects.spheres, active, q_bits_, config_.layout, threads, unused);
  }
  query_tree_built_.store(true, std::memory_order_release);
}

Status CpuDetector::broadphase(const Shapes& objects, std::span<const std::uint32_t> pairable,
                               std::span<const std::uint32_t> unpaired, std::span<const Filter> filters,
                               std::uint32_t static_from, int bits, int threads, std::vector<Pair>& pairs,
                               FrameStats& stats) {
  followed_ = false;
  // The static set is static_tree_'s (handles_static()): `objects` are the frame's alone.
  VISCD_ASSERT(static_from == ~0u, "the cpu backend's frames hold no static objects");
  (void)static_from;
  // Box frames: stages 4-6 order the boxes' proxies, which the broadphase makes when it sorts;
  // stages 7-8 pack and test the boxes.
  const std::span<const Sphere> spheres = objects.spheres;
  BucketBroadphase::Extras extras;
  if (objects.is_box()) extras.boxes = objects.boxes;
  // The objects left out of the tree, kept for queries with their filters (the tree's own
  // filters are kept in sorted order by the broadphase); no copy without filters.
  unpaired_built_.store(false);
  const std::size_t kept = unpaired.size();
  resize_with_headroom(unpaired_ids_, kept);
  resize_with_headroom(unpaired_spheres_, kept);
  resize_with_headroom(unpaired_boxes_, objects.is_box() ? kept : 0);
  resize_with_headroom(unpaired_filters_, kept);
  for (std::size_t k = 0; k < kept; ++k) {
    unpaired_ids_[k] = unpaired[k];
    unpaired_spheres_[k] = objects.is_box() ? box_proxy(objects.boxes[unpaired[k]]) : spheres[unpaired[k]];
    if (objects.is_box()) unpaired_boxes_[k] = objects.boxes[unpaired[k]];
    unpaired_filters_[k] = filters[unpaired[k]];
  }
  broadphase_.set_keep_order(config_.keep_order);
  broadphase_.set_simd(simd_level_for(config_.simd));
  if (Status s = broadphase_.run(spheres, pairable, filters, bits, config_.layout, threads, config_.pair_memory_cap,
                                 pairs, stats, extras);
      !s)
    return s;
  return static_pairs(threads, pairs, stats);
}

Status CpuDetector::static_pairs(int threads, std::vector<Pair>& pairs, FrameStats& stats) {
  Stopwatch sw;
  static_tree_.update(static_set_, config_.layout, threads);
  if (static_tree_.size() == 0) return {};
  const std::size_t allowed = pairs_within_cap(config_.pair_memory_cap);
  const std::size_t room = allowed > pairs.size() ? allowed - pairs.size() : 0;
  if (!static_tree_.pairs(broadphase_, broadphase_.sorted_filters(), true, simd_level_for(config_.simd), threads, room,
                          cross_))
    return check_pair_cap(pairs.size() + room + 1, config_.pair_memory_cap, true);
  // Merge: for each i the moving pairs come first (every static index is above every moving one).
  if (!cross_.empty()) {
    merged_.resize(pairs.size() + cross_.size());
    std::size_t a = 0, b = 0, o = 0;
    while (a < pairs.size() || b < cross_.size()) {
      const bool take_cross = a == pairs.size() || (b < cross_.size() && (cross_[b] >> 32) < pairs[a].i);
      if (take_cross) {
        merged_[o++] = Pair{static_cast<std::uint32_t>(cross_[b] >> 32), static_cast<std::uint32_t>(cross_[b])};
        ++b;
      } else {
        merged_[o++] = pairs[a++];
      }
    }
    pairs.swap(merged_);
  }
  stats.pairs = pairs.size();
  stats.ms(Stage::query) += sw.lap();
  return {};
}

const BucketBroadphase& CpuDetector::unpaired_tree() {
  if (!unpaired_built_.load(std::memory_order_acquire)) {
    const std::lock_guard<std::mutex> lock(lazy_mutex_);
    if (unpaired_built_.load(std::memory_order_relaxed)) return unpaired_tree_;
    const ExecutorScope scope(config_.executor);
    const int threads = frame_threads();
    const std::size_t n = unpaired_spheres_.size();
    if (iota_.size() < n) {
      const std::size_t old = iota_.size();
      iota_.resize(n);
      for (std::size_t k = old; k < n; ++k) iota_[k] = static_cast<std::uint32_t>(k);
    }
    BucketBroadphase::Extras extras;
    extras.boxes = unpaired_boxes_;  // box frames: the boxes themselves in the lanes
    unpaired_tree_.build(unpaired_spheres_, std::span<const std::uint32_t>(iota_.data(), n), 32, config_.layout,
                         threads, unpaired_stats_, extras);
    unpaired_built_.store(true, std::memory_order_release);
  }
  return unpaired_tree_;
}

// Each query searches the main tree, then the unpaired objects' tree (built on the first query
// that needs it), then the static set's trees; box frames' trees test box lanes. Detector sorts
// the lists.

bool CpuDetector::query_ray_first(const Ray& ray, const Filter* filter, RayHit& hit) {
  prepare_queries();
  bool found = broadphase_.ray_first(ray, main_objects(), filter, hit, false);
  if (!unpaired_ids_.empty()) found = unpaired_tree().ray_first(ray, unpaired_objects(), filter, hit, found);
  StaticTree::Part parts[2];
  for (std::size_t k = 0, n = static_tree_.parts(parts); k < n; ++k)
    found = parts[k].tree->ray_first(ray, parts[k].objects, filter, hit, found);
  return found;
}

void CpuDetector::query_ray_all(const Ray& ray, const Filter* filter, std::vector<RayHit>& hits) {
  prepare_queries();
  broadphase_.ray_all(ray, main_objects(), filter, hits);
  if (!unpaired_ids_.empty()) unpaired_tree().ray_all(ray, unpaired_objects(), filter, hits);
  StaticTree::Part parts[2];
  for (std::size_t k = 0, n = static_tree_.parts(parts); k < n; ++k)
    parts[k].tree->ray_all(ray, parts[k].objects, filter, hits);
}

void CpuDetector::query_ray_visit(const Ray& ray, const Filter* filter, RayVisitor& visitor) {
  prepare_queries();
  float max_t = ray.max_t;  // lowered by the visitor in the first tree, it prunes the second
  if (!broadphase_.ray_visit(ray, main_objects(), filter, max_t, visitor)) return;
  if (!unpaired_ids_.empty() && !unpaired_tree().ray_visit(ray, unpaired_objects(), filter, max_t, visitor)) return;
  StaticTree::Part parts[2];
  for (std::size_t k = 0, n = static_tree_.parts(parts); k < n; ++k)
    if (!parts[k].tree->ray_visit(ray, parts[k].objects, filter, max_t, visitor)) return;
}

void CpuDetector::query_sphere(const Sphere& sphere, const Filter* filter, std::vector<std::uint32_t>& indices) {
  prepare_queries();
  broadphase_.overlap(sphere, main_objects(), filter, indices);
  if (!unpaired_ids_.empty()) unpaired_tree().overlap(sphere, unpaired_objects(), filter, indices);
  StaticTree::Part parts[2];
  for (std::size_t k = 0, n = static_tree_.parts(parts); k < n; ++k)
    parts[k].tree->overlap(sphere, parts[k].objects, filter, indices);
}

void CpuDetector::query_box(const Box& box, const Filter* filter, std::vector<std::uint32_t>& indices) {
  prepare_queries();
  broadphase_.overlap_box(box, main_objects(), filter, indices);
  if (!unpaired_ids_.empty()) unpaired_tree().overlap_box(box, unpaired_objects(), filter, indices);
  StaticTree::Part parts[2];
  for (std::size_t k = 0, n = static_tree_.parts(parts); k < n; ++k)
    parts[k].tree->overlap_box(box, parts[k].objects, filter, indices);
}

void CpuDetector::query_sphere_visit(const Sphere& sphere, const Filter* filter, OverlapVisitor& visitor) {
  prepare_queries();
  if (!broadphase_.overlap_visit(sphere, main_objects(), filter, visitor)) return;
  if (!unpaired_ids_.empty() && !unpaired_tree().overlap_visit(sphere, unpaired_objects(), filter, visitor)) return;
  StaticTree::Part parts[2];
  for (std::size_t k = 0, n = static_tree_.parts(parts); k < n; ++k)
    if (!parts[k].tree->overlap_visit(sphere, parts[k].objects, filter, visitor)) return;
}

void CpuDetector::query_box_visit(const Box& box, const Filter* filter, OverlapVisitor& visitor) {
  prepare_queries();
  if (!broadphase_.overlap_box_visit(box, main_objects(), filter, visitor)) return;
  if (!unpaired_ids_.empty() && !unpaired_tree().overlap_box_visit(box, unpaired_objects(), filter, visitor)) return;
  StaticTree::Part parts[2];
  for (std::size_t k = 0, n = static_tree_.parts(parts); k < n; ++k)
    if (!parts[k].tree->overlap_box_visit(box, parts[k].objects, filter, visitor)) return;
}

}  // namespace detail

std::unique_ptr<Detector> make_cpu_detector(const Config& config) {
  return detail::DetectorAccess::wrap(std::make_unique<detail::CpuDetector>(config));
}

}  // namespace viscd
