#pragma once
// Helpers shared by the test suites: deterministic random spheres and pair comparisons.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <span>
#include <string>
#include <vector>

#include "viscd/viscd.hpp"

namespace viscd::test {

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

/// Brute-force pairs among spheres[active] (or all), the oracle written independently here.
inline std::vector<Pair> oracle_pairs(std::span<const Sphere> s, const std::vector<std::uint32_t>* active = nullptr) {
  std::vector<std::uint32_t> all;
  if (!active) {
    for (std::uint32_t k = 0; k < s.size(); ++k) all.push_back(k);
    active = &all;
  }
  std::vector<Pair> out;
  for (std::size_t a = 0; a < active->size(); ++a)
    for (std::size_t b = a + 1; b < active->size(); ++b) {
      const Sphere &p = s[(*active)[a]], &q = s[(*active)[b]];
      if (spheres_overlap(p, q)) out.push_back({(*active)[a], (*active)[b]});
    }
  return out;
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

}  // namespace viscd::test
