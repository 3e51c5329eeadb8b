#pragma once
// Small vector and box types for the core, the exact sphere test in its one hot-path form, and
// the ray-sphere test of the queries.

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

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

/// The ray-sphere test of the queries (ray_hits_sphere(); docs/architecture.md, "Queries"): the
/// smallest t in [0, max_t] with origin + t * dir inside or on the sphere, rounded to float. In
/// double from the float inputs (exact conversions; no product or sum of floats overflows there):
///   f = origin - centre, a = dir.dir, c = f.f - r^2;  c <= 0: the origin is inside, t = 0;
///   else b = f.dir must be < 0 (the sphere lies ahead), the closest approach l = f - (b/a) dir,
///   disc = r^2 - l.l >= 0 (the line reaches the sphere; no cancellation of b^2 - a c), and
///   t = c / (sqrt(a disc) - b), the smaller root in the form without cancellation.
/// Its hit point origin + t * dir lies within r + 2^-40 (|origin| + |centre| + r) of the centre;
/// the tree queries widen their boxes by that much (ray_box_margin()), so no hit is missed.
/// Preconditions: finite inputs (Detector checks them); a zero direction hits nothing.
inline bool ray_sphere(const float origin[3], const float dir[3], float max_t, const Sphere& s, float& t_out) {
  const double fx = double{origin[0]} - s.x, fy = double{origin[1]} - s.y, fz = double{origin[2]} - s.z;
  const double dx = dir[0], dy = dir[1], dz = dir[2];
  const double a = dx * dx + dy * dy + dz * dz;
  if (a == 0) return false;
  const double r = s.r;
  const double c = fx * fx + fy * fy + fz * fz - r * r;
  double t = 0;
  if (c > 0) {
    const double b = fx * dx + fy * dy + fz * dz;
    if (!(b < 0)) return false;
    const double k = b / a;
    const double lx = fx - k * dx, ly = fy - k * dy, lz = fz - k * dz;
    const double disc = r * r - (lx * lx + ly * ly + lz * lz);
    if (!(disc >= 0)) return false;
    t = c / (std::sqrt(a * disc) - b);
  }
  const auto tf = static_cast<float>(t);
  if (!(tf <= max_t)) return false;
  t_out = tf;
  return true;
}

/// The sphere-box test of the queries (sphere_overlaps_box(); docs/architecture.md, "Queries"):
/// the squared distance from the centre to the closed box [lo, hi], in double from the float
/// inputs, against r^2, touching counts:
///   e_k = lo_k - c_k when c_k < lo_k, c_k - hi_k when c_k > hi_k, else 0 (per axis, x, y, z);
///   d2 = (e_x^2 + e_y^2) + e_z^2;  overlap when d2 <= r^2.
/// Every backend calls this one function, so all agree bit for bit. No sum or product of floats
/// overflows or underflows to zero in double here, and the roundings (a few units of 2^-53) are
/// far inside conservative_box()'s margin, so a tree over conservative boxes never rejects what
/// this accepts. Preconditions: finite inputs with lo <= hi (Detector checks the box, and
/// validate_spheres() the sphere); a NaN centre would count as inside, so callers skip padding.
inline bool sphere_box_exact(const Sphere& s, const float lo[3], const float hi[3]) {
  const double c[3] = {s.x, s.y, s.z};
  double d2 = 0;
  for (int k = 0; k < 3; ++k) {
    const double e = c[k] < lo[k] ? double{lo[k]} - c[k] : c[k] > hi[k] ? c[k] - double{hi[k]} : 0.0;
    d2 += e * e;
  }
  const double r = s.r;
  return d2 <= r * r;
}

/// The box test (boxes_overlap()): closed intervals on every axis, in float; false on NaN.
inline bool box_overlap_exact(const Box& a, const Box& b) {
  return (a.min[0] <= b.max[0]) & (b.min[0] <= a.max[0]) & (a.min[1] <= b.max[1]) & (b.min[1] <= a.max[1]) &
         (a.min[2] <= b.max[2]) & (b.min[2] <= a.max[2]);
}
/// A box object as the tree's Aabb: itself (the box test is the same comparisons as overlaps(),
/// so no margin is needed).
inline Aabb box_aabb(const Box& b) { return Aabb{{b.min[0], b.min[1], b.min[2]}, {b.max[0], b.max[1], b.max[2]}}; }
/// What stages 4-6 see of a box: its centre ((min + max) / 2 in float; no overflow within
/// kMaxCoordinate) and, as the "radius", a sixth of its summed side lengths, so that the layout
/// rule's mean diameter is the boxes' mean side length.
inline Sphere box_proxy(const Box& b) {
  return Sphere{(b.min[0] + b.max[0]) * 0.5f, (b.min[1] + b.max[1]) * 0.5f, (b.min[2] + b.max[2]) * 0.5f,
                ((b.max[0] - b.min[0]) + (b.max[1] - b.min[1]) + (b.max[2] - b.min[2])) / 6.0f};
}

/// The ray-box test of the queries (ray_hits_box(); docs/architecture.md, "Queries"): slabs in
/// double from the float inputs. Along an axis with d = 0 the origin must lie in [lo, hi]; else
/// the slab is entered at (lo - o) / d and left at (hi - o) / d (the other way round for d < 0).
/// t0 = max(0, entries), t1 = min(exits); a hit when t0 <= t1 and t0, rounded to float, is at most
/// max_t. Preconditions: finite inputs, lo <= hi; a zero direction hits nothing.
inline bool ray_box_exact(const float origin[3], const float dir[3], float max_t, const Box& b, float& t_out) {
  if (dir[0] == 0 && dir[1] == 0 && dir[2] == 0) return false;
  double t0 = 0, t1 = std::numeric_limits<double>::infinity();
  for (int k = 0; k < 3; ++k) {
    const double o = origin[k], lo = b.min[k], hi = b.max[k];
    if (dir[k] == 0) {
      if (o < lo || o > hi) return false;
      continue;
    }
    const double d = dir[k];
    double a = (lo - o) / d, e = (hi - o) / d;
    if (a > e) std::swap(a, e);
    t0 = std::max(t0, a);
    t1 = std::min(t1, e);
  }
  if (!(t0 <= t1)) return false;
  const auto tf = static_cast<float>(t0);
  if (!(tf <= max_t)) return false;
  t_out = tf;
  return true;
}

/// How far beyond a sphere's conservative box ray_sphere()'s hit point can lie for a ray from
/// `origin`: its rounding in double is below 2^-46 of |origin| + |centre| + r; the box already
/// covers 2^-19 of |centre| + r, and this covers the origin's part with room to spare (2^-32), and
/// the rounding of the slab test that uses it.
inline double ray_box_margin(const float origin[3]) {
  return 0x1p-32 * (std::fabs(double{origin[0]}) + std::fabs(double{origin[1]}) + std::fabs(double{origin[2]})) + 1e-30;
}

}  // namespace viscd::detail
