#pragma once
// The cpu backend's broadphase (stages 4-8): the objects in Morton order cut into buckets of
// kBucket consecutive objects, a 16-wide tree over the buckets, and a sort that starts from the
// last frame's order. Exact: the result equals brute force over the active set for every m
// (tests/cpu/).
//
// Why buckets (docs/benchmarks.md, "The broadphase at the limit"): with one leaf per object most of
// the build, fit and query time goes to the bottom levels of the tree, where boxes hardly prune.
// Cutting the tree at kBucket objects makes it kBucket times smaller, and the objects of two
// buckets whose boxes overlap are compared all against all with SIMD lanes, out of contiguous
// arrays. Why a 16-wide tree over them rather than the paper's Karras tree: cpu/wide_tree.hpp.
//
//   kept order: when the active set is the last frame's, stages 4-6 are skipped and the last
//                     frame's order is kept: stage 7 refills the buckets in it with the objects'
//                     new positions, and the tree is rebuilt over their boxes (a refit). Kept
//                     while the bucket boxes' summed size and the query's bucket-pair count stay
//                     within kStaleness of those of the last sorted frame; else the frame sorts
//                     (docs/architecture.md, "The cpu broadphase, stage by stage"). Exact either way: any grouping
//                     of the objects into buckets gives the same pairs.
//   stage 4  layout:  extent of the active centres, Morton layout (shared with every backend)
//   stage 5  codes:   one code per active object; with a last order, the spheres are gathered in
//                     it (the one read of the caller's array out of its order) and coded there
//   stage 6  sort:    the last frame's order, filtered to this frame's active set, finished by
//                     insertion within 32 places, the objects that moved farther sorted apart and
//                     merged in; an LSD radix sort when there is no last order or a quarter of the
//                     objects moved far. Both give the same order: by code, ties by object id.
//   stage 7  build:   objects gathered into per-bucket lanes (x, y, z, r and the conservative half
//                     extent) and the bucket boxes; fit: the 16-wide tree over the buckets
//   stage 8  query:   per bucket, pairs inside it, then every later bucket whose box overlaps (the
//                     tree walk masks off earlier buckets); per object of the bucket a box test,
//                     then the exact test against the other bucket's lanes, then the pair's filters
//                     (when there are any: few candidates pass the exact test); pairs sorted at the
//                     end.
//
// The tree, the lanes and the sorted ids stay until the next frame: the ray and overlap queries
// (Detector::ray_cast, overlap) search them.

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "core/frame_rules.hpp"
#include "core/morton.hpp"
#include "cpu/broadphase.hpp"
#include "cpu/radix_sort.hpp"
#include "cpu/simd.hpp"
#include "cpu/wide_tree.hpp"
#include "viscd/config.hpp"
#include "viscd/frame.hpp"
#include "viscd/result.hpp"
#include "viscd/types.hpp"

