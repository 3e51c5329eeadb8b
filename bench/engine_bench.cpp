// viscd_engine_bench: measurements of the engine-facing features (docs/benchmarks.md, "Filters,
// id maps and queries"). Four modes, each printing a table (and, with --csv, writing it):
//
//   --filters  cpu frames on the moving ring scene without a camera: no filters, every filter the
//              default, half the objects in a group that collides with nothing (group 2, mask 0:
//              left out of the tree), and half filtered per pair (group 2 that the other half's
//              masks exclude, mask all: the pre-pass keeps them, the traversal drops their pairs).
//              Median detect() wall ms over the frames, and the ratio to the unfiltered frame.
//   --id-map   the caller's 1280x720 id map (a cpu frame's own map of the ring, per camera preset):
//              a plain sum over it, count_ids alone, detect() from the map (culled; its count,
//              cull and other stages) and detect() of every object without a map: median ms, the
//              four interleaved frame by frame, each after an idle gap (--gap-ms) as in a game.
//   --rays     ray_cast and overlap on a frame of N objects (no camera): median microseconds per
//              query over batches, rays from random points of the world in random directions.
//   --events   cpu frames of the moving ring scene without a camera, contact events off and on,
//              interleaved run by run: median detect() wall ms of each and their ratio.

#include <CLI/CLI.hpp>

#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <random>
#include <span>
#include <string>
#include <thread>
#include <vector>

#include "bench_util.hpp"
#include "cpu/parallel.hpp"
#include "cpu/pipeline.hpp"
#include "cpu/visibility.hpp"
#include "viscd/scene.hpp"
#include "viscd/viscd.hpp"

