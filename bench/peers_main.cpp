// viscd_peers: the benchmark driver of docs/benchmarks.md. Four modes, each writing a table to
// stdout, progress to stderr and, with --csv, the table as CSV:
//
//   (default)    viscd against the peer broadphases (Bullet dbvt and sweep-and-prune, FCL dynamic
//                tree) in one process on the same moving scene; every method's exact pair set is
//                checked against viscd's every frame. Per method: median, mean and minimum ms per
//                frame (update + query), pairs per frame, and how many times slower than viscd it is.
//   --stages     viscd's per-stage ms (layout, codes, sort, build, fit, query) and the
//                wall time of detect(), for the frames that sorted, those that kept the last
//                order, and the mean of all.
//   --sort-bits  the paper's Table 2: radix sort time of the scene's 16/32/64-bit Morton codes.
//   --tree-stats viscd's LBVH: depth, nodes visited and boxes tested per object in the query.

#include <signal.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>
#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <iterator>
#include <numeric>
#include <string>
#include <vector>

#include "bench_util.hpp"
#include "core/morton.hpp"
#include "cpu/morton_order.hpp"
#include "cpu/parallel.hpp"
#include "cpu/radix_sort.hpp"
#include "cpu/simd.hpp"
#include "karras/karras_lbvh.hpp"
#include "peers.hpp"
#include "viscd/scene.hpp"
#include "viscd/viscd.hpp"

namespace viscd::bench {
namespace {

constexpr float kFrameDt = 1.0f / 60.0f;  // scene time per frame, seconds (a 60 Hz simulation)

struct Options {
  std::vector<std::uint32_t> objects{2000, 10000, 100000};
  int frames = 20;
  int warmup = 3;
  int repeats = 1;
  int threads = 0;  // as Config::threads: 0 = all hardware threads
  std::uint64_t seed = 1;
  std::string scene = "ring";
  float packing = 0.04f;  // SceneParams::packing
  std::string csv;
  std::vector<std::string> methods;  // empty: viscd, viscd_1t and every peer built in
  bool stages = false;
  bool sort_bits = false;
  bool tree_stats = false;
  int bits = 0;  // --stages, --tree-stats: Morton width, 0 = adaptive (32 without camera)
  int sort_runs = 50;
  int busy = 0;  // cores to hold with spinning processes while measuring
};

// Holds `count` cores with spinning child processes for its lifetime (--busy): what an engine's
// job threads do to a library that wants the cores too. The children die with this process.
class BusyCores {
 public:
  explicit BusyCores(int count) {
    for (int k = 0; k < count; ++k) {
      const pid_t pid = fork();
      if (pid == 0) {
        prctl(PR_SET_PDEATHSIG, SIGKILL);
        volatile unsigned long spin = 0;
        for (;;) spin = spin + 1;
      }
      if (pid > 0) pids_.push_back(pid);
    }
  }
  ~BusyCores() {
    for (const pid_t pid : pids_) kill(pid, SIGKILL);
    for (const pid_t pid : pids_) waitpid(pid, nullptr, 0);
  }
  BusyCores(const BusyCores&) = delete;
  BusyCores& operator=(const BusyCores&) = delete;

