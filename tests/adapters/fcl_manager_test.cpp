// viscd::FclBroadphaseManager against fcl::NaiveCollisionManager, in the manner of FCL's own
// broadphase tests: random boxes, spheres, cylinders, meshes (and a half-space, whose AABB is
// infinite), every manager call, updates between queries, empty managers, early stops.
//   collide: every pair whose AABBs overlap is offered, once; pairs offered beyond those miss by
//            less than float rounding; the narrowphase contacts equal Naive's.
//   distance: the minimum distance equals Naive's, found with far fewer callback calls.
#include <fcl/broadphase/broadphase_bruteforce.h>
#include <fcl/broadphase/default_broadphase_callbacks.h>
#include <fcl/geometry/bvh/BVH_model.h>
#include <fcl/geometry/shape/box.h>
#include <fcl/geometry/shape/cylinder.h>
#include <fcl/geometry/shape/halfspace.h>
#include <fcl/geometry/shape/sphere.h>
#include <gtest/gtest.h>
#include <viscd/executor.hpp>
#include <viscd/fcl.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <random>
#include <set>
#include <utility>
#include <vector>

namespace {

using Object = fcl::CollisionObjectd;
using Manager = fcl::BroadPhaseCollisionManagerd;

std::shared_ptr<fcl::CollisionGeometryd> random_mesh(std::mt19937& rng, double size) {
  // A random closed tetrahedron pair (two tetrahedra sharing a face: a triangular bipyramid).
  std::uniform_real_distribution<double> u(-size, size);
  std::vector<fcl::Vector3d> points;
  for (int k = 0; k < 5; ++k) points.emplace_back(u(rng), u(rng), u(rng));
  const std::vector<fcl::Triangle> triangles = {{0, 1, 2}, {0, 1, 3}, {1, 2, 3}, {0, 2, 3},
                                                {0, 1, 4}, {1, 2, 4}, {0, 2, 4}};
  auto model = std::make_shared<fcl::BVHModel<fcl::OBBRSSd>>();
  model->beginModel();
  model->addSubModel(points, triangles);
  model->endModel();
  return model;
}

class Scene {
 public:
  Scene(unsigned seed, std::size_t count, double extent, bool with_halfspace = false) : rng_(seed), extent_(extent) {
    for (std::size_t k = 0; k < count; ++k) objects_.push_back(make_object(k % 4));
    if (with_halfspace)
      objects_.push_back(std::make_unique<Object>(std::make_shared<fcl::Halfspaced>(fcl::Vector3d(0, 0, 1), -extent)));
    for (auto& o : objects_) o->computeAABB();
  }

  std::unique_ptr<Object> make_object(std::size_t kind) {
    std::uniform_real_distribution<double> size(0.3, 1.5);
    std::shared_ptr<fcl::CollisionGeometryd> geometry;
    switch (kind) {
      case 0:
        geometry = std::make_shared<fcl::Boxd>(size(rng_), size(rng_), size(rng_));
        break;
      case 1:
        geometry = std::make_shared<fcl::Sphered>(0.5 * size(rng_));
        break;
      case 2:
        geometry = std::make_shared<fcl::Cylinderd>(0.5 * size(rng_), size(rng_));
        break;
      default:
        geometry = random_mesh(rng_, size(rng_));
    }
    auto object = std::make_unique<Object>(geometry, random_pose());
    object->computeAABB();
    return object;
  }
  fcl::Transform3d random_pose() {
    std::uniform_real_distribution<double> u(-extent_, extent_), angle(-3.14159, 3.14159);
    fcl::Transform3d t = fcl::Transform3d::Identity();
    t.translation() = fcl::Vector3d(u(rng_), u(rng_), u(rng_));
    t.linear() =
        (fcl::AngleAxisd(angle(rng_), fcl::Vector3d::UnitX()) * fcl::AngleAxisd(angle(rng_), fcl::Vector3d::UnitY()))
            .toRotationMatrix();
    return t;
  }
  // Moves a share of the objects (not the half-space) and returns them.
  std::vector<Object*> move(double share) {
    std::uniform_real_distribution<double> u(0, 1);
    std::vector<Object*> moved;
    for (auto& o : objects_) {
      if (u(rng_) >= share) continue;
      if (o->collisionGeometry()->getNodeType() == fcl::GEOM_HALFSPACE) continue;
      o->setTransform(random_pose());
      o->computeAABB();
      moved.push_back(o.get());
    }
    return moved;
  }
  std::vector<Object*> pointers() const {
    std::vector<Object*> out;
    for (const auto& o : objects_) out.push_back(o.get());
    return out;
  }
  std::mt19937& rng() { return rng_; }

