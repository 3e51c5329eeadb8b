// viscd::FclBroadphaseManager: FCL's broadphase manager interface on viscd's cpu detector.
//
// The manager keeps, per object, its double AABB (FCL's) and a float box rounded outward. The
// self frame (the detector run on those boxes) is made when a query first needs it after a
// change, and answers collide() and, through the detector's box query, collide(obj).
//
// distance() visits candidate pairs best-first by their AABB distance (the lower bound FCL's
// managers use). A candidate set for radius r comes from a frame whose boxes are grown by r / 2
// (a query box grown by r), which holds every pair whose AABB distance is at most r: such a pair
// is at most r apart on every axis. Rounds: r = 0 (the self frame); then r doubles from a guess
// until some pair is offered, then r = the running distance, which after that round is at most
// r, so every pair whose bound is below it has been offered: the result is the exact minimum.

#include "viscd/fcl.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <span>
#include <vector>

#include "adapter_util.hpp"
#include "viscd/detector.hpp"
#include "viscd/executor.hpp"

namespace viscd {
namespace {

using Object = fcl::CollisionObject<double>;
using Aabb = fcl::AABB<double>;

// Another manager's objects and their AABBs, for the queries against it.
void objects_of(const fcl::BroadPhaseCollisionManager<double>& manager, std::vector<Object*>& objects,
                std::vector<Aabb>& aabbs) {
  manager.getObjects(objects);
  aabbs.resize(objects.size());
  for (std::size_t k = 0; k < objects.size(); ++k) aabbs[k] = objects[k]->getAABB();
}

constexpr double kHuge = std::numeric_limits<double>::max();
// Pairs a grown frame may hold before a distance round falls back to visiting pairs one by one.
constexpr std::size_t kGrownPairMemory = std::size_t{512} << 20;

// The AABB as a float box holding it: bounds rounded outward, clamped to +-kMaxCoordinate
// (monotone, so overlaps are kept), a NaN bound spanning everything (fcl::AABB::overlap is true
// for NaN bounds). Without branches and inlined: update() converts every object's AABB.
inline Box to_box(const Aabb& a) {
  Box b;
  for (int k = 0; k < 3; ++k) {
    // Written so that a NaN bound fails the first comparison and lands at the far end.
    const float down = adapter_detail::round_down(a.min_[k]), up = adapter_detail::round_up(a.max_[k]);
    b.min[k] = down > -kMaxCoordinate ? std::min(down, kMaxCoordinate) : -kMaxCoordinate;
    b.max[k] = up < kMaxCoordinate ? std::max(up, -kMaxCoordinate) : kMaxCoordinate;
  }
  return b;
}

// The AABB grown by `grow` on every side, as such a box (one double step out first, for the
// rounding of the sum).
Box to_box(const Aabb& a, double grow) {
  if (!(grow > 0)) return to_box(a);
  Aabb g;
  for (int k = 0; k < 3; ++k) {
    g.min_[k] = std::nextafter(a.min_[k] - grow, -kHuge);
    g.max_[k] = std::nextafter(a.max_[k] + grow, kHuge);
  }
  return to_box(g);
}

// Half the radius each box grows by so that pairs whose computed AABB distance is at most r
// overlap: the computed distance may fall short of the exact gap by a few ulps, hence the factor.
double half_grow(double r) { return 0.5 * r * (1 + 1e-12); }

struct Candidate {
  double bound;     // AABB distance
  std::uint32_t a;  // this manager's object (or, for distance(obj), the object found)
  std::uint32_t b;  // the other side's
};

}  // namespace

struct FclBroadphaseManager::State {
  Config config;
  std::unique_ptr<Detector> detector;  // the self frame; collide(obj)'s box query
  std::unique_ptr<Detector> grown;     // grown and cross frames
  std::vector<Object*> objects;
  adapter_detail::PointerIndex index;  // object -> its index in `objects`
  std::vector<Aabb> aabbs;
  std::vector<Box> boxes;
  bool frame_ready = false;  // `frame` describes `boxes`
  // The objects whose box changed since the last self frame (FrameInput::moved), unless
  // moved_all: then the next frame is not listed (the detector compares every box itself).
  std::vector<std::uint32_t> moved;
  bool moved_all = true;
  bool detector_ok = false;  // and the detector answers box queries on them
  FrameResult frame;
  FrameResult grown_frame;
  Status status;
  std::vector<Box> work_boxes;
  std::vector<Filter> work_filters;
  std::vector<std::uint32_t> hits;
  // Lists lent to one call (a callback may call the manager again), so that calls reuse memory.
  adapter_detail::VectorPool<std::uint32_t> index_lists;
  adapter_detail::VectorPool<Object*> object_lists;
  adapter_detail::VectorPool<Aabb> aabb_lists;
  adapter_detail::VectorPool<Candidate> candidate_lists;

