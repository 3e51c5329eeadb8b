// viscd::BulletBroadphase: Bullet's broadphase interface on viscd's cpu detector.
//
// Ids. A moving proxy owns a slot s, its index in every frame's box array, from createProxy() to
// destroyProxy(); a static-set proxy owns the static slot k the detector gave it. The detector's
// contact events compare pairs by index, so an index must name the same proxy in the two frames
// they compare. Slots are reused, so the rule is: a slot whose occupant changed since the last
// successful frame (a proxy left it, or came into it) is "changed"; events naming a changed slot
// are ignored (the old occupant's pairs were removed from the cache when it was destroyed), and
// the frame's pairs naming a changed slot are added to the cache when missing. A destroyed moving
// proxy leaves a hole: a point box at its old centre with Filter{0, 0}, which pairs with nothing,
// until a new proxy takes the slot. When holes outnumber the live slots the frame is compacted
// (slots renumbered) and that frame's cache update is a full comparison instead of events.
//
// A pair cache with deferred removal (btSortedOverlappingPairCache) is brought up to date by the
// full comparison every frame, as btAxisSweep3 sorts and cleans its cache.

#include "viscd/bullet.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <type_traits>
#include <unordered_set>
#include <utility>
#include <vector>

#include "viscd/detector.hpp"

namespace viscd {
namespace {

constexpr std::uint32_t kNoSlot = 0xFFFFFFFFu;
constexpr std::uint32_t kStaticBits = static_cast<std::uint32_t>(btBroadphaseProxy::StaticFilter) |
                                      static_cast<std::uint32_t>(btBroadphaseProxy::KinematicFilter);
constexpr Filter kNeverPairs{0, 0};

struct Proxy final : btBroadphaseProxy {
  Proxy(const btVector3& lo, const btVector3& hi, void* user, int group, int mask)
      : btBroadphaseProxy(lo, hi, user, group, mask) {}
  bool fixed = false;            // belongs to the static set (in it while `valid`)
  bool valid = false;            // the AABB has no NaN: `box` holds it
  std::uint32_t slot = kNoSlot;  // moving slot, or static slot (kNoSlot while out of the set)
  std::uint32_t list_index = 0;  // position in State::proxies
  Box box;
};

Proxy* as_proxy(btBroadphaseProxy* p) { return static_cast<Proxy*>(p); }
const Proxy* as_proxy(const btBroadphaseProxy* p) { return static_cast<const Proxy*>(p); }

// btScalar to float, rounded down / up (exact in a float build).
float round_down(btScalar v) {
  if constexpr (std::is_same_v<btScalar, float>) {
    return v;
  } else {
    float f = static_cast<float>(v);
    if (static_cast<btScalar>(f) > v) f = std::nextafter(f, -std::numeric_limits<float>::infinity());
    return f;
  }
}
float round_up(btScalar v) {
  if constexpr (std::is_same_v<btScalar, float>) {
    return v;
  } else {
    float f = static_cast<float>(v);
    if (static_cast<btScalar>(f) < v) f = std::nextafter(f, std::numeric_limits<float>::infinity());
    return f;
  }
}

// The AABB as a viscd box, clamped to +-kMaxCoordinate (monotone, so no overlap is lost); false
// for a NaN bound or min > max.
bool to_box(const btVector3& lo, const btVector3& hi, Box& out) {
  for (int k = 0; k < 3; ++k) {
    if (std::isnan(lo[k]) || std::isnan(hi[k])) return false;
    out.min[k] = std::clamp(round_down(lo[k]), -kMaxCoordinate, kMaxCoordinate);
    out.max[k] = std::clamp(round_up(hi[k]), -kMaxCoordinate, kMaxCoordinate);
    if (out.min[k] > out.max[k]) return false;
  }
  return true;
}

bool same_box(const Box& a, const Box& b) {
  for (int k = 0; k < 3; ++k)
    if (a.min[k] != b.min[k] || a.max[k] != b.max[k]) return false;
  return true;
}

Box point_box(const Box& around) {
  Box b;
  for (int k = 0; k < 3; ++k) b.min[k] = b.max[k] = around.min[k] + 0.5f * (around.max[k] - around.min[k]);
  return b;
}

Filter filter_of(const btBroadphaseProxy& p) {
  return {static_cast<std::uint32_t>(p.m_collisionFilterGroup), static_cast<std::uint32_t>(p.m_collisionFilterMask)};
}

std::uint64_t pair_key(const btBroadphaseProxy* a, const btBroadphaseProxy* b) {
  auto ua = static_cast<std::uint32_t>(a->m_uniqueId), ub = static_cast<std::uint32_t>(b->m_uniqueId);
  if (ua > ub) std::swap(ua, ub);
  return (std::uint64_t{ua} << 32) | ub;
}

// The segment from + t (to - from), 0 <= t <= 1, against `box` grown by -sweep_max / -sweep_min
// (the Minkowski sum with the swept AABB, as btDbvt::rayTestInternal grows its nodes), in double.
bool swept_box_hit(const btVector3& from, const btVector3& to, const btVector3& sweep_min, const btVector3& sweep_max,
                   const Box& box) {
  double t0 = 0, t1 = 1;
  for (int k = 0; k < 3; ++k) {
    const double lo = double{box.min[k]} - double{sweep_max[k]}, hi = double{box.max[k]} - double{sweep_min[k]};
    const double o = from[k], d = double{to[k]} - double{from[k]};
    if (d == 0) {
      if (o < lo || o > hi) return false;
      continue;
    }
    double a = (lo - o) / d, b = (hi - o) / d;
    if (a > b) std::swap(a, b);
    t0 = std::max(t0, a);
    t1 = std::min(t1, b);
    if (t0 > t1) return false;
  }
  return true;
}

class CollectHits final : public RayVisitor {
 public:
  explicit CollectHits(std::vector<std::uint32_t>& out) : out_(out) {}
  float on_hit(const RayHit& hit) override {
    out_.push_back(hit.index);
    return std::numeric_limits<float>::infinity();  // keep every hit, as Bullet's broadphases do
  }

