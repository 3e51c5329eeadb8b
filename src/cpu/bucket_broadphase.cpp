#include "cpu/bucket_broadphase.hpp"

#include <algorithm>

#include "core/geometry.hpp"
#include "core/stopwatch.hpp"
#include "cpu/bucket_search.hpp"
#include "cpu/grow.hpp"
#include "cpu/parallel.hpp"
#include "viscd/assert.hpp"

namespace viscd::detail {

std::uint64_t BucketBroadphase::memory_bytes() const {
  std::uint64_t b = order_.memory_bytes() + buckets_.memory_bytes() + keep_order_.memory_bytes() +
                    pairs_.memory_bytes() + bytes_of(position_) + bytes_of(proxies_);
  for (const auto& level : tree_.level) b += bytes_of(level);
  return b;
}

Status BucketBroadphase::run(std::span<const Sphere> spheres, std::span<const std::uint32_t> active,
                             std::span<const Filter> filters, int bits, Layout layout, int threads,
                             std::size_t pair_memory_cap, std::vector<Pair>& pairs, FrameStats& stats,
                             const Extras& extras) {
  extras_ = extras;
  build_tree(spheres, active, filters, bits, layout, threads, stats);
  return find_pairs(active, threads, pair_memory_cap, pairs, stats);
}

void BucketBroadphase::build(std::span<const Sphere> spheres, std::span<const std::uint32_t> active, int bits,
                             Layout layout, int threads, FrameStats& stats, const Extras& extras) {
  extras_ = extras;
  build_tree(spheres, active, {}, bits, layout, threads, stats);
}

template <class SphereAt>
double BucketBroadphase::fill(std::size_t n, std::span<const std::uint32_t> ids, std::span<const Filter> filters,
                              int threads, SphereAt&& sphere_at) {
  if (!extras_.boxes.empty()) return buckets_.fill_boxes(extras_.boxes, n, ids, filters, threads);
  return buckets_.fill(n, ids, filters, threads, sphere_at);
}

double BucketBroadphase::fill_reading(std::span<const Sphere> spheres, std::size_t n,
                                      std::span<const std::uint32_t> ids, std::span<const Filter> filters,
                                      int threads) {
  return fill(n, ids, filters, threads, [&](std::size_t k) -> const Sphere& {
    if (k + kPrefetchAhead < n) __builtin_prefetch(&spheres[ids[k + kPrefetchAhead]]);
    return spheres[ids[k]];
  });
}

std::span<const Sphere> BucketBroadphase::box_proxies(int threads) {
  const std::span<const Box> boxes = extras_.boxes;
  resize_with_headroom(proxies_, boxes.size());
  parallel_for(boxes.size(), threads, [&](std::size_t k) { proxies_[k] = box_proxy(boxes[k]); });
  return {proxies_.data(), boxes.size()};
}

void BucketBroadphase::index_positions(int threads) {
  const std::span<const std::uint32_t> ids = order_.sorted_ids();
  if (!position_.empty() || ids.empty()) return;
  std::uint32_t most = 0;
  for (const std::uint32_t i : ids) most = std::max(most, i);
  position_.assign(std::size_t{most} + 1, ~0u);
  // The ids are distinct: each position is written once (a scatter over all of the tree's objects
  // after each rebuild, 10^6 of them for the rest set's main tree).
  parallel_for(ids.size(), threads, [&](std::size_t p) { position_[ids[p]] = static_cast<std::uint32_t>(p); });
}

void BucketBroadphase::erase(std::uint32_t id) {
  index_positions();
  if (id < position_.size() && position_[id] != ~0u) buckets_.erase_lane(position_[id], holds_boxes());
}

void BucketBroadphase::build_tree(std::span<const Sphere> spheres, std::span<const std::uint32_t> active,
                                  std::span<const Filter> filters, int bits, Layout layout, int threads,
                                  FrameStats& stats) {
  VISCD_ASSERT(bits == 16 || bits == 32 || bits == 64, "Morton width must be 16, 32 or 64");
  position_.clear();
  Stopwatch attempt;
  if (keep_last_order(spheres, active, filters, bits, layout, threads, stats)) return;
  // A box frame that gave no spheres: their proxies, now that stages 4-6 need them (a frame over
  // 10^5 boxes had made them every frame, kept order or not: a pass over every box).
  if (spheres.empty() && !extras_.boxes.empty()) spheres = box_proxies(threads);
  const double attempt_ms = attempt.lap();  // an attempt that found the buckets spread: counted in build

  order_.sort(spheres, active, bits, layout, threads, stats);  // stages 4-6
  report_ = order_.report();

  // Stage 7, build: the objects into bucket lanes, from the gathered spheres when the sort read
  // them in order already.
  Stopwatch sw;
  const std::size_t n = active.size();
  const std::span<const std::uint32_t> ids = order_.sorted_ids();
  const double box_sum =
      order_.gathered()
          ? fill(n, ids, filters, threads, [&](std::size_t k) -> const Sphere& { return order_.gathered_sphere(k); })
          : fill_reading(spheres, n, ids, filters, threads);
  stats.ms(Stage::build) = sw.lap() + attempt_ms;
  fit_tree(n, threads, stats);
  keep_order_.remember_sorted(spheres.size(), active, layout, box_sum);
}

void BucketBroadphase::fit_tree(std::size_t n, int threads, FrameStats& stats) {
  Stopwatch sw;
  build_wide_tree(buckets_.boxes().first(buckets_for(n)), tree_, threads);
  stats.ms(Stage::fit) = sw.lap();
#ifdef VISCD_VALIDATE
  const std::string problem = validate_wide_tree(tree_, buckets_.boxes());
  VISCD_ASSERT(problem.empty(), problem.c_str());
#endif
}

bool BucketBroadphase::keep_last_order(std::span<const Sphere> spheres, std::span<const std::uint32_t> active,
                                       std::span<const Filter> filters, int bits, Layout layout, int threads,
                                       FrameStats& stats) {
  report_ = {};
  const std::size_t n = active.size();
  if (bits != order_.bits() || order_.last_count() != n || !keep_order_.may_keep(objects_in(spheres), active, layout))
    return false;
  Stopwatch sw;
  stats.bits = bits;
  stats.layout = order_.layout().info();  // the layout of the codes that ordered the objects
  // The sorted ids hold the last order (the last sorted frame's stage 6 wrote them).
  const std::span<const std::uint32_t> ids = order_.sorted_ids();
  const double box_sum = fill_reading(spheres, n, ids, filters, threads);
  if (!keep_order_.keeps(box_sum)) return false;  // moved too much: sort
  stats.ms(Stage::build) = sw.lap();
  fit_tree(n, threads, stats);
  report_.kept = stats.order_kept = true;
  return true;
}

Status BucketBroadphase::find_pairs(std::span<const std::uint32_t> active, int threads, std::size_t pair_memory_cap,
                                    std::vector<Pair>& pairs, FrameStats& stats) {
  Stopwatch sw;
  const std::span<const std::uint32_t> ids = order_.sorted_ids();
  const BucketSearchInput in{buckets_.lanes(),
                             buckets_.box_lanes(),
                             !extras_.boxes.empty(),
                             buckets_.boxes(),
                             &tree_,
                             ids,
                             buckets_.sorted_filters(),
                             ids.empty() ? 0u : active.back() + 1};  // active is ascending
  std::uint64_t bucket_pairs = 0;
  const Status found = search_buckets(in, simd_, threads, pair_memory_cap, pairs_, pairs, bucket_pairs);
  if (!found) {
    keep_order_.sort_next();  // a search stopped by the pair cap counted only part
    return found;
  }
  keep_order_.after_search(report_.kept, bucket_pairs);
  stats.pairs = pairs.size();
  stats.ms(Stage::query) = sw.lap();
  return {};
}

}  // namespace viscd::detail
