#include "cpu/broadphase.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <limits>

#include "core/stopwatch.hpp"
#include "cpu/grow.hpp"
#include "cpu/parallel.hpp"

namespace viscd::detail {

ActiveExtent active_extent(std::span<const Sphere> spheres, std::span<const std::uint32_t> active, int threads) {
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

void sort_chunk_pairs(std::span<const std::vector<std::uint64_t>> lists, std::uint32_t objects,
                      std::vector<std::uint32_t>& offsets, std::vector<Pair>& scratch, std::vector<Pair>& out,
                      int threads) {
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
      for (const std::uint64_t key : lists[c])
        out[row[key >> (32 + kLowBits)]++] =
            Pair{static_cast<std::uint32_t>(key >> 32), static_cast<std::uint32_t>(key)};
    }
  });
  // Each block through a scratch of its own size (a counting sort by the low bits of i), then by j
  // within each i. A block larger than kMaxScratch pairs (degenerate scenes) is sorted in place by
  // std::sort, so the scratch stays small whatever the pairs.
  constexpr std::uint32_t kMaxScratch = 1u << 16;
  std::uint32_t largest = 0;
  for (std::size_t b = 0; b < blocks; ++b) largest = std::max(largest, start[b + 1] - start[b]);
  const std::uint32_t room = std::min(largest, kMaxScratch);
  resize_with_headroom(scratch, tasks * room);
  auto key = [](const Pair& q) { return std::uint64_t{q.i} << 32 | q.j; };  // (i, j) in one comparison
  auto by_ij = [&](const Pair& a, const Pair& b) { return key(a) < key(b); };
  for_chunks(blocks, tasks, [&](std::size_t b0, std::size_t b1, std::size_t t) {
    Pair* tmp = scratch.data() + t * room;
    std::uint32_t at[kDigits + 1];
    for (std::size_t blk = b0; blk < b1; ++blk) {
      const std::uint32_t first = start[blk], last = start[blk + 1];
      if (last - first < 2) continue;
      if (last - first > room) {
        std::sort(out.begin() + first, out.begin() + last, by_ij);
        continue;
      }
      std::copy(out.begin() + first, out.begin() + last, tmp);
      std::fill(std::begin(at), std::end(at), 0u);
      for (std::uint32_t a = 0; a < last - first; ++a) ++at[(tmp[a].i & (kDigits - 1)) + 1];
      at[0] = first;
      for (std::uint32_t d = 1; d <= kDigits; ++d) at[d] += at[d - 1];
      for (std::uint32_t a = 0; a < last - first; ++a) out[at[tmp[a].i & (kDigits - 1)]++] = tmp[a];
      // Sorted by i now; each object's few partners by j, by one insertion sort over the block
      // (no loop per object: most have none or one). Many partners out of order (a sphere that
      // overlaps hundreds) exceed the budget, and std::sort finishes.
      std::uint64_t moves = 0;
      const std::uint64_t budget = 16 * std::uint64_t{last - first} + 1024;
      for (std::uint32_t a = first + 1; a < last && moves <= budget; ++a) {
        const Pair p = out[a];
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

std::uint64_t LbvhBroadphase::memory_bytes() const {
  std::uint64_t b = bytes_of(sorted_ids_) + bytes_of(sorted_spheres_) + bytes_of(leaf_boxes_) + bytes_of(bvh_.nodes) +
                    bytes_of(bvh_.parent) + bytes_of(bvh_.leaf_parent) + bytes_of(bvh_.arrivals) +
                    pairs_.memory_bytes();
  keys_.for_each([&](const auto& v) { b += bytes_of(v); });
  scratch_.for_each([&](const auto& s) { b += bytes_of(s.keys) + bytes_of(s.values); });
  return b;
}

std::vector<std::uint64_t> LbvhBroadphase::sorted_codes() const { return keys_.widened(bits_, sorted_ids_.size()); }

Status LbvhBroadphase::run(std::span<const Sphere> spheres, std::span<const std::uint32_t> active, int bits,
                           Layout layout, int threads, std::size_t pair_memory_cap, std::vector<Pair>& pairs,
                           FrameStats& stats) {
  VISCD_ASSERT(bits == 16 || bits == 32 || bits == 64, "Morton width must be 16, 32 or 64");
  Stopwatch sw;
  const ActiveExtent extent = active_extent(spheres, active, threads);
  layout_ = make_layout(layout, bits, extent.bounds, extent.mean_diameter());
  bits_ = bits;
  stats.bits = bits;
  stats.layout = layout_.info();
  stats.ms(Stage::layout) = sw.lap();
  switch (bits) {
    case 16:
      return run_keys<std::uint16_t>(spheres, active, extent.bounds, threads, pair_memory_cap, pairs, stats);
    case 32:
      return run_keys<std::uint32_t>(spheres, active, extent.bounds, threads, pair_memory_cap, pairs, stats);
    default:
      return run_keys<std::uint64_t>(spheres, active, extent.bounds, threads, pair_memory_cap, pairs, stats);
  }
}

template <class K>
Status LbvhBroadphase::run_keys(std::span<const Sphere> spheres, std::span<const std::uint32_t> active,
                                const Aabb& bounds, int threads, std::size_t pair_memory_cap, std::vector<Pair>& pairs,
                                FrameStats& stats) {
  Stopwatch sw;
  const std::size_t n = active.size();
  std::vector<K>& key = keys_.get<K>();
  if (key.size() < n) key.resize(n);
  if (sorted_ids_.size() != n) sorted_ids_.resize(n);

  // Stage 5: codes. Values start as active object ids in ascending order, so the stable sort
  // breaks key ties by object index.
  const MortonEncoder encoder(layout_, bounds);
  parallel_for(n, threads, [&](std::size_t k) {
    const Sphere& s = spheres[active[k]];
    key[k] = static_cast<K>(encoder.encode(s.x, s.y, s.z));
    sorted_ids_[k] = active[k];
  });
  stats.ms(Stage::codes) = sw.lap();

  // Stage 6: sort.
  radix_sort<K>(std::span<K>(key.data(), n), std::span<std::uint32_t>(sorted_ids_.data(), n), 8 * sizeof(K), threads,
                scratch_.get<K>());
  stats.ms(Stage::sort) = sw.lap();

  // Stage 7: hierarchy, then boxes. Spheres are gathered into sorted order for coherent access.
  build_lbvh<K>(std::span<const K>(key.data(), n), bvh_, threads);
  stats.ms(Stage::build) = sw.lap();
  if (sorted_spheres_.size() != n) {
    sorted_spheres_.resize(n);
    leaf_boxes_.resize(n);
  }
  parallel_for(n, threads, [&](std::size_t p) {
    sorted_spheres_[p] = spheres[sorted_ids_[p]];
    leaf_boxes_[p] = conservative_box(sorted_spheres_[p]);
  });
  fit_lbvh(leaf_boxes_, bvh_, threads);
  stats.ms(Stage::fit) = sw.lap();
#ifdef VISCD_VALIDATE
  {
    const std::string problem = validate_lbvh(bvh_, leaf_boxes_);
    VISCD_ASSERT(problem.empty(), problem.c_str());
  }
#endif

  // Stage 8: each leaf p looks for partners q > p only, so each pair is found once.
  const std::size_t chunks = threads_for(n, threads) == 1 ? 1 : std::min<std::size_t>(n, 8 * threads);
  const std::uint32_t objects = n ? active.back() + 1 : 0;  // active is ascending
  const Status found =
      pairs_.collect(n, chunks, threads, pair_memory_cap, objects, pairs, [&](std::size_t p, auto& emit) {
        const Sphere& a = sorted_spheres_[p];
        for_each_overlap_after(bvh_, static_cast<std::uint32_t>(p), leaf_boxes_[p], [&](std::uint32_t q) {
          if (overlap_exact(a, sorted_spheres_[q])) emit(sorted_ids_[p], sorted_ids_[q]);
        });
      });
  if (!found) return found;
  stats.pairs = pairs.size();
  stats.ms(Stage::query) = sw.lap();
  return {};
}

bool brute_force_pairs(std::span<const Sphere> spheres, std::span<const std::uint32_t> active, std::vector<Pair>& pairs,
                       std::size_t max_pairs, std::span<const Filter> filters) {
  pairs.clear();
  const std::size_t n = active.size();
  for (std::size_t a = 0; a < n; ++a) {
    const Sphere& sa = spheres[active[a]];
    for (std::size_t b = a + 1; b < n; ++b) {
      if (!overlap_exact(sa, spheres[active[b]])) continue;
      if (!filters.empty() && !pair_passes_filter(filters[active[a]], filters[active[b]])) continue;
      if (pairs.size() == max_pairs) return false;
      pairs.push_back(Pair{active[a], active[b]});
    }
  }
  return true;
}

}  // namespace viscd::detail
