// viscd::BulletBroadphase on its own: after every calculateOverlappingPairs() the pair cache must
// hold exactly the pairs a brute force over the live proxies' AABBs finds (closed overlap,
// accepted by the cache's needsBroadphaseCollision, never two static-set proxies), while proxies
// move, are created and destroyed (slots reused, frames compacted), go static or kinematic, get
// NaN AABBs; with Bullet's hashed cache and its sorted cache (deferred removal). Queries against
// Bullet's own ray-box test (btRayAabb) and a brute-force box test.
#include <BulletCollision/BroadphaseCollision/btDbvtBroadphase.h>
#include <BulletCollision/BroadphaseCollision/btOverlappingPairCache.h>
#include <BulletCollision/CollisionDispatch/btCollisionDispatcher.h>
#include <BulletCollision/CollisionDispatch/btDefaultCollisionConfiguration.h>
#include <LinearMath/btAabbUtil2.h>
#include <gtest/gtest.h>
#include <viscd/bullet.hpp>

#include <algorithm>
#include <cstdint>
#include <limits>
#include <random>
#include <set>
#include <string>
#include <utility>
#include <vector>

namespace {

using Key = std::pair<int, int>;  // proxies' unique ids, smaller first

Key key(const btBroadphaseProxy* a, const btBroadphaseProxy* b) {
  return a->m_uniqueId < b->m_uniqueId ? Key{a->m_uniqueId, b->m_uniqueId} : Key{b->m_uniqueId, a->m_uniqueId};
}

bool finite(const btBroadphaseProxy* p) {
  for (int k = 0; k < 3; ++k)
    if (p->m_aabbMin[k] != p->m_aabbMin[k] || p->m_aabbMax[k] != p->m_aabbMax[k]) return false;
  return true;
}

bool aabbs_overlap(const btBroadphaseProxy* a, const btBroadphaseProxy* b) {
  return TestAabbAgainstAabb2(a->m_aabbMin, a->m_aabbMax, b->m_aabbMin, b->m_aabbMax);
}

// The cache's pairs, failing on duplicates.
std::set<Key> cache_pairs(btOverlappingPairCache& cache) {
  std::set<Key> pairs;
  const btBroadphasePairArray& array = cache.getOverlappingPairArray();
  for (int c = 0; c < array.size(); ++c) {
    EXPECT_TRUE(pairs.insert(key(array[c].m_pProxy0, array[c].m_pProxy1)).second) << "a pair twice in the cache";
  }
  return pairs;
}

// What the cache must hold: every pair of live proxies whose AABBs overlap, found by a sweep
// along x (the proxies sorted by their lower x bound; each one tested against those whose lower
// bound does not pass its upper one), then Bullet's own overlap test and filter rule. A proxy
// with a NaN bound pairs with nothing.
std::set<Key> expected_pairs(const viscd::BulletBroadphase& bp, btOverlappingPairCache& cache,
                             const std::vector<btBroadphaseProxy*>& proxies) {
  std::vector<btBroadphaseProxy*> swept;
  for (btBroadphaseProxy* p : proxies)
    if (finite(p)) swept.push_back(p);
  std::sort(swept.begin(), swept.end(),
            [](const btBroadphaseProxy* a, const btBroadphaseProxy* b) { return a->m_aabbMin.x() < b->m_aabbMin.x(); });
  std::set<Key> pairs;
  for (std::size_t a = 0; a < swept.size(); ++a)
    for (std::size_t b = a + 1; b < swept.size() && swept[b]->m_aabbMin.x() <= swept[a]->m_aabbMax.x(); ++b) {
      btBroadphaseProxy *p = swept[a], *q = swept[b];
      if (!aabbs_overlap(p, q)) continue;
      if (!cache.needsBroadphaseCollision(p, q)) continue;
      if (bp.in_static_set(p) && bp.in_static_set(q)) continue;  // refused by Bullet's rule anyway
      pairs.insert(key(p, q));
    }
  return pairs;
}

struct Filters {
  int group, mask;
};
// Dynamic, debris, static and kinematic bodies as Bullet's worlds file them, and odd masks.
constexpr Filters kFilters[] = {
    {btBroadphaseProxy::DefaultFilter, btBroadphaseProxy::AllFilter},
    {btBroadphaseProxy::DefaultFilter, btBroadphaseProxy::AllFilter},
    {btBroadphaseProxy::DebrisFilter, btBroadphaseProxy::AllFilter ^ btBroadphaseProxy::DebrisFilter},
    {btBroadphaseProxy::StaticFilter, btBroadphaseProxy::AllFilter ^ btBroadphaseProxy::StaticFilter},
    {btBroadphaseProxy::StaticFilter, btBroadphaseProxy::AllFilter ^ btBroadphaseProxy::StaticFilter},
    {btBroadphaseProxy::KinematicFilter,
     btBroadphaseProxy::AllFilter ^ (btBroadphaseProxy::StaticFilter | btBroadphaseProxy::KinematicFilter)},
    {btBroadphaseProxy::KinematicFilter, btBroadphaseProxy::AllFilter ^ btBroadphaseProxy::StaticFilter},  // moving
    {btBroadphaseProxy::StaticFilter, btBroadphaseProxy::AllFilter},                                       // moving
    {btBroadphaseProxy::CharacterFilter, btBroadphaseProxy::StaticFilter | btBroadphaseProxy::DefaultFilter},
};

class RandomProxies {
 public:
  RandomProxies(viscd::BulletBroadphase& bp, btDispatcher* dispatcher, unsigned seed)
      : bp_(bp), dispatcher_(dispatcher), rng_(seed) {}

