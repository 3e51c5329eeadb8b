// viscd_follow_soak: long random sequences of frames on a cpu detector that follows change
// (Config::follow_change) against one that rebuilds every frame, at the sizes where the followed
// path merges its candidates in chunks, packs them, rebuilds its main tree and gives up and comes
// back (thousands to tens of thousands of objects; the libFuzzer target fuzz_sequence covers up
// to 40). Each round draws a configuration (spheres or boxes, rest and own margins, the moved list
// given or not, filters, never-culled flags, a camera that culls, a static set, the executor) and
// a scene, then runs phases of a few frames each: nothing moves, objects jiggle inside or past the
// margin, glide, jump, gather into a cluster, scatter far apart, new movers every frame, everything
// moves; now and then the object count changes, filters and flags change, static objects come,
// move and go, a few objects are spawned at the end or removed (the last one into the gap), a frame
// holds a NaN.
//
// Checks, every frame: both detectors succeed or fail alike (a failure with the same message);
// their pairs, states, pixels and contact events are equal; a few queries answer alike; with few
// objects the pairs also equal a brute force written here. The moved list, when given, is the
// objects whose bounds differ bit for bit from the last successful frame's, with some unchanged
// ones added (allowed). On a mismatch it prints the round's seed and configuration, the frame and
// the first difference, and exits with 1; `--seed S --rounds 1` with that seed replays the round.
//
// Usage: viscd_follow_soak [--seed S] [--rounds R] [--seconds T] [--max-objects N] [--verbose]
//   ctest runs a fixed set of rounds (tests/CMakeLists.txt); --seconds runs rounds until the time
//   is spent (docs/robustness.md, "Soak runs of the followed frames").

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <initializer_list>
#include <limits>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "viscd/viscd.hpp"

