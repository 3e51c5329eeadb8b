#include "cpu/morton_order.hpp"

#include <algorithm>
#include <array>

#include "core/stopwatch.hpp"
#include "cpu/buckets.hpp"
#include "cpu/grow.hpp"
#include "cpu/parallel.hpp"
#include "viscd/assert.hpp"

namespace viscd::detail {

ActiveExtent active_extent(const Shapes& spheres, std::span<const std::uint32_t> active, int threads) {
  // Partial extents per chunk, merged in chunk order: the same for every executor.
  constexpr std::size_t kMaxChunks = 64;
  std::array<ActiveExtent, kMaxChunks> part{};
  const std::size_t n = active.size();
  const std::size_t chunks = std::min<std::size_t>(kMaxChunks, static_cast<std::size_t>(threads_for(n, threads)));
  for_chunks(n, chunks,
             [&](std::size_t b, std::size_t e, std::size_t c) { part[c] = extent_of(spheres, active, b, e); });
  ActiveExtent all;
  for (std::size_t c = 0; c < chunks; ++c) all.merge(part[c]);
  return all;
}

std::uint64_t MortonOrder::memory_bytes() const {
  std::uint64_t b = bytes_of(sorted_ids_) + bytes_of(at_) + bytes_of(rank_) + bytes_of(gathered_) + bytes_of(entries_) +
                    nearly_sorted_.memory_bytes();
  keys_.for_each([&](const auto& v) { b += bytes_of(v); });
  scratch_.for_each([&](const auto& s) { b += bytes_of(s.keys) + bytes_of(s.values); });
  return b;
}

MortonLayout layout_stage(const Shapes& spheres, std::span<const std::uint32_t> active, int bits, Layout layout,
                          int threads, ActiveExtent& extent, FrameStats& stats) {
  VISCD_ASSERT(bits == 16 || bits == 32 || bits == 64, "Morton width must be 16, 32 or 64");
  Stopwatch sw;
  extent = active_extent(spheres, active, threads);
  const MortonLayout l = make_layout(layout, bits, extent.bounds, extent.mean_diameter());
  stats.bits = bits;
  stats.layout = l.info();
  stats.ms(Stage::layout) = sw.lap();
  return l;
}

void MortonOrder::sort(std::span<const Sphere> spheres, std::span<const std::uint32_t> active, int bits, Layout layout,
                       int threads, FrameStats& stats) {
  ActiveExtent extent;
  layout_ = layout_stage(spheres, active, bits, layout, threads, extent, stats);
  if (bits != bits_) last_count_ = 0;  // the last order was by codes of another width
  bits_ = bits;
  switch (bits) {
    case 16:
      return sort_keys<std::uint16_t>(spheres, active, extent.bounds, threads, stats);
    case 32:
      return sort_keys<std::uint32_t>(spheres, active, extent.bounds, threads, stats);
    default:
      return sort_keys<std::uint64_t>(spheres, active, extent.bounds, threads, stats);
  }
}

// The last order is sorted_ids_[0, last_count_), rewritten here in place (an id is written at
// or before the place it is read from). When every object is active and the last frame had the
// same ones (the steady state without culling), it stays as it stands.
void MortonOrder::last_order(std::size_t objects, std::span<const std::uint32_t> active) {
  const std::size_t n = active.size(), last = last_count_;
  if (n == objects && last == n) {
    // active is 0..n-1 (ascending, distinct), and the last order holds n distinct ids: when all
    // are below n it is a permutation of them.
    if (std::all_of(sorted_ids_.begin(), sorted_ids_.begin() + static_cast<std::ptrdiff_t>(n),
                    [n](std::uint32_t id) { return id < n; }))
      return;
  }
  rank_.assign(objects, 0);  // 1: active and not yet placed
  for (const std::uint32_t id : active) rank_[id] = 1;
  std::size_t p = 0;
  for (std::size_t k = 0; k < last; ++k) {
    const std::uint32_t id = sorted_ids_[k];
    if (id >= objects || rank_[id] == 0) continue;
    sorted_ids_[p++] = id;
    rank_[id] = 0;
  }
  for (const std::uint32_t id : active)
    if (rank_[id]) sorted_ids_[p++] = id;
  VISCD_ASSERT(p == n, "every active object is placed once");
}

template <class K>
void MortonOrder::sort_keys(std::span<const Sphere> spheres, std::span<const std::uint32_t> active, const Aabb& bounds,
                            int threads, FrameStats& stats) {
  Stopwatch sw;
  const std::size_t n = active.size();
  std::vector<K>& key = keys_.get<K>();
  if (key.size() < n) resize_with_headroom(key, n);
  // Grown, never shrunk here: its first last_count_ ids are the last order (last_order()).
  if (sorted_ids_.size() < n) resize_with_headroom(sorted_ids_, n);
  encoder_.reset(layout_, bounds);
  const MortonEncoder& encoder = encoder_;
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
  report_ = {};
  const bool from_last = n > 1 && last_count_ != 0;
  bool reused = false;
  // Sized on every sorted frame, also from scratch: the next sorted frame may come after kept
  // frames, and should not be the one that allocates.
  resize_with_headroom(gathered_, n);
  resize_with_headroom(entries_, n);
  resize_with_headroom(at_, n);
  if (!from_last) {
    nearly_sorted_.reserve(n, threads);
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
    // The sorted entries go straight to the codes, the ids and each one's place in gathered_.
    reused = nearly_sorted_.sort(entries_.data(), n, threads, less, [&](std::size_t k, const SortEntry& e) {
      key[k] = code_in(e);
      sorted_ids_[k] = e.id;
      at_[k] = e.at;
    });
    const NearlySortedReport& r = nearly_sorted_.report();
    report_.reused = reused;
    report_.moves = r.moves;
    report_.far = r.far;
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
  last_count_ = sorted_count_ = n;
  stats.ms(Stage::sort) = sw.lap();
}

}  // namespace viscd::detail