 private:
  std::vector<std::uint32_t>& out_;
};

}  // namespace

struct BulletBroadphase::State {
  Config config;
  std::unique_ptr<Detector> detector;
  btOverlappingPairCache* cache = nullptr;
  std::unique_ptr<btHashedOverlappingPairCache> owned_cache;

  std::vector<Proxy*> proxies;  // every live proxy, unordered
  // The moving frame, by slot.
  std::vector<Box> boxes;
  std::vector<Filter> filters;
  std::vector<std::uint8_t> always_active;
  std::vector<Proxy*> slot_proxy;  // nullptr: a hole
  std::vector<std::uint32_t> free_slots;
  std::size_t always_count = 0;
  // The static set, by slot.
  std::vector<Proxy*> static_proxy;
  std::size_t static_live = 0;
  std::size_t static_members = 0;  // proxies that belong to the static set, in it or not

  // Slots whose occupant changed since the last successful frame (file comment).
  std::vector<std::uint8_t> moving_changed, static_changed;
  std::vector<std::uint32_t> moving_changed_list, static_changed_list;
  // Moving slots whose box changed since the last successful frame, for FrameInput::moved: a body
  // at rest then costs the detector nothing, not even a compare. Incomplete (no list given) after
  // a renumbering or a reset, until the next successful frame.
  std::vector<std::uint32_t> moved;
  std::vector<std::uint8_t> moved_flag;
  bool moved_complete = false;
  bool resync = false;        // compare the whole cache with the next frame's pairs
  bool queries_stale = true;  // the last frame does not describe the proxies as they are now

  std::optional<Camera> camera;
  std::span<const std::uint32_t> id_map;
  int id_map_width = 0, id_map_height = 0;

  FrameResult frame;
  FrameStats stats;
  Status status;
  int next_uid = 0;
  std::vector<std::uint32_t> hits;
  std::vector<std::pair<btBroadphaseProxy*, btBroadphaseProxy*>> stale_pairs;
  std::unordered_set<std::uint64_t> want, have;

