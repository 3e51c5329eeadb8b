// Queries by brute force over a backend's QueryObjects (core/brute_queries.hpp): what a backend
// without a structure of its own for queries answers with, and the reference for the others.
#include "core/brute_queries.hpp"

#include "core/backend.hpp"
#include "core/query_rules.hpp"

namespace viscd {

namespace detail {

namespace {
Filter filter_of(const QueryObjects& o, std::size_t k) { return o.filters.empty() ? Filter{} : o.filters[k]; }
}  // namespace

bool brute_ray(const QueryObjects& o, const Ray& ray, const Filter* filter, RayHit& hit) {
  bool found = false;
  for (std::size_t k = 0; k < o.shapes.size(); ++k) {
    float t = 0;
    if (!query_passes(filter, filter_of(o, k)) || !o.shapes.ray_hit(k, ray, t)) continue;
    const RayHit h{o.ids[k], t};
    if (!found || hit_before(h, hit)) hit = h;
    found = true;
  }
  return found;
}

void brute_ray_all(const QueryObjects& o, const Ray& ray, const Filter* filter, std::vector<RayHit>& hits) {
  for (std::size_t k = 0; k < o.shapes.size(); ++k) {
    float t = 0;
    if (query_passes(filter, filter_of(o, k)) && o.shapes.ray_hit(k, ray, t)) hits.push_back({o.ids[k], t});
  }
}

void brute_ray_visit(const QueryObjects& o, const Ray& ray, const Filter* filter, RayVisitor& visitor) {
  Ray r = ray;  // r.max_t is the current max t
  for (std::size_t k = 0; k < o.shapes.size(); ++k) {
    float t = 0;
    if (!query_passes(filter, filter_of(o, k)) || !o.shapes.ray_hit(k, r, t)) continue;
    if (!apply_ray_answer(visitor.on_hit({o.ids[k], t}), r.max_t)) return;
  }
}

void brute_overlap(const QueryObjects& o, const Sphere& sphere, const Filter* filter,
                   std::vector<std::uint32_t>& indices) {
  for (std::size_t k = 0; k < o.shapes.size(); ++k)
    if (query_passes(filter, filter_of(o, k)) && o.shapes.meets_sphere(k, sphere)) indices.push_back(o.ids[k]);
}

void brute_overlap_box(const QueryObjects& o, const Box& box, const Filter* filter,
                       std::vector<std::uint32_t>& indices) {
  for (std::size_t k = 0; k < o.shapes.size(); ++k)
    if (query_passes(filter, filter_of(o, k)) && o.shapes.meets_box(k, box)) indices.push_back(o.ids[k]);
}

void brute_overlap_visit(const QueryObjects& o, const Sphere& sphere, const Filter* filter, OverlapVisitor& visitor) {
  for (std::size_t k = 0; k < o.shapes.size(); ++k)
    if (query_passes(filter, filter_of(o, k)) && o.shapes.meets_sphere(k, sphere) && !visitor.on_overlap(o.ids[k]))
      return;
}

void brute_overlap_box_visit(const QueryObjects& o, const Box& box, const Filter* filter, OverlapVisitor& visitor) {
  for (std::size_t k = 0; k < o.shapes.size(); ++k)
    if (query_passes(filter, filter_of(o, k)) && o.shapes.meets_box(k, box) && !visitor.on_overlap(o.ids[k])) return;
}

Status Backend::validate_objects(const Shapes& objects) {
  return objects.is_box() ? validate_boxes(objects.boxes) : validate_spheres(objects.spheres);
}

bool Backend::query_ray_first(const Ray& ray, const Filter* filter, RayHit& hit) {
  return brute_ray(query_objects(), ray, filter, hit);
}
void Backend::query_ray_all(const Ray& ray, const Filter* filter, std::vector<RayHit>& hits) {
  brute_ray_all(query_objects(), ray, filter, hits);
}
void Backend::query_ray_visit(const Ray& ray, const Filter* filter, RayVisitor& visitor) {
  brute_ray_visit(query_objects(), ray, filter, visitor);
}
void Backend::query_sphere(const Sphere& sphere, const Filter* filter, std::vector<std::uint32_t>& indices) {
  brute_overlap(query_objects(), sphere, filter, indices);
}
void Backend::query_box(const Box& box, const Filter* filter, std::vector<std::uint32_t>& indices) {
  brute_overlap_box(query_objects(), box, filter, indices);
}
void Backend::query_sphere_visit(const Sphere& sphere, const Filter* filter, OverlapVisitor& visitor) {
  brute_overlap_visit(query_objects(), sphere, filter, visitor);
}
void Backend::query_box_visit(const Box& box, const Filter* filter, OverlapVisitor& visitor) {
  brute_overlap_box_visit(query_objects(), box, filter, visitor);
}

}  // namespace detail

}  // namespace viscd
