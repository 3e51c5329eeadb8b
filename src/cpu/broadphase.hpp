#pragma once
// Stages 4-8 over an active set: Morton layout, codes, radix sort, Karras build, fit, query.
// Exact: the result equals brute force over the active set for every m (tests/cpu/).

#include <cstdint>
#include <span>
#include <vector>

#include "core/frame_rules.hpp"
#include "core/morton.hpp"
#include "cpu/lbvh_build.hpp"
#include "cpu/radix_sort.hpp"
#include "viscd/config.hpp"
#include "viscd/frame.hpp"
#include "viscd/result.hpp"
#include "viscd/types.hpp"

namespace viscd::detail {

/// The extent of the active set, in parallel chunks (core's extent_of, merged in chunk order).
[[nodiscard]] ActiveExtent active_extent(std::span<const Sphere> spheres, std::span<const std::uint32_t> active,
                                         int threads);

/// A chunk's pair list covers the same objects every frame, but its count drifts as they move:
/// once the list is more than two-thirds full it gets room for twice its count, so frames whose
/// counts wander by up to half do not allocate.
inline void keep_headroom(std::vector<std::uint64_t>& list) {
  if (3 * list.size() > 2 * list.capacity()) list.reserve(2 * list.size());
}

/// Writes the pairs of per-chunk lists (keys i << 32 | j, i < j < objects) into `out` sorted by
/// (i, j): a counting sort by i, then each object's few partners by j. O(pairs + objects);
/// `offsets` is scratch (objects + 1 entries), kept between frames.
void sort_chunk_pairs(std::span<const std::vector<std::uint64_t>> lists, std::uint32_t objects,
                      std::vector<std::uint32_t>& offsets, std::vector<Pair>& out);

/// The LBVH broadphase. Keeps every buffer between frames: after the first frame of a given size,
/// run() allocates nothing unless the pair count grows. Not thread-safe.
class LbvhBroadphase {
 public:
  /// Finds all overlapping pairs among spheres[active[k]] (active ascending) with m-bit codes.
  /// Writes sorted pairs, stats.bits, stats.layout and the stage times of stages 4-8.
  /// Fails only when the pairs would exceed pair_memory_cap bytes (0 = no cap).
  [[nodiscard]] Status run(std::span<const Sphere> spheres, std::span<const std::uint32_t> active, int bits,
                           Layout layout, int threads, std::size_t pair_memory_cap, std::vector<Pair>& pairs,
                           FrameStats& stats);

  /// Inspection for tests: the last frame's tree, leaf boxes and sorted object ids.
  [[nodiscard]] const Lbvh& tree() const { return bvh_; }
  [[nodiscard]] std::span<const Aabb> leaf_boxes() const { return leaf_boxes_; }
  [[nodiscard]] std::span<const std::uint32_t> sorted_objects() const { return sorted_ids_; }
  [[nodiscard]] const MortonLayout& layout() const { return layout_; }
  /// Bytes of every buffer held (capacities).
  [[nodiscard]] std::uint64_t memory_bytes() const;
  /// Sorted codes of the last frame, widened to 64 bits.
  [[nodiscard]] std::vector<std::uint64_t> sorted_codes() const;

 private:
  template <class K>
  Status run_keys(std::span<const Sphere> spheres, std::span<const std::uint32_t> active, const Aabb& bounds,
                  int threads, std::size_t pair_memory_cap, std::vector<Pair>& pairs, FrameStats& stats);
  template <class K>
  std::vector<K>& keys();

  MortonLayout layout_;
  int bits_ = 32;
  std::vector<std::uint16_t> keys16_;
  std::vector<std::uint32_t> keys32_;
  std::vector<std::uint64_t> keys64_;
  RadixScratch<std::uint16_t> scratch16_;
  RadixScratch<std::uint32_t> scratch32_;
  RadixScratch<std::uint64_t> scratch64_;
  std::vector<std::uint32_t> sorted_ids_;
  std::vector<Sphere> sorted_spheres_;
  std::vector<Aabb> leaf_boxes_;
  Lbvh bvh_;
  std::vector<std::vector<std::uint64_t>> chunk_pairs_;
  std::vector<std::uint32_t> pair_offsets_;
};

/// O(n^2) brute force over the active set: the oracle. Pairs come out sorted. Stops and returns
/// false when there are more than `max_pairs`.
bool brute_force_pairs(std::span<const Sphere> spheres, std::span<const std::uint32_t> active, std::vector<Pair>& pairs,
                       std::size_t max_pairs = SIZE_MAX);

}  // namespace viscd::detail
