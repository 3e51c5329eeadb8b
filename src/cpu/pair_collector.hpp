#pragma once
// Stage 8's output on the CPU: the pairs found by parallel tasks, each chunk into a list of its
// own, with the pair cap enforced while searching, then sorted by (i, j) in two local passes.

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <new>
#include <span>
#include <vector>

#include "core/frame_rules.hpp"
#include "cpu/parallel.hpp"
#include "viscd/result.hpp"
#include "viscd/types.hpp"

namespace viscd::detail {

/// A pair as one key that sorts by (i, j): i << 32 | j, the entries of the lists below.
[[nodiscard]] inline std::uint64_t pair_key(std::uint32_t i, std::uint32_t j) { return std::uint64_t{i} << 32 | j; }
[[nodiscard]] inline std::uint32_t key_i(std::uint64_t k) { return static_cast<std::uint32_t>(k >> 32); }
[[nodiscard]] inline std::uint32_t key_j(std::uint64_t k) { return static_cast<std::uint32_t>(k); }

/// Writes the pairs of per-chunk lists (keys i << 32 | j, i < j < objects) into `out` sorted by
/// (i, j), with up to `threads` threads: O(pairs + objects / 1024 per list). `offsets` and
/// `scratch` are kept between frames: (lists + 1 + threads) (objects / 1024 + 1) + 1 offsets, and
/// per thread the pairs of the fullest block of 1024 first indices, at most 65536 (from 2^20 pairs
/// on, at least a cache line of 8 entries per block: the first pass's write combining).
void sort_chunk_pairs(std::span<const std::vector<std::uint64_t>> lists, std::uint32_t objects,
                      std::vector<std::uint32_t>& offsets, std::vector<Pair>& scratch, std::vector<Pair>& out,
                      int threads);
/// sort_chunk_pairs() into keys (i << 32 | j, sorted) instead of pairs.
void sort_chunk_keys(std::span<const std::vector<std::uint64_t>> lists, std::uint32_t objects,
                     std::vector<std::uint32_t>& offsets, std::vector<std::uint64_t>& scratch,
                     std::vector<std::uint64_t>& out, int threads);

/// Stage 8's pair lists, shared by the broadphases. The items searched (leaves or buckets) are cut
/// into chunks, several per thread because the work per item varies, and each chunk keeps its own
/// list. The pair cap is enforced while searching: chunks publish their counts every kPublish
/// pairs, and all stop once the frame is over the cap, before the pairs' memory is taken. An
/// allocation failure inside a task is carried out of it. Lists keep their memory between frames.
class PairCollector {
 public:
  /// What `each` gets: emit(a, b) records a pair; stopped() says the frame is over the cap (items
  /// that find many pairs check it between their parts).
  class Emitter {
   public:
    Emitter(std::vector<std::uint64_t>& local, std::atomic<std::size_t>& published, std::atomic<bool>& stop,
            std::size_t allowed)
        : local_(local), published_(published), stop_(stop), allowed_(allowed) {}
    void operator()(std::uint32_t a, std::uint32_t b) {
      constexpr std::size_t kPublish = 4096;
      local_.push_back(a < b ? pair_key(a, b) : pair_key(b, a));
      if (local_.size() % kPublish == 0 &&
          published_.fetch_add(kPublish, std::memory_order_relaxed) + kPublish > allowed_)
        stop_.store(true, std::memory_order_relaxed);
    }
    [[nodiscard]] bool stopped() const { return stop_.load(std::memory_order_relaxed); }

   private:
    std::vector<std::uint64_t>& local_;
    std::atomic<std::size_t>& published_;
    std::atomic<bool>& stop_;
    std::size_t allowed_;
  };

  /// Runs each(item, emit) for every item in [0, items), over `chunks` contiguous chunks; emit(a, b)
  /// records the pair of object ids a != b (either order). Then writes the pairs into `out` sorted
  /// by (i, j) with up to `threads` threads; `objects` bounds the ids. Fails only when the pairs exceed pair_memory_cap
  /// bytes.
  template <class Each>
  Status collect(std::size_t items, std::size_t chunks, int threads, std::size_t pair_memory_cap, std::uint32_t objects,
                 std::vector<Pair>& out, Each&& each) {
    const std::size_t allowed = pairs_within_cap(pair_memory_cap);
    std::atomic<std::size_t> published{0};
    std::atomic<bool> stop{false}, out_of_memory{false};
    chunks = std::max<std::size_t>(1, chunks);
    if (lists_.size() < chunks) lists_.resize(chunks);
    for (std::size_t c = 0; c < chunks; ++c) lists_[c].clear();  // also when no chunk runs
    for_chunks(items, chunks, [&](std::size_t begin, std::size_t end, std::size_t c) {
      Emitter emit{lists_[c], published, stop, allowed};
      try {
        for (std::size_t item = begin; item < end && !stop.load(std::memory_order_relaxed); ++item) each(item, emit);
      } catch (const std::bad_alloc&) {
        out_of_memory.store(true);
        stop.store(true);
      }
    });
    if (out_of_memory.load()) throw std::bad_alloc();
    if (stop.load()) return check_pair_cap(published.load(), pair_memory_cap, true);
    std::size_t total = 0;
    for (std::size_t c = 0; c < chunks; ++c) total += lists_[c].size();
    if (Status s = check_pair_cap(total, pair_memory_cap); !s) return s;
    // A chunk covers the same objects every frame, but its count drifts as they move: once a list
    // is more than two-thirds full it gets room for twice its count, so frames whose counts
    // wander by up to half do not allocate. At least kMinRoom each: a chunk with almost no pairs
    // (sparse scenes, filters) would otherwise allocate whenever its few pairs become more.
    constexpr std::size_t kMinRoom = 1024;  // 8 KiB
    for (std::size_t c = 0; c < chunks; ++c)
      if (3 * lists_[c].size() > 2 * lists_[c].capacity() || lists_[c].capacity() < kMinRoom)
        lists_[c].reserve(std::max(2 * lists_[c].size(), kMinRoom));
    sort_chunk_pairs(std::span(lists_.data(), chunks), objects, offsets_, scratch_, out, threads);
    return {};
  }

  /// Bytes of the lists and the sort's scratch (capacities).
  [[nodiscard]] std::uint64_t memory_bytes() const {
    std::uint64_t b = bytes_of(offsets_) + bytes_of(scratch_);
    for (const auto& l : lists_) b += bytes_of(l);
    return b;
  }

 private:
  std::vector<std::vector<std::uint64_t>> lists_;
  std::vector<std::uint32_t> offsets_;
  std::vector<Pair> scratch_;
};

}  // namespace viscd::detail
