#pragma once
// The cpu backend's broadphase (stages 4-8): the objects in Morton order cut into buckets of 16
// consecutive objects, a 16-wide tree over the buckets, and a sort that starts from the last
// frame's order. Exact: the result equals brute force over the active set for every m
// (tests/cpu/). This class runs the stages in order; each idea lives in a unit of its own:
//
//   keep the order  cpu/keep_order.hpp     when the last frame's order is kept (stages 4-6 skipped)
//   stages 4-6      cpu/morton_order.hpp   layout, codes, sort (cpu/nearly_sorted.hpp, radix_sort.hpp)
//   stage 7 build   cpu/buckets.hpp        the objects packed into bucket lanes, the bucket boxes
//   stage 7 fit     cpu/wide_tree.hpp      the 16-wide tree over the bucket boxes
//   stage 8         cpu/bucket_search.hpp  the pairs, bucket against bucket with SIMD lanes
//   queries         cpu/bucket_queries.cpp rays and overlaps on the last tree
//
// Why a 16-wide tree over buckets rather than the paper's Karras tree over objects:
// cpu/wide_tree.hpp and docs/architecture.md ("The cpu broadphase, stage by stage").
//
// The tree, the lanes and the sorted ids stay until the next frame: the ray and overlap queries
// (Detector::ray_cast, overlap) search them.

#include <cstdint>
#include <span>
#include <vector>

#include "core/brute_queries.hpp"
#include "cpu/buckets.hpp"
#include "cpu/keep_order.hpp"
#include "cpu/morton_order.hpp"
#include "cpu/pair_collector.hpp"
#include "cpu/simd.hpp"
#include "cpu/wide_tree.hpp"
#include "viscd/config.hpp"
#include "viscd/detector.hpp"
#include "viscd/frame.hpp"
#include "viscd/result.hpp"
#include "viscd/types.hpp"

namespace viscd::detail {

/// What a frame may add to its spheres: for a box frame the boxes (then the spheres are their
/// box_proxy(), which stages 4-6 order, and stages 7-8 pack and test the boxes themselves). A box
/// frame may give no spheres at all: the broadphase then makes the proxies itself, and only when
/// the frame sorts (a frame that keeps the last order reads the boxes alone).
struct BroadphaseExtras {
  std::span<const Box> boxes;
};

class BucketBroadphase {
 public:
  using Extras = BroadphaseExtras;
  /// Finds all overlapping pairs among spheres[active[k]] (active ascending) with m-bit codes.
  /// Writes sorted pairs, stats.bits, stats.layout, stats.order_kept and the stage times of
  /// stages 4-8. Fails only when the pairs would exceed pair_memory_cap bytes (0 = no cap).
  /// `filters` is empty or one per sphere: a pair is reported only when pair_passes_filter().
  [[nodiscard]] Status run(std::span<const Sphere> spheres, std::span<const std::uint32_t> active,
                           std::span<const Filter> filters, int bits, Layout layout, int threads,
                           std::size_t pair_memory_cap, std::vector<Pair>& pairs, FrameStats& stats,
                           const Extras& extras = {});
  /// run() without filters.
  [[nodiscard]] Status run(std::span<const Sphere> spheres, std::span<const std::uint32_t> active, int bits,
                           Layout layout, int threads, std::size_t pair_memory_cap, std::vector<Pair>& pairs,
                           FrameStats& stats) {
    return run(spheres, active, {}, bits, layout, threads, pair_memory_cap, pairs, stats);
  }
  /// Stages 4-7 only: the tree over spheres[active[k]], for queries. Writes stats.bits, layout and
  /// the stage times.
  void build(std::span<const Sphere> spheres, std::span<const std::uint32_t> active, int bits, Layout layout,
             int threads, FrameStats& stats, const Extras& extras = {});
  /// Whether the last tree holds boxes (box lanes: its queries test the boxes themselves).
  [[nodiscard]] bool holds_boxes() const { return !extras_.boxes.empty(); }

  /// What the queries report of the tree's objects. A tree object's id is its index in the
  /// spheres the tree was built from; it is reported as ids[id] when `ids` is not empty. Its
  /// filter is filters[id] when `filters` is not empty, else the frame's filter (run() with
  /// filters), else Filter{}.
  struct Objects {
    std::span<const std::uint32_t> ids;
    std::span<const Filter> filters;
  };