namespace {

using namespace viscd;

// Runs tasks last first on the calling thread and says it has four threads: the detector then
// cuts its work into more chunks than two threads would, and no output may depend on their order.
class BackwardsExecutor final : public Executor {
 public:
  [[nodiscard]] int concurrency() const override { return 4; }
  void run(std::uint32_t count, TaskRef task) override {
    for (std::uint32_t i = count; i-- > 0;) task(i);
  }
};

struct Round {
  std::uint64_t seed = 0;
  bool boxes = false;
  float rest_margin = 0, move_margin = 8;
  bool listed = false, verify = false, filters = false, always = false, camera = false;
  int executor = 0;  // 0 viscd's pool, 1 one thread, 2 backwards on four
  std::size_t n = 0, statics = 0;
  int scene = 0;  // 0 a sparse slab, 1 a touching lattice, 2 a dense cluster
  int frames = 0;
};

std::string describe(const Round& r) {
  char buf[320];
  std::snprintf(buf, sizeof buf,
                "seed %llu: %s, n %zu, scene %s, rest_margin %g, move_margin %g, %s%s%s%s%s, %zu static, "
                "executor %s, %d frames",
                static_cast<unsigned long long>(r.seed), r.boxes ? "boxes" : "spheres", r.n,
                r.scene == 0   ? "slab"
                : r.scene == 1 ? "lattice"
                               : "cluster",
                static_cast<double>(r.rest_margin), static_cast<double>(r.move_margin),
                r.listed ? "listed" : "compared", r.verify ? " verify_moved" : "", r.filters ? ", filters" : "",
                r.always ? ", never-culled" : "", r.camera ? ", camera" : "", r.statics,
                r.executor == 0   ? "pool"
                : r.executor == 1 ? "one thread"
                                  : "backwards",
                r.frames);
  return buf;
}

// One of `list`, each as likely.
template <class T>
T pick_one(std::mt19937_64& rng, std::initializer_list<T> list) {
  return list.begin()[std::uniform_int_distribution<std::size_t>(0, list.size() - 1)(rng)];
}

Round draw_round(std::uint64_t seed, std::size_t max_objects) {
  std::mt19937_64 rng(seed);
  auto pick = [&]<class T>(std::initializer_list<T> list) { return pick_one(rng, list); };
  auto chance = [&](double p) { return std::uniform_real_distribution<double>(0, 1)(rng) < p; };
  Round r;
  r.seed = seed;
  r.boxes = chance(0.5);
  r.rest_margin = pick({0.0f, 0.0f, 0.01f, 0.05f, 0.2f});
  r.move_margin = pick({8.0f, 8.0f, 0.0f, 2.0f});
  r.listed = chance(0.5);
  r.verify = r.listed && chance(0.25);
  r.filters = chance(0.3);
  r.always = chance(0.2);
  r.camera = chance(0.2);
  r.executor = pick({0, 0, 1, 2});
  r.n = std::min(max_objects,
                 pick(std::initializer_list<std::size_t>{0, 1, 2, 3, 17, 200, 1500, 5000, 5000, 12000, 12000, 25000}));
  r.statics = pick(std::initializer_list<std::size_t>{0, 0, 40, 400});
  r.scene = pick({0, 0, 1, 2});
  r.frames = pick({25, 40, 60});
  return r;
}

Box box_of(const Sphere& s) { return Box{{s.x - s.r, s.y - s.r, s.z - s.r}, {s.x + s.r, s.y + s.r, s.z + s.r}}; }

bool same_bits(const Sphere& a, const Sphere& b) { return std::memcmp(&a, &b, sizeof a) == 0; }

// The pairs of the active moving objects and with the static set, filters applied (few objects).
std::vector<Pair> brute_pairs(const std::vector<Sphere>& s, bool boxes, const std::vector<ObjectState>& state,
                              const std::vector<Filter>& filters, const std::vector<Sphere>& stat,
                              const std::vector<std::uint8_t>& stat_live, const std::vector<Filter>& stat_filters) {
  auto f = [&](std::size_t k) { return filters.empty() ? Filter{} : filters[k]; };
  auto meet = [&](const Sphere& a, const Sphere& b) {
    return boxes ? boxes_overlap(box_of(a), box_of(b)) : spheres_overlap(a, b);
  };
  std::vector<Pair> out;
  for (std::size_t i = 0; i < s.size(); ++i) {
    if (state[i] == ObjectState::culled) continue;
    for (std::size_t j = i + 1; j < s.size(); ++j)
      if (state[j] != ObjectState::culled && meet(s[i], s[j]) && pair_passes_filter(f(i), f(j)))
        out.push_back({static_cast<std::uint32_t>(i), static_cast<std::uint32_t>(j)});
    for (std::size_t k = 0; k < stat.size(); ++k)
      if (stat_live[k] && meet(s[i], stat[k]) && pair_passes_filter(f(i), stat_filters[k]))
        out.push_back({static_cast<std::uint32_t>(i), static_index(static_cast<std::uint32_t>(k))});
  }
  std::sort(out.begin(), out.end());
  return out;
}

// The first difference of two pair lists, for the report.
std::string first_difference(const std::vector<Pair>& a, const std::vector<Pair>& b) {
  std::size_t k = 0;
  while (k < a.size() && k < b.size() && a[k] == b[k]) ++k;
  char buf[160];
  auto at = [](const std::vector<Pair>& v, std::size_t t) {
    return t < v.size() ? "(" + std::to_string(v[t].i) + "," + std::to_string(v[t].j) + ")" : std::string("end");
  };
  std::snprintf(buf, sizeof buf, "%zu against %zu pairs; first difference at %zu: %s against %s", a.size(), b.size(), k,
                at(a, k).c_str(), at(b, k).c_str());
  return buf;
}

class Soak {
 public:
  Soak(const Round& r, bool verbose) : r_(r), verbose_(verbose), rng_(r.seed * 0x9E3779B97F4A7C15ull + 1) {}

  // Runs the round; false (after printing why) on a mismatch.
  bool run() {
    Config on;
    on.follow_change = true;
    on.rest_margin = r_.rest_margin;
    on.move_margin = r_.move_margin;
    on.verify_moved = r_.verify;
    on.contact_events = true;
    on.lambda = 4;
    on.report_pixels = r_.camera;
    if (r_.executor == 1) on.threads = 1;
    if (r_.executor == 2) on.executor = &backwards_;
    Config off = on;
    off.follow_change = false;
    follows_ = make_cpu_detector(on);
    rebuilds_ = make_cpu_detector(off);

    extent_ = 20.0f * std::cbrt(std::max<float>(1.0f, static_cast<float>(r_.n)) / 5000.0f);
    objects_.resize(r_.n);
    for (std::size_t k = 0; k < r_.n; ++k) objects_[k] = placed(k);
    if (r_.filters) filters_.resize(r_.n);
    for (auto& f : filters_) f = random_filter();
    if (r_.always) always_.assign(r_.n, 0);
    for (std::size_t k = 0; k < r_.statics; ++k)
      if (!add_static()) return false;

    int phase = 0, phase_left = 0;
    for (frame_ = 0; frame_ < r_.frames; ++frame_) {
      if (phase_left-- <= 0) {
        phase = static_cast<int>(index_below(8));
        phase_left = static_cast<int>(uniform(2, 9));
        fraction_ = pick_fraction(phase);
        gliders_.clear();
        for (std::size_t k = 0; k < objects_.size(); ++k)
          if (chance(fraction_)) gliders_.push_back(static_cast<std::uint32_t>(k));
        velocity_ = std::uniform_real_distribution<float>(0.002f, 0.12f)(rng_);
      }
      if (frame_ > 0) move(phase);
      if (!occasional()) return false;
      if (!check_frame()) return false;
    }
    if (verbose_)
      std::printf("  %s: %d of %d frames followed, %d failed alike\n", describe(r_).c_str(), followed_, r_.frames,
                  failed_alike_);
    std::fflush(stdout);
    return true;
  }

