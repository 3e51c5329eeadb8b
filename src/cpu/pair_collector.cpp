#include "cpu/pair_collector.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <limits>
#include <type_traits>

#include "cpu/grow.hpp"

namespace viscd::detail {

namespace {

// A sorted entry as a Pair or as its key (pair_key()).
[[nodiscard]] std::uint64_t key_of(const Pair& q) { return pair_key(q.i, q.j); }
[[nodiscard]] std::uint64_t key_of(std::uint64_t k) { return k; }
[[nodiscard]] std::uint32_t first_of(const Pair& q) { return q.i; }
[[nodiscard]] std::uint32_t first_of(std::uint64_t k) { return key_i(k); }
template <class T>
[[nodiscard]] T entry_of(std::uint64_t k) {
  if constexpr (std::is_same_v<T, Pair>)
    return Pair{key_i(k), key_j(k)};
  else
    return k;
}

template <class T>
void sort_chunks(std::span<const std::vector<std::uint64_t>> lists, std::uint32_t objects,
                 std::vector<std::uint32_t>& offsets, std::vector<T>& scratch, std::vector<T>& out, int threads) {
  // Two passes, each with few places to write to: the pairs go to blocks of 1024 consecutive
  // first indices (per list, so lists scatter in parallel and in a fixed order), then each block is
  // sorted on its own by the low 10 bits of i and each object's few partners by j. The blocks are
  // independent, so they sort in parallel.
  constexpr int kLowBits = 10;
  constexpr std::uint32_t kDigits = 1u << kLowBits;
  const std::size_t blocks = (std::size_t{objects} >> kLowBits) + 1;
  const std::size_t L = lists.size();
  std::size_t total = 0;
  for (const auto& list : lists) total += list.size();
  resize_with_headroom(out, total);
  const std::size_t tasks = static_cast<std::size_t>(threads_for(total, threads));
  // offsets[c * blocks + b]: where list c writes its next pair of block b; the last row holds
  // where each block starts (and the total).
  resize_with_headroom(offsets, (L + 1) * blocks + 1);
  std::uint32_t* const start = offsets.data() + L * blocks;
  for_chunks(L, tasks, [&](std::size_t b, std::size_t e, std::size_t) {
    for (std::size_t c = b; c < e; ++c) {
      std::uint32_t* row = offsets.data() + c * blocks;
      std::fill(row, row + blocks, 0u);
      for (const std::uint64_t key : lists[c]) ++row[key >> (32 + kLowBits)];
    }
  });
  std::uint32_t sum = 0;
  for (std::size_t b = 0; b < blocks; ++b) {
    start[b] = sum;
    for (std::size_t c = 0; c < L; ++c) {
      const std::uint32_t count = offsets[c * blocks + b];
      offsets[c * blocks + b] = sum;
      sum += count;
    }
  }
  start[blocks] = sum;
  for_chunks(L, tasks, [&](std::size_t b, std::size_t e, std::size_t) {
    for (std::size_t c = b; c < e; ++c) {
      std::uint32_t* row = offsets.data() + c * blocks;
      for (const std::uint64_t key : lists[c]) out[row[key >> (32 + kLowBits)]++] = entry_of<T>(key);
    }
  });
  // Each block through a scratch of its own size (a counting sort by the low bits of i), then by j
  // within each i. A block larger than kMaxScratch pairs (degenerate scenes) is sorted in place by
  // std::sort, so the scratch stays small whatever the pairs; so is one of at most kFewEntries.
  constexpr std::uint32_t kMaxScratch = 1u << 16;
  constexpr std::uint32_t kFewEntries = 64;
  std::uint32_t largest = 0;
  for (std::size_t b = 0; b < blocks; ++b) largest = std::max(largest, start[b + 1] - start[b]);
  const std::uint32_t room = std::min(largest, kMaxScratch);
  resize_with_headroom(scratch, tasks * room);
  auto key = [](const T& q) { return key_of(q); };  // (i, j) in one comparison
  auto by_ij = [&](const T& a, const T& b) { return key(a) < key(b); };
  for_chunks(blocks, tasks, [&](std::size_t b0, std::size_t b1, std::size_t t) {
    T* tmp = scratch.data() + t * room;
    std::uint32_t at[kDigits + 1];
    for (std::size_t blk = b0; blk < b1; ++blk) {
      const std::uint32_t first = start[blk], last = start[blk + 1];
      if (last - first < 2) continue;
      // A block of few entries (sparse keys: the new candidates of a few movers) is sorted as it
      // is: the counting sort's 1024 counters would cost more than the entries.
      if (last - first > room || last - first <= kFewEntries) {
        std::sort(out.begin() + first, out.begin() + last, by_ij);
        continue;
      }
      std::copy(out.begin() + first, out.begin() + last, tmp);
      std::fill(std::begin(at), std::end(at), 0u);
      for (std::uint32_t a = 0; a < last - first; ++a) ++at[(first_of(tmp[a]) & (kDigits - 1)) + 1];
      at[0] = first;
      for (std::uint32_t d = 1; d <= kDigits; ++d) at[d] += at[d - 1];
      for (std::uint32_t a = 0; a < last - first; ++a) out[at[first_of(tmp[a]) & (kDigits - 1)]++] = tmp[a];
      // Sorted by i now; each object's few partners by j, by one insertion sort over the block
      // (no loop per object: most have none or one). Many partners out of order (a sphere that
      // overlaps hundreds) exceed the budget, and std::sort finishes.
      std::uint64_t moves = 0;
      const std::uint64_t budget = 16 * std::uint64_t{last - first} + 1024;
      for (std::uint32_t a = first + 1; a < last && moves <= budget; ++a) {
        const T p = out[a];
        const std::uint64_t kp = key(p);
        if (kp > key(out[a - 1])) continue;
        std::uint32_t k = a;
        for (; k > first && kp < key(out[k - 1]); --k) out[k] = out[k - 1];
        out[k] = p;
        moves += a - k;
      }
      if (moves > budget) std::sort(out.begin() + first, out.begin() + last, by_ij);
    }
  });
}

}  // namespace

void sort_chunk_pairs(std::span<const std::vector<std::uint64_t>> lists, std::uint32_t objects,
                      std::vector<std::uint32_t>& offsets, std::vector<Pair>& scratch, std::vector<Pair>& out,
                      int threads) {
  sort_chunks(lists, objects, offsets, scratch, out, threads);
}

void sort_chunk_keys(std::span<const std::vector<std::uint64_t>> lists, std::uint32_t objects,
                     std::vector<std::uint32_t>& offsets, std::vector<std::uint64_t>& scratch,
                     std::vector<std::uint64_t>& out, int threads) {
  sort_chunks(lists, objects, offsets, scratch, out, threads);
}

}  // namespace viscd::detail
