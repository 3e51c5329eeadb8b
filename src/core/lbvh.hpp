#pragma once
// The paper's linear BVH over sorted Morton keys, one leaf per object: the tree the gl backend
// builds in stage 7 (its shaders lbvh_build.comp and lbvh_fit.comp), its node layout as the host
// reads it back, and its validation. The cpu backend builds another tree (a 16-wide tree over
// buckets of 16 objects: cpu/wide_tree.hpp); the same Karras tree on the CPU, the model the gl
// tree is tested against, is karras/karras_lbvh.hpp (not part of the library).
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

/// Checks parent/child links, that every leaf appears once, that every stored box contains its
/// subtree's boxes and that `last` is each subtree's largest position. Returns "" when valid,
/// else what is wrong. O(n). Used by tests and under VISCD_VALIDATE.
[[nodiscard]] std::string validate_lbvh(const Lbvh& bvh, std::span<const Aabb> leaf_boxes);
/// Depth of the deepest leaf (root = depth 0; a tree of one leaf has depth 0).
[[nodiscard]] int lbvh_depth(const Lbvh& bvh);

}  // namespace viscd::detail
