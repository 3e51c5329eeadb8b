// Real Bullet worlds on viscd::BulletBroadphase: a pile of spheres and boxes falling into a
// walled bin with pillars and a kinematic paddle, bodies removed and added while it runs. After
// every step the pair cache must hold every pair whose AABBs overlap under Bullet's filter rule
// (brute force over the proxies) and nothing else, and no body may fall through the floor. The
// same world on btDbvtBroadphase must end alike: every body in the bin, resting at similar heights.
// World queries (rayTest, convexSweepTest, contactTest) must agree with btDbvtBroadphase's.
#include <btBulletDynamicsCommon.h>
#include <gtest/gtest.h>
#include <viscd/bullet.hpp>

#include <algorithm>
#include <cmath>
#include <memory>
#include <random>
#include <set>
#include <utility>
#include <vector>

namespace {

constexpr float kHalfWidth = 5;

class BinWorld {
 public:
  explicit BinWorld(std::unique_ptr<btBroadphaseInterface> broadphase)
      : dispatcher_(&configuration_),
        broadphase_(std::move(broadphase)),
        world_(&dispatcher_, broadphase_.get(), &solver_, &configuration_) {
    world_.setGravity(btVector3(0, -9.81f, 0));
    add_static(box(kHalfWidth + 1, 0.5f, kHalfWidth + 1), btVector3(0, -0.5f, 0));
    btCollisionShape* wall_x = box(0.5f, 4, kHalfWidth + 1);
    btCollisionShape* wall_z = box(kHalfWidth + 1, 4, 0.5f);
    add_static(wall_x, btVector3(kHalfWidth + 0.5f, 4, 0));
    add_static(wall_x, btVector3(-kHalfWidth - 0.5f, 4, 0));
    add_static(wall_z, btVector3(0, 4, kHalfWidth + 0.5f));
    add_static(wall_z, btVector3(0, 4, -kHalfWidth - 0.5f));
    btCollisionShape* pillar = box(0.35f, 2, 0.35f);
    for (const float x : {-2.0f, 2.0f})
      for (const float z : {-2.0f, 2.0f}) add_static(pillar, btVector3(x, 2, z));
    // A kinematic paddle sweeping along the floor, stirring the pile's bottom layer.
    paddle_ = add(box(1.5f, 0.2f, 0.2f), btVector3(0, 0.5f, 0), 0);
    paddle_->setCollisionFlags(paddle_->getCollisionFlags() | btCollisionObject::CF_KINEMATIC_OBJECT);
    paddle_->setActivationState(DISABLE_DEACTIVATION);
    sphere_ = keep(std::make_unique<btSphereShape>(0.3f));
    cube_ = box(0.25f, 0.25f, 0.25f);
    for (int layer = 0; layer < 8; ++layer)
      for (int i = 0; i < 5; ++i)
        for (int k = 0; k < 5; ++k) add_falling(layer, i, k);
  }
  ~BinWorld() {
    for (auto& body : bodies_) world_.removeRigidBody(body.get());
  }

  void add_falling(int layer, int i, int k) {
    const float spacing = 2 * (kHalfWidth - 0.5f) / 4;
    const btVector3 at(-kHalfWidth + 0.5f + spacing * static_cast<float>(i) + 0.03f * static_cast<float>(layer),
                       3 + 0.8f * static_cast<float>(layer), -kHalfWidth + 0.5f + spacing * static_cast<float>(k));
    falling_.push_back(add((i + k + layer) % 2 ? sphere_ : cube_, at, 1));
  }

  void step(int n) {
    // The paddle (kinematic: moved by its transform, in viscd's static set) swings in x, at most
    // 3 m/s, between the pillars (x = +-2.5 at most: it stays 1 m off the walls).
    btTransform t;
    t.setIdentity();
    t.setOrigin(btVector3(1.0f * std::sin(0.05f * static_cast<float>(n)), 0.5f, 0));
    paddle_->setWorldTransform(t);
    paddle_->getMotionState()->setWorldTransform(t);
    world_.stepSimulation(1.0f / 60, 1, 1.0f / 60);
  }

