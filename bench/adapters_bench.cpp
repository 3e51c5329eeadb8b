// The adapters measured against the engines' own broadphases (docs/adapters.md, "Measurements"):
//   bullet: a btDiscreteDynamicsWorld of --bodies falling boxes in a walled bin, stepped on
//           viscd::BulletBroadphase, btDbvtBroadphase and bt32BitAxisSweep3, the worlds stepped
//           in turn (one step each) so that the machine's load falls on all alike; per step,
//           the broadphase's share (from the first setAabb of the step's updateAabbs to the end
//           of calculateOverlappingPairs), its own time (inside its setAabb calls and
//           calculateOverlappingPairs) and the whole step; medians over the steps. The worlds
//           drift apart (each broadphase hands Bullet its pairs in its own order), so the steps'
//           physics differ too, by the pile's state. With --pillars every other body is a sphere
//           and static pillars stand in the bin; with --settling, that world on a floor twice as
//           wide, where the bodies come to rest apart and Bullet puts them to sleep. Also per
//           quarter: the boxes whose AABB changed a step, and for viscd the steps that followed
//           change and the boxes placed again. With --replay R the world is stepped once on
//           btDbvtBroadphase with its broadphase calls recorded, and the calls are played through
//           each broadphase R times (the same input for all, no solver in between).
//   fcl:    self collision of --fcl-boxes random boxes with a counting callback (no narrowphase)
//           on viscd::FclBroadphaseManager and fcl::DynamicAABBTreeCollisionManager: setup +
//           collide, then update + collide after every box moved, then 10 frames in which 1 % of
//           the boxes move and update(vector) names them; medians over --reps (x 10 for the last).
//   queries: --query-bodies boxes resting on a landscape (a height field of hills), each step 1 %
//           of them moved (setAabb) and calculateOverlappingPairs, then --rays rays cast down
//           through the broadphase's rayTest and as many aabbTest boxes, on viscd::BulletBroadphase
//           and btDbvtBroadphase, interleaved step by step on the same moves and queries; medians
//           over --query-steps of the microseconds per ray and per box, and the hits found.
// Not a test: timings depend on the machine. Run: viscd_adapters_bench [--only bullet|fcl] ...
#include <btBulletDynamicsCommon.h>
#include <fcl/broadphase/broadphase_dynamic_AABB_tree.h>
#include <fcl/geometry/shape/box.h>
#include <CLI/CLI.hpp>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <functional>
#include <memory>
#include <random>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include "viscd/bullet.hpp"
#include "viscd/fcl.hpp"

#if defined(__x86_64__) || defined(__i386__)
#include <x86intrin.h>
#endif

namespace {

using Clock = std::chrono::steady_clock;
double ms_since(Clock::time_point t) { return std::chrono::duration<double, std::milli>(Clock::now() - t).count(); }

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

// The median of v over steps [b, e), or 0 when v does not reach e.
double span_median(const std::vector<double>& v, std::size_t b, std::size_t e) {
  if (v.size() < e) return 0.0;
  return median(
      std::vector<double>(v.begin() + static_cast<std::ptrdiff_t>(b), v.begin() + static_cast<std::ptrdiff_t>(e)));
}

// Steps [b, e) of quarter q of the n steps after the first `first`.
std::pair<std::size_t, std::size_t> quarter(std::size_t first, std::size_t n, int q) {
  return {first + n * static_cast<std::size_t>(q) / 4, first + n * static_cast<std::size_t>(q + 1) / 4};
}

// A cheap clock for timing the many short setAabb calls of a step: the time stamp counter where
// there is one, converted to ms by a calibration against steady_clock, less what reading it twice
// costs (measured once).
class CallClock {
 public:
  CallClock() {
    const auto t0 = Clock::now();
    const std::uint64_t c0 = ticks();
    while (ms_since(t0) < 20) {
    }
    const double ms = ms_since(t0);
    ms_per_tick_ = ms / static_cast<double>(std::max<std::uint64_t>(1, ticks() - c0));
    std::vector<double> pair;
    for (int r = 0; r < 101; ++r) {
      std::uint64_t sum = 0;
      for (int k = 0; k < 1000; ++k) {
        const std::uint64_t a = ticks();
        sum += ticks() - a;
      }
      pair.push_back(static_cast<double>(sum) / 1000);
    }
    overhead_ = median(pair);
    pair.clear();
    for (int r = 0; r < 101; ++r) {
      std::uint64_t sum = 0;
      for (int k = 0; k < 1000; ++k) {
        fence();
        const std::uint64_t a = ticks();
        sum += ticks() - a;
      }
      pair.push_back(static_cast<double>(sum) / 1000);
    }
    fenced_overhead_ = median(pair);
  }
  /// Waits until the loads before it have arrived (so that a span started after it does not pay
  /// for them).
  static void fence() {
#if defined(__x86_64__) || defined(__i386__)
    _mm_lfence();
#endif
  }
  static std::uint64_t ticks() {
#if defined(__x86_64__) || defined(__i386__)
    return __rdtsc();
#else
    return static_cast<std::uint64_t>(Clock::now().time_since_epoch().count());
#endif
  }
  /// A timed span of `calls` calls, `sum` ticks in all, in ms.
  [[nodiscard]] double ms(std::uint64_t sum, std::uint64_t calls) const {
    return std::max(0.0, static_cast<double>(sum) - overhead_ * static_cast<double>(calls)) * ms_per_tick_;
  }
  /// The same for spans each started after fence().
  [[nodiscard]] double fenced_ms(std::uint64_t sum, std::uint64_t calls) const {
    return std::max(0.0, static_cast<double>(sum) - fenced_overhead_ * static_cast<double>(calls)) * ms_per_tick_;
  }