 private:
  std::vector<pid_t> pids_;
};

void progress(const std::string& line) {
  std::fprintf(stderr, "[viscd_peers] %s\n", line.c_str());
  std::fflush(stderr);
}

Scene make_scene(const Options& opt, std::uint32_t n) {
  SceneParams params;
  params.kind = parse_scene_kind(opt.scene).value();
  params.objects = n;
  params.seed = opt.seed;
  params.packing = opt.packing;
  return Scene::make(params);
}

// Objects move on circles about the y axis, so |(x, z)| and y never leave their first-frame range.
WorldBounds world_bounds(const Scene& scene) {
  float max_r = 0, max_rho = 0, max_y = 0;
  for (const Sphere& s : scene.spheres()) {
    max_r = std::max(max_r, s.r);
    max_rho = std::max(max_rho, std::sqrt(s.x * s.x + s.z * s.z));
    max_y = std::max(max_y, std::fabs(s.y));
  }
  const float margin = 1.0f + 2.0f * max_r;
  const float horizontal = std::max(max_rho, scene.world_radius()) + margin;
  const float vertical = max_y + margin;
  WorldBounds w;
  w.lo[0] = w.lo[2] = -horizontal;
  w.hi[0] = w.hi[2] = horizontal;
  w.lo[1] = -vertical;
  w.hi[1] = vertical;
  w.max_abs = std::max(horizontal, vertical);
  return w;
}

std::unique_ptr<Method> make_method(const std::string& name, int threads) {
  if (name == "viscd") return make_viscd_method(name, threads);
  if (name == "viscd_1t") return make_viscd_method(name, 1);
  return make_peer(name);
}

// Describes how `got` differs from `want` (both sorted): counts and the first differing pair.
std::string describe_mismatch(const std::vector<Pair>& want, const std::vector<Pair>& got) {
  std::vector<Pair> missing, extra;
  std::set_difference(want.begin(), want.end(), got.begin(), got.end(), std::back_inserter(missing));
  std::set_difference(got.begin(), got.end(), want.begin(), want.end(), std::back_inserter(extra));
  std::string s =
      format("%zu pairs, viscd has %zu: %zu missing, %zu extra", got.size(), want.size(), missing.size(), extra.size());
  if (!missing.empty()) s += format(", first missing (%u,%u)", missing[0].i, missing[0].j);
  if (!extra.empty()) s += format(", first extra (%u,%u)", extra[0].i, extra[0].j);
  if (missing.empty() && extra.empty()) s += " (duplicates)";
  return s;
}

bool is_canonical(const std::vector<Pair>& pairs) {
  for (std::size_t k = 0; k < pairs.size(); ++k) {
    if (pairs[k].i >= pairs[k].j) return false;
    if (k > 0 && !(pairs[k - 1] < pairs[k])) return false;
  }
  return true;
}

// ---------------------------------------------------------------------------------------------
// Default mode: viscd against the peers.
//
// Every method is built once per N over the first frame, then the frames run in blocks: the
// warm-up block, then --repeats blocks of --frames timed frames. Methods take turns block by
// block (viscd first, its pairs are the reference of the block), so a load spike on a shared
// machine hits every method rather than one, and no method pays its build twice (Bullet's sweep
// and prune builds in O(N^2)). Each method steps its own copy of the scene: all see the same
// frame sequence.

// One method under test with its own copy of the moving scene.
struct Runner {
  std::string name;
  std::unique_ptr<Method> method;
  Scene scene;
  double build_ms = 0;
  std::vector<double> frame_ms, pair_counts, candidate_counts;  // timed frames only
};

// How much faster an independent loop runs on `threads` threads than on one, on this machine now:
// a shared VM's second core is not always a whole core, which bounds every threaded figure.
double parallel_probe(int threads) {
  std::vector<float> v(std::size_t{1} << 21, 1.0f);
  auto time_loop = [&](int t) {
    const auto start = std::chrono::steady_clock::now();
    detail::parallel_for(v.size(), t, [&](std::size_t i) { v[i] = std::sqrt(v[i] + 1.0f) * 0.5f; });
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  };
  std::vector<double> one, all;
  for (int r = 0; r < 7; ++r) one.push_back(time_loop(1)), all.push_back(time_loop(threads));  // interleaved
  std::sort(one.begin(), one.end());
  std::sort(all.begin(), all.end());
  return one[one.size() / 2] / all[all.size() / 2];
}

int run_peers(const Options& opt) {
  std::vector<std::string> names = opt.methods;
  if (names.empty()) {
    names = {"viscd", "viscd_1t"};
    for (const std::string& p : peer_names()) names.push_back(p);
  }
  names.erase(std::remove(names.begin(), names.end(), "viscd"), names.end());
  names.insert(names.begin(), "viscd");
  for (const std::string& name : names) {
    if (!make_method(name, opt.threads)) {
      std::fprintf(stderr, "unknown or not built method '%s'\n", name.c_str());
      return 2;
    }
  }

  CsvWriter csv(opt.csv, {"method", "objects", "median_ms", "min_ms", "pairs", "speedup_vs_viscd", "mean_ms"});
  std::printf(
      "# viscd_peers: %s scene, %d warm-up frames, then %d block(s) of %d timed frames, methods taking "
      "turns per block; viscd threads %d; %d core(s) held busy by spinning processes\n",
      opt.scene.c_str(), opt.warmup, opt.repeats, opt.frames, detail::resolve_threads(opt.threads), opt.busy);
  std::printf("# ms per frame = update + query + exact sphere test (viscd: detect(), pairs sorted)\n");
  std::printf("# viscd's stage 8 kernels: %s (VISCD_SIMD=sse2 or scalar lowers them)\n",
              detail::simd_name(detail::simd_level_for(bench_config().simd)));
  std::printf("# this machine now: an independent loop runs %.2fx faster on %d threads than on 1\n",
              parallel_probe(detail::resolve_threads(opt.threads)), detail::resolve_threads(opt.threads));

  for (const std::uint32_t n : opt.objects) {
    const Scene start = make_scene(opt, n);
    const WorldBounds world = world_bounds(start);
    std::vector<Runner> runners;
    for (const std::string& name : names) {
      progress(format("N=%u %s: building", n, name.c_str()));
      Runner r;
      r.name = name;
      r.method = make_method(name, opt.threads);
      r.scene = start;
      const Clock::time_point t0 = Clock::now();
      if (const std::string error = r.method->init(r.scene.spheres(), world); !error.empty()) {
        std::fprintf(stderr, "%s: %s\n", name.c_str(), error.c_str());
        return 1;
      }
      r.build_ms = ms_since(t0);
      progress(format("N=%u %s: built in %.1f ms", n, name.c_str(), r.build_ms));
      runners.push_back(std::move(r));
    }

    std::vector<std::vector<Pair>> reference;  // viscd's sorted pairs, per frame of the block
    std::vector<Pair> sorted;
    int frame = 0;  // frames run before this block
    for (int block = 0; block <= opt.repeats; ++block) {
      const int count = block == 0 ? opt.warmup : opt.frames;
      const Clock::time_point t_block = Clock::now();
      reference.clear();
      for (Runner& r : runners) {
        for (int f = 0; f < count; ++f) {
          r.scene.step(kFrameDt);
          std::span<const Pair> pairs;
          std::string error;
          const Clock::time_point t0 = Clock::now();
          const bool ok = r.method->frame(r.scene.spheres(), pairs, error);
          const double ms = ms_since(t0);
          if (!ok) {
            std::fprintf(stderr, "%s failed at N=%u frame %d: %s\n", r.name.c_str(), n, frame + f, error.c_str());
            return 1;
          }
          sorted.assign(pairs.begin(), pairs.end());
          std::sort(sorted.begin(), sorted.end());
          if (&r == &runners.front()) {
            if (!std::equal(sorted.begin(), sorted.end(), pairs.begin(), pairs.end()) || !is_canonical(sorted)) {
              std::fprintf(stderr, "MISMATCH: viscd pairs at N=%u frame %d are not sorted unique (i<j)\n", n,
                           frame + f);
              return 3;
            }
            reference.push_back(sorted);
          } else if (sorted != reference[static_cast<std::size_t>(f)]) {
            std::fprintf(stderr, "MISMATCH: %s at N=%u frame %d: %s\n", r.name.c_str(), n, frame + f,
                         describe_mismatch(reference[static_cast<std::size_t>(f)], sorted).c_str());
            return 3;
          }
          if (block > 0) {
            r.frame_ms.push_back(ms);
            r.pair_counts.push_back(static_cast<double>(sorted.size()));
            r.candidate_counts.push_back(static_cast<double>(r.method->candidates()));
          }
        }
      }
      frame += count;
      progress(format("N=%u block %d/%d (%s): %d frames x %zu methods, all pairs equal, %.1f s", n, block, opt.repeats,
                      block == 0 ? "warm-up" : "timed", count, runners.size(), ms_since(t_block) / 1000.0));
    }

    const double viscd_ms = median(runners[0].frame_ms);
    const Runner* fastest_peer = nullptr;
    for (const Runner& r : runners)
      if (r.name.rfind("viscd", 0) != 0 && (!fastest_peer || median(r.frame_ms) < median(fastest_peer->frame_ms)))
        fastest_peer = &r;
    std::printf("\nN = %u, pairs per frame (median) %.0f, all methods agree on all %d frames\n", n,
                median(runners[0].pair_counts), frame);
    // The mean counts every frame in full: the cpu backend's frames that sort after frames that
    // kept the order are few, so the median does not see them.
    std::printf("%-12s %10s %10s %10s %10s %10s %10s %10s\n", "method", "build_ms", "median_ms", "mean_ms", "min_ms",
                "pairs", "candidates", "vs_viscd");
    for (const Runner& r : runners) {
      const double med = median(r.frame_ms), ratio = med / viscd_ms, cand = median(r.candidate_counts);
      const double avg = mean(r.frame_ms);
      std::printf("%-12s %10.2f %10.3f %10.3f %10.3f %10.0f %10s %9.2fx\n", r.name.c_str(), r.build_ms, med, avg,
                  minimum(r.frame_ms), median(r.pair_counts), cand > 0 ? format("%.0f", cand).c_str() : "-", ratio);
      csv.row({r.name, std::to_string(n), format("%.4f", med), format("%.4f", minimum(r.frame_ms)),
               format("%.0f", median(r.pair_counts)), format("%.3f", ratio), format("%.4f", avg)});
    }
    if (fastest_peer)
      std::printf("viscd speed-up over the fastest peer (%s): %.2fx\n", fastest_peer->name.c_str(),
                  median(fastest_peer->frame_ms) / viscd_ms);
    std::fflush(stdout);
  }
  return csv.ok() ? 0 : 1;
}

// ---------------------------------------------------------------------------------------------
// --stages: where viscd's time goes.

constexpr Stage kBroadphaseStages[] = {Stage::layout, Stage::codes, Stage::sort,
                                       Stage::build,  Stage::fit,   Stage::query};

int run_stages(const Options& opt) {
  CsvWriter csv(opt.csv, {"objects", "threads", "bits", "frames", "layout_ms", "codes_ms", "sort_ms", "build_ms",
                          "fit_ms", "query_ms", "stages_ms", "wall_ms", "pairs"});
  Config config = bench_config();
  config.threads = opt.threads;
  config.bits = opt.bits == 0 ? Bits::adaptive : static_cast<Bits>(opt.bits);
  const int threads = detail::resolve_threads(opt.threads);
  std::printf(
      "# viscd_peers --stages: %s scene, cpu backend, no camera, %d thread(s), %d frames x %d repeat(s) after %d "
      "warm-up\n",
      opt.scene.c_str(), threads, opt.frames, opt.repeats, opt.warmup);
  std::printf(
      "# frames: 'sorted' (median of the frames that sorted), 'kept' (median of those that kept the last\n"
      "# order: no layout, codes or sort), 'all' (mean of every frame: what a frame costs on average)\n");
  std::printf("# wall = detect() incl. input validation; query includes the pair sort and object states\n");
  std::printf("# stage 8 kernels: %s (VISCD_SIMD=sse2 or scalar lowers them)\n",
              detail::simd_name(detail::simd_level_for(bench_config().simd)));
  std::printf("# this machine now: an independent loop runs %.2fx faster on %d threads than on 1\n",
              parallel_probe(detail::hardware_threads()), detail::hardware_threads());
  std::printf("%9s %4s %12s", "objects", "bits", "frames");
  for (Stage s : kBroadphaseStages) std::printf(" %9s", std::string(stage_name(s)).c_str());
  std::printf(" %9s %9s %9s  %s\n", "stages", "wall", "pairs", "layout");

  // One frame's times: the broadphase stages, their sum, the wall time.
  constexpr std::size_t kCols = std::size(kBroadphaseStages) + 2;
  using Times = std::array<double, kCols>;
  for (const std::uint32_t n : opt.objects) {
    std::vector<Times> sorted, kept;
    std::vector<double> pairs;
    int bits = 0;
    std::string layout;
    const Clock::time_point t_start = Clock::now();
    for (int rep = 0; rep < opt.repeats; ++rep) {
      Scene scene = make_scene(opt, n);
      auto detector = make_cpu_detector(config);
      FrameResult out;
      for (int f = 0; f < opt.warmup + opt.frames; ++f) {
        scene.step(kFrameDt);
        const Clock::time_point t0 = Clock::now();
        if (Status s = detector->detect(scene.spheres(), nullptr, out); !s) {
          std::fprintf(stderr, "detect failed at N=%u: %s\n", n, s.error().c_str());
          return 1;
        }
        const double wall = ms_since(t0);
        if (f < opt.warmup) continue;
        Times t{};
        for (std::size_t k = 0; k < std::size(kBroadphaseStages); ++k) {
          t[k] = out.stats.ms(kBroadphaseStages[k]);
          t[kCols - 2] += t[k];
        }
        t[kCols - 1] = wall;
        (out.stats.order_kept ? kept : sorted).push_back(t);
        pairs.push_back(static_cast<double>(out.pairs.size()));
        bits = out.stats.bits;
        layout = format_layout(out.stats.layout);
      }
    }
    progress(format("--stages N=%u done in %.1f s", n, ms_since(t_start) / 1000.0));
    auto column = [](const std::vector<Times>& v, std::size_t k) {
      std::vector<double> c;
      for (const Times& t : v) c.push_back(t[k]);
      return c;
    };
    std::vector<Times> all = sorted;
    all.insert(all.end(), kept.begin(), kept.end());
    auto print = [&](const char* what, const std::vector<Times>& v, bool use_mean) {
      if (v.empty()) return;
      const std::string frames = format("%s %zu", what, v.size());
      std::printf("%9u %4d %12s", n, bits, frames.c_str());
      std::vector<std::string> row{std::to_string(n), std::to_string(threads), std::to_string(bits), frames};
      for (std::size_t k = 0; k < kCols; ++k) {
        const std::vector<double> c = column(v, k);
        const double x = use_mean ? mean(c) : median(c);
        std::printf(" %9.3f", x);
        row.push_back(format("%.4f", x));
      }
      std::printf(" %9.0f  %s\n", median(pairs), layout.c_str());
      row.push_back(format("%.0f", median(pairs)));
      csv.row(row);
    };
    print("sorted", sorted, false);
    print("kept", kept, false);
    print("all", all, true);
    std::fflush(stdout);
  }
  return csv.ok() ? 0 : 1;
}

// ---------------------------------------------------------------------------------------------
// --sort-bits: the paper's Table 2 (sort time by Morton width).

// The paper's Table 2 (RTX 3080, 2000 objects): sort time in microseconds for 16/32/64 bits.
constexpr double kPaperSortUs[] = {98.13, 191.1, 403.3};

template <class K>
std::vector<double> time_radix_sort(const std::vector<std::uint64_t>& codes, const Options& opt) {
  const std::size_t n = codes.size();
  std::vector<K> keys(n);
  std::vector<std::uint32_t> values(n);
  detail::RadixScratch<K> scratch;
  std::vector<double> us;
  for (int run = -3; run < opt.sort_runs; ++run) {  // 3 warm-up runs fill the scratch and caches
    std::transform(codes.begin(), codes.end(), keys.begin(), [](std::uint64_t c) { return static_cast<K>(c); });
    std::iota(values.begin(), values.end(), 0u);
    const Clock::time_point t0 = Clock::now();
    // The same call as the pipeline's stage 6 (core/broadphase.cpp): the full key width.
    detail::radix_sort<K>(keys, values, 8 * sizeof(K), opt.threads, scratch);
    const double t = 1000.0 * ms_since(t0);
    if (run >= 0) us.push_back(t);
  }
  if (!std::is_sorted(keys.begin(), keys.end())) {
    std::fprintf(stderr, "radix_sort left %zu-bit keys unsorted\n", 8 * sizeof(K));
    std::exit(1);
  }
  return us;
}

int run_sort_bits(Options opt, bool objects_given) {
  if (!objects_given) opt.objects = {2000, 100000};
  opt.threads = detail::resolve_threads(opt.threads);
  CsvWriter csv(opt.csv, {"objects", "bits", "median_us", "min_us", "ratio_to_16", "configuration"});
  std::printf(
      "# viscd_peers --sort-bits: radix sort (8-bit digits) of the %s scene's extended Morton codes, "
      "%d thread(s), median of %d runs\n",
      opt.scene.c_str(), opt.threads, opt.sort_runs);
  std::printf("# paper (Table 2, RTX 3080, 2000 objects): 98.13 / 191.1 / 403.3 us = 1 : %.2f : %.2f\n",
              kPaperSortUs[1] / kPaperSortUs[0], kPaperSortUs[2] / kPaperSortUs[0]);
  std::printf("%9s %4s %10s %10s %9s %9s  %s\n", "objects", "bits", "median_us", "min_us", "ratio", "paper",
              "configuration");
  for (const std::uint32_t n : opt.objects) {
    Scene scene = make_scene(opt, n);
    scene.step(kFrameDt);
    std::vector<std::uint32_t> active(n);
    std::iota(active.begin(), active.end(), 0u);
    const detail::ActiveExtent extent = detail::active_extent(scene.spheres(), active, opt.threads);
    double us16 = 0;
    for (int b = 0; b < 3; ++b) {
      const int bits = 16 << b;
      const detail::MortonLayout layout =
          detail::make_layout(Layout::extended, bits, extent.bounds, extent.mean_diameter());
      const detail::MortonEncoder encoder(layout, extent.bounds);
      std::vector<std::uint64_t> codes(n);
      for (std::uint32_t k = 0; k < n; ++k) {
        const Sphere& s = scene.spheres()[k];
        codes[k] = encoder.encode(s.x, s.y, s.z);
      }
      const std::vector<double> us = bits == 16   ? time_radix_sort<std::uint16_t>(codes, opt)
                                     : bits == 32 ? time_radix_sort<std::uint32_t>(codes, opt)
                                                  : time_radix_sort<std::uint64_t>(codes, opt);
      const double med = median(us);
      if (bits == 16) us16 = med;
      const std::string config = format_layout(layout.info());
      std::printf("%9u %4d %10.2f %10.2f %8.2fx %8.2fx  %s\n", n, bits, med, minimum(us), med / us16,
                  kPaperSortUs[b] / kPaperSortUs[0], config.c_str());
      csv.row({std::to_string(n), std::to_string(bits), format("%.3f", med), format("%.3f", minimum(us)),
               format("%.3f", med / us16), config});
    }
    progress(format("--sort-bits N=%u done", n));
  }
  return csv.ok() ? 0 : 1;
}

// ---------------------------------------------------------------------------------------------
// --tree-stats: what the query stage does per object (evidence for docs/benchmarks.md).

struct TraversalCount {
  std::uint64_t nodes = 0;      // internal nodes fetched
  std::uint64_t box_tests = 0;  // child boxes tested (children not pruned by position)
  std::uint64_t leaf_hits = 0;  // leaves whose box overlaps: candidates for the exact test
};

// A counting replica of detail::for_each_overlap_after (karras/karras_lbvh.hpp): same order, same pruning.
void count_traversal(const detail::Lbvh& bvh, std::uint32_t p, const detail::Aabb& box, TraversalCount& c) {
  if (bvh.leaves < 2) return;
  std::vector<std::uint32_t> stack;
  std::uint32_t node = 0;
  for (;;) {
    const detail::BvhNode& nd = bvh.nodes[node];
    ++c.nodes;
    std::uint32_t next = detail::kNoParent;
    for (int k = 0; k < 2; ++k) {
      if (nd.last[k] <= p) continue;
      ++c.box_tests;
      if (!detail::overlaps(nd.box[k], box)) continue;
      if (nd.child[k] & detail::kLeafBit)
        ++c.leaf_hits;
      else if (next == detail::kNoParent)
        next = nd.child[k];
      else
        stack.push_back(nd.child[k]);
    }
    if (next != detail::kNoParent) {
      node = next;
    } else if (!stack.empty()) {
      node = stack.back();
      stack.pop_back();
    } else {
      return;
    }
  }
}

double mean_leaf_depth(const detail::Lbvh& bvh) {
  if (bvh.leaves < 2) return 0;
  std::uint64_t sum = 0;
  std::vector<std::pair<std::uint32_t, int>> stack{{0u, 0}};
  while (!stack.empty()) {
    const auto [node, d] = stack.back();
    stack.pop_back();
    for (const std::uint32_t ch : bvh.nodes[node].child) {
      if (ch & detail::kLeafBit)
        sum += static_cast<std::uint64_t>(d + 1);
      else
        stack.emplace_back(ch, d + 1);
    }
  }
  return static_cast<double>(sum) / bvh.leaves;
}

int run_tree_stats(const Options& opt) {
  const int threads = detail::resolve_threads(opt.threads);
  const int bits = opt.bits == 0 ? 32 : opt.bits;
  CsvWriter csv(opt.csv, {"objects", "bits", "max_depth", "mean_leaf_depth", "nodes_per_leaf", "box_tests_per_leaf",
                          "candidates_per_leaf", "pairs_per_leaf", "distinct_keys", "query_ms", "ns_per_node"});
  std::printf(
      "# viscd_peers --tree-stats: %s scene, %d-bit extended Morton codes, %d thread(s); per leaf p the "
      "query descends from the root to every leaf q > p whose box overlaps p's\n",
      opt.scene.c_str(), bits, threads);
  std::printf("%9s %4s %6s %7s %7s %9s %9s %9s %9s %8s %9s %8s\n", "objects", "bits", "depth", "mean_d", "log2N",
              "nodes/p", "tests/p", "cand/p", "pairs/p", "distinct", "query_ms", "ns/node");
  for (const std::uint32_t n : opt.objects) {
    Scene scene = make_scene(opt, n);
    std::vector<std::uint32_t> active(n);
    std::iota(active.begin(), active.end(), 0u);
    detail::KarrasBroadphase broadphase;
    std::vector<Pair> pairs;
    std::vector<double> query_ms;
    for (int f = 0; f < opt.warmup + opt.frames; ++f) {
      scene.step(kFrameDt);
      FrameStats stats;
      if (Status s = broadphase.run(scene.spheres(), active, bits, Layout::extended, threads, 0, pairs, stats); !s) {
        std::fprintf(stderr, "broadphase failed at N=%u: %s\n", n, s.error().c_str());
        return 1;
      }
      if (f >= opt.warmup) query_ms.push_back(stats.ms(Stage::query));
    }
    const detail::Lbvh& tree = broadphase.tree();
    const std::span<const detail::Aabb> boxes = broadphase.leaf_boxes();
    TraversalCount count;
    for (std::uint32_t p = 0; p < n; ++p) count_traversal(tree, p, boxes[p], count);
    std::vector<std::uint64_t> unique_codes = broadphase.sorted_codes();  // sorted: ties are adjacent
    const auto distinct_keys =
        static_cast<double>(std::unique(unique_codes.begin(), unique_codes.end()) - unique_codes.begin()) / n;
    const double dn = n, q_ms = median(query_ms);
    auto per_leaf = [dn](std::uint64_t v) { return static_cast<double>(v) / dn; };
    const double ns_per_node = q_ms * 1e6 * detail::threads_for(n, threads) / static_cast<double>(count.nodes);
    const int depth = detail::lbvh_depth(tree);
    const double mean_depth = mean_leaf_depth(tree);
    std::printf("%9u %4d %6d %7.1f %7.1f %9.1f %9.1f %9.2f %9.3f %7.1f%% %9.3f %8.2f\n", n, bits, depth, mean_depth,
                std::log2(dn), per_leaf(count.nodes), per_leaf(count.box_tests), per_leaf(count.leaf_hits),
                per_leaf(pairs.size()), 100 * distinct_keys, q_ms, ns_per_node);
    csv.row({std::to_string(n), std::to_string(bits), std::to_string(depth), format("%.2f", mean_depth),
             format("%.2f", per_leaf(count.nodes)), format("%.2f", per_leaf(count.box_tests)),
             format("%.3f", per_leaf(count.leaf_hits)), format("%.4f", per_leaf(pairs.size())),
             format("%.4f", distinct_keys), format("%.4f", q_ms), format("%.3f", ns_per_node)});
    progress(format("--tree-stats N=%u done", n));
    std::fflush(stdout);
  }
  return csv.ok() ? 0 : 1;
}

}  // namespace
}  // namespace viscd::bench

