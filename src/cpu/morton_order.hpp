#pragma once
// Stages 4-6 of the cpu broadphase: the Morton layout over the active centres, one code per
// active object, and the objects sorted by (code, object id).
//
//   stage 4  layout: extent of the active centres, Morton layout (core/morton.hpp, shared with every
//                    backend)
//   stage 5  codes:  one code per active object; with a last order, the spheres are gathered in it
//                    (the one read of the caller's array out of its order) and coded there
//   stage 6  sort:   the last frame's order, filtered to this frame's active set, finished by the
//                    nearly-sorted sort (cpu/nearly_sorted.hpp); an LSD radix sort
//                    (cpu/radix_sort.hpp) when there is no last order or the nearly-sorted sort
//                    gives up. Both give the same order: by code, ties by object id.

#include <cstdint>
#include <span>
#include <vector>

#include "core/frame_rules.hpp"
#include "core/morton.hpp"
#include "cpu/nearly_sorted.hpp"
#include "cpu/radix_sort.hpp"
#include "viscd/config.hpp"
#include "viscd/frame.hpp"
#include "viscd/types.hpp"

namespace viscd::detail {

/// Stage 4's input: the extent of the active centres and their mean diameter, in parallel
/// chunks (core's extent_of, merged in chunk order: the same for every thread count).
[[nodiscard]] ActiveExtent active_extent(const Shapes& spheres, std::span<const std::uint32_t> active, int threads);

/// Stage 4: the extent of the active centres (`extent`) and the layout of m = `bits` over it;
/// writes stats.bits, stats.layout and the stage's time.
[[nodiscard]] MortonLayout layout_stage(const Shapes& spheres, std::span<const std::uint32_t> active, int bits,
                                        Layout layout, int threads, ActiveExtent& extent, FrameStats& stats);

/// How a frame's stages 5-6 went (for tests and the bench).
struct SortReport {
  bool kept = false;        ///< the last order was kept: stages 4-6 skipped (then reused is false)
  bool reused = false;      ///< sorted from the last frame's order (else by the radix sort)
  std::uint64_t moves = 0;  ///< entries shifted by insertions within reach (also when it gave up)
  std::uint64_t far = 0;    ///< entries set aside, sorted and merged in
};

class MortonOrder {
 public:
  /// Stages 4-6 over spheres[active[k]] (active ascending) with m = `bits`: writes stats.bits,
  /// stats.layout and the times of stages 4-6, and sorted_ids().
  void sort(std::span<const Sphere> spheres, std::span<const std::uint32_t> active, int bits, Layout layout,
            int threads, FrameStats& stats);

  /// The objects in order (the last sorted frame's, also on frames that keep it).
  [[nodiscard]] std::span<const std::uint32_t> sorted_ids() const {
    return std::span<const std::uint32_t>(sorted_ids_).first(sorted_count_);
  }
  /// Objects in the last order (0 when there is none: the next sort starts from scratch).
  [[nodiscard]] std::size_t last_count() const { return last_count_; }
  /// m and the layout of the last sort.
  [[nodiscard]] int bits() const { return bits_; }
  [[nodiscard]] const MortonLayout& layout() const { return layout_; }
  /// Whether the last sort gathered the spheres in order (then gathered_sphere(k) is the k-th
  /// object's sphere, read from memory written in nearly that order).
  [[nodiscard]] bool gathered() const { return report_.reused; }
  [[nodiscard]] const Sphere& gathered_sphere(std::size_t k) const { return gathered_[at_[k]]; }
  [[nodiscard]] const SortReport& report() const { return report_; }
  /// The sorted codes of the last sort, widened to 64 bits (tests).
  [[nodiscard]] std::vector<std::uint64_t> sorted_codes() const { return keys_.widened(bits_, sorted_count_); }
  /// Forget the last order: the next sort starts from scratch.
  void forget() { last_count_ = 0; }

  [[nodiscard]] std::uint64_t memory_bytes() const;

 private:
  template <class K>
  void sort_keys(std::span<const Sphere> spheres, std::span<const std::uint32_t> active, const Aabb& bounds,
                 int threads, FrameStats& stats);
  /// The objects still active in the last frame's order, then the new ones by index, into
  /// sorted_ids_[0..n).
  void last_order(std::size_t objects, std::span<const std::uint32_t> active);

  MortonLayout layout_;
  MortonEncoder encoder_;  // on layout_; its tables kept while the layout stays
  int bits_ = 32;
  PerWidth<KeyVector> keys_;  // each object's code
  PerWidth<RadixScratch> scratch_;
  // The objects in order; the first last_count_ are also the last order, which the next sort
  // starts from (there is no copy of it: last_order() rewrites it in place).
  std::vector<std::uint32_t> sorted_ids_;
  std::size_t sorted_count_ = 0, last_count_ = 0;
  std::vector<std::uint32_t> at_;   // per place of the order, its sphere's place in gathered_
  std::vector<std::uint8_t> rank_;  // per object: active and not yet placed (last_order)
  std::vector<Sphere> gathered_;    // the active spheres in the last frame's order
  std::vector<SortEntry> entries_;
  NearlySortedSort nearly_sorted_;
  SortReport report_;
};

}  // namespace viscd::detail
