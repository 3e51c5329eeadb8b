#include "cpu/static_tree.hpp"

#include <algorithm>
#include <atomic>
#include <bit>
#include <type_traits>
#include <utility>

#include "cpu/bucket_search.hpp"
#include "cpu/cross_pairs.hpp"
#include "cpu/pair_collector.hpp"
#include "cpu/parallel.hpp"
#include "cpu/wide_tree.hpp"

namespace viscd::detail {
namespace {

constexpr std::size_t kRebuildFloor = 4096;

}  // namespace

void StaticTree::Side::build(const StaticSet& set, std::span<const std::uint32_t> slots, Layout layout, int threads) {
  count = slots.size();
  const bool box = set.kind() == ShapeKind::box;
  spheres.resize(count);
  boxes.resize(box ? count : 0);
  reported.resize(count);
  filters.resize(count);
  if (iota.size() < count) {
    const std::size_t old = iota.size();
    iota.resize(count);
    for (std::size_t k = old; k < count; ++k) iota[k] = static_cast<std::uint32_t>(k);
  }
  parallel_for(count, threads, [&](std::size_t k) {
    const std::uint32_t slot = slots[k];
    if (box) {
      boxes[k] = set.box(slot);
      spheres[k] = box_proxy(boxes[k]);
    } else {
      spheres[k] = set.sphere(slot);
    }
    reported[k] = static_index(slot);
    filters[k] = set.filter(slot);
  });
  FrameStats unused;
  tree.reset_order();
  tree.set_keep_order(false);
  BucketBroadphase::Extras extras;
  extras.boxes = boxes;
  tree.build(spheres, std::span<const std::uint32_t>(iota.data(), count), 32, layout, threads, unused, extras);
  // What a pair reports, by sorted position: a bucket's 16 objects share lines.
  const std::span<const std::uint32_t> sorted = tree.sorted_objects();
  reported_at.resize(sorted.size());
  filter_at.resize(sorted.size());
  std::atomic<bool> rejects{false};
  parallel_for(sorted.size(), threads, [&](std::size_t q) {
    reported_at[q] = reported[sorted[q]];
    filter_at[q] = filters[sorted[q]];
    if (!pair_passes_filter(Filter{}, filter_at[q])) rejects.store(true, std::memory_order_relaxed);
  });
  rejects_default = rejects.load();
}

std::uint64_t StaticTree::Side::memory_bytes() const {
  return tree.memory_bytes() + bytes_of(spheres) + bytes_of(boxes) + bytes_of(reported) + bytes_of(iota) +
         bytes_of(filters) + bytes_of(reported_at) + bytes_of(filter_at);
}

std::uint64_t StaticTree::memory_bytes() const {
  std::uint64_t b = main_.memory_bytes() + delta_.memory_bytes() + bytes_of(main_index_) + bytes_of(in_delta_) +
                    bytes_of(delta_slots_);
  for (const auto& l : lists_) b += bytes_of(l);
  return b;
}

void StaticTree::rebuild_all(StaticSet& set, Layout layout, int threads) {
  const StaticSet::Compact& c = set.compact();
  main_.build(set, c.slots, layout, threads);
  main_index_.assign(set.slot_count(), ~0u);
  for (std::size_t k = 0; k < c.slots.size(); ++k) main_index_[c.slots[k]] = static_cast<std::uint32_t>(k);
  in_delta_.assign(set.slot_count(), 0);
  delta_slots_.clear();
  delta_.build(set, delta_slots_, layout, threads);
  erased_ = 0;
}

void StaticTree::update(StaticSet& set, Layout layout, int threads) {
  set.take_changes(changes_);
  taken_from_ = std::exchange(taken_to_, set.version());
  StaticSet::Changes& changes = changes_;
  live_ = set.size();
  boxes_ = set.kind() == ShapeKind::box;
  if (changes.reset) {
    rebuild_all(set, layout, threads);
    return;
  }
  // Each slot once, in order (for the trees below and for last_changes()).
  std::sort(changes.slots.begin(), changes.slots.end());
  changes.slots.erase(std::unique(changes.slots.begin(), changes.slots.end()), changes.slots.end());
  if (changes.slots.empty()) return;
  main_index_.resize(set.slot_count(), ~0u);
  in_delta_.resize(set.slot_count(), 0);
  for (const std::uint32_t slot : changes.slots) {
    // Out of main (moved or removed: main holds where it was), into delta when it lives.
    if (main_index_[slot] != ~0u) {
      main_.tree.erase(main_index_[slot]);
      main_index_[slot] = ~0u;
      ++erased_;
    }
    in_delta_[slot] = set.live(slot) ? 1 : 0;
  }
  // Delta: the slots flagged, old and new (a merge with the changed ones, sorted above).
  merged_.clear();
  std::set_union(delta_slots_.begin(), delta_slots_.end(), changes.slots.begin(), changes.slots.end(),
                 std::back_inserter(merged_));
  delta_slots_.clear();
  for (const std::uint32_t slot : merged_)
    if (in_delta_[slot]) delta_slots_.push_back(slot);
  if (delta_slots_.size() + erased_ > std::max(kRebuildFloor, main_.count / 8)) {
    rebuild_all(set, layout, threads);
    return;
  }
  delta_.build(set, delta_slots_, layout, threads);
}

std::size_t StaticTree::parts(Part out[2]) const {
  std::size_t n = 0;
  // An empty set has nothing to find (its trees may still hold erased lanes).
  if (live_ == 0) return 0;
  for (const Side* s : {&main_, &delta_})
    if (s->count > 0) out[n++] = Part{&s->tree, {s->reported, s->filters}};
  return n;
}

bool StaticTree::pairs(const BucketBroadphase& moving, std::span<const Filter> moving_filters, bool filtered,
                       SimdLevel simd, int threads, std::size_t max_pairs, std::vector<std::uint64_t>& out,
                       const std::uint16_t* search) {
  out.clear();
  const std::size_t n = moving.sorted_objects().size();
  if (n == 0 || live_ == 0) return true;
  const std::size_t groups = (buckets_for(n) + kWide - 1) / kWide;
  const std::size_t chunks = threads_for(n, threads) == 1 ? 1 : std::min<std::size_t>(groups, 8 * threads);
  if (lists_.size() < chunks) lists_.resize(chunks);
  std::atomic<bool> over{false};
  for_chunks(groups, chunks, [&](std::size_t begin, std::size_t end, std::size_t c) {
    std::vector<std::uint64_t>& list = lists_[c];
    list.clear();
    for (std::size_t b = begin; b < end && !over.load(std::memory_order_relaxed); ++b) {
      for (const Side* s : {&main_, &delta_}) {
        if (s->count == 0) continue;
        const std::span<const std::uint32_t> mids = moving.sorted_objects();
        // Without moving filters (all the default one), filters are read only when some static
        // filter rejects the default.
        const bool check = filtered && (!moving_filters.empty() || s->rejects_default);
        auto emit = [&](std::size_t p, std::size_t q) {
          const Filter mf = moving_filters.empty() ? Filter{} : moving_filters[p];
          if (!check || pair_passes_filter(mf, s->filter_at[q])) list.push_back(pair_key(mids[p], s->reported_at[q]));
        };
        // The group walk first, whatever the counts: the moving objects and the static ones may
        // lie in different places (a ring of movers among a million static objects), so the counts
        // alone do not say how many buckets a group's box meets.
        const CrossWalk walk{true, cross_walk_for(n, s->count).bucket};
        auto fetch = [&](std::size_t q) {
          __builtin_prefetch(&s->reported_at[q]);
          if (check) __builtin_prefetch(&s->filter_at[q]);
        };
        if (boxes_)
          cross_pairs_at<BoxTests>(simd, moving, s->tree, b, walk, search, emit, fetch);
        else
          cross_pairs_at<SphereTests>(simd, moving, s->tree, b, walk, search, emit, fetch);
      }
      if (list.size() > max_pairs) over.store(true, std::memory_order_relaxed);
    }
  });
  std::size_t total = 0;
  for (std::size_t c = 0; c < chunks; ++c) total += lists_[c].size();
  if (over.load() || total > max_pairs) return false;
  out.reserve(total);
  for (std::size_t c = 0; c < chunks; ++c) out.insert(out.end(), lists_[c].begin(), lists_[c].end());
  std::sort(out.begin(), out.end());
  return true;
}

}  // namespace viscd::detail
