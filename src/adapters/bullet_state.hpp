#pragma once
// viscd::BulletBroadphase's inside (bullet_broadphase.cpp, bullet_queries.cpp): the proxy, its
// box and filter, and State, which keeps the slots, the static set, the frame and the pair
// cache in step. The rules of ids and slots are bullet_broadphase.cpp's opening comment.

#include "viscd/bullet.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <memory>
#include <new>
#include <type_traits>
#include <unordered_set>
#include <utility>
#include <vector>

#include "adapter_util.hpp"
#include "viscd/assert.hpp"
#include "viscd/detector.hpp"

namespace viscd {
namespace bullet_impl {

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

// Proxies made in cells of two cache lines, in slabs, in the order they are made (a destroyed
// one's cell is reused first). A world passes its objects' AABBs in the order it made them, so
// the proxies' memory streams past setAabb() instead of costing a miss or two per proxy (made
// one by one with new, the 10 000 proxies of a world at rest cost 0.2-0.3 ms a step).
class ProxyPool {
 public:
  ProxyPool() = default;
  ProxyPool(const ProxyPool&) = delete;
  ProxyPool& operator=(const ProxyPool&) = delete;
  ~ProxyPool() = default;  // the cells' proxies are destroyed by their owner first

  template <class... Args>
  Proxy* make(Args&&... args) {
    void* at = nullptr;
    if (!free_.empty()) {
      at = free_.back();
      free_.pop_back();
    } else {
      if (used_ == slabs_.size() * kSlab) slabs_.push_back(std::make_unique<Slab>());
      at = &slabs_[used_ / kSlab]->cells[used_ % kSlab];
      ++used_;
    }
    return new (at) Proxy(std::forward<Args>(args)...);
  }
  void release(Proxy* p) {
    p->~Proxy();
    free_.push_back(p);
  }
  /// Fetches the proxy made `ahead` after p (when p's slab holds it: the one a world is likely to
  /// pass next) into the cache, both of its lines. A hint only: a wrong guess costs nothing but the
  /// fetch.
  static void prefetch_after(const Proxy* p, std::size_t ahead) {
    const auto* next = reinterpret_cast<const char*>(p) + ahead * sizeof(Cell);
    __builtin_prefetch(next);
    __builtin_prefetch(next + 64);
  }

 private:
  static constexpr std::size_t kSlab = 256;
  struct alignas(64) Cell {
    alignas(64) unsigned char bytes[128];
  };
  static_assert(sizeof(Proxy) <= sizeof(Cell) && alignof(Proxy) <= alignof(Cell));
  struct Slab {
    Cell cells[kSlab];
  };
  std::vector<std::unique_ptr<Slab>> slabs_;
  std::size_t used_ = 0;  // cells handed out at least once, in slab order
  std::vector<void*> free_;
};

inline Proxy* as_proxy(btBroadphaseProxy* p) { return static_cast<Proxy*>(p); }
inline const Proxy* as_proxy(const btBroadphaseProxy* p) { return static_cast<const Proxy*>(p); }

using adapter_detail::round_down;
using adapter_detail::round_up;

// The AABB as a viscd box, clamped to +-kMaxCoordinate (monotone, so no overlap is lost); false
// for a NaN bound or min > max.
inline bool to_box(const btVector3& lo, const btVector3& hi, Box& out) {
  for (int k = 0; k < 3; ++k) {
    if (std::isnan(lo[k]) || std::isnan(hi[k])) return false;
    out.min[k] = std::clamp(round_down(lo[k]), -kMaxCoordinate, kMaxCoordinate);
    out.max[k] = std::clamp(round_up(hi[k]), -kMaxCoordinate, kMaxCoordinate);
    if (out.min[k] > out.max[k]) return false;
  }
  return true;
}

// Whether two vectors hold the same three scalars bit for bit (a NaN equals itself; the fourth,
// unused, is not read).
inline bool same_floats(const btVector3& a, const btVector3& b) {
  return std::memcmp(a.m_floats, b.m_floats, 3 * sizeof(btScalar)) == 0;
}

inline bool same_box(const Box& a, const Box& b) {
  for (int k = 0; k < 3; ++k)
    if (a.min[k] != b.min[k] || a.max[k] != b.max[k]) return false;
  return true;
}

inline Box point_box(const Box& around) {
  Box b;
  for (int k = 0; k < 3; ++k) b.min[k] = b.max[k] = around.min[k] + 0.5f * (around.max[k] - around.min[k]);
  return b;
}

inline Filter filter_of(const btBroadphaseProxy& p) {
  return {static_cast<std::uint32_t>(p.m_collisionFilterGroup), static_cast<std::uint32_t>(p.m_collisionFilterMask)};
}

inline std::uint64_t pair_key(const btBroadphaseProxy* a, const btBroadphaseProxy* b) {
  auto ua = static_cast<std::uint32_t>(a->m_uniqueId), ub = static_cast<std::uint32_t>(b->m_uniqueId);
  if (ua > ub) std::swap(ua, ub);
  return (std::uint64_t{ua} << 32) | ub;
}

// The segment from + t (to - from), 0 <= t <= 1, against `box` grown by -sweep_max / -sweep_min
// (the Minkowski sum with the swept AABB, as btDbvt::rayTestInternal grows its nodes), in double.
inline bool swept_box_hit(const btVector3& from, const btVector3& to, const btVector3& sweep_min,
                          const btVector3& sweep_max, const Box& box) {
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
}  // namespace bullet_impl

using namespace bullet_impl;  // NOLINT(google-build-using-namespace): the adapter's own helpers

struct BulletBroadphase::State {
  Config config;
  std::unique_ptr<Detector> detector;
  btOverlappingPairCache* cache = nullptr;
  std::unique_ptr<btHashedOverlappingPairCache> owned_cache;