namespace viscd::bench {
namespace {

constexpr float kFrameDt = 1.0f / 60.0f;

struct Options {
  std::vector<std::uint32_t> objects{100000};
  int frames = 20, warmup = 3, repeats = 3, threads = 0;
  bool filters = false, id_map = false, rays = false, events = false;
  std::vector<std::string> cameras{"zoom-out", "orbit", "zoom-in"};
  double gap_ms = 1.0;  // --id-map: idle time before each timed call
  int queries = 20000;
  std::string csv;
};

// Median detect() ms over frames of one moving scene (the same sequence for every variant).
double frame_ms(const Options& o, std::uint32_t n, const std::vector<Filter>& filters, std::size_t& pairs,
                std::array<double, kStageCount>& stage) {
  std::vector<double> all;
  std::array<std::vector<double>, kStageCount> per_stage;
  for (int rep = 0; rep < o.repeats; ++rep) {
    Scene scene = Scene::make({.objects = n});
    Config c = bench_config();
    c.threads = o.threads;
    auto d = make_cpu_detector(c);
    FrameResult f;
    for (int k = 0; k < o.warmup + o.frames; ++k) {
      scene.step(kFrameDt);
      FrameInput in;
      in.spheres = scene.spheres();
      in.filters = filters;
      const auto t0 = Clock::now();
      if (Status s = d->detect(in, f); !s) {
        std::fprintf(stderr, "detect failed: %s\n", s.error().c_str());
        std::exit(1);
      }
      if (k < o.warmup) continue;
      all.push_back(ms_since(t0));
      for (std::size_t st = 0; st < kStageCount; ++st) per_stage[st].push_back(f.stats.stage_ms[st]);
    }
    pairs = f.pairs.size();
  }
  for (std::size_t st = 0; st < kStageCount; ++st) stage[st] = median(per_stage[st]);
  return median(all);
}

// Frames with contact events off and on, the variants interleaved run by run in alternating
// order (same scene sequence): the median detect() ms of each, their ratio, the events per frame.
int run_events(const Options& o) {
  CsvWriter csv(o.csv, {"objects", "off_ms", "on_ms", "ratio", "pairs", "events_per_frame"});
  std::printf("%9s %10s %10s %7s %9s %16s\n", "objects", "off_ms", "on_ms", "ratio", "pairs", "events_per_frame");
  for (const std::uint32_t n : o.objects) {
    std::vector<double> off, on, events;
    std::size_t pairs = 0;
    for (int rep = 0; rep < o.repeats; ++rep) {
      for (const bool second : {false, true}) {
        const bool with_events = second != (rep % 2 == 1);  // the order alternates run by run
        Scene scene = Scene::make({.objects = n});
        Config c = bench_config();
        c.threads = o.threads;
        c.contact_events = with_events;
        auto d = make_cpu_detector(c);
        FrameResult f;
        for (int k = 0; k < o.warmup + o.frames; ++k) {
          scene.step(kFrameDt);
          const auto t0 = Clock::now();
          if (Status s = d->detect(scene.spheres(), nullptr, f); !s) {
            std::fprintf(stderr, "detect failed: %s\n", s.error().c_str());
            std::exit(1);
          }
          if (k < o.warmup) continue;
          (with_events ? on : off).push_back(ms_since(t0));
          if (with_events) events.push_back(static_cast<double>(f.began.size() + f.ended.size()));
        }
        pairs = f.pairs.size();
      }
    }
    const double a = median(off), b = median(on);
    std::printf("%9u %10.3f %10.3f %7.3f %9zu %16.1f\n", n, a, b, b / a, pairs, median(events));
    csv.row({std::to_string(n), format("%.4f", a), format("%.4f", b), format("%.4f", b / a), std::to_string(pairs),
             format("%.1f", median(events))});
  }
  return 0;
}

int run_filters(const Options& o) {
  CsvWriter csv(o.csv, {"objects", "variant", "median_ms", "ratio", "pairs", "cull_ms", "layout_ms", "codes_ms",
                        "sort_ms", "build_ms", "fit_ms", "query_ms"});
  std::printf("%9s %-28s %10s %7s %9s   median ms of cull layout codes sort build fit query\n", "objects", "variant",
              "median_ms", "ratio", "pairs");
  for (const std::uint32_t n : o.objects) {
    std::vector<Filter> none, defaults(n), half_nothing(n), half_per_pair(n);
    for (std::uint32_t k = 0; k < n; k += 2) half_nothing[k] = {2, 0};
    for (std::uint32_t k = 0; k < n; ++k) half_per_pair[k] = k % 2 ? Filter{1, ~2u} : Filter{2, ~0u};
    const struct {
      const char* name;
      const std::vector<Filter>* f;
    } variants[] = {{"no filters", &none},
                    {"all default filters", &defaults},
                    {"half collide with nothing", &half_nothing},
                    {"half filtered per pair", &half_per_pair}};
    double base = 0;
    for (const auto& v : variants) {
      std::size_t pairs = 0;
      std::array<double, kStageCount> st{};
      const double ms = frame_ms(o, n, *v.f, pairs, st);
      if (v.f == &none) base = ms;
      std::vector<std::string> row = {std::to_string(n), v.name, format("%.4f", ms), format("%.4f", ms / base),
                                      std::to_string(pairs)};
      std::printf("%9u %-28s %10.3f %7.3f %9zu  ", n, v.name, ms, ms / base, pairs);
      for (Stage s : {Stage::cull, Stage::layout, Stage::codes, Stage::sort, Stage::build, Stage::fit, Stage::query}) {
        std::printf(" %6.3f", st[static_cast<std::size_t>(s)]);
        row.push_back(format("%.4f", st[static_cast<std::size_t>(s)]));
      }
      std::printf("\n");
      csv.row(row);
    }
  }
  return 0;
}

// A plain sum over the map: what reading it once costs (the bar for counting it).
std::uint64_t plain_sum(std::span<const std::uint32_t> ids) {
  std::uint64_t s = 0;
  for (const std::uint32_t v : ids) s += v;
  return s;
}

int run_id_map(const Options& o) {
  CsvWriter csv(o.csv, {"objects", "camera", "what", "median_ms", "min_ms"});
  std::printf("%9s %-9s %-34s %10s %10s\n", "objects", "camera", "what", "median_ms", "min_ms");
  volatile std::uint64_t sink = 0;
  for (const std::uint32_t n : o.objects) {
    for (const std::string& preset : o.cameras) {
      Scene scene = Scene::make({.objects = n});
      const Camera cam = camera_preset(preset, scene, 1280, 720).value();
      Config c = bench_config();
      c.threads = o.threads;
      auto own = make_cpu_detector(c);
      FrameResult f;
      if (!own->detect(scene.spheres(), &cam, f).ok()) return 1;
      const auto& map = detail::backend_as<detail::PipelineDetector>(*own).visibility_map();
      const std::vector<std::uint32_t> ids(map.ids.begin(), map.ids.end());
      std::size_t runs = ids.empty() ? 0 : 1, background = 0;
      for (std::size_t k = 1; k < ids.size(); ++k) runs += ids[k] != ids[k - 1];
      for (std::uint32_t id : ids) background += id == 0;
      std::printf("%9u %-9s map: %zu runs of equal ids, %.1f %% background, %u of %u objects active\n", n,
                  preset.c_str(), runs, 100.0 * static_cast<double>(background) / static_cast<double>(ids.size()),
                  f.stats.active, n);
      const int threads = detail::resolve_threads(o.threads);
      std::vector<std::uint32_t> hist;
      detail::CountScratch scratch;
      std::vector<double> sum_ms, count_ms, stage_ms, cull_ms, rest_ms, culled_ms, all_ms;
      auto d = make_cpu_detector(c);
      auto every = make_cpu_detector(c);  // the baseline: every object, no map (no camera)
      FrameResult g;
      FrameInput in;
      in.spheres = scene.spheres();
      in.camera = &cam;
      in.id_map = ids;
      in.id_map_width = 1280;
      in.id_map_height = 720;
      // The variants interleaved frame by frame, so that the machine's state falls on all alike.
      // count_ids back to back first: the map, the histogram and the buckets stay in cache.
      std::vector<double> hot_ms;
      for (int k = 0; k < o.warmup + 10 * o.frames; ++k) {
        const auto th = Clock::now();
        if (!detail::count_ids(ids, n, threads, hist, scratch)) return 1;
        if (k >= o.warmup) hot_ms.push_back(ms_since(th));
      }
      // Each timed call follows a pause longer than viscd's pool spins (as a game's detect()
      // follows the rest of its frame): each starts with the workers asleep, whatever ran before.
      auto pause = [&] {
        if (o.gap_ms > 0) std::this_thread::sleep_for(std::chrono::duration<double, std::milli>(o.gap_ms));
      };
      for (int k = 0; k < o.warmup + 10 * o.frames; ++k) {
        pause();
        const auto ts = Clock::now();
        sink = sink + plain_sum(ids);
        const double sum = ms_since(ts);
        pause();
        const auto t0 = Clock::now();
        if (!detail::count_ids(ids, n, threads, hist, scratch)) return 1;
        const double t = ms_since(t0);
        pause();
        const auto t1 = Clock::now();
        if (!d->detect(in, f).ok()) return 1;
        const double culled = ms_since(t1);
        pause();
        const auto t2 = Clock::now();
        if (!every->detect(scene.spheres(), nullptr, g).ok()) return 1;
        const double all = ms_since(t2);
        if (k < o.warmup) continue;
        sum_ms.push_back(sum);
        count_ms.push_back(t);
        stage_ms.push_back(f.stats.ms(Stage::count));
        cull_ms.push_back(f.stats.ms(Stage::cull));
        rest_ms.push_back(culled - f.stats.ms(Stage::count) - f.stats.ms(Stage::cull));
        culled_ms.push_back(culled);
        all_ms.push_back(all);
      }
      for (const auto& [what, v] : {std::pair<const char*, std::vector<double>*>{"plain sum of the map", &sum_ms},
                                    {"count_ids", &count_ms},
                                    {"count_ids, back to back", &hot_ms},
                                    {"detect() with the map: count", &stage_ms},
                                    {"detect() with the map: cull", &cull_ms},
                                    {"detect() with the map: the rest", &rest_ms},
                                    {"detect() with the map, culled", &culled_ms},
                                    {"detect() of every object, no map", &all_ms}}) {
        std::printf("%9u %-9s %-34s %10.4f %10.4f\n", n, preset.c_str(), what, median(*v), minimum(*v));
        csv.row({std::to_string(n), preset, what, format("%.5f", median(*v)), format("%.5f", minimum(*v))});
      }
      std::printf("%9u %-9s count_ids / plain sum %.2f; every object / culled %.2f\n", n, preset.c_str(),
                  median(count_ms) / median(sum_ms), median(all_ms) / median(culled_ms));
    }
  }
  return sink == 1 ? 1 : 0;
}

int run_rays(const Options& o) {
  CsvWriter csv(o.csv, {"objects", "query", "median_us", "min_us", "hit_share"});
  std::printf("%9s %-22s %10s %10s %9s\n", "objects", "query", "median_us", "min_us", "hits");
  for (const std::uint32_t n : o.objects) {
    Scene scene = Scene::make({.objects = n});
    Config c = bench_config();
    c.threads = o.threads;
    auto d = make_cpu_detector(c);
    FrameResult f;
    for (int k = 0; k < 2; ++k) {
      scene.step(kFrameDt);
      if (!d->detect(scene.spheres(), nullptr, f).ok()) return 1;
    }
    std::mt19937_64 rng(5);
    std::uniform_real_distribution<float> u(-1, 1);
    const float wr = scene.world_radius(), wh = scene.world_half_height();
    std::vector<Ray> rays(static_cast<std::size_t>(o.queries));
    std::vector<Sphere> spheres(rays.size());
    for (std::size_t k = 0; k < rays.size(); ++k) {
      Ray& r = rays[k];
      r.origin[0] = wr * u(rng), r.origin[1] = wh * u(rng), r.origin[2] = wr * u(rng);
      r.dir[0] = u(rng), r.dir[1] = u(rng), r.dir[2] = u(rng);
      spheres[k] = {r.origin[0], r.origin[1], r.origin[2], 1.0f};
    }
    constexpr std::size_t kBatch = 100;
    std::vector<double> ray_us, all_us, overlap_us;
    std::size_t hits = 0;
    RayHit h{};
    std::vector<RayHit> all;
    std::vector<std::uint32_t> idx;
    for (std::size_t b = 0; b + kBatch <= rays.size(); b += kBatch) {
      auto t0 = Clock::now();
      for (std::size_t k = b; k < b + kBatch; ++k) hits += d->ray_cast(rays[k], h) ? 1 : 0;
      ray_us.push_back(1000.0 * ms_since(t0) / kBatch);
      t0 = Clock::now();
      for (std::size_t k = b; k < b + kBatch; ++k) d->overlap(spheres[k], idx);
      overlap_us.push_back(1000.0 * ms_since(t0) / kBatch);
    }
    // ray_cast_all on the first rays only: a ray through the world can hit thousands.
    for (std::size_t b = 0; b + kBatch <= std::min<std::size_t>(rays.size(), 2000); b += kBatch) {
      const auto t0 = Clock::now();
      for (std::size_t k = b; k < b + kBatch; ++k) d->ray_cast_all(rays[k], all);
      all_us.push_back(1000.0 * ms_since(t0) / kBatch);
    }
    const double share = static_cast<double>(hits) / static_cast<double>(ray_us.size() * kBatch);
    for (const auto& [what, v] : {std::pair<const char*, std::vector<double>*>{"ray_cast", &ray_us},
                                  {"ray_cast_all", &all_us},
                                  {"overlap (r = 1)", &overlap_us}}) {
      std::printf("%9u %-22s %10.3f %10.3f %9.3f\n", n, what, median(*v), minimum(*v), share);
      csv.row(
          {std::to_string(n), what, format("%.4f", median(*v)), format("%.4f", minimum(*v)), format("%.4f", share)});
    }
  }
  return 0;
}

}  // namespace
}  // namespace viscd::bench

