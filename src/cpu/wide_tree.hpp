#pragma once
// Stage 7 of the cpu broadphase, second half ("fit"): a 16-wide bounding volume hierarchy over
// leaves in a fixed order, the cpu broadphase's buckets,
// consecutive in Morton order. Node j of level 0 holds the boxes of leaves 16j .. 16j + 15; node j
// of level k + 1 holds the boxes of nodes 16j .. 16j + 15 of level k; the top level is one node.
// No topology is stored: a child's index follows from its parent's, and the leaves under an entry
// are a contiguous range of the order. One SIMD test checks a box against all 16 children of a
// node, and the search for "every later leaf" masks off the children that lie before the leaf.
//
// Why not the Karras tree over the buckets (docs/benchmarks.md, "The broadphase at the limit"):
// its descent tests two boxes per level with unpredictable branches, and at 10^5 dense objects
// that walk cost most of stage 8; this tree is 4 levels deep at 10^6 objects and tests 16 boxes
// per branch-free step.

#include <bit>
#include <cstdint>
#include <span>
#include <string>
#include <type_traits>
#include <vector>

#include "core/geometry.hpp"
#include "cpu/simd.hpp"

namespace viscd::detail {

inline constexpr std::uint32_t kWide = 16;
/// 16^8 = 2^32 leaves: more levels are never needed.
inline constexpr std::uint32_t kWideMaxLevels = 8;

/// The boxes of a node's children, by axis. An empty child is the empty box (lo = +inf,
/// hi = -inf), which overlaps nothing and leaves a union unchanged.
struct alignas(64) WideNode {
  float lo_x[kWide], lo_y[kWide], lo_z[kWide], hi_x[kWide], hi_y[kWide], hi_z[kWide];
  [[nodiscard]] Aabb child(std::uint32_t l) const { return {{lo_x[l], lo_y[l], lo_z[l]}, {hi_x[l], hi_y[l], hi_z[l]}}; }
  void set_child(std::uint32_t l, const Aabb& b) {
    lo_x[l] = b.lo.x, lo_y[l] = b.lo.y, lo_z[l] = b.lo.z;
    hi_x[l] = b.hi.x, hi_y[l] = b.hi.y, hi_z[l] = b.hi.z;
  }
  /// The union of the children (empty children change nothing).
  [[nodiscard]] Aabb box() const {
    Aabb b;
    for (std::uint32_t l = 0; l < kWide; ++l) b.grow(child(l));
    return b;
  }
};

struct WideTree {
  std::vector<std::vector<WideNode>> level;  ///< level[0] over the leaves; kept between frames
  std::uint32_t levels = 0;                  ///< levels in use; level[levels - 1] is one node
  std::size_t leaves = 0;
};

/// Builds the levels over leaf_boxes (0 leaves: no level). Allocates only when the tree grows.
void build_wide_tree(std::span<const Aabb> leaf_boxes, WideTree& tree, int threads);

/// Checks the layout: node counts per level, leaf boxes copied exactly, empty lanes empty, every
/// child box equal to the union of its node's children. Empty string when valid.
[[nodiscard]] std::string validate_wide_tree(const WideTree& tree, std::span<const Aabb> leaf_boxes);

namespace wide_detail {

// The depth-first walk shared by the searches: one frame per level (a node and the children
// still to visit). `keep(k, node)` masks the children of node `node` of level k worth a test;
// Simd (cpu/simd.hpp) tests them.
template <class Simd, class Keep, class F>
inline void walk(const WideTree& t, const Aabb& box, Keep&& keep, F&& f) {
  if (t.levels == 0) return;
  struct Frame {
    std::uint32_t node, mask;
  };
  Frame stack[kWideMaxLevels];
  auto enter = [&](std::uint32_t k, std::uint32_t node) {
    const std::uint32_t m = keep(k, node);
    stack[k] = {node, m ? Simd::node_children(t.level[k][node], box) & m : 0u};
  };
  std::uint32_t k = t.levels - 1;
  enter(k, 0);
  for (;;) {
    std::uint32_t& m = stack[k].mask;
    if (m == 0) {
      if (++k == t.levels) return;
      continue;
    }
    const std::uint32_t c = stack[k].node * kWide + static_cast<std::uint32_t>(std::countr_zero(m));
    m &= m - 1;
    if (k == 0) {
      if constexpr (std::is_same_v<decltype(f(c)), bool>) {
        if (!f(c)) return;
      } else {
        f(c);
      }
    } else {
      --k;
      enter(k, c);
    }
  }
}

}  // namespace wide_detail

/// Calls f(q) for every leaf q whose box overlaps `box` (until f returns false, when it returns bool).
template <class Simd = SimdBaseline, class F>
inline void for_each_wide_overlap(const WideTree& t, const Aabb& box, F&& f) {
  const auto keep = [](std::uint32_t, std::uint32_t) -> std::uint32_t { return 0xFFFFu; };
  wide_detail::walk<Simd>(t, box, keep, f);
}

/// Calls f(q) for every leaf q > p whose box overlaps `box`, so that each pair is found once.
/// Child l of node j at level k is entry 16j + l of the level below, which covers the leaves
/// [(16j + l) 16^k, (16j + l + 1) 16^k): it holds a leaf after p when 16j + l >= p >> 4k (at
/// level 0, where the entries are leaves: 16j + l > p).
template <class Simd = SimdBaseline, class F>
inline void for_each_wide_overlap_after(const WideTree& t, std::uint32_t p, const Aabb& box, F&& f) {
  const auto keep = [p](std::uint32_t k, std::uint32_t node) -> std::uint32_t {
    const std::uint64_t first = k == 0 ? std::uint64_t{p} + 1 : std::uint64_t{p} >> (4 * k);
    const std::uint64_t base = std::uint64_t{node} * kWide;
    if (first <= base) return 0xFFFFu;
    if (first >= base + kWide) return 0u;
    return (0xFFFFu << (first - base)) & 0xFFFFu;
  };
  wide_detail::walk<Simd>(t, box, keep, f);
}

}  // namespace viscd::detail
