#include "cpu/bucket_broadphase.hpp"

#include <algorithm>
#include <array>
#include <atomic>
#include <bit>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <limits>

#include "core/stopwatch.hpp"
#include "cpu/broadphase.hpp"
#include "cpu/grow.hpp"
#include "cpu/parallel.hpp"
#include "cpu/wide_tree.hpp"

#include "cpu/simd.hpp"

namespace viscd::detail {
namespace {

// What stage 8 searches, for search_group().
struct SearchView {
  const BucketLanes* lanes;
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

// Reads scattered over the caller's sphere array are prefetched this many entries ahead, so that
// many are in flight at once (at 10^6 objects each would otherwise wait on memory).
constexpr std::size_t kPrefetchAhead = 16;

// The pairs of bucket b with the later bucket qb (whose box overlaps b's): per object of b whose box
// reaches into qb's box, the exact test against all of qb's lanes; the filters come after the exact
// test (few candidates pass it, and the lanes stay as they are).
template <class Simd, class Emit>
inline void bucket_pairs(const SearchView& v, std::size_t b, std::uint32_t qb, Emit& emit) {
  const BucketLanes& lb = v.lanes[b];
  const BucketLanes& lq = v.lanes[qb];
  const auto first = static_cast<std::uint32_t>(b * kBucket);
  const std::uint32_t qfirst = qb * kBucket;
  for (std::uint32_t near = Simd::box_lanes(lb, v.boxes[qb]); near; near &= near - 1) {
    const auto i = static_cast<std::uint32_t>(std::countr_zero(near));
    for (std::uint32_t m = Simd::sphere_lanes(lq, lb.x[i], lb.y[i], lb.z[i], lb.r[i]); m; m &= m - 1)
      v.pair(first + i, qfirst + static_cast<std::uint32_t>(std::countr_zero(m)), emit);
  }
}

// The pairs inside bucket b: lane i against the lanes after it.
template <class Simd, class Emit>
inline void pairs_inside(const SearchView& v, std::size_t b, Emit& emit) {
  const BucketLanes& lb = v.lanes[b];
  const auto first = static_cast<std::uint32_t>(b * kBucket);
  const auto count = static_cast<std::uint32_t>(std::min<std::size_t>(kBucket, v.n - first));
  for (std::uint32_t i = 0; i + 1 < count; ++i) {
    std::uint32_t m = Simd::sphere_lanes(lb, lb.x[i], lb.y[i], lb.z[i], lb.r[i]) & (~0u << (i + 1));
    for (; m; m &= m - 1) v.pair(first + i, first + static_cast<std::uint32_t>(std::countr_zero(m)), emit);
  }
}

// The pairs of the buckets of group g (the 16 buckets under node g of the tree's lowest level):
// inside each bucket, then with every later bucket whose box overlaps its own, so each pair is
// found once. One tree walk per group, with the group's box, collects the later buckets that can
// meet any of its buckets (in increasing order); then each bucket tests its box against those
// candidates, 16 at a time. A walk per bucket would repeat most of the same walk 16 times. When
// more than kMaxCandidates turn up (a huge sphere), each bucket walks the tree itself.
template <class Simd, class Emit>
inline void search_group(const SearchView& v, std::size_t g, Emit& emit) {
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
      pairs_inside<Simd>(v, b, emit);
      for_each_wide_overlap_after<Simd>(*v.tree, static_cast<std::uint32_t>(b), v.boxes[b], [&](std::uint32_t qb) {
        ++tested;
        bucket_pairs<Simd>(v, b, qb, emit);
      });
    }
    std::atomic_ref<std::uint64_t>(*v.work).fetch_add(tested, std::memory_order_relaxed);
    return;
  }
  for (std::uint32_t l = count % kWide; l != 0 && l < kWide; ++l)  // empty lanes after the last
    box[count / kWide].set_child(l, Aabb{});
  std::uint32_t cut = 0;  // index[0..cut) <= b
  for (std::size_t b = b0; b < b1 && !emit.stopped(); ++b) {
    pairs_inside<Simd>(v, b, emit);
    while (cut < count && index[cut] <= b) ++cut;
    for (std::uint32_t k = cut / kWide; k * kWide < count; ++k) {
      std::uint32_t m = Simd::node_children(box[k], v.boxes[b]);
      if (k == cut / kWide) m &= (0xFFFFu << (cut % kWide)) & 0xFFFFu;
      tested += static_cast<std::uint64_t>(std::popcount(m));
      for (; m; m &= m - 1)
        bucket_pairs<Simd>(v, b, index[k * kWide + static_cast<std::uint32_t>(std::countr_zero(m))], emit);
    }
  }
  std::atomic_ref<std::uint64_t>(*v.work).fetch_add(tested, std::memory_order_relaxed);
}

#if VISCD_HAVE_AVX512
// search_group() with every call inlined into code compiled for AVX-512 (cpu/simd.hpp).
template <class Emit>
VISCD_AVX512_FLATTEN void search_group_avx512(const SearchView& v, std::size_t g, Emit& emit) {
  search_group<SimdAvx512>(v, g, emit);
}
#endif

}  // namespace

