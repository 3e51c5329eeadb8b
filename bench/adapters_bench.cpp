// The adapters measured against the engines' own broadphases (docs/adapters.md, "Measurements"):
//   bullet: a btDiscreteDynamicsWorld of --bodies falling boxes in a walled bin, stepped on
//           viscd::BulletBroadphase, btDbvtBroadphase and bt32BitAxisSweep3; per step, the
//           broadphase's share (from the first setAabb of the step's updateAabbs to the end of
//           calculateOverlappingPairs) and the whole step; medians over the steps.
//   fcl:    self collision of --fcl-boxes random boxes with a counting callback (no narrowphase)
//           on viscd::FclBroadphaseManager and fcl::DynamicAABBTreeCollisionManager: setup +
//           collide, then update + collide after every box moved, then 10 frames in which 1 % of
//           the boxes move and update(vector) names them; medians over --reps (x 10 for the last).
// Not a test: timings depend on the machine. Run: viscd_adapters_bench [--only bullet|fcl] ...
#include <btBulletDynamicsCommon.h>
#include <fcl/broadphase/broadphase_dynamic_AABB_tree.h>
#include <fcl/geometry/shape/box.h>
#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <functional>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "viscd/bullet.hpp"
#include "viscd/fcl.hpp"

namespace {

using Clock = std::chrono::steady_clock;
double ms_since(Clock::time_point t) { return std::chrono::duration<double, std::milli>(Clock::now() - t).count(); }

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

// Forwards everything to the broadphase it wraps and times each step's broadphase share.
class TimedBroadphase final : public btBroadphaseInterface {
 public:
  explicit TimedBroadphase(std::unique_ptr<btBroadphaseInterface> inner) : inner_(std::move(inner)) {}
  btBroadphaseProxy* createProxy(const btVector3& lo, const btVector3& hi, int type, void* user, int group, int mask,
                                 btDispatcher* d) override {
    return inner_->createProxy(lo, hi, type, user, group, mask, d);
  }
  void destroyProxy(btBroadphaseProxy* p, btDispatcher* d) override { inner_->destroyProxy(p, d); }
  void setAabb(btBroadphaseProxy* p, const btVector3& lo, const btVector3& hi, btDispatcher* d) override {
    if (!in_step_) {
      in_step_ = true;
      step_start_ = Clock::now();
    }
    inner_->setAabb(p, lo, hi, d);
  }
  void getAabb(btBroadphaseProxy* p, btVector3& lo, btVector3& hi) const override { inner_->getAabb(p, lo, hi); }
  void rayTest(const btVector3& from, const btVector3& to, btBroadphaseRayCallback& cb, const btVector3& lo,
               const btVector3& hi) override {
    inner_->rayTest(from, to, cb, lo, hi);
  }
  void aabbTest(const btVector3& lo, const btVector3& hi, btBroadphaseAabbCallback& cb) override {
    inner_->aabbTest(lo, hi, cb);
  }
  void calculateOverlappingPairs(btDispatcher* d) override {
    const auto start = Clock::now();
    inner_->calculateOverlappingPairs(d);
    pairs_ms.push_back(ms_since(start));
    share_ms.push_back(in_step_ ? ms_since(step_start_) : pairs_ms.back());
    in_step_ = false;
  }
  btOverlappingPairCache* getOverlappingPairCache() override { return inner_->getOverlappingPairCache(); }
  const btOverlappingPairCache* getOverlappingPairCache() const override { return inner_->getOverlappingPairCache(); }
  void getBroadphaseAabb(btVector3& lo, btVector3& hi) const override { inner_->getBroadphaseAabb(lo, hi); }
  void resetPool(btDispatcher* d) override { inner_->resetPool(d); }
  void printStats() override { inner_->printStats(); }

  std::vector<double> pairs_ms, share_ms;  // calculateOverlappingPairs; updateAabbs + it

