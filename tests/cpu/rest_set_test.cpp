// Cost follows change (Config::follow_change, cpu/rest_set.hpp): sequences of frames in which
// objects start and stop moving, jiggle inside their fat bounds, jump out of them, appear and
// vanish, change filters and never-culled flags, while the camera moves and the static set
// changes. Every frame is checked against a brute-force oracle written here (pairs of the active
// objects, filters, static pairs) and against a cpu detector that rebuilds every frame (states,
// pixels, contact events, queries), and the followed path must have run.

#include <gtest/gtest.h>

#include <algorithm>
#include <limits>
#include <memory>
#include <numeric>
#include <optional>
#include <random>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "cpu/cpu_detector.hpp"
#include "test_util.hpp"
#include "viscd/viscd.hpp"

namespace viscd {
namespace {

struct Scenario {
  bool boxes = false;
  float margin = 0;
  float move_margin = Config{}.move_margin;  // margins of their own for movers
  bool listed = false;                       // FrameInput::moved names the movers
  bool with_static = false;
  bool camera = false;  // culling by the detector's own map
  bool filters = false;
  bool always_active = false;
  bool resize = false;  // N changes now and then
  float move_fraction = 0.03f;
  std::size_t n = 600;
  int frames = 40;
  std::uint64_t seed = 1;
};

Box box_of(const Sphere& s) { return Box{{s.x - s.r, s.y - s.r, s.z - s.r}, {s.x + s.r, s.y + s.r, s.z + s.r}}; }

// n spheres of radius 0.5 in a slab 60 wide and 12 deep (about one neighbour each at 40 000).
std::vector<Sphere> slab_of(std::size_t n, std::mt19937_64& rng) {
  std::uniform_real_distribution<float> u(-30, 30);
  std::vector<Sphere> s(n);
  for (auto& x : s) x = {u(rng), u(rng), u(rng) * 0.2f, 0.5f};
  return s;
}

// The oracle: pairs of the active moving objects (by the exact tests), and of each active moving
// object with each static object, filters applied, sorted.
std::vector<Pair> oracle(const std::vector<Sphere>& sph, const std::vector<Box>& bx, bool boxes,
                         const std::vector<ObjectState>& state, const std::vector<Filter>& filters,
                         const std::vector<Sphere>& st_sph, const std::vector<Box>& st_bx,
                         const std::vector<Filter>& st_filters) {
  const std::size_t n = boxes ? bx.size() : sph.size();
  auto f = [&](std::size_t k) { return filters.empty() ? Filter{} : filters[k]; };
  std::vector<Pair> out;
  for (std::size_t i = 0; i < n; ++i) {
    if (state[i] == ObjectState::culled) continue;
    for (std::size_t j = i + 1; j < n; ++j) {
      if (state[j] == ObjectState::culled) continue;
      const bool hit = boxes ? boxes_overlap(bx[i], bx[j]) : spheres_overlap(sph[i], sph[j]);
      if (hit && pair_passes_filter(f(i), f(j)))
        out.push_back({static_cast<std::uint32_t>(i), static_cast<std::uint32_t>(j)});
    }
    const std::size_t sn = boxes ? st_bx.size() : st_sph.size();
    for (std::size_t k = 0; k < sn; ++k) {
      const bool hit = boxes ? boxes_overlap(bx[i], st_bx[k]) : spheres_overlap(sph[i], st_sph[k]);
      if (hit && pair_passes_filter(f(i), st_filters[k]))
        out.push_back({static_cast<std::uint32_t>(i), static_index(static_cast<std::uint32_t>(k))});
    }
  }
  std::sort(out.begin(), out.end());
  return out;
}

// A frame of the spheres, or of their boxes (made in `bx`, which the input then views).
FrameInput frame_of(const std::vector<Sphere>& sph, bool boxes, std::vector<Box>& bx) {
  FrameInput in;
  if (boxes) {
    bx.resize(sph.size());
    for (std::size_t k = 0; k < sph.size(); ++k) bx[k] = box_of(sph[k]);
    in.boxes = bx;
  } else {
    in.spheres = sph;
  }
  return in;
}

// One frame on the detector that follows change (given the moved list when `listed`) and on the
// one that rebuilds every frame (never given it).
std::pair<Status, Status> detect_both(Detector& follows, Detector& rebuilds, FrameInput in, bool listed,
                                      std::span<const std::uint32_t> moved, FrameResult& fa, FrameResult& fb) {
  if (listed) {
    in.moved = moved;
    in.moved_listed = true;
  }
  Status sa = follows.detect(in, fa);
  in.moved = {};
  in.moved_listed = false;
  return {std::move(sa), rebuilds.detect(in, fb)};
}

// A cpu detector that follows change with `on` and one that rebuilds every frame, else alike.
std::pair<std::unique_ptr<Detector>, std::unique_ptr<Detector>> follower_and_rebuilder(Config on) {
  on.follow_change = true;
  Config off = on;
  off.follow_change = false;
  return {make_cpu_detector(on), make_cpu_detector(off)};
}

// Runs a scenario; returns how many frames the detector followed.
int run_scenario(const Scenario& sc) {
  std::mt19937_64 rng(sc.seed);
  std::uniform_real_distribution<float> u(-1, 1), u01(0, 1);
  const float extent = 12.0f * std::cbrt(static_cast<float>(sc.n) / 600.0f);
  auto random_sphere = [&] {
    return Sphere{u(rng) * extent, u(rng) * extent * 0.3f, u(rng) * extent, 0.2f + 0.6f * u01(rng)};
  };

  Config on;
  on.follow_change = true;
  on.rest_margin = sc.margin;
  on.move_margin = sc.move_margin;
  on.contact_events = true;
  if (sc.camera) on.lambda = 10;
  Config off = on;
  off.follow_change = false;
  auto a = make_cpu_detector(on);
  auto b = make_cpu_detector(off);

  std::vector<Sphere> sph(sc.n);
  for (auto& s : sph) s = random_sphere();
  std::vector<Filter> filters;
  if (sc.filters) filters = test::random_filters(sc.n, sc.seed + 7);
  std::vector<std::uint8_t> always;
  if (sc.always_active) always.assign(sc.n, 0);

  std::vector<Sphere> st_sph;
  std::vector<Box> st_bx;
  std::vector<Filter> st_filters;
  if (sc.with_static) {
    for (int k = 0; k < 40; ++k) {
      const Sphere s = random_sphere();
      const Filter f = k % 7 == 0 ? Filter{2, 2} : Filter{};
      if (sc.boxes) {
        st_bx.push_back(box_of(s));
        EXPECT_TRUE(a->add_static_box(st_bx.back(), f).ok());
        EXPECT_TRUE(b->add_static_box(st_bx.back(), f).ok());
      } else {
        st_sph.push_back(s);
        EXPECT_TRUE(a->add_static_sphere(s, f).ok());
        EXPECT_TRUE(b->add_static_sphere(s, f).ok());
      }
      st_filters.push_back(f);
    }
  }

  Camera cam;
  cam.width = 320;
  cam.height = 240;
  int followed = 0;
  FrameResult fa, fb;
  std::vector<std::uint32_t> moved;
  // Objects that move every frame for a while (awake bodies), the rest now and then.
  std::vector<std::uint8_t> awake(sc.n, 0);
  for (int frame = 0; frame < sc.frames; ++frame) {
    SCOPED_TRACE("frame " + std::to_string(frame));
    moved.clear();
    const std::size_t n = sph.size();
    if (frame > 0) {
      for (std::size_t k = 0; k < n; ++k) {
        // About 4 % awake at a time (woken 0.2 % a frame, asleep again 5 %).
        if (u01(rng) < (awake[k] ? 0.05f : 0.002f)) awake[k] = !awake[k];
        const bool moves = awake[k] ? u01(rng) < 0.8f : u01(rng) < sc.move_fraction;
        if (!moves) continue;
        Sphere& s = sph[k];
        const float r = u01(rng);
        if (r < 0.3f && sc.margin > 0) {  // a jiggle, inside the margin
          s.x += u(rng) * sc.margin * 0.3f;
          s.y += u(rng) * sc.margin * 0.3f;
        } else if (r < 0.55f) {  // a glide: inside its own margin for a few frames (move_margin)
          s.x += u(rng) * 0.03f;
          s.z += u(rng) * 0.03f;
        } else if (r < 0.8f) {  // a step
          s.x += u(rng) * 0.5f;
          s.z += u(rng) * 0.5f;
        } else if (r < 0.9f) {  // a jump across the world
          s = random_sphere();
        } else {  // grows or shrinks
          s.r = std::max(0.0f, s.r + u(rng) * 0.2f);
        }
        moved.push_back(static_cast<std::uint32_t>(k));
      }
      if (sc.filters && frame % 9 == 4)
        for (int t = 0; t < 20; ++t)
          filters[static_cast<std::size_t>(u01(rng) * 0.999f * static_cast<float>(n))] = Filter{1u << (t % 3), 0x5u};
      if (sc.always_active && frame % 5 == 2)
        for (int t = 0; t < 30; ++t) always[static_cast<std::size_t>(u01(rng) * 0.999f * static_cast<float>(n))] ^= 1;
      if (sc.with_static && frame % 11 == 6) {
        const Sphere s = random_sphere();
        const std::uint32_t slot = static_cast<std::uint32_t>(frame % 40);
        if (sc.boxes) {
          st_bx[slot] = box_of(s);
          EXPECT_TRUE(a->move_static_box(slot, st_bx[slot]).ok());
          EXPECT_TRUE(b->move_static_box(slot, st_bx[slot]).ok());
        } else {
          st_sph[slot] = s;
          EXPECT_TRUE(a->move_static_sphere(slot, s).ok());
          EXPECT_TRUE(b->move_static_sphere(slot, s).ok());
        }
      }
      if (sc.resize && frame % 13 == 12) {
        // Objects vanish from the end, or new ones appear there.
        const std::size_t m = frame % 26 == 12 ? n - n / 10 : n + n / 10;
        const std::size_t old = sph.size();
        sph.resize(m);
        for (std::size_t k = old; k < m; ++k) sph[k] = random_sphere();
        awake.resize(m, 0);
        if (sc.filters) filters.resize(m, Filter{});
        if (sc.always_active) always.resize(m, 0);
        moved.clear();  // a new count: nothing to list
      }
    }
    const std::size_t n_now = sph.size();
    std::vector<Box> bx;
    if (sc.boxes) {
      bx.resize(n_now);
      for (std::size_t k = 0; k < n_now; ++k) bx[k] = box_of(sph[k]);
    }
    // From above the flat world, circling: few objects hide others.
    cam.eye[0] = 8.0f * std::sin(0.05f * static_cast<float>(frame));
    cam.eye[2] = 8.0f * std::cos(0.05f * static_cast<float>(frame));
    cam.eye[1] = 30;
    FrameInput in;
    if (sc.boxes)
      in.boxes = bx;
    else
      in.spheres = sph;
    if (sc.camera) in.camera = &cam;
    in.filters = filters;
    in.always_active = always;
    const auto [sa, sb] = detect_both(*a, *b, in, sc.listed, moved, fa, fb);
    EXPECT_TRUE(sa.ok()) << sa.error();
    EXPECT_TRUE(sb.ok()) << sb.error();
    if (!sa.ok() || !sb.ok()) return followed;
    followed += fa.stats.followed_change;
    EXPECT_FALSE(fb.stats.followed_change);

    EXPECT_TRUE(test::same_pairs(fa.pairs, oracle(sph, bx, sc.boxes, fb.state, filters, st_sph, st_bx, st_filters)));
    EXPECT_TRUE(test::same_pairs(fa.pairs, fb.pairs));
    EXPECT_EQ(fa.state, fb.state);
    EXPECT_EQ(fa.pixels, fb.pixels);
    EXPECT_TRUE(test::same_pairs(fa.began, fb.began));
    EXPECT_TRUE(test::same_pairs(fa.ended, fb.ended));

    // Queries see the frame's active objects where it put them, filters included.
    const Filter qf{1, 0x3};
    for (int q = 0; q < 4; ++q) {
      const Sphere qs = random_sphere();
      std::vector<std::uint32_t> ia, ib;
      a->overlap(Sphere{qs.x, qs.y, qs.z, 2.0f}, ia);
      b->overlap(Sphere{qs.x, qs.y, qs.z, 2.0f}, ib);
      EXPECT_EQ(ia, ib);
      a->overlap_box(box_of(Sphere{qs.x, qs.y, qs.z, 1.5f}), ia, &qf);
      b->overlap_box(box_of(Sphere{qs.x, qs.y, qs.z, 1.5f}), ib, &qf);
      EXPECT_EQ(ia, ib);
      const Ray ray = test::make_ray(qs.x, 20, qs.z, u(rng) * 0.2f, -1, u(rng) * 0.2f);
      std::vector<RayHit> ha, hb;
      a->ray_cast_all(ray, ha);
      b->ray_cast_all(ray, hb);
      EXPECT_EQ(ha, hb);
      RayHit fa1, fb1;
      EXPECT_EQ(a->ray_cast(ray, fa1, &qf), b->ray_cast(ray, fb1, &qf));
      EXPECT_EQ(fa1, fb1);
    }
  }
  // A pass that writes the pairs straight into the caller's list never misses the counts it
  // expected (it would merge again: right, but a sign that a candidate was dropped unforeseen).
  EXPECT_EQ(detail::backend_as<detail::CpuDetector>(*a).rest_set().direct_misses(), 0u);
  return followed;
}

class RestSetTest : public ::testing::TestWithParam<int> {};

Scenario scenario_of(int p) {
  Scenario sc;
  sc.boxes = p & 1;
  sc.margin = (p & 2) ? 0.05f : 0.0f;
  sc.listed = p & 4;
  sc.with_static = p & 8;
  if (p & 16) sc.move_margin = 0;
  sc.seed = static_cast<std::uint64_t>(p) + 11;
  return sc;
}

std::string scenario_name(const ::testing::TestParamInfo<int>& info) {
  const Scenario sc = scenario_of(info.param);
  return std::string(sc.boxes ? "boxes" : "spheres") + (sc.margin > 0 ? "_margin" : "_exact") +
         (sc.listed ? "_listed" : "_compared") + (sc.with_static ? "_static" : "") +
         (sc.move_margin > 0 ? "" : "_noMoveMargin");
}

TEST_P(RestSetTest, FramesEqualRebuiltOnes) {
  Scenario sc = scenario_of(GetParam());
  const int followed = run_scenario(sc);
  EXPECT_GE(followed, sc.frames / 2) << "the followed path must run";
}

TEST_P(RestSetTest, FiltersNeverCulledAndCamera) {
  Scenario sc = scenario_of(GetParam());
  sc.filters = true;
  sc.always_active = true;
  sc.camera = true;
  sc.frames = 30;
  // Culling leaves most objects active (at least half: the set follows such frames), and culls the
  // small, far and hidden ones, so the active mask applies to the carried candidates.
  const int followed = run_scenario(sc);
  EXPECT_GE(followed, sc.frames / 3) << "culled frames must be followed too";
}

TEST_P(RestSetTest, ObjectsAppearAndVanish) {
  Scenario sc = scenario_of(GetParam());
  sc.resize = true;
  sc.filters = true;
  const int followed = run_scenario(sc);
  EXPECT_GE(followed, sc.frames / 3);
}

TEST_P(RestSetTest, ATenthMoving) {
  // About a tenth moving each frame (7 % of the resting objects and most of the awake ones): the
  // movers' searches walk per bucket of movers, not per object (cpu/cross_pairs.hpp).
  Scenario sc = scenario_of(GetParam());
  sc.move_fraction = 0.07f;
  sc.n = 2000;
  sc.frames = 12;
  const int followed = run_scenario(sc);
  EXPECT_GE(followed, sc.frames / 3);
}

INSTANTIATE_TEST_SUITE_P(Cpu, RestSetTest, ::testing::Range(0, 16), scenario_name);

// The same scenarios without margins of their own (Config::move_margin 0): every object that
// changes is placed again.
class RestSetNoMoveMarginTest : public ::testing::TestWithParam<int> {};

TEST_P(RestSetNoMoveMarginTest, FramesEqualRebuiltOnes) {
  Scenario sc = scenario_of(GetParam());
  const int followed = run_scenario(sc);
  EXPECT_GE(followed, sc.frames / 2) << "the followed path must run";
}

INSTANTIATE_TEST_SUITE_P(Cpu, RestSetNoMoveMarginTest, ::testing::Range(16, 32), scenario_name);

TEST(RestSet, ManyMoversFallBackAndComeBack) {
  // Everything moves for a while (frames rebuild), then almost nothing (followed again).
  Scenario sc;
  sc.move_fraction = 0.0f;
  sc.frames = 1;
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<float> u(-8, 8);
  std::vector<Sphere> s(3000);
  for (auto& x : s) x = {u(rng), u(rng), u(rng), 0.4f};
  auto a = make_cpu_detector();
  FrameResult f;
  int followed = 0;
  for (int frame = 0; frame < 30; ++frame) {
    const bool storm = frame >= 10 && frame < 20;
    for (std::size_t k = 0; k < s.size(); ++k)
      if (storm || k % 100 == 0) s[k].x += 0.01f;
    ASSERT_TRUE(a->detect(s, nullptr, f).ok());
    EXPECT_TRUE(test::same_pairs(f.pairs, test::oracle_pairs(s)));
    if (storm && frame > 10) {
      EXPECT_FALSE(f.stats.followed_change) << frame;
    }
    followed += f.stats.followed_change;
  }
  EXPECT_GE(followed, 15);
}

TEST(RestSet, NewMoversEveryFrameGiveUpAndWait) {
  // A new random twentieth of the objects moves each frame (and the last frame's stop): main comes
  // due again every other frame, which costs more than rebuilding, so the set gives up and waits
  // longer each time; then the same few objects move and it follows again. Exact throughout.
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<float> step(-0.3f, 0.3f);
  std::vector<Sphere> s = slab_of(40000, rng);
  auto a = make_cpu_detector();
  std::uniform_int_distribution<std::uint32_t> pick(0, 39999);
  FrameResult f;
  int followed_churning = 0, followed_after = 0;
  for (int frame = 0; frame < 120; ++frame) {
    SCOPED_TRACE("frame " + std::to_string(frame));
    const bool churning = frame < 60;
    for (int t = 0; t < (churning ? 2000 : 100); ++t) {
      const std::uint32_t k = churning ? pick(rng) : static_cast<std::uint32_t>(t * 397);
      s[k].x += step(rng);
      s[k].y += step(rng);
    }
    ASSERT_TRUE(a->detect(s, nullptr, f).ok());
    if (frame % 10 == 0) {
      EXPECT_TRUE(test::same_pairs(f.pairs, test::oracle_pairs(s)));
    }
    if (churning && frame >= 20) followed_churning += f.stats.followed_change;
    if (!churning) followed_after += f.stats.followed_change;
  }
  const auto& rest = detail::backend_as<detail::CpuDetector>(*a).rest_set();
  EXPECT_GE(rest.churn_giveups(), 2u);
  EXPECT_LE(followed_churning, 20) << "new movers every frame should mostly rebuild";
  EXPECT_GE(followed_after, 15) << "the same few movers should be followed again";
}

TEST(RestSet, TheSameSixthMovingIsFollowed) {
  // The same 15 % move every frame: they leave main once (main is rebuilt over the others at once,
  // which is not churn: nothing came to rest) and are recent's from then on.
  std::mt19937_64 rng(12);
  std::uniform_real_distribution<float> step(-0.2f, 0.2f);
  std::vector<Sphere> s = slab_of(30000, rng);
  auto a = make_cpu_detector();
  FrameResult f;
  int followed = 0;
  for (int frame = 0; frame < 30; ++frame) {
    SCOPED_TRACE("frame " + std::to_string(frame));
    if (frame > 0)
      for (std::size_t k = 0; k < s.size(); k += 7) {  // 1 in 7: 14.3 %
        s[k].x += step(rng);
        s[k].y += step(rng);
      }
    ASSERT_TRUE(a->detect(s, nullptr, f).ok());
    if (frame % 6 == 5) {
      EXPECT_TRUE(test::same_pairs(f.pairs, test::oracle_pairs(s)));
    }
    followed += f.stats.followed_change;
  }
  const auto& rest = detail::backend_as<detail::CpuDetector>(*a).rest_set();
  EXPECT_EQ(rest.churn_giveups(), 0u);
  EXPECT_GE(followed, 20);
}

TEST(RestSet, GlidersWriteTheirPairsStraightIntoTheList) {
  // The same 1 in 50 glide a little every frame, inside margins of their own; every 7th frame a
  // resting one wakes and jumps (its candidates are dropped, and that frame merges as usual).
  // Frames where nothing woke write the pairs straight into the caller's list, each chunk where
  // the counts kept from the last frame put it; the pairs and states equal the oracle's every
  // frame, and no such frame misses its counts.
  // Both kernels of that pass run: the widest this CPU has, and the scalar one.
  for (const int variant : {0, 1, 2}) {
    const bool listed = variant == 1;
    SCOPED_TRACE(std::string(listed ? "listed" : "compared") + (variant == 2 ? ", scalar" : ""));
    std::mt19937_64 rng(21);
    std::uniform_real_distribution<float> step(-0.04f, 0.04f);
    std::vector<Sphere> s = slab_of(12000, rng);
    Config config;
    if (variant == 2) config.simd = Simd::scalar;
    auto a = make_cpu_detector(config);
    FrameResult f;
    int followed = 0;
    std::vector<std::uint32_t> moved;
    for (int frame = 0; frame < 40; ++frame) {
      SCOPED_TRACE("frame " + std::to_string(frame));
      moved.clear();
      if (frame > 0) {
        for (std::size_t k = 0; k < s.size(); k += 50) {
          s[k].x += step(rng);
          s[k].y += step(rng);
          moved.push_back(static_cast<std::uint32_t>(k));
        }
        if (frame % 7 == 3) {
          const std::size_t k = 25 + 50 * static_cast<std::size_t>(frame);
          s[k] = slab_of(1, rng)[0];
          moved.push_back(static_cast<std::uint32_t>(k));
          std::sort(moved.begin(), moved.end());
        }
      }
      FrameInput in;
      in.spheres = s;
      if (listed) {
        in.moved = moved;
        in.moved_listed = true;
      }
      ASSERT_TRUE(a->detect(in, f).ok());
      const std::vector<Pair> want = test::oracle_pairs(s);
      EXPECT_TRUE(test::same_pairs(f.pairs, want));
      // The states come from what the set keeps, not from a pass over the pairs: checked here.
      std::vector<ObjectState> state(s.size(), ObjectState::free);
      for (const Pair& p : want) state[p.i] = state[p.j] = ObjectState::colliding;
      EXPECT_EQ(f.state, state);
      followed += f.stats.followed_change;
    }
    const auto& rest = detail::backend_as<detail::CpuDetector>(*a).rest_set();
    EXPECT_GE(followed, 35);
    EXPECT_GE(rest.direct_frames(), 20u) << "the pairs were never written straight: the test lost its point";
    EXPECT_EQ(rest.direct_misses(), 0u);
  }
}

TEST(RestSet, InvalidObjectsAreFoundWhileComparing) {
  // Followed frames without a camera leave the objects' check to the comparing pass (an object bit
  // for bit the same was valid last frame; each changed one is checked), over every object or the
  // listed ones. A bad object among few or many changed ones, sphere or box, fails the frame
  // naming it, as a rebuilt frame would; the frames after it are exact again.
  for (const bool listed : {false, true}) {
    for (const bool boxes : {false, true}) {
      for (const std::size_t movers : {std::size_t{3}, std::size_t{5000}}) {
        SCOPED_TRACE(std::string(listed ? "listed, " : "compared, ") + (boxes ? "boxes, " : "spheres, ") +
                     std::to_string(movers) + " movers");
        std::mt19937_64 rng(31);
        std::vector<Sphere> s = slab_of(20000, rng);
        std::vector<Box> b(s.size());
        std::vector<std::uint32_t> moved;
        auto a = make_cpu_detector();
        auto ref = make_cpu_detector();
        FrameResult f, g;
        auto frame = [&](bool expect_ok) {
          FrameInput in;
          if (boxes) {
            for (std::size_t k = 0; k < s.size(); ++k) b[k] = box_of(s[k]);
            in.boxes = b;
          } else {
            in.spheres = s;
          }
          std::sort(moved.begin(), moved.end());
          moved.erase(std::unique(moved.begin(), moved.end()), moved.end());
          if (listed) {
            in.moved = moved;
            in.moved_listed = true;
          }
          const Status st = a->detect(in, f);
          in.moved = {};
          in.moved_listed = false;
          const Status want = ref->detect(in, g);
          if (st.ok()) moved.clear();  // the list names every change since the last frame that ran
          EXPECT_EQ(st.ok(), expect_ok);
          EXPECT_EQ(st.ok(), want.ok());
          EXPECT_EQ(st.error(), want.error());
          if (st.ok() && want.ok()) {
            EXPECT_TRUE(test::same_pairs(f.pairs, g.pairs));
          }
          return st;
        };
        for (int k = 0; k < 4; ++k) (void)frame(true);
        for (std::size_t k = 0; k < movers; ++k) {
          s[(k * 7919) % s.size()].x += 0.01f;
          moved.push_back(static_cast<std::uint32_t>((k * 7919) % s.size()));
        }
        const std::size_t bad = 12345;
        const Sphere keep = s[bad];
        s[bad].y = std::numeric_limits<float>::quiet_NaN();
        moved.push_back(static_cast<std::uint32_t>(bad));
        const Status st = frame(false);
        EXPECT_EQ(st.kind(), ErrorKind::invalid_input);
        EXPECT_NE(st.error().find(std::to_string(bad)), std::string::npos) << st.error();
        s[bad] = keep;
        for (int k = 0; k < 6; ++k) {
          s[(k * 31) % s.size()].z += 0.02f;
          moved.push_back(static_cast<std::uint32_t>((k * 31) % s.size()));
          (void)frame(true);
        }
        EXPECT_TRUE(f.stats.followed_change);
      }
    }
  }
}

TEST(RestSet, DegenerateCounts) {
  for (const std::size_t n : {0u, 1u, 2u, 15u, 16u, 17u, 100u, 4095u, 4097u}) {
    SCOPED_TRACE(n);
    // All centres equal (every pair), or past the parallel threshold a sparse cloud.
    std::vector<Sphere> s =
        n <= 100 ? std::vector<Sphere>(n, Sphere{1, 2, 3, 0.5f}) : test::random_spheres_by_half_extent(n, n, 20);
    auto a = make_cpu_detector();
    FrameResult f;
    for (int frame = 0; frame < 4; ++frame) {
      if (n > 0 && frame == 2) s[n / 2] = Sphere{100, 0, 0, 0};  // one leaves the pile
      ASSERT_TRUE(a->detect(s, nullptr, f).ok());
      EXPECT_TRUE(test::same_pairs(f.pairs, test::oracle_pairs(s)));
    }
    if (n >= 2) {
      EXPECT_TRUE(f.stats.followed_change);
    }
  }
}

TEST(RestSet, TouchingAndPointSpheres) {
  // Touching spheres and points at rest; one of them steps to touching another.
  std::vector<Sphere> s{{0, 0, 0, 1}, {2, 0, 0, 1}, {5, 0, 0, 0}, {5, 0, 0, 0}, {9, 0, 0, 1}};
  auto a = make_cpu_detector();
  FrameResult f;
  for (int frame = 0; frame < 4; ++frame) {
    if (frame == 3) s[4].x = 7;  // now touches nothing: {7,0,0,1} against the point at 5? 2 apart, r 1: no
    ASSERT_TRUE(a->detect(s, nullptr, f).ok());
    EXPECT_TRUE(test::same_pairs(f.pairs, test::oracle_pairs(s)));
  }
  s[4].x = 6;  // touches the points at 5
  ASSERT_TRUE(a->detect(s, nullptr, f).ok());
  EXPECT_TRUE(f.stats.followed_change);
  EXPECT_TRUE(test::same_pairs(f.pairs, test::oracle_pairs(s)));
}

TEST(RestSet, PairCapFailsAndRecovers) {
  std::vector<Sphere> s(200);
  for (std::size_t k = 0; k < s.size(); ++k) s[k] = {static_cast<float>(k) * 3, 0, 0, 1};
  Config c;
  c.pair_memory_cap = 10 * sizeof(Pair);
  auto a = make_cpu_detector(c);
  FrameResult f;
  ASSERT_TRUE(a->detect(s, nullptr, f).ok());
  ASSERT_TRUE(a->detect(s, nullptr, f).ok());
  EXPECT_TRUE(f.stats.followed_change);
  for (std::size_t k = 0; k < 20; ++k) s[k].x = 0;  // 190 pairs now
  const Status st = a->detect(s, nullptr, f);
  ASSERT_FALSE(st.ok());
  EXPECT_EQ(st.kind(), ErrorKind::pair_cap);
  for (std::size_t k = 0; k < 20; ++k) s[k].x = static_cast<float>(k) * 3;
  for (int frame = 0; frame < 3; ++frame) {
    ASSERT_TRUE(a->detect(s, nullptr, f).ok());
    EXPECT_TRUE(test::same_pairs(f.pairs, test::oracle_pairs(s)));
  }
}

TEST(RestSet, BadMovedListsFailAndChangeNothing) {
  std::vector<Sphere> s = test::random_spheres_by_half_extent(300, 5, 6);
  auto a = make_cpu_detector();
  FrameResult f;
  ASSERT_TRUE(a->detect(s, nullptr, f).ok());
  ASSERT_TRUE(a->detect(s, nullptr, f).ok());
  s[7].x += 1;
  s[9].x += 1;
  struct Bad {
    std::vector<std::uint32_t> moved;
    std::string says;
  };
  const Bad bad[] = {{{7, 9, 300}, "moved[2] = 300 is not an object of this frame"},
                     {{9, 7}, "moved[1] = 7 is below moved[0] = 9"},
                     {{7, 7, 9}, "moved[1] = 7 repeats moved[0]"}};
  for (const Bad& b : bad) {
    FrameInput in;
    in.spheres = s;
    in.moved = b.moved;
    in.moved_listed = true;
    const Status st = a->detect(in, f);
    ASSERT_FALSE(st.ok());
    EXPECT_EQ(st.kind(), ErrorKind::invalid_input);
    EXPECT_NE(st.error().find(b.says), std::string::npos) << st.error();
  }
  {
    FrameInput in;
    in.spheres = s;
    const std::uint32_t m[] = {7};
    in.moved = m;  // without moved_listed
    EXPECT_EQ(a->detect(in, f).kind(), ErrorKind::invalid_input);
  }
  // The failed frames changed nothing: a correct list now gives the exact frame.
  FrameInput in;
  in.spheres = s;
  const std::uint32_t m[] = {7, 9};
  in.moved = m;
  in.moved_listed = true;
  ASSERT_TRUE(a->detect(in, f).ok());
  EXPECT_TRUE(f.stats.followed_change);
  EXPECT_EQ(f.stats.moved, 2u);
  EXPECT_TRUE(test::same_pairs(f.pairs, test::oracle_pairs(s)));
}

TEST(RestSet, VerifyMovedFindsAnObjectLeftOut) {
  std::vector<Sphere> s = test::random_spheres_by_half_extent(300, 6, 6);
  Config c;
  c.verify_moved = true;
  auto a = make_cpu_detector(c);
  FrameResult f;
  ASSERT_TRUE(a->detect(s, nullptr, f).ok());
  ASSERT_TRUE(a->detect(s, nullptr, f).ok());
  s[3].y += 2;
  s[40].y += 2;
  FrameInput in;
  in.spheres = s;
  const std::uint32_t m[] = {3};
  in.moved = m;
  in.moved_listed = true;
  const Status st = a->detect(in, f);
  ASSERT_FALSE(st.ok());
  EXPECT_EQ(st.kind(), ErrorKind::invalid_input);
  EXPECT_NE(st.error().find("leaves out object 40"), std::string::npos) << st.error();
  const std::uint32_t m2[] = {3, 40};
  in.moved = m2;
  ASSERT_TRUE(a->detect(in, f).ok());
  EXPECT_TRUE(test::same_pairs(f.pairs, test::oracle_pairs(s)));
}

TEST(RestSet, BadMarginIsAnError) {
  const std::vector<Sphere> s(3, Sphere{0, 0, 0, 1});
  for (const float m : {-1.0f, std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity()})
    for (const bool own : {false, true}) {
      Config c;
      (own ? c.move_margin : c.rest_margin) = m;
      auto a = make_cpu_detector(c);
      FrameResult f;
      const Status st = a->detect(s, nullptr, f);
      ASSERT_FALSE(st.ok());
      EXPECT_EQ(st.kind(), ErrorKind::invalid_input);
      EXPECT_NE(st.error().find(own ? "Config::move_margin" : "Config::rest_margin"), std::string::npos) << st.error();
    }
}

// One sphere of radius r gliding along x by `step` a frame among 2 000 resting ones, with
// move_margin f: returns the frames (counted from the first followed one) in which it was placed
// again, checking every frame's pairs.
std::vector<int> placements(float r, float step, float f, int frames) {
  std::vector<Sphere> s;
  for (float x = 0; x < 20; ++x)
    for (float y = 0; y < 10; ++y)
      for (float z = 0; z < 10; ++z) s.push_back({3.0f * x, 3.0f * y, 3.0f * z, 1.0f});
  s[0] = Sphere{1.5f, 1.0f, 1.0f, r};  // between the others: meets the one at (3, 0, 0) as it glides
  Config c;
  c.move_margin = f;
  auto a = make_cpu_detector(c);
  FrameResult res;
  std::vector<int> at;
  int first = -1;
  for (int frame = 0; frame < frames; ++frame) {
    s[0].x = 1.5f + step * static_cast<float>(frame);
    EXPECT_TRUE(a->detect(s, nullptr, res).ok());
    EXPECT_TRUE(test::same_pairs(res.pairs, test::oracle_pairs(s)));
    if (!res.stats.followed_change || res.stats.replaced == s.size()) continue;  // not yet, or entering
    if (first < 0) first = frame;
    EXPECT_EQ(res.stats.moved, 1u);
    if (res.stats.replaced == 1) at.push_back(frame - first);
  }
  return at;
}

TEST(RestSet, MovingObjectsArePlacedEveryFewFrames) {
  // Worked by hand: the first followed frame takes a gliding sphere out of main with its exact
  // bounds (it may have moved once only); it moves again in the next, and, gliding 0.01 a frame
  // with move_margin 8.5, a sphere of radius 1 is placed with a margin of 0.085 (less than half
  // its size) and stays inside it for 8 more frames (0.08 < 0.085); the ninth takes it 0.09
  // away, and it is placed again.
  const std::vector<int> glide = placements(1.0f, 0.01f, 8.5f, 40);
  ASSERT_GE(glide.size(), 5u);
  EXPECT_EQ(glide[0], 0);
  EXPECT_EQ(glide[1], 1);
  for (std::size_t k = 2; k < glide.size(); ++k) EXPECT_EQ(glide[k] - glide[k - 1], 9) << k;
  // Without margins of its own it is placed again every frame it moves.
  const std::vector<int> none = placements(1.0f, 0.01f, 0.0f, 20);
  ASSERT_FALSE(none.empty());
  for (std::size_t k = 0; k < none.size(); ++k) EXPECT_EQ(none[k], static_cast<int>(k));
  // A move longer than half its size (radius 0.1, steps of 0.06): no margin of its own, placed
  // again every frame.
  const std::vector<int> jumps = placements(0.1f, 0.06f, 8.5f, 20);
  ASSERT_FALSE(jumps.empty());
  for (std::size_t k = 0; k < jumps.size(); ++k) EXPECT_EQ(jumps[k], static_cast<int>(k));
}

TEST(RestSet, MarginCarriesCandidatesOfJigglingObjects) {
  // A settled pile where every object jiggles a little each frame: with a margin, the frames are
  // followed and nobody leaves its fat bounds; without one every object leaves them.
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<float> u(-1, 1);
  std::vector<Sphere> s;
  for (int x = 0; x < 20; ++x)
    for (int y = 0; y < 10; ++y)
      for (int z = 0; z < 20; ++z)
        s.push_back({static_cast<float>(x), static_cast<float>(y), static_cast<float>(z), 0.5f + 0.01f * u(rng)});
  const std::vector<Sphere> home = s;
  Config c;
  c.rest_margin = 0.05f;
  auto a = make_cpu_detector(c);
  FrameResult f;
  int followed = 0;
  for (int frame = 0; frame < 12; ++frame) {
    for (std::size_t k = 0; k < s.size(); ++k) {
      s[k].x = home[k].x + 0.01f * u(rng);
      s[k].y = home[k].y + 0.01f * u(rng);
    }
    ASSERT_TRUE(a->detect(s, nullptr, f).ok());
    EXPECT_TRUE(test::same_pairs(f.pairs, test::oracle_pairs(s)));
    if (f.stats.followed_change && frame >= 2) {  // frame 1 placed every object
      ++followed;
      EXPECT_EQ(f.stats.moved, s.size());
      EXPECT_EQ(f.stats.replaced, 0u);
    }
  }
  EXPECT_GE(followed, 9);
}

// A settling pile on a static floor among static pillars, as in an engine's world: with a rest
// margin, 40 % of the objects jiggle inside their fat bounds every frame (the static candidates
// are then all tested again and chosen without a branch), and a few step or jump out of them
// (their static candidates replaced in the list). Pairs against brute force, states and events
// against a detector that rebuilds every frame.
void settling_pile_on_static_set(bool boxes, bool listed) {
  SCOPED_TRACE(std::string(boxes ? "boxes" : "spheres") + (listed ? ", listed" : ", compared"));
  std::mt19937_64 rng(boxes ? 21 : 22);
  std::uniform_real_distribution<float> u(-1, 1), u01(0, 1);
  std::vector<Sphere> sph;
  for (int x = 0; x < 16; ++x)
    for (int y = 0; y < 3; ++y)
      for (int z = 0; z < 16; ++z)
        sph.push_back(
            {static_cast<float>(x), 0.5f + static_cast<float>(y), static_cast<float>(z), 0.5f + 0.02f * u(rng)});
  const std::size_t n = sph.size();
  const std::vector<Sphere> home = sph;
  Config on;
  on.rest_margin = 0.05f;
  on.contact_events = true;
  auto [a, b] = follower_and_rebuilder(on);
  // The floor (touching the lowest layer), pillars among the objects, and a wall.
  std::vector<Sphere> st_sph;
  std::vector<Box> st_bx;
  std::vector<Filter> st_filters;
  const auto add_static = [&](const Box& bx) {
    if (boxes) {
      st_bx.push_back(bx);
      ASSERT_TRUE(a->add_static_box(bx).ok());
      ASSERT_TRUE(b->add_static_box(bx).ok());
    } else {
      const Sphere c{0.5f * (bx.min[0] + bx.max[0]), 0.5f * (bx.min[1] + bx.max[1]), 0.5f * (bx.min[2] + bx.max[2]),
                     0.5f * (bx.max[0] - bx.min[0])};
      st_sph.push_back(c);
      ASSERT_TRUE(a->add_static_sphere(c).ok());
      ASSERT_TRUE(b->add_static_sphere(c).ok());
    }
    st_filters.push_back(Filter{});
  };
  add_static(Box{{-1, -1, -1}, {17, 0.02f, 17}});
  for (int p = 0; p < 12; ++p) {
    const float x = 1.5f + static_cast<float>(p % 4) * 4, z = 1.5f + static_cast<float>(p / 4) * 5;
    add_static(Box{{x - 0.3f, -1, z - 0.3f}, {x + 0.3f, 3, z + 0.3f}});
  }
  add_static(Box{{15.4f, -1, -1}, {16, 4, 17}});
  std::vector<std::uint32_t> moved;
  FrameResult fa, fb;
  int followed = 0, spliced = 0;
  for (int frame = 0; frame < 24; ++frame) {
    SCOPED_TRACE("frame " + std::to_string(frame));
    moved.clear();
    if (frame > 0) {
      for (std::size_t k = 0; k < n; ++k) {
        const float r = u01(rng);
        if (r < 0.4f) {  // a jiggle about its place, inside the margin
          sph[k].x = home[k].x + 0.01f * u(rng);
          sph[k].y = home[k].y + 0.01f * u(rng);
        } else if (r < 0.41f) {  // a step out of its fat bounds
          sph[k].x += 0.3f * u(rng);
          sph[k].z += 0.3f * u(rng);
        } else if (r < 0.415f) {  // a jump across the pile, into or out of a pillar
          sph[k].x = 8 + 8 * u(rng);
          sph[k].z = 8 + 8 * u(rng);
        } else {
          continue;
        }
        moved.push_back(static_cast<std::uint32_t>(k));
      }
    }
    std::vector<Box> bx;
    const FrameInput in = frame_of(sph, boxes, bx);
    const auto [sa, sb] = detect_both(*a, *b, in, listed, moved, fa, fb);
    ASSERT_TRUE(sa.ok()) << sa.error();
    ASSERT_TRUE(sb.ok()) << sb.error();
    if (fa.stats.followed_change && frame >= 2) {
      ++followed;
      EXPECT_GT(fa.stats.moved * 4, n) << "most of a pile jiggles: the retests without a branch";
      spliced += fa.stats.replaced > 0;
    }
    const std::vector<ObjectState> all(n, ObjectState::free);
    EXPECT_TRUE(test::same_pairs(fa.pairs, oracle(sph, bx, boxes, all, {}, st_sph, st_bx, st_filters)));
    EXPECT_EQ(fa.state, fb.state);
    EXPECT_TRUE(test::same_pairs(fa.began, fb.began));
    EXPECT_TRUE(test::same_pairs(fa.ended, fb.ended));
  }
  EXPECT_GE(followed, 18) << "the pile's frames must be followed";
  EXPECT_GE(spliced, 18) << "objects must leave their fat bounds in most frames";
}

TEST(RestSet, SettlingPileOnAStaticSet) {
  for (const bool boxes : {false, true})
    for (const bool listed : {false, true}) settling_pile_on_static_set(boxes, listed);
}

// A static set that changes in a few slots between frames (a kinematic platform moved every
// frame, a door removed and put back, props added) is followed too: every such frame after the
// first few follows change, with pairs equal to brute force over the live static slots and
// pairs, states and events equal to a detector that rebuilds. Static objects move onto the resting
// objects, off them, far away, are removed (their slot reused by the next add) and added; a
// replaced set rebuilds the frame and the set is followed again later.
void static_changes_followed(bool boxes, float margin, bool listed) {
  SCOPED_TRACE(std::string(boxes ? "boxes" : "spheres") + ", margin " + std::to_string(margin) +
               (listed ? ", listed" : ", compared"));
  std::mt19937_64 rng(boxes ? 31 : 32);
  std::uniform_real_distribution<float> u(-1, 1), u01(0, 1);
  std::vector<Sphere> sph = slab_of(2000, rng);
  const std::size_t n = sph.size();
  Config on;
  on.rest_margin = margin;
  on.contact_events = true;
  auto [a, b] = follower_and_rebuilder(on);
  // The static set by slot (nullopt: a free slot), as the oracle sees it.
  std::vector<std::optional<Sphere>> st(80);
  auto as_box = [](const Sphere& c) { return box_of(c); };
  auto random_static = [&] { return Sphere{30 * u(rng), 30 * u(rng), 6 * u(rng), 0.5f + 2.5f * u01(rng)}; };
  auto check = [&](Status sa, Status sb) {
    ASSERT_TRUE(sa.ok()) << sa.error();
    ASSERT_TRUE(sb.ok()) << sb.error();
  };
  for (std::size_t k = 0; k < st.size(); ++k) {
    st[k] = random_static();
    const Result<std::uint32_t> ra = boxes ? a->add_static_box(as_box(*st[k])) : a->add_static_sphere(*st[k]);
    const Result<std::uint32_t> rb = boxes ? b->add_static_box(as_box(*st[k])) : b->add_static_sphere(*st[k]);
    ASSERT_TRUE(ra.ok() && rb.ok());
    ASSERT_EQ(ra.value(), k);
  }
  auto move_static = [&](std::uint32_t k, const Sphere& c) {
    st[k] = c;
    if (boxes)
      check(a->move_static_box(k, as_box(c)), b->move_static_box(k, as_box(c)));
    else
      check(a->move_static_sphere(k, c), b->move_static_sphere(k, c));
  };
  std::vector<std::uint32_t> moved;
  FrameResult fa, fb;
  int followed = 0, static_frames = 0;
  for (int frame = 0; frame < 40; ++frame) {
    SCOPED_TRACE("frame " + std::to_string(frame));
    moved.clear();
    bool static_changed = false;
    if (frame > 0) {
      for (std::size_t k = 0; k < n; ++k)
        if (u01(rng) < 0.01f) {
          sph[k].x += 0.2f * u(rng);
          sph[k].z += 0.2f * u(rng);
          moved.push_back(static_cast<std::uint32_t>(k));
        }
      // The platform: slot 0 glides every frame across the slab, through the objects.
      move_static(0, Sphere{-30.0f + 1.5f * static_cast<float>(frame), 0, 0, 2.0f});
      static_changed = true;
      if (frame % 3 == 1) {  // one onto a resting object, one small step, one far away
        const Sphere& on_top = sph[static_cast<std::size_t>(u01(rng) * 0.999f * static_cast<float>(n))];
        move_static(1 + static_cast<std::uint32_t>(frame % 20), Sphere{on_top.x, on_top.y, on_top.z, 1.0f});
        const std::uint32_t k = 30 + static_cast<std::uint32_t>(frame % 20);
        if (st[k]) move_static(k, Sphere{st[k]->x + 0.05f, st[k]->y, st[k]->z, st[k]->r});
        move_static(60, Sphere{1000, 1000, 1000, 1});
      }
      if (frame % 5 == 2) {  // a door taken out; it comes back into the smallest free slot
        const std::uint32_t k = 20 + static_cast<std::uint32_t>(frame % 10);
        if (st[k]) {
          check(a->remove_static(k), b->remove_static(k));
          st[k].reset();
        }
      }
      if (frame % 5 == 4) {
        const Sphere c = random_static();
        const Result<std::uint32_t> ra = boxes ? a->add_static_box(as_box(c)) : a->add_static_sphere(c);
        const Result<std::uint32_t> rb = boxes ? b->add_static_box(as_box(c)) : b->add_static_sphere(c);
        ASSERT_TRUE(ra.ok() && rb.ok());
        ASSERT_EQ(ra.value(), rb.value());
        ASSERT_LT(ra.value(), st.size());
        ASSERT_FALSE(st[ra.value()].has_value()) << "the smallest free slot";
        st[ra.value()] = c;
      }
      if (frame == 25) {  // the whole set replaced: that frame rebuilds
        std::vector<Sphere> all;
        std::vector<Box> all_boxes;
        for (auto& c : st) {
          c = random_static();
          all.push_back(*c);
          all_boxes.push_back(as_box(*c));
        }
        if (boxes)
          check(a->set_static_boxes(all_boxes), b->set_static_boxes(all_boxes));
        else
          check(a->set_static_spheres(all), b->set_static_spheres(all));
      }
    }
    std::vector<Box> bx;
    const FrameInput in = frame_of(sph, boxes, bx);
    const auto [sa, sb] = detect_both(*a, *b, in, listed, moved, fa, fb);
    ASSERT_TRUE(sa.ok()) << sa.error();
    ASSERT_TRUE(sb.ok()) << sb.error();
    if (frame == 25) {
      EXPECT_FALSE(fa.stats.followed_change) << "a replaced static set rebuilds";
    }
    if (static_changed && fa.stats.followed_change) ++static_frames;
    followed += fa.stats.followed_change;
    // The oracle: brute force over the moving objects and the live static slots.
    std::vector<Pair> want;
    for (std::uint32_t i = 0; i < n; ++i) {
      for (std::uint32_t j = i + 1; j < n; ++j)
        if (boxes ? boxes_overlap(bx[i], bx[j]) : spheres_overlap(sph[i], sph[j])) want.push_back({i, j});
      for (std::uint32_t k = 0; k < st.size(); ++k)
        if (st[k] && (boxes ? boxes_overlap(bx[i], as_box(*st[k])) : spheres_overlap(sph[i], *st[k])))
          want.push_back({i, static_index(k)});
    }
    std::sort(want.begin(), want.end());
    ASSERT_TRUE(test::same_pairs(fa.pairs, want));
    EXPECT_TRUE(test::same_pairs(fa.pairs, fb.pairs));
    EXPECT_EQ(fa.state, fb.state);
    EXPECT_TRUE(test::same_pairs(fa.began, fb.began));
    EXPECT_TRUE(test::same_pairs(fa.ended, fb.ended));
  }
  // Frames 0-2 enter (the sample watches first), and frame 25 and a few after it rebuild.
  EXPECT_GE(static_frames, 28) << followed << " frames followed";
}

TEST(RestSet, StaticChangesAreFollowed) {
  for (const bool boxes : {false, true})
    for (const float margin : {0.0f, 0.05f})
      for (const bool listed : {false, true}) static_changes_followed(boxes, margin, listed);
}

// Runs tasks last first and says it has four threads: emit() then merges in 16 chunks, whose
// outputs must not depend on the order they run in.
class BackwardsExecutor final : public Executor {
 public:
  [[nodiscard]] int concurrency() const override { return 4; }
  void run(std::uint32_t count, TaskRef task) override {
    for (std::uint32_t i = count; i-- > 0;) task(i);
  }
};

class RestSetSegments : public ::testing::TestWithParam<int> {};

TEST_P(RestSetSegments, StayExactWhileMoversGather) {
  // Enough candidates for emit() to merge them in chunks (their segments, with gaps where a chunk
  // dropped some), and movers that gather the low-numbered objects into a cluster, so that the
  // first segment grows until the list is packed and cut again. Against a detector that rebuilds
  // every frame (itself checked against brute force elsewhere: an oracle over 12 000 objects
  // would take minutes).
  const int p = GetParam();
  const bool boxes = p & 1, listed = p & 2;
  const float margin = (p & 4) ? 0.05f : 0.0f;
  std::mt19937_64 rng(static_cast<std::uint64_t>(p) + 5);
  std::uniform_real_distribution<float> u(-1, 1);
  constexpr std::size_t n = 12000;
  std::vector<Sphere> sph(n);
  for (auto& s : sph) s = {u(rng) * 20, u(rng) * 20, u(rng) * 20, 0.9f};
  BackwardsExecutor exec;
  Config on;
  on.follow_change = true;
  on.rest_margin = margin;
  on.executor = &exec;
  Config off = on;
  off.follow_change = false;
  auto a = make_cpu_detector(on);
  auto b = make_cpu_detector(off);
  for (int k = 0; k < 30; ++k) {  // static objects in the cluster: static pairs in the merge
    const Sphere s{u(rng) * 3, u(rng) * 3, u(rng) * 3, 0.5f};
    if (boxes) {
      ASSERT_TRUE(a->add_static_box(box_of(s)).ok());
      ASSERT_TRUE(b->add_static_box(box_of(s)).ok());
    } else {
      ASSERT_TRUE(a->add_static_sphere(s).ok());
      ASSERT_TRUE(b->add_static_sphere(s).ok());
    }
  }
  FrameResult fa, fb;
  std::vector<std::uint32_t> moved;
  std::vector<Box> bx(n);
  int followed = 0;
  for (int frame = 0; frame < 60; ++frame) {
    SCOPED_TRACE("frame " + std::to_string(frame));
    moved.clear();
    if (frame > 0) {
      // 60 of the first 1 500 objects into the cluster, 60 others anywhere (the same ones for
      // three frames at a time: movers that come to rest in delta, and main rebuilt over the
      // resting objects while some move).
      for (int t = 0; t < 60; ++t) {
        const int round = frame / 3;
        const auto k = static_cast<std::uint32_t>((round * 61 + t * 25) % 1500);
        sph[k] = {u(rng) * 4, u(rng) * 4, u(rng) * 4, 0.9f};
        moved.push_back(k);
        const auto o = static_cast<std::uint32_t>(1500 + (round * 977 + t * 173) % (n - 1500));
        sph[o] = {u(rng) * 20, u(rng) * 20, u(rng) * 20, 0.9f};
        moved.push_back(o);
      }
      // Every other frame the list also names objects 0-5999, most of them unchanged (allowed):
      // past the parallel threshold, so that the comparing pass splits the list into chunks
      // whose ends fall inside runs of one bitset word.
      if (frame % 2 == 0)
        for (std::uint32_t k = 0; k < 6000; ++k) moved.push_back(k);
      std::sort(moved.begin(), moved.end());
      moved.erase(std::unique(moved.begin(), moved.end()), moved.end());
    }
    FrameInput in;
    if (boxes) {
      for (std::size_t k = 0; k < n; ++k) bx[k] = box_of(sph[k]);
      in.boxes = bx;
    } else {
      in.spheres = sph;
    }
    if (listed) {
      in.moved = moved;
      in.moved_listed = true;
    }
    ASSERT_TRUE(a->detect(in, fa).ok());
    in.moved = {};
    in.moved_listed = false;
    ASSERT_TRUE(b->detect(in, fb).ok());
    followed += fa.stats.followed_change;
    EXPECT_TRUE(test::same_pairs(fa.pairs, fb.pairs));
    EXPECT_EQ(fa.state, fb.state);
  }
  EXPECT_GE(followed, 55);
  const auto& rest = detail::backend_as<detail::CpuDetector>(*a).rest_set();
  EXPECT_EQ(rest.segments(), 16u);
  EXPECT_GE(rest.packs(), 2u) << "the segments were never packed again: the test lost its point";
  EXPECT_GE(rest.main_rebuilds(), 1u) << "main was never rebuilt: the test lost its point";
}

INSTANTIATE_TEST_SUITE_P(Cpu, RestSetSegments, ::testing::Range(0, 8));

// Objects appended at the end (spawned bodies, particles) are placed as objects that leave their
// bounds are, and objects gone from the end (a swap-remove) are taken out as those are: such
// frames are followed, with the new objects' pairs among themselves, with the others and with the
// static set, and none of the vanished objects' pairs; more than 1 in 5 gone rebuilds. Spheres
// and boxes, with and without the moved list (which need not name the new objects), with own
// margins alone and a rest margin.
void objects_added_or_gone_at_the_end(bool boxes, bool listed, float margin) {
  SCOPED_TRACE(std::string(boxes ? "boxes" : "spheres") + (listed ? ", listed" : ", compared") + ", margin " +
               std::to_string(margin));
  std::mt19937_64 rng(41);
  std::uniform_real_distribution<float> u(-1, 1);
  auto near_origin = [&] { return Sphere{u(rng) * 14, u(rng) * 3, u(rng) * 14, 0.6f}; };
  std::vector<Sphere> sph(3000);
  for (auto& s : sph) s = near_origin();
  Config on;
  on.rest_margin = margin;
  on.contact_events = true;
  auto [a, b] = follower_and_rebuilder(on);
  std::vector<Sphere> st_sph;
  std::vector<Box> st_bx;
  for (int k = 0; k < 12; ++k) {
    const Sphere s = near_origin();
    if (boxes) {
      st_bx.push_back(box_of(s));
      ASSERT_TRUE(a->add_static_box(st_bx.back()).ok());
      ASSERT_TRUE(b->add_static_box(st_bx.back()).ok());
    } else {
      st_sph.push_back(s);
      ASSERT_TRUE(a->add_static_sphere(s).ok());
      ASSERT_TRUE(b->add_static_sphere(s).ok());
    }
  }
  FrameResult fa, fb;
  std::vector<std::uint32_t> moved;
  int grown_followed = 0, shrunk_followed = 0, shrunk = 0;
  for (int frame = 0; frame < 34; ++frame) {
    SCOPED_TRACE("frame " + std::to_string(frame));
    moved.clear();
    const std::size_t before = sph.size();
    bool grew = false, shrank = false;
    if (frame > 0) {
      for (int t = 0; t < 20; ++t) {  // a few move
        const auto k = static_cast<std::uint32_t>((frame * 131 + t * 17) % before);
        sph[k].x += u(rng) * 0.5f;
        moved.push_back(k);
      }
      std::sort(moved.begin(), moved.end());
      moved.erase(std::unique(moved.begin(), moved.end()), moved.end());
      // Some vanish from the end: more than were just added (resting ones go too), one, a whole
      // bitset word, and at frame 32 more than 1 in 5 (a rebuild).
      const std::size_t gone = frame == 8    ? 100
                               : frame == 12 ? 1
                               : frame == 16 ? 64
                               : frame == 20 ? 77
                               : frame == 32 ? before / 3
                                             : 0;
      if (gone > 0) {
        sph.resize(before - gone);
        moved.erase(std::remove_if(moved.begin(), moved.end(), [&](std::uint32_t k) { return k >= sph.size(); }),
                    moved.end());
        shrank = true;
      } else if (frame % 3 != 0) {  // new ones at the end, some on top of others, some on their own
        const int add = 1 + frame % 40;
        for (int t = 0; t < add; ++t) sph.push_back(t % 2 ? near_origin() : sph[(frame * 7 + t) % before]);
        if (frame % 5 == 1) moved.push_back(static_cast<std::uint32_t>(before));  // the list may name one
        grew = true;
      }
    }
    std::vector<Box> bx;
    const FrameInput in = frame_of(sph, boxes, bx);
    const auto [sa, sb] = detect_both(*a, *b, in, listed, moved, fa, fb);
    ASSERT_TRUE(sa.ok()) << sa.error();
    ASSERT_TRUE(sb.ok()) << sb.error();
    grown_followed += grew && fa.stats.followed_change;
    shrunk_followed += shrank && fa.stats.followed_change;
    shrunk += shrank;
    if (frame == 32) {
      EXPECT_FALSE(fa.stats.followed_change) << "a third of the objects gone: the frame rebuilds";
    }
    const std::vector<ObjectState> all_active(sph.size(), ObjectState::free);
    EXPECT_TRUE(test::same_pairs(fa.pairs, oracle(sph, bx, boxes, all_active, {}, st_sph, st_bx,
                                                  std::vector<Filter>(st_sph.size() + st_bx.size()))));
    EXPECT_TRUE(test::same_pairs(fa.pairs, fb.pairs));
    EXPECT_EQ(fa.state, fb.state);
    EXPECT_TRUE(test::same_pairs(fa.began, fb.began));
    EXPECT_TRUE(test::same_pairs(fa.ended, fb.ended));
    std::vector<std::uint32_t> ia, ib;
    a->overlap(Sphere{0, 0, 0, 3}, ia);
    b->overlap(Sphere{0, 0, 0, 3}, ib);
    EXPECT_EQ(ia, ib);
  }
  EXPECT_GE(grown_followed, 16) << "frames that added objects must be followed";
  EXPECT_EQ(shrunk, 5);
  EXPECT_EQ(shrunk_followed, 4) << "frames that lose a few objects from the end must be followed";
}

TEST(RestSet, ObjectsAddedOrGoneAtTheEndAreFollowed) {
  for (const bool boxes : {false, true})
    for (const bool listed : {false, true})
      for (const float margin : {0.0f, 0.05f}) objects_added_or_gone_at_the_end(boxes, listed, margin);
}

// 4 000 spheres of radius 0.6 in a slab 40 x 6 x 40.
std::vector<Sphere> wide_slab(std::mt19937_64& rng) {
  std::uniform_real_distribution<float> u(-1, 1);
  std::vector<Sphere> sph(4000);
  for (auto& s : sph) s = {u(rng) * 20, u(rng) * 3, u(rng) * 20, 0.6f};
  return sph;
}

// One frame of `sph` (their boxes with `boxes`) on both detectors, the follower given `moved`
// when `listed`: the pairs and states must agree. Returns whether the follower followed it.
bool same_frame(Detector& follows, Detector& rebuilds, const std::vector<Sphere>& sph, bool boxes, bool listed,
                std::span<const std::uint32_t> moved, FrameResult& fa, FrameResult& fb) {
  std::vector<Box> bx;
  const auto [sa, sb] = detect_both(follows, rebuilds, frame_of(sph, boxes, bx), listed, moved, fa, fb);
  EXPECT_TRUE(sa.ok()) << sa.error();
  EXPECT_TRUE(sb.ok()) << sb.error();
  EXPECT_TRUE(test::same_pairs(fa.pairs, fb.pairs));
  EXPECT_EQ(fa.state, fb.state);
  return sa.ok() && fa.stats.followed_change;
}

TEST(RestSet, AWorldThatRemovesEveryFrameStartsFollowing) {
  // Bodies removed every frame from the first one on, the last moved into each gap: the set's
  // sample must still stand when the count falls (it once required the same count or more, and
  // such a world rebuilt every frame), and the pairs stay the rebuilder's.
  for (const bool boxes : {false, true}) {
    SCOPED_TRACE(boxes ? "boxes" : "spheres");
    std::mt19937_64 rng(7);
    std::vector<Sphere> sph = wide_slab(rng);
    auto [a, b] = follower_and_rebuilder(Config{});
    FrameResult fa, fb;
    int followed = 0;
    for (int frame = 0; frame < 24; ++frame) {
      SCOPED_TRACE("frame " + std::to_string(frame));
      std::vector<std::uint32_t> moved;
      for (int t = 0; t < 6 && frame > 0; ++t) {
        const auto k = static_cast<std::uint32_t>(std::uniform_int_distribution<std::size_t>(0, sph.size() - 1)(rng));
        sph[k] = sph.back();
        sph.pop_back();
        moved.push_back(k);
      }
      std::sort(moved.begin(), moved.end());
      moved.erase(std::unique(moved.begin(), moved.end()), moved.end());
      while (!moved.empty() && moved.back() >= sph.size()) moved.pop_back();
      followed += same_frame(*a, *b, sph, boxes, frame % 2 == 0, moved, fa, fb);
    }
    EXPECT_GE(followed, 20);
  }
}

TEST(RestSet, StaticSetCountsFiltersThatRefuseTheDefault) {
  // Unfiltered frames pass every static pair without a test while no static filter refuses
  // Filter{}: the count must follow every way the set changes.
  detail::StaticSet set;
  const Sphere s{0, 0, 0, 1};
  const Filter kinematic{2, ~0u ^ 2u};  // Bullet's static bodies: pairs with the default
  const Filter picky{1, 2};             // pairs only with group 2: refuses Filter{}
  const std::vector<Sphere> three(3, s);
  const std::vector<Filter> filters = {Filter{}, kinematic, picky};
  ASSERT_TRUE(set.set(three, filters).ok());
  EXPECT_EQ(set.default_refused(), 1u);
  const Result<std::uint32_t> none = set.add(s, Filter{4, 0});
  ASSERT_TRUE(none.ok());
  EXPECT_EQ(set.default_refused(), 2u);
  ASSERT_TRUE(set.remove(2).ok());  // picky
  EXPECT_EQ(set.default_refused(), 1u);
  const Result<std::uint32_t> again = set.add(s, Filter{});  // into picky's slot
  ASSERT_TRUE(again.ok());
  EXPECT_EQ(again.value(), 2u);
  EXPECT_EQ(set.default_refused(), 1u);
  ASSERT_TRUE(set.move(none.value(), Sphere{1, 1, 1, 1}).ok());
  EXPECT_EQ(set.default_refused(), 1u);
  ASSERT_TRUE(set.set(three, {}).ok());
  EXPECT_EQ(set.default_refused(), 0u);
  ASSERT_TRUE(set.add(s, picky).ok());
  set.clear();
  EXPECT_EQ(set.default_refused(), 0u);
}

TEST(RestSet, MoversThatStopWaitInRecentWithOwnMargins) {
  // A world where a few bodies start moving each frame and stop a frame or three later (the
  // default margins: own ones alone). Those that stop wait in recent and join delta together
  // once more than 512 wait, instead of rebuilding delta every frame; some move again while they
  // wait (a leave: their own margin is gone), some jump. The pairs and states are the
  // rebuilder's every frame.
  for (const bool boxes : {false, true}) {
    SCOPED_TRACE(boxes ? "boxes" : "spheres");
    std::mt19937_64 rng(21);
    std::uniform_real_distribution<float> u(-1, 1);
    std::vector<Sphere> sph = wide_slab(rng);
    auto [a, b] = follower_and_rebuilder(Config{});
    FrameResult fa, fb;
    std::vector<std::uint32_t> until(sph.size(), 0);  // moves in frames before this one
    int followed = 0;
    for (std::uint32_t frame = 0; frame < 48; ++frame) {
      SCOPED_TRACE("frame " + std::to_string(frame));
      for (int t = 0; t < 30 && frame > 0; ++t) {  // new movers, for 1-3 frames
        const auto k = static_cast<std::uint32_t>((frame * 37 + static_cast<std::uint32_t>(t) * 131) % sph.size());
        until[k] = frame + 1 + static_cast<std::uint32_t>(t % 3);
      }
      if (frame % 5 == 4)  // some that stopped two frames ago move again, while they wait
        for (std::uint32_t k = 0; k < sph.size(); ++k)
          if (until[k] + 2 == frame && k % 2 == 0) until[k] = frame + 1;
      std::vector<std::uint32_t> moved;
      for (std::uint32_t k = 0; k < sph.size(); ++k) {
        if (until[k] <= frame) continue;
        const float reach = k % 17 == 0 ? 6.0f : 0.05f;  // a few jump
        sph[k].x += reach * u(rng);
        sph[k].z += reach * u(rng);
        moved.push_back(k);
      }
      followed += same_frame(*a, *b, sph, boxes, frame % 2 == 0, moved, fa, fb);
    }
    if (!boxes) {
      EXPECT_TRUE(test::same_pairs(fa.pairs, test::oracle_pairs(sph)));
    }
    EXPECT_GE(followed, 44);
    const auto& rest = detail::backend_as<detail::CpuDetector>(*a).rest_set();
    EXPECT_GE(rest.delta_builds(), 1u) << "nothing ever joined delta: the test lost its point";
    EXPECT_LE(rest.delta_builds(), 12u) << "delta was rebuilt nearly every frame";
  }
}

TEST(RestSet, FewerChunksAfterAMergeCountEachChangeOnce) {
  // With own margins alone (the default) the objects in pairs are counted as candidates are dropped
  // and merged, chunk by chunk of emit()'s merge. Objects jump out of a dense grid until the
  // candidates fall below what is merged in chunks (4096), and the list is packed into one chunk:
  // the changes the sixteen chunks of the frame before listed must not be counted again (they
  // were, when only the chunks in use were emptied: an object alone far away then stayed
  // "colliding").
  BackwardsExecutor four;
  Config on;
  on.executor = &four;
  Config off = on;
  off.follow_change = false;
  auto a = make_cpu_detector(on);
  auto b = make_cpu_detector(off);
  std::vector<Sphere> s;
  for (int x = 0; x < 16; ++x)
    for (int y = 0; y < 12; ++y)
      for (int z = 0; z < 16; ++z)
        s.push_back({static_cast<float>(x), static_cast<float>(y), static_cast<float>(z), 0.55f});
  const std::size_t n = s.size();
  std::vector<std::uint32_t> order(n);
  std::iota(order.begin(), order.end(), 0u);
  std::shuffle(order.begin(), order.end(), std::mt19937_64(3));
  const std::size_t per_frame = n / 12;  // under the 1 in 5 that makes the set give up
  std::size_t jumped = 0;
  FrameResult fa, fb;
  std::vector<std::uint32_t> moved;
  int followed = 0;
  std::size_t most_segments = 0;
  for (int frame = 0; frame < 20; ++frame) {
    SCOPED_TRACE("frame " + std::to_string(frame));
    moved.clear();
    if (frame >= 2)
      for (std::size_t k = 0; k < per_frame && jumped < n; ++k, ++jumped) {
        const std::uint32_t o = order[jumped];
        s[o] = {1000.0f + 3.0f * static_cast<float>(o), 0, 0, 0.55f};  // alone, far away
        moved.push_back(o);
      }
    std::sort(moved.begin(), moved.end());
    FrameInput in;
    in.spheres = s;
    const auto [sa, sb] = detect_both(*a, *b, in, true, moved, fa, fb);
    ASSERT_TRUE(sa.ok()) << sa.error();
    ASSERT_TRUE(sb.ok()) << sb.error();
    followed += fa.stats.followed_change;
    EXPECT_TRUE(test::same_pairs(fa.pairs, fb.pairs));
    EXPECT_EQ(fa.state, fb.state);
    most_segments = std::max(most_segments, detail::backend_as<detail::CpuDetector>(*a).rest_set().segments());
  }
  EXPECT_GE(followed, 16);
  EXPECT_EQ(most_segments, 16u) << "the candidates were never merged in chunks: the test lost its point";
  EXPECT_EQ(detail::backend_as<detail::CpuDetector>(*a).rest_set().segments(), 1u)
      << "the list was never packed into one chunk: the test lost its point";
}

}  // namespace
}  // namespace viscd
