// Boxes and the static set on the cpu backend (docs/benchmarks.md, "Boxes and the static set"):
//   static   a frame of M moving spheres alone, and with a static set of S spheres around them
//            (the moving ones move every frame; the static set is handed over once);
//   churn    building the static set (set_static + the first frame) against moving 1 % of it
//            (move_static + the next frame), each minus the frame of the moving objects alone;
//   boxes    N dense boxes against N dense spheres of the same density (each box the sphere's
//            cube, scaled to the sphere's volume), the box pairs checked by a sweep along x.
// Each is timed interleaved, repeated, and reported as medians (milliseconds).
#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include "viscd/viscd.hpp"

namespace {

using Clock = std::chrono::steady_clock;
double ms_since(Clock::time_point t) { return std::chrono::duration<double, std::milli>(Clock::now() - t).count(); }
double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : v[v.size() / 2];
}

// n spheres in a cube sized so that each meets about `pairs_per_object` others.
std::vector<viscd::Sphere> dense(std::size_t n, std::uint64_t seed, float r, double pairs_per_object, float dz = 0) {
  // Expected pairs per object = density * volume of a sphere of radius 2r (centres within 2r).
  const double volume = 4.0 / 3.0 * 3.14159265358979 * std::pow(2.0 * r, 3.0);
  const double side = std::cbrt(static_cast<double>(n) * volume / (2.0 * pairs_per_object));
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> u(0.0f, static_cast<float>(side));
  std::vector<viscd::Sphere> s(n);
  for (auto& x : s) x = {u(rng), u(rng), u(rng) + dz, r};
  return s;
}

void move_all(std::vector<viscd::Sphere>& s, std::mt19937_64& rng, float step) {
  std::uniform_real_distribution<float> d(-step, step);
  for (auto& x : s) x.x += d(rng), x.y += d(rng), x.z += d(rng);
}

void check(const viscd::Status& s) {
  if (!s) {
    std::fprintf(stderr, "viscd_shapes_bench: %s\n", s.error().c_str());
    std::exit(1);
  }
}