  // Removes every fourth falling body and drops as many new ones from above.
  void churn(int round) {
    std::vector<btRigidBody*> kept;
    int removed = 0;
    for (std::size_t b = 0; b < falling_.size(); ++b) {
      if (b % 4 == static_cast<std::size_t>(round % 4)) {
        world_.removeRigidBody(falling_[b]);
        ++removed;
      } else {
        kept.push_back(falling_[b]);
      }
    }
    falling_ = kept;
    for (int r = 0; r < removed; ++r) add_falling(10 + r / 25, (r / 5) % 5, r % 5);
  }

  btDiscreteDynamicsWorld& world() { return world_; }
  btBroadphaseInterface& broadphase() { return *broadphase_; }
  const std::vector<btRigidBody*>& falling() const { return falling_; }

 private:
  btCollisionShape* keep(std::unique_ptr<btCollisionShape> shape) {
    shapes_.push_back(std::move(shape));
    return shapes_.back().get();
  }
  btCollisionShape* box(float x, float y, float z) { return keep(std::make_unique<btBoxShape>(btVector3(x, y, z))); }
  btRigidBody* add(btCollisionShape* shape, const btVector3& at, float mass) {
    btVector3 inertia(0, 0, 0);
    if (mass > 0) shape->calculateLocalInertia(mass, inertia);
    btTransform transform;
    transform.setIdentity();
    transform.setOrigin(at);
    motions_.push_back(std::make_unique<btDefaultMotionState>(transform));
    btRigidBody::btRigidBodyConstructionInfo info(mass, motions_.back().get(), shape, inertia);
    info.m_friction = 0.6f;
    bodies_.push_back(std::make_unique<btRigidBody>(info));
    world_.addRigidBody(bodies_.back().get());
    return bodies_.back().get();
  }
  void add_static(btCollisionShape* shape, const btVector3& at) { add(shape, at, 0); }