  State(const Config& c, btOverlappingPairCache* user_cache) : config(c) {
    config.contact_events = true;
    detector = make_cpu_detector(config);
    if (user_cache) {
      cache = user_cache;
    } else {
      owned_cache = std::make_unique<btHashedOverlappingPairCache>();
      cache = owned_cache.get();
    }
  }

  void mark_moving(std::uint32_t s) {
    if (moving_changed.size() <= s) moving_changed.resize(s + 1, 0);
    if (moving_changed[s]) return;
    moving_changed[s] = 1;
    moving_changed_list.push_back(s);
  }
  void note_moved(std::uint32_t s) {
    if (moved_flag.size() <= s) moved_flag.resize(s + 1, 0);
    if (moved_flag[s]) return;
    moved_flag[s] = 1;
    moved.push_back(s);
  }
  void clear_moved(bool complete) {
    for (const std::uint32_t s : moved)
      if (s < moved_flag.size()) moved_flag[s] = 0;
    moved.clear();
    moved_complete = complete;
  }
  void mark_static(std::uint32_t k) {
    if (static_changed.size() <= k) static_changed.resize(k + 1, 0);
    if (static_changed[k]) return;
    static_changed[k] = 1;
    static_changed_list.push_back(k);
  }
  void clear_changed() {
    for (const std::uint32_t s : moving_changed_list) moving_changed[s] = 0;
    for (const std::uint32_t k : static_changed_list) static_changed[k] = 0;
    moving_changed_list.clear();
    static_changed_list.clear();
  }
  [[nodiscard]] bool index_changed(std::uint32_t index) const {
    if (is_static_index(index)) {
      const std::uint32_t k = static_slot(index);
      return k < static_changed.size() && static_changed[k];
    }
    return index < moving_changed.size() && moving_changed[index];
  }
  [[nodiscard]] Proxy* proxy_of(std::uint32_t index) const {
    if (is_static_index(index)) {
      const std::uint32_t k = static_slot(index);
      return k < static_proxy.size() ? static_proxy[k] : nullptr;
    }
    return index < slot_proxy.size() ? slot_proxy[index] : nullptr;
  }

  void enter_static(Proxy* p) {
    Result<std::uint32_t> k = detector->add_static_box(p->box, filter_of(*p));
    if (!k) {  // not expected: the box is valid and the set holds boxes only
      status = k.status();
      return;
    }
    p->slot = k.value();
    if (static_proxy.size() <= p->slot) static_proxy.resize(p->slot + 1, nullptr);
    static_proxy[p->slot] = p;
    ++static_live;
    mark_static(p->slot);
  }
  void leave_static(Proxy* p) {
    if (p->slot == kNoSlot) return;
    if (Status s = detector->remove_static(p->slot); !s) status = s;
    static_proxy[p->slot] = nullptr;
    --static_live;
    mark_static(p->slot);
    p->slot = kNoSlot;
  }

  void take_moving_slot(Proxy* p) {
    std::uint32_t s;
    if (!free_slots.empty()) {
      s = free_slots.back();
      free_slots.pop_back();
    } else {
      s = static_cast<std::uint32_t>(slot_proxy.size());
      slot_proxy.push_back(nullptr);
      boxes.emplace_back();
      filters.push_back(kNeverPairs);
      always_active.push_back(0);
    }
    p->slot = s;
    slot_proxy[s] = p;
    boxes[s] = p->valid ? p->box : Box{};
    filters[s] = p->valid ? filter_of(*p) : kNeverPairs;
    mark_moving(s);
    note_moved(s);
  }
  void release_moving_slot(Proxy* p) {
    const std::uint32_t s = p->slot;
    slot_proxy[s] = nullptr;
    boxes[s] = point_box(boxes[s]);
    filters[s] = kNeverPairs;
    if (always_active[s]) --always_count;
    always_active[s] = 0;
    free_slots.push_back(s);
    mark_moving(s);
    note_moved(s);
  }