int main(int argc, char** argv) {
  using viscd::bench::Options;
  Options opt;
  CLI::App app{
      "viscd_peers: viscd against Bullet and FCL broadphases, per-stage times, sort time by "
      "Morton width (docs/benchmarks.md)"};
  app.add_option("--objects", opt.objects, "object counts N, comma separated")->delimiter(',');
  app.add_option("--frames", opt.frames, "timed frames per repeat")->check(CLI::PositiveNumber);
  app.add_option("--warmup", opt.warmup, "untimed frames before the timed ones")->check(CLI::NonNegativeNumber);
  app.add_option("--repeats", opt.repeats,
                 "peers: blocks of --frames timed frames (methods take turns per block); --stages: runs")
      ->check(CLI::PositiveNumber);
  app.add_option("--threads", opt.threads, "viscd worker threads, 0 = all")->check(CLI::NonNegativeNumber);
  app.add_option("--seed", opt.seed, "scene seed");
  app.add_option("--scene", opt.scene, "ring, box or clusters")->check(CLI::IsMember({"ring", "box", "clusters"}));
  app.add_option("--packing", opt.packing, "volume fraction of the spheres (0.04: 0.135 pairs per object in the ring)")
      ->check(CLI::Range(0.001f, 0.5f));
  app.add_option("--csv", opt.csv, "write the table as CSV to this file");
  app.add_option("--methods", opt.methods, "methods to compare (default: viscd, viscd_1t and every peer built in)")
      ->delimiter(',');
  auto* stages =
      app.add_flag("--stages", opt.stages,
                   "per-stage ms of viscd's cpu backend: frames that sorted, frames that kept the order, mean of all");
  auto* sort_bits = app.add_flag("--sort-bits", opt.sort_bits, "paper Table 2: radix sort time for 16/32/64-bit keys");
  auto* tree_stats =
      app.add_flag("--tree-stats", opt.tree_stats, "viscd's LBVH: depth and work per object in the query");
  stages->excludes(sort_bits)->excludes(tree_stats);
  sort_bits->excludes(tree_stats);
  app.add_option("--bits", opt.bits,
                 "--stages, --tree-stats: Morton width 16, 32 or 64 (default adaptive = 32 without camera)")
      ->check(CLI::IsMember({0, 16, 32, 64}));
  app.add_option("--runs", opt.sort_runs, "--sort-bits: timed sorts per width")->check(CLI::PositiveNumber);
  app.add_option("--busy", opt.busy,
                 "hold this many cores with spinning processes while measuring (what an engine's own "
                 "threads do); compare viscd with viscd_1t in that run")
      ->check(CLI::Range(0, 256));
  CLI11_PARSE(app, argc, argv);
  const viscd::bench::BusyCores busy(opt.busy);

  if (opt.stages) return viscd::bench::run_stages(opt);
  if (opt.tree_stats) return viscd::bench::run_tree_stats(opt);
  if (opt.sort_bits) return viscd::bench::run_sort_bits(opt, app.count("--objects") > 0);
  return viscd::bench::run_peers(opt);
}