  btDefaultCollisionConfiguration configuration_;
  btCollisionDispatcher dispatcher_;
  std::unique_ptr<btBroadphaseInterface> broadphase_;
  btSequentialImpulseConstraintSolver solver_;
  btDiscreteDynamicsWorld world_;
  std::vector<std::unique_ptr<btCollisionShape>> shapes_;
  std::vector<std::unique_ptr<btDefaultMotionState>> motions_;
  std::vector<std::unique_ptr<btRigidBody>> bodies_;  // removed ones stay here, out of the world
  std::vector<btRigidBody*> falling_;
  btRigidBody* paddle_ = nullptr;
  btCollisionShape* sphere_ = nullptr;
  btCollisionShape* cube_ = nullptr;
};

using ProxyPair = std::pair<const void*, const void*>;
ProxyPair proxy_pair(const btBroadphaseProxy* a, const btBroadphaseProxy* b) {
  return a < b ? ProxyPair{a, b} : ProxyPair{b, a};
}

// Pairs the cache is missing and pairs it has that it should not.
void check_cache(btDiscreteDynamicsWorld& world, const viscd::BulletBroadphase& bp, int step) {
  btOverlappingPairCache& cache = *world.getBroadphase()->getOverlappingPairCache();
  std::set<ProxyPair> got;
  const btBroadphasePairArray& array = cache.getOverlappingPairArray();
  for (int c = 0; c < array.size(); ++c)
    ASSERT_TRUE(got.insert(proxy_pair(array[c].m_pProxy0, array[c].m_pProxy1)).second);
  std::set<ProxyPair> want;
  const btCollisionObjectArray& objects = world.getCollisionObjectArray();
  for (int a = 0; a < objects.size(); ++a)
    for (int b = a + 1; b < objects.size(); ++b) {
      btBroadphaseProxy *p = objects[a]->getBroadphaseHandle(), *q = objects[b]->getBroadphaseHandle();
      if (!TestAabbAgainstAabb2(p->m_aabbMin, p->m_aabbMax, q->m_aabbMin, q->m_aabbMax)) continue;
      if (!cache.needsBroadphaseCollision(p, q)) continue;
      ASSERT_FALSE(bp.in_static_set(p) && bp.in_static_set(q));  // Bullet's rule refuses those
      want.insert(proxy_pair(p, q));
    }
  std::vector<ProxyPair> missing, extra;
  std::set_difference(want.begin(), want.end(), got.begin(), got.end(), std::back_inserter(missing));
  std::set_difference(got.begin(), got.end(), want.begin(), want.end(), std::back_inserter(extra));
  ASSERT_TRUE(missing.empty()) << missing.size() << " pairs missing after step " << step;
  ASSERT_TRUE(extra.empty()) << extra.size() << " pairs too many after step " << step;
}

struct Outcome {
  std::size_t bodies = 0, inside = 0, resting = 0;
  double mean_height = 0;
};

Outcome outcome(const BinWorld& w) {
  Outcome o;
  for (const btRigidBody* body : w.falling()) {
    const btVector3 p = body->getCenterOfMassPosition();
    ++o.bodies;
    if (p.y() > 0 && p.y() < 12 && std::abs(p.x()) < kHalfWidth && std::abs(p.z()) < kHalfWidth) ++o.inside;
    if (body->getLinearVelocity().length() < 0.2f) ++o.resting;
    o.mean_height += p.y();
  }
  o.mean_height /= static_cast<double>(o.bodies);
  return o;
}

constexpr int kSteps = 300;

Outcome run(BinWorld& w, const viscd::BulletBroadphase* viscd_bp, int* followed = nullptr) {
  for (int step = 1; step <= kSteps; ++step) {
    w.step(step);
    if (viscd_bp) {
      EXPECT_TRUE(viscd_bp->last_status().ok()) << viscd_bp->last_status().error();
      if (followed) *followed += viscd_bp->last_stats().followed_change;
      check_cache(w.world(), *viscd_bp, step);
      if (::testing::Test::HasFatalFailure()) return {};
    }
    for (const btRigidBody* body : w.falling()) {
      const btVector3 p = body->getCenterOfMassPosition();
      if (p.y() < 0 || std::abs(p.x()) > kHalfWidth || std::abs(p.z()) > kHalfWidth) {
        ADD_FAILURE() << "a body fell through the floor or left the bin at step " << step << ": at " << p.x() << " "
                      << p.y() << " " << p.z();
        return {};
      }
    }
    if (step == 90 || step == 150) w.churn(step);
  }
  return outcome(w);
}

TEST(BulletWorld, CacheExactEveryStepAndEndsLikeDbvt) {
  // The adapter names the bodies whose boxes changed (FrameInput::moved); verify_moved checks
  // every list against the boxes, failing the step (last_status()) if one is incomplete.
  viscd::Config config;
  config.verify_moved = true;
  auto viscd_bp = std::make_unique<viscd::BulletBroadphase>(config);
  const viscd::BulletBroadphase* bp = viscd_bp.get();
  BinWorld on_viscd(std::move(viscd_bp));
  EXPECT_EQ(bp->static_proxy_count(), 10u);  // floor, 4 walls, 4 pillars, the kinematic paddle
  int followed = 0;
  const Outcome v = run(on_viscd, bp, &followed);
  std::printf("viscd: %d of %d steps followed change\n", followed, kSteps);
  ASSERT_FALSE(::testing::Test::HasFailure());

  BinWorld on_dbvt(std::make_unique<btDbvtBroadphase>());
  const Outcome d = run(on_dbvt, nullptr);
  ASSERT_FALSE(::testing::Test::HasFailure());

  std::printf("viscd: %zu bodies, %zu inside, %zu resting, mean height %.3f\n", v.bodies, v.inside, v.resting,
              v.mean_height);
  std::printf("dbvt:  %zu bodies, %zu inside, %zu resting, mean height %.3f\n", d.bodies, d.inside, d.resting,
              d.mean_height);
  EXPECT_EQ(v.bodies, d.bodies);
  EXPECT_EQ(v.inside, v.bodies);
  EXPECT_EQ(d.inside, d.bodies);
  EXPECT_NEAR(static_cast<double>(v.resting), static_cast<double>(d.resting), 0.1 * static_cast<double>(d.bodies));
  EXPECT_NEAR(v.mean_height, d.mean_height, 0.1 * d.mean_height);
}

// The world's queries (through the broadphase's rayTest and aabbTest) on the same scene, before it
// moves: the same objects as with btDbvtBroadphase.
TEST(BulletWorld, QueriesAgreeWithDbvt) {
  BinWorld on_viscd(std::make_unique<viscd::BulletBroadphase>());
  BinWorld on_dbvt(std::make_unique<btDbvtBroadphase>());
  for (BinWorld* w : {&on_viscd, &on_dbvt}) w->world().performDiscreteCollisionDetection();
  const auto index_of = [](const BinWorld& w, const btCollisionObject* o) {
    const btCollisionObjectArray& objects = const_cast<BinWorld&>(w).world().getCollisionObjectArray();
    return objects.findLinearSearch(const_cast<btCollisionObject*>(o));
  };
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(-7, 7), h(-1, 12);
  for (int q = 0; q < 100; ++q) {
    const btVector3 from(u(rng), h(rng), u(rng)), to(u(rng), h(rng), u(rng));
    std::set<int> hits[2];
    int i = 0;
    for (BinWorld* w : {&on_viscd, &on_dbvt}) {
      btCollisionWorld::AllHitsRayResultCallback all(from, to);
      w->world().rayTest(from, to, all);
      for (int k = 0; k < all.m_collisionObjects.size(); ++k) hits[i].insert(index_of(*w, all.m_collisionObjects[k]));
      ++i;
    }
    EXPECT_EQ(hits[0], hits[1]) << "ray " << q;

    btSphereShape probe(0.4f);
    btTransform a, b;
    a.setIdentity();
    b.setIdentity();
    a.setOrigin(from);
    b.setOrigin(to);
    // The first hit's fraction (objects may tie: a probe starting inside two objects hits both
    // at 0; then either is the closest), and the object when it is not a tie at the start.
    int closest[2] = {-2, -2};
    btScalar fraction[2] = {2, 2};
    i = 0;
    for (BinWorld* w : {&on_viscd, &on_dbvt}) {
      btCollisionWorld::ClosestConvexResultCallback sweep(from, to);
      w->world().convexSweepTest(&probe, a, b, sweep);
      closest[i] = sweep.hasHit() ? index_of(*w, sweep.m_hitCollisionObject) : -1;
      fraction[i++] = sweep.m_closestHitFraction;
    }
    EXPECT_EQ(fraction[0], fraction[1]) << "sweep " << q;
    if (fraction[0] > 0) {
      EXPECT_EQ(closest[0], closest[1]) << "sweep " << q;
    }

    // Objects the probe touches or penetrates. (btDbvtBroadphase's fattened leaves also let
    // through objects whose AABBs miss the probe's, for which Bullet reports points at a positive
    // distance; an exact broadphase, as btSimpleBroadphase, does not: those are left out.)
    struct Count final : btCollisionWorld::ContactResultCallback {
      std::set<const void*> objects;
      btScalar addSingleResult(btManifoldPoint& point, const btCollisionObjectWrapper* w0, int, int,
                               const btCollisionObjectWrapper* w1, int, int) override {
        if (point.getDistance() > 0) return 0;
        objects.insert(w0->getCollisionObject());
        objects.insert(w1->getCollisionObject());
        return 0;
      }
    };
    btCollisionObject probe_object;
    probe_object.setCollisionShape(&probe);
    probe_object.setWorldTransform(a);
    std::size_t touched[2];
    i = 0;
    for (BinWorld* w : {&on_viscd, &on_dbvt}) {
      Count count;
      w->world().contactTest(&probe_object, count);
      touched[i++] = count.objects.size();
    }
    EXPECT_EQ(touched[0], touched[1]) << "contact " << q;
  }
}

}  // namespace
