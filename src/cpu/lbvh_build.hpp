#pragma once
// The CPU's LBVH: Karras build and bottom-up fit (stage 7) as parallel loops, and the traversals
// of stage 8. The tree's definition and its validation are core/lbvh.hpp.

#include <atomic>
#include <span>

#include "core/lbvh.hpp"

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

}  // namespace viscd::detail