std::uint64_t BucketBroadphase::memory_bytes() const {
  std::uint64_t b = bytes_of(sorted_ids_) + bytes_of(previous_ids_) + bytes_of(rank_) + bytes_of(lanes_) +
                    bytes_of(bucket_boxes_) + bytes_of(gathered_) + bytes_of(entries_) + bytes_of(merged_) +
                    bytes_of(previous_active_) + pairs_.memory_bytes();
  for (const auto& f : far_) b += bytes_of(f);
  for (const auto& level : tree_.level) b += bytes_of(level);
  keys_.for_each([&](const auto& v) { b += bytes_of(v); });
  scratch_.for_each([&](const auto& s) { b += bytes_of(s.keys) + bytes_of(s.values); });
  return b;
}

std::vector<std::uint64_t> BucketBroadphase::sorted_codes() const { return keys_.widened(bits_, sorted_ids_.size()); }

Status BucketBroadphase::run(std::span<const Sphere> spheres, std::span<const std::uint32_t> active,
                             std::span<const Filter> filters, int bits, Layout layout, int threads,
                             std::size_t pair_memory_cap, std::vector<Pair>& pairs, FrameStats& stats) {
  build_tree(spheres, active, filters, bits, layout, threads, stats);
  return find_pairs(active, !filters.empty(), threads, pair_memory_cap, pairs, stats);
}

void BucketBroadphase::build(std::span<const Sphere> spheres, std::span<const std::uint32_t> active, int bits,
                             Layout layout, int threads, FrameStats& stats) {
  build_tree(spheres, active, {}, bits, layout, threads, stats);
}

void BucketBroadphase::build_tree(std::span<const Sphere> spheres, std::span<const std::uint32_t> active,
                                  std::span<const Filter> filters, int bits, Layout layout, int threads,
                                  FrameStats& stats) {
  VISCD_ASSERT(bits == 16 || bits == 32 || bits == 64, "Morton width must be 16, 32 or 64");
  Stopwatch attempt;
  if (keep_last_order(spheres, active, filters, bits, layout, threads, stats)) return;
  const double attempt_ms = attempt.lap();  // an attempt that found the buckets spread: counted in build
  Stopwatch sw;
  const ActiveExtent extent = active_extent(spheres, active, threads);
  layout_ = make_layout(layout, bits, extent.bounds, extent.mean_diameter());
  if (bits != bits_) previous_ids_.clear();  // the last order was by codes of another width
  bits_ = bits;
  stats.bits = bits;
  stats.layout = layout_.info();
  stats.ms(Stage::layout) = sw.lap();
  double box_sum = 0;
  switch (bits) {
    case 16:
      box_sum = build_keys<std::uint16_t>(spheres, active, filters, extent.bounds, threads, stats);
      break;
    case 32:
      box_sum = build_keys<std::uint32_t>(spheres, active, filters, extent.bounds, threads, stats);
      break;
    default:
      box_sum = build_keys<std::uint64_t>(spheres, active, filters, extent.bounds, threads, stats);
  }
  stats.ms(Stage::build) += attempt_ms;
  fit_tree(active.size(), threads, stats);
  remember_sorted(spheres, active, layout, box_sum);
}

void BucketBroadphase::fit_tree(std::size_t n, int threads, FrameStats& stats) {
  Stopwatch sw;
  build_wide_tree(std::span<const Aabb>(bucket_boxes_.data(), (n + kBucket - 1) / kBucket), tree_, threads);
  stats.ms(Stage::fit) = sw.lap();
#ifdef VISCD_VALIDATE
  const std::string problem = validate_wide_tree(tree_, bucket_boxes_);
  VISCD_ASSERT(problem.empty(), problem.c_str());
#endif
}

// The same active set as the last sorted frame (and every frame since): all objects of as many,
// or the same ids. active is ascending and distinct, so n == spheres.size() means all of them.
bool BucketBroadphase::same_active_set(std::size_t objects, std::span<const std::uint32_t> active) const {
  if (active.size() == objects) return previous_all_ && previous_objects_ == objects;
  return !previous_all_ && std::equal(active.begin(), active.end(), previous_active_.begin(), previous_active_.end());
}