  explicit State(const Config& c) : config(c) {
    config.contact_events = false;
    detector = make_cpu_detector(config);
  }

  void read(std::uint32_t k) {
    aabbs[k] = objects[k]->getAABB();
    boxes[k] = to_box(aabbs[k]);
  }

  // update(obj): the AABB read again; listed for the next frame when its float box changed.
  void reread(std::uint32_t k) {
    const Box before = boxes[k];
    read(k);
    frame_ready = false;
    if (std::memcmp(&before, &boxes[k], sizeof(Box)) != 0) moved.push_back(k);
  }

  // The self frame on the current boxes; by brute force if the detector fails (out of memory).
  void ensure_frame() {
    if (frame_ready) return;
    FrameInput in;
    in.boxes = boxes;
    if (!moved_all) {  // only the named objects changed: the detector compares nothing else
      std::sort(moved.begin(), moved.end());
      moved.erase(std::unique(moved.begin(), moved.end()), moved.end());
      in.moved = moved;
      in.moved_listed = true;
    }
    status = detector->detect(in, frame);
    detector_ok = status.ok();
    moved.clear();
    moved_all = !detector_ok;  // after a failed frame the next one compares everything
    if (!detector_ok) {
      frame.pairs.clear();
      for (std::uint32_t i = 0; i < boxes.size(); ++i)
        for (std::uint32_t j = i + 1; j < boxes.size(); ++j)
          if (boxes_overlap(boxes[i], boxes[j])) frame.pairs.push_back({i, j});
    }
    frame_ready = true;
  }

  // This manager's objects whose box overlaps `query` (sorted by index).
  void overlapping(const Box& query, std::vector<std::uint32_t>& out) {
    ensure_frame();
    if (detector_ok) {
      detector->overlap_box(query, out);
      return;
    }
    out.clear();
    for (std::uint32_t i = 0; i < boxes.size(); ++i)
      if (boxes_overlap(boxes[i], query)) out.push_back(i);
  }

  // Pairs (i < j) of this manager whose boxes grown by r / 2 overlap; false when the frame failed
  // (too many pairs): the caller then visits pairs one by one.
  bool self_candidates(double r, std::vector<Candidate>& out) {
    out.clear();
    if (r == 0) {
      ensure_frame();
      for (const Pair& q : frame.pairs) out.push_back({aabbs[q.i].distance(aabbs[q.j]), q.i, q.j});
      return true;
    }
    const double g = half_grow(r);
    work_boxes.resize(boxes.size());
    for (std::size_t k = 0; k < boxes.size(); ++k) work_boxes[k] = to_box(aabbs[k], g);
    FrameInput in;
    in.boxes = work_boxes;
    if (!run_grown(in)) return false;
    for (const Pair& q : grown_frame.pairs) out.push_back({aabbs[q.i].distance(aabbs[q.j]), q.i, q.j});
    return true;
  }

