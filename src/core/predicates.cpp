// The public geometric predicates: the exact tests every backend and query uses
// (core/geometry.hpp), with the checks a caller's input gets.
#include "core/geometry.hpp"
#include "core/query_rules.hpp"
#include "viscd/detector.hpp"

namespace viscd {

bool spheres_overlap(const Sphere& a, const Sphere& b) { return detail::overlap_exact(a, b); }

bool ray_hits_sphere(const Ray& ray, const Sphere& sphere, float& t) {
  return detail::ray_sphere(ray.origin, ray.dir, ray.max_t, sphere, t);
}

bool sphere_overlaps_box(const Sphere& sphere, const Box& box) {
  return detail::valid_query_sphere(sphere) && detail::valid_query_box(box) &&
         detail::sphere_box_exact(sphere, box.min, box.max);
}

bool boxes_overlap(const Box& a, const Box& b) { return detail::box_overlap_exact(a, b); }

bool ray_hits_box(const Ray& ray, const Box& box, float& t) {
  return validate_boxes({&box, 1}).ok() && detail::ray_box_exact(ray.origin, ray.dir, ray.max_t, box, t);
}

}  // namespace viscd