bool BucketBroadphase::keep_last_order(std::span<const Sphere> spheres, std::span<const std::uint32_t> active,
                                       std::span<const Filter> filters, int bits, Layout layout, int threads,
                                       FrameStats& stats) {
  sort_report_ = {};
  const std::size_t n = active.size();
  if (!keep_order_ || sort_next_ || bits != bits_ || layout != previous_layout_ || n < 2 || previous_ids_.size() != n ||
      !std::isfinite(sorted_box_sum_) || !same_active_set(spheres.size(), active))
    return false;
  Stopwatch sw;
  stats.bits = bits;
  stats.layout = layout_.info();  // the layout of the codes that ordered the objects
  // sorted_ids_ holds the last order (the stage 6 of the last sorted frame wrote it).
  const double box_sum = fill_lanes_in_order(spheres, n, filters, threads);
  if (!(box_sum <= (1 + kStaleness) * sorted_box_sum_)) return false;  // moved too much: sort
  stats.ms(Stage::build) = sw.lap();
  fit_tree(n, threads, stats);
  sort_report_.kept = stats.order_kept = true;
  return true;
}

void BucketBroadphase::remember_sorted(std::span<const Sphere> spheres, std::span<const std::uint32_t> active,
                                       Layout layout, double box_sum) {
  previous_all_ = active.size() == spheres.size();
  previous_objects_ = spheres.size();
  previous_layout_ = layout;
  if (previous_all_) {
    previous_active_.clear();
  } else {
    resize_with_headroom(previous_active_, active.size());
    std::copy(active.begin(), active.end(), previous_active_.begin());
  }
  sorted_box_sum_ = box_sum;
  sorted_work_ = 0;  // until this frame's query counts it
  sort_next_ = false;
}

template <class SphereAt>
double BucketBroadphase::fill_lanes(std::size_t n, std::span<const Filter> filters, int threads, SphereAt&& sphere_at) {
  constexpr float kNan = std::numeric_limits<float>::quiet_NaN();
  const std::size_t buckets = (n + kBucket - 1) / kBucket;
  if (lanes_.size() != buckets) {
    resize_with_headroom(lanes_, buckets);
    resize_with_headroom(bucket_boxes_, buckets);
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
        if (!filters.empty()) sorted_filters_[first + l] = filters[sorted_ids_[first + l]];
      } else {
        ln.x[l] = ln.y[l] = ln.z[l] = kNan;
        ln.r[l] = 0;
        ln.h[l] = kNan;
      }
    }
    bucket_boxes_[b] = box;
  });
  // Summed in bucket order, so the decisions that use it do not depend on the thread count.
  double sum = 0;
  for (std::size_t b = 0; b < buckets; ++b) {
    const Aabb& box = bucket_boxes_[b];
    sum += double{box.hi.x - box.lo.x} + double{box.hi.y - box.lo.y} + double{box.hi.z - box.lo.z};
  }
  return sum;
}

double BucketBroadphase::fill_lanes_in_order(std::span<const Sphere> spheres, std::size_t n,
                                             std::span<const Filter> filters, int threads) {
  return fill_lanes(n, filters, threads, [&](std::size_t k) -> const Sphere& {
    if (k + kPrefetchAhead < n) __builtin_prefetch(&spheres[sorted_ids_[k + kPrefetchAhead]]);
    return spheres[sorted_ids_[k]];
  });
}

// The objects still active in the last frame's order, then the new ones by index, into
// sorted_ids_[0..n). When every object is active and the last frame had the same ones (the steady
// state without culling), that is the last order as it stands.
void BucketBroadphase::last_order(std::size_t objects, std::span<const std::uint32_t> active) {
  const std::size_t n = active.size();
  if (n == objects && previous_ids_.size() == n) {
    // active is 0..n-1 (ascending, distinct), and the last order holds n distinct ids: when all
    // are below n it is a permutation of them.
    if (std::all_of(previous_ids_.begin(), previous_ids_.end(), [n](std::uint32_t id) { return id < n; })) {
      std::copy(previous_ids_.begin(), previous_ids_.end(), sorted_ids_.begin());
      return;
    }
  }
  rank_.assign(objects, 0);  // 1: active and not yet placed
  for (const std::uint32_t id : active) rank_[id] = 1;
  std::size_t p = 0;
  for (const std::uint32_t id : previous_ids_) {
    if (id >= objects || rank_[id] == 0) continue;
    sorted_ids_[p++] = id;
    rank_[id] = 0;
  }
  for (const std::uint32_t id : active)
    if (rank_[id]) sorted_ids_[p++] = id;
  VISCD_ASSERT(p == n, "every active object is placed once");
}

