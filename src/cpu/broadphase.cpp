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
                      std::vector<std::uint32_t>& offsets, std::vector<Pair>& out) {
  std::size_t total = 0;
  for (const auto& list : lists) total += list.size();
  resize_with_headroom(out, total);
  // Counting sort by i: counts, exclusive prefix (offsets[i] = start of i's partners), scatter.
  resize_with_headroom(offsets, static_cast<std::size_t>(objects) + 1);
  std::fill(offsets.begin(), offsets.end(), 0u);
  for (const auto& list : lists)
    for (const std::uint64_t key : list) ++offsets[(key >> 32) + 1];
  for (std::size_t i = 1; i <= objects; ++i) offsets[i] += offsets[i - 1];
  for (const auto& list : lists)
    for (const std::uint64_t key : list)
      out[offsets[key >> 32]++] = Pair{static_cast<std::uint32_t>(key >> 32), static_cast<std::uint32_t>(key)};
  // Now offsets[i] is where i's partners end. Each object has a few partners: insertion sort by j.
  std::uint32_t begin = 0;
  for (std::size_t i = 0; i < objects; ++i) {
    const std::uint32_t end = offsets[i];
    for (std::uint32_t a = begin + 1; a < end; ++a) {
      const Pair p = out[a];
      std::uint32_t b = a;
      for (; b > begin && out[b - 1].j > p.j; --b) out[b] = out[b - 1];
      out[b] = p;
    }
    begin = end;
  }
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
  layout_.write(stats.layout);
  stats.stage_ms[static_cast<std::size_t>(Stage::layout)] = sw.lap();
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
  auto ms = [&](Stage s) -> double& { return stats.stage_ms[static_cast<std::size_t>(s)]; };
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
  ms(Stage::codes) = sw.lap();

  // Stage 6: sort.
  radix_sort<K>(std::span<K>(key.data(), n), std::span<std::uint32_t>(sorted_ids_.data(), n), 8 * sizeof(K), threads,
                scratch_.get<K>());
  ms(Stage::sort) = sw.lap();

  // Stage 7: hierarchy, then boxes. Spheres are gathered into sorted order for coherent access.
  build_lbvh<K>(std::span<const K>(key.data(), n), bvh_, threads);
  ms(Stage::build) = sw.lap();
  if (sorted_spheres_.size() != n) {
    sorted_spheres_.resize(n);
    leaf_boxes_.resize(n);
  }
  parallel_for(n, threads, [&](std::size_t p) {
    sorted_spheres_[p] = spheres[sorted_ids_[p]];
    leaf_boxes_[p] = conservative_box(sorted_spheres_[p]);
  });
  fit_lbvh(leaf_boxes_, bvh_, threads);
  ms(Stage::fit) = sw.lap();
#ifdef VISCD_VALIDATE
  {
    const std::string problem = validate_lbvh(bvh_, leaf_boxes_);
    VISCD_ASSERT(problem.empty(), problem.c_str());
  }
#endif

  // Stage 8: each leaf p looks for partners q > p only, so each pair is found once.
  const std::size_t chunks = threads_for(n, threads) == 1 ? 1 : std::min<std::size_t>(n, 8 * threads);
  const std::uint32_t objects = n ? active.back() + 1 : 0;  // active is ascending
  const Status found = pairs_.collect(n, chunks, pair_memory_cap, objects, pairs, [&](std::size_t p, auto& emit) {
    const Sphere& a = sorted_spheres_[p];
    for_each_overlap_after(bvh_, static_cast<std::uint32_t>(p), leaf_boxes_[p], [&](std::uint32_t q) {
      if (overlap_exact(a, sorted_spheres_[q])) emit(sorted_ids_[p], sorted_ids_[q]);
    });
  });
  if (!found) return found;
  stats.pairs = pairs.size();
  ms(Stage::query) = sw.lap();
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
