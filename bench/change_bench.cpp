// viscd_change_bench: what a frame costs when only some objects move (Config::follow_change;
// docs/benchmarks.md, "Cost follows change"). Two modes, each printing a table (and, with --csv,
// writing it):
//
//   --fractions  a uniform world of N objects (about 0.5 pairs per object), spheres or boxes, in
//                which a fraction of them moves each frame (a fixed set, as awake bodies; or
//                --redraw: a new random set every frame), the rest keeping their bounds bit for
//                bit. Three detectors see the same frames, interleaved frame by frame: one that
//                rebuilds every frame (follow_change off), one that follows change comparing
//                bounds, and one told the movers (FrameInput::moved). Median detect() wall ms of
//                each, and each over the rebuild of a frame in which every object moves.
//                --static K adds a static set of K objects, of which --static-moving M glide
//                every frame (kinematic platforms: the static set changes in M slots a frame).
//                --spawn K adds K objects at the end every frame, --remove K removes K as
//                engines do (the last object moved into the gap; the list names the gaps).
//   --pile       a settled pile of N grains on a lattice, every grain jiggling a little about its
//                place each frame (as a granular solver leaves them): rebuild against
//                follow_change with --margin, interleaved; the pairs are compared each frame.

#include <CLI/CLI.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numeric>
#include <random>
#include <string>
#include <vector>

#include "bench_util.hpp"
#include "viscd/viscd.hpp"