 private:
  double ms_per_tick_ = 0, overhead_ = 0, fenced_overhead_ = 0;
};

const CallClock& call_clock() {
  static const CallClock c;
  return c;
}

// Forwards everything to the broadphase it wraps and times each step's broadphase share, and its
// own time: the time spent inside its setAabb calls and calculateOverlappingPairs (not Bullet's
// AABB computation between the setAabb calls).
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
      changed.push_back(0);
      set_ticks_ = set_calls_ = 0;
    }
    // Whether the box changed (proxies the world keeps awake change; sleeping ones do not).
    changed.back() += !(p->m_aabbMin == lo && p->m_aabbMax == hi);
    const std::uint64_t t = CallClock::ticks();
    inner_->setAabb(p, lo, hi, d);
    set_ticks_ += CallClock::ticks() - t;
    ++set_calls_;
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
    own_ms.push_back(pairs_ms.back() + (in_step_ ? call_clock().ms(set_ticks_, set_calls_) : 0));
    in_step_ = false;
    // viscd's: whether the frame followed change, and how many boxes it placed again.
    if (const auto* v = dynamic_cast<const viscd::BulletBroadphase*>(inner_.get())) {
      followed.push_back(v->last_stats().followed_change ? 1 : 0);
      stage_ms.push_back(v->last_stats().stage_ms);
      replaced.push_back(v->last_stats().followed_change ? v->last_stats().replaced : v->last_stats().objects);
    }
  }
  btOverlappingPairCache* getOverlappingPairCache() override { return inner_->getOverlappingPairCache(); }
  const btOverlappingPairCache* getOverlappingPairCache() const override { return inner_->getOverlappingPairCache(); }
  void getBroadphaseAabb(btVector3& lo, btVector3& hi) const override { inner_->getBroadphaseAabb(lo, hi); }
  void resetPool(btDispatcher* d) override { inner_->resetPool(d); }
  void printStats() override { inner_->printStats(); }

  std::vector<double> pairs_ms, share_ms;  // calculateOverlappingPairs; updateAabbs + it
  std::vector<double> own_ms;              // calculateOverlappingPairs + the step's setAabb calls
  std::vector<int> changed;                // per step: setAabb calls that changed a box
  std::vector<int> followed;               // viscd's: per step, 1 when the frame followed change
  std::vector<std::uint32_t> replaced;     // viscd's: boxes placed again (all of them in a rebuild)
  std::vector<std::array<double, viscd::kStageCount>> stage_ms;  // viscd's: its frame's stage times

 private:
  std::unique_ptr<btBroadphaseInterface> inner_;
  bool in_step_ = false;
  Clock::time_point step_start_;
  std::uint64_t set_ticks_ = 0, set_calls_ = 0;  // this step's setAabb calls: ticks inside, count
};

struct BulletRun {
  double pairs_ms = 0, share_ms = 0, step_ms = 0;
  int cache_pairs = 0;
  double mean_height = 0;
  // Per quarter of the run (the first 5 steps left out): median step and broadphase share, and the
  // broadphase share's mean over the whole run.
  double quarter_step_ms[4] = {}, quarter_share_ms[4] = {};
  double mean_share_ms = 0;
  // The broadphase's own time (setAabb calls + calculateOverlappingPairs): per quarter its median,
  // and its mean over the run.
  double quarter_own_ms[4] = {};
  double mean_own_ms = 0;
  // viscd's: per quarter, the share of steps that followed change and the mean boxes placed again
  // (negative: not viscd).
  double quarter_followed[4] = {-1, -1, -1, -1}, quarter_replaced[4] = {-1, -1, -1, -1};
  double quarter_changed[4] = {};  // per quarter, the mean boxes that changed a step
  // viscd's: over the second half of the run, the mean ms of each stage its frames report, and of
  // calculateOverlappingPairs (the rest is the adapter's and the detector's own work: events, the
  // cache); empty for the others.
  std::vector<double> late_stage_ms;
  double late_pairs_ms = 0;
};

// One Bullet world of `bodies` falling boxes in a walled bin on a broadphase, stepped by the
// caller (so that the worlds of several broadphases step in turn, under the same load).
class BulletWorld {
 public:
  /// `pillars`: every other body a sphere, and static pillars standing in the bin. `settling`
  /// (with pillars): a floor twice as wide, so that the fallen bodies cover about a third of it
  /// in small islands, friction 0.6 and rolling friction on the spheres, so that they stop
  /// rolling: a world whose bodies Bullet puts to sleep.
  BulletWorld(std::unique_ptr<btBroadphaseInterface> inner, int bodies, bool pillars, bool settling)
      : dispatcher_(&configuration_),
        broadphase_(std::move(inner)),
        world_(&dispatcher_, &broadphase_, &solver_, &configuration_),
        bodies_(bodies) {
    world_.setGravity(btVector3(0, -9.81f, 0));
    // A bin whose floor holds the pile about 4 layers deep; boxes of 0.5 m in a jittered grid.
    const int per_side = static_cast<int>(std::ceil(std::sqrt(static_cast<double>(bodies) / 8)));
    const float half = (settling ? 1.2f : 0.6f) * static_cast<float>(per_side);
    const float cell = settling ? 2.4f : 1.2f;  // the grid's spacing in x and z
    shapes_.push_back(std::make_unique<btBoxShape>(btVector3(half + 1, 0.5f, half + 1)));
    add(shapes_.back().get(), btVector3(0, -0.5f, 0), 0);
    shapes_.push_back(std::make_unique<btBoxShape>(btVector3(0.5f, 10, half + 1)));
    add(shapes_.back().get(), btVector3(half + 0.5f, 10, 0), 0);
    add(shapes_.back().get(), btVector3(-half - 0.5f, 10, 0), 0);
    shapes_.push_back(std::make_unique<btBoxShape>(btVector3(half + 1, 10, 0.5f)));
    add(shapes_.back().get(), btVector3(0, 10, half + 0.5f), 0);
    add(shapes_.back().get(), btVector3(0, 10, -half - 0.5f), 0);
    if (pillars) {
      // A pillar 0.4 m thick and 3 m tall every other grid line, between the grid's columns.
      shapes_.push_back(std::make_unique<btBoxShape>(btVector3(0.2f, 1.5f, 0.2f)));
      for (float x = -half + cell; x < half; x += 2 * cell)
        for (float z = -half + cell; z < half; z += 2 * cell) add(shapes_.back().get(), btVector3(x, 1.5f, z), 0);
    }
    shapes_.push_back(std::make_unique<btBoxShape>(btVector3(0.25f, 0.25f, 0.25f)));
    btCollisionShape* box = shapes_.back().get();
    shapes_.push_back(std::make_unique<btSphereShape>(0.25f));
    btCollisionShape* ball = shapes_.back().get();
    first_body_ = rigid_.size();
    std::mt19937 rng(1);
    std::uniform_real_distribution<float> jitter(-0.05f, 0.05f);
    for (int k = 0; k < bodies; ++k) {
      const int i = k % per_side, j = (k / per_side) % per_side, layer = k / (per_side * per_side);
      const bool sphere = pillars && k % 2 == 1;
      btRigidBody* b = add(
          sphere ? ball : box,
          btVector3(-half + cell / 2 + cell * static_cast<float>(i) + jitter(rng), 1 + 0.8f * static_cast<float>(layer),
                    -half + cell / 2 + cell * static_cast<float>(j) + jitter(rng)),
          1);
      if (settling) {
        b->setFriction(0.6f);
        if (sphere) b->setRollingFriction(0.05f);
      }
    }
  }
  BulletWorld(const BulletWorld&) = delete;
  BulletWorld& operator=(const BulletWorld&) = delete;
  ~BulletWorld() {
    for (auto& body : rigid_) world_.removeRigidBody(body.get());
  }

  void step() {
    const auto start = Clock::now();
    world_.stepSimulation(1.0f / 60, 1, 1.0f / 60);
    step_ms_.push_back(ms_since(start));
  }

