#pragma once
// A sort for entries that are nearly in order already: the cpu broadphase's codes in the last
// frame's object order, where most objects have moved a few places and a few have moved far.
//
// The entries are cut into one run per thread (at most kMaxSortRuns). Each run is finished by
// insertion within kReach places; an entry that belongs farther back, or sits above the entry
// kReach ahead of it (it moved far forward: kept, everything after it would be shifted past it),
// is set aside instead. The set-aside entries are sorted apart (they are few), and the runs and
// them are merged, in parallel over parts of the output cut at the first key of each run, into
// the caller's arrays (emit(k, entry) for each place k of the result: no buffer of entries is
// kept here for the output). When a
// run would set aside more than a quarter of its entries the last order says little, and the
// sort gives up (an LSD radix sort over all entries is then cheaper).
//
// Every result is the one std::sort gives with the same `less` (no two entries compare equal).
// tests/cpu/nearly_sorted_test.cpp checks it against std::sort.

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "cpu/parallel.hpp"

namespace viscd::detail {

/// An entry of the sort: the code (packed with the id when the code has at most 32 bits), the
/// object id, and its place in the input (where its sphere was gathered).
struct SortEntry {
  std::uint64_t key;
  std::uint32_t id, at;
};

/// How the last sort went (for tests and the bench).
struct NearlySortedReport {
  bool sorted = false;      ///< the entries are sorted (false: it gave up, the entries are garbage)
  std::uint64_t moves = 0;  ///< entries shifted by insertions within reach (also when it gave up)
  std::uint64_t far = 0;    ///< entries set aside, sorted and merged in
};

class NearlySortedSort {
 public:
  static constexpr std::size_t kMaxSortRuns = 8;
  /// Insertions reach this many places back.
  static constexpr std::size_t kReach = 32;

  /// The runs `n` entries are cut into with `threads` threads.
  [[nodiscard]] static std::size_t runs_for(std::size_t n, int threads) {
    return std::min<std::size_t>(kMaxSortRuns, static_cast<std::size_t>(threads_for(n, threads)));
  }

  /// Room for what the runs over n entries may set aside (a quarter of a run and 64 each, and all
  /// of it together), so that the sort allocates nothing in a steady state. Set-aside entries are
  /// reserved, not written: memory that is never written takes no pages.
  void reserve(std::size_t n, int threads) {
    const std::size_t runs = runs_for(n, threads);
    const std::size_t limit = (n + runs - 1) / runs / 4 + 64;
    for (std::size_t r = 0; r < runs; ++r)
      if (far_[r].capacity() < limit) far_[r].reserve(limit + limit / 2);
    if (far_[kMaxSortRuns].capacity() < runs * limit) far_[kMaxSortRuns].reserve(runs * limit + runs * limit / 2);
  }

  /// Sorts entries[0..n) by `less` with up to `threads` threads, and hands the result over as
  /// emit(k, entry) for every place k in [0, n), once each, from several threads at once (distinct
  /// k). `entries` is sorted run by run in place and read by the merge. Returns false when it gave
  /// up (then nothing is emitted, and entries[0..n) are no longer a permutation of the input).
  template <class Less, class Emit>
  bool sort(SortEntry* entries, std::size_t n, int threads, Less less, Emit&& emit);

  [[nodiscard]] const NearlySortedReport& report() const { return report_; }
  /// Bytes of the buffers held (capacities).
  [[nodiscard]] std::uint64_t memory_bytes() const {
    std::uint64_t b = 0;
    for (const auto& f : far_) b += f.capacity() * sizeof(SortEntry);
    return b;
  }

 private:
  template <class Less>
  static bool insert_within_reach(SortEntry* e, std::size_t len, std::size_t far_limit, std::vector<SortEntry>& far,
                                  std::size_t& kept, std::uint64_t& moved, Less less);

  std::array<std::vector<SortEntry>, kMaxSortRuns + 1> far_;  // set aside per run; then all, sorted
  NearlySortedReport report_;
};

// One run: sorts e[0..len) in place into e[0..kept) and sets the entries that moved far aside
// into `far` (unsorted). An entry that belongs at most kReach places back is shifted in. False
// when more than far_limit are set aside.
template <class Less>
bool NearlySortedSort::insert_within_reach(SortEntry* e, std::size_t len, std::size_t far_limit,
                                           std::vector<SortEntry>& far, std::size_t& kept, std::uint64_t& moved,
                                           Less less) {
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

template <class Less, class Emit>
bool NearlySortedSort::sort(SortEntry* entries, std::size_t n, int threads, Less less, Emit&& emit) {
  const std::size_t runs = runs_for(n, threads);
  std::array<std::size_t, kMaxSortRuns> begin{}, kept{};
  std::array<std::uint64_t, kMaxSortRuns> moved{};
  std::array<bool, kMaxSortRuns> ok{};
  ok.fill(true);  // a run that gets no entries (n = 0) has nothing to give up on
  reserve(n, threads);
  for_chunks(n, runs, [&](std::size_t b, std::size_t e, std::size_t r) {
    std::vector<SortEntry>& far = far_[r];
    const std::size_t far_limit = (e - b) / 4 + 64;
    far.clear();
    begin[r] = b;
    ok[r] = insert_within_reach(entries + b, e - b, far_limit, far, kept[r], moved[r], less);
  });
  std::uint64_t moves = 0, set_aside = 0;
  for (std::size_t r = 0; r < runs; ++r) moves += moved[r], set_aside += far_[r].size();
  report_ = {};
  report_.sorted = std::all_of(ok.begin(), ok.begin() + static_cast<std::ptrdiff_t>(runs), [](bool b) { return b; });
  report_.moves = moves;
  report_.far = set_aside;
  if (!report_.sorted) return false;
  if (runs == 1 && set_aside == 0) {  // sorted in place
    for (std::size_t k = 0; k < n; ++k) emit(k, entries[k]);
    return true;
  }

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
  for (std::size_t r = 0; r < runs; ++r) in[r] = {entries + begin[r], kept[r]};
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
      emit(o, in[best].data[at[best]++]);
    }
  });
  return true;
}

}  // namespace viscd::detail