  [[nodiscard]] int followed() const { return followed_; }

 private:
  float uniform(float lo, float hi) { return std::uniform_real_distribution<float>(lo, hi)(rng_); }
  bool chance(double p) { return std::uniform_real_distribution<double>(0, 1)(rng_) < p; }
  std::size_t index_below(std::size_t n) { return std::uniform_int_distribution<std::size_t>(0, n - 1)(rng_); }

  Filter random_filter() {
    if (chance(0.6)) return Filter{};
    return Filter{1u << index_below(3), chance(0.5) ? 0x5u : 0x3u};
  }

  // Object k where the scene puts it.
  Sphere placed(std::size_t k) {
    switch (r_.scene) {
      case 1: {  // a lattice of touching grains, 30 wide and 30 deep
        const float x = static_cast<float>(k % 30), z = static_cast<float>((k / 30) % 30),
                    y = static_cast<float>(k / 900);
        return Sphere{x, y, z, 0.5f};
      }
      case 2:  // a dense cluster: many pairs per object
        return Sphere{uniform(-1, 1) * extent_ * 0.25f, uniform(-1, 1) * extent_ * 0.25f,
                      uniform(-1, 1) * extent_ * 0.25f, uniform(0.3f, 1.0f)};
      default:  // a slab with a neighbour or two each
        return Sphere{uniform(-1, 1) * extent_, uniform(-1, 1) * extent_ * 0.2f, uniform(-1, 1) * extent_,
                      uniform(0.1f, 0.9f)};
    }
  }

  float pick_fraction(int phase) {
    static constexpr float kFractions[] = {0.001f, 0.01f, 0.05f, 0.15f, 0.3f, 0.6f, 1.0f};
    if (phase == 0) return 0;
    if (phase == 6) return 1;
    if (phase == 7) return kFractions[2 + index_below(2)];  // 1 in 20 or 1 in 7 a frame
    return kFractions[index_below(6)];
  }

  // Moves objects as the phase says.
  void move(int phase) {
    const float m = std::max(r_.rest_margin, 0.01f);
    switch (phase) {
      case 1:  // jiggle: inside the margin mostly, past it now and then
        for (const std::uint32_t k : gliders_) {
          if (k >= objects_.size()) continue;
          const float a = chance(0.9) ? 0.3f * m : 2.0f * m;
          objects_[k].x += uniform(-a, a);
          objects_[k].y += uniform(-a, a);
        }
        break;
      case 2:  // glide: the same objects at a steady velocity (margins of their own)
        for (const std::uint32_t k : gliders_)
          if (k < objects_.size()) objects_[k].x += velocity_;
        break;
      case 3:  // jump anywhere
        for (const std::uint32_t k : gliders_)
          if (k < objects_.size()) objects_[k] = placed(k);
        break;
      case 4:  // gather: a step at a time into a cluster about the origin, a third of the
               // world's size (no tighter: a few pairs each, not all of them with all)
        for (const std::uint32_t k : gliders_)
          if (k < objects_.size()) {
            Sphere& s = objects_[k];
            const float d = std::max({std::fabs(s.x), std::fabs(s.y), std::fabs(s.z)});
            if (d > extent_ / 3) {
              s.x *= 0.8f;
              s.y *= 0.8f;
              s.z *= 0.8f;
            }
          }
        break;
      case 5:  // new movers every frame, a step each
        for (std::size_t k = 0; k < objects_.size(); ++k)
          if (chance(fraction_)) {
            objects_[k].x += uniform(-0.5f, 0.5f);
            objects_[k].z += uniform(-0.5f, 0.5f);
            if (chance(0.1)) objects_[k].r = std::max(0.0f, objects_[k].r + uniform(-0.2f, 0.2f));
          }
        break;
      case 7:  // scatter: new ones every frame, each far from everything (the candidates thin out
               // until the merge packs them into fewer chunks)
        for (std::size_t k = 0; k < objects_.size(); ++k)
          if (chance(fraction_)) objects_[k] = Sphere{1000.0f + 4.0f * static_cast<float>(k), 0, 0, 0.5f};
        break;
      case 6:  // everything moves a little
        for (auto& s : objects_) {
          s.x += uniform(-0.05f, 0.05f);
          s.z += uniform(-0.05f, 0.05f);
        }
        break;
      default:  // at rest
        break;
    }
  }

