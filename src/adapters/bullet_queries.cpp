// viscd::BulletBroadphase's queries: rayTest (a ray, or an AABB swept along it) and aabbTest,
// answered by the detector's queries on the last frame and the static set, plus the proxies the
// last frame culled or left out, tested directly.

#include "bullet_state.hpp"

namespace viscd {

void BulletBroadphase::rayTest(const btVector3& rayFrom, const btVector3& rayTo, btBroadphaseRayCallback& rayCallback,
                               const btVector3& aabbMin, const btVector3& aabbMax) {
  State& st = *state_;
  const bool swept = !aabbMin.isZero() || !aabbMax.isZero();
  if (!swept && rayFrom == rayTo) {  // a point: the boxes that contain it
    aabbTest(rayFrom, rayTo, rayCallback);
    return;
  }
  if (swept) {
    // Candidates: the boxes overlapping the box the swept AABB covers; then the exact test.
    btVector3 lo = rayFrom, hi = rayFrom;
    lo.setMin(rayTo);
    hi.setMax(rayTo);
    struct Filtered final : btBroadphaseAabbCallback {
      const btVector3 *from, *to, *sweep_min, *sweep_max;
      btBroadphaseRayCallback* inner;
      bool process(const btBroadphaseProxy* proxy) override {
        if (swept_box_hit(*from, *to, *sweep_min, *sweep_max, as_proxy(proxy)->box)) inner->process(proxy);
        return true;
      }
    } filtered;
    filtered.from = &rayFrom;
    filtered.to = &rayTo;
    filtered.sweep_min = &aabbMin;
    filtered.sweep_max = &aabbMax;
    filtered.inner = &rayCallback;
    aabbTest(lo + aabbMin, hi + aabbMax, filtered);
    return;
  }
  Ray ray;
  for (int k = 0; k < 3; ++k) {
    ray.origin[k] = static_cast<float>(rayFrom[k]);
    ray.dir[k] = static_cast<float>(rayTo[k] - rayFrom[k]);
  }
  ray.max_t = 1;
  float t = 0;
  const auto hit = [&](const Box& box) { return ray_hits_box(ray, box, t); };
  if (!st.frame_answers_queries()) {
    for (std::size_t c = 0; c < st.proxies.size(); ++c) {
      Proxy* p = st.proxies[c];
      if (p->valid && hit(p->box)) rayCallback.process(p);
    }
    return;
  }
  // Collected first and called after: the callback may then use the broadphase again.
  auto hits = st.hit_lists.take();
  auto found = st.proxy_lists.take();
  CollectHits collect(*hits);
  st.detector->ray_cast(ray, collect);
  for (const std::uint32_t index : *hits)
    if (Proxy* p = st.proxy_of(index); p && p->valid) found->push_back(p);
  st.visit_culled(hit, [&](Proxy* p) { found->push_back(p); });
  for (Proxy* p : *found) rayCallback.process(p);
}

void BulletBroadphase::aabbTest(const btVector3& aabbMin, const btVector3& aabbMax,
                                btBroadphaseAabbCallback& callback) {
  State& st = *state_;
  Box query;
  if (!to_box(aabbMin, aabbMax, query)) return;
  const auto overlaps = [&](const Box& box) { return boxes_overlap(box, query); };
  auto found = st.proxy_lists.take();  // collected first, as in rayTest()
  if (!st.frame_answers_queries()) {
    for (Proxy* p : st.proxies)
      if (p->valid && overlaps(p->box)) found->push_back(p);
  } else {
    auto hits = st.hit_lists.take();
    st.detector->overlap_box(query, *hits);
    for (const std::uint32_t index : *hits)
      if (Proxy* p = st.proxy_of(index); p && p->valid) found->push_back(p);
    st.visit_culled(overlaps, [&](Proxy* p) { found->push_back(p); });
  }
  for (Proxy* p : *found) callback.process(p);
}

}  // namespace viscd