 private:
  std::mt19937 rng_;
  double extent_;
  std::vector<std::unique_ptr<Object>> objects_;
};

using PairSet = std::set<std::pair<const Object*, const Object*>>;
std::pair<const Object*, const Object*> unordered(const Object* a, const Object* b) {
  return a < b ? std::make_pair(a, b) : std::make_pair(b, a);
}

// Records the pairs offered and those that collide.
struct CollideRecord {
  std::vector<std::pair<const Object*, const Object*>> offered;
  PairSet colliding;
  int stop_after = -1;  // return true on this call (0-based); -1: never
};
bool record_collision(Object* a, Object* b, void* data) {
  auto* r = static_cast<CollideRecord*>(data);
  r->offered.push_back(unordered(a, b));
  fcl::CollisionRequestd request;
  fcl::CollisionResultd result;
  if (a != b && fcl::collide(a, b, request, result) > 0) r->colliding.insert(unordered(a, b));
  return r->stop_after >= 0 && static_cast<int>(r->offered.size()) > r->stop_after;
}

struct DistanceRecord {
  fcl::DefaultDistanceData<double> data;
  int calls = 0;
};
bool record_distance(Object* a, Object* b, void* data, double& dist) {
  auto* r = static_cast<DistanceRecord*>(data);
  ++r->calls;
  return fcl::DefaultDistanceFunction(a, b, &r->data, dist);
}

bool aabbs_overlap(const Object* a, const Object* b) { return a->getAABB().overlap(b->getAABB()); }

// Checks collide(self): no duplicates, a superset of the overlapping pairs, extras within float
// rounding, the same contacts as Naive.
void check_self_collide(Manager& ours, Manager& naive) {
  CollideRecord got, want;
  ours.collide(&got, record_collision);
  naive.collide(&want, record_collision);
  const PairSet offered(got.offered.begin(), got.offered.end());
  EXPECT_EQ(offered.size(), got.offered.size()) << "a pair offered twice";
  for (const auto& [a, b] : got.offered) {
    EXPECT_NE(a, b);
    if (!aabbs_overlap(a, b)) {
      EXPECT_LT(a->getAABB().distance(b->getAABB()), 1e-5) << "an extra pair far apart";
    }
  }
  for (const auto& p : want.offered) EXPECT_TRUE(offered.count(p)) << "a pair whose AABBs overlap is missing";
  EXPECT_EQ(got.colliding, want.colliding);
}

void check_object_collide(Manager& ours, Manager& naive, Object* query) {
  CollideRecord got, want;
  ours.collide(query, &got, record_collision);
  naive.collide(query, &want, record_collision);
  std::vector<Object*> objects;
  naive.getObjects(objects);
  const PairSet offered(got.offered.begin(), got.offered.end());
  EXPECT_EQ(offered.size(), got.offered.size());
  for (Object* o : objects)
    if (aabbs_overlap(query, o)) {
      EXPECT_TRUE(offered.count(unordered(query, o)));
    }
  EXPECT_EQ(got.colliding, want.colliding);
}

// The same objects in both managers, set up.
void register_both(Manager& ours, Manager& naive, const std::vector<Object*>& all) {
  ours.registerObjects(all);
  naive.registerObjects(all);
  ours.setup();
  naive.setup();
}

void check_distance(double got, double want) { EXPECT_NEAR(got, want, 1e-9 * std::max(1.0, std::abs(want))); }

TEST(FclBroadphaseManager, EveryCallAgainstNaive) {
  Scene scene(1, 400, 12, /*with_halfspace=*/true);
  viscd::FclBroadphaseManager ours;
  fcl::NaiveCollisionManagerd naive;
  const std::vector<Object*> all = scene.pointers();
  register_both(ours, naive, all);
  EXPECT_EQ(ours.size(), all.size());
  EXPECT_FALSE(ours.empty());
  std::vector<Object*> listed;
  ours.getObjects(listed);
  EXPECT_EQ(std::set<Object*>(listed.begin(), listed.end()), std::set<Object*>(all.begin(), all.end()));

  // A second set, for collide(other) and distance(other), in our manager and in a Naive one.
  Scene others(2, 120, 12);
  viscd::FclBroadphaseManager ours_other;
  fcl::NaiveCollisionManagerd naive_other;
  ours_other.registerObjects(others.pointers());
  naive_other.registerObjects(others.pointers());
  ours_other.setup();

  for (int round = 0; round < 6; ++round) {
    SCOPED_TRACE(round);
    check_self_collide(ours, naive);
    for (int q = 0; q < 8; ++q) {
      auto query = scene.make_object(static_cast<std::size_t>(q) % 4);
      check_object_collide(ours, naive, query.get());
    }
    check_object_collide(ours, naive, all[5]);  // a registered object meets itself too, as in Naive

    CollideRecord cross_ours, cross_naive_other, cross_want;
    ours.collide(&ours_other, &cross_ours, record_collision);
    ours.collide(&naive_other, &cross_naive_other, record_collision);
    naive.collide(&naive_other, &cross_want, record_collision);
    EXPECT_EQ(cross_ours.colliding, cross_want.colliding);
    EXPECT_EQ(cross_naive_other.colliding, cross_want.colliding);
    const PairSet cross_offered(cross_ours.offered.begin(), cross_ours.offered.end());
    EXPECT_EQ(cross_offered.size(), cross_ours.offered.size());
    for (const auto& p : cross_want.offered) EXPECT_TRUE(cross_offered.count(p));
    // And the other way round: the small manager against the large one.
    CollideRecord small_large, small_large_want;
    ours_other.collide(&ours, &small_large, record_collision);
    naive_other.collide(&naive, &small_large_want, record_collision);
    EXPECT_EQ(small_large.colliding, small_large_want.colliding);

    // Self collide through collide(this).
    CollideRecord via_other, self_want;
    ours.collide(&ours, &via_other, record_collision);
    naive.collide(&self_want, record_collision);
    EXPECT_EQ(via_other.colliding, self_want.colliding);

    // Updates: all three forms.
    const std::vector<Object*> moved = scene.move(0.3);
    if (round % 3 == 0) {
      ours.update(moved);
    } else if (round % 3 == 1) {
      for (Object* o : moved) ours.update(o);
    } else {
      ours.update();
    }
    others.move(0.2);
    ours_other.update();
  }

  // Unregister and register: the order of getObjects() may change, the answers may not.
  for (std::size_t k = 0; k < all.size(); k += 3) {
    ours.unregisterObject(all[k]);
    naive.unregisterObject(all[k]);
  }
  ours.unregisterObject(all[0]);  // twice: ignored
  ours.registerObject(all[1]);    // already there: ignored
  EXPECT_EQ(ours.size(), naive.size());
  check_self_collide(ours, naive);
}

// Few objects named to update() each round, as a simulation reports its movers: the manager lists
// them to its detector (FrameInput::moved), which keeps the rest. Every round's self collide
// against Naive, with objects named that did not move, an unknown object named, an update() of
// everything, and removals in between (which renumber: the next frame is not listed).
TEST(FclBroadphaseManager, FewNamedUpdatesAgainstNaive) {
  Scene scene(5, 1500, 20);
  viscd::FclBroadphaseManager ours;
  fcl::NaiveCollisionManagerd naive;
  const std::vector<Object*> all = scene.pointers();
  register_both(ours, naive, all);
  auto stranger = scene.make_object(0);
  for (int round = 0; round < 24; ++round) {
    SCOPED_TRACE(round);
    check_self_collide(ours, naive);
    std::vector<Object*> moved = scene.move(0.01);
    moved.push_back(all[7]);                             // named, not moved
    moved.push_back(stranger.get());                     // not registered: ignored
    if (!moved.empty()) moved.push_back(moved.front());  // named twice
    if (round % 2) {
      ours.update(moved);
    } else {
      for (Object* o : moved) ours.update(o);
    }
    if (round == 9) ours.update();
    if (round == 15) {
      ours.unregisterObject(all[100]);
      naive.unregisterObject(all[100]);
    }
  }
  EXPECT_TRUE(ours.last_status().ok()) << ours.last_status().error();
}

TEST(FclBroadphaseManager, DistanceIsTheExactMinimumAndStopsEarly) {
  for (const unsigned seed : {3u, 4u, 5u}) {
    SCOPED_TRACE(seed);
    Scene scene(seed, 300, 40);  // sparse: few objects touch
    viscd::FclBroadphaseManager ours;
    fcl::NaiveCollisionManagerd naive;
    ours.registerObjects(scene.pointers());
    naive.registerObjects(scene.pointers());
    ours.setup();
    for (int round = 0; round < 3; ++round) {
      DistanceRecord got, want;
      ours.distance(&got, record_distance);
      naive.distance(&want, record_distance);
      check_distance(got.data.result.min_distance, want.data.result.min_distance);
      // Best first: the callback is called only for pairs whose AABB distance is at most the
      // minimum (0 when objects collide: FCL reports a negative distance), which any exact search
      // must look at (Naive looks at every pair's AABBs).
      const std::vector<Object*> objects = scene.pointers();
      const double limit = std::max(want.data.result.min_distance, 0.0);
      int needed = 0;
      for (std::size_t i = 0; i < objects.size(); ++i)
        for (std::size_t j = i + 1; j < objects.size(); ++j)
          if (objects[i]->getAABB().distance(objects[j]->getAABB()) <= limit) ++needed;
      EXPECT_LE(got.calls, needed);

      for (int q = 0; q < 5; ++q) {
        auto query = scene.make_object(static_cast<std::size_t>(q) % 4);
        DistanceRecord one, one_want;
        ours.distance(query.get(), &one, record_distance);
        naive.distance(query.get(), &one_want, record_distance);
        check_distance(one.data.result.min_distance, one_want.data.result.min_distance);
      }

      Scene others(seed + 10, 50, 40);
      viscd::FclBroadphaseManager ours_other;
      fcl::NaiveCollisionManagerd naive_other;
      ours_other.registerObjects(others.pointers());
      naive_other.registerObjects(others.pointers());
      DistanceRecord cross, cross_naive_other, cross_want, reverse, reverse_want;
      ours.distance(&ours_other, &cross, record_distance);
      ours.distance(&naive_other, &cross_naive_other, record_distance);
      naive.distance(&naive_other, &cross_want, record_distance);
      ours_other.distance(&ours, &reverse, record_distance);
      naive_other.distance(&naive, &reverse_want, record_distance);
      check_distance(cross.data.result.min_distance, cross_want.data.result.min_distance);
      check_distance(cross_naive_other.data.result.min_distance, cross_want.data.result.min_distance);
      check_distance(reverse.data.result.min_distance, reverse_want.data.result.min_distance);

      ours.update(scene.move(0.5));
    }
  }
}

// A pair cap too small for the frames: every answer still exact (brute force, pairs one by one),
// and last_status() says why, for the self frame and for distance()'s grown frames alike.
TEST(FclBroadphaseManager, FramesOverThePairCapFallBackAndSayWhy) {
  Scene scene(21, 200, 3);  // dense: hundreds of overlapping pairs
  viscd::Config config;
  config.pair_memory_cap = 64;  // eight pairs
  viscd::FclBroadphaseManager ours(config);
  fcl::NaiveCollisionManagerd naive;
  register_both(ours, naive, scene.pointers());
  check_self_collide(ours, naive);
  ASSERT_FALSE(ours.last_status().ok());
  EXPECT_NE(ours.last_status().error().find("pair"), std::string::npos) << ours.last_status().error();
  DistanceRecord got, want;
  ours.distance(&got, record_distance);
  naive.distance(&want, record_distance);
  check_distance(got.data.result.min_distance, want.data.result.min_distance);
  ASSERT_FALSE(ours.last_status().ok());
  // Far apart, the self frame fits again: ok once more.
  Scene sparse(22, 20, 400);
  viscd::FclBroadphaseManager roomy(config);
  fcl::NaiveCollisionManagerd naive_sparse;
  register_both(roomy, naive_sparse, sparse.pointers());
  check_self_collide(roomy, naive_sparse);
  EXPECT_TRUE(roomy.last_status().ok()) << roomy.last_status().error();
}

// Enough objects for update() to read them in parallel chunks on the detector's executor (here a
// caller's, which counts its calls and runs the tasks in reverse order); every box moved, then a
// self collide against Naive. With Config::threads = 1 the executor is not asked.
class CountingExecutor final : public viscd::Executor {
 public:
  int runs = 0;
  [[nodiscard]] int concurrency() const override { return 4; }
  void run(std::uint32_t count, viscd::TaskRef task) override {
    ++runs;
    for (std::uint32_t i = count; i-- > 0;) task(i);
  }
};

TEST(FclBroadphaseManager, UpdateReadsInParallelChunks) {
  for (const int threads : {0, 1}) {
    SCOPED_TRACE(threads);
    Scene scene(31, 9000, 60);  // two chunks of 4096 or more
    CountingExecutor executor;
    viscd::Config config;
    config.executor = &executor;
    config.threads = threads;
    viscd::FclBroadphaseManager ours(config);
    fcl::NaiveCollisionManagerd naive;
    register_both(ours, naive, scene.pointers());
    (void)scene.move(1.0);  // every object somewhere else
    executor.runs = 0;
    ours.update();
    naive.update();
    if (threads == 1) {
      EXPECT_EQ(executor.runs, 0);
    } else {
      EXPECT_EQ(executor.runs, 1);  // update()'s read; the frame runs at the collide
    }
    check_self_collide(ours, naive);
  }
}

// Two objects far apart, then one object: the radius doubling and the empty answers.
TEST(FclBroadphaseManager, FewAndFarObjects) {
  auto a = std::make_unique<Object>(std::make_shared<fcl::Sphered>(1.0), fcl::Transform3d::Identity());
  fcl::Transform3d far = fcl::Transform3d::Identity();
  far.translation() = fcl::Vector3d(1000, -2000, 3000);
  auto b = std::make_unique<Object>(std::make_shared<fcl::Boxd>(1, 2, 3), far);
  a->computeAABB();
  b->computeAABB();
  viscd::FclBroadphaseManager ours;
  fcl::NaiveCollisionManagerd naive;
  for (Manager* m : {static_cast<Manager*>(&ours), static_cast<Manager*>(&naive)})
    m->registerObjects({a.get(), b.get()});
  ours.setup();
  DistanceRecord got, want;
  ours.distance(&got, record_distance);
  naive.distance(&want, record_distance);
  check_distance(got.data.result.min_distance, want.data.result.min_distance);
  EXPECT_EQ(got.calls, 1);
  CollideRecord none;
  ours.collide(&none, record_collision);
  EXPECT_TRUE(none.offered.empty());

  ours.unregisterObject(b.get());
  DistanceRecord single;
  ours.distance(&single, record_distance);
  EXPECT_EQ(single.calls, 0);
}

TEST(FclBroadphaseManager, EmptyManagers) {
  viscd::FclBroadphaseManager ours, other;
  EXPECT_TRUE(ours.empty());
  EXPECT_EQ(ours.size(), 0u);
  ours.setup();
  ours.update();
  CollideRecord c;
  DistanceRecord d;
  ours.collide(&c, record_collision);
  ours.collide(&other, &c, record_collision);
  ours.distance(&d, record_distance);
  ours.distance(&other, &d, record_distance);
  auto query = std::make_unique<Object>(std::make_shared<fcl::Sphered>(1.0), fcl::Transform3d::Identity());
  query->computeAABB();
  ours.collide(query.get(), &c, record_collision);
  ours.distance(query.get(), &d, record_distance);
  EXPECT_TRUE(c.offered.empty());
  EXPECT_EQ(d.calls, 0);
  // A full manager against an empty one, both ways.
  Scene scene(6, 20, 3);
  other.registerObjects(scene.pointers());
  other.collide(&ours, &c, record_collision);
  ours.collide(&other, &c, record_collision);
  other.distance(&ours, &d, record_distance);
  EXPECT_TRUE(c.offered.empty());
  EXPECT_EQ(d.calls, 0);
  other.clear();
  EXPECT_TRUE(other.empty());
}

// AABBs no float holds: NaN bounds (FCL's overlap test is true for them), bounds beyond the float
// range and beyond viscd's coordinate limit, tiny ones. Every pair whose AABBs overlap is offered
// once, through the first read, update() and collide(obj), against Naive's pairs.
TEST(FclBroadphaseManager, BoundsNoFloatHoldsKeepEveryOverlap) {
  const double nan = std::nan(""), max_float = std::numeric_limits<float>::max();
  std::vector<std::unique_ptr<Object>> objects;
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-2, 2);
  auto add = [&](double x, double y, double z) {
    fcl::Transform3d t = fcl::Transform3d::Identity();
    t.translation() = fcl::Vector3d(x, y, z);
    objects.push_back(std::make_unique<Object>(std::make_shared<fcl::Boxd>(1, 1, 1), t));
    objects.back()->computeAABB();
  };
  for (int k = 0; k < 40; ++k) add(u(rng), u(rng), u(rng));
  for (const double far : {1e300, -1e300, 1.5 * max_float, -1.5 * max_float, 2e18, -2e18}) add(far, u(rng), u(rng));
  add(nan, 0, 0);
  add(0, nan, 1);
  add(1e-40, -1e-40, 1e-45);
  struct Offered {
    static bool add(Object* a, Object* b, void* data) {
      static_cast<std::vector<std::pair<const Object*, const Object*>>*>(data)->push_back(unordered(a, b));
      return false;
    }
  };
  auto check = [&](Manager& ours, Manager& naive) {
    std::vector<std::pair<const Object*, const Object*>> got, want;
    ours.collide(&got, Offered::add);
    naive.collide(&want, Offered::add);
    const PairSet offered(got.begin(), got.end());
    EXPECT_EQ(offered.size(), got.size()) << "a pair offered twice";
    for (const auto& p : want) EXPECT_TRUE(offered.count(p)) << "a pair whose AABBs overlap is missing";
    for (const auto& o : objects) {
      std::vector<std::pair<const Object*, const Object*>> one;
      ours.collide(o.get(), &one, Offered::add);
      for (const auto& other : objects)
        if (other != o && aabbs_overlap(o.get(), other.get())) {
          EXPECT_TRUE(std::count(one.begin(), one.end(), unordered(o.get(), other.get())) == 1);
        }
    }
  };
  std::vector<Object*> all;
  for (auto& o : objects) all.push_back(o.get());
  viscd::FclBroadphaseManager ours;
  fcl::NaiveCollisionManagerd naive;
  register_both(ours, naive, all);
  check(ours, naive);
  std::shuffle(objects.begin(), objects.end() - 1, rng);
  for (std::size_t k = 0; k + 1 < objects.size(); k += 2) {  // pairs of objects swap places
    const fcl::Transform3d t = objects[k]->getTransform();
    objects[k]->setTransform(objects[k + 1]->getTransform());
    objects[k + 1]->setTransform(t);
    objects[k]->computeAABB();
    objects[k + 1]->computeAABB();
  }
  ours.update();
  naive.update();
  check(ours, naive);
}

TEST(FclBroadphaseManager, StopsWhenTheCallbackSaysSo) {
  Scene scene(7, 200, 4);  // dense: many overlaps
  viscd::FclBroadphaseManager ours, other;
  ours.registerObjects(scene.pointers());
  ours.setup();
  Scene second(8, 50, 4);
  other.registerObjects(second.pointers());
  CollideRecord self, one, cross;
  self.stop_after = one.stop_after = cross.stop_after = 2;
  ours.collide(&self, record_collision);
  ours.collide(scene.pointers()[0], &one, record_collision);
  ours.collide(&other, &cross, record_collision);
  EXPECT_EQ(self.offered.size(), 3u);
  EXPECT_EQ(one.offered.size(), 3u);
  EXPECT_EQ(cross.offered.size(), 3u);
  struct Stop {
    static bool first(Object*, Object*, void* calls, double&) {
      ++*static_cast<int*>(calls);
      return true;
    }
  };
  int calls = 0;
  ours.distance(&calls, Stop::first);
  ours.distance(&other, &calls, Stop::first);
  ours.distance(scene.pointers()[1], &calls, Stop::first);
  EXPECT_EQ(calls, 3);
}

}  // namespace