// Box pairs by a sweep along x: sort by min x, then each box against the boxes starting before its
// max x. Independent of the library.
std::size_t sweep_pairs(const std::vector<viscd::Box>& b) {
  std::vector<std::uint32_t> order(b.size());
  for (std::uint32_t k = 0; k < b.size(); ++k) order[k] = k;
  std::sort(order.begin(), order.end(), [&](auto x, auto y) { return b[x].min[0] < b[y].min[0]; });
  std::size_t pairs = 0;
  for (std::size_t a = 0; a < order.size(); ++a)
    for (std::size_t c = a + 1; c < order.size() && b[order[c]].min[0] <= b[order[a]].max[0]; ++c) {
      const auto& p = b[order[a]];
      const auto& q = b[order[c]];
      pairs += p.min[1] <= q.max[1] && q.min[1] <= p.max[1] && p.min[2] <= q.max[2] && q.min[2] <= p.max[2];
    }
  return pairs;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"viscd_shapes_bench: boxes and the static set on the cpu backend"};
  std::size_t moving = 10000, statics = 1000000, boxes_n = 100000;
  int frames = 20, repeats = 5;
  app.add_option("--moving", moving, "moving objects in the static case");
  app.add_option("--static", statics, "static objects");
  app.add_option("--boxes", boxes_n, "objects in the boxes-against-spheres case");
  app.add_option("--frames", frames, "frames per timing");
  app.add_option("--repeats", repeats, "interleaved repeats (medians reported)");
  CLI11_PARSE(app, argc, argv);

  std::mt19937_64 rng(7);
  // ---- static: M moving spheres alone, and among S static ones spread over the same ground ----
  const std::vector<viscd::Sphere> field = dense(statics, 1, 0.5f, 0.3);
  std::vector<viscd::Sphere> mov = dense(moving, 2, 0.5f, 0.6);
  auto alone = viscd::make_cpu_detector();
  auto with = viscd::make_cpu_detector();
  check(with->set_static_spheres(field));
  viscd::FrameResult out;
  check(with->detect(mov, nullptr, out));  // builds the static trees
  std::vector<double> t_alone, t_with;
  std::uint64_t static_pairs = 0;
  for (int r = 0; r < repeats; ++r)
    for (int which = 0; which < 2; ++which) {
      viscd::Detector& d = which ? *with : *alone;
      std::vector<viscd::Sphere> m = mov;
      std::mt19937_64 steps(11);
      const auto t = Clock::now();
      for (int f = 0; f < frames; ++f) {
        move_all(m, steps, 0.05f);
        check(d.detect(m, nullptr, out));
        if (which) static_pairs = out.pairs.size();
      }
      (which ? t_with : t_alone).push_back(ms_since(t) / frames);
    }
  std::printf("static: %zu moving alone %.3f ms/frame; with %zu static %.3f ms/frame (%.2fx); %llu pairs\n", moving,
              median(t_alone), statics, median(t_with), median(t_with) / median(t_alone),
              static_cast<unsigned long long>(static_pairs));

  // ---- churn: build the set vs move 1 % of it (each with one frame of the moving objects) ----
  std::vector<double> t_build, t_move;
  for (int r = 0; r < repeats; ++r) {
    auto d = viscd::make_cpu_detector();
    auto t = Clock::now();
    check(d->set_static_spheres(field));
    check(d->detect(mov, nullptr, out));
    t_build.push_back(ms_since(t));
    std::uniform_int_distribution<std::uint32_t> pick(0, static_cast<std::uint32_t>(statics - 1));
    std::uniform_real_distribution<float> step(-1.0f, 1.0f);
    t = Clock::now();
    for (std::size_t k = 0; k < statics / 100; ++k) {
      const std::uint32_t s = pick(rng);
      viscd::Sphere x = field[s];
      x.x += step(rng), x.y += step(rng);
      check(d->move_static_sphere(s, x));
    }
    check(d->detect(mov, nullptr, out));
    t_move.push_back(ms_since(t));
  }
  const double frame = median(t_alone);
  std::printf("churn: build %zu static %.2f ms, move 1%% %.2f ms (%.3f of the build; frame alone %.3f ms)\n", statics,
              median(t_build), median(t_move), (median(t_move) - frame) / (median(t_build) - frame), frame);

  // ---- boxes against spheres at the same density ----
  const std::vector<viscd::Sphere> sph = dense(boxes_n, 3, 0.5f, 0.6);
  std::vector<viscd::Box> box(boxes_n);
  // A cube of the sphere's volume: side r cbrt(4 pi / 3), half of it each way.
  const float h = 0.5f * sph.front().r * std::cbrt(4.0f / 3.0f * 3.14159265f);
  for (std::size_t k = 0; k < boxes_n; ++k)
    box[k] = viscd::Box{{sph[k].x - h, sph[k].y - h, sph[k].z - h}, {sph[k].x + h, sph[k].y + h, sph[k].z + h}};
  auto ds = viscd::make_cpu_detector(), db = viscd::make_cpu_detector();
  std::vector<double> t_s, t_b;
  std::size_t box_pairs = 0, sphere_pairs = 0;
  viscd::FrameInput in;
  for (int r = 0; r < repeats; ++r)
    for (int which = 0; which < 2; ++which) {
      std::vector<viscd::Sphere> s = sph;
      std::vector<viscd::Box> b = box;
      std::mt19937_64 steps(13);
      const auto t = Clock::now();
      for (int f = 0; f < frames; ++f) {
        if (which) {
          std::uniform_real_distribution<float> d(-0.05f, 0.05f);
          for (auto& x : b) {
            const float dx = d(steps), dy = d(steps), dz = d(steps);
            x.min[0] += dx, x.max[0] += dx, x.min[1] += dy, x.max[1] += dy, x.min[2] += dz, x.max[2] += dz;
          }
          in = {};
          in.boxes = b;
          check(db->detect(in, out));
          box_pairs = out.pairs.size();
        } else {
          move_all(s, steps, 0.05f);
          check(ds->detect(s, nullptr, out));
          sphere_pairs = out.pairs.size();
        }
      }
      (which ? t_b : t_s).push_back(ms_since(t) / frames);
      if (which && r == 0 && sweep_pairs(b) != box_pairs) {
        std::fprintf(stderr, "viscd_shapes_bench: box pairs %zu, the sweep finds %zu\n", box_pairs, sweep_pairs(b));
        return 1;
      }
    }
  std::printf("boxes: %zu dense spheres %.3f ms/frame (%zu pairs); boxes %.3f ms/frame (%zu pairs, checked); %.2fx\n",
              boxes_n, median(t_s), sphere_pairs, median(t_b), box_pairs, median(t_b) / median(t_s));
  return 0;
}
