#include "cpu/bucket_search.hpp"

#include <algorithm>
#include <atomic>
#include <bit>

#include "cpu/parallel.hpp"

namespace viscd::detail {
namespace {

// What stage 8 searches, for search_group().
template <class Lanes>
struct SearchView {
  const Lanes* lanes;
  const Aabb* boxes;
  const WideTree* tree;
  const std::uint32_t* ids;  // sorted position -> object id
  const Filter* filter;      // in sorted order, when filtered
  bool filtered;
  std::size_t n;        // objects
  std::uint64_t* work;  // bucket pairs whose boxes overlap, summed over the groups (atomically)

  // Emits the pair of sorted positions p and q when it passes the filters (when there are any).
  template <class Emit>
  void pair(std::uint32_t p, std::uint32_t q, Emit& emit) const {
    if (!filtered || pair_passes_filter(filter[p], filter[q])) emit(ids[p], ids[q]);
  }
};

// The pairs of bucket b with the later bucket qb (whose box overlaps b's): per object of b whose box
// reaches into qb's box, the exact test against all of qb's lanes; the filters come after the exact
// test (few candidates pass it, and the lanes stay as they are).
template <class T, class Lanes, class Emit>
inline void bucket_pairs(const SearchView<Lanes>& v, std::size_t b, std::uint32_t qb, Emit& emit) {
  const Lanes& lb = v.lanes[b];
  const Lanes& lq = v.lanes[qb];
  const auto first = static_cast<std::uint32_t>(b * kBucket);
  const std::uint32_t qfirst = qb * kBucket;
  for (std::uint32_t near = T::near(lb, v.boxes[qb]); near; near &= near - 1) {
    const auto i = static_cast<std::uint32_t>(std::countr_zero(near));
    for (std::uint32_t m = T::exact(lq, lb, i); m; m &= m - 1)
      v.pair(first + i, qfirst + static_cast<std::uint32_t>(std::countr_zero(m)), emit);
  }
}

// The pairs inside bucket b: lane i against the lanes after it.
template <class T, class Lanes, class Emit>
inline void pairs_inside(const SearchView<Lanes>& v, std::size_t b, Emit& emit) {
  const Lanes& lb = v.lanes[b];
  const auto first = static_cast<std::uint32_t>(b * kBucket);
  const auto count = static_cast<std::uint32_t>(std::min<std::size_t>(kBucket, v.n - first));
  for (std::uint32_t i = 0; i + 1 < count; ++i) {
    std::uint32_t m = T::exact(lb, lb, i) & (~0u << (i + 1));
    for (; m; m &= m - 1) v.pair(first + i, first + static_cast<std::uint32_t>(std::countr_zero(m)), emit);
  }
}

// The pairs of the buckets of group g (the 16 buckets under node g of the tree's lowest level):
// inside each bucket, then with every later bucket whose box overlaps its own, so each pair is
// found once. One tree walk per group, with the group's box, collects the later buckets that can
// meet any of its buckets (in increasing order); then each bucket tests its box against those
// candidates, 16 at a time. A walk per bucket would repeat most of the same walk 16 times. When
// more than kMaxCandidates turn up (a huge sphere), each bucket walks the tree itself.
template <class Simd, template <class> class Tests, class Lanes, class Emit>
inline void search_group(const SearchView<Lanes>& v, std::size_t g, Emit& emit) {
  using T = Tests<Simd>;
  constexpr std::uint32_t kMaxCandidates = 512;
  const std::size_t buckets = (v.n + kBucket - 1) / kBucket;
  const std::size_t b0 = g * kWide, b1 = std::min(buckets, b0 + kWide);
  const Aabb group_box = v.tree->level[0][g].box();
  WideNode box[kMaxCandidates / kWide];  // the candidates' boxes, 16 to a block
  std::uint32_t index[kMaxCandidates];
  std::uint32_t count = 0;
  bool overflow = false;
  std::uint64_t tested = 0;  // bucket pairs whose boxes overlap
  auto collect = [&](std::uint32_t q) {
    if (count == kMaxCandidates) {
      overflow = true;
      return;
    }
    box[count / kWide].set_child(count % kWide, v.boxes[q]);
    index[count++] = q;
  };
  if (g == 0)
    for_each_wide_overlap<Simd>(*v.tree, group_box, collect);
  else
    for_each_wide_overlap_after<Simd>(*v.tree, static_cast<std::uint32_t>(b0 - 1), group_box, collect);
  if (overflow) {
    for (std::size_t b = b0; b < b1 && !emit.stopped(); ++b) {
      pairs_inside<T>(v, b, emit);
      for_each_wide_overlap_after<Simd>(*v.tree, static_cast<std::uint32_t>(b), v.boxes[b], [&](std::uint32_t qb) {
        ++tested;
        bucket_pairs<T>(v, b, qb, emit);
      });
    }
    std::atomic_ref<std::uint64_t>(*v.work).fetch_add(tested, std::memory_order_relaxed);
    return;
  }
  for (std::uint32_t l = count % kWide; l != 0 && l < kWide; ++l)  // empty lanes after the last
    box[count / kWide].set_child(l, Aabb{});
  std::uint32_t cut = 0;  // index[0..cut) <= b
  for (std::size_t b = b0; b < b1 && !emit.stopped(); ++b) {
    pairs_inside<T>(v, b, emit);
    while (cut < count && index[cut] <= b) ++cut;
    for (std::uint32_t k = cut / kWide; k * kWide < count; ++k) {
      std::uint32_t m = Simd::node_children(box[k], v.boxes[b]);
      if (k == cut / kWide) m &= (0xFFFFu << (cut % kWide)) & 0xFFFFu;
      tested += static_cast<std::uint64_t>(std::popcount(m));
      for (; m; m &= m - 1)
        bucket_pairs<T>(v, b, index[k * kWide + static_cast<std::uint32_t>(std::countr_zero(m))], emit);
    }
  }
  std::atomic_ref<std::uint64_t>(*v.work).fetch_add(tested, std::memory_order_relaxed);
}

#if VISCD_HAVE_AVX512
// search_group() with every call inlined into code compiled for AVX-512 (cpu/simd.hpp).
template <template <class> class Tests, class Lanes, class Emit>
VISCD_AVX512_FLATTEN void search_group_avx512(const SearchView<Lanes>& v, std::size_t g, Emit& emit) {
  search_group<SimdAvx512, Tests>(v, g, emit);
}
#endif

}  // namespace

namespace {

template <template <class> class Tests, class Lanes>
Status search(const BucketSearchInput& in, std::span<const Lanes> lanes, SimdLevel simd, int threads,
              std::size_t pair_memory_cap, PairCollector& collector, std::vector<Pair>& pairs,
              std::uint64_t& bucket_pairs) {
  const std::size_t n = in.ids.size();
  const std::size_t buckets = buckets_for(n);
  const std::size_t groups = (buckets + kWide - 1) / kWide;
  const std::size_t chunks = threads_for(n, threads) == 1 ? 1 : std::min<std::size_t>(groups, 8 * threads);
  bucket_pairs = 0;
  const SearchView<Lanes> view{lanes.data(),      in.boxes.data(),     in.tree, in.ids.data(),
                               in.filters.data(), !in.filters.empty(), n,       &bucket_pairs};
  return collector.collect(groups, chunks, threads, pair_memory_cap, in.objects, pairs, [&](std::size_t g, auto& emit) {
    switch (simd) {
#if VISCD_HAVE_AVX512
      case SimdLevel::avx512:
        return search_group_avx512<Tests>(view, g, emit);
#endif
#if defined(__SSE2__)
      case SimdLevel::sse2:
        return search_group<SimdSse2, Tests>(view, g, emit);
#endif
      default:
        return search_group<SimdScalar, Tests>(view, g, emit);
    }
  });
}

}  // namespace

Status search_buckets(const BucketSearchInput& in, SimdLevel simd, int threads, std::size_t pair_memory_cap,
                      PairCollector& collector, std::vector<Pair>& pairs, std::uint64_t& bucket_pairs) {
  if (in.box_frame)
    return search<BoxTests>(in, in.box_lanes, simd, threads, pair_memory_cap, collector, pairs, bucket_pairs);
  return search<SphereTests>(in, in.lanes, simd, threads, pair_memory_cap, collector, pairs, bucket_pairs);
}

}  // namespace viscd::detail