namespace viscd::bench {
namespace {

struct Options {
  std::vector<std::uint32_t> objects{1000000};
  std::vector<double> fractions{0.0, 0.01, 0.1, 1.0};
  std::vector<std::string> shapes{"sphere", "box"};
  int frames = 20, warmup = 3, threads = 0;
  std::uint32_t spawn = 0;                       // --fractions: objects added at the end each frame
  std::uint32_t remove = 0;                      // --fractions: objects removed (last into the gap) each frame
  std::uint32_t statics = 0, static_moving = 0;  // --fractions: the static set, and how many of it move each frame
  bool redraw = false, pile = false, run_fractions = false, stages = false;
  std::vector<std::string> variants{"rebuild", "compared", "listed"};
  float margin = 0.02f, jiggle = 0.004f, rest_margin = 0.0f, move_margin = Config{}.move_margin;
  std::string csv;
};

Box box_of(const Sphere& s) { return Box{{s.x - s.r, s.y - s.r, s.z - s.r}, {s.x + s.r, s.y + s.r, s.z + s.r}}; }

struct World {
  std::vector<Sphere> spheres;
  std::vector<Box> boxes;
  bool is_box = false;
  float side = 0;  // the slab's x and z extent (y: a tenth)
  void set(std::size_t k, const Sphere& s) {
    spheres[k] = s;
    if (is_box) boxes[k] = box_of(s);
  }
  void add(const Sphere& s) {
    spheres.push_back(s);
    if (is_box) boxes.push_back(box_of(s));
  }
  /// Removes object k as an engine does: the last one takes its place.
  void remove(std::size_t k) {
    set(k, spheres.back());
    spheres.pop_back();
    if (is_box) boxes.pop_back();
  }
  [[nodiscard]] FrameInput input() const {
    FrameInput in;
    if (is_box)
      in.boxes = boxes;
    else
      in.spheres = spheres;
    return in;
  }
};

// N objects of radius 0.5 in a flat slab whose size gives about 0.5 pairs per object.
World make_world(std::size_t n, bool is_box, std::mt19937_64& rng) {
  // Pairs per object ~ (n / volume) * (4/3 pi (2r)^3) / 2 with r = 0.5: volume = n * 2.09 / 0.5.
  const double volume = static_cast<double>(n) * 4.19 / 2.0 / 0.5;
  const auto side = static_cast<float>(std::cbrt(volume / 0.1));  // x and z; y is a tenth
  std::uniform_real_distribution<float> u(0, 1);
  World w;
  w.is_box = is_box;
  w.side = side;
  w.spheres.resize(n);
  if (is_box) w.boxes.resize(n);
  for (std::size_t k = 0; k < n; ++k) w.set(k, Sphere{u(rng) * side, u(rng) * side * 0.1f, u(rng) * side, 0.5f});
  return w;
}

void run_fractions(const Options& o, CsvWriter& csv) {
  // Medians of the frames, each over the all-moving frame's median; then the same for the means,
  // which count frames that cost more now and then (main rebuilt every few frames) at their share.
  std::printf("%-6s %9s %8s %6s | %10s %10s %10s | %9s %9s %9s | %9s %9s %9s | %s\n", "shape", "objects", "moving",
              "mode", "rebuild", "compared", "listed", "rebuild/a", "compared/a", "listed/a", "mean r/a", "mean c/a",
              "mean l/a", "pairs");
  for (const std::string& shape : o.shapes) {
    for (const std::uint32_t n : o.objects) {
      double all_moving_ms = 0;  // the rebuild of a frame where every object moves
      // Fraction 1 first: the denominator.
      std::vector<double> fractions = o.fractions;
      std::sort(fractions.begin(), fractions.end(), [](double a, double b) { return a > b; });
      for (const double fraction : fractions) {
        std::mt19937_64 rng(n + static_cast<std::uint64_t>(fraction * 1e6));
        World w = make_world(n, shape == "box", rng);
        Config rebuild = bench_config(), follow = bench_config();
        rebuild.threads = follow.threads = o.threads;
        rebuild.follow_change = false;
        follow.follow_change = true;
        follow.rest_margin = o.rest_margin;
        follow.move_margin = o.move_margin;
        auto d_rebuild = make_cpu_detector(rebuild), d_compared = make_cpu_detector(follow),
             d_listed = make_cpu_detector(follow);
        // The static set: objects of radius 2 in the slab, the first --static-moving of them
        // gliding every frame (kinematic platforms), the same on every detector.
        std::vector<Sphere> st(o.statics);
        std::uniform_real_distribution<float> place(0, 1);
        for (Sphere& c : st) c = Sphere{place(rng) * w.side, place(rng) * w.side * 0.1f, place(rng) * w.side, 2.0f};
        auto set_static = [&](Detector& d) {
          if (st.empty()) return true;
          if (!w.is_box) return d.set_static_spheres(st).ok();
          std::vector<Box> b(st.size());
          for (std::size_t k = 0; k < st.size(); ++k) b[k] = box_of(st[k]);
          return d.set_static_boxes(b).ok();
        };
        if (!set_static(*d_rebuild) || !set_static(*d_compared) || !set_static(*d_listed)) {
          std::fprintf(stderr, "the static set was refused\n");
          std::exit(1);
        }
        FrameResult fr, fc, fl;
        std::vector<double> t_rebuild, t_compared, t_listed;
        const auto movers = static_cast<std::size_t>(std::llround(fraction * n));
        std::vector<std::uint32_t> moved(n);
        std::iota(moved.begin(), moved.end(), 0u);
        std::shuffle(moved.begin(), moved.end(), rng);
        moved.resize(movers);
        std::sort(moved.begin(), moved.end());
        std::uniform_real_distribution<float> step(-0.05f, 0.05f);
        std::uniform_int_distribution<std::uint32_t> pick(0, n - 1);
        std::vector<std::uint32_t> listed;  // the frame's moved list: the movers still here and the gaps filled
        bool ok = true;
        for (int frame = 0; frame < o.warmup + o.frames; ++frame) {
          listed.clear();
          if (frame > 0) {
            if (o.redraw && fraction < 1) {
              for (auto& m : moved) m = pick(rng);
              std::sort(moved.begin(), moved.end());
              moved.erase(std::unique(moved.begin(), moved.end()), moved.end());
            }
            for (const std::uint32_t k : moved) {
              if (k >= w.spheres.size()) continue;  // removed (--remove)
              listed.push_back(k);
              Sphere s = w.spheres[k];
              s.x += step(rng);
              s.z += step(rng);
              w.set(k, s);
            }
            for (std::uint32_t k = 0; k < o.static_moving && k < st.size(); ++k) {
              st[k].x += 0.2f;
              if (st[k].x > w.side) st[k].x = 0;
              for (Detector* d : {d_rebuild.get(), d_compared.get(), d_listed.get()})
                ok &= w.is_box ? d->move_static_box(k, box_of(st[k])).ok() : d->move_static_sphere(k, st[k]).ok();
            }
            // Spawned at the end (the moved list need not name them).
            std::uniform_real_distribution<float> at(0, 1);
            for (std::uint32_t t = 0; t < o.spawn; ++t)
              w.add(Sphere{at(rng) * w.side, at(rng) * w.side * 0.1f, at(rng) * w.side, 0.5f});
            // Removed: the last object into the gap, which the list names.
            for (std::uint32_t t = 0; t < o.remove && w.spheres.size() > 1; ++t) {
              const auto k =
                  static_cast<std::uint32_t>(std::uniform_int_distribution<std::size_t>(0, w.spheres.size() - 1)(rng));
              w.remove(k);
              listed.push_back(k);
            }
            std::sort(listed.begin(), listed.end());
            listed.erase(std::unique(listed.begin(), listed.end()), listed.end());
            while (!listed.empty() && listed.back() >= w.spheres.size()) listed.pop_back();
          } else {
            listed = moved;
          }
          FrameInput in = w.input();
          auto timed = [&](const char* name, Detector& d, FrameResult& f) {
            if (std::find(o.variants.begin(), o.variants.end(), name) == o.variants.end()) return 0.0;
            const auto t0 = Clock::now();
            ok &= d.detect(in, f).ok();
            return ms_since(t0);
          };
          const double a = timed("rebuild", *d_rebuild, fr);
          const double b = timed("compared", *d_compared, fc);
          in.moved = listed;
          in.moved_listed = true;
          const double c = timed("listed", *d_listed, fl);
          if (o.variants.size() == 3 && (fr.pairs != fc.pairs || fr.pairs != fl.pairs)) {
            std::fprintf(stderr, "pairs differ at frame %d\n", frame);
            std::exit(1);
          }
          if (frame >= o.warmup) {
            t_rebuild.push_back(a);
            t_compared.push_back(b);
            t_listed.push_back(c);
          }
        }
        if (!ok) {
          std::fprintf(stderr, "a frame failed\n");
          std::exit(1);
        }
        const double mr = median(t_rebuild), mc = median(t_compared), ml = median(t_listed);
        if (o.stages)
          for (const FrameResult* f : {&fr, &fc, &fl}) {
            std::printf("   stages of the last frame (followed %d):", f->stats.followed_change);
            for (std::size_t s = 0; s < kStageCount; ++s)
              if (f->stats.stage_ms[s] > 0)
                std::printf(" %s %.3f", std::string(stage_name(static_cast<Stage>(s))).c_str(), f->stats.stage_ms[s]);
            std::printf("\n");
          }
        if (fraction >= 1.0) all_moving_ms = mr;
        const double denom = all_moving_ms > 0 ? all_moving_ms : mr;
        const double ar = mean(t_rebuild), ac = mean(t_compared), al = mean(t_listed);
        std::printf("%-6s %9u %7.1f%% %6s | %10.3f %10.3f %10.3f | %9.3f %9.3f %9.3f | %9.3f %9.3f %9.3f | %zu\n",
                    shape.c_str(), n, 100 * fraction, o.redraw ? "redraw" : "fixed", mr, mc, ml, mr / denom, mc / denom,
                    ml / denom, ar / denom, ac / denom, al / denom, fr.pairs.size());
        csv.row({shape, std::to_string(n), std::to_string(fraction), o.redraw ? "redraw" : "fixed", std::to_string(mr),
                 std::to_string(mc), std::to_string(ml), std::to_string(denom), std::to_string(fr.pairs.size()),
                 std::to_string(ar), std::to_string(ac), std::to_string(al)});
        std::fflush(stdout);
      }
    }
  }
}

void run_pile(const Options& o, CsvWriter& csv) {
  std::printf("%9s %7s %7s | %10s %10s %7s | %9s %s\n", "grains", "margin", "jiggle", "rebuild", "follow", "ratio",
              "followed", "pairs");
  for (const std::uint32_t n : o.objects) {
    // A lattice of spacing 1 whose grains (radius 0.5 to 0.52) touch their neighbours a little.
    const auto side = static_cast<std::uint32_t>(std::ceil(std::cbrt(n / 0.25)));
    std::mt19937_64 rng(n);
    std::uniform_real_distribution<float> u(-1, 1);
    std::vector<Sphere> home(n), s(n);
    for (std::uint32_t k = 0; k < n; ++k) {
      const std::uint32_t x = k % side, z = (k / side) % side, y = k / (side * side);
      home[k] = {static_cast<float>(x), static_cast<float>(y), static_cast<float>(z), 0.5f + 0.02f * std::fabs(u(rng))};
    }
    Config rebuild = bench_config(), follow = bench_config();
    rebuild.threads = follow.threads = o.threads;
    rebuild.follow_change = false;
    follow.rest_margin = o.margin;
    follow.move_margin = o.move_margin;
    auto a = make_cpu_detector(rebuild), b = make_cpu_detector(follow);
    FrameResult fa, fb;
    std::vector<double> ta, tb;
    int followed = 0;
    for (int frame = 0; frame < o.warmup + o.frames; ++frame) {
      for (std::uint32_t k = 0; k < n; ++k)
        s[k] = {home[k].x + o.jiggle * u(rng), home[k].y + o.jiggle * u(rng), home[k].z + o.jiggle * u(rng), home[k].r};
      const bool rebuild_too = std::find(o.variants.begin(), o.variants.end(), "rebuild") != o.variants.end();
      auto t0 = Clock::now();
      const bool ok_a = !rebuild_too || a->detect(s, nullptr, fa).ok();
      const double x = ms_since(t0);
      t0 = Clock::now();
      const bool ok_b = b->detect(s, nullptr, fb).ok();
      const double y = ms_since(t0);
      if (!ok_a || !ok_b || (rebuild_too && fa.pairs != fb.pairs)) {
        std::fprintf(stderr, "frame %d: failed or pairs differ\n", frame);
        std::exit(1);
      }
      if (frame >= o.warmup) {
        ta.push_back(x);
        tb.push_back(y);
        followed += fb.stats.followed_change;
      }
    }
    const double ma = median(ta), mb = median(tb);
    if (o.stages)
      for (const FrameResult* f : {&fa, &fb}) {
        std::printf("   stages of the last frame (followed %d):", f->stats.followed_change);
        for (std::size_t st = 0; st < kStageCount; ++st)
          if (f->stats.stage_ms[st] > 0)
            std::printf(" %s %.3f", std::string(stage_name(static_cast<Stage>(st))).c_str(), f->stats.stage_ms[st]);
        std::printf("\n");
      }
    std::printf("%9u %7.3f %7.4f | %10.3f %10.3f %7.2f | %5d/%-3d %zu\n", n, o.margin, o.jiggle, ma, mb, ma / mb,
                followed, o.frames, fa.pairs.size());
    csv.row({std::to_string(n), std::to_string(o.margin), std::to_string(o.jiggle), std::to_string(ma),
             std::to_string(mb), std::to_string(followed), std::to_string(fa.pairs.size())});
    std::fflush(stdout);
  }
}

}  // namespace
}  // namespace viscd::bench

