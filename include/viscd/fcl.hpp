#pragma once
/// \file fcl.hpp
/// viscd as an FCL broadphase manager: an fcl::BroadPhaseCollisionManager<double> that takes the
/// place of fcl::DynamicAABBTreeCollisionManager (docs/adapters.md). Library viscd::fcl (target
/// viscd_fcl), built when FCL is found.

#include <fcl/broadphase/broadphase_collision_manager.h>

#include <memory>
#include <vector>

#include "viscd/config.hpp"
#include "viscd/result.hpp"

namespace viscd {

/// An FCL broadphase manager on viscd's cpu detector. Swap it in where a manager is made:
///
///     viscd::FclBroadphaseManager manager;   // instead of fcl::DynamicAABBTreeCollisionManagerd
///     manager.registerObjects(objects);
///     manager.setup();
///     manager.collide(&data, fcl::DefaultCollisionFunction<double>);
///
/// The manager keeps each object's AABB (CollisionObject::getAABB()) as it was when the object
/// was registered or last given to update() / setup(), as FCL's tree managers do; the object
/// given to collide(obj) / distance(obj) and the other manager's objects are read at the call.
///
/// collide: calls the callback for every pair whose AABBs overlap (closed boxes, as
/// fcl::AABB::overlap), each unordered pair once, the manager's own object first for
/// collide(obj) and this manager's object first for collide(other). The test runs on float boxes
/// rounded outward (std::nextafter), so a pair is never missed; a pair whose double AABBs miss by
/// less than float rounding may be called too (the narrowphase the callback runs rejects it). A
/// bound beyond viscd::kMaxCoordinate (a half-space's or plane's infinite AABB) is clamped to it
/// and a NaN bound spans everything, which keeps the superset. Stops when the callback returns
/// true.
///
/// distance: the callback's running distance (its `dist`, starting at the largest double) ends as
/// the true minimum, as with fcl::NaiveCollisionManager: candidate pairs are visited best-first by
/// their AABB distance (fcl::AABB::distance), each only while that lower bound is below the
/// running distance; candidates come from frames whose boxes are grown by a radius that doubles
/// until a pair is found, then grows to the running distance. Stops when the callback returns true.
///
/// Threading: not thread-safe (FCL's managers are not); const calls update internal caches.
class FclBroadphaseManager final : public fcl::BroadPhaseCollisionManager<double> {
 public:
  using Object = fcl::CollisionObject<double>;

  FclBroadphaseManager();
  /// `config` for the cpu detectors (culling does not apply: no camera is ever given).
  explicit FclBroadphaseManager(const Config& config);
  ~FclBroadphaseManager() override;
  FclBroadphaseManager(const FclBroadphaseManager&) = delete;
  FclBroadphaseManager& operator=(const FclBroadphaseManager&) = delete;

  /// Adds objects (not owned; they must outlive their registration). Registering an object twice
  /// is ignored.
  void registerObjects(const std::vector<Object*>& other_objs) override;
  void registerObject(Object* obj) override;
  /// Removes an object (unknown objects are ignored). The order of getObjects() may change.
  void unregisterObject(Object* obj) override;
  /// Reads every object's AABB again (as update()).
  void setup() override;
  /// Reads every object's AABB again.
  void update() override;
  /// Reads these objects' AABBs again (unknown objects are ignored). The next self collide() is
  /// told which boxes changed (FrameInput::moved), so with the detector's resting objects
  /// (Config::follow_change) it costs about what moved and what is near it; update() and
  /// registering or removing objects let the detector compare every box itself.
  void update(Object* updated_obj) override;
  void update(const std::vector<Object*>& updated_objs) override;
  void clear() override;
  /// The registered objects (replaces the vector's contents).
  void getObjects(std::vector<Object*>& objs) const override;

  void collide(Object* obj, void* cdata, fcl::CollisionCallBack<double> callback) const override;
  void distance(Object* obj, void* cdata, fcl::DistanceCallBack<double> callback) const override;
  void collide(void* cdata, fcl::CollisionCallBack<double> callback) const override;
  void distance(void* cdata, fcl::DistanceCallBack<double> callback) const override;
  /// Any other manager (its objects through getObjects(), their AABBs read now); this one itself
  /// is the self query.
  void collide(fcl::BroadPhaseCollisionManager<double>* other_manager, void* cdata,
               fcl::CollisionCallBack<double> callback) const override;
  void distance(fcl::BroadPhaseCollisionManager<double>* other_manager, void* cdata,
                fcl::DistanceCallBack<double> callback) const override;

  [[nodiscard]] bool empty() const override;
  [[nodiscard]] size_t size() const override;

  /// The last detector frame's outcome: the self frame's (collide(), collide(obj)), or that of a
  /// frame over grown boxes that distance() or collide(other) ran, which fails when its pairs
  /// would pass 512 MiB (or Config::pair_memory_cap, when lower). A failed frame is answered by brute force over the
  /// AABBs (distance() then visits the pairs one by one), so the callbacks' guarantees hold either way; this says why.
  [[nodiscard]] const Status& last_status() const;

  struct State;  ///< internal

 private:
  std::unique_ptr<State> state_;
};

}  // namespace viscd