template <class K>
double BucketBroadphase::build_keys(std::span<const Sphere> spheres, std::span<const std::uint32_t> active,
                                    std::span<const Filter> filters, const Aabb& bounds, int threads,
                                    FrameStats& stats) {
  Stopwatch sw;
  const std::size_t n = active.size();
  std::vector<K>& key = keys_.get<K>();
  if (key.size() < n) resize_with_headroom(key, n);
  resize_with_headroom(sorted_ids_, n);
  const MortonEncoder encoder(layout_, bounds);
  auto code_of = [&](const Sphere& s) { return static_cast<K>(encoder.encode(s.x, s.y, s.z)); };
  // (code, id) in one entry: packed into `key` when the code has at most 32 bits, so that one
  // comparison orders by code and ties by id; else code and id compared in turn.
  auto entry_of = [](K code, std::uint32_t id, std::uint32_t at) {
    if constexpr (sizeof(K) <= 4)
      return SortEntry{std::uint64_t{code} << 32 | id, id, at};
    else
      return SortEntry{code, id, at};
  };
  auto less = [](const SortEntry& a, const SortEntry& b) {
    if constexpr (sizeof(K) <= 4)
      return a.key < b.key;
    else
      return a.key < b.key || (a.key == b.key && a.id < b.id);
  };
  auto code_in = [](const SortEntry& e) { return static_cast<K>(sizeof(K) <= 4 ? e.key >> 32 : e.key); };

  // Stages 5 and 6 from the last frame's order: the spheres are read once, in that order, into
  // gathered_ (the one pass that reads them out of the caller's order); their codes are taken on
  // the way; the sort moves (code, id, place) entries; and the lanes of stage 7 read gathered_
  // in nearly the order it was written.
  sort_report_ = {};
  const bool from_last = n > 1 && !previous_ids_.empty();
  bool reused = false;
  // Sized on every sorted frame, also from scratch: the next sorted frame may come after kept
  // frames, and should not be the one that allocates.
  resize_with_headroom(gathered_, n);
  resize_with_headroom(entries_, n);
  resize_with_headroom(merged_, n);
  if (!from_last) {
    reserve_far(n, sort_runs(n, threads));
    if (rank_.capacity() < spheres.size()) rank_.reserve(spheres.size() + spheres.size() / 2);
  }
  if (from_last) {
    last_order(spheres.size(), active);
    for_chunks(n, static_cast<std::size_t>(threads_for(n, threads)), [&](std::size_t b, std::size_t e, std::size_t) {
      for (std::size_t p = b; p < e; ++p) {
        if (p + kPrefetchAhead < e) __builtin_prefetch(&spheres[sorted_ids_[p + kPrefetchAhead]]);
        const Sphere& s = spheres[sorted_ids_[p]];
        gathered_[p] = s;
        entries_[p] = entry_of(code_of(s), sorted_ids_[p], static_cast<std::uint32_t>(p));
      }
    });
    stats.ms(Stage::codes) = sw.lap();
    reused = sort_nearly_sorted(n, threads, less);
    if (reused) {
      parallel_for(n, threads, [&](std::size_t k) {
        key[k] = code_in(entries_[k]);
        sorted_ids_[k] = entries_[k].id;
      });
    }
  }
  if (!reused) {
    // From scratch: codes in active order, then the radix sort. Values start as the active ids in
    // ascending order and the sort is stable, so ties end up by object id, as above.
    parallel_for(n, threads, [&](std::size_t k) { key[k] = code_of(spheres[active[k]]); });
    if (!from_last) stats.ms(Stage::codes) = sw.lap();  // else the failed attempt's codes are timed
    for (std::size_t k = 0; k < n; ++k) sorted_ids_[k] = active[k];
    radix_sort<K>(std::span<K>(key.data(), n), std::span<std::uint32_t>(sorted_ids_.data(), n), 8 * sizeof(K), threads,
                  scratch_.get<K>());
  }
  resize_with_headroom(previous_ids_, n);
  std::copy(sorted_ids_.begin(), sorted_ids_.end(), previous_ids_.begin());
  stats.ms(Stage::sort) = sw.lap();

  // Stage 7: build gathers the objects into bucket lanes and takes the bucket boxes (fit, the
  // tree over them, follows in build_tree()).
  const double box_sum = reused ? fill_lanes(n, filters, threads,
                                             [&](std::size_t k) -> const Sphere& { return gathered_[entries_[k].at]; })
                                : fill_lanes_in_order(spheres, n, filters, threads);
  stats.ms(Stage::build) = sw.lap();
  return box_sum;
}