  // Renumbers the moving slots densely when holes outnumber live proxies (their point boxes cost
  // the broadphase for nothing). The next frame's events then compare different numberings, so
  // that frame is applied by the full comparison.
  void compact_if_sparse() {
    const std::size_t holes = free_slots.size(), live = slot_proxy.size() - holes;
    if (holes <= 64 || holes <= live) return;
    std::size_t next = 0;
    for (std::size_t s = 0; s < slot_proxy.size(); ++s) {
      Proxy* p = slot_proxy[s];
      if (!p) continue;
      slot_proxy[next] = p;
      boxes[next] = boxes[s];
      filters[next] = filters[s];
      always_active[next] = always_active[s];
      p->slot = static_cast<std::uint32_t>(next++);
    }
    slot_proxy.resize(next);
    boxes.resize(next);
    filters.resize(next);
    always_active.resize(next);
    free_slots.clear();
    for (const std::uint32_t s : moving_changed_list)
      if (s < moving_changed.size()) moving_changed[s] = 0;
    moving_changed_list.clear();
    moving_changed.assign(next, 0);
    clear_moved(false);
    moved_flag.clear();
    resync = true;
    queries_stale = true;
  }

  void add_if_missing(Proxy* a, Proxy* b) {
    if (!cache->findPair(a, b)) cache->addOverlappingPair(a, b);
  }

  // Makes the cache hold exactly this frame's pairs (as far as its filter callback lets them in).
  void compare_whole_cache(btDispatcher* dispatcher) {
    want.clear();
    have.clear();
    for (const Pair& q : frame.pairs) {
      Proxy *a = proxy_of(q.i), *b = proxy_of(q.j);
      if (a && b) want.insert(pair_key(a, b));
    }
    btBroadphasePairArray& array = cache->getOverlappingPairArray();
    if (cache->hasDeferredRemoval()) {
      // As btAxisSweep3::calculateOverlappingPairs: clean the pairs to go, null their proxies,
      // sort them to the end and cut them off.
      int removed = 0;
      for (int c = 0; c < array.size(); ++c) {
        btBroadphasePair& pair = array[c];
        const bool keep = pair.m_pProxy0 && pair.m_pProxy1 && want.count(pair_key(pair.m_pProxy0, pair.m_pProxy1)) &&
                          have.insert(pair_key(pair.m_pProxy0, pair.m_pProxy1)).second;
        if (keep) continue;
        cache->cleanOverlappingPair(pair, dispatcher);
        pair.m_pProxy0 = nullptr;
        pair.m_pProxy1 = nullptr;
        ++removed;
      }
      if (removed > 0) {
        array.quickSort(btBroadphasePairSortPredicate());
        array.resize(array.size() - removed);
      }
    } else {
      stale_pairs.clear();
      for (int c = 0; c < array.size(); ++c) {
        const btBroadphasePair& pair = array[c];
        const std::uint64_t key = pair_key(pair.m_pProxy0, pair.m_pProxy1);
        if (want.count(key))
          have.insert(key);
        else
          stale_pairs.emplace_back(pair.m_pProxy0, pair.m_pProxy1);
      }
      for (const auto& [a, b] : stale_pairs) cache->removeOverlappingPair(a, b, dispatcher);
    }
    for (const Pair& q : frame.pairs) {
      Proxy *a = proxy_of(q.i), *b = proxy_of(q.j);
      if (a && b && !have.count(pair_key(a, b))) cache->addOverlappingPair(a, b);
    }
  }

  void apply_events(btDispatcher* dispatcher) {
    for (const Pair& q : frame.ended) {
      if (index_changed(q.i) || index_changed(q.j)) continue;  // the old occupant's pairs went with it
      Proxy *a = proxy_of(q.i), *b = proxy_of(q.j);
      if (a && b) cache->removeOverlappingPair(a, b, dispatcher);
    }
    for (const Pair& q : frame.began) {
      if (index_changed(q.i) || index_changed(q.j)) continue;  // below
      Proxy *a = proxy_of(q.i), *b = proxy_of(q.j);
      if (a && b) cache->addOverlappingPair(a, b);
    }
    if (moving_changed_list.empty() && static_changed_list.empty()) return;
    // A new occupant's pairs: those of this frame that name its slot, whether or not the events
    // call them new (a pair of the old occupant may have had the same indices).
    for (const Pair& q : frame.pairs) {
      if (!index_changed(q.i) && !index_changed(q.j)) continue;
      Proxy *a = proxy_of(q.i), *b = proxy_of(q.j);
      if (a && b) add_if_missing(a, b);
    }
  }

