// The ray-sphere test of the queries (ray_hits_sphere, core's ray_sphere): hand-worked cases, and
// random rays against an independent computation in long double.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

#include "core/geometry.hpp"
#include "test_util.hpp"
#include "viscd/detector.hpp"

namespace viscd {
namespace {

Ray ray(float ox, float oy, float oz, float dx, float dy, float dz,
        float max_t = std::numeric_limits<float>::infinity()) {
  return test::make_ray(ox, oy, oz, dx, dy, dz, max_t);
}

// t of the hit, or -1 for a miss.
float hit_t(const Ray& r, const Sphere& s) {
  float t = -2;
  return ray_hits_sphere(r, s, t) ? t : -1.0f;
}

TEST(RaySphere, AlongAnAxis) {
  // |(0, 0, t) - (0, 0, 10)| = 2 at t = 8.
  EXPECT_EQ(hit_t(ray(0, 0, 0, 0, 0, 1), {0, 0, 10, 2}), 8.0f);
  // dir of length 2: t is in units of |dir|.
  EXPECT_EQ(hit_t(ray(0, 0, 0, 0, 0, 2), {0, 0, 10, 2}), 4.0f);
  EXPECT_EQ(hit_t(ray(0, 0, 0, 0, 0, 0.5f), {0, 0, 10, 2}), 16.0f);
  // Along -x and +y.
  EXPECT_EQ(hit_t(ray(0, 0, 0, -1, 0, 0), {-7, 0, 0, 1}), 6.0f);
  EXPECT_EQ(hit_t(ray(3, -5, 0, 0, 1, 0), {3, 5, 0, 0.5f}), 9.5f);
  // Behind the origin, or off the line: misses.
  EXPECT_EQ(hit_t(ray(0, 0, 0, 0, 0, -1), {0, 0, 10, 2}), -1.0f);
  EXPECT_EQ(hit_t(ray(0, 0, 0, 0, 0, 1), {0, 3, 10, 2}), -1.0f);
}

TEST(RaySphere, Grazing) {
  // The line y = 1 touches the unit sphere at (0, 1, 0): discriminant exactly 0, t = 5.
  EXPECT_EQ(hit_t(ray(-5, 1, 0, 1, 0, 0), {0, 0, 0, 1}), 5.0f);
  EXPECT_EQ(hit_t(ray(-5, -1, 0, 1, 0, 0), {0, 0, 0, 1}), 5.0f);
  EXPECT_EQ(hit_t(ray(0, 0, -5, 0, 0, 1), {1, 0, 0, 1}), 5.0f);
  // One ulp further out: a miss.
  EXPECT_EQ(hit_t(ray(-5, std::nextafter(1.0f, 2.0f), 0, 1, 0, 0), {0, 0, 0, 1}), -1.0f);
  // One ulp inside: a hit just before the tangent point.
  const float t = hit_t(ray(-5, std::nextafter(1.0f, 0.0f), 0, 1, 0, 0), {0, 0, 0, 1});
  EXPECT_GT(t, 4.99f);
  EXPECT_LE(t, 5.0f);
}

TEST(RaySphere, OriginInsideOrOnTheSphere) {
  EXPECT_EQ(hit_t(ray(0, 0, 0, 1, 0, 0), {0, 0, 0, 1}), 0.0f) << "centre";
  EXPECT_EQ(hit_t(ray(0.5f, 0, 0, -1, 0, 0), {0, 0, 0, 1}), 0.0f) << "inside, pointing through the centre";
  EXPECT_EQ(hit_t(ray(0.5f, 0, 0, 1, 0, 0), {0, 0, 0, 1}), 0.0f) << "inside, pointing out";
  EXPECT_EQ(hit_t(ray(1, 0, 0, 1, 0, 0), {0, 0, 0, 1}), 0.0f) << "on the surface, pointing out";
  EXPECT_EQ(hit_t(ray(0, 0, 2, 0, 1, 0), {0, 0, 0, 2}), 0.0f) << "on the surface, tangent";
  EXPECT_EQ(hit_t(ray(0, 0, 0, 1, 0, 0, 0.0f), {0, 0, 0, 1}), 0.0f) << "max_t 0 still holds t = 0";
}

TEST(RaySphere, MaxT) {
  const Sphere s{0, 0, 10, 2};
  EXPECT_EQ(hit_t(ray(0, 0, 0, 0, 0, 1, 8.0f), s), 8.0f) << "max_t is inclusive";
  EXPECT_EQ(hit_t(ray(0, 0, 0, 0, 0, 1, std::nextafter(8.0f, 0.0f)), s), -1.0f);
  EXPECT_EQ(hit_t(ray(0, 0, 0, 0, 0, 1, -1.0f), {0, 0, 0, 1}), -1.0f) << "negative max_t: nothing";
  EXPECT_EQ(hit_t(ray(0, 0, 0, 0, 0, 1, std::numeric_limits<float>::quiet_NaN()), {0, 0, 0, 1}), -1.0f);
}

TEST(RaySphere, PointsAndZeroDirection) {
  // A sphere of radius 0 is a point: hit exactly when the line goes through it.
  EXPECT_EQ(hit_t(ray(0, 0, 0, 0, 0, 1), {0, 0, 5, 0}), 5.0f);
  EXPECT_EQ(hit_t(ray(0, 0, 0, 1, 1, 0), {3, 3, 0, 0}), 3.0f);
  EXPECT_EQ(hit_t(ray(0, 0, 0, 0, 0, 1), {1e-6f, 0, 5, 0}), -1.0f);
  EXPECT_EQ(hit_t(ray(0, 0, 5, 0, 0, 1), {0, 0, 5, 0}), 0.0f) << "origin at the point";
  // A zero direction hits nothing, not even a sphere around the origin.
  EXPECT_EQ(hit_t(ray(0, 0, 0, 0, 0, 0), {0, 0, 0, 1}), -1.0f);
}

TEST(RaySphere, AgreesWithLongDouble) {
  // Away from the tangent and the t = max_t boundaries, hit and t agree with the root computed
  // in long double from the same float inputs.
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<float> pos(-50, 50), dir(-1, 1), rad(0, 8), scale(-3, 3);
  int hits = 0, misses = 0;
  for (int k = 0; k < 200000; ++k) {
    const float sc = std::pow(10.0f, scale(rng));
    const Sphere s{pos(rng) * sc, pos(rng) * sc, pos(rng) * sc, rad(rng) * sc};
    // Aimed within about 1.5 radii of the centre (half the rays miss), a fifth of them backwards.
    Ray r = ray(pos(rng) * sc, pos(rng) * sc, pos(rng) * sc, 0, 0, 0);
    const float aim[3] = {s.x + 1.5f * s.r * dir(rng), s.y + 1.5f * s.r * dir(rng), s.z + 1.5f * s.r * dir(rng)};
    const float sign = k % 5 == 0 ? -1.0f : 1.0f;
    for (int c = 0; c < 3; ++c) r.dir[c] = sign * (aim[c] - r.origin[c]);
    using L = long double;
    const L fx = L{r.origin[0]} - s.x, fy = L{r.origin[1]} - s.y, fz = L{r.origin[2]} - s.z;
    const L dx = r.dir[0], dy = r.dir[1], dz = r.dir[2];
    const L a = dx * dx + dy * dy + dz * dz, b = fx * dx + fy * dy + fz * dz;
    const L c = fx * fx + fy * fy + fz * fz - L{s.r} * s.r;
    const L disc = b * b - a * c;
    float t = 0;
    const bool got = ray_hits_sphere(r, s, t);
    const L scale2 = (fx * fx + fy * fy + fz * fz + L{s.r} * s.r) * a;
    if (std::fabs(disc) < 1e-9L * scale2 || std::fabs(c) < 1e-9L * (fx * fx + fy * fy + fz * fz)) continue;
    const bool want = c <= 0 || (disc >= 0 && b < 0);
    ASSERT_EQ(got, want) << "case " << k;
    if (!want) {
      ++misses;
      continue;
    }
    ++hits;
    const L root = c <= 0 ? 0.0L : (-b - std::sqrt(disc)) / a;
    EXPECT_NEAR(static_cast<double>(t), static_cast<double>(root), 1e-5 * static_cast<double>(root) + 1e-30)
        << "case " << k;
  }
  EXPECT_GT(hits, 10000);
  EXPECT_GT(misses, 10000);
}

TEST(RaySphere, HitPointLiesWithinTheMarginOfTheSphere) {
  // What the tree queries rely on: the hit point is within r + ray_box_margin() of the centre,
  // also for rays from far away towards small spheres (where the float-only formula would accept
  // rays passing far outside).
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<float> u(-1, 1);
  int hits = 0;
  for (int k = 0; k < 100000; ++k) {
    const float far = std::pow(10.0f, 2.0f + 15.0f * (u(rng) + 1) / 2);
    const Sphere s{u(rng), u(rng), u(rng), 1e-3f * (u(rng) + 1)};
    // Aim from far away at a point near the sphere.
    Ray r = ray(far * u(rng), far * u(rng), far, 0, 0, 0);
    const float aim[3] = {s.x + 2e-3f * u(rng), s.y + 2e-3f * u(rng), s.z + 2e-3f * u(rng)};
    for (int c = 0; c < 3; ++c) r.dir[c] = aim[c] - r.origin[c];
    float t = 0;
    if (!ray_hits_sphere(r, s, t)) continue;
    ++hits;
    using L = long double;
    const L px = L{r.origin[0]} + L{t} * r.dir[0] - s.x, py = L{r.origin[1]} + L{t} * r.dir[1] - s.y,
            pz = L{r.origin[2]} + L{t} * r.dir[2] - s.z;
    // t is rounded to float: the point moves by up to half an ulp of t along dir.
    const L ulp_move = L{std::nextafter(t, 2 * t + 1) - t} *
                       std::sqrt(L{r.dir[0]} * r.dir[0] + L{r.dir[1]} * r.dir[1] + L{r.dir[2]} * r.dir[2]);
    const L d = std::sqrt(px * px + py * py + pz * pz);
    EXPECT_LE(d, L{s.r} + L{detail::ray_box_margin(r.origin)} + ulp_move) << "case " << k;
  }
  EXPECT_GT(hits, 1000);
}

}  // namespace
}  // namespace viscd
