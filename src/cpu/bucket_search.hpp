#pragma once
// Stage 8 of the cpu broadphase: every overlapping pair among the bucketed objects. Per group of
// 16 buckets (the buckets under one node of the tree's lowest level): the pairs inside each
// bucket, then with every later bucket whose box overlaps its own, so each pair is found once.
// Per object of a bucket whose box reaches into the other bucket's box, the exact sphere test
// against all 16 of its lanes at once (cpu/simd.hpp): spheres by the sphere test, boxes by the
// box test (the tree's own node test); the filters come after the exact test (few candidates pass
// it). Exact for any grouping of the objects into buckets.

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "cpu/buckets.hpp"
#include "cpu/pair_collector.hpp"
#include "cpu/simd.hpp"
#include "cpu/wide_tree.hpp"
#include "viscd/detector.hpp"
#include "viscd/result.hpp"
#include "viscd/types.hpp"

namespace viscd::detail {

/// The two tests of stage 8 for each kind of lanes: `near`, the lanes whose box reaches into a
/// box; `exact`, the lanes that pass the exact test with lane i of another bucket.
template <class Simd>
struct SphereTests {
  using Lanes = BucketLanes;
  /// The bytes of a bucket's lanes that `exact` reads of the other bucket: x, y, z and r.
  static constexpr std::size_t kExactBytes = offsetof(BucketLanes, h);
  static std::uint32_t near(const BucketLanes& l, const Aabb& box) { return Simd::box_lanes(l, box); }
  static std::uint32_t exact(const BucketLanes& l, const BucketLanes& o, std::uint32_t i) {
    return Simd::sphere_lanes(l, o.x[i], o.y[i], o.z[i], o.r[i]);
  }
};
template <class Simd>
struct BoxTests {
  using Lanes = BoxLanes;
  static constexpr std::size_t kExactBytes = sizeof(BoxLanes);
  static std::uint32_t near(const BoxLanes& l, const Aabb& box) { return Simd::node_children(l, box); }
  static std::uint32_t exact(const BoxLanes& l, const BoxLanes& o, std::uint32_t i) {
    return Simd::node_children(l, o.box(i));
  }
};

/// What stage 8 searches.
struct BucketSearchInput {
  std::span<const BucketLanes> lanes;   ///< sphere frames
  std::span<const BoxLanes> box_lanes;  ///< box frames
  bool box_frame = false;
  std::span<const Aabb> boxes;         ///< per bucket
  const WideTree* tree;                ///< over the bucket boxes
  std::span<const std::uint32_t> ids;  ///< sorted position -> object id
  std::span<const Filter> filters;     ///< in sorted order; empty: no filters
  std::uint32_t objects;               ///< ids are below this
};

/// Finds every pair (sorted, in `pairs`) with the kernels of `simd`, collected through
/// `collector` (which enforces pair_memory_cap: 0 = none). `bucket_pairs` gets the number of
/// bucket pairs whose boxes overlap (what the keep-the-order policy watches).
[[nodiscard]] Status search_buckets(const BucketSearchInput& in, SimdLevel simd, int threads,
                                    std::size_t pair_memory_cap, PairCollector& collector, std::vector<Pair>& pairs,
                                    std::uint64_t& bucket_pairs);

}  // namespace viscd::detail
