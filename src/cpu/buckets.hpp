#pragma once
// Stage 7 of the cpu broadphase, first half ("build"): the objects, in sorted order, packed into
// buckets of kBucket consecutive objects. Each bucket keeps its objects in lanes (x, y, z, r and
// the half extent of each object's conservative box, as arrays of 16, so that stage 8's SIMD
// kernels test 16 objects at once, cpu/simd.hpp) and the box around them, over which the 16-wide
// tree is built (cpu/wide_tree.hpp). Unused lanes of the last bucket hold NaN centres, which
// overlap nothing.
//
// Why buckets (docs/benchmarks.md, "The broadphase at the limit"): with one leaf per object most
// of the build, fit and query time goes to the bottom levels of a tree, where boxes hardly prune.
// Cutting the tree at kBucket objects makes it kBucket times smaller, and the objects of two
// buckets whose boxes overlap are compared all against all out of contiguous arrays.

#include <cstddef>
#include <cstdint>
#include <limits>
#include <span>
#include <vector>

#include "core/geometry.hpp"
#include "cpu/grow.hpp"
#include "cpu/parallel.hpp"
#include "viscd/types.hpp"

namespace viscd::detail {

/// Objects per bucket: 16 beat 4 and 8 (docs/benchmarks.md, "The broadphase at the limit").
inline constexpr std::uint32_t kBucket = 16;  // the SIMD kernels (cpu/simd.hpp) are 16 lanes wide
static_assert(kBucket == 16, "the SIMD kernels (cpu/simd.hpp) test 16 lanes");

/// Reads scattered over the caller's sphere array are prefetched this many entries ahead, so
/// that many are in flight at once (at 10^6 objects each would otherwise wait on memory).
inline constexpr std::size_t kPrefetchAhead = 16;

/// The objects of one bucket in lanes; unused lanes hold NaN centres, which overlap nothing.
struct alignas(32) BucketLanes {
  float x[kBucket], y[kBucket], z[kBucket], r[kBucket];
  float h[kBucket];  ///< half extent of the object's conservative_box()
};

/// Buckets needed for n objects.
[[nodiscard]] constexpr std::size_t buckets_for(std::size_t n) { return (n + kBucket - 1) / kBucket; }

class Buckets {
 public:
  /// Packs n objects: the k-th in sorted order is sphere_at(k), object sorted_ids[k], whose
  /// filter (when `filters` is not empty) is filters[sorted_ids[k]]. Returns the bucket boxes'
  /// summed size (their three side lengths added, in bucket order: the same for any thread count).
  template <class SphereAt>
  double fill(std::size_t n, std::span<const std::uint32_t> sorted_ids, std::span<const Filter> filters, int threads,
              SphereAt&& sphere_at);
  /// fill() reading spheres[sorted_ids[k]], prefetched: the reads are out of the caller's order.
  double fill_in_order(std::span<const Sphere> spheres, std::size_t n, std::span<const std::uint32_t> sorted_ids,
                       std::span<const Filter> filters, int threads) {
    return fill(n, sorted_ids, filters, threads, [&](std::size_t k) -> const Sphere& {
      if (k + kPrefetchAhead < n) __builtin_prefetch(&spheres[sorted_ids[k + kPrefetchAhead]]);
      return spheres[sorted_ids[k]];
    });
  }

  [[nodiscard]] std::span<const BucketLanes> lanes() const { return lanes_; }
  [[nodiscard]] std::span<const Aabb> boxes() const { return boxes_; }
  /// The filters in sorted order (frames with filters; else empty).
  [[nodiscard]] std::span<const Filter> sorted_filters() const { return sorted_filters_; }
  [[nodiscard]] std::uint64_t memory_bytes() const {
    return lanes_.capacity() * sizeof(BucketLanes) + boxes_.capacity() * sizeof(Aabb) +
           sorted_filters_.capacity() * sizeof(Filter);
  }

 private:
  std::vector<BucketLanes> lanes_;
  std::vector<Aabb> boxes_;
  std::vector<Filter> sorted_filters_;
};

template <class SphereAt>
double Buckets::fill(std::size_t n, std::span<const std::uint32_t> sorted_ids, std::span<const Filter> filters,
                     int threads, SphereAt&& sphere_at) {
  constexpr float kNan = std::numeric_limits<float>::quiet_NaN();
  const std::size_t buckets = buckets_for(n);
  if (lanes_.size() != buckets) {
    resize_with_headroom(lanes_, buckets);
    resize_with_headroom(boxes_, buckets);
  }
  resize_with_headroom(sorted_filters_, filters.empty() ? 0 : n);
  parallel_for(buckets, threads, [&](std::size_t b) {
    BucketLanes& ln = lanes_[b];
    Aabb box;
    const std::size_t first = b * kBucket;
    for (std::uint32_t l = 0; l < kBucket; ++l) {
      if (first + l < n) {
        const Sphere& s = sphere_at(first + l);
        const float e = conservative_half_extent(s);  // conservative_box() is s -/+ e
        box.grow(Aabb{{s.x - e, s.y - e, s.z - e}, {s.x + e, s.y + e, s.z + e}});
        ln.x[l] = s.x, ln.y[l] = s.y, ln.z[l] = s.z, ln.r[l] = s.r, ln.h[l] = e;
        if (!filters.empty()) sorted_filters_[first + l] = filters[sorted_ids[first + l]];
      } else {
        ln.x[l] = ln.y[l] = ln.z[l] = kNan;
        ln.r[l] = 0;
        ln.h[l] = kNan;
      }
    }
    boxes_[b] = box;
  });
  // Summed in bucket order, so the decisions that use it do not depend on the thread count.
  double sum = 0;
  for (std::size_t b = 0; b < buckets; ++b) {
    const Aabb& box = boxes_[b];
    sum += double{box.hi.x - box.lo.x} + double{box.hi.y - box.lo.y} + double{box.hi.z - box.lo.z};
  }
  return sum;
}

}  // namespace viscd::detail
