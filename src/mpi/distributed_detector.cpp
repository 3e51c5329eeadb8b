// DistributedDetector: regions, ghosts, the local frame and the ownership rule (docs/mpi.md).
#include <algorithm>
#include <climits>
#include <cstdint>
#include <cstring>
#include <new>
#include <numeric>
#include <string>
#include <type_traits>
#include <unordered_map>
#include <vector>

#include "core/geometry.hpp"
#include "core/stopwatch.hpp"
#include "cpu/parallel.hpp"
#include "mpi/comm.hpp"
#include "mpi/global_ids.hpp"
#include "viscd/assert.hpp"
#include "viscd/mpi.hpp"

namespace viscd::mpi {
namespace {

using viscd::detail::Aabb;
using viscd::detail::overlaps;

/// What a rank holds; `none` for a rank without objects of that role.
enum class Kind : std::uint8_t { none = 0, sphere = 1, box = 2 };

const char* kind_name(Kind k) { return k == Kind::sphere ? "spheres" : "boxes"; }

/// An object as it travels to another rank: its shape, global id and filter.
template <class Shape>
struct Record;
template <>
struct Record<Sphere> {
  Sphere shape;
  std::uint64_t id = 0;
  Filter filter;
};
template <>
struct Record<Box> {
  Box shape;
  std::uint64_t id = 0;
  Filter filter;
};
static_assert(sizeof(Record<Sphere>) == 32 && sizeof(Record<Box>) == 40);

/// The box the exchange tests for an object: for a box the box; for a sphere its box widened by
/// the rank's `margin` (widen()), which holds the conservative box the trees use
/// (viscd::detail::conservative_box()): every sphere the float overlap test can accept with it
/// meets that box, so a rank whose region misses it holds nothing the object overlaps.
Aabb bounds(const Sphere& s, float margin) {
  const float h = s.r + margin;
  return Aabb{{s.x - h, s.y - h, s.z - h}, {s.x + h, s.y + h, s.z + h}};
}
Aabb bounds(const Box& b, float) { return Aabb{{b.min[0], b.min[1], b.min[2]}, {b.max[0], b.max[1], b.max[2]}}; }

/// The margin for a rank's spheres whose plain boxes (c +- r) span `raw` with radii up to `rmax`:
/// conservative_half_extent() adds at most (|c| + r) 2^-19 + 1e-21 to r; four times that (2^-17)
/// also covers the roundings of c +- r and of the sums here.
float widen(const Aabb& raw, float rmax) {
  const float m = std::max({std::fabs(raw.lo.x), std::fabs(raw.lo.y), std::fabs(raw.lo.z), std::fabs(raw.hi.x),
                            std::fabs(raw.hi.y), std::fabs(raw.hi.z)});
  return (m + rmax) * 0x1p-17f + 1e-20f;
}

bool same_bits(const Sphere& a, const Sphere& b) { return std::memcmp(&a, &b, sizeof a) == 0; }
bool same_bits(const Box& a, const Box& b) { return std::memcmp(&a, &b, sizeof a) == 0; }

/// What every rank tells every other at the start of a frame.
struct Header {
  Aabb region;  ///< the box around this rank's moving objects' bounds() (empty when it has none)
  std::uint32_t moving = 0, statics = 0;
  Kind moving_kind = Kind::none, static_kind = Kind::none;
  std::uint8_t ids_changed = 0;  ///< this rank's ids (moving or static) differ from its last frame's
  std::uint8_t has_filters = 0;  ///< this rank gives filters (moving or static)
};
static_assert(sizeof(Header) == 36);

/// A static object of another rank, held in the local detector's static set.
struct GhostStatic {
  std::uint32_t slot = 0;
  Filter filter;
  Sphere sphere;
  Box box;
  bool seen = false;
};

/// What a frame needs to know of a rank's ids without keeping a copy: whether they count up
/// (first, first + 1, ...; then pairs need no lookup) and, when they do not, a fingerprint that
/// tells a changed list from last frame's (a 64-bit sum of mixed (index, id): a change that keeps
/// it has odds of 2^-64, and would only skip one repeat check, never change a pair).
struct IdSummary {
  std::size_t count = 0;
  bool consecutive = true;
  std::uint64_t first = 0;
  std::uint64_t fingerprint = 0;
  [[nodiscard]] bool same(const IdSummary& o) const {
    if (count != o.count || consecutive != o.consecutive) return false;
    return consecutive ? first == o.first : fingerprint == o.fingerprint;
  }
};

/// One pass over the ids, in parallel chunks.
IdSummary summarise(std::span<const std::uint64_t> ids, int threads) {
  IdSummary sum;
  sum.count = ids.size();
  sum.first = ids.empty() ? 0 : ids[0];
  const std::size_t chunks = viscd::detail::ranges_for(ids.size(), threads);
  std::vector<std::uint64_t> prints(chunks, 0);
  std::vector<std::uint8_t> counting(chunks, 1);
  // First whether they count up (a compare per id); the fingerprint only when they do not.
  viscd::detail::for_chunks(ids.size(), chunks, [&](std::size_t b, std::size_t e, std::size_t c) {
    bool up = true;
    for (std::size_t i = b; i < e; ++i) up &= ids[i] == sum.first + i;
    counting[c] = up;
  });
  for (std::size_t c = 0; c < chunks; ++c) sum.consecutive = sum.consecutive && counting[c] != 0;
  if (sum.consecutive) return sum;
  viscd::detail::for_chunks(ids.size(), chunks, [&](std::size_t b, std::size_t e, std::size_t c) {
    std::uint64_t f = 0;
    for (std::size_t i = b; i < e; ++i) f += detail::mix64(ids[i] ^ detail::mix64(i));
    prints[c] = f;
  });
  for (std::size_t c = 0; c < chunks; ++c) sum.fingerprint += prints[c];
  return sum;
}

}  // namespace

struct DistributedDetector::State {
  MPI_Comm comm = MPI_COMM_NULL;
  Status broken;  // why the detector cannot run (MPI not initialized, no communicator)
  int rank = 0, size = 1;
  std::unique_ptr<Detector> local;
  detail::ByteTypes types;