namespace viscd::detail {

/// Objects per leaf bucket: 16 beat 4 and 8 (docs/benchmarks.md, "The broadphase at the limit").
inline constexpr std::uint32_t kBucket = 16;  // the SIMD kernels (cpu/simd.hpp) are 16 lanes wide
static_assert(kBucket == 16, "the SIMD kernels (cpu/simd.hpp) test 16 lanes");

/// The objects of one bucket in lanes; unused lanes hold NaN centres, which overlap nothing.
struct alignas(32) BucketLanes {
  float x[kBucket], y[kBucket], z[kBucket], r[kBucket];
  float h[kBucket];  ///< half extent of the object's conservative_box()
};

/// A kept order stays while the bucket boxes' summed size, and the count of bucket pairs whose
/// boxes overlap, exceed those of the last sorted frame by at most this fraction.
inline constexpr double kStaleness = 1.0 / 16;

/// How the last frame's stages 5-6 went (for tests and the bench).
struct SortReport {
  bool kept = false;        ///< the last order was kept: stages 4-6 skipped (then reused is false)
  bool reused = false;      ///< sorted from the last frame's order (else by the radix sort)
  std::uint64_t moves = 0;  ///< entries shifted by insertions within reach (also when it gave up)
  std::uint64_t far = 0;    ///< entries set aside, sorted and merged in
};

/// An entry of the sort from the last order: the code (packed with the id, when the code has at
/// most 32 bits), the object id, and its place in the last order (in the gathered spheres).
struct SortEntry {
  std::uint64_t key;
  std::uint32_t id, at;
};

class BucketBroadphase {
 public:
  /// Finds all overlapping pairs among spheres[active[k]] (active ascending) with m-bit codes.
  /// Writes sorted pairs, stats.bits, stats.layout and the stage times of stages 4-8.
  /// Fails only when the pairs would exceed pair_memory_cap bytes (0 = no cap).
  /// `filters` is empty or one per sphere: a pair is reported only when pair_passes_filter().
  [[nodiscard]] Status run(std::span<const Sphere> spheres, std::span<const std::uint32_t> active,
                           std::span<const Filter> filters, int bits, Layout layout, int threads,
                           std::size_t pair_memory_cap, std::vector<Pair>& pairs, FrameStats& stats);
  /// run() without filters.
  [[nodiscard]] Status run(std::span<const Sphere> spheres, std::span<const std::uint32_t> active, int bits,
                           Layout layout, int threads, std::size_t pair_memory_cap, std::vector<Pair>& pairs,
                           FrameStats& stats) {
    return run(spheres, active, {}, bits, layout, threads, pair_memory_cap, pairs, stats);
  }
  /// Stages 4-7 only: the tree over spheres[active[k]], for queries. Writes stats.bits, layout and
  /// the stage times.
  void build(std::span<const Sphere> spheres, std::span<const std::uint32_t> active, int bits, Layout layout,
             int threads, FrameStats& stats);

  /// Queries on the last tree (docs/architecture.md, "Queries"). A tree object's id is its index
  /// in the spheres it was built from, reported as ids[id] when `ids` is not empty.
  /// ray_first: the first hit (smallest t, ties to the smaller reported index) if it comes before
  /// `best` (when `found`); returns whether there is a hit now.
  [[nodiscard]] bool ray_first(const Ray& ray, std::span<const std::uint32_t> ids, RayHit& best, bool found) const;
  /// Appends every hit, unsorted.
  void ray_all(const Ray& ray, std::span<const std::uint32_t> ids, std::vector<RayHit>& hits) const;
  /// Appends the objects that overlap `sphere` by overlap_exact(), unsorted.
  void overlap(const Sphere& sphere, std::span<const std::uint32_t> ids, std::vector<std::uint32_t>& out) const;

  /// Inspection for tests: the last frame's tree over buckets, the bucket boxes, the objects in
  /// sorted order, the sorted codes (widened to 64 bits) and how the sort went.
  [[nodiscard]] const WideTree& tree() const { return tree_; }
  [[nodiscard]] std::span<const Aabb> leaf_boxes() const { return bucket_boxes_; }
  [[nodiscard]] std::span<const std::uint32_t> sorted_objects() const { return sorted_ids_; }
  [[nodiscard]] std::vector<std::uint64_t> sorted_codes() const;
  [[nodiscard]] const SortReport& sort_report() const { return sort_report_; }
  /// Forget the last frame's order: the next frame sorts from scratch.
  void reset_order() { previous_ids_.clear(); }
  /// Whether frames may keep the last order (Config::keep_order; default on). Off, every frame
  /// sorts: for tests of the sort and for measurements.
  void set_keep_order(bool on) { keep_order_ = on; }
  /// The SIMD kernels stage 8 uses (default: the best this CPU has).
  void set_simd(SimdLevel level) { simd_ = usable_simd_level(level); }
  /// Bytes of every buffer held (capacities).
  [[nodiscard]] std::uint64_t memory_bytes() const;

