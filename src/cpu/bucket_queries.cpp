// The queries on the cpu broadphase's last tree (docs/architecture.md, "Queries"): rays (first hit,
// all hits) and sphere overlaps. A ray walks the 16-wide tree nearest child first with slab tests
// in double against boxes widened by ray_box_margin() (cpu/simd.hpp: ray_children, ray_lanes), so
// no hit is missed; candidates get the exact test ray_sphere(). Overlaps walk the tree with the
// sphere's conservative box and test 16 lanes at a time with overlap_exact().

#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>

#include "cpu/bucket_broadphase.hpp"
#include "cpu/simd.hpp"

namespace viscd::detail {
namespace {

// Every t whose float rounding is at most `limit` is at most this.
inline double upper_t(float limit) {
  return static_cast<double>(std::nextafter(limit, std::numeric_limits<float>::infinity()));
}

}  // namespace

template <class Visit>
void BucketBroadphase::ray_walk(const Ray& ray, double& t_hi, Visit&& visit) const {
  if (tree_.levels == 0) return;
  const RaySetup q(ray);
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
    for (std::uint32_t m = ray_children(q, nd, t_hi, t_enter); m; m &= m - 1) {
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
void BucketBroadphase::ray_hits(const Ray& ray, double& t_hi, Hit&& hit) const {
  ray_walk(ray, t_hi, [&](const RaySetup& q, std::uint32_t b) {
    const BucketLanes& ln = buckets_.lanes()[b];
    const std::size_t first = std::size_t{b} * kBucket;
    for (std::uint32_t m = ray_lanes(q, ln, t_hi); m; m &= m - 1) {
      const auto l = static_cast<std::uint32_t>(std::countr_zero(m));
      float t = 0;
      if (ray_sphere(ray.origin, ray.dir, ray.max_t, Sphere{ln.x[l], ln.y[l], ln.z[l], ln.r[l]}, t))
        hit(order_.sorted_ids()[first + l], t);
    }
  });
}

bool BucketBroadphase::ray_first(const Ray& ray, std::span<const std::uint32_t> ids, RayHit& best, bool found) const {
  double t_hi = upper_t(found ? std::min(best.t, ray.max_t) : ray.max_t);
  ray_hits(ray, t_hi, [&](std::uint32_t id, float t) {
    const std::uint32_t index = ids.empty() ? id : ids[id];
    if (found && (t > best.t || (t == best.t && index > best.index))) return;
    best = {index, t};
    found = true;
    t_hi = upper_t(t);
  });
  return found;
}

void BucketBroadphase::ray_all(const Ray& ray, std::span<const std::uint32_t> ids, std::vector<RayHit>& hits) const {
  double t_hi = upper_t(ray.max_t);
  ray_hits(ray, t_hi, [&](std::uint32_t id, float t) { hits.push_back({ids.empty() ? id : ids[id], t}); });
}

void BucketBroadphase::overlap(const Sphere& sphere, std::span<const std::uint32_t> ids,
                               std::vector<std::uint32_t>& out) const {
  const std::size_t n = order_.sorted_ids().size();
  if (n == 0) return;
  // Both boxes conservative: every sphere the exact test accepts is found (as for pairs).
  const Aabb box = conservative_box(sphere);
  auto visit = [&](std::uint32_t b) {
    // Padding lanes hold NaN centres: overlap_mask() never sets their bits.
    for (std::uint32_t m = SimdBaseline::sphere_lanes(buckets_.lanes()[b], sphere.x, sphere.y, sphere.z, sphere.r); m;
         m &= m - 1) {
      const std::uint32_t id =
          order_.sorted_ids()[std::size_t{b} * kBucket + static_cast<std::uint32_t>(std::countr_zero(m))];
      out.push_back(ids.empty() ? id : ids[id]);
    }
  };
  for_each_wide_overlap(tree_, box, visit);
}

}  // namespace viscd::detail