int main(int argc, char** argv) {
  viscd::bench::Options o;
  CLI::App app{"viscd_engine_bench: filters, the caller's id map and queries (docs/benchmarks.md)"};
  app.add_option("--objects", o.objects, "object counts")->delimiter(',');
  app.add_option("--frames", o.frames, "timed frames per run");
  app.add_option("--warmup", o.warmup, "untimed frames first");
  app.add_option("--repeats", o.repeats, "runs per variant (--filters, --events)");
  app.add_option("--threads", o.threads, "as Config::threads (0 = all)");
  app.add_option("--cameras", o.cameras, "camera presets of the map (--id-map)")->delimiter(',');
  app.add_option("--gap-ms", o.gap_ms,
                 "--id-map: idle milliseconds before each timed call, so that each starts as a game's detect() "
                 "does, after other work (0: back to back)");
  app.add_option("--queries", o.queries, "queries per kind (--rays)");
  app.add_option("--csv", o.csv, "also write the table here");
  app.add_flag("--filters", o.filters, "filtered against unfiltered frames");
  app.add_flag("--id-map", o.id_map,
               "counting a 1280x720 id map, and detect() culled by it against detect() of every object");
  app.add_flag("--rays", o.rays, "ray and overlap queries");
  app.add_flag("--events", o.events, "frames with contact events on against off");
  CLI11_PARSE(app, argc, argv);
  if (o.filters) return viscd::bench::run_filters(o);
  if (o.id_map) return viscd::bench::run_id_map(o);
  if (o.rays) return viscd::bench::run_rays(o);
  if (o.events) return viscd::bench::run_events(o);
  std::fprintf(stderr, "viscd_engine_bench: give --filters, --id-map, --rays or --events\n");
  return 2;
}