  [[nodiscard]] bool frame_answers_queries() const { return !queries_stale && status.ok(); }

  // Moving proxies the last frame culled: invisible to the detector's queries, seen by ours.
  template <class Test, class Visit>
  void visit_culled(Test&& test, Visit&& visit) const {
    if (frame.stats.active == frame.stats.objects) return;
    for (std::size_t s = 0; s < frame.state.size() && s < slot_proxy.size(); ++s) {
      Proxy* p = slot_proxy[s];
      if (frame.state[s] == ObjectState::culled && p && p->valid && test(p->box)) visit(p);
    }
  }
};

BulletBroadphase::BulletBroadphase() : BulletBroadphase(Config{}, nullptr) {}
BulletBroadphase::BulletBroadphase(btOverlappingPairCache* pair_cache) : BulletBroadphase(Config{}, pair_cache) {}
BulletBroadphase::BulletBroadphase(const Config& config, btOverlappingPairCache* pair_cache)
    : state_(std::make_unique<State>(config, pair_cache)) {}

BulletBroadphase::~BulletBroadphase() {
  for (Proxy* p : state_->proxies) delete p;
}

bool BulletBroadphase::goes_to_static_set(int collision_filter_group, int collision_filter_mask) {
  const auto g = static_cast<std::uint32_t>(collision_filter_group);
  const auto m = static_cast<std::uint32_t>(collision_filter_mask);
  const auto fixed = static_cast<std::uint32_t>(btBroadphaseProxy::StaticFilter);
  const auto kinematic = static_cast<std::uint32_t>(btBroadphaseProxy::KinematicFilter);
  // Two members a, b: g_a & m_b needs the kinematic bit in g_a and m_b (no mask has the static
  // bit), and then g_b & m_a needs it in g_b and m_a, but a group with it has a mask without it.
  return g != 0 && (g & ~kStaticBits) == 0 && (m & fixed) == 0 && ((g & kinematic) == 0 || (m & kinematic) == 0);
}

btBroadphaseProxy* BulletBroadphase::createProxy(const btVector3& aabbMin, const btVector3& aabbMax, int /*shapeType*/,
                                                 void* userPtr, int collisionFilterGroup, int collisionFilterMask,
                                                 btDispatcher* /*dispatcher*/) {
  State& st = *state_;
  auto* p = new Proxy(aabbMin, aabbMax, userPtr, collisionFilterGroup, collisionFilterMask);
  p->m_uniqueId = ++st.next_uid;
  p->list_index = static_cast<std::uint32_t>(st.proxies.size());
  st.proxies.push_back(p);
  p->valid = to_box(aabbMin, aabbMax, p->box);
  p->fixed = goes_to_static_set(collisionFilterGroup, collisionFilterMask);
  if (p->fixed) {
    ++st.static_members;
    if (p->valid) st.enter_static(p);
  } else {
    st.take_moving_slot(p);
  }
  st.queries_stale = true;
  return p;
}

void BulletBroadphase::destroyProxy(btBroadphaseProxy* proxy, btDispatcher* dispatcher) {
  State& st = *state_;
  Proxy* p = as_proxy(proxy);
  st.cache->removeOverlappingPairsContainingProxy(p, dispatcher);
  if (p->fixed) {
    st.leave_static(p);
    --st.static_members;
  } else {
    st.release_moving_slot(p);
  }
  Proxy* last = st.proxies.back();
  st.proxies[p->list_index] = last;
  last->list_index = p->list_index;
  st.proxies.pop_back();
  delete p;
  st.queries_stale = true;
}

void BulletBroadphase::setAabb(btBroadphaseProxy* proxy, const btVector3& aabbMin, const btVector3& aabbMax,
                               btDispatcher* dispatcher) {
  State& st = *state_;
  Proxy* p = as_proxy(proxy);
  p->m_aabbMin = aabbMin;
  p->m_aabbMax = aabbMax;
  Box box;
  const bool valid = to_box(aabbMin, aabbMax, box);
  if (valid == p->valid && (!valid || same_box(box, p->box))) return;  // resting bodies cost nothing
  const bool was_valid = p->valid;
  p->valid = valid;
  if (valid) p->box = box;
  st.queries_stale = true;
  if (p->fixed) {
    if (valid && was_valid) {
      if (Status s = st.detector->move_static_box(p->slot, box); !s) st.status = s;
    } else if (valid) {
      st.enter_static(p);
    } else {
      // Its slot counts as changed, so the events will not end its pairs: remove them now.
      st.cache->removeOverlappingPairsContainingProxy(p, dispatcher);
      st.leave_static(p);
    }
  } else {
    st.boxes[p->slot] = valid ? box : point_box(st.boxes[p->slot]);
    st.filters[p->slot] = valid ? filter_of(*p) : kNeverPairs;
    st.note_moved(p->slot);
  }
}

void BulletBroadphase::getAabb(btBroadphaseProxy* proxy, btVector3& aabbMin, btVector3& aabbMax) const {
  aabbMin = proxy->m_aabbMin;
  aabbMax = proxy->m_aabbMax;
}

void BulletBroadphase::calculateOverlappingPairs(btDispatcher* dispatcher) {
  State& st = *state_;
  st.compact_if_sparse();
  // Filters are read every frame, so that a moving proxy's group or mask edited in place counts.
  for (std::size_t s = 0; s < st.slot_proxy.size(); ++s)
    if (const Proxy* p = st.slot_proxy[s]) st.filters[s] = p->valid ? filter_of(*p) : kNeverPairs;

  FrameInput in;
  in.boxes = st.boxes;
  in.filters = st.filters;
  if (st.always_count > 0) in.always_active = st.always_active;
  if (st.camera) in.camera = &*st.camera;
  if (!st.id_map.empty()) {
    in.id_map = st.id_map;
    in.id_map_width = st.id_map_width;
    in.id_map_height = st.id_map_height;
  }
  if (st.moved_complete) {
    std::sort(st.moved.begin(), st.moved.end());
    in.moved = st.moved;
    in.moved_listed = true;
  }
  st.status = st.detector->detect(in, st.frame);
  if (!st.status) {
    st.queries_stale = true;
    return;  // the cache stays as it was; the slots' changes wait for the next good frame
  }
  st.clear_moved(true);
  st.stats = st.frame.stats;
  if (st.resync || st.cache->hasDeferredRemoval()) {
    st.compare_whole_cache(dispatcher);
    st.resync = false;
  } else {
    st.apply_events(dispatcher);
  }
  st.clear_changed();
  st.queries_stale = false;
}

btOverlappingPairCache* BulletBroadphase::getOverlappingPairCache() { return state_->cache; }
const btOverlappingPairCache* BulletBroadphase::getOverlappingPairCache() const { return state_->cache; }

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
  st.hits.clear();
  CollectHits collect(st.hits);
  st.detector->ray_cast(ray, collect);
  // Collected first and called after: the callback may then use the broadphase again.
  std::vector<Proxy*> found;
  found.reserve(st.hits.size());
  for (const std::uint32_t index : st.hits)
    if (Proxy* p = st.proxy_of(index); p && p->valid) found.push_back(p);
  st.visit_culled(hit, [&](Proxy* p) { found.push_back(p); });
  for (Proxy* p : found) rayCallback.process(p);
}