  [[nodiscard]] BulletRun result() const {
    BulletRun r;
    // The first steps (proxies created, first pairs) are left out of the medians.
    const auto tail = [&](const std::vector<double>& v) {
      return median(std::vector<double>(v.begin() + std::min<std::ptrdiff_t>(5, std::ssize(v)), v.end()));
    };
    r.pairs_ms = tail(broadphase_.pairs_ms);
    r.share_ms = tail(broadphase_.share_ms);
    r.step_ms = tail(step_ms_);
    const std::size_t first = std::min<std::size_t>(5, step_ms_.size()), n = step_ms_.size() - first;
    // The mean of v after the first steps.
    const auto run_mean = [&](const std::vector<double>& v) {
      double sum = 0;
      for (std::size_t k = first; k < v.size(); ++k) sum += v[k];
      return v.size() > first ? sum / static_cast<double>(v.size() - first) : 0.0;
    };
    for (int q = 0; q < 4; ++q) {
      const auto [b, e] = quarter(first, n, q);
      r.quarter_step_ms[q] = span_median(step_ms_, b, e);
      r.quarter_share_ms[q] = span_median(broadphase_.share_ms, b, e);
      r.quarter_own_ms[q] = span_median(broadphase_.own_ms, b, e);
      if (broadphase_.changed.size() >= e && e > b) {
        double c = 0;
        for (std::size_t k = b; k < e; ++k) c += broadphase_.changed[k];
        r.quarter_changed[q] = c / static_cast<double>(e - b);
      }
      if (broadphase_.followed.size() >= e && e > b) {
        double f = 0, m = 0;
        for (std::size_t k = b; k < e; ++k) {
          f += broadphase_.followed[k];
          m += broadphase_.replaced[k];
        }
        r.quarter_followed[q] = f / static_cast<double>(e - b);
        r.quarter_replaced[q] = m / static_cast<double>(e - b);
      }
    }
    r.mean_share_ms = run_mean(broadphase_.share_ms);
    r.mean_own_ms = run_mean(broadphase_.own_ms);
    if (!broadphase_.stage_ms.empty() && broadphase_.stage_ms.size() == broadphase_.pairs_ms.size()) {
      const std::size_t from = broadphase_.stage_ms.size() / 2, count = broadphase_.stage_ms.size() - from;
      r.late_stage_ms.assign(viscd::kStageCount, 0);
      for (std::size_t k = from; k < broadphase_.stage_ms.size(); ++k) {
        for (std::size_t g = 0; g < viscd::kStageCount; ++g)
          r.late_stage_ms[g] += broadphase_.stage_ms[k][g] / static_cast<double>(count);
        r.late_pairs_ms += broadphase_.pairs_ms[k] / static_cast<double>(count);
      }
    }
    r.cache_pairs = broadphase_.getOverlappingPairCache()->getNumOverlappingPairs();
    for (std::size_t b = first_body_; b < rigid_.size(); ++b) r.mean_height += rigid_[b]->getCenterOfMassPosition().y();
    r.mean_height /= static_cast<double>(bodies_);
    return r;
  }

 private:
  btRigidBody* add(btCollisionShape* shape, const btVector3& at, float mass) {
    btVector3 inertia(0, 0, 0);
    if (mass > 0) shape->calculateLocalInertia(mass, inertia);
    btTransform t;
    t.setIdentity();
    t.setOrigin(at);
    motions_.push_back(std::make_unique<btDefaultMotionState>(t));
    rigid_.push_back(std::make_unique<btRigidBody>(
        btRigidBody::btRigidBodyConstructionInfo(mass, motions_.back().get(), shape, inertia)));
    world_.addRigidBody(rigid_.back().get());
    return rigid_.back().get();
  }

  btDefaultCollisionConfiguration configuration_;
  btCollisionDispatcher dispatcher_;
  TimedBroadphase broadphase_;
  btSequentialImpulseConstraintSolver solver_;
  btDiscreteDynamicsWorld world_;
  int bodies_;
  std::vector<std::unique_ptr<btCollisionShape>> shapes_;
  std::vector<std::unique_ptr<btDefaultMotionState>> motions_;
  std::vector<std::unique_ptr<btRigidBody>> rigid_;
  std::vector<double> step_ms_;
  std::size_t first_body_ = 0;  // rigid_[first_body_..] are the falling bodies
};

// The broadphase calls of a Bullet world, recorded once and played again through each broadphase
// (--replay): every broadphase sees the same calls, without Bullet's narrowphase and solver in
// between, so their own times compare on equal input in seconds instead of minutes of stepping.
struct CallLog {
  enum Op : std::uint32_t { kCreate = 0, kDestroy = 1, kSet = 2, kStep = 3 };
  struct Call {
    std::uint32_t op_id;  // op in the top 2 bits, proxy id below
    std::uint32_t aabb;   // kCreate, kSet: index in aabbs; kCreate also filter index in filters
  };
  std::vector<Call> calls;
  std::vector<std::array<btScalar, 6>> aabbs;
  std::vector<std::array<int, 3>> creates;  // per kCreate: shape type, group, mask
  std::size_t steps = 0, proxies = 0;

 private:
  static constexpr std::uint64_t kMagic = 0x766973636442756cull ^ sizeof(btScalar);  // "viscdBul", by scalar size
  template <class T>
  static bool write(std::FILE* f, const std::vector<T>& v) {
    return v.empty() || std::fwrite(v.data(), sizeof(T), v.size(), f) == v.size();
  }
  template <class T>
  static bool read(std::FILE* f, std::vector<T>& v) {
    return v.empty() || std::fread(v.data(), sizeof(T), v.size(), f) == v.size();
  }

 public:
  /// Writes the log to `path` / reads it back; false on an I/O error or a file of another layout.
  [[nodiscard]] bool save(const std::string& path) const {
    std::FILE* f = std::fopen(path.c_str(), "wb");
    if (!f) return false;
    const std::uint64_t head[5] = {kMagic, calls.size(), aabbs.size(), creates.size(), steps};
    const bool ok = std::fwrite(head, sizeof head, 1, f) == 1 && write(f, calls) && write(f, aabbs) &&
                    write(f, creates) && std::fwrite(&proxies, sizeof proxies, 1, f) == 1;
    return std::fclose(f) == 0 && ok;
  }
  [[nodiscard]] bool load(const std::string& path) {
    std::FILE* f = std::fopen(path.c_str(), "rb");
    if (!f) return false;
    std::uint64_t head[5] = {};
    bool ok = std::fread(head, sizeof head, 1, f) == 1 && head[0] == kMagic;
    if (ok) {
      calls.resize(head[1]);
      aabbs.resize(head[2]);
      creates.resize(head[3]);
      steps = head[4];
      ok = read(f, calls) && read(f, aabbs) && read(f, creates) && std::fread(&proxies, sizeof proxies, 1, f) == 1;
    }
    std::fclose(f);
    return ok;
  }

  static Call make(Op op, std::uint32_t id, std::uint32_t aabb) { return {(std::uint32_t{op} << 30) | id, aabb}; }
  std::uint32_t add_aabb(const btVector3& lo, const btVector3& hi) {
    aabbs.push_back({lo.x(), lo.y(), lo.z(), hi.x(), hi.y(), hi.z()});
    return static_cast<std::uint32_t>(aabbs.size() - 1);
  }
};