 private:
  /// Stages 5-7 (build, without the tree); returns fill_lanes()'s box sum.
  template <class K>
  double build_keys(std::span<const Sphere> spheres, std::span<const std::uint32_t> active,
                    std::span<const Filter> filters, const Aabb& bounds, int threads, FrameStats& stats);
  void build_tree(std::span<const Sphere> spheres, std::span<const std::uint32_t> active,
                  std::span<const Filter> filters, int bits, Layout layout, int threads, FrameStats& stats);
  Status find_pairs(std::span<const std::uint32_t> active, bool filtered, int threads, std::size_t pair_memory_cap,
                    std::vector<Pair>& pairs, FrameStats& stats);
  template <class Visit>
  void ray_walk(const Ray& ray, double& t_hi, Visit&& visit) const;
  /// Calls hit(id, t) for each sphere the ray hits within t_hi (which the calls may lower); id is
  /// the sphere's entry of sorted_ids_.
  template <class Hit>
  void ray_hits(const Ray& ray, double& t_hi, Hit&& hit) const;
  void last_order(std::size_t objects, std::span<const std::uint32_t> active);
  /// Stages 4-7 keeping the last order; false (and nothing usable built) when this frame must sort.
  bool keep_last_order(std::span<const Sphere> spheres, std::span<const std::uint32_t> active,
                       std::span<const Filter> filters, int bits, Layout layout, int threads, FrameStats& stats);
  /// Stage 7's lanes and bucket boxes from sphere_at(k), the k-th object in sorted_ids_ order;
  /// returns the bucket boxes' summed size (their three side lengths added).
  template <class SphereAt>
  double fill_lanes(std::size_t n, std::span<const Filter> filters, int threads, SphereAt&& sphere_at);
  /// fill_lanes() reading spheres[sorted_ids_[k]] (prefetched: the reads are out of the caller's order).
  double fill_lanes_in_order(std::span<const Sphere> spheres, std::size_t n, std::span<const Filter> filters,
                             int threads);
  /// Fit: the 16-wide tree over the buckets of n objects (checked with VISCD_VALIDATE).
  void fit_tree(std::size_t n, int threads, FrameStats& stats);
  /// Whether `active` (ascending) over `objects` spheres is the last sorted frame's active set.
  [[nodiscard]] bool same_active_set(std::size_t objects, std::span<const std::uint32_t> active) const;
  /// After a sorted frame: what the next frames compare with to keep its order.
  void remember_sorted(std::span<const Sphere> spheres, std::span<const std::uint32_t> active, Layout layout,
                       double box_sum);
  template <class Less>
  bool sort_nearly_sorted(std::size_t n, int threads, Less less);
  /// The runs sort_nearly_sorted() cuts n entries into, and room for what they set aside.
  static std::size_t sort_runs(std::size_t n, int threads);
  void reserve_far(std::size_t n, std::size_t runs);

  MortonLayout layout_;
  int bits_ = 32;
  // What keeping the order compares with: the last sorted frame's active set (all objects, or
  // previous_active_), layout kind, summed bucket box size and bucket-pair count (0: unknown).
  bool keep_order_ = true;
  SimdLevel simd_ = best_simd_level();
  bool sort_next_ = true;
  bool previous_all_ = false;
  std::size_t previous_objects_ = 0;
  Layout previous_layout_ = Layout::extended;
  std::vector<std::uint32_t> previous_active_;
  double sorted_box_sum_ = 0;
  std::uint64_t sorted_work_ = 0;
  PerWidth<KeyVector> keys_;  // each object's code
  PerWidth<RadixScratch> scratch_;
  std::vector<std::uint32_t> sorted_ids_, previous_ids_;
  std::vector<std::uint8_t> rank_;  // per object: active and not yet placed (last_order)
  std::vector<Sphere> gathered_;    // the active spheres in the last frame's order
  std::vector<SortEntry> entries_, merged_;
  static constexpr std::size_t kMaxSortRuns = 8;
  std::array<std::vector<SortEntry>, kMaxSortRuns + 1> far_;  // set aside per run; all, sorted
  SortReport sort_report_;
  std::vector<BucketLanes> lanes_;
  std::vector<Filter> sorted_filters_;  // the filters in sorted order (frames with filters)
  std::vector<Aabb> bucket_boxes_;
  WideTree tree_;
  PairCollector pairs_;
};

}  // namespace viscd::detail
