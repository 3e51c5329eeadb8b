// viscd_microbench: Google Benchmark micro-benchmarks (docs/benchmarks.md).
//
//   bm_radix_sort<K>   stage 6 alone: 16/32/64-bit random keys with values 0..n-1, all threads and 1
//   bm_pair_sort       stage 8's pair sort alone: random pairs (i < j) of n objects in 16 lists
//   bm_cpu_frame       one whole cpu frame (detect(), no camera) on the moving ring scene
//
// Both use manual timing: the untimed part of each iteration (restoring the unsorted keys,
// advancing the scene) is outside the measured interval.

#include <benchmark/benchmark.h>

#include <chrono>
#include <cstdint>
#include <numeric>
#include <random>
#include <vector>

#include "cpu/pair_collector.hpp"
#include "cpu/parallel.hpp"
#include "cpu/radix_sort.hpp"
#include "viscd/scene.hpp"
#include "viscd/viscd.hpp"

namespace {

constexpr float kFrameDt = 1.0f / 60.0f;  // scene time per frame, seconds

double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// range(0) = n, range(1) = threads (0 = all).
template <class K>
void bm_radix_sort(benchmark::State& state) {
  const auto n = static_cast<std::size_t>(state.range(0));
  std::mt19937_64 rng(42);
  std::vector<K> original(n), keys(n);
  for (K& k : original) k = static_cast<K>(rng());
  std::vector<std::uint32_t> values(n);
  viscd::detail::RadixScratch<K> scratch;
  const int threads = viscd::detail::resolve_threads(static_cast<int>(state.range(1)));
  for (auto _ : state) {
    keys = original;
    std::iota(values.begin(), values.end(), 0u);
    const auto t0 = std::chrono::steady_clock::now();
    viscd::detail::radix_sort<K>(keys, values, 8 * sizeof(K), threads, scratch);
    state.SetIterationTime(seconds_since(t0));
    benchmark::DoNotOptimize(keys.data());
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations()) * state.range(0));
}

// range(0) = objects, range(1) = pairs, range(2) = threads (0 = all). The pairs are spread over
// 16 lists (one per chunk of the search, as a frame on two threads makes them), first indices
// uniform: object ids carry no order of place, so a frame's pairs arrive in no order either.
void bm_pair_sort(benchmark::State& state) {
  const auto objects = static_cast<std::uint32_t>(state.range(0));
  const auto count = static_cast<std::size_t>(state.range(1));
  constexpr std::size_t kLists = 16;
  std::mt19937 rng(7);
  std::uniform_int_distribution<std::uint32_t> first(0, objects - 2);
  std::vector<std::vector<std::uint64_t>> lists(kLists);
  for (std::size_t k = 0; k < count; ++k) {
    const std::uint32_t i = first(rng);
    const std::uint32_t j = i + 1 + static_cast<std::uint32_t>(rng() % (objects - 1 - i));
    lists[k % kLists].push_back(viscd::detail::pair_key(i, j));
  }
  std::vector<std::uint32_t> offsets;
  std::vector<viscd::Pair> scratch, out;
  const int threads = viscd::detail::resolve_threads(static_cast<int>(state.range(2)));
  for (auto _ : state) {
    const auto t0 = std::chrono::steady_clock::now();
    viscd::detail::sort_chunk_pairs(lists, objects, offsets, scratch, out, threads);
    state.SetIterationTime(seconds_since(t0));
    benchmark::DoNotOptimize(out.data());
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations()) * state.range(1));
}

// range(0) = N, range(1) = Config::threads (0 = all).
void bm_cpu_frame(benchmark::State& state) {
  viscd::SceneParams params;
  params.kind = viscd::SceneKind::ring;
  params.objects = static_cast<std::uint32_t>(state.range(0));
  params.seed = 1;
  viscd::Scene scene = viscd::Scene::make(params);
  viscd::Config config;
  config.threads = static_cast<int>(state.range(1));
  auto detector = viscd::make_cpu_detector(config);
  viscd::FrameResult out;
  for (int warm = 0; warm < 3; ++warm) {  // grows every buffer to its steady size
    scene.step(kFrameDt);
    if (!detector->detect(scene.spheres(), nullptr, out)) {
      state.SkipWithError("detect failed");
      return;
    }
  }
  for (auto _ : state) {
    scene.step(kFrameDt);
    const auto t0 = std::chrono::steady_clock::now();
    const viscd::Status s = detector->detect(scene.spheres(), nullptr, out);
    state.SetIterationTime(seconds_since(t0));
    if (!s) {
      state.SkipWithError(s.error().c_str());
      break;
    }
  }
  state.counters["pairs"] = static_cast<double>(out.pairs.size());
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations()) * state.range(0));
}

void size_and_thread_args(benchmark::internal::Benchmark* b) {
  b->ArgsProduct({{2000, 10000, 100000, 1000000}, {0, 1}})->ArgNames({"n", "threads"});
}

}  // namespace

BENCHMARK_TEMPLATE(bm_radix_sort, std::uint16_t)
    ->Apply(size_and_thread_args)
    ->UseManualTime()
    ->Unit(benchmark::kMicrosecond);
BENCHMARK_TEMPLATE(bm_radix_sort, std::uint32_t)
    ->Apply(size_and_thread_args)
    ->UseManualTime()
    ->Unit(benchmark::kMicrosecond);
BENCHMARK_TEMPLATE(bm_radix_sort, std::uint64_t)
    ->Apply(size_and_thread_args)
    ->UseManualTime()
    ->Unit(benchmark::kMicrosecond);
BENCHMARK(bm_pair_sort)
    ->Args({100000, 97000, 0})
    ->Args({1000000, 580000, 0})
    ->Args({1000000, 2500000, 0})
    ->Args({1000000, 2500000, 1})
    ->ArgNames({"objects", "pairs", "threads"})
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond);
BENCHMARK(bm_cpu_frame)->Apply(size_and_thread_args)->UseManualTime()->Unit(benchmark::kMillisecond);

BENCHMARK_MAIN();