  btVector3 point(float extent) {
    std::uniform_real_distribution<float> u(-extent, extent);
    return {u(rng_), u(rng_), u(rng_)};
  }
  std::pair<btVector3, btVector3> random_aabb() {
    std::uniform_real_distribution<float> size(0.2f, 3.0f);
    const btVector3 lo = point(15);
    return {lo, lo + btVector3(size(rng_), size(rng_), size(rng_))};
  }
  // A proxy with one of kFilters (`moving`: the default group and mask).
  void create(bool moving = false) {
    const auto [lo, hi] = random_aabb();
    const Filters f =
        moving ? kFilters[0] : kFilters[std::uniform_int_distribution<std::size_t>(0, std::size(kFilters) - 1)(rng_)];
    proxies_.push_back(bp_.createProxy(lo, hi, BOX_SHAPE_PROXYTYPE, nullptr, f.group, f.mask, dispatcher_));
  }
  // A random proxy destroyed (`moving`: one outside the static set, if the first few picks find
  // one).
  void destroy_random(bool moving = false) {
    if (proxies_.empty()) return;
    std::size_t k = std::uniform_int_distribution<std::size_t>(0, proxies_.size() - 1)(rng_);
    for (int tries = 0; moving && tries < 8 && bp_.in_static_set(proxies_[k]); ++tries)
      k = std::uniform_int_distribution<std::size_t>(0, proxies_.size() - 1)(rng_);
    if (moving && bp_.in_static_set(proxies_[k])) return;
    bp_.destroyProxy(proxies_[k], dispatcher_);
    proxies_[k] = proxies_.back();
    proxies_.pop_back();
  }
  // Moves a share of the proxies by a small step (so pairs persist), a few far, a few to NaN and
  // back; with `fixed_stay`, none of those in the static set (which then stays: run_random_frames()
  // then makes and destroys only proxies outside it too).
  void move(double share, bool fixed_stay = false) {
    std::uniform_real_distribution<double> u(0, 1);
    std::uniform_real_distribution<float> step(-0.4f, 0.4f);
    for (btBroadphaseProxy* p : proxies_) {
      if (u(rng_) >= share) continue;
      if (fixed_stay && bp_.in_static_set(p)) continue;
      btVector3 lo = p->m_aabbMin, hi = p->m_aabbMax;
      const double roll = u(rng_);
      if (roll < 0.02) {
        const float nan = std::numeric_limits<float>::quiet_NaN();
        lo.setX(nan);
      } else if (roll < 0.06 || lo.x() != lo.x()) {
        std::tie(lo, hi) = random_aabb();
      } else {
        // A step, or a jiggle inside the default rest margin (0.05) a third of the time.
        const float scale = roll < 0.36 ? 0.02f : 1.0f;
        const btVector3 d(scale * step(rng_), scale * step(rng_), scale * step(rng_));
        lo += d;
        hi += d;
      }
      bp_.setAabb(p, lo, hi, dispatcher_);
    }
  }
  std::vector<btBroadphaseProxy*>& proxies() { return proxies_; }
  std::mt19937& rng() { return rng_; }

