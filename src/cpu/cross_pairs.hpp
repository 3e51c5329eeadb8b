#pragma once
// The pairs of one tree's objects with another tree's, both of the bucket broadphase's kind, kept
// across frames or built for the frame: the static set against the moving objects
// (cpu/static_tree.hpp), and the objects that moved against the resting ones
// (cpu/rest_set.hpp).

#include <algorithm>
#include <bit>
#include <cstdint>
#include <span>
#include <type_traits>

#include "cpu/bucket_broadphase.hpp"
#include "cpu/bucket_search.hpp"
#include "cpu/wide_tree.hpp"

namespace viscd::detail {

/// A tree's lanes of the kind K tests (stage 8's tests, cpu/bucket_search.hpp).
template <class K>
std::span<const typename K::Lanes> lanes_of(const BucketBroadphase& t) {
  if constexpr (std::is_same_v<typename K::Lanes, BoxLanes>)
    return t.box_lanes();
  else
    return t.lanes();
}

/// The box of lane l of a bucket: a sphere lane's conservative box, or a box lane's box.
inline Aabb lane_box(const BucketLanes& ln, std::uint32_t l) {
  const float h = ln.h[l];
  return Aabb{{ln.x[l] - h, ln.y[l] - h, ln.z[l] - h}, {ln.x[l] + h, ln.y[l] + h, ln.z[l] + h}};
}
inline Aabb lane_box(const BoxLanes& ln, std::uint32_t l) { return ln.box(l); }

/// How cross_pairs() walks the other tree, chosen from how many objects each tree holds: the
/// fewer the moving objects, the farther apart they lie, and the larger the boxes of their buckets
/// and groups are beside the other tree's buckets (when both sets spread over the same space, as
/// the moving and resting objects of one world do). Limits measured at 10^6 objects of which 1-10 %
/// move (docs/benchmarks.md, "Walks of the moving buckets").
struct CrossWalk {
  bool group = true;    ///< first one walk per group of 16 buckets (up to 512 buckets met)
  bool bucket = false;  ///< then one walk per bucket (up to 64 buckets met with lanes that reach them)
};
[[nodiscard]] inline CrossWalk cross_walk_for(std::size_t moving, std::size_t other) {
  return {other <= 4 * moving, other <= 25 * moving};
}

/// The pairs of the buckets of group g of `moving` (the 16 under node g of its lowest level) with
/// the tree `other`. With walk.group: one walk of `other` with the group's box collects the
/// buckets that can meet any of them, then each moving bucket tests its box against those
/// candidates 16 at a time (as the moving search does, cpu/bucket_search.cpp); per bucket met, the
/// moving lanes that reach it against all 16 of its lanes by K's exact test. Past kMaxCandidates,
/// or without walk.group, each moving bucket walks on its own: with walk.bucket, one walk with the
/// bucket's box, each bucket met tested against the lanes that reach it; past kBucketMet such
/// buckets (a huge object, or objects spread far apart, as the few that move in a world at rest),
/// or without walk.bucket, each moving object walks the tree with its own box. Every way finds the
/// same pairs. Calls emit(p, q) for each pair: p the moving object's sorted position in `moving`,
/// q the other's sorted position in `other` (its id is other.sorted_objects()[q]; callers keep what
/// they report per sorted position, so that the reads of one bucket's objects share cache lines).
/// `fetch(q)`, called for the first sorted position q of each bucket of `other` whose lanes the
/// walks of single buckets and objects will read, prefetches what emit() reads for that bucket.
/// `search` (when not null) holds per bucket of `moving` the lanes that search; the others find
/// nothing.
template <class Simd, template <class> class Tests, class Emit, class Fetch>
void cross_pairs(const BucketBroadphase& moving, const BucketBroadphase& other, std::size_t g, CrossWalk walk,
                 const std::uint16_t* search, Emit&& emit, Fetch&& fetch) {
  using K = Tests<Simd>;
  constexpr std::uint32_t kMaxCandidates = 512;
  const auto ml = lanes_of<K>(moving);
  const auto sl = lanes_of<K>(other);
  const std::span<const Aabb> mboxes = moving.leaf_boxes();
  // Bucket sb's box as the walk just tested it: the lowest level's nodes hold the leaf boxes
  // (bit for bit), on lines the walk read, where leaf_boxes()[sb] would be one more miss.
  const std::span<const WideNode> leaves =
      other.tree().levels > 0 ? std::span<const WideNode>(other.tree().level[0]) : std::span<const WideNode>();
  auto walked_box = [&](std::uint32_t sb) { return leaves[sb / kWide].child(sb % kWide); };
  const std::size_t buckets = buckets_for(moving.sorted_objects().size());
  const std::size_t b0 = g * kWide, b1 = std::min(buckets, b0 + kWide);
  auto searching = [&](std::size_t b) -> std::uint32_t { return search != nullptr ? search[b] : 0xFFFFu; };
  if (search != nullptr) {
    std::uint32_t any = 0;
    for (std::size_t b = b0; b < b1; ++b) any |= search[b];
    if (any == 0) return;
  }
  // The pairs of the moving lanes `lanes` of bucket b with bucket sb of `other`: each of those
  // lanes against all 16 of sb's by K's exact test.
  auto emit_lanes = [&](std::size_t b, std::uint32_t sb, std::uint32_t lanes) {
    const std::size_t m_first = b * kBucket, s_first = std::size_t{sb} * kBucket;
    for (; lanes; lanes &= lanes - 1) {
      const auto i = static_cast<std::uint32_t>(std::countr_zero(lanes));
      for (std::uint32_t m = K::exact(sl[sb], ml[b], i); m; m &= m - 1)
        emit(m_first + i, s_first + static_cast<std::size_t>(std::countr_zero(m)));
    }
  };
  // The lanes of a bucket of `other` that K's exact test reads (a sphere lane's h is not one of
  // them), and what emit() reads for it, fetched before they are tested.
  auto prefetch = [&](std::uint32_t sb) {
    const char* lanes = reinterpret_cast<const char*>(&sl[sb]);
    for (std::size_t line = 0; line < K::kExactBytes; line += 64) __builtin_prefetch(lanes + line);
    fetch(std::size_t{sb} * kBucket);
  };
  if (walk.group) {
    WideNode box[kMaxCandidates / kWide];
    std::uint32_t index[kMaxCandidates];
    std::uint32_t count = 0;
    bool overflow = false;
    for_each_wide_overlap<Simd>(other.tree(), moving.tree().level[0][g].box(), [&](std::uint32_t sb) {
      if (count == kMaxCandidates) {
        overflow = true;
        return false;
      }
      box[count / kWide].set_child(count % kWide, walked_box(sb));
      index[count++] = sb;
      return true;
    });
    if (!overflow) {
      for (std::uint32_t l = count % kWide; l != 0 && l < kWide; ++l) box[count / kWide].set_child(l, Aabb{});
      for (std::size_t b = b0; b < b1; ++b) {
        const std::uint32_t lanes = searching(b);
        if (lanes == 0) continue;
        for (std::uint32_t k = 0; k * kWide < count; ++k)
          for (std::uint32_t m = Simd::node_children(box[k], mboxes[b]); m; m &= m - 1) {
            const auto l = static_cast<std::uint32_t>(std::countr_zero(m));
            emit_lanes(b, index[k * kWide + l], K::near(ml[b], box[k].child(l)) & lanes);
          }
      }
      return;
    }
  }
  // The buckets met are listed first, their lanes prefetched, and tested afterwards: the lanes of
  // buckets scattered over the world miss the cache, and this way the misses overlap instead of
  // queueing. met[t] is a bucket of `other`, reach[t] the moving lanes that reach it (a
  // bucket's walk) or the one lane whose walk met it (an object's walk).
  constexpr std::uint32_t kMet = 256, kBucketMet = 64, kFewLanes = 2;
  std::uint32_t met[kMet], reach[kMet];
  for (std::size_t b = b0; b < b1; ++b) {
    const std::uint32_t lanes = searching(b);
    if (lanes == 0) continue;
    std::uint32_t count_met = 0;
    auto test_met = [&] {
      for (std::uint32_t t = 0; t < count_met; ++t) emit_lanes(b, met[t], reach[t]);
      count_met = 0;
    };
    // A bucket with few lanes that search walks them one by one: its box would meet what the
    // other lanes reach too.
    if (walk.bucket && static_cast<std::uint32_t>(std::popcount(lanes)) > kFewLanes) {
      bool over = false;
      for_each_wide_overlap<Simd>(other.tree(), mboxes[b], [&](std::uint32_t sb) {
        if (count_met == kBucketMet) {
          over = true;
          return false;
        }
        if (const std::uint32_t near = K::near(ml[b], walked_box(sb)) & lanes; near != 0) {
          prefetch(sb);
          met[count_met] = sb;
          reach[count_met++] = near;
        }
        return true;
      });
      if (!over) {
        test_met();
        continue;
      }
      count_met = 0;
    }
    for (std::uint32_t i = 0; i < kBucket; ++i) {
      if (!((lanes >> i) & 1)) continue;
      const Aabb own = lane_box(ml[b], i);
      if (!(own.lo.x <= own.hi.x)) continue;  // padding (NaN) or an erased lane
      for_each_wide_overlap<Simd>(other.tree(), own, [&](std::uint32_t sb) {
        if (count_met == kMet) test_met();
        prefetch(sb);
        met[count_met] = sb;
        reach[count_met++] = 1u << i;
      });
    }
    test_met();
  }
}

#if VISCD_HAVE_AVX512
/// cross_pairs() with every call inlined into code compiled for AVX-512 (cpu/simd.hpp).
template <template <class> class Tests, class Emit, class Fetch>
VISCD_AVX512_FLATTEN void cross_pairs_avx512(const BucketBroadphase& moving, const BucketBroadphase& other,
                                             std::size_t g, CrossWalk walk, const std::uint16_t* search, Emit& emit,
                                             Fetch& fetch) {
  cross_pairs<SimdAvx512, Tests>(moving, other, g, walk, search, emit, fetch);
}
#endif

/// cross_pairs() with the kernels of `level` (a usable level: simd_level_for(), usable_simd_level()).
template <template <class> class Tests, class Emit, class Fetch>
void cross_pairs_at(SimdLevel level, const BucketBroadphase& moving, const BucketBroadphase& other, std::size_t g,
                    CrossWalk walk, const std::uint16_t* search, Emit& emit, Fetch& fetch) {
  switch (level) {
#if VISCD_HAVE_AVX512
    case SimdLevel::avx512:
      return cross_pairs_avx512<Tests>(moving, other, g, walk, search, emit, fetch);
#endif
#if defined(__SSE2__)
    case SimdLevel::sse2:
      return cross_pairs<SimdSse2, Tests>(moving, other, g, walk, search, emit, fetch);
#endif
    default:
      return cross_pairs<SimdScalar, Tests>(moving, other, g, walk, search, emit, fetch);
  }
}

}  // namespace viscd::detail
