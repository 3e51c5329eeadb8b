#pragma once
/// \file bullet.hpp
/// viscd as a Bullet broadphase: a btBroadphaseInterface that a btCollisionWorld or
/// btDiscreteDynamicsWorld takes in place of btDbvtBroadphase (docs/adapters.md). Library
/// viscd::bullet (target viscd_bullet), built when Bullet is found.

#include <BulletCollision/BroadphaseCollision/btBroadphaseInterface.h>
#include <BulletCollision/BroadphaseCollision/btOverlappingPairCache.h>

#include <cstdint>
#include <memory>
#include <optional>
#include <span>

#include "viscd/config.hpp"
#include "viscd/frame.hpp"
#include "viscd/result.hpp"
#include "viscd/types.hpp"

namespace viscd {

/// A Bullet broadphase on viscd's cpu detector. Swap it in where a world is made:
///
///     viscd::BulletBroadphase broadphase;   // instead of btDbvtBroadphase
///     btDiscreteDynamicsWorld world(&dispatcher, &broadphase, &solver, &configuration);
///
/// What it keeps (docs/adapters.md, "Bullet"):
///   - Proxies whose filter puts them in Bullet's static or kinematic groups and keeps them from
///     pairing with each other (goes_to_static_set(); Bullet's own static and kinematic bodies
///     qualify) live in the detector's static set: moving one costs about one object, not a
///     rebuild. Every other proxy is a moving box of each frame, in a slot of its own that it
///     keeps until it is destroyed.
///   - After calculateOverlappingPairs() the pair cache holds exactly the pairs of proxies whose
///     AABBs overlap (closed boxes: touching counts) and whose collision filter groups and masks
///     accept each other (Bullet's rule, which is viscd's Filter rule), except pairs of two
///     static-set proxies (which Bullet's rule refuses anyway). Pairs are added when they begin
///     and removed, with the dispatcher so that their manifolds go, when they end: contact
///     manifolds persist as with Bullet's own broadphases. The cache's overlap filter callback,
///     when set, is asked when a pair begins (addOverlappingPair); it can narrow the group/mask
///     rule, never widen it.
///   - A proxy's pairs with others appear at the next calculateOverlappingPairs() (btDbvtBroadphase
///     adds a new proxy's pairs at once; a world asks for pairs before it uses them either way).
///     destroyProxy() removes the proxy's pairs at once, as Bullet's broadphases do.
///   - rayTest() and aabbTest() answer from viscd's queries on the last frame while nothing changed
///     since; after a change (a proxy created, destroyed or moved) they test every proxy's AABB.
///
/// AABBs become float boxes (btScalar is float in a default Bullet build; a double build rounds
/// outward). A bound beyond kMaxCoordinate is clamped to it; a proxy with a NaN bound pairs with
/// nothing and is not seen by queries until its AABB is finite again.
///
/// Culling (off by default): with a camera (set_camera()) or the caller's id map (set_id_map()),
/// proxies covering fewer than Config::lambda pixels get no pairs. A culled body has no contacts:
/// it falls through floors and walls while it is not seen, and its manifolds are dropped. Mark
/// the proxies that must never be culled with set_always_active() (the player, what the camera
/// rides, anything resting where the camera may turn). Queries see culled proxies all the same.
///
/// Threading: not thread-safe, as Bullet's broadphases are not; the detector may use worker
/// threads inside calculateOverlappingPairs() (Config::threads, Config::executor).
class BulletBroadphase final : public btBroadphaseInterface {
 public:
  /// default_config() and a pair cache of its own (btHashedOverlappingPairCache).
  BulletBroadphase();
  /// `config` for the cpu detector (Config::contact_events is forced on: the cache is kept from
  /// the events); start from default_config() to keep its rest margin. `pair_cache`: the caller's
  /// cache (not owned; must outlive this), or nullptr for one of its own, as btDbvtBroadphase
  /// takes one.
  explicit BulletBroadphase(const Config& config, btOverlappingPairCache* pair_cache = nullptr);
  /// default_config() and the caller's pair cache (not owned).
  explicit BulletBroadphase(btOverlappingPairCache* pair_cache);
  /// Config{} with Config::rest_margin 0.05: btDbvtBroadphase's own margin, in Bullet's units (a
  /// body jiggling in place in an island Bullet keeps awake stays inside its fat bounds, and costs
  /// a test of its candidates, not a search). The pairs are exact either way.
  [[nodiscard]] static Config default_config();
  /// Deletes the proxies still alive (a world removes its objects first) and an owned cache.
  ~BulletBroadphase() override;
  BulletBroadphase(const BulletBroadphase&) = delete;
  BulletBroadphase& operator=(const BulletBroadphase&) = delete;