// Forwards to btDbvtBroadphase and writes each call into a CallLog (a setAabb that repeats the
// proxy's last box reuses its entry).
class RecordingBroadphase final : public btBroadphaseInterface {
 public:
  explicit RecordingBroadphase(CallLog& log) : log_(log) {}
  btBroadphaseProxy* createProxy(const btVector3& lo, const btVector3& hi, int type, void* user, int group, int mask,
                                 btDispatcher* d) override {
    btBroadphaseProxy* p = inner_.createProxy(lo, hi, type, user, group, mask, d);
    const auto id = static_cast<std::uint32_t>(log_.proxies++);
    ids_[p] = id;
    last_.resize(log_.proxies);
    last_[id] = log_.add_aabb(lo, hi);
    log_.calls.push_back(CallLog::make(CallLog::kCreate, id, last_[id]));
    log_.creates.push_back({type, group, mask});
    return p;
  }
  void destroyProxy(btBroadphaseProxy* p, btDispatcher* d) override {
    log_.calls.push_back(CallLog::make(CallLog::kDestroy, ids_.at(p), 0));
    ids_.erase(p);
    inner_.destroyProxy(p, d);
  }
  void setAabb(btBroadphaseProxy* p, const btVector3& lo, const btVector3& hi, btDispatcher* d) override {
    const std::uint32_t id = ids_.at(p);
    const auto& a = log_.aabbs[last_[id]];
    if (!(a[0] == lo.x() && a[1] == lo.y() && a[2] == lo.z() && a[3] == hi.x() && a[4] == hi.y() && a[5] == hi.z()))
      last_[id] = log_.add_aabb(lo, hi);
    log_.calls.push_back(CallLog::make(CallLog::kSet, id, last_[id]));
    inner_.setAabb(p, lo, hi, d);
  }
  void getAabb(btBroadphaseProxy* p, btVector3& lo, btVector3& hi) const override { inner_.getAabb(p, lo, hi); }
  void rayTest(const btVector3& from, const btVector3& to, btBroadphaseRayCallback& cb, const btVector3& lo,
               const btVector3& hi) override {
    inner_.rayTest(from, to, cb, lo, hi);
  }
  void aabbTest(const btVector3& lo, const btVector3& hi, btBroadphaseAabbCallback& cb) override {
    inner_.aabbTest(lo, hi, cb);
  }
  void calculateOverlappingPairs(btDispatcher* d) override {
    log_.calls.push_back(CallLog::make(CallLog::kStep, 0, 0));
    ++log_.steps;
    inner_.calculateOverlappingPairs(d);
  }
  btOverlappingPairCache* getOverlappingPairCache() override { return inner_.getOverlappingPairCache(); }
  const btOverlappingPairCache* getOverlappingPairCache() const override { return inner_.getOverlappingPairCache(); }
  void getBroadphaseAabb(btVector3& lo, btVector3& hi) const override { inner_.getBroadphaseAabb(lo, hi); }
  void resetPool(btDispatcher* d) override { inner_.resetPool(d); }
  void printStats() override { inner_.printStats(); }

 private:
  CallLog& log_;
  btDbvtBroadphase inner_;
  std::unordered_map<const btBroadphaseProxy*, std::uint32_t> ids_;
  std::vector<std::uint32_t> last_;  // per proxy id, its last box in log_.aabbs
};

// One broadphase playing a CallLog back one step at a time, timing its own time per step (the
// setAabb calls and calculateOverlappingPairs).
class Player {
 public:
  Player(std::unique_ptr<btBroadphaseInterface> bp, const CallLog& log)
      : dispatcher_(&configuration_), bp_(std::move(bp)), log_(log), proxies_(log.proxies, nullptr) {}
  Player(const Player&) = delete;
  Player& operator=(const Player&) = delete;
  ~Player() {
    for (btBroadphaseProxy* p : proxies_)
      if (p) bp_->destroyProxy(p, &dispatcher_);
  }
  /// Plays the calls up to and including the next step's calculateOverlappingPairs; false at the end.
  bool step() {
    std::uint64_t set_ticks = 0, set_calls = 0;
    while (at_ < log_.calls.size()) {
      const CallLog::Call c = log_.calls[at_++];
      const std::uint32_t op = c.op_id >> 30, id = c.op_id & 0x3FFFFFFFu;
      if (op == CallLog::kStep) {
        const auto start = Clock::now();
        bp_->calculateOverlappingPairs(&dispatcher_);
        pairs_ms.push_back(ms_since(start));
        own_ms.push_back(pairs_ms.back() + call_clock().fenced_ms(set_ticks, set_calls));
        if (const auto* v = dynamic_cast<const viscd::BulletBroadphase*>(bp_.get())) {
          stage_ms.push_back(v->last_stats().stage_ms);
          moved.push_back(v->last_stats().followed_change ? v->last_stats().moved : v->last_stats().objects);
          replaced.push_back(v->last_stats().followed_change ? v->last_stats().replaced : v->last_stats().objects);
        }
        return true;
      }
      if (op == CallLog::kDestroy) {
        bp_->destroyProxy(proxies_[id], &dispatcher_);
        proxies_[id] = nullptr;
        continue;
      }
      const auto& a = log_.aabbs[c.aabb];
      const btVector3 lo(a[0], a[1], a[2]), hi(a[3], a[4], a[5]);
      if (op == CallLog::kCreate) {
        const auto& k = log_.creates[created_++];
        proxies_[id] = bp_->createProxy(lo, hi, k[0], nullptr, k[1], k[2], &dispatcher_);
        continue;
      }
      // The log's boxes are read ahead, and the clock starts only once this one has arrived (the
      // world computes each AABB right before its call: a miss on the log is not the broadphase's).
      if (at_ + 16 < log_.calls.size()) __builtin_prefetch(&log_.aabbs[log_.calls[at_ + 16].aabb]);
      CallClock::fence();
      const std::uint64_t t = CallClock::ticks();
      bp_->setAabb(proxies_[id], lo, hi, &dispatcher_);
      set_ticks += CallClock::ticks() - t;
      ++set_calls;
    }
    return false;
  }
  [[nodiscard]] int cache_pairs() const { return bp_->getOverlappingPairCache()->getNumOverlappingPairs(); }
  std::vector<double> pairs_ms, own_ms;
  // viscd's, per step: its frame's stage times, the boxes that changed and those placed again.
  std::vector<std::array<double, viscd::kStageCount>> stage_ms;
  std::vector<double> moved, replaced;

 private:
  btDefaultCollisionConfiguration configuration_;
  btCollisionDispatcher dispatcher_;
  std::unique_ptr<btBroadphaseInterface> bp_;
  const CallLog& log_;
  std::vector<btBroadphaseProxy*> proxies_;
  std::size_t at_ = 0, created_ = 0;
};

// Each broadphase of the Bullet part: the key --broadphases picks it by, its name, how to make one.
struct Kind {
  std::string key, name;
  std::function<std::unique_ptr<btBroadphaseInterface>()> make;
};