  // Pairs (i of this, j of `other`) whose boxes grown by r / 2 overlap.
  bool cross_candidates(double r, const std::vector<Aabb>& other, std::vector<Candidate>& out) {
    out.clear();
    const std::size_t n = boxes.size(), m = other.size();
    if (m * 8 <= n) {  // a few query boxes against the self frame
      for (std::uint32_t j = 0; j < m; ++j) {
        overlapping(to_box(other[j], 2 * half_grow(r)), hits);
        for (const std::uint32_t i : hits) out.push_back({aabbs[i].distance(other[j]), i, j});
      }
      return true;
    }
    const double g = half_grow(r);
    work_boxes.resize(n + m);
    work_filters.resize(n + m);
    for (std::size_t k = 0; k < n; ++k) {
      work_boxes[k] = r == 0 ? boxes[k] : to_box(aabbs[k], g);
      work_filters[k] = Filter{1, 2};
    }
    for (std::size_t k = 0; k < m; ++k) {
      work_boxes[n + k] = to_box(other[k], g);
      work_filters[n + k] = Filter{2, 1};
    }
    FrameInput in;
    in.boxes = work_boxes;
    in.filters = work_filters;
    if (!run_grown(in)) return false;
    for (const Pair& q : grown_frame.pairs) {
      const auto j = static_cast<std::uint32_t>(q.j - n);
      out.push_back({aabbs[q.i].distance(other[j]), q.i, j});
    }
    return true;
  }

  // A grown frame; its outcome becomes last_status(), so that a fall back to visiting pairs one
  // by one says why.
  bool run_grown(const FrameInput& in) {
    if (!grown) {
      Config c = config;
      c.pair_memory_cap =  // the caller's cap when lower
          config.pair_memory_cap != 0 ? std::min(config.pair_memory_cap, kGrownPairMemory) : kGrownPairMemory;
      grown = make_cpu_detector(c);
    }
    status = grown->detect(in, grown_frame);
    return status.ok();
  }

  // The radii of the rounds: `guess`, a first radius when no AABBs overlap (the scene's diagonal
  // over the cube root of the count: the spacing of objects spread evenly), and `all`, the
  // diagonal, which no AABB distance exceeds.
  struct Radii {
    double guess, all;
  };
  [[nodiscard]] static Radii radii(std::span<const Aabb> a, std::span<const Aabb> b) {
    double lo[3] = {kHuge, kHuge, kHuge}, hi[3] = {-kHuge, -kHuge, -kHuge};
    for (const auto* set : {&a, &b})
      for (const Aabb& x : *set)
        for (int k = 0; k < 3; ++k) {
          lo[k] = std::min(lo[k], x.min_[k]);
          hi[k] = std::max(hi[k], x.max_[k]);
        }
    double d2 = 0;
    for (int k = 0; k < 3; ++k) d2 += (hi[k] - lo[k]) * (hi[k] - lo[k]);
    const double all = std::sqrt(d2), n = static_cast<double>(a.size() + b.size());
    const double guess = std::isfinite(all) ? all / std::cbrt(std::max(n, 1.0)) : 1.0;
    return {std::max(guess, 1e-9), all};
  }

  // The best-first rounds (file comment). `candidates(r, out)` lists pairs with bound <= r (and
  // maybe more), false when it cannot; `each_pair(visit)` visits every pair as (bound, a, b) for
  // the fallback; `offer(a, b, dist)` calls the callback. Returns when the callback says stop or
  // the minimum is known.
  template <class Candidates, class EachPair, class Offer>
  void best_first(Radii radii, Candidates&& candidates, EachPair&& each_pair, Offer&& offer) {
    double min_dist = kHuge;
    double covered = -1;  // every pair with bound <= covered has been offered (or ruled out)
    double r = 0;
    auto loan = candidate_lists.take();
    std::vector<Candidate>& list = *loan;
    for (;;) {
      if (!std::isfinite(r) || !candidates(r, list)) {
        // Visit the remaining pairs one by one, as fcl::NaiveCollisionManager does.
        bool stop = false;
        each_pair([&](double bound, std::uint32_t a, std::uint32_t b) {
          if (stop || !(bound > covered && bound < min_dist)) return;  // NaN bounds are never offered
          stop = offer(a, b, min_dist);
        });
        return;
      }
      list.erase(std::remove_if(list.begin(), list.end(),
                                [&](const Candidate& c) { return !(c.bound > covered && c.bound <= r); }),
                 list.end());
      std::sort(list.begin(), list.end(), [](const Candidate& x, const Candidate& y) {
        return x.bound < y.bound || (x.bound == y.bound && (x.a < y.a || (x.a == y.a && x.b < y.b)));
      });
      for (const Candidate& c : list) {
        if (c.bound >= min_dist) return;  // and every later bound is as large
        if (offer(c.a, c.b, min_dist)) return;
      }
      covered = r;
      if (min_dist <= covered || covered >= radii.all) return;
      r = min_dist < kHuge ? min_dist : (r == 0 ? radii.guess : 2 * r);
    }
  }