namespace {

// One run of the sort from the last order: sorts e[0..len) in place into e[0..kept) and sets the
// entries that moved far aside into `far` (unsorted). An entry that belongs at most kReach places
// back is shifted in. False when more than far_limit are set aside.
template <class Less>
bool insert_within_reach(SortEntry* e, std::size_t len, std::size_t far_limit, std::vector<SortEntry>& far,
                         std::size_t& kept, std::uint64_t& moved, Less less) {
  constexpr std::size_t kReach = 32;
  std::size_t m = 0;  // e[0..m) holds the entries kept so far, sorted
  for (std::size_t i = 0; i < len; ++i) {
    const SortEntry x = e[i];
    // Set aside: an entry above the one kReach ahead (it moved far forward: kept, it would stay
    // on top while everything after it had to be shifted past it), or one that belongs more
    // than kReach places back.
    const bool above_ahead = i + kReach < len && less(e[i + kReach], x);
    if ((m == 0 || less(e[m - 1], x)) && !above_ahead) {
      e[m++] = x;
      continue;
    }
    const std::size_t lo = m > kReach ? m - kReach : 0;
    if (above_ahead || (lo > 0 && less(x, e[lo]))) {
      if (far.size() == far_limit) return false;
      far.push_back(x);
      continue;
    }
    std::size_t j = m;  // shift up the entries above x (e[m - 1] is)
    do {
      e[j] = e[j - 1];
      --j;
    } while (j > lo && less(x, e[j - 1]));
    e[j] = x;
    moved += m - j;
    ++m;
  }
  kept = m;
  return true;
}

}  // namespace

std::size_t BucketBroadphase::sort_runs(std::size_t n, int threads) {
  return std::min<std::size_t>(kMaxSortRuns, static_cast<std::size_t>(threads_for(n, threads)));
}

// Room for what each of `runs` runs over n entries may set aside (a quarter of a run, and 64), and
// for all of it together.
void BucketBroadphase::reserve_far(std::size_t n, std::size_t runs) {
  const std::size_t limit = (n + runs - 1) / runs / 4 + 64;
  for (std::size_t r = 0; r < runs; ++r)
    if (far_[r].capacity() < limit) far_[r].reserve(limit + limit / 2);
  if (far_[kMaxSortRuns].capacity() < runs * limit) far_[kMaxSortRuns].reserve(runs * limit + runs * limit / 2);
}

// Sorts entries_[0..n), nearly sorted already, by `less` (no two entries equal). The entries are
// cut into one run per thread; each run is finished by insert_within_reach(), which sets aside the
// entries that moved far (objects that crossed a large Morton cell). Then the runs and the
// set-aside entries (sorted: they are few) are merged, in parallel over parts of the output cut at
// the first key of each run. Gives up (false) when a run sets aside more than a quarter of its
// entries: then the last order says little, and the radix sort costs less.
template <class Less>
bool BucketBroadphase::sort_nearly_sorted(std::size_t n, int threads, Less less) {
  const std::size_t runs = sort_runs(n, threads);
  std::array<std::size_t, kMaxSortRuns> begin{}, kept{};
  std::array<std::uint64_t, kMaxSortRuns> moved{};
  std::array<bool, kMaxSortRuns> ok{};
  reserve_far(n, runs);
  for_chunks(n, runs, [&](std::size_t b, std::size_t e, std::size_t r) {
    std::vector<SortEntry>& far = far_[r];
    const std::size_t far_limit = (e - b) / 4 + 64;
    far.clear();
    begin[r] = b;
    ok[r] = insert_within_reach(entries_.data() + b, e - b, far_limit, far, kept[r], moved[r], less);
  });
  std::uint64_t moves = 0, set_aside = 0;
  for (std::size_t r = 0; r < runs; ++r) moves += moved[r], set_aside += far_[r].size();
  sort_report_ = {};
  sort_report_.reused =
      std::all_of(ok.begin(), ok.begin() + static_cast<std::ptrdiff_t>(runs), [](bool b) { return b; });
  sort_report_.moves = moves;
  sort_report_.far = set_aside;
  if (!sort_report_.reused) return false;
  if (runs == 1 && set_aside == 0) return true;

  // The inputs of the merge: each run, and all set-aside entries in one sorted list.
  std::vector<SortEntry>& far = far_[kMaxSortRuns];
  if (far.capacity() < set_aside) far.reserve(set_aside + set_aside / 2);
  far.clear();
  for (std::size_t r = 0; r < runs; ++r) far.insert(far.end(), far_[r].begin(), far_[r].end());
  std::sort(far.begin(), far.end(), less);
  struct Input {
    const SortEntry* data;
    std::size_t size;
  };
  std::array<Input, kMaxSortRuns + 1> in{};
  for (std::size_t r = 0; r < runs; ++r) in[r] = {entries_.data() + begin[r], kept[r]};
  in[runs] = {far.data(), far.size()};
  const std::size_t inputs = runs + 1;
  // Part p of the output holds the entries from the first key of run p (raised to the previous
  // part's when runs overlap, so parts follow each other) up to part p + 1's.
  std::array<std::array<std::size_t, kMaxSortRuns + 1>, kMaxSortRuns + 1> cut{};  // [part][input]
  std::array<std::size_t, kMaxSortRuns + 1> out_at{};
  const SortEntry* splitter = nullptr;
  for (std::size_t p = 0; p <= runs; ++p) {
    if (p == 0 || p == runs) {
      for (std::size_t k = 0; k < inputs; ++k) cut[p][k] = p == 0 ? 0 : in[k].size;
    } else {
      if (in[p].size > 0 && (splitter == nullptr || less(*splitter, in[p].data[0]))) splitter = in[p].data;
      for (std::size_t k = 0; k < inputs; ++k)
        cut[p][k] = splitter ? static_cast<std::size_t>(
                                   std::lower_bound(in[k].data, in[k].data + in[k].size, *splitter, less) - in[k].data)
                             : 0;
    }
    out_at[p] = 0;
    for (std::size_t k = 0; k < inputs; ++k) out_at[p] += cut[p][k];
  }
  run_tasks(static_cast<std::uint32_t>(runs), [&](std::uint32_t p) {
    std::array<std::size_t, kMaxSortRuns + 1> at{};
    for (std::size_t k = 0; k < inputs; ++k) at[k] = cut[p][k];
    for (std::size_t o = out_at[p]; o < out_at[p + 1]; ++o) {
      std::size_t best = inputs;
      for (std::size_t k = 0; k < inputs; ++k)
        if (at[k] < cut[p + 1][k] && (best == inputs || less(in[k].data[at[k]], in[best].data[at[best]]))) best = k;
      merged_[o] = in[best].data[at[best]++];
    }
  });
  std::swap(entries_, merged_);
  return true;
}