std::vector<Kind> bullet_kinds(int bodies, const std::vector<std::string>& pick) {
  const float extent = 1000;
  std::vector<Kind> kinds = {
      {"viscd", "viscd::BulletBroadphase", [] { return std::make_unique<viscd::BulletBroadphase>(); }},
      {"rebuilding", "viscd, rebuilding",
       [] {
         viscd::Config c = viscd::BulletBroadphase::default_config();
         c.follow_change = false;
         return std::make_unique<viscd::BulletBroadphase>(c);
       }},
      {"one-thread", "viscd, one thread",
       [] {
         viscd::Config c = viscd::BulletBroadphase::default_config();
         c.threads = 1;
         return std::make_unique<viscd::BulletBroadphase>(c);
       }},
      {"margin0", "viscd, rest margin 0",
       [] {
         viscd::Config c = viscd::BulletBroadphase::default_config();
         c.rest_margin = 0;
         return std::make_unique<viscd::BulletBroadphase>(c);
       }},
      {"move0", "viscd, move margin 0",
       [] {
         viscd::Config c = viscd::BulletBroadphase::default_config();
         c.move_margin = 0;
         return std::make_unique<viscd::BulletBroadphase>(c);
       }},
      {"dbvt", "btDbvtBroadphase", [] { return std::make_unique<btDbvtBroadphase>(); }},
      {"sweep", "bt32BitAxisSweep3",
       [=] {
         return std::make_unique<bt32BitAxisSweep3>(btVector3(-extent, -extent, -extent),
                                                    btVector3(extent, extent, extent),
                                                    static_cast<unsigned>(bodies + 1024));
       }},
  };
  if (!pick.empty())
    std::erase_if(kinds, [&](const Kind& k) { return std::find(pick.begin(), pick.end(), k.key) == pick.end(); });
  return kinds;
}

void bench_bullet(int bodies, int steps, bool pillars, bool settling, const std::vector<std::string>& pick) {
  std::printf("bullet: %d falling %s%s, %d steps at 60 Hz, the worlds stepped in turn (one step each, same load),\n",
              bodies, pillars ? "boxes and spheres among static pillars" : "boxes",
              settling ? " on a floor twice as wide (a world that settles)" : "", steps);
  std::printf("medians after the first 5 steps (ms)\n");
  std::printf("%-22s %12s %18s %10s %12s %12s\n", "broadphase", "pairs_ms", "aabbs+pairs_ms", "step_ms", "cache_pairs",
              "mean_height");
  std::vector<Kind> kinds = bullet_kinds(bodies, pick);
  std::vector<std::unique_ptr<BulletWorld>> worlds;
  for (const Kind& k : kinds) worlds.push_back(std::make_unique<BulletWorld>(k.make(), bodies, pillars, settling));
  for (int s = 0; s < steps; ++s) {
    for (auto& w : worlds) w->step();
    if ((s + 1) % 100 == 0 || s + 1 == steps) std::fprintf(stderr, "step %d/%d\n", s + 1, steps);
  }
  std::vector<std::pair<std::string, BulletRun>> runs;
  for (std::size_t k = 0; k < kinds.size(); ++k) {
    const BulletRun r = worlds[k]->result();
    std::printf("%-22s %12.3f %18.3f %10.3f %12d %12.3f\n", kinds[k].name.c_str(), r.pairs_ms, r.share_ms, r.step_ms,
                r.cache_pairs, r.mean_height);
    runs.emplace_back(kinds[k].name, r);
  }
  worlds.clear();
  std::printf("\nper quarter of the run: median step ms | median aabbs+pairs ms; mean aabbs+pairs ms over the run\n");
  std::printf("%-22s %9s %9s %9s %9s | %9s %9s %9s %9s | %9s\n", "broadphase", "step Q1", "Q2", "Q3", "Q4", "bp Q1",
              "Q2", "Q3", "Q4", "bp mean");
  for (const auto& [name, r] : runs)
    std::printf("%-22s %9.3f %9.3f %9.3f %9.3f | %9.3f %9.3f %9.3f %9.3f | %9.3f\n", name.c_str(), r.quarter_step_ms[0],
                r.quarter_step_ms[1], r.quarter_step_ms[2], r.quarter_step_ms[3], r.quarter_share_ms[0],
                r.quarter_share_ms[1], r.quarter_share_ms[2], r.quarter_share_ms[3], r.mean_share_ms);
  std::printf(
      "\nthe broadphase's own time (setAabb calls + calculateOverlappingPairs, not Bullet's AABB computation):\n"
      "median ms per quarter; mean ms over the run\n");
  std::printf("%-22s %9s %9s %9s %9s | %9s\n", "broadphase", "own Q1", "Q2", "Q3", "Q4", "own mean");
  for (const auto& [name, r] : runs)
    std::printf("%-22s %9.3f %9.3f %9.3f %9.3f | %9.3f\n", name.c_str(), r.quarter_own_ms[0], r.quarter_own_ms[1],
                r.quarter_own_ms[2], r.quarter_own_ms[3], r.mean_own_ms);
  std::printf("\nboxes whose AABB changed, mean a step per quarter (the world keeps some awake)\n");
  for (const auto& [name, r] : runs)
    std::printf("%-22s %9.1f %9.1f %9.1f %9.1f\n", name.c_str(), r.quarter_changed[0], r.quarter_changed[1],
                r.quarter_changed[2], r.quarter_changed[3]);
  std::printf(
      "\nviscd over the second half of the run: mean ms of calculateOverlappingPairs and of the stages its\n"
      "frames report (the rest: events, the pair cache, the detector's own passes)\n");
  std::printf("%-22s %9s", "broadphase", "pairs");
  for (std::size_t g = 0; g < viscd::kStageCount; ++g)
    if (g != static_cast<std::size_t>(viscd::Stage::shade))
      std::printf(" %9.9s", std::string(viscd::stage_name(static_cast<viscd::Stage>(g))).c_str());
  std::printf(" %9s\n", "rest");
  for (const auto& [name, r] : runs) {
    if (r.late_stage_ms.empty()) continue;
    std::printf("%-22s %9.3f", name.c_str(), r.late_pairs_ms);
    double sum = 0;
    for (std::size_t g = 0; g < viscd::kStageCount; ++g) {
      sum += r.late_stage_ms[g];
      if (g != static_cast<std::size_t>(viscd::Stage::shade)) std::printf(" %9.3f", r.late_stage_ms[g]);
    }
    std::printf(" %9.3f\n", r.late_pairs_ms - sum);
  }
  std::printf("\nviscd per quarter: steps that followed change (%%) | mean boxes placed again a step\n");
  for (const auto& [name, r] : runs) {
    if (r.quarter_followed[0] < 0) continue;
    std::printf("%-22s %9.1f %9.1f %9.1f %9.1f | %9.1f %9.1f %9.1f %9.1f\n", name.c_str(), 100 * r.quarter_followed[0],
                100 * r.quarter_followed[1], 100 * r.quarter_followed[2], 100 * r.quarter_followed[3],
                r.quarter_replaced[0], r.quarter_replaced[1], r.quarter_replaced[2], r.quarter_replaced[3]);
  }
}

