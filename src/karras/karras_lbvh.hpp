#pragma once
// The paper's hierarchy on the CPU: a Karras 2012 LBVH over the sorted Morton codes (one leaf per
// object), fitted bottom-up, and the traversal that finds each pair once (Karras build and fit as
// parallel loops). No backend runs it: it is the model the gl backend's tree (its shaders) is
// tested against, leaf for leaf and box for box, and the subject of the bench's tree statistics
// (viscd_peers --tree-stats). It is built as its own library, viscd_karras, for the tests and the
// bench; the library viscd does not contain it. The tree's layout and validation are
// core/lbvh.hpp, which the gl backend shares. Why the cpu backend uses a 16-wide tree over buckets
// instead: cpu/wide_tree.hpp.

#include <atomic>
#include <cstdint>
#include <span>
#include <vector>

#include "core/lbvh.hpp"
#include "core/morton.hpp"
#include "cpu/pair_collector.hpp"
#include "cpu/radix_sort.hpp"
#include "viscd/config.hpp"
#include "viscd/frame.hpp"
#include "viscd/result.hpp"
#include "viscd/types.hpp"

namespace viscd::detail {

/// Builds the topology over `sorted_keys` (ascending) of width `key_bits` = 8 * sizeof(K).
template <class K>
void build_lbvh(std::span<const K> sorted_keys, Lbvh& bvh, int threads);
/// Fits boxes bottom-up; leaf_boxes[p] is the box of the leaf at sorted position p.
void fit_lbvh(std::span<const Aabb> leaf_boxes, Lbvh& bvh, int threads);
/// Calls f(q) for every leaf of the subtree under internal node `root` whose box overlaps `box`.
/// The stack holds kStackDepth entries and a Karras tree is at most 96 deep; should a deeper tree
/// ever come in, the overflowing subtree is finished by recursion, so no leaf is ever dropped.
template <class F>
inline void for_each_overlap_in_subtree(const Lbvh& bvh, std::uint32_t root, const Aabb& box, F&& f) {
  std::uint32_t stack[kStackDepth];
  int sp = 0;
  std::uint32_t node = root;
  for (;;) {
    const BvhNode& nd = bvh.nodes[node];
    std::uint32_t next = kNoParent;
    for (int c = 0; c < 2; ++c) {
      if (!overlaps(nd.box[c], box)) continue;
      const std::uint32_t ch = nd.child[c];
      if (ch & kLeafBit) {
        f(ch & ~kLeafBit);
      } else if (next == kNoParent) {
        next = ch;
      } else if (sp < kStackDepth) {
        stack[sp++] = ch;
      } else {
        for_each_overlap_in_subtree(bvh, ch, box, f);  // unreachable for build_lbvh's trees
      }
    }
    if (next != kNoParent) {
      node = next;
    } else if (sp > 0) {
      node = stack[--sp];
    } else {
      return;
    }
  }
}

/// Calls f(q) for every leaf q > p whose box overlaps `box`, so that each pair is found once.
///
/// Walks up from leaf p: at every ancestor where p lies in the left subtree, the right subtree
/// holds only positions > p (Karras ranges are contiguous) and is searched; where p lies in the
/// right subtree, the left one holds only positions < p and is skipped. This tests one box per
/// such ancestor instead of two per level on a descent from the root, and needs no range checks.
template <class F>
inline void for_each_overlap_after(const Lbvh& bvh, std::uint32_t p, const Aabb& box, F&& f) {
  if (bvh.leaves < 2) return;
  std::uint32_t child = p | kLeafBit;
  std::uint32_t node = bvh.leaf_parent[p];
  while (node != kNoParent) {
    const BvhNode& nd = bvh.nodes[node];
    if (nd.child[0] == child && overlaps(nd.box[1], box)) {
      if (nd.child[1] & kLeafBit)
        f(nd.child[1] & ~kLeafBit);
      else
        for_each_overlap_in_subtree(bvh, nd.child[1], box, f);
    }
    child = node;
    node = bvh.parent[node];
  }
}

/// Stages 4-8 with the Karras tree: layout, codes, radix sort, build, fit, traversal. Keeps every buffer between
/// frames: after the first frame of a given size, run() allocates nothing unless the pair count grows. Not thread-safe.
class KarrasBroadphase {
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

  MortonLayout layout_;
  int bits_ = 32;
  PerWidth<KeyVector> keys_;
  PerWidth<RadixScratch> scratch_;
  std::vector<std::uint32_t> sorted_ids_;
  std::vector<Sphere> sorted_spheres_;
  std::vector<Aabb> leaf_boxes_;
  Lbvh bvh_;
  PairCollector pairs_;
};

}  // namespace viscd::detail