 private:
  viscd::BulletBroadphase& bp_;
  btDispatcher* dispatcher_;
  std::mt19937 rng_;
  std::vector<btBroadphaseProxy*> proxies_;
};

struct Bullet {
  btDefaultCollisionConfiguration configuration;
  btCollisionDispatcher dispatcher{&configuration};
};

// Returns the frames the detector followed change in (few move with a small `share`).
int run_random_frames(viscd::BulletBroadphase& bp, btDispatcher* dispatcher, unsigned seed, int frames,
                      std::size_t objects, double share = 0.5, bool fixed_stay = false) {
  RandomProxies world(bp, dispatcher, seed);
  for (std::size_t k = 0; k < objects; ++k) world.create();
  std::uniform_int_distribution<int> churn(0, 6);
  int followed = 0;
  for (int frame = 0; frame < frames; ++frame) {
    world.move(share, fixed_stay);
    for (int c = churn(world.rng()); c > 0; --c) world.destroy_random(fixed_stay);
    for (int c = churn(world.rng()); c > 0; --c) world.create(fixed_stay);
    bp.calculateOverlappingPairs(dispatcher);
    EXPECT_TRUE(bp.last_status().ok()) << bp.last_status().error();
    if (!bp.last_status().ok()) break;
    followed += bp.last_stats().followed_change ? 1 : 0;
    const std::set<Key> got = cache_pairs(*bp.getOverlappingPairCache());
    const std::set<Key> want = expected_pairs(bp, *bp.getOverlappingPairCache(), world.proxies());
    EXPECT_EQ(got, want) << "frame " << frame;
    if (got != want) break;
  }
  for (btBroadphaseProxy* p : world.proxies()) bp.destroyProxy(p, dispatcher);
  EXPECT_EQ(bp.getOverlappingPairCache()->getNumOverlappingPairs(), 0) << "pairs outlived their proxies";
  return followed;
}

TEST(BulletBroadphase, CacheMatchesBruteForceWhileProxiesMoveComeAndGo) {
  Bullet bullet;
  viscd::BulletBroadphase bp;
  EXPECT_EQ(bp.config().rest_margin, 0.05f);  // default_config()
  run_random_frames(bp, &bullet.dispatcher, 1, 60, 400);
  EXPECT_EQ(bp.proxy_count(), 0u);
}

TEST(BulletBroadphase, CacheMatchesBruteForceWithoutRestMargin) {
  Bullet bullet;
  viscd::Config config = viscd::BulletBroadphase::default_config();
  config.rest_margin = 0;
  viscd::BulletBroadphase bp(config);
  run_random_frames(bp, &bullet.dispatcher, 11, 40, 400);
  EXPECT_GT(run_random_frames(bp, &bullet.dispatcher, 12, 60, 2000, 0.04), 20);
  EXPECT_EQ(bp.proxy_count(), 0u);
}

// A few percent of the proxies move or jiggle a frame: the detector follows change, with the
// default rest margin (jiggles inside it), and the cache stays exact.
TEST(BulletBroadphase, CacheMatchesBruteForceWhileFewMove) {
  Bullet bullet;
  viscd::BulletBroadphase bp;
  EXPECT_GT(run_random_frames(bp, &bullet.dispatcher, 13, 60, 2000, 0.04), 20);
  EXPECT_EQ(bp.proxy_count(), 0u);
}

// Runs tasks last first on the calling thread and says it has four threads: the detector then
// merges its candidates in 16 chunks, and nothing may depend on their order.
class BackwardsExecutor final : public viscd::Executor {
 public:
  [[nodiscard]] int concurrency() const override { return 4; }
  void run(std::uint32_t count, viscd::TaskRef task) override {
    for (std::uint32_t i = count; i-- > 0;) task(i);
  }
};

// Enough proxies (12 000, some 80 000 pairs) for the followed frames to merge their candidates
// in chunks, with the default rest margin and a few percent moving (the static proxies staying);
// proxies come and go, and new slots add objects at the end.
TEST(BulletBroadphase, CacheMatchesBruteForceAtScale) {
  Bullet bullet;
  BackwardsExecutor four;
  viscd::Config config = viscd::BulletBroadphase::default_config();
  config.executor = &four;
  viscd::BulletBroadphase bp(config);
  EXPECT_GT(run_random_frames(bp, &bullet.dispatcher, 17, 30, 12000, 0.03, true), 20);
  EXPECT_EQ(bp.proxy_count(), 0u);
}

// Kinematic bodies (platforms, doors, a character pushed by gameplay) belong to the static set
// and move every step: the static set then changes in a few slots every frame, which the
// detector follows (it used to rebuild every such frame). 40 kinematic proxies glide through
// 3 000 resting dynamic ones of which 1 % move; static ones stay. The cache is exact every frame
// and nearly every frame is followed.
TEST(BulletBroadphase, KinematicProxiesMovingEveryStepAreFollowed) {
  Bullet bullet;
  viscd::BulletBroadphase bp;
  RandomProxies world(bp, &bullet.dispatcher, 23);
  for (int k = 0; k < 3000; ++k) world.create(true);
  std::vector<btBroadphaseProxy*> kinematic, fixed;
  const int kin_group = btBroadphaseProxy::KinematicFilter;
  const int kin_mask =
      btBroadphaseProxy::AllFilter ^ (btBroadphaseProxy::StaticFilter | btBroadphaseProxy::KinematicFilter);
  const int fixed_group = btBroadphaseProxy::StaticFilter;
  const int fixed_mask = btBroadphaseProxy::AllFilter ^ btBroadphaseProxy::StaticFilter;
  for (int k = 0; k < 40; ++k) {
    const btVector3 lo = world.point(15);
    kinematic.push_back(bp.createProxy(lo, lo + btVector3(2, 0.5f, 2), BOX_SHAPE_PROXYTYPE, nullptr, kin_group,
                                       kin_mask, &bullet.dispatcher));
    ASSERT_TRUE(bp.in_static_set(kinematic.back()));
  }
  for (int k = 0; k < 20; ++k) {
    const btVector3 lo = world.point(15);
    fixed.push_back(bp.createProxy(lo, lo + btVector3(4, 1, 4), BOX_SHAPE_PROXYTYPE, nullptr, fixed_group, fixed_mask,
                                   &bullet.dispatcher));
  }
  std::vector<btBroadphaseProxy*> all = world.proxies();
  all.insert(all.end(), kinematic.begin(), kinematic.end());
  all.insert(all.end(), fixed.begin(), fixed.end());
  int followed = 0;
  const int frames = 40;
  for (int frame = 0; frame < frames; ++frame) {
    SCOPED_TRACE("frame " + std::to_string(frame));
    if (frame > 0) {
      world.move(0.01, true);
      for (btBroadphaseProxy* p : kinematic) {
        const btVector3 d(0.3f, 0, frame % 2 ? 0.1f : -0.1f);
        bp.setAabb(p, p->m_aabbMin + d, p->m_aabbMax + d, &bullet.dispatcher);
      }
    }
    bp.calculateOverlappingPairs(&bullet.dispatcher);
    ASSERT_TRUE(bp.last_status().ok()) << bp.last_status().error();
    followed += bp.last_stats().followed_change ? 1 : 0;
    const std::set<Key> got = cache_pairs(*bp.getOverlappingPairCache());
    ASSERT_EQ(got, expected_pairs(bp, *bp.getOverlappingPairCache(), all));
  }
  // The first frames enter (the detector watches a sample first); the rest follow.
  EXPECT_GE(followed, frames - 4);
  for (btBroadphaseProxy* p : all) bp.destroyProxy(p, &bullet.dispatcher);
  world.proxies().clear();
  EXPECT_EQ(bp.getOverlappingPairCache()->getNumOverlappingPairs(), 0);
}

TEST(BulletBroadphase, SortedCacheWithDeferredRemoval) {
  Bullet bullet;
  btSortedOverlappingPairCache cache;
  ASSERT_TRUE(cache.hasDeferredRemoval());
  viscd::BulletBroadphase bp(&cache);
  run_random_frames(bp, &bullet.dispatcher, 2, 30, 250);
}

TEST(BulletBroadphase, SerialDetectorAndFixedBits) {
  Bullet bullet;
  viscd::Config config;
  config.threads = 1;
  config.bits = viscd::Bits::b16;
  viscd::BulletBroadphase bp(config);
  EXPECT_TRUE(bp.config().contact_events);
  run_random_frames(bp, &bullet.dispatcher, 3, 30, 300);
}

TEST(BulletBroadphase, SlotsAreReusedAndCompacted) {
  Bullet bullet;
  viscd::BulletBroadphase bp;
  RandomProxies world(bp, &bullet.dispatcher, 4);
  for (int k = 0; k < 600; ++k) world.create();
  bp.calculateOverlappingPairs(&bullet.dispatcher);
  const std::size_t slots = bp.moving_slots();
  // Destroy most: the holes outnumber the live slots, so the next frame compacts.
  while (world.proxies().size() > 100) world.destroy_random();
  bp.calculateOverlappingPairs(&bullet.dispatcher);
  EXPECT_LT(bp.moving_slots(), slots);
  EXPECT_EQ(cache_pairs(*bp.getOverlappingPairCache()),
            expected_pairs(bp, *bp.getOverlappingPairCache(), world.proxies()));
  // Then frames as usual on the renumbered slots, new proxies filling the free ones.
  for (int frame = 0; frame < 10; ++frame) {
    world.move(0.5);
    world.destroy_random();
    world.create();
    world.create();
    bp.calculateOverlappingPairs(&bullet.dispatcher);
    ASSERT_EQ(cache_pairs(*bp.getOverlappingPairCache()),
              expected_pairs(bp, *bp.getOverlappingPairCache(), world.proxies()));
  }
}

// A destroyed proxy's slot taken by a new proxy at the same place before the next frame: the
// events see the same index pair in both frames, the cache must still swap the proxies.
// A proxy of another broadphase (or a null pointer) is not one of viscd's: it is never read as
// one, and the calls that take a proxy say so. The other broadphase's proxy is freed by it alone.
TEST(BulletBroadphase, ForeignProxiesAreNotReadAsOurs) {
  Bullet bullet;
  viscd::BulletBroadphase bp;
  btDbvtBroadphase other;
  const int dyn = btBroadphaseProxy::DefaultFilter, all = btBroadphaseProxy::AllFilter;
  const int fixed = btBroadphaseProxy::StaticFilter, not_fixed = all ^ fixed;
  btBroadphaseProxy* ours = bp.createProxy({0, 0, 0}, {1, 1, 1}, BOX_SHAPE_PROXYTYPE, nullptr, dyn, all, nullptr);
  btBroadphaseProxy* theirs =
      other.createProxy({0, 0, 0}, {1, 1, 1}, BOX_SHAPE_PROXYTYPE, nullptr, fixed, not_fixed, &bullet.dispatcher);
  EXPECT_TRUE(bp.moving_index(ours).has_value());
  EXPECT_FALSE(bp.moving_index(theirs).has_value());
  EXPECT_FALSE(bp.in_static_set(theirs));
  EXPECT_FALSE(bp.moving_index(nullptr).has_value());
  EXPECT_FALSE(bp.in_static_set(nullptr));
  bp.set_always_active(theirs, true);  // ignored
  bp.set_always_active(nullptr, true);
  bp.calculateOverlappingPairs(&bullet.dispatcher);
  EXPECT_TRUE(bp.last_status().ok()) << bp.last_status().error();
  // A destroyed proxy is no longer ours either.
  btBroadphaseProxy* gone = bp.createProxy({5, 0, 0}, {6, 1, 1}, BOX_SHAPE_PROXYTYPE, nullptr, dyn, all, nullptr);
  EXPECT_TRUE(bp.moving_index(gone).has_value());
  bp.destroyProxy(gone, &bullet.dispatcher);
  EXPECT_FALSE(bp.moving_index(gone).has_value());
  other.destroyProxy(theirs, &bullet.dispatcher);
  bp.destroyProxy(ours, &bullet.dispatcher);
}

TEST(BulletBroadphase, SlotTakenOverWithinAFrame) {
  Bullet bullet;
  viscd::BulletBroadphase bp;
  const int dyn = btBroadphaseProxy::DefaultFilter, all = btBroadphaseProxy::AllFilter;
  const int fixed = btBroadphaseProxy::StaticFilter, not_fixed = all ^ fixed;
  btBroadphaseProxy* a = bp.createProxy({0, 0, 0}, {1, 1, 1}, BOX_SHAPE_PROXYTYPE, nullptr, dyn, all, nullptr);
  btBroadphaseProxy* b = bp.createProxy({0.5, 0, 0}, {2, 1, 1}, BOX_SHAPE_PROXYTYPE, nullptr, dyn, all, nullptr);
  btBroadphaseProxy* s = bp.createProxy({0, -1, 0}, {2, 0, 1}, BOX_SHAPE_PROXYTYPE, nullptr, fixed, not_fixed, nullptr);
  EXPECT_TRUE(bp.in_static_set(s));
  EXPECT_FALSE(bp.in_static_set(a));
  bp.calculateOverlappingPairs(&bullet.dispatcher);
  btOverlappingPairCache& cache = *bp.getOverlappingPairCache();
  EXPECT_EQ(cache.getNumOverlappingPairs(), 3);
  const auto slot_b = bp.moving_index(b);
  bp.destroyProxy(b, &bullet.dispatcher);
  bp.destroyProxy(s, &bullet.dispatcher);
  EXPECT_EQ(cache.getNumOverlappingPairs(), 0);  // removed at once, as Bullet's broadphases do
  btBroadphaseProxy* c = bp.createProxy({0.5, 0, 0}, {2, 1, 1}, BOX_SHAPE_PROXYTYPE, nullptr, dyn, all, nullptr);
  btBroadphaseProxy* t = bp.createProxy({0, -1, 0}, {2, 0, 1}, BOX_SHAPE_PROXYTYPE, nullptr, fixed, not_fixed, nullptr);
  EXPECT_EQ(bp.moving_index(c), slot_b);
  bp.calculateOverlappingPairs(&bullet.dispatcher);
  EXPECT_EQ(cache.getNumOverlappingPairs(), 3);
  EXPECT_NE(cache.findPair(a, c), nullptr);
  EXPECT_NE(cache.findPair(a, t), nullptr);
  EXPECT_NE(cache.findPair(c, t), nullptr);
  for (btBroadphaseProxy* p : {a, c, t}) bp.destroyProxy(p, &bullet.dispatcher);
  bp.resetPool(&bullet.dispatcher);
  EXPECT_EQ(bp.moving_slots(), 0u);
}

// The cache's overlap filter callback narrows the rule: pairs it refuses never enter.
TEST(BulletBroadphase, OverlapFilterCallbackNarrows) {
  struct OddOnly final : btOverlapFilterCallback {
    bool needBroadphaseCollision(btBroadphaseProxy* p, btBroadphaseProxy* q) const override {
      const bool rule = (p->m_collisionFilterGroup & q->m_collisionFilterMask) != 0 &&
                        (q->m_collisionFilterGroup & p->m_collisionFilterMask) != 0;
      return rule && ((p->m_uniqueId + q->m_uniqueId) % 3 != 0);
    }
  } callback;
  Bullet bullet;
  viscd::BulletBroadphase bp;
  bp.getOverlappingPairCache()->setOverlapFilterCallback(&callback);
  run_random_frames(bp, &bullet.dispatcher, 5, 20, 300);
}

// A moving proxy's group and mask edited in place count once Bullet passes its AABB again, the
// box unchanged (every step for every body in a default world), and only then.
TEST(BulletBroadphase, FiltersEditedInPlaceCountWhenTheAabbIsPassed) {
  Bullet bullet;
  viscd::BulletBroadphase bp;
  const btVector3 lo(0, 0, 0), hi(1, 1, 1), shift(0.5f, 0, 0);
  btBroadphaseProxy* a = bp.createProxy(lo, hi, BOX_SHAPE_PROXYTYPE, nullptr, btBroadphaseProxy::DefaultFilter,
                                        btBroadphaseProxy::AllFilter, &bullet.dispatcher);
  btBroadphaseProxy* b =
      bp.createProxy(lo + shift, hi + shift, BOX_SHAPE_PROXYTYPE, nullptr, btBroadphaseProxy::DefaultFilter,
                     btBroadphaseProxy::AllFilter, &bullet.dispatcher);
  btOverlappingPairCache& cache = *bp.getOverlappingPairCache();
  bp.calculateOverlappingPairs(&bullet.dispatcher);
  EXPECT_EQ(cache.getNumOverlappingPairs(), 1);
  // Edited, both boxes passed again unchanged: the rule refuses the pair.
  a->m_collisionFilterMask = btBroadphaseProxy::StaticFilter;
  bp.setAabb(a, lo, hi, &bullet.dispatcher);
  bp.setAabb(b, lo + shift, hi + shift, &bullet.dispatcher);
  bp.calculateOverlappingPairs(&bullet.dispatcher);
  EXPECT_EQ(cache.getNumOverlappingPairs(), 0);
  // Edited back: the pair returns once a's AABB is passed.
  a->m_collisionFilterMask = btBroadphaseProxy::AllFilter;
  bp.setAabb(a, lo, hi, &bullet.dispatcher);
  bp.calculateOverlappingPairs(&bullet.dispatcher);
  EXPECT_EQ(cache.getNumOverlappingPairs(), 1);
  bp.destroyProxy(a, &bullet.dispatcher);
  bp.destroyProxy(b, &bullet.dispatcher);
}

TEST(BulletBroadphase, StaticSetMembersNeverPassBulletsRule) {
  EXPECT_TRUE(viscd::BulletBroadphase::goes_to_static_set(
      btBroadphaseProxy::StaticFilter, btBroadphaseProxy::AllFilter ^ btBroadphaseProxy::StaticFilter));
  EXPECT_FALSE(
      viscd::BulletBroadphase::goes_to_static_set(btBroadphaseProxy::DefaultFilter, btBroadphaseProxy::AllFilter));
  // Every group and mask over five low bits and the high ones: two members never pass.
  std::vector<std::pair<int, int>> members;
  for (int g = 0; g < 32; ++g)
    for (int m = 0; m < 32; ++m)
      for (const int high : {0, ~31}) {
        const int mask = m | high;
        if (viscd::BulletBroadphase::goes_to_static_set(g, mask)) members.emplace_back(g, mask);
      }
  ASSERT_FALSE(members.empty());
  for (const auto& [g1, m1] : members)
    for (const auto& [g2, m2] : members) ASSERT_FALSE((g1 & m2) != 0 && (g2 & m1) != 0) << g1 << " " << m1;
}

// Queries: rayTest and aabbTest give exactly the proxies Bullet's own tests accept, on a fresh
// frame (viscd's queries) and after changes (brute force), with culled proxies seen too.
struct Collect final : btBroadphaseRayCallback {
  std::set<int> ids;
  bool process(const btBroadphaseProxy* proxy) override {
    EXPECT_TRUE(ids.insert(proxy->m_uniqueId).second) << "a proxy twice";
    return true;
  }
};

void check_queries(viscd::BulletBroadphase& bp, RandomProxies& world) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> size(0, 4);
  for (int q = 0; q < 60; ++q) {
    const btVector3 from = world.point(20), to = world.point(20);
    const btVector3 sweep_min(-size(rng), -size(rng), -size(rng)), sweep_max(size(rng), size(rng), size(rng));
    const bool swept = q % 2 == 1;
    const btVector3 lo = swept ? sweep_min : btVector3(0, 0, 0), hi = swept ? sweep_max : btVector3(0, 0, 0);
    Collect got;
    bp.rayTest(from, to, got, lo, hi);
    std::set<int> want;
    for (const btBroadphaseProxy* p : world.proxies()) {
      if (!finite(p)) continue;
      btScalar param = 1;
      btVector3 normal;
      if (btRayAabb(from, to, p->m_aabbMin - hi, p->m_aabbMax - lo, param, normal)) want.insert(p->m_uniqueId);
    }
    EXPECT_EQ(got.ids, want) << "ray " << q << (swept ? " swept" : "");

    const btVector3 box_lo = world.point(15), box_hi = box_lo + btVector3(size(rng), size(rng), size(rng));
    Collect in_box;
    bp.aabbTest(box_lo, box_hi, in_box);
    want.clear();
    for (const btBroadphaseProxy* p : world.proxies())
      if (finite(p) && TestAabbAgainstAabb2(p->m_aabbMin, p->m_aabbMax, box_lo, box_hi)) want.insert(p->m_uniqueId);
    EXPECT_EQ(in_box.ids, want) << "box " << q;
  }
}

