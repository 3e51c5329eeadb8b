#pragma once
// Helpers shared by the test suites: deterministic random spheres and pair comparisons.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <iterator>
#include <limits>
#include <memory>
#include <numeric>
#include <ostream>
#include <random>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "viscd/viscd.hpp"

namespace viscd {
// GoogleTest prints these by value.
inline void PrintTo(const RayHit& h, std::ostream* os) { *os << "{index " << h.index << ", t " << h.t << "}"; }
inline void PrintTo(const Pair& p, std::ostream* os) { *os << "(" << p.i << "," << p.j << ")"; }
}  // namespace viscd

namespace viscd::test {

/// A frame from the caller's id map: w x h ids (0 background, k + 1 object k).
inline FrameInput id_map_input(std::span<const Sphere> spheres, const Camera* camera,
                               std::span<const std::uint32_t> ids, int w, int h) {
  FrameInput in;
  in.spheres = spheres;
  in.camera = camera;
  in.id_map = ids;
  in.id_map_width = w;
  in.id_map_height = h;
  return in;
}

/// The indices 0 .. n-1: every object active.
inline std::vector<std::uint32_t> all_of(std::size_t n) {
  std::vector<std::uint32_t> a(n);
  std::iota(a.begin(), a.end(), 0u);
  return a;
}

/// n spheres with centres uniform in [-half_extent, half_extent]^3 and radii uniform in
/// [rmin, rmax] (std::mt19937_64 seeded with `seed`).
inline std::vector<Sphere> random_spheres_by_half_extent(std::size_t n, std::uint64_t seed, float half_extent = 10,
                                                         float rmin = 0.1f, float rmax = 1.0f) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> c(-half_extent, half_extent), r(rmin, rmax);
  std::vector<Sphere> s(n);
  for (auto& sp : s) sp = {c(rng), c(rng), c(rng), r(rng)};
  return s;
}

/// `count` pairs of spheres near (1e5, 0, -1e5), where boxes round the most, whose float overlap
/// test sits exactly at equality or one ulp to either side (the second radius is chosen so).
inline std::vector<Sphere> float_boundary_pairs(int count, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1, 1);
  std::vector<Sphere> s;
  for (int k = 0; k < count; ++k) {
    const float cx = 1e5f + u(rng) * 1000, cy = u(rng) * 50, cz = -1e5f + u(rng) * 1000;
    const float dx = u(rng) * 3, dy = u(rng) * 3, dz = u(rng) * 3;
    const Sphere a{cx, cy, cz, std::fabs(u(rng)) + 0.1f};
    Sphere b{cx + dx, cy + dy, cz + dz, 0};
    const float fx = a.x - b.x, fy = a.y - b.y, fz = a.z - b.z;
    const float d = std::sqrt(fx * fx + fy * fy + fz * fz);
    b.r = std::nextafter(std::max(0.0f, d - a.r), (k % 3 == 0) ? 0.0f : (k % 3 == 1) ? 1e9f : b.r);
    s.push_back(a);
    s.push_back(b);
  }
  return s;
}