  // This rank's static set as given, and whether the local detector holds it yet.
  Kind static_kind = Kind::none;
  std::vector<Sphere> static_spheres;
  std::vector<Box> static_boxes;
  std::vector<std::uint64_t> static_ids;
  std::vector<Filter> static_filters;
  float static_margin = 0;  // bounds() margin of the static spheres
  Aabb static_region;       // the box around their bounds()
  bool statics_pending = true;
  // The local detector's static set: slots 0..static_ids.size()-1 hold this rank's own, in order;
  // later slots hold other ranks' static objects near this rank's moving ones.
  std::vector<std::uint64_t> slot_id;
  std::unordered_map<std::uint64_t, GhostStatic> ghost_statics;

  // The last frame's ids, to see when they must be checked again.
  IdSummary ids;          // this frame's
  IdSummary checked_ids;  // those of the last frame whose ids passed the check
  bool ids_known = false;

  // The local detector's threads: its executor, or viscd's pool with Config::threads of them.
  Executor* executor = nullptr;
  int threads = 1;

  // Frame buffers, kept for their capacity.
  std::vector<Header> headers;
  float margin = 0;                                                              // this frame's bounds() margin
  std::vector<std::vector<std::uint32_t>> send_index;                            // per rank
  std::vector<std::uint32_t> near;                                               // ranks whose regions meet ours
  std::vector<std::vector<std::pair<std::uint32_t, std::uint32_t>>> chunk_hits;  // (rank, object) per chunk
  std::vector<std::vector<GlobalPair>> chunk_cross;  // kept pairs with a ghost or static object, per chunk
  std::vector<std::size_t> own_count;                // own pairs before each chunk
  std::vector<GlobalPair> cross;
  std::vector<Sphere> spheres;
  std::vector<Box> boxes;
  std::vector<Filter> filters;
  std::vector<std::uint8_t> always_active;
  std::vector<std::uint64_t> ghost_ids;
  FrameResult frame;
};

namespace {

using State = DistributedDetector::State;

/// One pass over a rank's shapes, in parallel chunks: whether every one is valid (finite, within
/// kMaxCoordinate, r >= 0, min <= max; validate_spheres() and validate_boxes() name the first bad
/// one when not), and the box around their bounds(), widened by the sphere margin it returns in
/// `margin`.
template <class Shape>
bool measure(std::span<const Shape> shapes, int threads, Aabb& region, float& margin) {
  const std::size_t chunks = viscd::detail::ranges_for(shapes.size(), threads);
  std::vector<Aabb> part(chunks);
  std::vector<float> rmax(chunks, 0);
  std::vector<std::uint8_t> bad(chunks, 0);
  viscd::detail::for_chunks(shapes.size(), chunks, [&](std::size_t b, std::size_t e, std::size_t c) {
    Aabb a;
    float rm = 0;
    bool wrong = false;
    const auto ok = [](float v) { return v >= -kMaxCoordinate && v <= kMaxCoordinate; };  // false for NaN
    for (std::size_t i = b; i < e; ++i) {
      const Shape& o = shapes[i];
      if constexpr (std::is_same_v<Shape, Sphere>) {
        wrong |= !(ok(o.x) & ok(o.y) & ok(o.z) & ok(o.r) & (o.r >= 0));
        rm = std::max(rm, o.r);
      } else {
        for (int k = 0; k < 3; ++k) wrong |= !(ok(o.min[k]) & ok(o.max[k]) & (o.min[k] <= o.max[k]));
      }
      a.grow(bounds(o, 0));
    }
    part[c] = a;
    rmax[c] = rm;
    bad[c] = wrong;
  });
  Aabb raw;
  float rm = 0;
  bool valid = true;
  for (std::size_t c = 0; c < chunks; ++c) raw.grow(part[c]), rm = std::max(rm, rmax[c]), valid = valid && !bad[c];
  margin = 0;
  region = raw;
  if (!valid || !std::is_same_v<Shape, Sphere> || shapes.empty()) return valid;
  margin = widen(raw, rm);
  region = Aabb{{raw.lo.x - margin, raw.lo.y - margin, raw.lo.z - margin},
                {raw.hi.x + margin, raw.hi.y + margin, raw.hi.z + margin}};
  return true;
}

/// Local checks of one rank's frame, and its header. With one rank the local detector checks the
/// shapes itself (the messages are the same: there are no ghosts), and no region is needed.
template <class Shape>
Status check_input(const State& st, const DistributedInput& in, std::span<const Shape> own, Header& h, float& margin) {
  const std::size_t n = own.size();
  const char* what = std::is_same_v<Shape, Sphere> ? "spheres" : "boxes";
  if (!in.spheres.empty() && !in.boxes.empty())
    return Status::failure(ErrorKind::invalid_input, "a frame holds spheres or boxes, not both");
  if (in.ids.size() != n)
    return Status::failure(ErrorKind::invalid_input, std::to_string(in.ids.size()) + " ids for " + std::to_string(n) +
                                                         " " + what + " (one global id per object)");
  if (!in.filters.empty() && in.filters.size() != n)
    return Status::failure(ErrorKind::invalid_input, std::to_string(in.filters.size()) + " filters for " +
                                                         std::to_string(n) + " " + what + " (none, or one per object)");
  if (!in.always_active.empty() && in.always_active.size() != n)
    return Status::failure(ErrorKind::invalid_input, std::to_string(in.always_active.size()) +
                                                         " always_active flags for " + std::to_string(n) + " " + what +
                                                         " (none, or one per object)");
  h.moving = static_cast<std::uint32_t>(n);
  if (n > 0) h.moving_kind = std::is_same_v<Shape, Sphere> ? Kind::sphere : Kind::box;
  if (st.size == 1) return {};
  if (measure(own, st.threads, h.region, margin)) return {};
  Status s = std::is_same_v<Shape, Sphere> ? validate_spheres(in.spheres) : validate_boxes(in.boxes);
  return s ? Status::failure(ErrorKind::invalid_input, "invalid object (validation disagrees)") : s;
}

/// The kind every rank agrees on (none when no rank holds an object), or the first disagreement.
/// Every rank computes it from the same headers, so every rank fails alike without a message.
Status common_kind(const std::vector<Header>& headers, Kind& kind) {
  kind = Kind::none;
  int from = -1;
  for (std::size_t r = 0; r < headers.size(); ++r)
    for (const Kind k : {headers[r].moving_kind, headers[r].static_kind}) {
      if (k == Kind::none) continue;
      if (kind == Kind::none) {
        kind = k;
        from = static_cast<int>(r);
      } else if (k != kind) {
        return Status::failure(ErrorKind::invalid_input, "rank " + std::to_string(from) + " gives " + kind_name(kind) +
                                                             " and rank " + std::to_string(r) + " " + kind_name(k) +
                                                             ": every rank's moving and static objects must be of one "
                                                             "kind");
      }
    }
  return {};
}

/// Brings the local detector's static set up to date: this rank's own (when they changed) and the
/// static ghosts received this frame (added, moved, removed by global id).
template <class Shape>
Status update_static_set(State& st, std::span<const Record<Shape>> ghosts) {
  Detector& det = *st.local;
  if (st.statics_pending) {
    Status s = std::is_same_v<Shape, Sphere> ? det.set_static_spheres(st.static_spheres, st.static_filters)
                                             : det.set_static_boxes(st.static_boxes, st.static_filters);
    if (!s) return s;
    st.slot_id = st.static_ids;
    st.ghost_statics.clear();
    st.statics_pending = false;
  }
  for (auto& [id, g] : st.ghost_statics) g.seen = false;
  for (const Record<Shape>& rec : ghosts) {
    auto it = st.ghost_statics.find(rec.id);
    if (it != st.ghost_statics.end()) {
      GhostStatic& g = it->second;
      g.seen = true;
      const bool same_filter = g.filter.group == rec.filter.group && g.filter.mask == rec.filter.mask;
      bool same_shape = false;
      if constexpr (std::is_same_v<Shape, Sphere>)
        same_shape = same_bits(g.sphere, rec.shape);
      else
        same_shape = same_bits(g.box, rec.shape);
      if (same_shape && same_filter) continue;
      if (same_filter) {
        Status s;
        if constexpr (std::is_same_v<Shape, Sphere>)
          s = det.move_static_sphere(g.slot, g.sphere = rec.shape);
        else
          s = det.move_static_box(g.slot, g.box = rec.shape);
        if (!s) return s;
        continue;
      }
      if (Status s = det.remove_static(g.slot); !s) return s;
      st.ghost_statics.erase(it);
    }
    Result<std::uint32_t> slot = [&] {
      if constexpr (std::is_same_v<Shape, Sphere>)
        return det.add_static_sphere(rec.shape, rec.filter);
      else
        return det.add_static_box(rec.shape, rec.filter);
    }();
    if (!slot) return slot.status();
    GhostStatic g;
    g.slot = slot.value();
    g.filter = rec.filter;
    if constexpr (std::is_same_v<Shape, Sphere>)
      g.sphere = rec.shape;
    else
      g.box = rec.shape;
    g.seen = true;
    if (st.slot_id.size() <= g.slot) st.slot_id.resize(g.slot + 1);
    st.slot_id[g.slot] = rec.id;
    st.ghost_statics.emplace(rec.id, g);
  }
  for (auto it = st.ghost_statics.begin(); it != st.ghost_statics.end();) {
    if (it->second.seen) {
      ++it;
      continue;
    }
    if (Status s = det.remove_static(it->second.slot); !s) return s;
    it = st.ghost_statics.erase(it);
  }
  return {};
}

/// Which of `shapes` go to which rank: those whose bounds() with `margin` meet that rank's moving
/// region; st.send_index[r] lists them for rank r, ascending. `around` holds every shape's
/// bounds, so only the ranks whose regions meet it are tested (a rank's neighbours, however many
/// ranks there are). On the local detector's threads.
template <class Shape>
void select_ghosts(State& st, std::span<const Shape> shapes, float margin, const Aabb& around) {
  const auto k = static_cast<std::size_t>(st.size);
  st.send_index.resize(k);
  for (auto& v : st.send_index) v.clear();
  st.near.clear();
  Aabb others;  // the box around the near regions: most objects of a rank meet none
  for (std::size_t r = 0; r < k; ++r)
    if (static_cast<int>(r) != st.rank && st.headers[r].moving > 0 && overlaps(st.headers[r].region, around)) {
      st.near.push_back(static_cast<std::uint32_t>(r));
      others.grow(st.headers[r].region);
    }
  if (shapes.empty() || st.near.empty()) return;
  const std::size_t chunks = viscd::detail::ranges_for(shapes.size(), st.threads);
  st.chunk_hits.resize(chunks);
  for (auto& h : st.chunk_hits) h.clear();
  viscd::detail::for_chunks(shapes.size(), chunks, [&](std::size_t b, std::size_t e, std::size_t c) {
    auto& hits = st.chunk_hits[c];
    for (std::size_t i = b; i < e; ++i) {
      const Aabb box = bounds(shapes[i], margin);
      if (!overlaps(box, others)) continue;
      for (const std::uint32_t r : st.near)
        if (overlaps(box, st.headers[r].region)) hits.push_back({r, static_cast<std::uint32_t>(i)});
    }
  });
  for (const auto& hits : st.chunk_hits)
    for (const auto& [r, i] : hits) st.send_index[r].push_back(i);
}

/// Packs the selected objects into records grouped by destination rank, and their counts.
template <class Shape>
void pack(const std::vector<std::vector<std::uint32_t>>& to, std::span<const Shape> shapes,
          std::span<const std::uint64_t> ids, std::span<const Filter> filters, std::vector<Record<Shape>>& out,
          std::vector<std::uint64_t>& counts) {
  out.clear();
  counts.assign(to.size(), 0);
  for (std::size_t r = 0; r < to.size(); ++r) {
    counts[r] = to[r].size();
    for (const std::uint32_t i : to[r]) {
      Record<Shape> rec;
      rec.shape = shapes[i];
      rec.id = ids[i];
      if (!filters.empty()) rec.filter = filters[i];
      out.push_back(rec);
    }
  }
}

/// The frame after the headers: id check, ghost exchange, local frame, ownership rule.
template <class Shape>
Status run_frame(State& st, std::span<const Shape> own, const DistributedInput& in, DistributedResult& out,
                 detail::Traffic& traffic, double& exchange_ms, double& detect_ms) {
  viscd::detail::Stopwatch clock;
  const std::size_t n_own = own.size();
  bool any_filters = false, any_statics = false;
  for (const Header& h : st.headers) {
    any_filters = any_filters || h.has_filters != 0;
    any_statics = any_statics || h.statics > 0;
  }

  // Moving ghosts, then static ghosts (only while some rank has static objects).
  std::vector<Record<Shape>> send, ghosts, static_send, static_ghosts;
  std::vector<std::uint64_t> counts;
  std::vector<int> recv_counts;
  Status local;
  try {
    select_ghosts(st, own, st.margin, st.headers[static_cast<std::size_t>(st.rank)].region);
    pack(st.send_index, own, in.ids, in.filters, send, counts);
  } catch (const std::bad_alloc&) {
    local = Status::failure(ErrorKind::out_of_memory,
                            "out of memory selecting ghosts of " + std::to_string(n_own) + " objects");
  }
  if (Status s = detail::agree(st.comm, local, true); !s) return s;
  out.stats.ghosts_sent = static_cast<std::uint32_t>(std::accumulate(counts.begin(), counts.end(), std::uint64_t{0}));
  if (Status s = detail::all_to_all<Record<Shape>>(st.comm, st.types, send, counts, ghosts, recv_counts, traffic); !s)
    return s;
  out.stats.ghosts_received = static_cast<std::uint32_t>(ghosts.size());
  if (any_statics) {
    try {
      std::span<const Shape> mine;
      if constexpr (std::is_same_v<Shape, Sphere>)
        mine = st.static_spheres;
      else
        mine = st.static_boxes;
      select_ghosts(st, mine, st.static_margin, st.static_region);
      pack(st.send_index, mine, std::span<const std::uint64_t>(st.static_ids),
           std::span<const Filter>(st.static_filters), static_send, counts);
    } catch (const std::bad_alloc&) {
      local = Status::failure(ErrorKind::out_of_memory, "out of memory selecting static ghosts");
    }
    if (Status s = detail::agree(st.comm, local, true); !s) return s;
    out.stats.static_ghosts_sent =
        static_cast<std::uint32_t>(std::accumulate(counts.begin(), counts.end(), std::uint64_t{0}));
    if (Status s = detail::all_to_all<Record<Shape>>(st.comm, st.types, static_send, counts, static_ghosts, recv_counts,
                                                     traffic);
        !s)
      return s;
    out.stats.static_ghosts_received = static_cast<std::uint32_t>(static_ghosts.size());
  }
  exchange_ms += clock.lap();

  // The local frame over own + ghost objects.
  const std::size_t n = n_own + ghosts.size();
  FrameResult& frame = st.frame;
  try {
    if (n > INT32_MAX)
      local = Status::failure(ErrorKind::unsupported_input,
                              std::to_string(n) + " objects with ghosts on one rank (at most 2^31 - 1)");
    if (local) local = update_static_set<Shape>(st, static_ghosts);
    if (local && n > 0) {
      FrameInput fi;
      std::span<const Shape> shapes = own;
      if (!ghosts.empty()) {
        std::vector<Shape>* all = nullptr;
        if constexpr (std::is_same_v<Shape, Sphere>)
          all = &st.spheres;
        else
          all = &st.boxes;
        all->assign(own.begin(), own.end());
        for (const auto& g : ghosts) all->push_back(g.shape);
        shapes = *all;
      }
      if constexpr (std::is_same_v<Shape, Sphere>)
        fi.spheres = shapes;
      else
        fi.boxes = shapes;
      if (any_filters) {
        st.filters.assign(in.filters.begin(), in.filters.end());
        st.filters.resize(n_own);  // Filter{} for an own object when this rank gave none
        for (const auto& g : ghosts) st.filters.push_back(g.filter);
        fi.filters = st.filters;
      }
      if (!in.always_active.empty()) {
        st.always_active.assign(in.always_active.begin(), in.always_active.end());
        st.always_active.resize(n, 0);
        fi.always_active = st.always_active;
      }
      local = st.local->detect(fi, frame);
    }
  } catch (const std::bad_alloc&) {
    local = Status::failure(ErrorKind::out_of_memory,
                            "out of memory building the local frame of " + std::to_string(n) + " objects");
  }
  detect_ms += clock.lap();
  if (Status s = detail::agree(st.comm, local, true); !s) return s;

  // The ownership rule: a pair of two moving objects is this rank's when it owns the one with the
  // smaller id; a pair with a static object when it owns the moving one.
  out.pairs.clear();
  out.state.clear();
  out.local = {};
  const bool consecutive = st.ids.consecutive;
  const std::uint64_t first_id = st.ids.first;
  const auto id_of = [&](std::uint32_t i) {
    if (i >= n_own) return st.ghost_ids[i - n_own];
    return consecutive ? first_id + i : in.ids[i];
  };
  try {
    st.ghost_ids.resize(ghosts.size());
    for (std::size_t g = 0; g < ghosts.size(); ++g) st.ghost_ids[g] = ghosts[g].id;
    // A rank without objects ran no local frame: nothing to keep (it still agrees below).
    if (n == 0) frame.pairs.clear();
    // In parallel chunks: pairs of two own objects (in the local order, which is the ids' order
    // when a rank lists its objects by ascending id) apart from those with a ghost or a static
    // object; each part sorted, then merged.
    // Two passes over the chunks: the first counts the own pairs and collects the others (few),
    // the second writes the own pairs straight into place.
    const std::size_t m = frame.pairs.size(), chunks = viscd::detail::ranges_for(m, st.threads);
    st.chunk_cross.resize(chunks);
    st.own_count.assign(chunks + 1, 0);
    for (std::size_t c = 0; c < chunks; ++c) st.chunk_cross[c].clear();
    st.cross.clear();
    enum class Keep { no, both_own, cross };
    const auto keep = [&](const Pair& p, GlobalPair& g) {
      const bool i_own = p.i < n_own;
      const bool j_static = is_static_index(p.j), j_own = !j_static && p.j < n_own;
      if (!i_own && !j_own) return Keep::no;  // two ghosts, or a ghost and a static object
      const std::uint64_t a = id_of(p.i), b = j_static ? st.slot_id[static_slot(p.j)] : id_of(p.j);
      g = {std::min(a, b), std::max(a, b)};
      if (i_own && j_own) return Keep::both_own;
      if (!j_static && (i_own ? a > b : b > a)) return Keep::no;  // the other rank owns the smaller id
      return Keep::cross;
    };
    // Without ghosts and static objects every pair is this rank's: no counting pass.
    const bool all_own = n == n_own && st.slot_id.empty();
    if (all_own) {
      const std::size_t used = std::max<std::size_t>(1, std::min(chunks, m));  // as for_chunks() splits
      for (std::size_t c = 0; c < chunks; ++c)
        st.own_count[c + 1] = c < used ? viscd::detail::chunk_of(m, c, used).end : m;
    } else {
      viscd::detail::for_chunks(m, chunks, [&](std::size_t b, std::size_t e, std::size_t c) {
        std::size_t own_pairs = 0;
        GlobalPair g;
        for (std::size_t q = b; q < e; ++q) {
          const Keep k = keep(frame.pairs[q], g);
          own_pairs += k == Keep::both_own;
          if (k == Keep::cross) st.chunk_cross[c].push_back(g);
        }
        st.own_count[c + 1] = own_pairs;
      });
      for (std::size_t c = 0; c < chunks; ++c) {
        st.own_count[c + 1] += st.own_count[c];
        st.cross.insert(st.cross.end(), st.chunk_cross[c].begin(), st.chunk_cross[c].end());
      }
    }
    out.pairs.resize(st.own_count[chunks]);
    viscd::detail::for_chunks(m, chunks, [&](std::size_t b, std::size_t e, std::size_t c) {
      GlobalPair* to = out.pairs.data() + st.own_count[c];
      GlobalPair g;
      for (std::size_t q = b; q < e; ++q)
        if (keep(frame.pairs[q], g) == Keep::both_own) *to++ = g;
    });
    // Consecutive ids keep the local order (i < j gives id_i < id_j): sorted already.
    if (!consecutive && !std::is_sorted(out.pairs.begin(), out.pairs.end()))
      std::sort(out.pairs.begin(), out.pairs.end());
    if (!st.cross.empty()) {
      std::sort(st.cross.begin(), st.cross.end());
      const auto middle = static_cast<std::ptrdiff_t>(out.pairs.size());
      out.pairs.insert(out.pairs.end(), st.cross.begin(), st.cross.end());
      std::inplace_merge(out.pairs.begin(), out.pairs.begin() + middle, out.pairs.end());
      st.cross.clear();
    }
    if (n > 0 && n == n_own) {
      out.state.swap(frame.state);  // no ghosts: every state is this rank's (the frame's buffer comes back next time)
    } else if (n > 0) {
      out.state.assign(frame.state.begin(), frame.state.begin() + static_cast<std::ptrdiff_t>(n_own));
    }
    if (n > 0) out.local = frame.stats;
  } catch (const std::bad_alloc&) {
    local = Status::failure(ErrorKind::out_of_memory, "out of memory keeping the pairs");
  }
  return detail::agree(st.comm, local, true);
}

}  // namespace

DistributedDetector::DistributedDetector(MPI_Comm comm, const Config& config)
    : DistributedDetector(comm, make_cpu_detector(config)) {}

DistributedDetector::DistributedDetector(MPI_Comm comm, std::unique_ptr<Detector> local)
    : state_(std::make_unique<State>()) {
  VISCD_ASSERT(local != nullptr, "DistributedDetector needs a local detector");
  State& st = *state_;
  st.local = std::move(local);
  int initialized = 0, finalized = 0;
  MPI_Initialized(&initialized);
  MPI_Finalized(&finalized);
  if (!initialized || finalized) {
    st.broken = Status::failure(ErrorKind::backend_failure,
                                "MPI is not initialized: call MPI_Init (in Python: from mpi4py import MPI) before "
                                "making a DistributedDetector");
    return;
  }
  if (Status s = detail::mpi_status(MPI_Comm_dup(comm, &st.comm), "MPI_Comm_dup"); !s) {
    st.broken = s;
    st.comm = MPI_COMM_NULL;
    return;
  }
  MPI_Comm_set_errhandler(st.comm, MPI_ERRORS_RETURN);
  const Config& config = st.local->config();
  st.executor = config.executor;
  st.threads = viscd::detail::resolve_threads(config.threads, config.executor ? config.executor->concurrency() : 0);
  MPI_Comm_rank(st.comm, &st.rank);
  MPI_Comm_size(st.comm, &st.size);
}

DistributedDetector::~DistributedDetector() {
  if (!state_ || state_->comm == MPI_COMM_NULL) return;
  int finalized = 0;
  MPI_Finalized(&finalized);
  if (!finalized) MPI_Comm_free(&state_->comm);
}

int DistributedDetector::rank() const { return state_->rank; }
int DistributedDetector::size() const { return state_->size; }
const Detector& DistributedDetector::local() const { return *state_->local; }

namespace {

/// This rank's static set, replaced: checked, kept, its region measured; the local detector gets
/// it at the next frame.
template <class Shape>
Status replace_static(State& st, std::span<const Shape> shapes, std::span<const std::uint64_t> ids,
                      std::span<const Filter> filters) {
  const char* what = std::is_same_v<Shape, Sphere> ? " static spheres" : " static boxes";
  if (ids.size() != shapes.size())
    return Status::failure(ErrorKind::invalid_input,
                           std::to_string(ids.size()) + " ids for " + std::to_string(shapes.size()) + what);
  if (!filters.empty() && filters.size() != shapes.size())
    return Status::failure(ErrorKind::invalid_input,
                           std::to_string(filters.size()) + " filters for " + std::to_string(shapes.size()) + what);
  Status valid;
  if constexpr (std::is_same_v<Shape, Sphere>)
    valid = validate_spheres(shapes);
  else
    valid = validate_boxes(shapes);
  if (!valid) return Status::failure(valid.kind(), "static " + valid.error());
  st.static_spheres.clear();
  st.static_boxes.clear();
  if constexpr (std::is_same_v<Shape, Sphere>)
    st.static_spheres.assign(shapes.begin(), shapes.end());
  else
    st.static_boxes.assign(shapes.begin(), shapes.end());
  st.static_ids.assign(ids.begin(), ids.end());
  st.static_filters.assign(filters.begin(), filters.end());
  st.static_kind = shapes.empty() ? Kind::none : std::is_same_v<Shape, Sphere> ? Kind::sphere : Kind::box;
  (void)measure(shapes, 1, st.static_region, st.static_margin);
  st.statics_pending = true;
  return {};
}

}  // namespace

Status DistributedDetector::set_static_spheres(std::span<const Sphere> spheres, std::span<const std::uint64_t> ids,
                                               std::span<const Filter> filters) {
  return replace_static(*state_, spheres, ids, filters);
}

Status DistributedDetector::set_static_boxes(std::span<const Box> boxes, std::span<const std::uint64_t> ids,
                                             std::span<const Filter> filters) {
  return replace_static(*state_, boxes, ids, filters);
}

void DistributedDetector::clear_static() { (void)replace_static<Sphere>(*state_, {}, {}, {}); }

Status DistributedDetector::detect(const DistributedInput& in, DistributedResult& out) {
  State& st = *state_;
  if (!st.broken) return st.broken;
  const viscd::detail::ExecutorScope scope(st.executor);
  viscd::detail::Stopwatch clock, total;
  out.stats = {};
  detail::Traffic traffic;
  double exchange_ms = 0, detect_ms = 0;
  const bool boxes = !in.boxes.empty();

  // Local checks, then every rank's header.
  Header h;
  Status local;
  try {
    local = boxes ? check_input<Box>(st, in, in.boxes, h, st.margin)
                  : check_input<Sphere>(st, in, in.spheres, h, st.margin);
    h.statics = static_cast<std::uint32_t>(st.static_ids.size());
    h.static_kind = st.static_kind;
    h.has_filters = static_cast<std::uint8_t>(!in.filters.empty() || !st.static_filters.empty());
    st.ids = summarise(in.ids, st.threads);
    const bool same_ids = st.ids_known && !st.statics_pending && st.ids.same(st.checked_ids);
    h.ids_changed = static_cast<std::uint8_t>(!same_ids);
  } catch (const std::bad_alloc&) {
    local = Status::failure(ErrorKind::out_of_memory, "out of memory checking the frame's input");
  }
  if (Status s = detail::agree(st.comm, local, true); !s) return s;
  st.headers.resize(static_cast<std::size_t>(st.size));
  {
    MPI_Datatype type = MPI_DATATYPE_NULL;
    if (Status s = st.types.get(sizeof(Header), type); !s) return s;
    const detail::TrafficTimer timer(traffic);
    if (Status s = detail::mpi_status(MPI_Allgather(&h, 1, type, st.headers.data(), 1, type, st.comm), "MPI_Allgather");
        !s)
      return s;
    traffic.sent += sizeof(Header) * static_cast<std::uint64_t>(st.size - 1);
    traffic.received += sizeof(Header) * static_cast<std::uint64_t>(st.size - 1);
  }
  Kind kind = Kind::none;
  if (Status s = common_kind(st.headers, kind); !s) return s;
  bool check_ids = false;
  for (const Header& hr : st.headers) check_ids = check_ids || hr.ids_changed != 0;
  if (check_ids) {
    st.ids_known = false;  // until the check passes
    if (Status s = detail::check_global_ids(st.comm, st.types, in.ids, st.static_ids, traffic); !s) return s;
    out.stats.ids_checked = true;
  }
  st.checked_ids = st.ids;
  st.ids_known = true;
  exchange_ms += clock.lap();

  Status s = kind == Kind::box ? run_frame<Box>(st, in.boxes, in, out, traffic, exchange_ms, detect_ms)
                               : run_frame<Sphere>(st, in.spheres, in, out, traffic, exchange_ms, detect_ms);
  if (!s) return s;
  out.stats.objects = h.moving;
  out.stats.static_objects = h.statics;
  out.stats.bytes_sent = traffic.sent;
  out.stats.bytes_received = traffic.received;
  out.stats.pairs = out.pairs.size();
  out.stats.exchange_ms = exchange_ms;
  out.stats.communication_ms = traffic.ms;
  out.stats.detect_ms = detect_ms;
  out.stats.total_ms = total.lap();
  return {};
}

Status DistributedDetector::gather_pairs(const DistributedResult& result, std::vector<GlobalPair>& all, int root) {
  State& st = *state_;
  if (!st.broken) return st.broken;
  all.clear();
  Status local;
  if (root < 0 || root >= st.size)
    return Status::failure(ErrorKind::invalid_input, "gather_pairs: root " + std::to_string(root) +
                                                         " is not a rank of " + std::to_string(st.size));
  if (result.pairs.size() > INT_MAX)
    local = Status::failure(ErrorKind::unsupported_input, "more than 2^31 - 1 pairs on one rank to gather");
  if (Status s = detail::agree(st.comm, local, true); !s) return s;
  const int count = static_cast<int>(result.pairs.size());
  std::vector<int> counts(st.rank == root ? static_cast<std::size_t>(st.size) : 0), displs(counts.size());
  if (Status s =
          detail::mpi_status(MPI_Gather(&count, 1, MPI_INT, counts.data(), 1, MPI_INT, root, st.comm), "MPI_Gather");
      !s)
    return s;
  if (st.rank == root) {
    std::uint64_t total = 0;
    for (std::size_t r = 0; r < counts.size(); ++r) {
      displs[r] = static_cast<int>(std::min<std::uint64_t>(total, INT_MAX));
      total += static_cast<std::uint64_t>(counts[r]);
    }
    if (total > INT_MAX) {
      local = Status::failure(ErrorKind::unsupported_input,
                              std::to_string(total) + " pairs to gather on one rank (at most 2^31 - 1)");
    } else {
      try {
        all.resize(total);
      } catch (const std::bad_alloc&) {
        local =
            Status::failure(ErrorKind::out_of_memory, "out of memory gathering " + std::to_string(total) + " pairs");
      }
    }
  }
  if (Status s = detail::agree(st.comm, local, true); !s) return s;
  MPI_Datatype type = MPI_DATATYPE_NULL;
  if (Status s = st.types.get(sizeof(GlobalPair), type); !s) return s;
  if (Status s = detail::mpi_status(
          MPI_Gatherv(result.pairs.data(), count, type, all.data(), counts.data(), displs.data(), type, root, st.comm),
          "MPI_Gatherv");
      !s)
    return s;
  // Each rank's share is sorted and the shares are disjoint: one sort puts them in order.
  if (st.rank == root) std::sort(all.begin(), all.end());
  return {};
}

}  // namespace viscd::mpi
