#pragma once
// Parallel LSD radix sort of (key, value) pairs, 8-bit digits, stable: equal keys keep the
// order of their values (callers pass values in increasing order, so ties end up by index).
// The number of passes follows the key width: 2 for 16-bit, 4 for 32-bit and 8 for 64-bit keys;
// a pass whose digit is the same for every key is skipped (it would move nothing).
//
// Each pass: a task per contiguous chunk builds its histogram; an exclusive scan over
// (digit, chunk) gives each chunk its own output offsets; a task per chunk scatters it.
// Stability follows from the offsets following chunk order and in-chunk order being kept.

#include <array>
#include <cstdint>
#include <cstring>
#include <span>
#include <vector>

#include "cpu/grow.hpp"
#include "cpu/parallel.hpp"
#include "viscd/assert.hpp"

namespace viscd::detail {

/// Below this many keys the sort runs on one thread: with two threads, scatters to neighbouring
/// buckets write the same cache lines, and on 2 cores one thread won up to ~100k keys
/// (bench: viscd_microbench bm_radix_sort, docs/benchmarks.md).
inline constexpr std::size_t kRadixParallelThreshold = std::size_t{1} << 17;

/// Reusable scratch for radix_sort (one per caller; not thread-safe).
template <class K>
struct RadixScratch {
  std::vector<K> keys;
  std::vector<std::uint32_t> values;
  std::vector<std::array<std::uint32_t, 256>> histograms;  // per chunk
};

/// One buffer per Morton key width (16, 32, 64 bits), picked by the key type: the broadphases
/// keep their keys and sort scratch per width, so that a change of m reuses what was grown.
template <template <class> class Of>
struct PerWidth {
  Of<std::uint16_t> w16;
  Of<std::uint32_t> w32;
  Of<std::uint64_t> w64;
  template <class K>
  Of<K>& get() {
    if constexpr (sizeof(K) == 2)
      return w16;
    else if constexpr (sizeof(K) == 4)
      return w32;
    else
      return w64;
  }
  /// The first n keys of the width `bits`, widened (for tests and tools).
  [[nodiscard]] std::vector<std::uint64_t> widened(int bits, std::size_t n) const {
    const auto take = [n](const auto& v) {
      return std::vector<std::uint64_t>(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(n));
    };
    return bits == 16 ? take(w16) : bits == 32 ? take(w32) : take(w64);
  }
  /// Calls f on each width's buffer.
  template <class F>
  void for_each(F&& f) const {
    f(w16);
    f(w32);
    f(w64);
  }
};
template <class K>
using KeyVector = std::vector<K>;

/// Sorts keys[0..n) ascending, carrying values along (pass an empty `values` to sort keys only). `key_bits` (<= 8 *
/// sizeof(K)) bounds the bits that may be non-zero; passes above it are not run. Uses up to `threads` threads.
template <class K>
void radix_sort(std::span<K> keys, std::span<std::uint32_t> values, int key_bits, int threads,
                RadixScratch<K>& scratch) {
  const bool has_values = !values.empty();
  VISCD_ASSERT(!has_values || keys.size() == values.size(), "keys and values differ in length");
  VISCD_ASSERT(key_bits <= static_cast<int>(8 * sizeof(K)), "key_bits exceeds the key type");
  const std::size_t n = keys.size();
  if (n < 2) return;
  if (scratch.keys.size() < n) {
    resize_with_headroom(scratch.keys, n);
  }
  if (has_values && scratch.values.size() < n) resize_with_headroom(scratch.values, n);
  const int t_count = n < kRadixParallelThreshold ? 1 : threads;
  if (scratch.histograms.size() < static_cast<std::size_t>(t_count)) scratch.histograms.resize(t_count);

  K* src_k = keys.data();
  std::uint32_t* src_v = values.data();
  K* dst_k = scratch.keys.data();
  std::uint32_t* dst_v = scratch.values.data();
  const int passes = (key_bits + 7) / 8;
  for (int pass = 0; pass < passes; ++pass) {
    const int shift = 8 * pass;
    bool constant_digit = false;
    // Histograms per chunk, a serial scan in (digit, chunk) order, then a stable scatter per
    // chunk: two tasks per chunk and pass, the same chunks whichever thread runs them.
    const auto chunks = static_cast<std::size_t>(t_count);
    for_chunks(n, chunks, [&](std::size_t b, std::size_t e, std::size_t t) {
      auto& h = scratch.histograms[t];
      h.fill(0);
      for (std::size_t i = b; i < e; ++i) ++h[(src_k[i] >> shift) & 0xFF];
    });
    std::uint32_t sum = 0;
    for (int d = 0; d < 256; ++d) {
      std::uint32_t digit_total = 0;
      for (std::size_t u = 0; u < chunks; ++u) {
        const std::uint32_t c_count = scratch.histograms[u][d];
        scratch.histograms[u][d] = sum;
        sum += c_count;
        digit_total += c_count;
      }
      if (digit_total == n) constant_digit = true;
    }
    if (!constant_digit) {
      for_chunks(n, chunks, [&](std::size_t b, std::size_t e, std::size_t t) {
        auto& h = scratch.histograms[t];
        for (std::size_t i = b; i < e; ++i) {
          const std::uint32_t pos = h[(src_k[i] >> shift) & 0xFF]++;
          dst_k[pos] = src_k[i];
          if (has_values) dst_v[pos] = src_v[i];
        }
      });
    }
    if (!constant_digit) {
      std::swap(src_k, dst_k);
      std::swap(src_v, dst_v);
    }
  }
  if (src_k != keys.data()) {
    std::memcpy(keys.data(), src_k, n * sizeof(K));
    if (has_values) std::memcpy(values.data(), src_v, n * sizeof(std::uint32_t));
  }
}

}  // namespace viscd::detail
