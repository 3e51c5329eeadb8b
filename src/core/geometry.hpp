#pragma once
// Small vector and box types for the core, and the exact sphere test in its one hot-path form.

#include <algorithm>
#include <cmath>
#include <limits>

#include "viscd/types.hpp"

namespace viscd::detail {

struct Vec3 {
  float x = 0, y = 0, z = 0;
};

/// Axis-aligned box; `empty()` boxes have lo > hi.
struct Aabb {
  Vec3 lo{std::numeric_limits<float>::infinity(), std::numeric_limits<float>::infinity(),
          std::numeric_limits<float>::infinity()};
  Vec3 hi{-std::numeric_limits<float>::infinity(), -std::numeric_limits<float>::infinity(),
          -std::numeric_limits<float>::infinity()};

  void grow(const Aabb& b) {
    lo = {std::min(lo.x, b.lo.x), std::min(lo.y, b.lo.y), std::min(lo.z, b.lo.z)};
    hi = {std::max(hi.x, b.hi.x), std::max(hi.y, b.hi.y), std::max(hi.z, b.hi.z)};
  }
  void grow(float x, float y, float z) {
    lo = {std::min(lo.x, x), std::min(lo.y, y), std::min(lo.z, z)};
    hi = {std::max(hi.x, x), std::max(hi.y, y), std::max(hi.z, z)};
  }
  [[nodiscard]] bool contains(const Aabb& b) const {
    return lo.x <= b.lo.x && lo.y <= b.lo.y && lo.z <= b.lo.z && hi.x >= b.hi.x && hi.y >= b.hi.y && hi.z >= b.hi.z;
  }
};

/// Closed-interval overlap (touching boxes overlap). Bitwise & rather than &&: in a traversal the
/// outcome of each comparison is unpredictable, and one branch on the result costs less than six.
inline bool overlaps(const Aabb& a, const Aabb& b) {
  return (a.lo.x <= b.hi.x) & (b.lo.x <= a.hi.x) & (a.lo.y <= b.hi.y) & (b.lo.y <= a.hi.y) & (a.lo.z <= b.hi.z) &
         (b.lo.z <= a.hi.z);
}

/// The overlap test (docs/architecture.md, "Contracts"), exactly as every backend evaluates it:
/// float, touching counts, no FMA (the library is compiled with -ffp-contract=off).
inline bool overlap_exact(const Sphere& a, const Sphere& b) {
  const float dx = a.x - b.x, dy = a.y - b.y, dz = a.z - b.z;
  const float s = a.r + b.r;
  return dx * dx + dy * dy + dz * dz <= s * s;
}

/// A box that contains every point the float overlap test can accept for this sphere.
///
/// The float test can accept spheres whose true distance exceeds r_i + r_j by a few ulps
/// (rounding of the differences, squares and sums: at most ~5 units of 2^-24 relative), or, when
/// the squares underflow to subnormals or zero, by up to ~4e-23 absolute. Computing c +- r in
/// float rounds too. Inflating r by 2^-19 (16 ulps) of (|c|max + r), plus 1e-21 absolute, covers
/// all of it, so the tree never rejects a pair the exact test accepts; the extra candidates it
/// lets through are rejected by overlap_exact. (docs/architecture.md, "Exactness".)
inline float conservative_half_extent(const Sphere& s) {
  const float m = std::max({std::fabs(s.x), std::fabs(s.y), std::fabs(s.z)});
  return s.r + (m + s.r) * 0x1p-19f + 1e-21f;
}
inline Aabb conservative_box(const Sphere& s) {
  const float r = conservative_half_extent(s);
  return Aabb{{s.x - r, s.y - r, s.z - r}, {s.x + r, s.y + r, s.z + r}};
}

}  // namespace viscd::detail
