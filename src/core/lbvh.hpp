#pragma once
// Linear BVH over sorted Morton keys: build and fit (stage 7), traversal (stage 8).
//
// Build: Karras 2012, "Maximizing Parallelism in the Construction of BVHs, Octrees, and k-d
// Trees" (HPG), one independent task per internal node. n leaves (sorted positions 0..n-1) and
// n-1 internal nodes, the root is internal node 0. Equal keys are split by position:
//     delta(i, j) = clz_m(key_i ^ key_j)         if key_i != key_j
//                 = m + clz_32(i ^ j)            otherwise              (m = key width)
// so delta strictly increases from a node to its internal children and the depth of any leaf is
// at most m + 32 (delta < m + 32): a traversal stack of kStackDepth >= 96 entries cannot overflow.
//
// Node layout: each internal node stores both children's boxes, child ids and the last sorted
// position of each child's subtree (for validation and the gl backend's traversal), in one
// 64-byte cache line, so a traversal step tests both children with one fetch:
//     +---------------+---------------+----------+----------+---------+---------+
//     | box[0] 24 B   | box[1] 24 B   | child[0] | child[1] | last[0] | last[1] |
//     +---------------+---------------+----------+----------+---------+---------+
// child ids with the top bit (kLeafBit) set are leaves (sorted positions).
//
// Fit: bottom-up, one task per leaf; at each internal node an atomic arrival counter lets the
// second task through (the first task's box write happens-before it by acq_rel ordering).

#include <atomic>
#include <bit>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "core/geometry.hpp"
#include "viscd/assert.hpp"

namespace viscd::detail {

inline constexpr std::uint32_t kLeafBit = 0x80000000u;
inline constexpr std::uint32_t kNoParent = 0xFFFFFFFFu;
/// Traversal stack entries; >= 64 + 32, the deepest possible tree (see above).
inline constexpr int kStackDepth = 128;
static_assert(kStackDepth >= 64 + 32, "stack must hold the deepest Karras tree over 64-bit keys");

struct alignas(64) BvhNode {
  Aabb box[2];
  std::uint32_t child[2];
  std::uint32_t last[2];
};
static_assert(sizeof(BvhNode) == 64);

struct Lbvh {
  std::uint32_t leaves = 0;
  std::vector<BvhNode> nodes;              // leaves - 1 internal nodes, root = 0
  std::vector<std::uint32_t> parent;       // parent of each internal node (root: kNoParent)
  std::vector<std::uint32_t> leaf_parent;  // parent of each leaf
  std::vector<std::uint32_t> arrivals;     // fit: arrival counters, one per internal node
  Aabb root_box;
};

/// Builds the topology over `sorted_keys` (ascending) of width `key_bits` = 8 * sizeof(K).
template <class K>
void build_lbvh(std::span<const K> sorted_keys, Lbvh& bvh, int threads);
/// Fits boxes bottom-up; leaf_boxes[p] is the box of the leaf at sorted position p.
void fit_lbvh(std::span<const Aabb> leaf_boxes, Lbvh& bvh, int threads);
/// Checks parent/child links, that every leaf appears once, that every stored box contains its
/// subtree's boxes and that `last` is each subtree's largest position. Returns "" when valid,
/// else what is wrong. O(n). Used by tests and under VISCD_VALIDATE.
[[nodiscard]] std::string validate_lbvh(const Lbvh& bvh, std::span<const Aabb> leaf_boxes);
/// Depth of the deepest leaf (root = depth 0; a tree of one leaf has depth 0).
[[nodiscard]] int lbvh_depth(const Lbvh& bvh);

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