  // ---- btBroadphaseInterface ----
  btBroadphaseProxy* createProxy(const btVector3& aabbMin, const btVector3& aabbMax, int shapeType, void* userPtr,
                                 int collisionFilterGroup, int collisionFilterMask, btDispatcher* dispatcher) override;
  void destroyProxy(btBroadphaseProxy* proxy, btDispatcher* dispatcher) override;
  void setAabb(btBroadphaseProxy* proxy, const btVector3& aabbMin, const btVector3& aabbMax,
               btDispatcher* dispatcher) override;
  void getAabb(btBroadphaseProxy* proxy, btVector3& aabbMin, btVector3& aabbMax) const override;
  /// Calls rayCallback.process() for each proxy whose AABB the segment rayFrom -> rayTo hits
  /// (ray_hits_box(), origin rayFrom, direction rayTo - rayFrom, max t 1), or, with aabbMin /
  /// aabbMax not zero (a swept box, as convexSweepTest passes), whose AABB grown by them the
  /// segment hits (slabs in double). Each proxy at most once; what process() returns is ignored, as
  /// btDbvtBroadphase ignores it. The callback must not call this broadphase.
  void rayTest(const btVector3& rayFrom, const btVector3& rayTo, btBroadphaseRayCallback& rayCallback,
               const btVector3& aabbMin = btVector3(0, 0, 0), const btVector3& aabbMax = btVector3(0, 0, 0)) override;
  /// Calls callback.process() for each proxy whose AABB overlaps [aabbMin, aabbMax] (closed).
  void aabbTest(const btVector3& aabbMin, const btVector3& aabbMax, btBroadphaseAabbCallback& callback) override;
  /// Runs one viscd frame on the proxies' current AABBs and brings the pair cache up to date.
  /// A failed frame (last_status()) leaves the cache as it was.
  void calculateOverlappingPairs(btDispatcher* dispatcher) override;
  btOverlappingPairCache* getOverlappingPairCache() override;
  const btOverlappingPairCache* getOverlappingPairCache() const override;
  /// The box around every proxy's AABB; zero when there is none (as btDbvtBroadphase).
  void getBroadphaseAabb(btVector3& aabbMin, btVector3& aabbMax) const override;
  /// With no proxy alive: frees the slots and the detector's memory and restarts proxy ids.
  void resetPool(btDispatcher* dispatcher) override;
  /// Prints proxy counts, slots and the last frame's pairs and time to stdout.
  void printStats() override;

  // ---- viscd's own ----
  /// Whether a proxy with this collision filter goes to the static set: its group holds only
  /// btBroadphaseProxy::StaticFilter and/or KinematicFilter bits, its mask lacks StaticFilter, and
  /// lacks KinematicFilter too when the group has it. Two such proxies never pass Bullet's filter
  /// rule, so the static set (which never pairs its members) loses nothing. Bullet's static and
  /// kinematic rigid bodies (group StaticFilter, mask AllFilter ^ StaticFilter) qualify.
  [[nodiscard]] static bool goes_to_static_set(int collision_filter_group, int collision_filter_mask);
  /// Culling from this camera (copied; nullptr: none, the default). Takes effect at the next
  /// calculateOverlappingPairs().
  void set_camera(const Camera* camera);
  /// Culling from the caller's id map: width x height, row-major, 0 background, moving_index() + 1
  /// for a moving proxy (static-set proxies are background). Not copied: it must live until the
  /// next calculateOverlappingPairs(), or until cleared with an empty span.
  void set_id_map(std::span<const std::uint32_t> ids, int width, int height);
  /// Never cull this proxy (FrameInput::always_active). Off for new proxies; static-set proxies are
  /// never culled anyway; a pointer that is not a live proxy of this broadphase is ignored.
  void set_always_active(btBroadphaseProxy* proxy, bool always_active);
  /// The proxy's index in the detector's frame (its slot; what an id map writes, minus 1), or
  /// nothing for a static-set proxy, or for a pointer that is not a live proxy of this broadphase
  /// (another broadphase's, or destroyed), which is never read.
  [[nodiscard]] std::optional<std::uint32_t> moving_index(const btBroadphaseProxy* proxy) const;
  /// Whether the proxy lives in the static set (false for a pointer that is not a live proxy of
  /// this broadphase).
  [[nodiscard]] bool in_static_set(const btBroadphaseProxy* proxy) const;
  /// Proxies alive, and how many of them are in the static set.
  [[nodiscard]] std::size_t proxy_count() const;
  [[nodiscard]] std::size_t static_proxy_count() const;
  /// Slots of the moving frame (live proxies plus free slots waiting to be reused or compacted).
  [[nodiscard]] std::size_t moving_slots() const;
  /// The last calculateOverlappingPairs()'s outcome (ok, or why the frame failed).
  [[nodiscard]] const Status& last_status() const;
  /// The last successful frame's numbers (objects, active, pairs, stage times).
  [[nodiscard]] const FrameStats& last_stats() const;
  /// The detector's settings (Config::contact_events always on).
  [[nodiscard]] const Config& config() const;
  /// Changes the detector's settings from the next frame on (contact_events stays on).
  void set_config(const Config& config);

  struct State;  ///< internal

 private:
  std::unique_ptr<State> state_;
};

}  // namespace viscd