TEST(BulletBroadphase, RayAndAabbTestsMatchBulletsTests) {
  Bullet bullet;
  viscd::BulletBroadphase bp;
  RandomProxies world(bp, &bullet.dispatcher, 8);
  for (int k = 0; k < 300; ++k) world.create();
  check_queries(bp, world);  // before any frame: brute force
  bp.calculateOverlappingPairs(&bullet.dispatcher);
  check_queries(bp, world);  // viscd's queries
  world.move(0.3);
  check_queries(bp, world);  // changed since the frame: brute force
  // Culling: a camera that sees a corner of the world only; queries still see everything.
  viscd::Camera camera;
  camera.eye[0] = 40, camera.eye[1] = 40, camera.eye[2] = 40;
  camera.target[0] = 15, camera.target[1] = 15, camera.target[2] = 15;
  camera.width = 320, camera.height = 240;
  bp.set_camera(&camera);
  bp.calculateOverlappingPairs(&bullet.dispatcher);
  ASSERT_TRUE(bp.last_status().ok()) << bp.last_status().error();
  EXPECT_LT(bp.last_stats().active, bp.last_stats().objects);
  check_queries(bp, world);
}

// Culling drops a culled proxy's pairs, except for always-active proxies; static ones never.
TEST(BulletBroadphase, CullingAndAlwaysActive) {
  Bullet bullet;
  viscd::BulletBroadphase bp;
  const int dyn = btBroadphaseProxy::DefaultFilter, all = btBroadphaseProxy::AllFilter;
  const int fixed = btBroadphaseProxy::StaticFilter, not_fixed = all ^ fixed;
  // Two touching pairs far behind the camera, and a static floor under one of them.
  btBroadphaseProxy* a = bp.createProxy({0, 0, 50}, {1, 1, 51}, BOX_SHAPE_PROXYTYPE, nullptr, dyn, all, nullptr);
  btBroadphaseProxy* b = bp.createProxy({0.5, 0, 50}, {2, 1, 51}, BOX_SHAPE_PROXYTYPE, nullptr, dyn, all, nullptr);
  btBroadphaseProxy* c = bp.createProxy({5, 0, 50}, {6, 1, 51}, BOX_SHAPE_PROXYTYPE, nullptr, dyn, all, nullptr);
  btBroadphaseProxy* d = bp.createProxy({5.5, 0, 50}, {7, 1, 51}, BOX_SHAPE_PROXYTYPE, nullptr, dyn, all, nullptr);
  btBroadphaseProxy* f =
      bp.createProxy({4, -1, 49}, {8, 0, 52}, BOX_SHAPE_PROXYTYPE, nullptr, fixed, not_fixed, nullptr);
  bp.calculateOverlappingPairs(&bullet.dispatcher);
  btOverlappingPairCache& cache = *bp.getOverlappingPairCache();
  EXPECT_EQ(cache.getNumOverlappingPairs(), 4);  // a-b, c-d, c-f, d-f
  viscd::Camera camera;                          // at the origin looking down -z: everything is behind it
  camera.eye[2] = 10;
  bp.set_camera(&camera);
  bp.set_always_active(c, true);
  bp.calculateOverlappingPairs(&bullet.dispatcher);
  ASSERT_TRUE(bp.last_status().ok()) << bp.last_status().error();
  EXPECT_EQ(bp.last_stats().active, 1u);
  EXPECT_EQ(cache.findPair(a, b), nullptr);
  EXPECT_EQ(cache.findPair(c, d), nullptr);  // d is culled
  EXPECT_NE(cache.findPair(c, f), nullptr);  // c never is, f is static
  EXPECT_EQ(cache.getNumOverlappingPairs(), 1);
  bp.set_camera(nullptr);
  bp.set_always_active(c, false);
  bp.calculateOverlappingPairs(&bullet.dispatcher);
  EXPECT_EQ(cache.getNumOverlappingPairs(), 4);
  btVector3 lo, hi;
  bp.getBroadphaseAabb(lo, hi);
  EXPECT_EQ(lo, btVector3(0, -1, 49));
  EXPECT_EQ(hi, btVector3(8, 1, 52));
  bp.getAabb(f, lo, hi);
  EXPECT_EQ(lo, btVector3(4, -1, 49));
  bp.printStats();
  for (btBroadphaseProxy* p : {a, b, c, d, f}) bp.destroyProxy(p, &bullet.dispatcher);
}

}  // namespace