  ProxyPool pool;               // where the proxies live
  std::vector<Proxy*> proxies;  // every live proxy, unordered
  // The moving frame, by slot.
  std::vector<Box> boxes;
  std::vector<Filter> filters;  // written through set_filter()
  std::size_t odd_filters = 0;  // slots whose filter is not Filter{} (Bullet's default group and mask)
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
  std::unordered_set<const btBroadphaseProxy*> owned;   // every live proxy of this broadphase
  adapter_detail::VectorPool<std::uint32_t> hit_lists;  // the queries' lists, lent per call
  adapter_detail::VectorPool<Proxy*> proxy_lists;
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

  // The static set's calls below cannot fail for what the adapter passes (a valid box, to a set
  // of boxes only, far fewer than 2^31 - 1 of them); only an allocation can, and it throws
  // std::bad_alloc as Bullet's own do. So they are invariants, asserted, not errors to report.
  void enter_static(Proxy* p) {
    Result<std::uint32_t> k = detector->add_static_box(p->box, filter_of(*p));
    VISCD_ASSERT(k.ok(), "the static set refused a valid box");
    if (!k) return;  // (asserts off) the proxy stays out of the set: slot kNoSlot, no pairs
    p->slot = k.value();
    if (static_proxy.size() <= p->slot) static_proxy.resize(p->slot + 1, nullptr);
    static_proxy[p->slot] = p;
    ++static_live;
    mark_static(p->slot);
  }
  // False (asserts off) when the set refused: the caller then takes the proxy out of the set, so
  // that the detector never holds a box the proxy no longer has.
  [[nodiscard]] bool move_static(Proxy* p) {
    const Status s = detector->move_static_box(p->slot, p->box);
    VISCD_ASSERT(s.ok(), "the static set refused to move a valid box");
    return s.ok();
  }
  void leave_static(Proxy* p) {
    if (p->slot == kNoSlot) return;
    [[maybe_unused]] const Status s = detector->remove_static(p->slot);
    VISCD_ASSERT(s.ok(), "the static set refused to remove a live slot");
    static_proxy[p->slot] = nullptr;
    --static_live;
    mark_static(p->slot);
    p->slot = kNoSlot;
  }
  // Whether `proxy` is one of this broadphase's (checked before it is read as a Proxy).
  [[nodiscard]] bool owns(const btBroadphaseProxy* proxy) const { return proxy && owned.count(proxy) != 0; }

  // Slot s's filter, counted when it is not the default: a frame whose moving filters are all
  // Filter{} is given none (the same rule, and the detector's unfiltered passes).
  static bool is_default(const Filter& f) { return f.group == Filter{}.group && f.mask == Filter{}.mask; }
  void set_filter(std::uint32_t s, const Filter& f) {
    Filter& at = filters[s];
    odd_filters += static_cast<std::size_t>(!is_default(f)) - static_cast<std::size_t>(!is_default(at));
    at = f;
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
      ++odd_filters;
      always_active.push_back(0);
    }
    p->slot = s;
    slot_proxy[s] = p;
    boxes[s] = p->valid ? p->box : Box{};
    set_filter(s, p->valid ? filter_of(*p) : kNeverPairs);
    mark_moving(s);
    note_moved(s);
  }
  void release_moving_slot(Proxy* p) {
    const std::uint32_t s = p->slot;
    slot_proxy[s] = nullptr;
    boxes[s] = point_box(boxes[s]);
    set_filter(s, kNeverPairs);
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
    odd_filters = static_cast<std::size_t>(
        std::count_if(filters.begin(), filters.end(), [](const Filter& f) { return !is_default(f); }));
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

}  // namespace viscd
