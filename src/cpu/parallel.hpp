#pragma once
// Parallel loops over an Executor: the caller's (Config::executor) or viscd's own pool. The stages
// are flat data-parallel loops over arrays; each becomes a few tasks over contiguous chunks, or
// many small tasks where the work per item varies (docs/architecture.md, "Threads").

#include <algorithm>
#include <cstddef>
#include <cstdint>

#include "viscd/executor.hpp"

namespace viscd::detail {

/// Below this many elements a loop runs serially: handing it out costs more than it saves.
inline constexpr std::size_t kParallelThreshold = 4096;

/// Hardware threads of this machine (at least 1).
[[nodiscard]] int hardware_threads();

/// Threads to use: `requested` > 0 as given but at most `available` (0: the machine's hardware
/// threads; a caller's executor passes its concurrency), else all of them.
[[nodiscard]] int resolve_threads(int requested, int available = 0);

/// Threads for a loop of n elements: 1 below the threshold.
inline int threads_for(std::size_t n, int threads) { return n < kParallelThreshold ? 1 : threads; }
/// Ranges for a loop of n elements: two per thread (a thread that gets no core then holds up half
/// its share, which the others take over), one below the threshold.
inline std::size_t ranges_for(std::size_t n, int threads) {
  return n < kParallelThreshold ? 1 : 2 * static_cast<std::size_t>(std::max(1, threads));
}

/// [begin, end) of chunk t of T over n elements, contiguous and balanced.
struct Chunk {
  std::size_t begin, end;
};
inline Chunk chunk_of(std::size_t n, std::size_t t, std::size_t count) {
  const std::size_t base = n / count, extra = n % count;
  const std::size_t begin = t * base + std::min(t, extra);
  return {begin, begin + base + (t < extra ? 1 : 0)};
}

/// viscd's own pool, shared by every detector that has no executor of its own: one thread per
/// hardware thread but one (the caller is the last), created on first use. A pool that is busy
/// with another detector's stage runs the new stage on its caller instead of queueing it.
[[nodiscard]] Executor& default_executor();

/// The executor of the frame running on this thread: set for the length of detect() by an
/// ExecutorScope, else default_executor().
[[nodiscard]] Executor& current_executor();

/// Makes `executor` (nullptr: the default) current on this thread until destroyed.
class ExecutorScope {
 public:
  explicit ExecutorScope(Executor* executor);
  ~ExecutorScope();
  ExecutorScope(const ExecutorScope&) = delete;
  ExecutorScope& operator=(const ExecutorScope&) = delete;

 private:
  Executor* previous_;
};

/// Runs f(task) for task in [0, count) on the current executor; inline when count <= 1.
template <class F>
void run_tasks(std::uint32_t count, F&& f) {
  if (count == 0) return;
  if (count == 1) {
    f(0u);
    return;
  }
  current_executor().run(count, TaskRef(f));
}

/// Splits [0, n) into `chunks` contiguous ranges and runs f(begin, end, chunk) for each (chunk
/// indices are stable: the same n and chunks give the same ranges, whichever thread runs them).
template <class F>
void for_chunks(std::size_t n, std::size_t chunks, F&& f) {
  chunks = std::max<std::size_t>(1, std::min(chunks, n));
  if (chunks == 1) {
    if (n) f(std::size_t{0}, n, std::size_t{0});
    return;
  }
  run_tasks(static_cast<std::uint32_t>(chunks), [&](std::uint32_t t) {
    const Chunk c = chunk_of(n, t, chunks);
    f(c.begin, c.end, static_cast<std::size_t>(t));
  });
}

/// The loop `for i in [0, n): f(i)` over `threads_for(n, threads)` balanced chunks.
template <class F>
void parallel_for(std::size_t n, int threads, F&& f) {
  for_chunks(n, static_cast<std::size_t>(threads_for(n, threads)), [&](std::size_t b, std::size_t e, std::size_t) {
    for (std::size_t i = b; i < e; ++i) f(i);
  });
}

}  // namespace viscd::detail
