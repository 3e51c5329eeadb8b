// Ray and overlap queries on the last frame: the cpu backend's tree and the reference backend's
// brute force against a brute-force loop over ray_hits_sphere / spheres_overlap written here
// (test_util.hpp), on random and degenerate scenes, and hand-worked cases.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

#include "test_util.hpp"

namespace viscd {
namespace {

using test::oracle_hits;
using test::oracle_overlap;
using test::random_spheres_by_half_extent;

using test::describe;
using test::kInf;
using test::make_ray;

// Every query of `d` (which ran the last frame on `s`) against the oracles over `active`.
void check_ray(Detector& d, std::span<const Sphere> s, const std::vector<std::uint32_t>* active, const Ray& r,
               const std::string& what) {
  const std::vector<RayHit> want = oracle_hits(s, r, active);
  std::vector<RayHit> all;
  d.ray_cast_all(r, all);
  ASSERT_EQ(all, want) << d.name() << ": " << what << ": " << describe(r);
  RayHit first{};
  const bool found = d.ray_cast(r, first);
  ASSERT_EQ(found, !want.empty()) << d.name() << ": " << what << ": " << describe(r);
  if (found) {
    ASSERT_EQ(first, want.front()) << d.name() << ": " << what << ": " << describe(r);
  }
}

void check_overlap(Detector& d, std::span<const Sphere> s, const std::vector<std::uint32_t>* active, const Sphere& q,
                   const std::string& what) {
  std::vector<std::uint32_t> got;
  d.overlap(q, got);
  ASSERT_EQ(got, oracle_overlap(s, q, active)) << d.name() << ": " << what;
}

// Rays of every kind at a scene of half extent `h` around `centre`: from inside and outside,
// axis-aligned (zero direction components), finite max_t, from far away.
std::vector<Ray> rays_for(std::size_t count, float h, std::uint64_t seed, float centre = 0) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> u(-1, 1);
  std::vector<Ray> rays;
  for (std::size_t k = 0; k < count; ++k) {
    const float ox = centre + 1.2f * h * u(rng), oy = centre + 1.2f * h * u(rng), oz = centre + 1.2f * h * u(rng);
    float d[3] = {u(rng), u(rng), u(rng)};
    switch (k % 6) {
      case 0:  // along an axis
        d[(k / 6) % 3] = 0, d[(k / 6 + 1) % 3] = 0;
        break;
      case 1:  // in an axis plane
        d[(k / 6) % 3] = 0;
        break;
      case 2: {  // from far away, at the scene
        const float far[3] = {centre + 1e4f * h * u(rng), centre + 1e4f * h * u(rng), centre + 1e4f * h * u(rng)};
        rays.push_back(make_ray(far[0], far[1], far[2], ox - far[0], oy - far[1], oz - far[2]));
        continue;
      }
      default:
        break;
    }
    if (d[0] == 0 && d[1] == 0 && d[2] == 0) d[0] = 1;
    const float max_t = k % 4 == 3 ? h * (u(rng) + 1) : kInf;
    rays.push_back(make_ray(ox, oy, oz, d[0], d[1], d[2], max_t));
  }
  return rays;
}

void check_scene(Detector& d, std::span<const Sphere> s, const std::vector<std::uint32_t>* active, float h,
                 std::uint64_t seed, const std::string& what, float centre = 0) {
  for (const Ray& r : rays_for(300, h, seed, centre)) {
    check_ray(d, s, active, r, what);
    if (::testing::Test::HasFatalFailure()) return;
  }
  // Rays aimed at objects, grazing them, and from their centres.
  std::mt19937_64 rng(seed + 1);
  for (std::size_t k = 0; k < std::min<std::size_t>(s.size(), 100); ++k) {
    const Sphere& t = s[rng() % s.size()];
    check_ray(d, s, active,
              make_ray(centre, centre, centre - 2 * h, t.x - centre, t.y + t.r - centre, t.z + 2 * h - centre),
              what + ", aimed at the top of an object");
    check_ray(d, s, active, make_ray(t.x - 3 * h, t.y + t.r, t.z, 1, 0, 0), what + ", grazing along x");
    check_ray(d, s, active, make_ray(t.x, t.y, t.z, 0, -1, 0), what + ", from an object's centre");
    if (::testing::Test::HasFatalFailure()) return;
  }
  std::uniform_real_distribution<float> u(-1, 1);
  for (int k = 0; k < 100; ++k) {
    const float r = k % 10 == 0 ? 0.0f : h * 0.2f * (u(rng) + 1);
    check_overlap(d, s, active, {centre + h * u(rng), centre + h * u(rng), centre + h * u(rng), r}, what);
    if (::testing::Test::HasFatalFailure()) return;
  }
  for (std::size_t k = 0; k < std::min<std::size_t>(s.size(), 30); ++k) {
    const Sphere& t = s[rng() % s.size()];
    check_overlap(d, s, active, {t.x, t.y, t.z, 0}, what + ", a point at an object's centre");
    check_overlap(d, s, active, {t.x + t.r, t.y, t.z, 0}, what + ", a point on an object's surface");
  }
}

using test::Factory;
using test::kBackends;

TEST(Query, RandomScenesAgainstBruteForce) {
  for (std::size_t n : {1u, 2u, 15u, 16u, 17u, 33u, 200u, 5000u}) {
    const float h = 2.0f + std::cbrt(static_cast<float>(n));
    const auto s = random_spheres_by_half_extent(n, n, h, 0.05f, 1.0f);
    for (Factory make : kBackends) {
      if (n > 1000 && make == make_reference_detector) continue;  // its brute force is the same loop
      auto d = make(Config{});
      test::run_frame(*d, s);
      check_scene(*d, s, nullptr, h, n + 1, "n = " + std::to_string(n));
    }
  }
}

TEST(Query, FarFromTheOriginAndTinyOrHugeRadii) {
  // Coordinates near 1e5 (boxes round most), radii over six orders of magnitude, points.
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<float> u(-1, 1);
  std::vector<Sphere> s;
  for (int k = 0; k < 3000; ++k) {
    const float r = k % 7 == 0 ? 0.0f : std::pow(10.0f, -4.0f + 3.0f * (u(rng) + 1));
    s.push_back({1e5f + 30 * u(rng), -1e5f + 30 * u(rng), 1e5f + 30 * u(rng), r});
  }
  s[10] = {1e5f, -1e5f, 1e5f, 40};
  auto d = make_cpu_detector(Config{});
  test::run_frame(*d, s);
  check_scene(*d, s, nullptr, 30, 9, "near 1e5", 0);
  // The same scene queried from rays centred on it.
  for (const Ray& r0 : rays_for(500, 30, 11)) {
    Ray r = r0;
    r.origin[0] += 1e5f, r.origin[1] -= 1e5f, r.origin[2] += 1e5f;
    check_ray(*d, s, nullptr, r, "near 1e5, rays from the scene");
    if (HasFatalFailure()) return;
  }
}

TEST(Query, RaysFromVeryFarAwayAtSmallSpheres) {
  // Where the double evaluation's rounding (relative to the origin's magnitude) exceeds the
  // spheres' own box margins: the tree must widen its boxes for the ray (ray_box_margin()).
  std::mt19937_64 rng(31);
  std::uniform_real_distribution<float> u(-1, 1);
  std::vector<Sphere> s;
  for (int k = 0; k < 2000; ++k) s.push_back({u(rng), u(rng), u(rng), k % 5 == 0 ? 0.0f : 1e-3f * (u(rng) + 1)});
  auto d = make_cpu_detector(Config{});
  test::run_frame(*d, s);
  for (int k = 0; k < 4000; ++k) {
    const float far = std::pow(10.0f, 6.0f + 11.0f * (u(rng) + 1) / 2);
    const Sphere& t = s[rng() % s.size()];
    Ray r = make_ray(far * u(rng), far * u(rng), far * (k % 2 ? 1.0f : -1.0f), 0, 0, 0);
    const float aim[3] = {t.x + 3e-3f * u(rng), t.y + 3e-3f * u(rng), t.z + 3e-3f * u(rng)};
    for (int c = 0; c < 3; ++c) r.dir[c] = aim[c] - r.origin[c];
    check_ray(*d, s, nullptr, r, "from far away");
    if (HasFatalFailure()) return;
  }
}

TEST(Query, IdenticalSpheresTieByIndex) {
  const std::vector<Sphere> s(40, Sphere{0, 0, 5, 1});
  for (Factory make : kBackends) {
    auto d = make(Config{});
    test::run_frame(*d, s);
    RayHit h{};
    ASSERT_TRUE(d->ray_cast(make_ray(0, 0, 0, 0, 0, 1), h));
    EXPECT_EQ(h, (RayHit{0, 4.0f})) << d->name();
    std::vector<RayHit> all;
    d->ray_cast_all(make_ray(0, 0, 0, 0, 0, 1), all);
    ASSERT_EQ(all.size(), 40u);
    for (std::uint32_t k = 0; k < 40; ++k) EXPECT_EQ(all[k], (RayHit{k, 4.0f})) << d->name();
    std::vector<std::uint32_t> idx;
    d->overlap({0, 0, 7, 1}, idx);  // touches them all exactly: 2 <= 1 + 1
    EXPECT_EQ(idx.size(), 40u) << d->name();
  }
}

TEST(Query, HandWorkedLineOfSpheres) {
  // Spheres of radius 0.5 at x = 0, 2, 4, ..., 18 on the x axis; a point at x = 21; one above.
  std::vector<Sphere> s;
  for (int k = 0; k < 10; ++k) s.push_back({2.0f * static_cast<float>(k), 0, 0, 0.5f});
  s.push_back({21, 0, 0, 0});    // 10: a point
  s.push_back({6, 0.5f, 0, 0});  // 11: a point on top of sphere 3 (6, 0, 0)
  for (Factory make : kBackends) {
    auto d = make(Config{});
    test::run_frame(*d, s);
    const std::string name(d->name());
    RayHit h{};
    // Along +x from -10: the first sphere's surface at x = -0.5.
    ASSERT_TRUE(d->ray_cast(make_ray(-10, 0, 0, 1, 0, 0), h)) << name;
    EXPECT_EQ(h, (RayHit{0, 9.5f})) << name;
    // From inside sphere 4 (x = 8), along -x: t = 0 for sphere 4 itself.
    ASSERT_TRUE(d->ray_cast(make_ray(8.25f, 0, 0, -1, 0, 0), h)) << name;
    EXPECT_EQ(h, (RayHit{4, 0.0f})) << name;
    // Along -x from 30 with dir length 2: the point at 21 first (t = 4.5), then sphere 9 (18.5: t = 5.75).
    std::vector<RayHit> all;
    d->ray_cast_all(make_ray(30, 0, 0, -2, 0, 0), all);
    ASSERT_EQ(all.size(), 11u) << name;
    EXPECT_EQ(all[0], (RayHit{10, 4.5f})) << name;
    EXPECT_EQ(all[1], (RayHit{9, 5.75f})) << name;
    EXPECT_EQ(all[10], (RayHit{0, 14.75f})) << name;
    // max_t cuts the list: up to t = 5.75 inclusive.
    d->ray_cast_all(make_ray(30, 0, 0, -2, 0, 0, 5.75f), all);
    EXPECT_EQ(all.size(), 2u) << name;
    // Grazing along y = 0.5 from x = -1: touches every sphere at its top (discriminant 0), and
    // the point 11 on top of sphere 3 at the same t.
    d->ray_cast_all(make_ray(-1, 0.5f, 0, 1, 0, 0), all);
    ASSERT_EQ(all.size(), 11u) << name;
    EXPECT_EQ(all[0], (RayHit{0, 1.0f})) << name;
    EXPECT_EQ(all[3], (RayHit{3, 7.0f})) << name;
    EXPECT_EQ(all[4], (RayHit{11, 7.0f})) << name << ": ties by index";
    // Just above the tops: nothing.
    EXPECT_FALSE(d->ray_cast(make_ray(-1, std::nextafter(0.5f, 1.0f), 0, 1, 0, 0), h)) << name;
    // Overlap: a point at (3, 0, 0) between spheres 1 and 2 touches neither (distance 1 > 0.5).
    std::vector<std::uint32_t> idx;
    d->overlap({3, 0, 0, 0}, idx);
    EXPECT_TRUE(idx.empty()) << name;
    d->overlap({3, 0, 0, 0.5f}, idx);  // touches spheres 1 and 2 exactly
    EXPECT_EQ(idx, (std::vector<std::uint32_t>{1, 2})) << name;
    d->overlap({6, 0.5f, 0, 0}, idx);  // the point 11, on sphere 3's surface
    EXPECT_EQ(idx, (std::vector<std::uint32_t>{3, 11})) << name;
  }
}

TEST(Query, InvalidQueriesFindNothing) {
  const std::vector<Sphere> s = {{0, 0, 0, 1}, {0, 0, 5, 1}};
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (Factory make : kBackends) {
    auto d = make(Config{});
    test::run_frame(*d, s);
    RayHit h{};
    std::vector<RayHit> all;
    std::vector<std::uint32_t> idx;
    for (const Ray& r : {make_ray(0, 0, 0, 0, 0, 0), make_ray(0, 0, 0, 0, 0, 1, -1.0f), make_ray(0, 0, 0, 0, 0, 1, nan),
                         make_ray(nan, 0, 0, 0, 0, 1), make_ray(0, 0, 0, kInf, 0, 1), make_ray(0, -kInf, 0, 0, 0, 1)}) {
      EXPECT_FALSE(d->ray_cast(r, h)) << d->name() << ": " << describe(r);
      all.push_back({7, 7});
      d->ray_cast_all(r, all);
      EXPECT_TRUE(all.empty()) << d->name() << ": " << describe(r);
    }
    for (const Sphere& q : {Sphere{0, 0, 0, -1}, Sphere{nan, 0, 0, 1}, Sphere{0, 0, 0, kInf}, Sphere{2e18f, 0, 0, 1}}) {
      idx.push_back(9);
      d->overlap(q, idx);
      EXPECT_TRUE(idx.empty()) << d->name();
    }
    // A sphere that validates: found.
    d->overlap({0, 0, 0, 0}, idx);
    EXPECT_EQ(idx, std::vector<std::uint32_t>{0}) << d->name();
  }
}

TEST(Query, EmptyFrameAllCulledAndFailedFrames) {
  for (Factory make : kBackends) {
    auto d = make(Config{});
    RayHit h{};
    std::vector<std::uint32_t> idx;
    EXPECT_FALSE(d->ray_cast(make_ray(0, 0, 0, 0, 0, 1), h)) << d->name() << ": before any frame";
    test::run_frame(*d, std::vector<Sphere>{});
    EXPECT_FALSE(d->ray_cast(make_ray(0, 0, 0, 0, 0, 1), h)) << d->name() << ": empty frame";
    d->overlap({0, 0, 0, 1e9f}, idx);
    EXPECT_TRUE(idx.empty());
    // All culled: the camera looks away from the spheres.
    const auto s = random_spheres_by_half_extent(100, 2, 3.0f);
    Camera cam;
    cam.eye[2] = 20;
    cam.target[2] = 40;
    cam.width = 64, cam.height = 48;
    const FrameResult f = test::run_frame(*d, s, &cam);
    ASSERT_EQ(f.stats.active, 0u) << d->name();
    EXPECT_FALSE(d->ray_cast(make_ray(0, 0, -20, 0, 0, 1), h)) << d->name() << ": all culled";
    d->overlap({0, 0, 0, 10}, idx);
    EXPECT_TRUE(idx.empty()) << d->name() << ": all culled";
    // A good frame, then a failed one: queries see nothing until the next good frame.
    test::run_frame(*d, s);
    EXPECT_TRUE(d->ray_cast(make_ray(0, 0, -20, 0, 0, 1), h)) << d->name();
    std::vector<Sphere> bad = s;
    bad[5].r = -1;
    FrameResult out;
    ASSERT_FALSE(d->detect(bad, nullptr, out).ok());
    EXPECT_FALSE(d->ray_cast(make_ray(0, 0, -20, 0, 0, 1), h)) << d->name() << ": after a failed frame";
    d->overlap({0, 0, 0, 10}, idx);
    EXPECT_TRUE(idx.empty()) << d->name() << ": after a failed frame";
    test::run_frame(*d, s);
    EXPECT_TRUE(d->ray_cast(make_ray(0, 0, -20, 0, 0, 1), h)) << d->name();
  }
}

TEST(Query, CulledObjectsAreInvisibleFilteredOnesAreNot) {
  const auto s = random_spheres_by_half_extent(800, 12, 6.0f, 0.2f, 1.2f);
  std::vector<Filter> f(s.size());
  for (std::size_t k = 0; k < f.size(); k += 3) f[k] = {0, 0};  // pair with nothing
  for (std::size_t k = 1; k < f.size(); k += 3) f[k] = {2, 2};  // only among themselves
  Camera cam;
  cam.eye[2] = 14;
  cam.width = 160, cam.height = 120;
  Config c;
  c.lambda = 30;
  for (Factory make : kBackends) {
    for (const bool with_camera : {false, true}) {
      auto d = make(c);
      FrameInput in;
      in.spheres = s;
      in.filters = f;
      in.camera = with_camera ? &cam : nullptr;
      FrameResult out;
      ASSERT_TRUE(d->detect(in, out).ok());
      std::vector<std::uint32_t> active;
      for (std::uint32_t k = 0; k < s.size(); ++k)
        if (out.state[k] != ObjectState::culled) active.push_back(k);
      if (with_camera) {
        ASSERT_LT(active.size(), s.size());
      }
      check_scene(*d, s, &active, 6.0f, 21, std::string("filters, camera ") + (with_camera ? "on" : "off"));
    }
  }
}

TEST(Query, AcrossFramesOfAMovingScene) {
  // One detector over a moving scene whose N changes: queries always see the last frame.
  auto d = make_cpu_detector(Config{});
  std::mt19937_64 rng(8);
  std::uniform_real_distribution<float> u(-1, 1);
  std::vector<Sphere> s = random_spheres_by_half_extent(1500, 4, 10.0f);
  for (int frame = 0; frame < 6; ++frame) {
    for (Sphere& x : s) x.x += 0.3f * u(rng);
    if (frame == 2) s.resize(700);
    if (frame == 4) {
      const auto more = random_spheres_by_half_extent(2500, 99, 10.0f);
      s.insert(s.end(), more.begin(), more.end());
    }
    std::vector<Filter> f;
    if (frame % 2) {
      f.assign(s.size(), Filter{});
      for (std::size_t k = 0; k < f.size(); k += 2) f[k] = {4, 0};
    }
    FrameInput in;
    in.spheres = s;
    in.filters = f;
    FrameResult out;
    ASSERT_TRUE(d->detect(in, out).ok());
    for (const Ray& r : rays_for(80, 10, static_cast<std::uint64_t>(frame)))
      check_ray(*d, s, nullptr, r, "frame " + std::to_string(frame));
    check_overlap(*d, s, nullptr, {0, 0, 0, 3}, "frame " + std::to_string(frame));
  }
}

}  // namespace
}  // namespace viscd