// --replay: the world stepped once on btDbvtBroadphase with its broadphase calls recorded, then
// the calls played through each picked broadphase, `rounds` times, the players stepped in turn.
// Per round and player: the mean own time over the run (the first 5 steps left out), its median
// per quarter, and the mean of calculateOverlappingPairs over the second half; then the medians
// over the rounds and each round's ratio to btDbvt's.
void bench_bullet_replay(int bodies, int steps, bool pillars, bool settling, int rounds,
                         const std::vector<std::string>& pick, const std::string& log_path) {
  CallLog log;
  if (!log_path.empty() && log.load(log_path)) {
    std::printf("bullet replay: %zu steps read from %s: %zu calls, %zu boxes\n", log.steps, log_path.c_str(),
                log.calls.size(), log.aabbs.size());
  } else {
    const auto start = Clock::now();
    {
      BulletWorld world(std::make_unique<RecordingBroadphase>(log), bodies, pillars, settling);
      for (int s = 0; s < steps; ++s) {
        world.step();
        if ((s + 1) % 100 == 0 || s + 1 == steps) std::fprintf(stderr, "recording: step %d/%d\n", s + 1, steps);
      }
    }
    std::printf("bullet replay: %d bodies%s%s, %d steps recorded on btDbvtBroadphase in %.1f s: %zu calls, %zu boxes\n",
                bodies, pillars ? ", pillars" : "", settling ? ", settling" : "", steps, ms_since(start) / 1000,
                log.calls.size(), log.aabbs.size());
    // The world's destruction is not played: the calls end with the last step.
    while (!log.calls.empty() && (log.calls.back().op_id >> 30) != CallLog::kStep) log.calls.pop_back();
    if (!log_path.empty() && !log.save(log_path)) std::fprintf(stderr, "could not write %s\n", log_path.c_str());
  }
  // Sized for the log's proxies (a log read from a file may come from a larger world).
  const std::vector<Kind> kinds = bullet_kinds(std::max(bodies, static_cast<int>(log.proxies)), pick);
  const std::size_t first = 5;
  struct Summary {
    std::vector<double> mean_own, mean_set, late_pairs, q[4];
  };
  std::vector<Summary> sums(kinds.size());
  std::printf("%-5s %-22s %9s %9s %9s %9s | %9s %9s | %9s %10s\n", "round", "broadphase", "own Q1", "Q2", "Q3", "Q4",
              "own mean", "setAabb", "late pairs", "cache");
  for (int r = 0; r < rounds; ++r) {
    std::vector<std::unique_ptr<Player>> players;
    for (const Kind& k : kinds) players.push_back(std::make_unique<Player>(k.make(), log));
    for (bool more = true; more;)
      for (auto& p : players) more = p->step() && more;
    for (std::size_t k = 0; k < kinds.size(); ++k) {
      const Player& p = *players[k];
      const std::size_t n = p.own_ms.size();
      double sum = 0, set = 0;
      for (std::size_t s = first; s < n; ++s) {
        sum += p.own_ms[s];
        set += p.own_ms[s] - p.pairs_ms[s];
      }
      double late = 0;
      for (std::size_t s = n / 2; s < n; ++s) late += p.pairs_ms[s];
      Summary& m = sums[k];
      m.mean_own.push_back(sum / static_cast<double>(n - first));
      m.mean_set.push_back(set / static_cast<double>(n - first));
      m.late_pairs.push_back(late / static_cast<double>(n - n / 2));
      std::printf("%-5d %-22s", r, kinds[k].name.c_str());
      for (int q = 0; q < 4; ++q) {
        const auto [b, e] = quarter(first, n - first, q);
        m.q[q].push_back(span_median(p.own_ms, b, e));
        std::printf(" %9.3f", m.q[q].back());
      }
      std::printf(" | %9.3f %9.3f | %9.3f %10d\n", m.mean_own.back(), m.mean_set.back(), m.late_pairs.back(),
                  p.cache_pairs());
      if (p.stage_ms.size() == n) {
        // viscd's second half: its stages, the rest of calculateOverlappingPairs, boxes changed and placed.
        std::array<double, viscd::kStageCount> st{};
        double mv = 0, rp = 0, all = 0;
        for (std::size_t s = n / 2; s < n; ++s) {
          for (std::size_t g = 0; g < viscd::kStageCount; ++g) st[g] += p.stage_ms[s][g];
          mv += p.moved[s];
          rp += p.replaced[s];
        }
        std::printf("      second half, mean ms:");
        for (std::size_t g = 0; g < viscd::kStageCount; ++g) {
          all += st[g];
          if (st[g] > 0)
            std::printf(" %s %.3f", std::string(viscd::stage_name(static_cast<viscd::Stage>(g))).c_str(),
                        st[g] / static_cast<double>(n - n / 2));
        }
        std::printf(" rest %.3f; changed %.0f, placed again %.0f a step\n",
                    m.late_pairs.back() - all / static_cast<double>(n - n / 2), mv / static_cast<double>(n - n / 2),
                    rp / static_cast<double>(n - n / 2));
      }
    }
    std::fflush(stdout);
  }
  std::printf("\nmedians over %d rounds (ms)\n", rounds);
  std::printf("%-22s %9s %9s %9s %9s | %9s %9s | %9s\n", "broadphase", "own Q1", "Q2", "Q3", "Q4", "own mean",
              "setAabb", "late pairs");
  for (std::size_t k = 0; k < kinds.size(); ++k) {
    const Summary& m = sums[k];
    std::printf("%-22s %9.3f %9.3f %9.3f %9.3f | %9.3f %9.3f | %9.3f\n", kinds[k].name.c_str(), median(m.q[0]),
                median(m.q[1]), median(m.q[2]), median(m.q[3]), median(m.mean_own), median(m.mean_set),
                median(m.late_pairs));
  }
  const auto dbvt = std::find_if(kinds.begin(), kinds.end(), [](const Kind& k) { return k.key == "dbvt"; });
  if (dbvt == kinds.end()) return;
  const auto d = static_cast<std::size_t>(dbvt - kinds.begin());
  std::printf("\nbtDbvtBroadphase's mean own time over each one's, per round (above 1: faster than btDbvt)\n");
  for (std::size_t k = 0; k < kinds.size(); ++k) {
    if (k == d) continue;
    std::printf("%-22s", kinds[k].name.c_str());
    for (int r = 0; r < rounds; ++r) std::printf(" %6.2f", sums[d].mean_own[r] / sums[k].mean_own[r]);
    std::printf("\n");
  }
}

// Counts the proxies a rayTest reports. The fields set() fills are what btDbvtBroadphase's rayTest
// reads (as btCollisionWorld's own ray callback fills them).
struct CountRay final : btBroadphaseRayCallback {
  std::size_t hits = 0;
  void set(const btVector3& from, const btVector3& to) {
    btVector3 dir = to - from;
    dir.normalize();
    for (int k = 0; k < 3; ++k) {
      m_rayDirectionInverse[k] = dir[k] == btScalar(0) ? btScalar(BT_LARGE_FLOAT) : btScalar(1) / dir[k];
      m_signs[k] = m_rayDirectionInverse[k] < 0;
    }
    m_lambda_max = dir.dot(to - from);
  }
  bool process(const btBroadphaseProxy*) override {
    ++hits;
    return true;
  }
};

