#include "karras/karras_lbvh.hpp"

#include <algorithm>
#include <bit>

#include "core/stopwatch.hpp"
#include "cpu/grow.hpp"
#include "cpu/morton_order.hpp"
#include "cpu/parallel.hpp"
#include "viscd/assert.hpp"

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

std::uint64_t KarrasBroadphase::memory_bytes() const {
  std::uint64_t b = bytes_of(sorted_ids_) + bytes_of(sorted_spheres_) + bytes_of(leaf_boxes_) + bytes_of(bvh_.nodes) +
                    bytes_of(bvh_.parent) + bytes_of(bvh_.leaf_parent) + bytes_of(bvh_.arrivals) +
                    pairs_.memory_bytes();
  keys_.for_each([&](const auto& v) { b += bytes_of(v); });
  scratch_.for_each([&](const auto& s) { b += bytes_of(s.keys) + bytes_of(s.values); });
  return b;
}

std::vector<std::uint64_t> KarrasBroadphase::sorted_codes() const { return keys_.widened(bits_, sorted_ids_.size()); }

Status KarrasBroadphase::run(std::span<const Sphere> spheres, std::span<const std::uint32_t> active, int bits,
                             Layout layout, int threads, std::size_t pair_memory_cap, std::vector<Pair>& pairs,
                             FrameStats& stats) {
  ActiveExtent extent;
  layout_ = layout_stage(spheres, active, bits, layout, threads, extent, stats);
  bits_ = bits;
  switch (bits) {
    case 16:
      return run_keys<std::uint16_t>(spheres, active, extent.bounds, threads, pair_memory_cap, pairs, stats);
    case 32:
      return run_keys<std::uint32_t>(spheres, active, extent.bounds, threads, pair_memory_cap, pairs, stats);
    default:
      return run_keys<std::uint64_t>(spheres, active, extent.bounds, threads, pair_memory_cap, pairs, stats);
  }
}

template <class K>
Status KarrasBroadphase::run_keys(std::span<const Sphere> spheres, std::span<const std::uint32_t> active,
                                  const Aabb& bounds, int threads, std::size_t pair_memory_cap,
                                  std::vector<Pair>& pairs, FrameStats& stats) {
  Stopwatch sw;
  const std::size_t n = active.size();
  std::vector<K>& key = keys_.get<K>();
  if (key.size() < n) key.resize(n);
  if (sorted_ids_.size() != n) sorted_ids_.resize(n);

  // Stage 5: codes. Values start as active object ids in ascending order, so the stable sort
  // breaks key ties by object index.
  const MortonEncoder encoder(layout_, bounds);
  parallel_for(n, threads, [&](std::size_t k) {
    const Sphere& s = spheres[active[k]];
    key[k] = static_cast<K>(encoder.encode(s.x, s.y, s.z));
    sorted_ids_[k] = active[k];
  });
  stats.ms(Stage::codes) = sw.lap();

  // Stage 6: sort.
  radix_sort<K>(std::span<K>(key.data(), n), std::span<std::uint32_t>(sorted_ids_.data(), n), 8 * sizeof(K), threads,
                scratch_.get<K>());
  stats.ms(Stage::sort) = sw.lap();

  // Stage 7: hierarchy, then boxes. Spheres are gathered into sorted order for coherent access.
  build_lbvh<K>(std::span<const K>(key.data(), n), bvh_, threads);
  stats.ms(Stage::build) = sw.lap();
  if (sorted_spheres_.size() != n) {
    sorted_spheres_.resize(n);
    leaf_boxes_.resize(n);
  }
  parallel_for(n, threads, [&](std::size_t p) {
    sorted_spheres_[p] = spheres[sorted_ids_[p]];
    leaf_boxes_[p] = conservative_box(sorted_spheres_[p]);
  });
  fit_lbvh(leaf_boxes_, bvh_, threads);
  stats.ms(Stage::fit) = sw.lap();
#ifdef VISCD_VALIDATE
  {
    const std::string problem = validate_lbvh(bvh_, leaf_boxes_);
    VISCD_ASSERT(problem.empty(), problem.c_str());
  }
#endif

  // Stage 8: each leaf p looks for partners q > p only, so each pair is found once.
  const std::size_t chunks = threads_for(n, threads) == 1 ? 1 : std::min<std::size_t>(n, 8 * threads);
  const std::uint32_t objects = n ? active.back() + 1 : 0;  // active is ascending
  const Status found =
      pairs_.collect(n, chunks, threads, pair_memory_cap, objects, pairs, [&](std::size_t p, auto& emit) {
        const Sphere& a = sorted_spheres_[p];
        for_each_overlap_after(bvh_, static_cast<std::uint32_t>(p), leaf_boxes_[p], [&](std::uint32_t q) {
          if (overlap_exact(a, sorted_spheres_[q])) emit(sorted_ids_[p], sorted_ids_[q]);
        });
      });
  if (!found) return found;
  stats.pairs = pairs.size();
  stats.ms(Stage::query) = sw.lap();
  return {};
}

}  // namespace viscd::detail