Status BucketBroadphase::find_pairs(std::span<const std::uint32_t> active, bool filtered, int threads,
                                    std::size_t pair_memory_cap, std::vector<Pair>& pairs, FrameStats& stats) {
  Stopwatch sw;
  // Stage 8: per group of 16 buckets, search_group().
  const std::size_t n = sorted_ids_.size();
  const std::size_t buckets = (n + kBucket - 1) / kBucket;
  const std::size_t groups = (buckets + kWide - 1) / kWide;
  const std::size_t chunks = threads_for(n, threads) == 1 ? 1 : std::min<std::size_t>(groups, 8 * threads);
  const std::uint32_t objects = n ? active.back() + 1 : 0;  // active is ascending
  std::uint64_t work = 0;                                   // bucket pairs whose boxes overlap
  const SearchView view{
      lanes_.data(), bucket_boxes_.data(), &tree_, sorted_ids_.data(), sorted_filters_.data(), filtered, n, &work};
  const SimdLevel simd = simd_;
  const Status found =
      pairs_.collect(groups, chunks, threads, pair_memory_cap, objects, pairs, [&](std::size_t g, auto& emit) {
        switch (simd) {
#if VISCD_HAVE_AVX512
          case SimdLevel::avx512:
            return search_group_avx512(view, g, emit);
#endif
#if defined(__SSE2__)
          case SimdLevel::sse2:
            return search_group<SimdSse2>(view, g, emit);
#endif
          default:
            return search_group<SimdScalar>(view, g, emit);
        }
      });
  // The bucket-pair count of a sorted frame is what kept frames compare with; a kept frame whose
  // count has grown past it by more than kStaleness makes the next frame sort. (A frame stopped by
  // the pair cap counted only part.)
  if (!found) {
    sort_next_ = true;
    return found;
  }
  if (!sort_report_.kept)
    sorted_work_ = work;
  else if (sorted_work_ != 0 && static_cast<double>(work) > (1 + kStaleness) * static_cast<double>(sorted_work_))
    sort_next_ = true;
  stats.pairs = pairs.size();
  stats.ms(Stage::query) = sw.lap();
  return {};
}

// ---- queries ----