  void remove_at(std::uint32_t k) {
    const auto last = static_cast<std::uint32_t>(objects.size() - 1);
    index.erase(objects[k]);
    if (k != last) {
      objects[k] = objects[last];
      aabbs[k] = aabbs[last];
      boxes[k] = boxes[last];
      index.assign(objects[k], k);
    }
    objects.pop_back();
    aabbs.pop_back();
    boxes.pop_back();
    frame_ready = false;
    moved_all = true;  // renumbered
  }
};

FclBroadphaseManager::FclBroadphaseManager() : FclBroadphaseManager(Config{}) {}
FclBroadphaseManager::FclBroadphaseManager(const Config& config) : state_(std::make_unique<State>(config)) {}
FclBroadphaseManager::~FclBroadphaseManager() = default;

void FclBroadphaseManager::registerObjects(const std::vector<Object*>& other_objs) {
  State& st = *state_;
  st.objects.reserve(st.objects.size() + other_objs.size());
  st.index.reserve(st.objects.size() + other_objs.size());
  for (Object* obj : other_objs) registerObject(obj);
}

void FclBroadphaseManager::registerObject(Object* obj) {
  State& st = *state_;
  const auto k = static_cast<std::uint32_t>(st.objects.size());
  if (!st.index.insert(obj, k)) return;  // null, or registered already
  st.objects.push_back(obj);
  st.aabbs.emplace_back();
  st.boxes.emplace_back();
  st.read(k);
  st.frame_ready = false;
  st.moved_all = true;  // a new object
}

void FclBroadphaseManager::unregisterObject(Object* obj) {
  State& st = *state_;
  const std::uint32_t k = st.index.find(obj);
  if (k != adapter_detail::PointerIndex::kMissing) st.remove_at(k);
}

void FclBroadphaseManager::setup() { update(); }

void FclBroadphaseManager::update() {
  State& st = *state_;
  // The objects lie wherever the caller allocated them: each read waits on memory. So the AABBs
  // a few objects ahead are fetched early, and the objects are read in parallel chunks on the
  // detector's executor (Config::executor, else viscd's pool), as many as Config::threads allows
  // (docs/adapters.md: 100 000 boxes, 15.7 ms read one at a time).
  constexpr std::size_t kAhead = 16, kPerChunk = 4096;
  const std::size_t n = st.objects.size();
  Executor& executor = st.config.executor ? *st.config.executor : shared_executor();
  const int threads =
      st.config.threads > 0 ? std::min(st.config.threads, executor.concurrency()) : executor.concurrency();
  const std::size_t chunks =
      threads <= 1 ? 1 : std::clamp<std::size_t>(n / kPerChunk, 1, 2 * static_cast<std::size_t>(threads));
  const auto read_range = [&](std::size_t begin, std::size_t end) {
    for (std::size_t k = begin; k < end; ++k) {
      if (k + kAhead < end) {  // both lines an AABB (48 bytes) may span
        const auto* ahead = reinterpret_cast<const char*>(&st.objects[k + kAhead]->getAABB());
        __builtin_prefetch(ahead);
        __builtin_prefetch(ahead + sizeof(Aabb) - 1);
      }
      st.read(static_cast<std::uint32_t>(k));
    }
  };
  if (chunks == 1) {
    read_range(0, n);
  } else {
    executor.run(static_cast<std::uint32_t>(chunks), [&](std::uint32_t c) {
      read_range(n * c / chunks, n * (c + 1) / chunks);  // each object in one chunk: no shared writes
    });
  }
  st.frame_ready = false;
  st.moved_all = true;  // any box may have changed: the detector finds which
}

void FclBroadphaseManager::update(Object* updated_obj) {
  State& st = *state_;
  const std::uint32_t k = st.index.find(updated_obj);
  if (k != adapter_detail::PointerIndex::kMissing) st.reread(k);
}

void FclBroadphaseManager::update(const std::vector<Object*>& updated_objs) {
  // Each object costs its index slot, its AABB, and its entries in aabbs and boxes, all scattered:
  // the slots and AABBs of the objects eight ahead are fetched, and the entries of those four
  // ahead (whose slots are in cache by then). Each object is looked up once, four ahead, and its
  // index waits in a ring until its turn.
  State& st = *state_;
  constexpr std::size_t kSlotAhead = 8, kEntryAhead = 4;
  constexpr std::uint32_t kMissing = adapter_detail::PointerIndex::kMissing;
  const std::size_t n = updated_objs.size();
  auto look_up = [&](std::size_t t) {
    const std::uint32_t k = st.index.find(updated_objs[t]);
    if (k != kMissing) {
      __builtin_prefetch(&st.aabbs[k]);
      __builtin_prefetch(&st.boxes[k]);
    }
    return k;
  };
  std::uint32_t ring[kEntryAhead];
  for (std::size_t t = 0; t < std::min(n, kEntryAhead); ++t) ring[t] = look_up(t);
  for (std::size_t t = 0; t < n; ++t) {
    if (t + kSlotAhead < n && updated_objs[t + kSlotAhead] != nullptr) {
      const Object* ahead = updated_objs[t + kSlotAhead];
      __builtin_prefetch(st.index.slot_of(ahead));
      __builtin_prefetch(&ahead->getAABB());
    }
    const std::uint32_t k = ring[t % kEntryAhead];
    if (t + kEntryAhead < n) ring[t % kEntryAhead] = look_up(t + kEntryAhead);
    if (k != kMissing) st.reread(k);
  }
}

void FclBroadphaseManager::clear() {
  State& st = *state_;
  st.objects.clear();
  st.index.clear();
  st.aabbs.clear();
  st.boxes.clear();
  st.frame_ready = false;
  st.moved_all = true;
}

void FclBroadphaseManager::getObjects(std::vector<Object*>& objs) const { objs = state_->objects; }

void FclBroadphaseManager::collide(Object* obj, void* cdata, fcl::CollisionCallBack<double> callback) const {
  State& st = *state_;
  if (st.objects.empty()) return;
  auto found = st.index_lists.take();
  st.overlapping(to_box(obj->getAABB()), *found);
  for (const std::uint32_t i : *found)
    if (callback(obj, st.objects[i], cdata)) return;
}

void FclBroadphaseManager::collide(void* cdata, fcl::CollisionCallBack<double> callback) const {
  State& st = *state_;
  if (st.objects.size() < 2) return;
  st.ensure_frame();
  // The pairs ascend by i, so objects[i] is read in order; objects[j] is scattered over the list
  // (800 KB for 100 000 objects) and had stalled the loop: fetched sixteen pairs ahead.
  constexpr std::size_t kAhead = 16;
  const std::vector<Pair>& pairs = st.frame.pairs;
  for (std::size_t t = 0; t < pairs.size(); ++t) {
    if (t + kAhead < pairs.size()) __builtin_prefetch(&st.objects[pairs[t + kAhead].j]);
    const Pair q = pairs[t];
    if (callback(st.objects[q.i], st.objects[q.j], cdata)) return;
  }
}

void FclBroadphaseManager::collide(fcl::BroadPhaseCollisionManager<double>* other_manager, void* cdata,
                                   fcl::CollisionCallBack<double> callback) const {
  if (other_manager == this) {
    collide(cdata, callback);
    return;
  }
  State& st = *state_;
  auto others_loan = st.object_lists.take();
  auto aabbs_loan = st.aabb_lists.take();
  std::vector<Object*>& others = *others_loan;
  std::vector<Aabb>& other_aabbs = *aabbs_loan;
  objects_of(*other_manager, others, other_aabbs);
  if (st.objects.empty() || others.empty()) return;
  auto list_loan = st.candidate_lists.take();
  std::vector<Candidate>& list = *list_loan;
  if (!st.cross_candidates(0, other_aabbs, list)) {  // too many pairs: one by one
    for (std::uint32_t i = 0; i < st.objects.size(); ++i)
      for (std::uint32_t j = 0; j < others.size(); ++j)
        if (boxes_overlap(st.boxes[i], to_box(other_aabbs[j])) && callback(st.objects[i], others[j], cdata)) return;
    return;
  }
  for (const Candidate& c : list)
    if (callback(st.objects[c.a], others[c.b], cdata)) return;
}

void FclBroadphaseManager::distance(Object* obj, void* cdata, fcl::DistanceCallBack<double> callback) const {
  State& st = *state_;
  if (st.objects.empty()) return;
  const Aabb query = obj->getAABB();
  auto found_loan = st.index_lists.take();
  std::vector<std::uint32_t>& found = *found_loan;
  st.best_first(
      State::radii(st.aabbs, std::span<const Aabb>(&query, 1)),
      [&](double r, std::vector<Candidate>& out) {
        out.clear();
        st.overlapping(to_box(query, 2 * half_grow(r)), found);
        for (const std::uint32_t i : found) out.push_back({query.distance(st.aabbs[i]), i, 0});
        return true;
      },
      [&](auto&& visit) {
        for (std::uint32_t i = 0; i < st.objects.size(); ++i) visit(query.distance(st.aabbs[i]), i, 0u);
      },
      [&](std::uint32_t i, std::uint32_t, double& dist) { return callback(obj, st.objects[i], cdata, dist); });
}

void FclBroadphaseManager::distance(void* cdata, fcl::DistanceCallBack<double> callback) const {
  State& st = *state_;
  if (st.objects.size() < 2) return;
  st.best_first(
      State::radii(st.aabbs, {}), [&](double r, std::vector<Candidate>& out) { return st.self_candidates(r, out); },
      [&](auto&& visit) {
        for (std::uint32_t i = 0; i < st.objects.size(); ++i)
          for (std::uint32_t j = i + 1; j < st.objects.size(); ++j) visit(st.aabbs[i].distance(st.aabbs[j]), i, j);
      },
      [&](std::uint32_t i, std::uint32_t j, double& dist) {
        return callback(st.objects[i], st.objects[j], cdata, dist);
      });
}

void FclBroadphaseManager::distance(fcl::BroadPhaseCollisionManager<double>* other_manager, void* cdata,
                                    fcl::DistanceCallBack<double> callback) const {
  if (other_manager == this) {
    distance(cdata, callback);
    return;
  }
  State& st = *state_;
  auto others_loan = st.object_lists.take();
  auto aabbs_loan = st.aabb_lists.take();
  std::vector<Object*>& others = *others_loan;
  std::vector<Aabb>& other_aabbs = *aabbs_loan;
  objects_of(*other_manager, others, other_aabbs);
  if (st.objects.empty() || others.empty()) return;
  st.best_first(
      State::radii(st.aabbs, other_aabbs),
      [&](double r, std::vector<Candidate>& out) { return st.cross_candidates(r, other_aabbs, out); },
      [&](auto&& visit) {
        for (std::uint32_t i = 0; i < st.objects.size(); ++i)
          for (std::uint32_t j = 0; j < others.size(); ++j) visit(st.aabbs[i].distance(other_aabbs[j]), i, j);
      },
      [&](std::uint32_t i, std::uint32_t j, double& dist) { return callback(st.objects[i], others[j], cdata, dist); });
}

bool FclBroadphaseManager::empty() const { return state_->objects.empty(); }
size_t FclBroadphaseManager::size() const { return state_->objects.size(); }
const Status& FclBroadphaseManager::last_status() const { return state_->status; }

}  // namespace viscd