struct CountBox final : btBroadphaseAabbCallback {
  std::size_t hits = 0;
  bool process(const btBroadphaseProxy*) override {
    ++hits;
    return true;
  }
};

// Boxes on a landscape: x, z uniform over a square, resting on hills y = h(x, z), sides 0.5-2 m;
// each step 1 % of them shift a little (a few bodies awake). Rays fall from 50 m above onto the
// ground with a small slant; query boxes of 1-4 m sit on the ground.
void bench_queries(const std::vector<int>& counts, int rays, int steps) {
  std::printf("queries: boxes on a landscape, 1 %% moving per step, %d rays and %d aabbTest boxes per step,\n", rays,
              rays);
  std::printf("medians over %d steps (the first left out), broadphases interleaved step by step\n", steps);
  std::printf("%-10s %-26s %12s %12s %12s %12s %12s\n", "bodies", "broadphase", "us_per_ray", "us_per_box", "ray_hits",
              "box_hits", "step_ms");
  for (const int n : counts) {
    const double side = std::sqrt(static_cast<double>(n)) * 3.0;
    const auto ground = [&](double x, double z) { return 4.0 * std::sin(x * 0.05) * std::cos(z * 0.07); };
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> at(0, side), size(0.5, 2.0), nudge(-0.05, 0.05), slant(-0.2, 0.2);
    std::vector<btVector3> lo(static_cast<std::size_t>(n)), hi(static_cast<std::size_t>(n));
    for (std::size_t k = 0; k < lo.size(); ++k) {
      const double x = at(rng), z = at(rng), sx = size(rng), sy = size(rng), sz = size(rng);
      const double y = ground(x, z);
      lo[k] = btVector3(btScalar(x), btScalar(y), btScalar(z));
      hi[k] = btVector3(btScalar(x + sx), btScalar(y + sy), btScalar(z + sz));
    }
    struct Side {
      std::string name;
      std::unique_ptr<btBroadphaseInterface> bp;
      std::vector<btBroadphaseProxy*> proxies;
      std::vector<double> ray_us, box_us, step_ms;
      std::size_t ray_hits = 0, box_hits = 0;
    };
    std::vector<Side> sides;
    sides.push_back({"viscd::BulletBroadphase", std::make_unique<viscd::BulletBroadphase>(), {}, {}, {}, {}, 0, 0});
    sides.push_back({"btDbvtBroadphase", std::make_unique<btDbvtBroadphase>(), {}, {}, {}, {}, 0, 0});
    btDefaultCollisionConfiguration configuration;
    btCollisionDispatcher dispatcher(&configuration);
    for (Side& s : sides) {
      for (std::size_t k = 0; k < lo.size(); ++k)
        s.proxies.push_back(s.bp->createProxy(lo[k], hi[k], BOX_SHAPE_PROXYTYPE, nullptr, 1, -1, &dispatcher));
      s.bp->calculateOverlappingPairs(&dispatcher);
    }
    std::vector<std::size_t> moved;
    std::vector<std::pair<btVector3, btVector3>> ray_ends, boxes;
    for (int step = 0; step < steps; ++step) {
      moved.clear();
      for (std::size_t k = 0; k < lo.size(); k += 100) {
        const std::size_t m = (k + static_cast<std::size_t>(step) * 37) % lo.size();
        const btVector3 d(btScalar(nudge(rng)), btScalar(nudge(rng)), btScalar(nudge(rng)));
        lo[m] += d;
        hi[m] += d;
        moved.push_back(m);
      }
      ray_ends.clear();
      boxes.clear();
      for (int r = 0; r < rays; ++r) {
        const double x = at(rng), z = at(rng);
        ray_ends.emplace_back(btVector3(btScalar(x), 50, btScalar(z)),
                              btVector3(btScalar(x + 60 * slant(rng)), -10, btScalar(z + 60 * slant(rng))));
        const double bx = at(rng), bz = at(rng), s = 1 + 3 * at(rng) / side, y = ground(bx, bz);
        boxes.emplace_back(btVector3(btScalar(bx), btScalar(y), btScalar(bz)),
                           btVector3(btScalar(bx + s), btScalar(y + s), btScalar(bz + s)));
      }
      for (Side& s : sides) {
        auto start = Clock::now();
        for (const std::size_t m : moved) s.bp->setAabb(s.proxies[m], lo[m], hi[m], &dispatcher);
        s.bp->calculateOverlappingPairs(&dispatcher);
        const double step_ms = ms_since(start);
        CountRay ray;
        start = Clock::now();
        for (const auto& [from, to] : ray_ends) {
          ray.set(from, to);
          s.bp->rayTest(from, to, ray);
        }
        const double ray_ms = ms_since(start);
        CountBox box;
        start = Clock::now();
        for (const auto& [a, b] : boxes) s.bp->aabbTest(a, b, box);
        const double box_ms = ms_since(start);
        if (step == 0) continue;  // the first queries build what queries need
        s.step_ms.push_back(step_ms);
        s.ray_us.push_back(1000 * ray_ms / rays);
        s.box_us.push_back(1000 * box_ms / rays);
        s.ray_hits += ray.hits;
        s.box_hits += box.hits;
      }
    }
    for (Side& s : sides) {
      std::printf("%-10d %-26s %12.3f %12.3f %12zu %12zu %12.3f\n", n, s.name.c_str(), median(s.ray_us),
                  median(s.box_us), s.ray_hits, s.box_hits, median(s.step_ms));
      for (btBroadphaseProxy* p : s.proxies) s.bp->destroyProxy(p, &dispatcher);
    }
    std::fflush(stdout);
  }
}

bool count_pair(fcl::CollisionObjectd*, fcl::CollisionObjectd*, void* data) {
  ++*static_cast<std::size_t*>(data);
  return false;
}