namespace {

// A ray prepared for slab tests against boxes widened by ray_box_margin(), in double (see there).
// Along an axis the widened slab [lo - margin, hi + margin] is entered at (lo - (o + margin)) / d
// and left at (hi - (o - margin)) / d for d > 0 (the other way round for d < 0); along an axis
// with d = 0 the origin must lie in the slab.
struct RaySetup {
  double lo_shift[3], hi_shift[3], inv[3];  // o + margin, o - margin, 1 / d
  bool flat[3], negative[3];
  explicit RaySetup(const Ray& r) {
    const double margin = ray_box_margin(r.origin);
    for (int k = 0; k < 3; ++k) {
      lo_shift[k] = double{r.origin[k]} + margin;
      hi_shift[k] = double{r.origin[k]} - margin;
      flat[k] = r.dir[k] == 0;
      negative[k] = r.dir[k] < 0;
      inv[k] = flat[k] ? 0.0 : 1.0 / double{r.dir[k]};
    }
  }
};

// Where the segment t in [0, t_hi] enters the widened box; false when it misses it.
// (Used by the builds without SSE2; the SSE2 ones test two boxes at a time with slab2().)
[[maybe_unused]] inline bool ray_box(const RaySetup& q, const Aabb& b, double t_hi, double& t_enter) {
  const float lo[3] = {b.lo.x, b.lo.y, b.lo.z}, hi[3] = {b.hi.x, b.hi.y, b.hi.z};
  double t0 = 0, t1 = t_hi;
  for (int k = 0; k < 3; ++k) {
    const double a = (double{lo[k]} - q.lo_shift[k]) * q.inv[k], c = (double{hi[k]} - q.hi_shift[k]) * q.inv[k];
    if (q.flat[k]) {
      if (double{lo[k]} > q.lo_shift[k] || double{hi[k]} < q.hi_shift[k]) return false;
    } else {
      t0 = std::max(t0, q.negative[k] ? c : a);
      t1 = std::min(t1, q.negative[k] ? a : c);
    }
  }
  t_enter = t0;
  return t0 <= t1;
}

#if defined(__SSE2__)
// One axis of the slab test of ray_box() on two boxes at once ([lo, hi] per lane, in double):
// narrows [t0, t1], or along an axis the ray does not move, clears `inside` where the origin
// lies outside the widened slab.
inline void slab2(const RaySetup& q, int k, __m128d lo, __m128d hi, __m128d& t0, __m128d& t1, __m128d& inside) {
  if (q.flat[k]) {
    inside = _mm_and_pd(
        inside, _mm_and_pd(_mm_cmple_pd(lo, _mm_set1_pd(q.lo_shift[k])), _mm_cmpge_pd(hi, _mm_set1_pd(q.hi_shift[k]))));
    return;
  }
  const __m128d inv = _mm_set1_pd(q.inv[k]);
  const __m128d a = _mm_mul_pd(_mm_sub_pd(lo, _mm_set1_pd(q.lo_shift[k])), inv);
  const __m128d e = _mm_mul_pd(_mm_sub_pd(hi, _mm_set1_pd(q.hi_shift[k])), inv);
  t0 = _mm_max_pd(t0, q.negative[k] ? e : a);
  t1 = _mm_min_pd(t1, q.negative[k] ? a : e);
}

// Two floats into two doubles (the 64-bit load reads through a may_alias type).
inline __m128d two_doubles(const float* f) {
  return _mm_cvtps_pd(_mm_castsi128_ps(_mm_loadl_epi64(reinterpret_cast<const __m128i*>(f))));
}
#endif

// The lanes of a bucket whose conservative boxes (centre -/+ h, in double) the segment t in
// [0, t_hi] meets, widened as ray_box(): only those need the exact test. Padding lanes (NaN) fail.
inline std::uint32_t ray_lanes(const RaySetup& q, const BucketLanes& b, double t_hi) {
  std::uint32_t mask = 0;
#if defined(__SSE2__)
  const float* axis[3] = {b.x, b.y, b.z};
  for (std::uint32_t l = 0; l < kBucket; l += 2) {
    const __m128d h = two_doubles(b.h + l);
    __m128d t0 = _mm_setzero_pd(), t1 = _mm_set1_pd(t_hi);
    __m128d inside = _mm_cmpeq_pd(h, h);  // all set, but NaN lanes clear
    for (int k = 0; k < 3; ++k) {
      const __m128d c = two_doubles(axis[k] + l);
      slab2(q, k, _mm_sub_pd(c, h), _mm_add_pd(c, h), t0, t1, inside);
    }
    mask |= static_cast<std::uint32_t>(_mm_movemask_pd(_mm_and_pd(inside, _mm_cmple_pd(t0, t1)))) << l;
  }
#else
  for (std::uint32_t l = 0; l < kBucket; ++l) {
    const float h = b.h[l];
    const Aabb box{{b.x[l] - h, b.y[l] - h, b.z[l] - h}, {b.x[l] + h, b.y[l] + h, b.z[l] + h}};
    double te = 0;
    if (!std::isnan(h) && ray_box(q, box, t_hi, te)) mask |= 1u << l;
  }
#endif
  return mask;
}

// The children of a wide node whose boxes the segment t in [0, t_hi] meets, widened as ray_box();
// t_enter[l] is where it enters child l's box (set for every lane). Empty children fail.
inline std::uint32_t ray_children(const RaySetup& q, const WideNode& n, double t_hi, double* t_enter) {
  std::uint32_t mask = 0;
#if defined(__SSE2__)
  const float* lo_axis[3] = {n.lo_x, n.lo_y, n.lo_z};
  const float* hi_axis[3] = {n.hi_x, n.hi_y, n.hi_z};
  for (std::uint32_t l = 0; l < kWide; l += 2) {
    __m128d t0 = _mm_setzero_pd(), t1 = _mm_set1_pd(t_hi);
    __m128d inside = _mm_castsi128_pd(_mm_set1_epi32(-1));
    for (int k = 0; k < 3; ++k) slab2(q, k, two_doubles(lo_axis[k] + l), two_doubles(hi_axis[k] + l), t0, t1, inside);
    _mm_storeu_pd(t_enter + l, t0);
    mask |= static_cast<std::uint32_t>(_mm_movemask_pd(_mm_and_pd(inside, _mm_cmple_pd(t0, t1)))) << l;
  }
#else
  for (std::uint32_t l = 0; l < kWide; ++l)
    if (ray_box(q, n.child(l), t_hi, t_enter[l])) mask |= 1u << l;
#endif
  return mask;
}

// Every t whose float rounding is at most `limit` is at most this.
inline double upper_t(float limit) {
  return static_cast<double>(std::nextafter(limit, std::numeric_limits<float>::infinity()));
}

}  // namespace

