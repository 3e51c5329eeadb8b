#include "cpu/pair_collector.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <limits>
#include <type_traits>

#include "cpu/grow.hpp"

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

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

// The first pass's scatter through one line of 8 entries per block (software write combining):
// a full line goes out in streaming stores, so that a scatter to a thousand blocks neither reads
// each line of the output before writing it nor keeps it in the cache (docs/architecture.md, "The
// cpu broadphase, stage by stage"). The lines at the ends of each block's range, which other
// lists share, are written with plain stores. `lines` (64-byte aligned) holds 8 entries a block,
// `head` one index a block.
inline constexpr std::size_t kLine = 8;  // entries of 8 bytes in a cache line
inline constexpr std::size_t kCombineBlocks = 64, kCombineEntries = std::size_t{1} << 20;

template <class T>
void store_line(T* to, const T* line) {
#if defined(__SSE2__)
  const auto* from = reinterpret_cast<const __m128i*>(line);
  auto* dst = reinterpret_cast<__m128i*>(to);
  for (int q = 0; q < 4; ++q) _mm_stream_si128(dst + q, _mm_load_si128(from + q));
#else
  std::copy(line, line + kLine, to);
#endif
}

template <class T>
void scatter_combined(const std::vector<std::uint64_t>& keys, int low_bits, std::uint32_t* row, std::size_t blocks,
                      T* out, T* lines, std::uint32_t* head) {
  static_assert(sizeof(T) == 8 && kLine * sizeof(T) == 64);
  // Entry p starts a line when (p + shift) % 8 == 0 (out is 8-byte aligned).
  const auto shift = static_cast<std::uint32_t>((reinterpret_cast<std::uintptr_t>(out) / sizeof(T)) % kLine);
  constexpr auto kMask = static_cast<std::uint32_t>(kLine - 1);
  // head[b]: the first entry of block b's range that starts a line; those before it go out as
  // plain stores.
  for (std::size_t b = 0; b < blocks; ++b) head[b] = ((row[b] + shift + kMask) & ~kMask) - shift;
  for (const std::uint64_t key : keys) {
    const std::size_t b = key >> (32 + low_bits);
    const std::uint32_t p = row[b]++;
    const T e = entry_of<T>(key);
    if (p < head[b]) {
      out[p] = e;
      continue;
    }
    const std::uint32_t lane = (p + shift) & kMask;
    T* const line = lines + b * kLine;
    line[lane] = e;
    if (lane == kMask) store_line(out + (p - kMask), line);
  }
  // Each block's last line, if it is partial: its entries as plain stores.
  for (std::size_t b = 0; b < blocks; ++b) {
    const std::uint32_t end = row[b];
    if (end <= head[b]) continue;
    const std::uint32_t partial = (end + shift) & kMask;
    std::copy(lines + b * kLine, lines + b * kLine + partial, out + (end - partial));
  }
#if defined(__SSE2__)
  _mm_sfence();  // the streaming stores are seen by the threads that sort the blocks next
#endif
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
  resize_with_headroom(offsets, (L + 1) * blocks + 1 + tasks * blocks);  // the last part: scatter_combined()'s heads
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
  // Through lines of their own when the blocks are many and the output does not stay in the cache
  // (bm_pair_sort, 2.5 million random pairs of 10^6 objects into 977 blocks: the whole sort 32-42
  // ms on two threads before, 27-33 after; at 580 000 pairs the two measured level). The lines
  // need 8-byte entries on 8-byte boundaries (operator new's alignment is 16).
  const bool combine = blocks >= kCombineBlocks && total >= kCombineEntries &&
                       reinterpret_cast<std::uintptr_t>(out.data()) % sizeof(T) == 0;
  std::uint32_t* const heads = offsets.data() + (L + 1) * blocks + 1;
  T* lines = nullptr;
  if (combine) {
    resize_with_headroom(scratch, tasks * blocks * kLine + kLine);
    lines = scratch.data();
    while (reinterpret_cast<std::uintptr_t>(lines) % 64 != 0) ++lines;  // 8-byte entries: at most 7 steps
  }
  for_chunks(L, tasks, [&](std::size_t b, std::size_t e, std::size_t t) {
    for (std::size_t c = b; c < e; ++c) {
      std::uint32_t* row = offsets.data() + c * blocks;
      if (combine) {
        scatter_combined(lists[c], kLowBits, row, blocks, out.data(), lines + t * blocks * kLine, heads + t * blocks);
        continue;
      }
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
