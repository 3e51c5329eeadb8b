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
/// that many are in flight at once (at 10^6 objects each would otherwise wait on memory). 64, not
/// 16: a read that misses the cache and the TLB takes longer than 16 objects' work (the build of
/// a kept frame, ring without culling, 2 threads: 3.9 -> 2.4 ms at 10^6 objects, 63 -> 33 ms at
/// 10^7; 48 to 128 alike; docs/benchmarks.md, "Ten million objects").
inline constexpr std::size_t kPrefetchAhead = 64;

/// The objects of one bucket in lanes; unused lanes hold NaN centres, which overlap nothing.
struct alignas(64) BucketLanes {
  float x[kBucket], y[kBucket], z[kBucket], r[kBucket];
  float h[kBucket];  ///< half extent of the object's conservative_box()
};

/// The boxes of one bucket's objects (box frames) in lanes, named as WideNode's children so that
/// the same SIMD test (node_children(), the exact box test) serves both; unused lanes hold NaN.
struct alignas(64) BoxLanes {
  float lo_x[kBucket], lo_y[kBucket], lo_z[kBucket], hi_x[kBucket], hi_y[kBucket], hi_z[kBucket];
  [[nodiscard]] Aabb box(std::uint32_t l) const {
    return Aabb{{lo_x[l], lo_y[l], lo_z[l]}, {hi_x[l], hi_y[l], hi_z[l]}};
  }
  /// As ray_children() reads a node's children.
  [[nodiscard]] Aabb child(std::uint32_t l) const { return box(l); }
  /// Lane l as the object's Box.
  [[nodiscard]] Box object(std::uint32_t l) const {
    return Box{{lo_x[l], lo_y[l], lo_z[l]}, {hi_x[l], hi_y[l], hi_z[l]}};
  }
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
  /// fill() for box frames: the k-th object in sorted order is boxes[sorted_ids[k]], into box_lanes().
  double fill_boxes(std::span<const Box> boxes, std::size_t n, std::span<const std::uint32_t> sorted_ids,
                    std::span<const Filter> filters, int threads);

  [[nodiscard]] std::span<const BucketLanes> lanes() const { return lanes_; }
  [[nodiscard]] std::span<const BoxLanes> box_lanes() const { return box_lanes_; }
  [[nodiscard]] std::span<const Aabb> boxes() const { return boxes_; }
  /// The filters in sorted order (frames with filters; else empty).
  [[nodiscard]] std::span<const Filter> sorted_filters() const { return sorted_filters_; }
  [[nodiscard]] std::uint64_t memory_bytes() const {
    return lanes_.capacity() * sizeof(BucketLanes) + box_lanes_.capacity() * sizeof(BoxLanes) +
           boxes_.capacity() * sizeof(Aabb) + sorted_filters_.capacity() * sizeof(Filter);
  }

  /// Takes the object at sorted position p out: its lane becomes padding (NaN), which no test
  /// passes. The bucket's box stays as it was (still around what is left). `boxes_frame`: the
  /// buckets hold box lanes.
  void erase_lane(std::size_t p, bool boxes_frame) {
    constexpr float kNan = std::numeric_limits<float>::quiet_NaN();
    const std::size_t b = p / kBucket, l = p % kBucket;
    if (boxes_frame) {
      BoxLanes& ln = box_lanes_[b];
      ln.lo_x[l] = ln.lo_y[l] = ln.lo_z[l] = ln.hi_x[l] = ln.hi_y[l] = ln.hi_z[l] = kNan;
    } else {
      BucketLanes& ln = lanes_[b];
      ln.x[l] = ln.y[l] = ln.z[l] = ln.h[l] = kNan;
      ln.r[l] = 0;
    }
  }

 private:
  /// Summed size of the bucket boxes, in bucket order (the same for any thread count).
  [[nodiscard]] double box_sum(std::size_t buckets) const;

  std::vector<BucketLanes> lanes_;
  std::vector<BoxLanes> box_lanes_;
  std::vector<Aabb> boxes_;
  std::vector<Filter> sorted_filters_;
};

template <class SphereAt>
double Buckets::fill(std::size_t n, std::span<const std::uint32_t> sorted_ids, std::span<const Filter> filters,
                     int threads, SphereAt&& sphere_at) {
  constexpr float kNan = std::numeric_limits<float>::quiet_NaN();
  const std::size_t buckets = buckets_for(n);
  if (lanes_.size() != buckets || boxes_.size() != buckets) {
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
  return box_sum(buckets);
}

inline double Buckets::box_sum(std::size_t buckets) const {
  // Summed in bucket order, so the decisions that use it do not depend on the thread count.
  double sum = 0;
  for (std::size_t b = 0; b < buckets; ++b) {
    const Aabb& box = boxes_[b];
    sum += double{box.hi.x - box.lo.x} + double{box.hi.y - box.lo.y} + double{box.hi.z - box.lo.z};
  }
  return sum;
}

inline double Buckets::fill_boxes(std::span<const Box> boxes, std::size_t n, std::span<const std::uint32_t> sorted_ids,
                                  std::span<const Filter> filters, int threads) {
  constexpr float kNan = std::numeric_limits<float>::quiet_NaN();
  const std::size_t buckets = buckets_for(n);
  if (box_lanes_.size() != buckets || boxes_.size() != buckets) {
    resize_with_headroom(box_lanes_, buckets);
    resize_with_headroom(boxes_, buckets);
  }
  resize_with_headroom(sorted_filters_, filters.empty() ? 0 : n);
  parallel_for(buckets, threads, [&](std::size_t b) {
    BoxLanes& ln = box_lanes_[b];
    Aabb box;
    const std::size_t first = b * kBucket;
    for (std::uint32_t l = 0; l < kBucket; ++l) {
      if (first + l < n) {
        if (first + l + kPrefetchAhead < n) __builtin_prefetch(&boxes[sorted_ids[first + l + kPrefetchAhead]]);
        const Box& o = boxes[sorted_ids[first + l]];
        box.grow(box_aabb(o));
        ln.lo_x[l] = o.min[0], ln.lo_y[l] = o.min[1], ln.lo_z[l] = o.min[2];
        ln.hi_x[l] = o.max[0], ln.hi_y[l] = o.max[1], ln.hi_z[l] = o.max[2];
        if (!filters.empty()) sorted_filters_[first + l] = filters[sorted_ids[first + l]];
      } else {
        ln.lo_x[l] = ln.lo_y[l] = ln.lo_z[l] = ln.hi_x[l] = ln.hi_y[l] = ln.hi_z[l] = kNan;
      }
    }
    boxes_[b] = box;
  });
  return box_sum(buckets);
}

}  // namespace viscd::detail