void bench_fcl(int boxes, int reps, const std::vector<std::string>& managers) {
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
  // Pairs: after setup, every manager's callback count is exact or above (viscd: float boxes
  // rounded outward); after update, DynamicAABBTree keeps a leaf's old box while it contains the
  // new one, so it may count more.
  // `managers` picks them (default both): FCL's time differs from process to process, so a ratio
  // taken in one process moves with FCL's mode there; each alone over many processes compares
  // medians.
  using Make = std::function<std::unique_ptr<fcl::BroadPhaseCollisionManagerd>()>;
  std::vector<std::pair<std::string, Make>> kinds;
  const auto wanted = [&](const char* key) {
    return managers.empty() || std::find(managers.begin(), managers.end(), key) != managers.end();
  };
  if (wanted("viscd"))
    kinds.emplace_back("viscd::FclBroadphaseManager", [] { return std::make_unique<viscd::FclBroadphaseManager>(); });
  if (wanted("fcl"))
    kinds.emplace_back("fcl::DynamicAABBTreeCollisionManager",
                       [] { return std::make_unique<fcl::DynamicAABBTreeCollisionManagerd>(); });
  const char* how = kinds.size() == 1 ? ", one manager"
                                      : "; the managers take\nturns in every run, and x FCL is the median of the "
                                        "runs' ratios";
  std::printf("fcl: self collision of %d boxes, counting callback, medians of %d runs (ms)%s\n", boxes, reps, how);
  std::vector<fcl::Transform3d> initial;
  for (auto& o : objects) initial.push_back(o->getTransform());
  struct Times {
    std::vector<double> first, second, update, few;
    std::size_t pairs = 0, setup_pairs = 0;
  };
  std::vector<Times> times(kinds.size());
  for (int r = 0; r < reps; ++r) {
    for (std::size_t kind = 0; kind < kinds.size(); ++kind) {
      // Every manager sees the same boxes and the same moves.
      for (std::size_t k = 0; k < objects.size(); ++k) {
        objects[k]->setTransform(initial[k]);
        objects[k]->computeAABB();
      }
      std::mt19937 moves(3 + static_cast<unsigned>(r));
      Times& t = times[kind];
      auto manager = kinds[kind].second();
      auto start = Clock::now();
      manager->registerObjects(pointers);
      manager->setup();
      t.pairs = 0;
      manager->collide(&t.pairs, count_pair);
      t.first.push_back(ms_since(start));
      t.setup_pairs = t.pairs;
      for (auto& o : objects) {  // every box moves a little
        fcl::Transform3d pose = o->getTransform();
        pose.translation() += fcl::Vector3d(step(moves), step(moves), step(moves));
        o->setTransform(pose);
        o->computeAABB();
      }
      start = Clock::now();
      manager->update();
      t.update.push_back(ms_since(start));
      t.pairs = 0;
      manager->collide(&t.pairs, count_pair);
      t.second.push_back(ms_since(start));
      // Then frames where 1 % of the boxes move and update(vector) names them; the run's median.
      std::vector<double> few;
      for (int f = 0; f < 10; ++f) {
        std::vector<fcl::CollisionObjectd*> named;
        for (std::size_t k = 0; k < objects.size(); k += 100) {
          auto& o = objects[(k + static_cast<std::size_t>(f) * 37) % objects.size()];
          fcl::Transform3d pose = o->getTransform();
          pose.translation() += fcl::Vector3d(step(moves), step(moves), step(moves));
          o->setTransform(pose);
          o->computeAABB();
          named.push_back(o.get());
        }
        start = Clock::now();
        manager->update(named);
        t.pairs = 0;
        manager->collide(&t.pairs, count_pair);
        few.push_back(ms_since(start));
      }
      t.few.push_back(median(few));
    }
  }
  // The ratio of FCL's time (the last kind) to viscd's, per run.
  const auto ratio = [&](std::vector<double> Times::*column) {
    std::vector<double> r;
    for (std::size_t k = 0; k < (times[0].*column).size(); ++k)
      r.push_back((times.back().*column)[k] / (times[0].*column)[k]);
    return median(r);
  };
  std::printf("%-38s %14s %16s %10s %16s %12s %14s\n", "manager", "setup+collide", "update+collide", "(update)",
              "1%named+collide", "setup_pairs", "pairs_last");
  for (std::size_t kind = 0; kind < kinds.size(); ++kind) {
    const Times& t = times[kind];
    std::printf("%-38s %14.1f %16.1f %10.2f %16.2f %12zu %14zu\n", kinds[kind].first.c_str(), median(t.first),
                median(t.second), median(t.update), median(t.few), t.setup_pairs, t.pairs);
  }
  if (kinds.size() == 2)
    std::printf("%-38s %14.2f %16.2f %10s %16.2f\n", "x FCL (median of per-run ratios)", ratio(&Times::first),
                ratio(&Times::second), "", ratio(&Times::few));
  std::fflush(stdout);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"viscd's Bullet and FCL adapters against the engines' own broadphases"};
  std::string only;
  int bodies = 10000, steps = 120, fcl_boxes = 100000, reps = 3, rays = 500, query_steps = 21, replay = 0;
  std::string replay_log;
  std::vector<int> query_bodies = {1000, 10000};
  app.add_option("--only", only, "run one part: bullet, fcl or queries")
      ->check(CLI::IsMember({"bullet", "fcl", "queries"}));
  app.add_option("--bodies", bodies, "falling bodies in the Bullet world")->check(CLI::Range(1, 10000000));
  app.add_option("--steps", steps, "Bullet steps (60 Hz)")->check(CLI::Range(6, 100000));
  bool pillars = false;
  std::vector<std::string> broadphases, fcl_managers;
  app.add_option("--broadphases", broadphases,
                 "Bullet world: the broadphases stepped (default all): viscd, rebuilding, one-thread, margin0, move0, "
                 "dbvt, sweep")
      ->delimiter(',')
      ->check(CLI::IsMember({"viscd", "rebuilding", "one-thread", "margin0", "move0", "dbvt", "sweep"}));
  app.add_flag("--pillars", pillars, "Bullet world: every other body a sphere, and static pillars in the bin");
  bool settling = false;
  app.add_flag("--settling", settling,
               "Bullet world: --pillars on a floor twice as wide, friction 0.6, rolling friction on the spheres "
               "(a world whose bodies Bullet puts to sleep)");
  app.add_option("--replay", replay,
                 "Bullet world: step it once on btDbvt recording its broadphase calls, then play them through each "
                 "broadphase this many rounds (their own times on the same calls, without the solver)")
      ->check(CLI::Range(1, 1000));
  app.add_option("--replay-log", replay_log,
                 "with --replay: read the recorded calls from this file, or record them and write it (the world's "
                 "options are then those it was recorded with)");
  app.add_option("--fcl-managers", fcl_managers,
                 "FCL part: the managers timed (default both, in turns): viscd, fcl (one alone per process, "
                 "for medians over processes)")
      ->delimiter(',')
      ->check(CLI::IsMember({"viscd", "fcl"}));
  app.add_option("--fcl-boxes", fcl_boxes, "boxes in the FCL self collision")->check(CLI::Range(2, 100000000));
  app.add_option("--reps", reps, "FCL runs per manager")->check(CLI::Range(1, 1000));
  app.add_option("--query-bodies", query_bodies, "proxies in the query part, one run each (e.g. 1000,10000)")
      ->delimiter(',')
      ->check(CLI::Range(1, 10000000));
  app.add_option("--rays", rays, "rays (and aabbTest boxes) per step in the query part")->check(CLI::Range(1, 1000000));
  app.add_option("--query-steps", query_steps, "steps in the query part")->check(CLI::Range(2, 100000));
  CLI11_PARSE(app, argc, argv);
  if ((only.empty() || only == "bullet") && replay > 0)
    bench_bullet_replay(bodies, steps, pillars || settling, settling, replay, broadphases, replay_log);
  else if (only.empty() || only == "bullet")
    bench_bullet(bodies, steps, pillars || settling, settling, broadphases);
  if (only.empty() || only == "fcl") bench_fcl(fcl_boxes, reps, fcl_managers);
  if (only.empty() || only == "queries") bench_queries(query_bodies, rays, query_steps);
  return 0;
}