/// The pairs among spheres[active] (or all) by spheres_overlap(), the oracle written independently
/// here: every pair is tested that a sweep along x cannot rule out, in the order of brute force
/// (by position in `active`); a pair whose y intervals are apart is not tested either. The sweep is
/// conservative: the float test accepts a pair only when |x_a - x_b| (and |y_a - y_b|) is within
/// r_a + r_b plus a few ulps of the coordinates and radii (or a tiny absolute amount where the
/// squares underflow), and each interval here is widened by far more: 2^-12 of (max |coordinate|
/// + r), plus 1e-18. Spheres with a coordinate or radius above 1e15 in
/// magnitude (where the squares may overflow), a negative radius or one not finite are tested
/// against every other one.
inline std::vector<Pair> oracle_pairs(std::span<const Sphere> s, const std::vector<std::uint32_t>* active = nullptr) {
  std::vector<std::uint32_t> all;
  if (!active) {
    for (std::uint32_t k = 0; k < s.size(); ++k) all.push_back(k);
    active = &all;
  }
  const std::vector<std::uint32_t>& act = *active;
  const std::size_t n = act.size();
  std::vector<double> lo(n), hi(n), ylo(n), yhi(n);
  std::vector<std::uint32_t> swept, odd;  // positions in `act`
  for (std::uint32_t a = 0; a < n; ++a) {
    const Sphere& p = s[act[a]];
    const double m = std::max({std::fabs(p.x), std::fabs(p.y), std::fabs(p.z), std::fabs(p.r)});
    const double r = static_cast<double>(p.r) + (m + std::fabs(p.r)) * 0x1p-12 + 1e-18;
    lo[a] = static_cast<double>(p.x) - r;
    hi[a] = static_cast<double>(p.x) + r;
    ylo[a] = static_cast<double>(p.y) - r;
    yhi[a] = static_cast<double>(p.y) + r;
    (m <= 1e15 && p.r >= 0 ? swept : odd).push_back(a);  // false for NaN
  }
  std::sort(swept.begin(), swept.end(), [&](std::uint32_t a, std::uint32_t b) { return lo[a] < lo[b]; });
  // The swept intervals in their sorted order, side by side, so that the inner loop reads memory
  // in order (it passes over every sphere within reach along x: hundreds in the dense tests).
  const std::size_t m = swept.size();
  std::vector<double> slo(m), shi(m), sylo(m), syhi(m);
  for (std::size_t k = 0; k < m; ++k) {
    slo[k] = lo[swept[k]];
    shi[k] = hi[swept[k]];
    sylo[k] = ylo[swept[k]];
    syhi[k] = yhi[swept[k]];
  }
  std::vector<std::pair<std::uint32_t, std::uint32_t>> found;  // positions, first < second
  auto test = [&](std::uint32_t a, std::uint32_t b) {
    if (spheres_overlap(s[act[a]], s[act[b]])) found.emplace_back(std::min(a, b), std::max(a, b));
  };
  for (std::size_t k = 0; k < m; ++k) {
    const double h = shi[k], yl = sylo[k], yh = syhi[k];
    for (std::size_t l = k + 1; l < m && slo[l] <= h; ++l)
      if (sylo[l] <= yh && yl <= syhi[l]) test(swept[k], swept[l]);
  }
  for (std::size_t k = 0; k < odd.size(); ++k) {
    for (std::uint32_t b : swept) test(odd[k], b);
    for (std::size_t l = k + 1; l < odd.size(); ++l) test(odd[k], odd[l]);
  }
  std::sort(found.begin(), found.end());
  std::vector<Pair> out;
  out.reserve(found.size());
  for (const auto& [a, b] : found) out.push_back({act[a], act[b]});
  return out;
}

/// Brute-force pairs among spheres[active] (or all) whose filters accept each other, with the
/// filter rule written out here: (group_i & mask_j) != 0 and (group_j & mask_i) != 0.
inline std::vector<Pair> oracle_filtered_pairs(std::span<const Sphere> s, std::span<const Filter> f,
                                               const std::vector<std::uint32_t>* active = nullptr) {
  std::vector<Pair> out;
  for (const Pair& p : oracle_pairs(s, active))
    if ((f[p.i].group & f[p.j].mask) != 0 && (f[p.j].group & f[p.i].mask) != 0) out.push_back(p);
  return out;
}

/// n filters drawn from a few groups and masks (including group 0, mask 0 and one-sided masks),
/// deterministic in `seed`.
inline std::vector<Filter> random_filters(std::size_t n, std::uint64_t seed) {
  static constexpr std::uint32_t kGroups[] = {1, 1, 2, 4, 1 | 2, 0, 0x80000000u};
  static constexpr std::uint32_t kMasks[] = {0xFFFFFFFFu, 1, 2, 1 | 4, 0, 0x80000000u | 2, 0xFFFFFFFEu};
  std::mt19937_64 rng(seed);
  std::vector<Filter> f(n);
  for (Filter& x : f) x = {kGroups[rng() % std::size(kGroups)], kMasks[rng() % std::size(kMasks)]};
  return f;
}

/// Every hit of `ray` on spheres[active] (or all) by the library's ray_hits_sphere(), sorted by
/// (t, index): the queries' oracle.
inline std::vector<RayHit> oracle_hits(std::span<const Sphere> s, const Ray& ray,
                                       const std::vector<std::uint32_t>* active = nullptr) {
  std::vector<RayHit> out;
  for (std::uint32_t k = 0; k < s.size(); ++k) {
    if (active && !std::binary_search(active->begin(), active->end(), k)) continue;
    float t = 0;
    if (ray_hits_sphere(ray, s[k], t)) out.push_back({k, t});
  }
  std::sort(out.begin(), out.end(),
            [](const RayHit& a, const RayHit& b) { return a.t < b.t || (a.t == b.t && a.index < b.index); });
  return out;
}

