#pragma once
// OpenMP helpers. viscd uses OpenMP rather than oneTBB: the stages are flat data-parallel loops
// over arrays (no nested tasks), OpenMP is part of the compiler (no extra dependency), its static
// schedule is deterministic, and a team's start-up costs a few microseconds on 2 cores
// (docs/architecture.md, "Threads").

#include <omp.h>

#include <algorithm>
#include <cstddef>

namespace viscd::detail {

/// Below this many elements a loop runs serially: a parallel region costs more than it saves.
inline constexpr std::size_t kParallelThreshold = 4096;

/// Threads to use: `requested` > 0 as given but at most what the machine has, else every
/// hardware thread OpenMP sees. (Asking OpenMP for tens of thousands of threads crashes it.)
inline int resolve_threads(int requested) {
  const int available = std::max(1, std::max(omp_get_max_threads(), omp_get_num_procs()));
  return requested > 0 ? std::min(requested, available) : available;
}

/// Threads for a loop of n elements: 1 below the threshold.
inline int threads_for(std::size_t n, int threads) { return n < kParallelThreshold ? 1 : threads; }

/// [begin, end) of chunk t of T over n elements, contiguous and balanced.
struct Chunk {
  std::size_t begin, end;
};
inline Chunk chunk_of(std::size_t n, int t, int count) {
  const std::size_t base = n / static_cast<std::size_t>(count), extra = n % static_cast<std::size_t>(count);
  const auto tt = static_cast<std::size_t>(t);
  const std::size_t begin = tt * base + std::min(tt, extra);
  return {begin, begin + base + (tt < extra ? 1 : 0)};
}

}  // namespace viscd::detail