  bool add_static() {
    const Sphere s = placed(index_below(std::max<std::size_t>(1, r_.n)));
    const Filter f = chance(0.8) ? Filter{} : Filter{2, 2};
    Result<std::uint32_t> a = r_.boxes ? follows_->add_static_box(box_of(s), f) : follows_->add_static_sphere(s, f);
    Result<std::uint32_t> b = r_.boxes ? rebuilds_->add_static_box(box_of(s), f) : rebuilds_->add_static_sphere(s, f);
    if (!a.ok() || !b.ok() || a.value() != b.value()) return fail("add_static: the detectors disagree");
    const std::uint32_t k = a.value();
    if (stat_.size() <= k) {
      stat_.resize(k + 1);
      stat_live_.resize(k + 1, 0);
      stat_filters_.resize(k + 1);
    }
    stat_[k] = s;
    stat_live_[k] = 1;
    stat_filters_[k] = f;
    return true;
  }

  // The count, filters, flags, the static set and the camera, now and then.
  bool occasional() {
    if (frame_ > 0 && chance(0.06) && !objects_.empty()) {
      const std::size_t n = objects_.size();
      const std::size_t m = chance(0.5) ? n - n / 10 - (n > 0 ? 1 : 0) : n + n / 10 + 1;
      objects_.resize(m);
      for (std::size_t k = n; k < m; ++k) objects_[k] = placed(k);
      if (r_.filters) filters_.resize(m, Filter{});
      if (r_.always) always_.resize(m, 0);
    }
    if (frame_ > 0 && chance(0.15)) {  // a few spawned at the end
      const std::size_t n = objects_.size(), m = n + 1 + index_below(20);
      objects_.resize(m);
      for (std::size_t k = n; k < m; ++k) objects_[k] = placed(k);
      if (r_.filters) filters_.resize(m, Filter{});
      if (r_.always) always_.resize(m, 0);
    }
    if (frame_ > 0 && chance(0.15)) {  // a few removed as engines remove them: the last one into the gap
      for (std::size_t t = 1 + index_below(20); t > 0 && objects_.size() > 1; --t) {
        const std::size_t k = index_below(objects_.size());
        objects_[k] = objects_.back();
        objects_.pop_back();
        if (r_.filters) {
          filters_[k] = filters_.back();
          filters_.pop_back();
        }
        if (r_.always) {
          always_[k] = always_.back();
          always_.pop_back();
        }
      }
    }
    if (r_.filters && chance(0.1))
      for (int t = 0; t < 20 && !filters_.empty(); ++t) filters_[index_below(filters_.size())] = random_filter();
    if (r_.always && chance(0.15))
      for (int t = 0; t < 30 && !always_.empty(); ++t) always_[index_below(always_.size())] ^= 1;
    if (r_.statics > 0 && chance(0.1)) {
      const std::uint32_t k = static_cast<std::uint32_t>(index_below(stat_.size()));
      const int what = static_cast<int>(index_below(3));
      if (what == 0 || !stat_live_[k]) {
        if (!add_static()) return false;
      } else if (what == 1) {
        const Sphere s = placed(index_below(std::max<std::size_t>(1, r_.n)));
        const Status a = r_.boxes ? follows_->move_static_box(k, box_of(s)) : follows_->move_static_sphere(k, s);
        const Status b = r_.boxes ? rebuilds_->move_static_box(k, box_of(s)) : rebuilds_->move_static_sphere(k, s);
        if (!a.ok() || !b.ok()) return fail("move_static: " + a.error() + " / " + b.error());
        stat_[k] = s;
      } else {
        if (!follows_->remove_static(k).ok() || !rebuilds_->remove_static(k).ok()) return fail("remove_static failed");
        stat_live_[k] = 0;
      }
    }
    if (r_.camera && chance(0.1)) camera_on_ = !camera_on_;
    return true;
  }