/// The objects of spheres[active] (or all) that overlap `q` by spheres_overlap(), ascending.
inline std::vector<std::uint32_t> oracle_overlap(std::span<const Sphere> s, const Sphere& q,
                                                 const std::vector<std::uint32_t>* active = nullptr) {
  std::vector<std::uint32_t> out;
  for (std::uint32_t k = 0; k < s.size(); ++k) {
    if (active && !std::binary_search(active->begin(), active->end(), k)) continue;
    if (spheres_overlap(q, s[k])) out.push_back(k);
  }
  return out;
}

/// began = now \ before and ended = before \ now, by std::set_difference.
inline void oracle_events(const std::vector<Pair>& before, const std::vector<Pair>& now, std::vector<Pair>& began,
                          std::vector<Pair>& ended) {
  began.clear();
  ended.clear();
  std::set_difference(now.begin(), now.end(), before.begin(), before.end(), std::back_inserter(began));
  std::set_difference(before.begin(), before.end(), now.begin(), now.end(), std::back_inserter(ended));
}

/// Runs a detector on one frame and returns the result; fails the test on error.
inline FrameResult run_frame(Detector& d, std::span<const Sphere> s, const Camera* cam = nullptr) {
  FrameResult f;
  const Status st = d.detect(s, cam, f);
  EXPECT_TRUE(st.ok()) << d.name() << ": " << st.error();
  return f;
}

/// Pair lists must be identical; reports the first difference.
inline ::testing::AssertionResult same_pairs(const std::vector<Pair>& got, const std::vector<Pair>& want) {
  for (std::size_t k = 0; k < std::min(got.size(), want.size()); ++k)
    if (!(got[k] == want[k]))
      return ::testing::AssertionFailure() << "pair " << k << " differs: got (" << got[k].i << "," << got[k].j
                                           << ") want (" << want[k].i << "," << want[k].j << ")";
  if (got.size() != want.size())
    return ::testing::AssertionFailure() << "got " << got.size() << " pairs, want " << want.size();
  return ::testing::AssertionSuccess();
}

inline Config config_bits(Bits b, Layout l = Layout::extended) {
  Config c;
  c.bits = b;
  c.layout = l;
  return c;
}

inline constexpr float kInf = std::numeric_limits<float>::infinity();

/// The box from (x0, y0, z0) to (x1, y1, z1).
inline Box make_box(float x0, float y0, float z0, float x1, float y1, float z1) {
  Box b;
  b.min[0] = x0, b.min[1] = y0, b.min[2] = z0;
  b.max[0] = x1, b.max[1] = y1, b.max[2] = z1;
  return b;
}

/// The detectors that answer queries on the cpu: the cpu backend and the reference.
using Factory = std::unique_ptr<Detector> (*)(const Config&);
inline constexpr Factory kBackends[] = {make_cpu_detector, make_reference_detector};

/// A ray in words, for failure messages.
inline std::string describe(const Ray& r) {
  char buf[220];
  std::snprintf(buf, sizeof buf, "ray (%.9g, %.9g, %.9g) + t (%.9g, %.9g, %.9g), max_t %.9g", r.origin[0], r.origin[1],
                r.origin[2], r.dir[0], r.dir[1], r.dir[2], r.max_t);
  return buf;
}

/// A ray from (ox, oy, oz) along (dx, dy, dz) up to max_t.
inline Ray make_ray(float ox, float oy, float oz, float dx, float dy, float dz,
                    float max_t = std::numeric_limits<float>::infinity()) {
  Ray r;
  r.origin[0] = ox, r.origin[1] = oy, r.origin[2] = oz;
  r.dir[0] = dx, r.dir[1] = dy, r.dir[2] = dz;
  r.max_t = max_t;
  return r;
}

/// A ray visitor that keeps every hit (returns infinity: the max t stays).
struct AllHits final : RayVisitor {
  std::vector<RayHit> hits;
  float on_hit(const RayHit& h) override {
    hits.push_back(h);
    return std::numeric_limits<float>::infinity();
  }
};

}  // namespace viscd::test