 private:
  std::unique_ptr<btBroadphaseInterface> inner_;
  bool in_step_ = false;
  Clock::time_point step_start_;
};

struct BulletRun {
  double pairs_ms = 0, share_ms = 0, step_ms = 0;
  int cache_pairs = 0;
  double mean_height = 0;
  // Per quarter of the run (the first 5 steps left out): median step and broadphase share, and the
  // broadphase share's mean over the whole run.
  double quarter_step_ms[4] = {}, quarter_share_ms[4] = {};
  double mean_share_ms = 0;
};

BulletRun run_bullet(std::unique_ptr<btBroadphaseInterface> inner, int bodies, int steps) {
  btDefaultCollisionConfiguration configuration;
  btCollisionDispatcher dispatcher(&configuration);
  TimedBroadphase broadphase(std::move(inner));
  btSequentialImpulseConstraintSolver solver;
  btDiscreteDynamicsWorld world(&dispatcher, &broadphase, &solver, &configuration);
  world.setGravity(btVector3(0, -9.81f, 0));
  // A bin whose floor holds the pile about 4 layers deep; boxes of 0.5 m in a jittered grid.
  const int per_side = static_cast<int>(std::ceil(std::sqrt(static_cast<double>(bodies) / 8)));
  const float half = 0.6f * static_cast<float>(per_side);
  std::vector<std::unique_ptr<btCollisionShape>> shapes;
  std::vector<std::unique_ptr<btDefaultMotionState>> motions;
  std::vector<std::unique_ptr<btRigidBody>> rigid;
  const auto add = [&](btCollisionShape* shape, const btVector3& at, float mass) {
    btVector3 inertia(0, 0, 0);
    if (mass > 0) shape->calculateLocalInertia(mass, inertia);
    btTransform t;
    t.setIdentity();
    t.setOrigin(at);
    motions.push_back(std::make_unique<btDefaultMotionState>(t));
    rigid.push_back(std::make_unique<btRigidBody>(
        btRigidBody::btRigidBodyConstructionInfo(mass, motions.back().get(), shape, inertia)));
    world.addRigidBody(rigid.back().get());
  };
  shapes.push_back(std::make_unique<btBoxShape>(btVector3(half + 1, 0.5f, half + 1)));
  add(shapes.back().get(), btVector3(0, -0.5f, 0), 0);
  shapes.push_back(std::make_unique<btBoxShape>(btVector3(0.5f, 10, half + 1)));
  add(shapes.back().get(), btVector3(half + 0.5f, 10, 0), 0);
  add(shapes.back().get(), btVector3(-half - 0.5f, 10, 0), 0);
  shapes.push_back(std::make_unique<btBoxShape>(btVector3(half + 1, 10, 0.5f)));
  add(shapes.back().get(), btVector3(0, 10, half + 0.5f), 0);
  add(shapes.back().get(), btVector3(0, 10, -half - 0.5f), 0);
  shapes.push_back(std::make_unique<btBoxShape>(btVector3(0.25f, 0.25f, 0.25f)));
  btCollisionShape* box = shapes.back().get();
  std::mt19937 rng(1);
  std::uniform_real_distribution<float> jitter(-0.05f, 0.05f);
  for (int k = 0; k < bodies; ++k) {
    const int i = k % per_side, j = (k / per_side) % per_side, layer = k / (per_side * per_side);
    add(box,
        btVector3(-half + 0.6f + 1.2f * static_cast<float>(i) + jitter(rng), 1 + 0.8f * static_cast<float>(layer),
                  -half + 0.6f + 1.2f * static_cast<float>(j) + jitter(rng)),
        1);
  }
  std::vector<double> step_ms;
  for (int s = 0; s < steps; ++s) {
    const auto start = Clock::now();
    world.stepSimulation(1.0f / 60, 1, 1.0f / 60);
    step_ms.push_back(ms_since(start));
  }
  BulletRun r;
  // The first steps (proxies created, first pairs) are left out of the medians.
  const auto tail = [&](const std::vector<double>& v) {
    return median(std::vector<double>(v.begin() + std::min<std::ptrdiff_t>(5, std::ssize(v)), v.end()));
  };
  r.pairs_ms = tail(broadphase.pairs_ms);
  r.share_ms = tail(broadphase.share_ms);
  r.step_ms = tail(step_ms);
  const std::size_t first = std::min<std::size_t>(5, step_ms.size()), n = step_ms.size() - first;
  for (int q = 0; q < 4; ++q) {
    const std::size_t b = first + n * static_cast<std::size_t>(q) / 4,
                      e = first + n * static_cast<std::size_t>(q + 1) / 4;
    r.quarter_step_ms[q] = median(std::vector<double>(step_ms.begin() + static_cast<std::ptrdiff_t>(b),
                                                      step_ms.begin() + static_cast<std::ptrdiff_t>(e)));
    if (broadphase.share_ms.size() >= e)
      r.quarter_share_ms[q] = median(std::vector<double>(broadphase.share_ms.begin() + static_cast<std::ptrdiff_t>(b),
                                                         broadphase.share_ms.begin() + static_cast<std::ptrdiff_t>(e)));
  }
  for (std::size_t k = first; k < broadphase.share_ms.size(); ++k) r.mean_share_ms += broadphase.share_ms[k];
  if (broadphase.share_ms.size() > first) r.mean_share_ms /= static_cast<double>(broadphase.share_ms.size() - first);
  r.cache_pairs = broadphase.getOverlappingPairCache()->getNumOverlappingPairs();
  for (std::size_t b = 5; b < rigid.size(); ++b) r.mean_height += rigid[b]->getCenterOfMassPosition().y();
  r.mean_height /= static_cast<double>(bodies);
  for (auto& body : rigid) world.removeRigidBody(body.get());
  return r;
}

void bench_bullet(int bodies, int steps) {
  std::printf("bullet: %d falling boxes, %d steps at 60 Hz, medians after the first 5 steps (ms)\n", bodies, steps);
  std::printf("%-22s %12s %18s %10s %12s %12s\n", "broadphase", "pairs_ms", "aabbs+pairs_ms", "step_ms", "cache_pairs",
              "mean_height");
  const float extent = 1000;
  const std::vector<std::pair<std::string, std::function<std::unique_ptr<btBroadphaseInterface>()>>> kinds = {
      {"viscd::BulletBroadphase", [] { return std::make_unique<viscd::BulletBroadphase>(); }},
      {"viscd, rebuilding",
       [] {
         viscd::Config c;
         c.follow_change = false;
         return std::make_unique<viscd::BulletBroadphase>(c);
       }},
      {"btDbvtBroadphase", [] { return std::make_unique<btDbvtBroadphase>(); }},
      {"bt32BitAxisSweep3",
       [&] {
         return std::make_unique<bt32BitAxisSweep3>(btVector3(-extent, -extent, -extent),
                                                    btVector3(extent, extent, extent),
                                                    static_cast<unsigned>(bodies + 16));
       }},
  };
  std::vector<std::pair<std::string, BulletRun>> runs;
  for (const auto& [name, make] : kinds) {
    const BulletRun r = run_bullet(make(), bodies, steps);
    std::printf("%-22s %12.3f %18.3f %10.3f %12d %12.3f\n", name.c_str(), r.pairs_ms, r.share_ms, r.step_ms,
                r.cache_pairs, r.mean_height);
    std::fflush(stdout);
    runs.emplace_back(name, r);
  }
  std::printf("\nper quarter of the run: median step ms | median aabbs+pairs ms; mean aabbs+pairs ms over the run\n");
  std::printf("%-22s %9s %9s %9s %9s | %9s %9s %9s %9s | %9s\n", "broadphase", "step Q1", "Q2", "Q3", "Q4", "bp Q1",
              "Q2", "Q3", "Q4", "bp mean");
  for (const auto& [name, r] : runs)
    std::printf("%-22s %9.3f %9.3f %9.3f %9.3f | %9.3f %9.3f %9.3f %9.3f | %9.3f\n", name.c_str(), r.quarter_step_ms[0],
                r.quarter_step_ms[1], r.quarter_step_ms[2], r.quarter_step_ms[3], r.quarter_share_ms[0],
                r.quarter_share_ms[1], r.quarter_share_ms[2], r.quarter_share_ms[3], r.mean_share_ms);
}

bool count_pair(fcl::CollisionObjectd*, fcl::CollisionObjectd*, void* data) {
  ++*static_cast<std::size_t*>(data);
  return false;
}

void bench_fcl(int boxes, int reps) {
  // Boxes of 0.5 to 1.5 m, spread so that each overlaps about one other on average.
  std::mt19937 rng(2);
  const double side = std::cbrt(static_cast<double>(boxes) * 4.0);
  std::uniform_real_distribution<double> at(0, side), size(0.5, 1.5), step(-0.2, 0.2);
  std::vector<std::unique_ptr<fcl::CollisionObjectd>> objects;
  for (int k = 0; k < boxes; ++k) {
    fcl::Transform3d t = fcl::Transform3d::Identity();
    t.translation() = fcl::Vector3d(at(rng), at(rng), at(rng));
    objects.push_back(
        std::make_unique<fcl::CollisionObjectd>(std::make_shared<fcl::Boxd>(size(rng), size(rng), size(rng)), t));
    objects.back()->computeAABB();
  }
  std::vector<fcl::CollisionObjectd*> pointers;
  for (auto& o : objects) pointers.push_back(o.get());
  std::printf("fcl: self collision of %d boxes, counting callback, medians of %d runs (ms)\n", boxes, reps);
  // Pairs: after setup, every manager's callback count is exact or above (viscd: float boxes
  // rounded outward); after update, DynamicAABBTree keeps a leaf's old box while it contains the
  // new one, so it may count more.
  std::printf("%-38s %14s %16s %16s %12s %14s\n", "manager", "setup+collide", "update+collide", "1%named+collide",
              "setup_pairs", "pairs_last");
  const std::vector<std::pair<std::string, std::function<std::unique_ptr<fcl::BroadPhaseCollisionManagerd>()>>> kinds =
      {
          {"viscd::FclBroadphaseManager", [] { return std::make_unique<viscd::FclBroadphaseManager>(); }},
          {"fcl::DynamicAABBTreeCollisionManager",
           [] { return std::make_unique<fcl::DynamicAABBTreeCollisionManagerd>(); }},
      };
  std::vector<fcl::Transform3d> initial;
  for (auto& o : objects) initial.push_back(o->getTransform());
  for (const auto& [name, make] : kinds) {
    // Every manager sees the same boxes and the same moves.
    for (std::size_t k = 0; k < objects.size(); ++k) {
      objects[k]->setTransform(initial[k]);
      objects[k]->computeAABB();
    }
    std::mt19937 moves(3);
    std::vector<double> first, second, few;
    std::size_t pairs = 0, setup_pairs = 0;
    for (int r = 0; r < reps; ++r) {
      auto manager = make();
      auto start = Clock::now();
      manager->registerObjects(pointers);
      manager->setup();
      pairs = 0;
      manager->collide(&pairs, count_pair);
      first.push_back(ms_since(start));
      setup_pairs = pairs;
      for (auto& o : objects) {  // every box moves a little
        fcl::Transform3d t = o->getTransform();
        t.translation() += fcl::Vector3d(step(moves), step(moves), step(moves));
        o->setTransform(t);
        o->computeAABB();
      }
      start = Clock::now();
      manager->update();
      pairs = 0;
      manager->collide(&pairs, count_pair);
      second.push_back(ms_since(start));
      // Then frames where 1 % of the boxes move and update(vector) names them.
      for (int f = 0; f < 10; ++f) {
        std::vector<fcl::CollisionObjectd*> named;
        for (std::size_t k = 0; k < objects.size(); k += 100) {
          auto& o = objects[(k + static_cast<std::size_t>(f) * 37) % objects.size()];
          fcl::Transform3d t = o->getTransform();
          t.translation() += fcl::Vector3d(step(moves), step(moves), step(moves));
          o->setTransform(t);
          o->computeAABB();
          named.push_back(o.get());
        }
        start = Clock::now();
        manager->update(named);
        pairs = 0;
        manager->collide(&pairs, count_pair);
        few.push_back(ms_since(start));
      }
    }
    std::printf("%-38s %14.1f %16.1f %16.2f %12zu %14zu\n", name.c_str(), median(first), median(second), median(few),
                setup_pairs, pairs);
    std::fflush(stdout);
  }
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"viscd's Bullet and FCL adapters against the engines' own broadphases"};
  std::string only;
  int bodies = 10000, steps = 120, fcl_boxes = 100000, reps = 3;
  app.add_option("--only", only, "run one part: bullet or fcl")->check(CLI::IsMember({"bullet", "fcl"}));
  app.add_option("--bodies", bodies, "falling boxes in the Bullet world")->check(CLI::Range(1, 10000000));
  app.add_option("--steps", steps, "Bullet steps (60 Hz)")->check(CLI::Range(6, 100000));
  app.add_option("--fcl-boxes", fcl_boxes, "boxes in the FCL self collision")->check(CLI::Range(2, 100000000));
  app.add_option("--reps", reps, "FCL runs per manager")->check(CLI::Range(1, 1000));
  CLI11_PARSE(app, argc, argv);
  if (only.empty() || only == "bullet") bench_bullet(bodies, steps);
  if (only.empty() || only == "fcl") bench_fcl(fcl_boxes, reps);
  return 0;
}