  /// Queries on the last tree (docs/architecture.md, "Queries"); `filter` is the query's filter
  /// or null (query_passes()). Results are appended unsorted.
  /// ray_first: the first hit (smallest t, ties to the smaller reported index) if it comes before
  /// `best` (when `found`); returns whether there is a hit now.
  [[nodiscard]] bool ray_first(const Ray& ray, const Objects& objects, const Filter* filter, RayHit& best,
                               bool found) const;
  /// Appends every hit.
  void ray_all(const Ray& ray, const Objects& objects, const Filter* filter, std::vector<RayHit>& hits) const;
  /// The hits through `visitor`, as Detector::ray_cast(ray, visitor): the walk prunes by the max t
  /// `max_t`, which the visitor's answers lower (and which carries over to a next tree). Returns
  /// false when the visitor stopped the query.
  [[nodiscard]] bool ray_visit(const Ray& ray, const Objects& objects, const Filter* filter, float& max_t,
                               RayVisitor& visitor) const;
  /// Appends the objects that overlap `sphere` by overlap_exact().
  void overlap(const Sphere& sphere, const Objects& objects, const Filter* filter,
               std::vector<std::uint32_t>& out) const;
  /// Appends the objects that overlap `box` (finite, min <= max) by sphere_box_exact().
  void overlap_box(const Box& box, const Objects& objects, const Filter* filter, std::vector<std::uint32_t>& out) const;
  /// overlap() and overlap_box() through a visitor; false when it stopped the query.
  [[nodiscard]] bool overlap_visit(const Sphere& sphere, const Objects& objects, const Filter* filter,
                                   OverlapVisitor& visitor) const;
  [[nodiscard]] bool overlap_box_visit(const Box& box, const Objects& objects, const Filter* filter,
                                       OverlapVisitor& visitor) const;

  /// Inspection for tests: the last frame's tree over buckets, the bucket boxes, the objects in
  /// sorted order, the sorted codes (widened to 64 bits) and how the sort went.
  [[nodiscard]] const WideTree& tree() const { return tree_; }
  [[nodiscard]] std::span<const Aabb> leaf_boxes() const { return buckets_.boxes(); }
  /// The objects in lanes (sphere or box lanes, as holds_boxes()), and their filters in sorted
  /// order (frames with filters).
  [[nodiscard]] std::span<const BucketLanes> lanes() const { return buckets_.lanes(); }
  [[nodiscard]] std::span<const BoxLanes> box_lanes() const { return buckets_.box_lanes(); }
  [[nodiscard]] std::span<const Filter> sorted_filters() const { return buckets_.sorted_filters(); }
  /// Takes object `id` (an index into the spheres the tree was built from) out of the tree, so
  /// that no pair or query finds it; the tree's boxes stay. For trees kept across frames (the
  /// static set's). Calls for distinct objects may run from several threads at once once
  /// index_positions() has run since the tree was built.
  void erase(std::uint32_t id);
  /// Makes the index erase() reads (object id to sorted position), if it is not made yet, on up
  /// to `threads` threads.
  void index_positions(int threads = 1);
  [[nodiscard]] std::span<const std::uint32_t> sorted_objects() const { return order_.sorted_ids(); }
  [[nodiscard]] std::vector<std::uint64_t> sorted_codes() const { return order_.sorted_codes(); }
  [[nodiscard]] const SortReport& sort_report() const { return report_; }
  /// Forget the last frame's order: the next frame sorts from scratch.
  void reset_order() { order_.forget(); }
  /// Whether frames may keep the last order (Config::keep_order; default on). Off, every frame
  /// sorts: for tests of the sort and for measurements.
  void set_keep_order(bool on) { keep_order_.set_enabled(on); }
  /// The SIMD kernels stage 8 uses (Config::simd; default: the best this CPU has).
  void set_simd(SimdLevel level) { simd_ = usable_simd_level(level); }
  /// Bytes of every buffer held (capacities).
  [[nodiscard]] std::uint64_t memory_bytes() const;

