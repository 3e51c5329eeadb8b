// The queries on the cpu broadphase's last tree (docs/architecture.md, "Queries"): rays (first hit,
// all hits) and sphere overlaps. A ray walks the 16-wide tree nearest child first with slab tests
// in double against boxes widened by ray_box_margin() (cpu/simd.hpp: ray_children, ray_lanes), so
// no hit is missed; candidates get the exact test ray_sphere(). Overlaps walk the tree with the
// sphere's conservative box and test 16 lanes at a time with overlap_exact(); box overlaps walk it
// with the box itself and test each lane with sphere_box_exact(). The visitor forms walk the same
// way and stop the walk when the visitor says so; a ray visitor that lowers the max t prunes it.
// A query filter is checked before the exact test (Objects: the frame's filters in sorted order).

#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>

#include "cpu/bucket_broadphase.hpp"
#include "cpu/simd.hpp"

namespace viscd::detail {
namespace {

// One callable made of several lambdas: an exact test for sphere lanes and one for box lanes.
template <class... F>
struct Overloaded : F... {
  using F::operator()...;
};
template <class... F>
Overloaded(F...) -> Overloaded<F...>;

// ray_children() at the tree's SIMD level: eight lanes at a time with AVX-512, else two (SSE2).
template <class N>
inline std::uint32_t ray_children_at(SimdLevel level, const RaySetup& q, const N& n, double t_hi, double* t_enter) {
#if VISCD_HAVE_AVX512
  if (level == SimdLevel::avx512) return ray_children_avx512(q, n, t_hi, t_enter);
#else
  (void)level;
#endif
  return ray_children(q, n, t_hi, t_enter);
}

// Every t whose float rounding is at most `limit` is at most this. (For a limit of 0 this is the
// smallest positive float: hits at t = 0 stay in reach.)
inline double upper_t(float limit) {
  return static_cast<double>(std::nextafter(limit, std::numeric_limits<float>::infinity()));
}

}  // namespace

template <class Visit>
void BucketBroadphase::ray_walk(const Ray& ray, double& t_hi, Visit&& visit) const {
  if (tree_.levels == 0) return;
  const RaySetup q(ray, holds_boxes() ? box_ray_margin() : 0.0);
  // Depth first from the top node; a node's children that the ray meets are pushed farthest first,
  // so the nearest is searched first, and an entry whose box starts beyond t_hi (which the visits
  // may lower) is skipped. Level -1 entries are buckets. At most 16 entries wait per level.
  struct Entry {
    std::int32_t level;
    std::uint32_t index;
    double t;
  };
  Entry stack[kWide * (kWideMaxLevels + 1)];
  int sp = 0;
  stack[sp++] = {static_cast<std::int32_t>(tree_.levels) - 1, 0, 0.0};
  while (sp > 0) {
    const Entry e = stack[--sp];
    if (e.t > t_hi) continue;
    if (e.level < 0) {
      visit(q, e.index);
      continue;
    }
    const WideNode& nd = tree_.level[static_cast<std::size_t>(e.level)][e.index];
    double t_enter[kWide];
    Entry hit[kWide];
    int hits = 0;
    for (std::uint32_t m = ray_children_at(simd_, q, nd, t_hi, t_enter); m; m &= m - 1) {
      const auto l = static_cast<std::uint32_t>(std::countr_zero(m));
      // Insertion by t, farthest first.
      const Entry x{e.level - 1, e.index * kWide + l, t_enter[l]};
      int h = hits++;
      for (; h > 0 && hit[h - 1].t < x.t; --h) hit[h] = hit[h - 1];
      hit[h] = x;
    }
    for (int h = 0; h < hits; ++h) stack[sp++] = hit[h];
  }
}

template <class Hit>
void BucketBroadphase::ray_hits(const Ray& ray, const Objects& objects, const Filter* filter, double& t_hi,
                                const float& max_t, Hit&& hit) const {
  if (holds_boxes()) {
    // Box lanes: the widened slab test on all 16 (padding and erased lanes are NaN and fail),
    // then ray_box_exact() on those it passes.
    ray_walk(ray, t_hi, [&](const RaySetup& q, std::uint32_t b) {
      const BoxLanes& ln = buckets_.box_lanes()[b];
      const std::size_t first = std::size_t{b} * kBucket;
      double t_enter[kBucket];
      for (std::uint32_t m = ray_children_at(simd_, q, ln, t_hi, t_enter); m && t_hi >= 0; m &= m - 1) {
        const auto l = static_cast<std::uint32_t>(std::countr_zero(m));
        if (!passes(filter, first + l, objects)) continue;
        float t = 0;
        if (ray_box_exact(ray.origin, ray.dir, max_t, ln.object(l), t)) hit(reported(first + l, objects), t);
      }
    });
    return;
  }
  ray_walk(ray, t_hi, [&](const RaySetup& q, std::uint32_t b) {
    const BucketLanes& ln = buckets_.lanes()[b];
    const std::size_t first = std::size_t{b} * kBucket;
    for (std::uint32_t m = ray_lanes(q, ln, t_hi); m && t_hi >= 0; m &= m - 1) {
      const auto l = static_cast<std::uint32_t>(std::countr_zero(m));
      if (!passes(filter, first + l, objects)) continue;
      float t = 0;
      if (ray_sphere(ray.origin, ray.dir, max_t, Sphere{ln.x[l], ln.y[l], ln.z[l], ln.r[l]}, t))
        hit(reported(first + l, objects), t);
    }
  });
}

bool BucketBroadphase::ray_first(const Ray& ray, const Objects& objects, const Filter* filter, RayHit& best,
                                 bool found) const {
  const float max_t = ray.max_t;
  double t_hi = upper_t(found ? std::min(best.t, ray.max_t) : ray.max_t);
  ray_hits(ray, objects, filter, t_hi, max_t, [&](std::uint32_t index, float t) {
    if (found && (t > best.t || (t == best.t && index > best.index))) return;
    best = {index, t};
    found = true;
    t_hi = upper_t(t);
  });
  return found;
}

void BucketBroadphase::ray_all(const Ray& ray, const Objects& objects, const Filter* filter,
                               std::vector<RayHit>& hits) const {
  double t_hi = upper_t(ray.max_t);
  ray_hits(ray, objects, filter, t_hi, ray.max_t, [&](std::uint32_t index, float t) { hits.push_back({index, t}); });
}

bool BucketBroadphase::ray_visit(const Ray& ray, const Objects& objects, const Filter* filter, float& max_t,
                                 RayVisitor& visitor) const {
  // The walk prunes by t_hi, which follows max_t as the visitor lowers it: every hit with
  // t <= the final max t is still reached, and boxes beyond it are skipped.
  double t_hi = upper_t(max_t);
  bool go_on = true;
  ray_hits(ray, objects, filter, t_hi, max_t, [&](std::uint32_t index, float t) {
    if (!apply_ray_answer(visitor.on_hit({index, t}), max_t)) {
      go_on = false;
      t_hi = -1;  // ends the walk: every entry and lane starts at t >= 0
      return;
    }
    t_hi = upper_t(max_t);
  });
  return go_on;
}

template <class Exact, class Found>
bool BucketBroadphase::overlap_walk(const Aabb& box, const Objects& objects, const Filter* filter, Exact&& exact,
                                    Found&& found) const {
  const std::size_t n = order_.sorted_ids().size();
  if (n == 0) return true;
  bool go_on = true;
  const bool boxes = holds_boxes();
  // The shared walk, told to enter nothing more once the visitor stopped: what is left of the
  // nodes already on its stack (at most 15 entries a level) is skipped without a box test.
  const auto keep = [&](std::uint32_t, std::uint32_t) -> std::uint32_t { return go_on ? 0xFFFFu : 0u; };
  const auto visit = [&](std::uint32_t b) {
    if (!go_on) return;
    const std::size_t first = std::size_t{b} * kBucket;
    if (boxes) {
      // The lanes whose boxes meet the walk's box (padding and erased lanes are NaN and fail),
      // then the exact test.
      const BoxLanes& ln = buckets_.box_lanes()[b];
      for (std::uint32_t m = SimdBaseline::node_children(ln, box); m && go_on; m &= m - 1) {
        const auto l = static_cast<std::uint32_t>(std::countr_zero(m));
        if (!passes(filter, first + l, objects) || !exact(ln.object(l))) continue;
        go_on = found(reported(first + l, objects));
      }
      return;
    }
    const BucketLanes& ln = buckets_.lanes()[b];
    // Only the lanes in use, and of those not the ones taken out (erase(): NaN centres, which
    // sphere_box_exact() would count as inside).
    const std::size_t lanes = std::min<std::size_t>(kBucket, n - first);
    for (std::size_t l = 0; l < lanes && go_on; ++l) {
      if (std::isnan(ln.x[l])) continue;
      if (!passes(filter, first + l, objects) || !exact(Sphere{ln.x[l], ln.y[l], ln.z[l], ln.r[l]})) continue;
      go_on = found(reported(first + l, objects));
    }
  };
  wide_detail::walk<SimdBaseline>(tree_, box, keep, visit);
  return go_on;
}

void BucketBroadphase::overlap(const Sphere& sphere, const Objects& objects, const Filter* filter,
                               std::vector<std::uint32_t>& out) const {
  const std::size_t n = order_.sorted_ids().size();
  if (n == 0) return;
  if (holds_boxes()) {
    (void)sphere_overlap_walk(sphere, objects, filter, [&](std::uint32_t index) {
      out.push_back(index);
      return true;
    });
    return;
  }
  // Both boxes conservative: every sphere the exact test accepts is found (as for pairs).
  const Aabb box = conservative_box(sphere);
  auto visit = [&](std::uint32_t b) {
    // Padding lanes hold NaN centres: overlap_mask() never sets their bits.
    for (std::uint32_t m = SimdBaseline::sphere_lanes(buckets_.lanes()[b], sphere.x, sphere.y, sphere.z, sphere.r); m;
         m &= m - 1) {
      const std::size_t p = std::size_t{b} * kBucket + static_cast<std::uint32_t>(std::countr_zero(m));
      if (passes(filter, p, objects)) out.push_back(reported(p, objects));
    }
  };
  for_each_wide_overlap(tree_, box, visit);
}

template <class Found>
bool BucketBroadphase::sphere_overlap_walk(const Sphere& sphere, const Objects& objects, const Filter* filter,
                                           Found&& found) const {
  // The sphere's conservative box holds every point sphere_box_exact() accepts, so every box it
  // accepts meets that box (and the tree's boxes hold the objects' boxes exactly).
  return overlap_walk(conservative_box(sphere), objects, filter,
                      Overloaded{[&](const Sphere& s) { return overlap_exact(sphere, s); },
                                 [&](const Box& b) { return sphere_box_exact(sphere, b.min, b.max); }},
                      found);
}

bool BucketBroadphase::overlap_visit(const Sphere& sphere, const Objects& objects, const Filter* filter,
                                     OverlapVisitor& visitor) const {
  return sphere_overlap_walk(sphere, objects, filter, [&](std::uint32_t index) { return visitor.on_overlap(index); });
}

namespace {
// The query box as the tree's box type. No widening: the tree's boxes contain every object's
// conservative box (sphere lanes) or the object's box itself (box lanes), which contain every
// point sphere_box_exact() can accept as within r, and every box that box_overlap_exact() accepts.
Aabb tree_box(const Box& b) { return Aabb{{b.min[0], b.min[1], b.min[2]}, {b.max[0], b.max[1], b.max[2]}}; }

// The exact tests of a box query: a sphere lane by sphere_box_exact(), a box lane by
// box_overlap_exact().
auto box_query_tests(const Box& box) {
  return Overloaded{[&box](const Sphere& s) { return sphere_box_exact(s, box.min, box.max); },
                    [&box](const Box& b) { return box_overlap_exact(box, b); }};
}
}  // namespace

void BucketBroadphase::overlap_box(const Box& box, const Objects& objects, const Filter* filter,
                                   std::vector<std::uint32_t>& out) const {
  (void)overlap_walk(tree_box(box), objects, filter, box_query_tests(box), [&](std::uint32_t index) {
    out.push_back(index);
    return true;
  });
}

bool BucketBroadphase::overlap_box_visit(const Box& box, const Objects& objects, const Filter* filter,
                                         OverlapVisitor& visitor) const {
  return overlap_walk(tree_box(box), objects, filter, box_query_tests(box),
                      [&](std::uint32_t index) { return visitor.on_overlap(index); });
}

double BucketBroadphase::box_ray_margin() const {
  // 2^-32 of the largest coordinate in the tree: far above the rounding of the slab test's
  // products in double (a few units of 2^-53 of |box| + |origin|), far below any gap that matters.
  const Aabb root = tree_.level[tree_.levels - 1][0].box();
  const double m = std::max({std::fabs(double{root.lo.x}), std::fabs(double{root.lo.y}), std::fabs(double{root.lo.z}),
                             std::fabs(double{root.hi.x}), std::fabs(double{root.hi.y}), std::fabs(double{root.hi.z})});
  return 0x1p-32 * m;
}

}  // namespace viscd::detail
