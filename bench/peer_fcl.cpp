// FCL's dynamic AABB tree manager as a peer, used as a broadphase only: the collide() callback
// receives candidate pairs (objects whose boxes overlap), applies the exact sphere test itself and
// returns false ("keep going"); no narrowphase runs.
//
// Each frame every object gets its new translation and box (computeAABB), then the manager's
// update() refits and rebalances its tree (FCL's documented use for moving objects).

#include <fcl/broadphase/broadphase_dynamic_AABB_tree.h>
#include <fcl/geometry/shape/sphere.h>
#include <fcl/narrowphase/collision_object.h>

#include <cstdint>
#include <numeric>

#include "peers.hpp"
#include "viscd/detector.hpp"

namespace viscd::bench {
namespace {

using Real = float;  // the spheres are float; FCL in double would only add conversions

struct CollectContext {
  std::span<const Sphere> spheres;
  std::vector<Pair>* pairs = nullptr;
  std::uint64_t candidates = 0;
};

bool collect_exact_pair(fcl::CollisionObject<Real>* o1, fcl::CollisionObject<Real>* o2, void* data) {
  auto& ctx = *static_cast<CollectContext*>(data);
  ++ctx.candidates;
  const std::uint32_t a = *static_cast<const std::uint32_t*>(o1->getUserData());
  const std::uint32_t b = *static_cast<const std::uint32_t*>(o2->getUserData());
  if (spheres_overlap(ctx.spheres[a], ctx.spheres[b])) ctx.pairs->push_back(a < b ? Pair{a, b} : Pair{b, a});
  return false;  // never stop early: every candidate is wanted
}

class FclMethod final : public Method {
 public:
  [[nodiscard]] std::string_view name() const override { return "fcl_dtree"; }

  [[nodiscard]] std::string init(std::span<const Sphere> spheres, const WorldBounds& world) override {
    const std::size_t n = spheres.size();
    ids_.resize(n);
    std::iota(ids_.begin(), ids_.end(), 0u);
    objects_.clear();
    objects_.reserve(n);
    std::vector<fcl::CollisionObject<Real>*> raw(n);
    for (std::size_t k = 0; k < n; ++k) {
      const Sphere& s = spheres[k];
      // FCL's box is centre -/+ radius in float. Widen the radius as viscd's conservative box
      // does (core/geometry.hpp), with the world's largest coordinate, so that the box never
      // rejects a pair the float sphere test accepts.
      const float r = s.r + (world.max_abs + s.r) * 0x1p-19f + 1e-21f;
      auto geometry = std::make_shared<fcl::Sphere<Real>>(r);
      objects_.push_back(std::make_unique<fcl::CollisionObject<Real>>(
          geometry, fcl::Transform3<Real>(fcl::Translation3<Real>(fcl::Vector3<Real>(s.x, s.y, s.z)))));
      objects_.back()->setUserData(&ids_[k]);
      raw[k] = objects_.back().get();
    }
    manager_ = std::make_unique<fcl::DynamicAABBTreeCollisionManager<Real>>();
    manager_->registerObjects(raw);
    manager_->setup();
    return "";
  }

  [[nodiscard]] bool frame(std::span<const Sphere> spheres, std::span<const Pair>& pairs, std::string&) override {
    const std::size_t n = spheres.size();
    for (std::size_t k = 0; k < n; ++k) {
      fcl::CollisionObject<Real>& o = *objects_[k];
      o.setTranslation(fcl::Vector3<Real>(spheres[k].x, spheres[k].y, spheres[k].z));
      o.computeAABB();
    }
    manager_->update();
    pairs_.clear();
    CollectContext ctx{spheres, &pairs_};
    manager_->collide(&ctx, collect_exact_pair);
    candidates_ = ctx.candidates;
    pairs = pairs_;
    return true;
  }
  [[nodiscard]] std::uint64_t candidates() const override { return candidates_; }

 private:
  std::vector<std::uint32_t> ids_;  // object user data points here
  std::vector<std::unique_ptr<fcl::CollisionObject<Real>>> objects_;
  std::unique_ptr<fcl::DynamicAABBTreeCollisionManager<Real>> manager_;  // destroyed before the objects
  std::vector<Pair> pairs_;
  std::uint64_t candidates_ = 0;
};

}  // namespace

std::unique_ptr<Method> make_fcl_dynamic_tree() { return std::make_unique<FclMethod>(); }

}  // namespace viscd::bench
