#include "cpu/lbvh_build.hpp"

#include <algorithm>
#include <bit>

#include "cpu/grow.hpp"
#include "cpu/parallel.hpp"

namespace viscd::detail {
namespace {

// Length of the common prefix of the keys at sorted positions i and j, ties split by position;
// -1 when j is outside [0, n).
template <class K>
inline int delta(const K* keys, std::int64_t n, std::int64_t i, std::int64_t j) {
  if (j < 0 || j >= n) return -1;
  const K a = keys[i], b = keys[j];
  if (a != b) return std::countl_zero(static_cast<K>(a ^ b));
  constexpr int kBits = 8 * sizeof(K);
  return kBits + std::countl_zero(static_cast<std::uint32_t>(i ^ j));
}

}  // namespace

template <class K>
void build_lbvh(std::span<const K> sorted_keys, Lbvh& bvh, int threads) {
  const auto n = static_cast<std::int64_t>(sorted_keys.size());
  VISCD_ASSERT(n < static_cast<std::int64_t>(kLeafBit), "too many leaves for 31-bit ids");
  bvh.leaves = static_cast<std::uint32_t>(n);
  if (n < 2) {
    bvh.nodes.clear();
    bvh.parent.clear();
    bvh.leaf_parent.assign(static_cast<std::size_t>(n), kNoParent);
    return;
  }
  resize_with_headroom(bvh.nodes, static_cast<std::size_t>(n - 1));
  resize_with_headroom(bvh.parent, static_cast<std::size_t>(n - 1));
  resize_with_headroom(bvh.leaf_parent, static_cast<std::size_t>(n));
  bvh.parent[0] = kNoParent;
  const K* keys = sorted_keys.data();
  parallel_for(static_cast<std::size_t>(n - 1), threads, [&](std::size_t node_index) {
    const auto i = static_cast<std::int64_t>(node_index);
    // Direction of the range: towards the neighbour with the longer common prefix.
    const int d = delta(keys, n, i, i + 1) - delta(keys, n, i, i - 1) > 0 ? 1 : -1;
    const int delta_min = delta(keys, n, i, i - d);
    // Upper bound of the range length, then binary search for its other end j.
    std::int64_t lmax = 2;
    while (delta(keys, n, i, i + lmax * d) > delta_min) lmax *= 2;
    std::int64_t l = 0;
    for (std::int64_t t = lmax / 2; t >= 1; t /= 2)
      if (delta(keys, n, i, i + (l + t) * d) > delta_min) l += t;
    const std::int64_t j = i + l * d;
    // Split position: the last position sharing more than delta_node bits with i.
    const int delta_node = delta(keys, n, i, j);
    std::int64_t s = 0;
    std::int64_t t = l;
    do {
      t = (t + 1) / 2;
      if (delta(keys, n, i, i + (s + t) * d) > delta_node) s += t;
    } while (t > 1);
    const std::int64_t gamma = i + s * d + std::min(d, 0);
    const std::int64_t first = std::min(i, j), last = std::max(i, j);

    BvhNode& node = bvh.nodes[static_cast<std::size_t>(i)];
    const auto ui = static_cast<std::uint32_t>(i);
    if (first == gamma) {
      node.child[0] = static_cast<std::uint32_t>(gamma) | kLeafBit;
      bvh.leaf_parent[static_cast<std::size_t>(gamma)] = ui;
    } else {
      node.child[0] = static_cast<std::uint32_t>(gamma);
      bvh.parent[static_cast<std::size_t>(gamma)] = ui;
    }
    if (last == gamma + 1) {
      node.child[1] = static_cast<std::uint32_t>(gamma + 1) | kLeafBit;
      bvh.leaf_parent[static_cast<std::size_t>(gamma + 1)] = ui;
    } else {
      node.child[1] = static_cast<std::uint32_t>(gamma + 1);
      bvh.parent[static_cast<std::size_t>(gamma + 1)] = ui;
    }
    node.last[0] = static_cast<std::uint32_t>(gamma);
    node.last[1] = static_cast<std::uint32_t>(last);
  });
}

template void build_lbvh<std::uint16_t>(std::span<const std::uint16_t>, Lbvh&, int);
template void build_lbvh<std::uint32_t>(std::span<const std::uint32_t>, Lbvh&, int);
template void build_lbvh<std::uint64_t>(std::span<const std::uint64_t>, Lbvh&, int);

void fit_lbvh(std::span<const Aabb> leaf_boxes, Lbvh& bvh, int threads) {
  const std::size_t n = bvh.leaves;
  VISCD_ASSERT(leaf_boxes.size() == n, "one box per leaf");
  if (n == 0) {
    bvh.root_box = Aabb{};
    return;
  }
  if (n == 1) {
    bvh.root_box = leaf_boxes[0];
    return;
  }
  resize_with_headroom(bvh.arrivals, n - 1);
  std::fill(bvh.arrivals.begin(), bvh.arrivals.end(), 0u);
  parallel_for(n, threads, [&](std::size_t p) {
    std::uint32_t child = static_cast<std::uint32_t>(p) | kLeafBit;
    std::uint32_t node = bvh.leaf_parent[p];
    Aabb box = leaf_boxes[p];
    for (;;) {
      BvhNode& nd = bvh.nodes[node];
      nd.box[nd.child[0] == child ? 0 : 1] = box;
      // acq_rel: the first arrival's box write is visible to the second arrival, which merges.
      const std::uint32_t before =
          std::atomic_ref<std::uint32_t>(bvh.arrivals[node]).fetch_add(1, std::memory_order_acq_rel);
      if (before == 0) break;
      box = nd.box[0];
      box.grow(nd.box[1]);
      if (node == 0) {
        bvh.root_box = box;
        break;
      }
      child = node;
      node = bvh.parent[node];
    }
  });
}

}  // namespace viscd::detail
