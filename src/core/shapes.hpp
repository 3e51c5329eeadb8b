#pragma once
// A frame's objects as one view: spheres or axis-aligned boxes (FrameInput::spheres or ::boxes).
// The stages that do not care which (counting, culling, sorting) see only the count; the ones that
// do (drawing, the exact tests, the queries) branch on `kind` once per call, never per object.

#include <cstddef>
#include <span>
#include <vector>

#include "core/geometry.hpp"
#include "viscd/frame.hpp"
#include "viscd/types.hpp"

namespace viscd::detail {

struct Shapes {
  ShapeKind kind = ShapeKind::sphere;
  std::span<const Sphere> spheres;  ///< the objects when kind is sphere
  std::span<const Box> boxes;       ///< the objects when kind is box

  Shapes() = default;
  Shapes(std::span<const Sphere> s) : spheres(s) {}  // NOLINT(google-explicit-constructor): spheres are the default
  Shapes(std::span<const Box> b) : kind(ShapeKind::box), boxes(b) {}     // NOLINT(google-explicit-constructor)
  Shapes(const std::vector<Sphere>& s) : spheres(s) {}                   // NOLINT(google-explicit-constructor)
  Shapes(const std::vector<Box>& b) : kind(ShapeKind::box), boxes(b) {}  // NOLINT(google-explicit-constructor)
  /// The frame's objects: its boxes when it has any, else its spheres.
  static Shapes of(const FrameInput& in) { return in.boxes.empty() ? Shapes(in.spheres) : Shapes(in.boxes); }

  [[nodiscard]] bool is_box() const { return kind == ShapeKind::box; }
  [[nodiscard]] std::size_t size() const { return is_box() ? boxes.size() : spheres.size(); }
  [[nodiscard]] bool empty() const { return size() == 0; }
  /// A box around object k that no exact test reaches beyond (conservative_box() for a sphere,
  /// the box itself for a box).
  [[nodiscard]] Aabb aabb(std::size_t k) const { return is_box() ? box_aabb(boxes[k]) : conservative_box(spheres[k]); }
  /// The queries' exact tests of object k: ray_hits_sphere() / ray_hits_box() (t: the hit's t),
  /// a query sphere (spheres_overlap(), sphere_overlaps_box()), a query box (sphere_overlaps_box(),
  /// boxes_overlap()).
  [[nodiscard]] bool ray_hit(std::size_t k, const Ray& r, float& t) const {
    return is_box() ? ray_box_exact(r.origin, r.dir, r.max_t, boxes[k], t)
                    : ray_sphere(r.origin, r.dir, r.max_t, spheres[k], t);
  }
  [[nodiscard]] bool meets_sphere(std::size_t k, const Sphere& s) const {
    return is_box() ? sphere_box_exact(s, boxes[k].min, boxes[k].max) : overlap_exact(s, spheres[k]);
  }
  [[nodiscard]] bool meets_box(std::size_t k, const Box& b) const {
    return is_box() ? box_overlap_exact(boxes[k], b) : sphere_box_exact(spheres[k], b.min, b.max);
  }
  /// What stages 4-6 see of object k: the sphere itself, or box_proxy().
  [[nodiscard]] Sphere proxy(std::size_t k) const { return is_box() ? box_proxy(boxes[k]) : spheres[k]; }
  /// Fetches object k into the cache ahead of a test (a box of 24 bytes may span two lines).
  void prefetch(std::size_t k) const {
    if (is_box()) {
      const auto* b = reinterpret_cast<const char*>(boxes.data() + k);
      __builtin_prefetch(b);
      __builtin_prefetch(b + sizeof(Box) - 1);
    } else {
      __builtin_prefetch(spheres.data() + k);
    }
  }
  /// The exact overlap test of objects a and b (the same kind).
  [[nodiscard]] bool overlap(std::size_t a, std::size_t b) const {
    return is_box() ? box_overlap_exact(boxes[a], boxes[b]) : overlap_exact(spheres[a], spheres[b]);
  }
};

}  // namespace viscd::detail