void BulletBroadphase::aabbTest(const btVector3& aabbMin, const btVector3& aabbMax,
                                btBroadphaseAabbCallback& callback) {
  State& st = *state_;
  Box query;
  if (!to_box(aabbMin, aabbMax, query)) return;
  const auto overlaps = [&](const Box& box) { return boxes_overlap(box, query); };
  std::vector<Proxy*> found;
  if (!st.frame_answers_queries()) {
    for (Proxy* p : st.proxies)
      if (p->valid && overlaps(p->box)) found.push_back(p);
  } else {
    st.detector->overlap_box(query, st.hits);
    found.reserve(st.hits.size());
    for (const std::uint32_t index : st.hits)
      if (Proxy* p = st.proxy_of(index); p && p->valid) found.push_back(p);
    st.visit_culled(overlaps, [&](Proxy* p) { found.push_back(p); });
  }
  for (Proxy* p : found) callback.process(p);
}

void BulletBroadphase::getBroadphaseAabb(btVector3& aabbMin, btVector3& aabbMax) const {
  const State& st = *state_;
  if (st.proxies.empty()) {
    aabbMin.setValue(0, 0, 0);
    aabbMax.setValue(0, 0, 0);
    return;
  }
  aabbMin = st.proxies.front()->m_aabbMin;
  aabbMax = st.proxies.front()->m_aabbMax;
  for (const Proxy* p : st.proxies) {
    aabbMin.setMin(p->m_aabbMin);
    aabbMax.setMax(p->m_aabbMax);
  }
}

