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
  std::uint32_t static_from = ~0u;     ///< ids from here on are static: no pair of two of them
};

/// Finds every pair (sorted, in `pairs`) with the kernels of `simd`, collected through
/// `collector` (which enforces pair_memory_cap: 0 = none). `bucket_pairs` gets the number of
/// bucket pairs whose boxes overlap (what the keep-the-order policy watches).
[[nodiscard]] Status search_buckets(const BucketSearchInput& in, SimdLevel simd, int threads,
                                    std::size_t pair_memory_cap, PairCollector& collector, std::vector<Pair>& pairs,
                                    std::uint64_t& bucket_pairs);

}  // namespace viscd::detail
