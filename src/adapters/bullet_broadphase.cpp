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

#include "bullet_state.hpp"

namespace viscd {

BulletBroadphase::BulletBroadphase() : BulletBroadphase(default_config(), nullptr) {}
BulletBroadphase::BulletBroadphase(btOverlappingPairCache* pair_cache)
    : BulletBroadphase(default_config(), pair_cache) {}

Config BulletBroadphase::default_config() {
  Config c;
  c.rest_margin = 0.05f;  // btDbvtBroadphase's DBVT_BP_MARGIN
  return c;
}
BulletBroadphase::BulletBroadphase(const Config& config, btOverlappingPairCache* pair_cache)
    : state_(std::make_unique<State>(config, pair_cache)) {}

BulletBroadphase::~BulletBroadphase() {
  for (Proxy* p : state_->proxies) state_->pool.release(p);
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
  Proxy* p = st.pool.make(aabbMin, aabbMax, userPtr, collisionFilterGroup, collisionFilterMask);
  p->m_uniqueId = ++st.next_uid;
  p->list_index = static_cast<std::uint32_t>(st.proxies.size());
  st.proxies.push_back(p);
  st.owned.insert(p);
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
  st.owned.erase(p);
  st.pool.release(p);
  st.queries_stale = true;
}

void BulletBroadphase::setAabb(btBroadphaseProxy* proxy, const btVector3& aabbMin, const btVector3& aabbMax,
                               btDispatcher* dispatcher) {
  State& st = *state_;
  Proxy* p = as_proxy(proxy);
  // A world passes its objects' AABBs in the order it made them, which is the pool's: the proxies
  // it passes next are fetched while it computes their AABBs (each proxy's second line, read
  // below, had missed the cache for every body of a large world, at rest or not).
  ProxyPool::prefetch_after(p, 4);
  // A body Bullet did not move passes the very floats it passed last time: nothing to convert or
  // compare (the proxy's box and validity were made from them).
  if (same_floats(p->m_aabbMin, aabbMin) && same_floats(p->m_aabbMax, aabbMax)) {
    if (p->valid && !p->fixed) st.set_filter(p->slot, filter_of(*p));  // see below
    return;
  }
  p->m_aabbMin = aabbMin;
  p->m_aabbMax = aabbMax;
  Box box;
  const bool valid = to_box(aabbMin, aabbMax, box);
  if (valid == p->valid && (!valid || same_box(box, p->box))) {  // resting bodies cost nothing more
    // A moving proxy's group and mask are read here, where the proxy is at hand, so that editing
    // them in place counts from the next frame (a pass over every proxy for them had cost more
    // than the frame of a world at rest).
    if (valid && !p->fixed) st.set_filter(p->slot, filter_of(*p));
    return;
  }
  const bool was_valid = p->valid;
  p->valid = valid;
  if (valid) p->box = box;
  st.queries_stale = true;
  if (p->fixed) {
    if (valid && was_valid && p->slot != kNoSlot) {
      if (!st.move_static(p)) {  // not expected (see State::enter_static): out of the set, no pairs
        st.cache->removeOverlappingPairsContainingProxy(p, dispatcher);
        st.leave_static(p);
      }
    } else if (valid) {
      st.enter_static(p);
    } else {
      // Its slot counts as changed, so the events will not end its pairs: remove them now.
      st.cache->removeOverlappingPairsContainingProxy(p, dispatcher);
      st.leave_static(p);
    }
  } else {
    st.boxes[p->slot] = valid ? box : point_box(st.boxes[p->slot]);
    st.set_filter(p->slot, valid ? filter_of(*p) : kNeverPairs);
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

  FrameInput in;
  in.boxes = st.boxes;
  if (st.odd_filters > 0) in.filters = st.filters;  // else every one is Filter{}: none given, the same rule
  if (st.always_count > 0) in.always_active = st.always_active;
  if (st.camera) in.camera = &*st.camera;
  if (!st.id_map.empty()) {
    in.id_map = st.id_map;
    in.id_map_width = st.id_map_width;
    in.id_map_height = st.id_map_height;
  }
  if (st.moved_complete) {
    // Bullet updates its objects in their order, which is the slots' unless proxies came and went.
    if (!std::is_sorted(st.moved.begin(), st.moved.end())) std::sort(st.moved.begin(), st.moved.end());
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
  st.odd_filters = 0;
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
  if (!st.owns(proxy)) return;
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
  if (!st.owns(proxy)) return std::nullopt;  // not read as ours: another broadphase's, or freed
  const Proxy* p = as_proxy(proxy);
  if (!p || p->fixed || p->slot >= st.slot_proxy.size() || st.slot_proxy[p->slot] != p) return std::nullopt;
  return p->slot;
}

bool BulletBroadphase::in_static_set(const btBroadphaseProxy* proxy) const {
  if (!state_->owns(proxy)) return false;
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