template <class Visit>
void BucketBroadphase::ray_walk(const Ray& ray, double& t_hi, Visit&& visit) const {
  if (tree_.levels == 0) return;
  const RaySetup q(ray);
  // Depth first from the top node; a node's children that the ray meets are pushed farthest first,
  // so the nearest is searched first, and an entry whose box starts beyond t_hi (which the visits
  // may lower) is skipped. Level -1 entries are buckets. At most 16 entries wait per level.
  struct Entry {
    std::int32_t level;
    std::uint32_t index;
    double t;
  };
  Entry stack[kWide * (kWideMaxLevels + 1)];
  int sp = 0;
  stack[sp++] = {static_cast<std::int32_t>(tree_.levels) - 1, 0, 0.0};
  while (sp > 0) {
    const Entry e = stack[--sp];
    if (e.t > t_hi) continue;
    if (e.level < 0) {
      visit(q, e.index);
      continue;
    }
    const WideNode& nd = tree_.level[static_cast<std::size_t>(e.level)][e.index];
    double t_enter[kWide];
    Entry hit[kWide];
    int hits = 0;
    for (std::uint32_t m = ray_children(q, nd, t_hi, t_enter); m; m &= m - 1) {
      const auto l = static_cast<std::uint32_t>(std::countr_zero(m));
      // Insertion by t, farthest first.
      const Entry x{e.level - 1, e.index * kWide + l, t_enter[l]};
      int h = hits++;
      for (; h > 0 && hit[h - 1].t < x.t; --h) hit[h] = hit[h - 1];
      hit[h] = x;
    }
    for (int h = 0; h < hits; ++h) stack[sp++] = hit[h];
  }
}

template <class Hit>
void BucketBroadphase::ray_hits(const Ray& ray, double& t_hi, Hit&& hit) const {
  ray_walk(ray, t_hi, [&](const RaySetup& q, std::uint32_t b) {
    const BucketLanes& ln = lanes_[b];
    const std::size_t first = std::size_t{b} * kBucket;
    for (std::uint32_t m = ray_lanes(q, ln, t_hi); m; m &= m - 1) {
      const auto l = static_cast<std::uint32_t>(std::countr_zero(m));
      float t = 0;
      if (ray_sphere(ray.origin, ray.dir, ray.max_t, Sphere{ln.x[l], ln.y[l], ln.z[l], ln.r[l]}, t))
        hit(sorted_ids_[first + l], t);
    }
  });
}

bool BucketBroadphase::ray_first(const Ray& ray, std::span<const std::uint32_t> ids, RayHit& best, bool found) const {
  double t_hi = upper_t(found ? std::min(best.t, ray.max_t) : ray.max_t);
  ray_hits(ray, t_hi, [&](std::uint32_t id, float t) {
    const std::uint32_t index = ids.empty() ? id : ids[id];
    if (found && (t > best.t || (t == best.t && index > best.index))) return;
    best = {index, t};
    found = true;
    t_hi = upper_t(t);
  });
  return found;
}

void BucketBroadphase::ray_all(const Ray& ray, std::span<const std::uint32_t> ids, std::vector<RayHit>& hits) const {
  double t_hi = upper_t(ray.max_t);
  ray_hits(ray, t_hi, [&](std::uint32_t id, float t) { hits.push_back({ids.empty() ? id : ids[id], t}); });
}

void BucketBroadphase::overlap(const Sphere& sphere, std::span<const std::uint32_t> ids,
                               std::vector<std::uint32_t>& out) const {
  const std::size_t n = sorted_ids_.size();
  if (n == 0) return;
  // Both boxes conservative: every sphere the exact test accepts is found (as for pairs).
  const Aabb box = conservative_box(sphere);
  auto visit = [&](std::uint32_t b) {
    // Padding lanes hold NaN centres: overlap_mask() never sets their bits.
    for (std::uint32_t m = SimdBaseline::sphere_lanes(lanes_[b], sphere.x, sphere.y, sphere.z, sphere.r); m;
         m &= m - 1) {
      const std::uint32_t id = sorted_ids_[std::size_t{b} * kBucket + static_cast<std::uint32_t>(std::countr_zero(m))];
      out.push_back(ids.empty() ? id : ids[id]);
    }
  };
  for_each_wide_overlap(tree_, box, visit);
}

}  // namespace viscd::detail
