#pragma once
// Queries by brute force over given spheres and their object ids (ascending): the answers of the
// backends that keep no tree for queries (reference, gl), and the definition the others are
// tested against. Exact: ray_hits_sphere() and spheres_overlap() on every sphere.

#include <cstdint>
#include <span>
#include <vector>

#include "viscd/types.hpp"

namespace viscd::detail {

/// The first hit (smallest t, ties to the smaller id); false when there is none.
[[nodiscard]] bool brute_ray(std::span<const Sphere> spheres, std::span<const std::uint32_t> ids, const Ray& ray,
                             RayHit& hit);
/// Appends every hit, then sorts `hits` by (t, id).
void brute_ray_all(std::span<const Sphere> spheres, std::span<const std::uint32_t> ids, const Ray& ray,
                   std::vector<RayHit>& hits);
/// Appends the ids of the spheres that overlap `sphere`, in the order of `ids`.
void brute_overlap(std::span<const Sphere> spheres, std::span<const std::uint32_t> ids, const Sphere& sphere,
                   std::vector<std::uint32_t>& indices);

}  // namespace viscd::detail