int main(int argc, char** argv) {
  using namespace viscd::bench;
  Options o;
  CLI::App app{"viscd_change_bench: frames in which only some objects move (docs/benchmarks.md)"};
  app.add_flag("--fractions", o.run_fractions, "objects of which a fraction moves; see --fraction");
  app.add_flag("--pile", o.pile, "a settled pile whose grains all jiggle");
  app.add_option("--objects", o.objects, "object counts")->delimiter(',');
  app.add_option("--fraction", o.fractions, "fractions that move each frame (--fractions)")->delimiter(',');
  app.add_option("--shapes", o.shapes, "sphere and/or box (--fractions)")->delimiter(',');
  app.add_flag("--redraw", o.redraw, "a new random set of movers every frame (--fractions)");
  app.add_option("--spawn", o.spawn, "objects added at the end of the array every frame (--fractions)");
  app.add_option("--remove", o.remove, "objects removed every frame, the last one moved into each gap (--fractions)");
  app.add_option("--static", o.statics, "static objects of radius 2 in the slab (--fractions)");
  app.add_option("--static-moving", o.static_moving,
                 "of them, how many glide every frame, as kinematic platforms do (--fractions)");
  app.add_option("--margin", o.margin, "Config::rest_margin (--pile)");
  app.add_option("--rest-margin", o.rest_margin, "Config::rest_margin of the following detectors (--fractions)");
  app.add_option("--move-margin", o.move_margin, "Config::move_margin of the following detectors")
      ->capture_default_str();
  app.add_option("--jiggle", o.jiggle, "how far a grain strays from its place, each axis (--pile)");
  app.add_option("--frames", o.frames, "timed frames");
  app.add_option("--warmup", o.warmup, "untimed frames first");
  app.add_option("--threads", o.threads, "Config::threads (0: all)");
  app.add_option("--variants", o.variants,
                 "which detectors run: rebuild, compared, listed (--fractions); rebuild or not (--pile)")
      ->delimiter(',');
  app.add_flag("--stages", o.stages, "print the stage times of each detector's last frame");
  app.add_option("--csv", o.csv, "also write the table to this CSV file");
  CLI11_PARSE(app, argc, argv);
  if (!o.run_fractions && !o.pile) {
    std::fprintf(stderr, "choose --fractions or --pile\n");
    return 2;
  }
  if (o.pile) {
    CsvWriter csv(o.csv, {"grains", "margin", "jiggle", "rebuild_ms", "follow_ms", "followed", "pairs"});
    run_pile(o, csv);
  } else {
    CsvWriter csv(o.csv, {"shape", "objects", "fraction", "mode", "rebuild_ms", "compared_ms", "listed_ms",
                          "all_moving_ms", "pairs", "rebuild_mean_ms", "compared_mean_ms", "listed_mean_ms"});
    run_fractions(o, csv);
  }
  return 0;
}