  bool fail(const std::string& why) {
    std::fprintf(stderr, "viscd_follow_soak: %s\n  round %s\n  frame %d\n", why.c_str(), describe(r_).c_str(), frame_);
    return false;
  }

  bool check_frame() {
    const std::size_t n = objects_.size();
    // Now and then a NaN in one object, for this frame alone: both must refuse the frame alike.
    std::size_t nan_at = n;
    Sphere kept{};
    if (n > 0 && chance(0.03)) {
      nan_at = index_below(n);
      kept = objects_[nan_at];
      objects_[nan_at].y = std::numeric_limits<float>::quiet_NaN();
    }
    std::vector<Box> bx;
    if (r_.boxes) {
      bx.resize(n);
      for (std::size_t k = 0; k < n; ++k) bx[k] = box_of(objects_[k]);
    }
    // The moved list: what differs from the last successful frame, plus some unchanged objects.
    moved_.clear();
    const std::size_t common = std::min(n, last_ok_.size());
    for (std::size_t k = 0; k < common; ++k)
      if (!same_bits(objects_[k], last_ok_[k]) || chance(0.002)) moved_.push_back(static_cast<std::uint32_t>(k));

    Camera cam;
    cam.width = 160;
    cam.height = 120;
    cam.eye[0] = extent_ * std::sin(0.07f * static_cast<float>(frame_));
    cam.eye[1] = extent_ * 1.5f;
    cam.eye[2] = extent_ * std::cos(0.07f * static_cast<float>(frame_));
    FrameInput in;
    if (r_.boxes)
      in.boxes = bx;
    else
      in.spheres = objects_;
    if (r_.camera && camera_on_) in.camera = &cam;
    in.filters = filters_;
    in.always_active = always_;
    if (r_.listed) {
      in.moved = moved_;
      in.moved_listed = true;
    }
    const Status sa = follows_->detect(in, fa_);
    in.moved = {};
    in.moved_listed = false;
    const Status sb = rebuilds_->detect(in, fb_);
    if (nan_at < n) objects_[nan_at] = kept;
    if (sa.ok() != sb.ok() || sa.kind() != sb.kind() || sa.error() != sb.error())
      return fail("the statuses differ: \"" + sa.error() + "\" against \"" + sb.error() + "\"");
    if (!sa.ok()) {
      if (nan_at == n) return fail("a frame without a NaN failed: " + sa.error());
      ++failed_alike_;
      return true;  // a failed frame changes nothing: the next one is compared with the last good one
    }
    if (nan_at < n) return fail("a frame with a NaN object succeeded");
    last_ok_ = objects_;
    followed_ += fa_.stats.followed_change;
    if (fa_.pairs != fb_.pairs) return fail("pairs: " + first_difference(fa_.pairs, fb_.pairs));
    if (fa_.state != fb_.state) return fail("the states differ");
    if (fa_.pixels != fb_.pixels) return fail("the pixels differ");
    if (fa_.began != fb_.began) return fail("began: " + first_difference(fa_.began, fb_.began));
    if (fa_.ended != fb_.ended) return fail("ended: " + first_difference(fa_.ended, fb_.ended));
    if (n <= 1500) {
      const std::vector<Pair> want =
          brute_pairs(objects_, r_.boxes, fb_.state, filters_, stat_, stat_live_, stat_filters_);
      if (fa_.pairs != want) return fail("against brute force: " + first_difference(fa_.pairs, want));
    }
    return check_queries();
  }

  bool check_queries() {
    const Filter qf{1, 0x3};
    for (int q = 0; q < 3; ++q) {
      const Sphere at = placed(index_below(std::max<std::size_t>(1, r_.n)));
      std::vector<std::uint32_t> ia, ib;
      follows_->overlap(Sphere{at.x, at.y, at.z, 1.5f}, ia);
      rebuilds_->overlap(Sphere{at.x, at.y, at.z, 1.5f}, ib);
      if (ia != ib) return fail("overlap queries differ");
      follows_->overlap_box(box_of(Sphere{at.x, at.y, at.z, 1.0f}), ia, &qf);
      rebuilds_->overlap_box(box_of(Sphere{at.x, at.y, at.z, 1.0f}), ib, &qf);
      if (ia != ib) return fail("overlap_box queries differ");
      const Ray ray{{at.x, extent_ + 5, at.z}, {uniform(-0.2f, 0.2f), -1, uniform(-0.2f, 0.2f)}, 1000};
      std::vector<RayHit> ha, hb;
      follows_->ray_cast_all(ray, ha);
      rebuilds_->ray_cast_all(ray, hb);
      if (ha.size() != hb.size()) return fail("ray_cast_all differs");
      for (std::size_t k = 0; k < ha.size(); ++k)
        if (ha[k].index != hb[k].index || ha[k].t != hb[k].t) return fail("ray_cast_all differs");
    }
    return true;
  }

