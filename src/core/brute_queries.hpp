#pragma once
// Queries by brute force over given spheres, their object ids (ascending) and filters: the
// answers of the backends that keep no tree for queries (reference, gl), and the definition the
// others are tested against. Exact: ray_hits_sphere() / ray_hits_box(), spheres_overlap(),
// sphere_overlaps_box() and boxes_overlap() on every object. Also the rules every backend shares: which object a
// query filter lets through, and what a RayVisitor's answer does to the ray.

#include <cmath>
#include <cstdint>
#include <span>
#include <vector>

#include "core/shapes.hpp"
#include "viscd/detector.hpp"
#include "viscd/types.hpp"

namespace viscd::detail {

/// The objects a brute-force query searches: the active objects (spheres or boxes), their
/// reported indices (ascending) and their filters (parallel to `shapes`; empty when the frame had
/// none: every object then has Filter{}).
struct QueryObjects {
  Shapes shapes;
  std::span<const std::uint32_t> ids;
  std::span<const Filter> filters;
};

/// Whether a query with `query_filter` (null: none) may report an object with `object_filter`.
[[nodiscard]] inline bool query_passes(const Filter* query_filter, const Filter& object_filter) {
  return query_filter == nullptr || pair_passes_filter(*query_filter, object_filter);
}

/// Applies a RayVisitor's answer `v` to the ray's max t (the rules of RayVisitor): false when the
/// visitor stops the query; a positive v lowers `max_t` to it; a negative or NaN v changes nothing.
[[nodiscard]] inline bool apply_ray_answer(float v, float& max_t) {
  if (v == 0) return false;
  if (v > 0 && v < max_t) max_t = v;
  return true;
}

/// The first hit (smallest t, ties to the smaller id); false when there is none.
[[nodiscard]] bool brute_ray(const QueryObjects& objects, const Ray& ray, const Filter* filter, RayHit& hit);
/// Appends every hit, in the order of `ids` (Detector sorts them by (t, index)).
void brute_ray_all(const QueryObjects& objects, const Ray& ray, const Filter* filter, std::vector<RayHit>& hits);
/// The hits in the order of `ids`, as Detector::ray_cast(ray, visitor) defines them.
void brute_ray_visit(const QueryObjects& objects, const Ray& ray, const Filter* filter, RayVisitor& visitor);
/// Appends the ids of the spheres that overlap `sphere`, in the order of `ids`.
void brute_overlap(const QueryObjects& objects, const Sphere& sphere, const Filter* filter,
                   std::vector<std::uint32_t>& indices);
/// Appends the ids of the spheres that overlap `box` (a valid box), in the order of `ids`.
void brute_overlap_box(const QueryObjects& objects, const Box& box, const Filter* filter,
                       std::vector<std::uint32_t>& indices);
/// brute_overlap() and brute_overlap_box() through a visitor, until it returns false.
void brute_overlap_visit(const QueryObjects& objects, const Sphere& sphere, const Filter* filter,
                         OverlapVisitor& visitor);
void brute_overlap_box_visit(const QueryObjects& objects, const Box& box, const Filter* filter,
                             OverlapVisitor& visitor);

}  // namespace viscd::detail
