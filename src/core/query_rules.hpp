#pragma once
// The checks every query makes on its input, and the order of ray hits, shared by the Detector's
// queries (detector.cpp), the public predicates (predicates.cpp) and the brute-force queries.

#include <cmath>
#include <span>

#include "viscd/detector.hpp"
#include "viscd/types.hpp"

namespace viscd::detail {

/// A query sphere: what validate_spheres() takes.
[[nodiscard]] inline bool valid_query_sphere(const Sphere& s) {
  return validate_spheres(std::span<const Sphere>(&s, 1)).ok();
}

/// A query box: finite bounds, min <= max on every axis (false for NaN too).
[[nodiscard]] inline bool valid_query_box(const Box& b) {
  for (int k = 0; k < 3; ++k)
    if (!std::isfinite(b.min[k]) || !std::isfinite(b.max[k]) || !(b.min[k] <= b.max[k])) return false;
  return true;
}

/// A query ray: finite origin and direction, a direction that is not zero, max_t >= 0 (false for
/// a NaN max_t too).
[[nodiscard]] inline bool valid_ray(const Ray& r) {
  for (int k = 0; k < 3; ++k)
    if (!std::isfinite(r.origin[k]) || !std::isfinite(r.dir[k])) return false;
  const bool moves = r.dir[0] != 0 || r.dir[1] != 0 || r.dir[2] != 0;
  return moves && r.max_t >= 0;
}

/// Hits sort by (t, index).
[[nodiscard]] inline bool hit_before(const RayHit& a, const RayHit& b) {
  return a.t < b.t || (a.t == b.t && a.index < b.index);
}

}  // namespace viscd::detail