void BulletBroadphase::resetPool(btDispatcher* /*dispatcher*/) {
  State& st = *state_;
  if (!st.proxies.empty()) return;
  st.boxes = {};
  st.filters = {};
  st.always_active = {};
  st.slot_proxy = {};
  st.free_slots = {};
  st.static_proxy = {};
  st.moving_changed = {};
  st.static_changed = {};
  st.clear_moved(false);
  st.moved_flag = {};
  st.moving_changed_list.clear();
  st.static_changed_list.clear();
  st.always_count = 0;
  st.static_live = 0;
  st.static_members = 0;
  st.detector->clear_static();
  st.detector->reset_events();
  st.frame = FrameResult{};
  st.resync = false;
  st.queries_stale = true;
  st.next_uid = 0;
}

void BulletBroadphase::printStats() {
  const State& st = *state_;
  std::printf("viscd::BulletBroadphase: %zu proxies (%zu static), %zu moving slots (%zu free), %llu pairs, %.3f ms\n",
              st.proxies.size(), st.static_live, st.slot_proxy.size(), st.free_slots.size(),
              static_cast<unsigned long long>(st.stats.pairs), st.stats.total_ms());
}

void BulletBroadphase::set_camera(const Camera* camera) {
  if (camera)
    state_->camera = *camera;
  else
    state_->camera.reset();
}

void BulletBroadphase::set_id_map(std::span<const std::uint32_t> ids, int width, int height) {
  state_->id_map = ids;
  state_->id_map_width = width;
  state_->id_map_height = height;
}

void BulletBroadphase::set_always_active(btBroadphaseProxy* proxy, bool always_active) {
  State& st = *state_;
  const Proxy* p = as_proxy(proxy);
  if (p->fixed) return;  // never culled
  std::uint8_t& flag = st.always_active[p->slot];
  if (flag == static_cast<std::uint8_t>(always_active)) return;
  flag = always_active ? 1 : 0;
  if (always_active)
    ++st.always_count;
  else
    --st.always_count;
}

std::optional<std::uint32_t> BulletBroadphase::moving_index(const btBroadphaseProxy* proxy) const {
  const State& st = *state_;
  const Proxy* p = as_proxy(proxy);
  if (!p || p->fixed || p->slot >= st.slot_proxy.size() || st.slot_proxy[p->slot] != p) return std::nullopt;
  return p->slot;
}

bool BulletBroadphase::in_static_set(const btBroadphaseProxy* proxy) const {
  const Proxy* p = as_proxy(proxy);
  return p && p->fixed && p->slot != kNoSlot;
}

std::size_t BulletBroadphase::proxy_count() const { return state_->proxies.size(); }
std::size_t BulletBroadphase::static_proxy_count() const { return state_->static_live; }
std::size_t BulletBroadphase::moving_slots() const { return state_->slot_proxy.size(); }
const Status& BulletBroadphase::last_status() const { return state_->status; }
const FrameStats& BulletBroadphase::last_stats() const { return state_->stats; }
const Config& BulletBroadphase::config() const { return state_->config; }

void BulletBroadphase::set_config(const Config& config) {
  state_->config = config;
  state_->config.contact_events = true;
  state_->detector->set_config(state_->config);
}

}  // namespace viscd