 private:
  /// Stages 4-7: keeps the last order when the policy allows, else sorts.
  void build_tree(std::span<const Sphere> spheres, std::span<const std::uint32_t> active,
                  std::span<const Filter> filters, int bits, Layout layout, int threads, FrameStats& stats);
  /// Stage 7 keeping the last order; false (and nothing usable built) when this frame must sort.
  bool keep_last_order(std::span<const Sphere> spheres, std::span<const std::uint32_t> active,
                       std::span<const Filter> filters, int bits, Layout layout, int threads, FrameStats& stats);
  /// Stage 7's fit: the 16-wide tree over the buckets of n objects (checked with VISCD_VALIDATE).
  void fit_tree(std::size_t n, int threads, FrameStats& stats);
  /// Stage 8.
  Status find_pairs(std::span<const std::uint32_t> active, int threads, std::size_t pair_memory_cap,
                    std::vector<Pair>& pairs, FrameStats& stats);
  template <class Visit>
  void ray_walk(const Ray& ray, double& t_hi, Visit&& visit) const;
  /// Calls hit(index, t) for each sphere that passes `filter` and that the ray hits with
  /// t <= max_t (both of which the calls may lower; a negative t_hi ends the walk); index is the
  /// reported index.
  template <class Hit>
  void ray_hits(const Ray& ray, const Objects& objects, const Filter* filter, double& t_hi, const float& max_t,
                Hit&& hit) const;
  /// Calls found(index) for each object that passes `filter` and `exact(sphere)` (sphere lanes) or
  /// `exact(box)` (box lanes), among those whose conservative box (or box) meets `box`, until
  /// found() returns false; returns false then.
  template <class Exact, class Found>
  bool overlap_walk(const Aabb& box, const Objects& objects, const Filter* filter, Exact&& exact, Found&& found) const;
  /// overlap_walk() for a sphere query: each object that overlaps `sphere` (overlap_exact() on
  /// sphere lanes, sphere_box_exact() on box lanes).
  template <class Found>
  bool sphere_overlap_walk(const Sphere& sphere, const Objects& objects, const Filter* filter, Found&& found) const;
  /// A box tree's rays widen its boxes by this much more than ray_box_margin() (RaySetup): the
  /// tree's boxes are the objects' boxes, with no conservative margin around them.
  [[nodiscard]] double box_ray_margin() const;
  /// Whether the object at sorted position p passes the query's filter (null: none).
  [[nodiscard]] bool passes(const Filter* filter, std::size_t p, const Objects& objects) const {
    if (filter == nullptr) return true;
    if (!objects.filters.empty()) return pair_passes_filter(*filter, objects.filters[order_.sorted_ids()[p]]);
    const std::span<const Filter> sorted = buckets_.sorted_filters();
    return pair_passes_filter(*filter, sorted.empty() ? Filter{} : sorted[p]);
  }
  /// The index a query reports for the object at sorted position p.
  [[nodiscard]] std::uint32_t reported(std::size_t p, const Objects& objects) const {
    const std::uint32_t id = order_.sorted_ids()[p];
    return objects.ids.empty() ? id : objects.ids[id];
  }

  KeepOrderPolicy keep_order_;
  MortonOrder order_;
  Buckets buckets_;
  WideTree tree_;
  PairCollector pairs_;
  /// Stage 7's packing of the objects in `ids` order: box lanes in box frames (from the frame's
  /// boxes), sphere lanes else (the k-th from sphere_at(k)).
  template <class SphereAt>
  double fill(std::size_t n, std::span<const std::uint32_t> ids, std::span<const Filter> filters, int threads,
              SphereAt&& sphere_at);
  /// fill() reading spheres[ids[k]], prefetched: the reads are out of the array's order.
  double fill_reading(std::span<const Sphere> spheres, std::size_t n, std::span<const std::uint32_t> ids,
                      std::span<const Filter> filters, int threads);

  /// The objects of this frame: its spheres, or its boxes when it gave none.
  [[nodiscard]] std::size_t objects_in(std::span<const Sphere> spheres) const {
    return spheres.empty() ? extras_.boxes.size() : spheres.size();
  }
  /// box_proxy() of each of this frame's boxes, in proxies_.
  std::span<const Sphere> box_proxies(int threads);

  SimdLevel simd_ = best_simd_level();
  SortReport report_;
  Extras extras_;                        // this frame's
  std::vector<Sphere> proxies_;          // box frames that gave no spheres, when they sort
  std::vector<std::uint32_t> position_;  // erase(): object id -> sorted position, made on first use
};

}  // namespace viscd::detail