  Round r_;
  bool verbose_;
  std::mt19937_64 rng_;
  BackwardsExecutor backwards_;
  std::unique_ptr<Detector> follows_, rebuilds_;
  float extent_ = 1;
  std::vector<Sphere> objects_, last_ok_;
  std::vector<Filter> filters_;
  std::vector<std::uint8_t> always_;
  std::vector<Sphere> stat_;
  std::vector<std::uint8_t> stat_live_;
  std::vector<Filter> stat_filters_;
  std::vector<std::uint32_t> gliders_, moved_;
  float fraction_ = 0, velocity_ = 0;
  bool camera_on_ = true;
  int frame_ = 0, followed_ = 0, failed_alike_ = 0;
  FrameResult fa_, fb_;
};

constexpr const char* kUsage =
    "usage: viscd_follow_soak [--seed S] [--rounds R] [--seconds T] [--max-objects N] [--verbose]\n"
    "  Random rounds of frames: a cpu detector that follows change against one that rebuilds every\n"
    "  frame, and a brute force up to 1 500 objects. Round k uses seed S + k (default S = 1, R = 8);\n"
    "  with --seconds, rounds run until T seconds have passed (R, if given, still bounds them).\n"
    "  --max-objects caps each round's object count (default 25000); --verbose prints each round.\n"
    "  Exits 0 when every round passed, 1 on the first mismatch (its seed, configuration, frame and\n"
    "  first difference on stderr; --seed <that seed> --rounds 1 replays it), 2 on a bad argument.\n";

int usage(const std::string& why) {
  std::fprintf(stderr, "viscd_follow_soak: %s\n%s", why.c_str(), kUsage);
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  std::uint64_t seed = 1;
  long rounds = -1;
  double seconds = 0;
  std::size_t max_objects = 25000;
  bool verbose = false;
  for (int a = 1; a < argc; ++a) {
    const std::string arg = argv[a];
    auto value = [&]() -> const char* { return a + 1 < argc ? argv[++a] : nullptr; };
    const char* v = nullptr;
    char* end = nullptr;
    if (arg == "--verbose") {
      verbose = true;
    } else if (arg == "--seed" || arg == "--rounds" || arg == "--seconds" || arg == "--max-objects") {
      if (!(v = value())) return usage(arg + " needs a value");
      const double x = std::strtod(v, &end);
      if (end == v || *end != '\0' || !(x >= 0) || x > 1e15) return usage(arg + ": not a number >= 0: " + v);
      if (arg != "--seconds" && x != std::floor(x)) return usage(arg + ": not a whole number: " + v);
      if (arg == "--seed") seed = static_cast<std::uint64_t>(x);
      if (arg == "--rounds") rounds = static_cast<long>(x);
      if (arg == "--seconds") seconds = x;
      if (arg == "--max-objects") max_objects = static_cast<std::size_t>(x);
    } else if (arg == "-h" || arg == "--help") {
      std::fputs(kUsage, stdout);
      return 0;
    } else {
      return usage("unknown argument " + arg);
    }
  }
  if (rounds < 0) rounds = seconds > 0 ? std::numeric_limits<long>::max() : 8;
  const auto start = std::chrono::steady_clock::now();
  auto elapsed = [&] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(); };
  long done = 0, followed = 0;
  for (long k = 0; k < rounds; ++k) {
    if (seconds > 0 && elapsed() >= seconds) break;
    const Round r = draw_round(seed + static_cast<std::uint64_t>(k), max_objects);
    Soak soak(r, verbose);
    if (!soak.run()) return 1;
    ++done;
    followed += soak.followed();
  }
  std::printf("viscd_follow_soak: %ld rounds from seed %llu passed in %.1f s (%ld frames followed)\n", done,
              static_cast<unsigned long long>(seed), elapsed(), followed);
  return 0;
}
