#include "cpu/rest_set.hpp"

#include <algorithm>
#include <atomic>
#include <bit>
#include <cmath>
#include <cstddef>
#include <cstring>
#include <limits>

#include "core/frame_rules.hpp"
#include "core/stopwatch.hpp"
#include "cpu/bucket_search.hpp"
#include "cpu/cross_pairs.hpp"
#include "cpu/grow.hpp"
#include "cpu/pair_collector.hpp"
#include "cpu/parallel.hpp"
#include "cpu/simd.hpp"

namespace viscd::detail {
namespace {

/// Main is rebuilt over the resting objects when its erased lanes and the objects of delta pass
/// an eighth of all, and at least this many.
constexpr std::size_t kMainRebuildFloor = 4096;
// The objects of recent that did not leave again (with a rest margin) or did not change (own
// margins alone) wait there, not searching, until more than this many do; then they join delta
// together (RestSet::update()).
constexpr std::size_t kWaitMost = 512;
/// A main due again within this many frames of the last build, with delta (the objects that came
/// to rest since) a quarter of what makes it due, means that objects keep starting and stopping (a
/// new set of movers every frame; the same movers frame after frame leave main once and stay in
/// recent): each rebuild of main costs about a rebuilt frame,
/// and following then costs more than rebuilding (at 10^6 objects, 5 % of them drawn anew each
/// frame: 1.2-1.5 rebuilt frames). The set then gives up and waits kChurnWait frames before it
/// watches its sample again, twice as long after each such give-up (up to kChurnWaitMost), and
/// back to kChurnWait after kChurnForgive followed frames without one.
constexpr std::size_t kChurnFrames = 3;
constexpr std::size_t kChurnWait = 8;
constexpr std::size_t kChurnWaitMost = 256;
constexpr std::size_t kChurnForgive = 64;
/// Objects watched while the set is out of use; it takes over when all but 1 in kTakeOver of them
/// rest, and gives up when more than 1 in kGiveUp objects leave their fat bounds in a frame (the
/// gap between the two keeps a world near the limit from entering and leaving frame after frame).
/// An object placed again costs several times what it costs in a rebuild (walks of trees whose
/// buckets lie far apart in memory, and its candidates merged into the list): at 10^6 objects a
/// frame with a tenth moving costs about 0.42 of a rebuilt one (docs/benchmarks.md, "Walks of the
/// moving buckets"), 0.45-0.51 with 15 % moving, and about a rebuilt one past 20 % (5 in 6 resting
/// to take over: a sample of 256 with 18 % moving does in about a third of the frames).
constexpr std::size_t kSample = 256;
constexpr std::size_t kTakeOver = 6;
constexpr std::size_t kGiveUp = 5;
/// A frame whose static set changed in up to 1 in kStaticShare of the moving count (and at least
/// 16 slots) is followed: each changed slot costs a query of each tree, its entries sorted and
/// merged (about 3 us at 10^5 objects: 1 000 changed slots cost about 0.4 of a rebuilt frame).
constexpr std::size_t kStaticShare = 64;
/// A side-list entry's byte: bit 0 its exact result, kRecheck set while one of its objects may
/// move inside its own fat bounds (found by a search of recent with Config::move_margin), so that
/// only those are tested again.
constexpr std::uint8_t kRecheck = 2;
/// Set on a candidate of an object that left (dropped in place by emit() with the side list), or
/// on a side-list entry that is no candidate any more; skipped, and dropped by the next merge.
constexpr std::uint8_t kDrop = 4;

/// With own margins alone, the side list is merged into the candidates once its unmarked entries
/// and the candidates dropped in place pass a sixteenth of the candidates (and this floor).
constexpr std::size_t kSideShare = 16;
constexpr std::size_t kSideFloor = 4096;

/// Bit k of a bitset (one bit per object: 125 KB for 10^6 objects, which stays in cache while the
/// candidates stream past).
[[nodiscard]] std::uint64_t bit(const std::uint64_t* b, std::uint32_t k) { return (b[k >> 6] >> (k & 63)) & 1; }

[[nodiscard]] bool same_bits(const Sphere& a, const Sphere& b) { return std::memcmp(&a, &b, sizeof(Sphere)) == 0; }
[[nodiscard]] bool same_bits(const Box& a, const Box& b) { return std::memcmp(&a, &b, sizeof(Box)) == 0; }

/// The exact test of moving object i with the static object of index `index` (static_index()):
/// what the static trees' kernels report for the two (the static set holds the frame's kind).
[[nodiscard]] std::uint8_t static_overlap(const Shapes& s, const StaticSet& set, std::uint32_t i, std::uint32_t index) {
  const std::uint32_t q = static_slot(index);
  return s.is_box() ? s.meets_box(i, set.box(q)) : s.meets_sphere(i, set.sphere(q));
}

/// Chunks of emit()'s merge for this many candidates and static pairs.
[[nodiscard]] std::size_t merge_chunks(std::size_t keys, int threads) {
  return threads_for(keys, threads) == 1 ? 1 : 4 * static_cast<std::size_t>(std::max(1, threads));
}

/// The direct pass's run of candidates from `a` up to the first key at or past `below` (or `ae`):
/// each live one that holds (its byte exactly 1: not dropped) written as a pair at po[out], none
/// past `lim` (then `over` is set). No object of theirs left this frame (none woke from rest: an
/// object in recent has no candidates here). Returns where the run ends.
std::size_t direct_run_scalar(const std::uint64_t* ak, const std::uint8_t* ah, std::size_t a, std::size_t ae,
                              std::uint64_t below, Pair* po, std::size_t& out, std::size_t lim, bool& over) {
  for (; a < ae && ak[a] < below; ++a) {
    const std::uint8_t h = ah[a];
    if (h & kDrop) continue;
    if (out < lim) po[out] = Pair{key_i(ak[a]), key_j(ak[a])};
    out += h & 1u;
  }
  over |= out > lim;
  return a;
}

#if VISCD_HAVE_AVX512
// GCC 12 takes the undefined pass-through operands inside some AVX-512 intrinsics for
// uninitialised variables.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif
/// direct_run_scalar() eight candidates at a time: the keys below `below` and the bytes equal to
/// 1 as masks, the keys' halves swapped into pairs and compressed into the output.
VISCD_AVX512_TARGET std::size_t direct_run_avx512(const std::uint64_t* ak, const std::uint8_t* ah, std::size_t a,
                                                  std::size_t ae, std::uint64_t below, Pair* po, std::size_t& out,
                                                  std::size_t lim, bool& over) {
  static_assert(sizeof(Pair) == 8 && offsetof(Pair, i) == 0 && offsetof(Pair, j) == 4);
  const __m512i vbelow = _mm512_set1_epi64(static_cast<long long>(below));
  const __m512i one = _mm512_set1_epi64(1);
  while (a + 8 <= ae) {
    const __m512i k = _mm512_loadu_si512(ak + a);
    const __mmask8 run = _mm512_cmplt_epu64_mask(k, vbelow);  // a prefix: the keys ascend
    const __m128i bytes = _mm_loadl_epi64(reinterpret_cast<const __m128i*>(ah + a));
    const __mmask8 take = run & _mm512_cmpeq_epi64_mask(_mm512_cvtepu8_epi64(bytes), one);
    const auto count = static_cast<std::size_t>(std::popcount(static_cast<unsigned>(take)));
    if (out + count > lim) {
      over = true;
      return ae;
    }
    _mm512_mask_compressstoreu_epi64(po + out, take, _mm512_ror_epi64(k, 32));  // {i, j}: j high
    out += count;
    if (run != 0xFF) return a + static_cast<std::size_t>(std::popcount(static_cast<unsigned>(run)));
    a += 8;
  }
  return direct_run_scalar(ak, ah, a, ae, below, po, out, lim, over);
}
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic pop
#endif
#endif

}  // namespace

std::size_t RestSet::candidate_count() const {
  std::size_t n = 0;
  for (const Segment& g : segs_) n += g.end - g.begin;
  return n;
}

void RestSet::pack(int threads) {
  ++packs_;
  // One run: the segments copied into cand_next_ in order.
  const std::size_t count = candidate_count();
  if (segs_.size() > 1 || (segs_.size() == 1 && segs_[0].begin != 0)) {
    resize_with_headroom(cand_next_, count);
    resize_with_headroom(hit_next_, count);
    std::size_t at = 0;
    std::vector<std::size_t>& to = pack_at_;
    to.assign(segs_.size(), 0);
    for (std::size_t c = 0; c < segs_.size(); ++c) {
      to[c] = at;
      at += segs_[c].end - segs_[c].begin;
    }
    for_chunks(segs_.size(), segs_.size(), [&](std::size_t c, std::size_t, std::size_t) {
      const std::size_t len = segs_[c].end - segs_[c].begin;
      std::copy_n(cand_.data() + segs_[c].begin, len, cand_next_.data() + to[c]);
      std::copy_n(hit_.data() + segs_[c].begin, len, hit_next_.data() + to[c]);
    });
    cand_.swap(cand_next_);
    hit_.swap(hit_next_);
  }
  cand_.resize(count);
  hit_.resize(count);
  // Cut at keys of the longer of the candidates and the static pairs, so that each chunk merges
  // about as much.
  const std::size_t chunks = merge_chunks(count + stat_.size(), threads);
  const std::span<const std::uint64_t> longer = count >= stat_.size() ? std::span<const std::uint64_t>(cand_) : stat_;
  cuts_.assign(1, 0);
  for (std::size_t c = 1; c < chunks && !longer.empty(); ++c) {
    const std::uint64_t k = longer[c * longer.size() / chunks];
    if (k > cuts_.back()) cuts_.push_back(k);
  }
  segs_.resize(cuts_.size());
  for (std::size_t c = 0; c < cuts_.size(); ++c) {
    segs_[c].begin = c == 0 ? 0 : segs_[c - 1].end;
    segs_[c].end =
        c + 1 < cuts_.size()
            ? static_cast<std::size_t>(std::lower_bound(cand_.begin(), cand_.end(), cuts_[c + 1]) - cand_.begin())
            : count;
  }
}

std::uint64_t RestSet::Part::memory_bytes() const {
  return tree.memory_bytes() + bytes_of(spheres) + bytes_of(boxes) + bytes_of(ids) + bytes_of(iota) + bytes_of(at);
}

std::uint64_t RestSet::memory_bytes() const {
  std::uint64_t b = bytes_of(cur_sph_) + bytes_of(cur_box_) + bytes_of(fat_box_) + bytes_of(fat_sph_) +
                    bytes_of(fat_r_) + bytes_of(part_of_) + bytes_of(changed_bits_) + bytes_of(left_bits_) +
                    bytes_of(local_) + bytes_of(left_) + bytes_of(scratch_) + bytes_of(cand_) + bytes_of(cand_next_) +
                    bytes_of(found_) + bytes_of(stat_) + bytes_of(stat_next_) + bytes_of(stat_found_) +
                    bytes_of(stat_hit_) + bytes_of(stat_hit_next_) + bytes_of(hit_) + bytes_of(hit_next_) +
                    bytes_of(local_pairs_) + bytes_of(active_mask_) + bytes_of(pair_buf_) + bytes_of(segs_) +
                    bytes_of(cuts_) + bytes_of(sample_index_) + bytes_of(sample_);
  for (const Part& p : parts_) b += p.memory_bytes();
  for (const auto& l : chunk_keys_) b += bytes_of(l);
  b += bytes_of(key_offsets_) + bytes_of(key_scratch_);
  for (const auto& l : chunk_left_) b += bytes_of(l);
  for (const auto& l : chunk_margin_) b += bytes_of(l);
  b += bytes_of(side_) + bytes_of(side_next_) + bytes_of(side_hit_) + bytes_of(side_hit_next_);
  b += bytes_of(static_changed_) + bytes_of(near_) + bytes_of(near_hits_);
  b += bytes_of(a_count_) + bytes_of(a_bits_) + bytes_of(pair_bits_);
  for (const auto& l : chunk_gone_) b += bytes_of(l);
  for (const auto& l : chunk_added_) b += bytes_of(l);
  b += bytes_of(recent_bits_) + bytes_of(left_margin_) + bytes_of(recent_next_) + bytes_of(search_) +
       bytes_of(found_hit_);
  return b;
}

void RestSet::reset() {
  live_ = false;
  churned_ = false;
  frames_since_main_ = 0;
  sample_n_ = 0;
  std::fill(changed_bits_.begin(), changed_bits_.end(), std::uint64_t{0});
  std::fill(left_bits_.begin(), left_bits_.end(), std::uint64_t{0});
  vanished_ = 0;
}

void RestSet::clear_bits() {
  std::fill(changed_bits_.begin(), changed_bits_.end(), std::uint64_t{0});
  std::fill(left_bits_.begin(), left_bits_.end(), std::uint64_t{0});
}

float RestSet::margin_of(const Shapes& s, std::size_t k) const {
  // Only an object that moved in the last frame too (in recent) keeps moving: one that starts
  // from rest may move once and stop (margins for those had made frames with new movers every
  // frame a tenth dearer).
  if (move_margin_ <= 0 || !bit(recent_bits_.data(), static_cast<std::uint32_t>(k))) return margin_;
  // Its own: move_margin times how far it moved since the last frame (its copy, cur_, still the
  // last frame's), at most half its size, and none when it moved farther than that (a jump: the
  // next frame is not likely to be near).
  float size = 0, moved = 0;
  if (s.is_box()) {
    const Box& a = s.boxes[k];
    const Box& b = cur_box_[k];
    size = 0.5f * std::max({a.max[0] - a.min[0], a.max[1] - a.min[1], a.max[2] - a.min[2]});
    for (int c = 0; c < 3; ++c)
      moved = std::max({moved, std::fabs(a.min[c] - b.min[c]), std::fabs(a.max[c] - b.max[c])});
  } else {
    const Sphere& a = s.spheres[k];
    const Sphere& b = cur_sph_[k];
    const float dx = a.x - b.x, dy = a.y - b.y, dz = a.z - b.z;
    size = a.r;
    moved = std::sqrt(dx * dx + dy * dy + dz * dz) + std::fabs(a.r - b.r);
  }
  if (!(moved >= 0)) return margin_;  // an infinite move (validation allows huge coordinates)
  const float cap = 0.5f * size;
  const float own = moved <= cap ? std::min(move_margin_ * moved, cap) : 0.0f;
  return std::max(margin_, own);
}

void RestSet::place(const Shapes& s, std::size_t k, float m) {
  constexpr float kInf = std::numeric_limits<float>::infinity();
  if (s.is_box()) {
    // The box grown by the margin, rounded outward: it holds the box grown by exactly the margin.
    const Box& b = s.boxes[k];
    for (int c = 0; c < 3; ++c) {
      fat_box_[k].min[c] = std::nextafter(b.min[c] - m, -kInf);
      fat_box_[k].max[c] = std::nextafter(b.max[c] + m, kInf);
    }
    return;
  }
  // The sphere's conservative extent (which holds every point its float test can accept) plus
  // the margin, rounded up; in the trees widened once more, so that the float test between two
  // fat spheres accepts every two that truly meet (docs/architecture.md, "Resting objects").
  const Sphere& o = s.spheres[k];
  const float r = std::nextafter(conservative_half_extent(o) + m, kInf);
  fat_r_[k] = r;
  fat_sph_[k] = Sphere{o.x, o.y, o.z, conservative_half_extent(Sphere{o.x, o.y, o.z, r})};
}

// Inlined into find_changes()'s loop (a call per object cost a fifth of the pass).
[[gnu::always_inline]] inline bool RestSet::inside_fat(const Shapes& s, std::size_t k) const {
  if (s.is_box()) {
    const Box& b = s.boxes[k];
    const Box& f = fat_box_[k];
    return b.min[0] >= f.min[0] && b.min[1] >= f.min[1] && b.min[2] >= f.min[2] && b.max[0] <= f.max[0] &&
           b.max[1] <= f.max[1] && b.max[2] <= f.max[2];
  }
  // |c - c0| + extent <= r in double (the widening in the trees absorbs its rounding).
  const Sphere& o = s.spheres[k];
  const Sphere& f = fat_sph_[k];
  const double dx = double{o.x} - f.x, dy = double{o.y} - f.y, dz = double{o.z} - f.z;
  const double room = double{fat_r_[k]} - conservative_half_extent(o);
  return room >= 0 && dx * dx + dy * dy + dz * dz <= room * room;
}

void RestSet::build_part(Part& part, std::span<const std::uint32_t> objs, std::uint8_t which, bool fat, int threads,
                         std::vector<Pair>* pairs) {
  const std::size_t count = objs.size();
  part.count = count;
  part.erased = 0;
  if (which == kMain) return build_main(objs, threads, pairs);
  // The same objects as at its last build (objects that move frame after frame, in recent): the
  // tree keeps its last order while its buckets stay tight (Config::keep_order's rule), and sorts
  // from it when they do not.
  const bool same = part.ids.size() == count && std::equal(objs.begin(), objs.end(), part.ids.begin());
  // Then recent's objects are its own still, at the same places (the erase pass leaves them so).
  const bool placed = same && which == kRecent;
  part.ids.assign(objs.begin(), objs.end());
  if (part.iota.size() < count) {
    const std::size_t old = part.iota.size();
    part.iota.resize(count);
    for (std::size_t k = old; k < count; ++k) part.iota[k] = static_cast<std::uint32_t>(k);
  }
  const bool boxes = fat ? box_lanes() : kind_ == ShapeKind::box;
  // Recent holds its objects' own fat bounds (move_margin); main and delta the rest margin's.
  const bool use_fat = fat && (margin_ > 0 || (move_margin_ > 0 && which == kRecent));
  resize_with_headroom(part.spheres, count);
  resize_with_headroom(part.boxes, boxes ? count : 0);
  // The objects' bounds gathered (they lie scattered: read ahead).
  const Shapes src = boxes ? Shapes(std::span<const Box>(use_fat ? fat_box_ : cur_box_))
                           : Shapes(std::span<const Sphere>(use_fat ? fat_sph_ : cur_sph_));
  for_chunks(count, ranges_for(count, threads), [&](std::size_t b, std::size_t e, std::size_t) {
    constexpr std::size_t kAhead = 16;
    for (std::size_t k = b; k < e; ++k) {
      if (k + kAhead < e) src.prefetch(objs[k + kAhead]);
      const std::uint32_t o = objs[k];
      if (boxes) {
        part.boxes[k] = src.boxes[o];
        part.spheres[k] = box_proxy(src.boxes[o]);
      } else {
        part.spheres[k] = src.spheres[o];
      }
      if (which != kNowhere && !placed) {
        part_of_[o] = which;
        local_[o] = static_cast<std::uint32_t>(k);
      }
    }
  });
  FrameStats built;
  if (!same) part.tree.reset_order();
  part.tree.set_keep_order(same);
  part.tree.set_simd(simd_);
  BucketBroadphase::Extras extras;
  extras.boxes = std::span<const Box>(part.boxes.data(), boxes ? count : 0);
  const std::span<const std::uint32_t> ids(part.iota.data(), count);
  const std::span<const Sphere> spheres(part.spheres.data(), count);
  if (pairs != nullptr)
    (void)part.tree.run(spheres, ids, {}, bits_, layout_, threads, 0, *pairs, built, extras);  // no cap: never fails
  else
    part.tree.build(spheres, ids, bits_, layout_, threads, built, extras);
  if (which != kNowhere && !(placed && built.order_kept)) {
    // The object at each sorted position, for the movers' searches (cross_pairs() reports those).
    const std::span<const std::uint32_t> sorted = part.tree.sorted_objects();
    resize_with_headroom(part.at, sorted.size());
    parallel_for(sorted.size(), threads, [&](std::size_t q) { part.at[q] = part.ids[sorted[q]]; });
  }
}

void RestSet::build_main(std::span<const std::uint32_t> objs, int threads, std::vector<Pair>* pairs) {
  // Main's tree takes its objects by their own index, from the whole arrays (objs ascending, its
  // active set): nothing is copied, and its last order, in object indices, holds from one build
  // to the next, so that the sort starts from it (from the objects' index order, a rebuild of
  // main over 10^6 objects had cost about a rebuilt frame).
  Part& part = parts_[kMain];
  const std::size_t count = objs.size();
  part.by_index = true;
  const bool boxes = box_lanes(), use_fat = margin_ > 0;
  const std::vector<Box>& box_of = use_fat ? fat_box_ : cur_box_;
  if (boxes) resize_with_headroom(part.spheres, n_);  // the proxies, by object index
  parallel_for(count, threads, [&](std::size_t k) {
    const std::uint32_t o = objs[k];
    if (boxes) part.spheres[o] = box_proxy(box_of[o]);
    part_of_[o] = kMain;
    local_[o] = o;
  });
  FrameStats built;
  part.tree.set_keep_order(false);
  part.tree.set_simd(simd_);
  BucketBroadphase::Extras extras;
  if (boxes) extras.boxes = std::span<const Box>(box_of.data(), n_);
  const std::span<const Sphere> spheres = boxes     ? std::span<const Sphere>(part.spheres.data(), n_)
                                          : use_fat ? std::span<const Sphere>(fat_sph_)
                                                    : std::span<const Sphere>(cur_sph_);
  if (pairs != nullptr)
    (void)part.tree.run(spheres, objs, {}, bits_, layout_, threads, 0, *pairs, built, extras);  // no cap: never fails
  else
    part.tree.build(spheres, objs, bits_, layout_, threads, built, extras);
  main_layout_ = built.layout;
}

std::span<const std::uint32_t> RestSet::enter_main(int threads, std::vector<Pair>* pairs) {
  resize_with_headroom(scratch_, n_);
  parallel_for(n_, threads, [&](std::size_t k) { scratch_[k] = static_cast<std::uint32_t>(k); });
  const std::span<const std::uint32_t> all(scratch_.data(), n_);
  build_part(parts_[kMain], all, kMain, true, threads, pairs);
  for (const std::uint8_t p : {kDelta, kRecent}) {
    parts_[p].count = parts_[p].erased = 0;
    parts_[p].ids.clear();
  }
  return all;
}

bool RestSet::sample_rests(const Shapes& s, float margin) {
  const std::size_t n = s.size();
  bool rests = false;
  // The last sample's objects are still there when the count stayed or grew (objects added at
  // the end do not keep the set from starting); when it fell, those gone count as moved (a world
  // that removes a few bodies every frame starts following too).
  if (sample_n_ > 0 && sample_kind_ == s.kind && !sample_index_.empty()) {
    std::size_t still = 0;
    for (std::size_t k = 0; k < sample_index_.size(); ++k) {
      if (sample_index_[k] >= n) continue;
      const Aabb now = s.aabb(sample_index_[k]);
      const Box& was = sample_[k];
      if (margin == 0) {
        still += now.lo.x == was.min[0] && now.lo.y == was.min[1] && now.lo.z == was.min[2] && now.hi.x == was.max[0] &&
                 now.hi.y == was.max[1] && now.hi.z == was.max[2];
      } else {
        still += now.lo.x >= was.min[0] - margin && now.lo.y >= was.min[1] - margin &&
                 now.lo.z >= was.min[2] - margin && now.hi.x <= was.max[0] + margin &&
                 now.hi.y <= was.max[1] + margin && now.hi.z <= was.max[2] + margin;
      }
    }
    rests = still * kTakeOver >= sample_index_.size() * (kTakeOver - 1);
  }
  // Evenly spread, from an offset that changes with every sample (a fixed sample that happened
  // to hold more of a fixed set of movers than the whole would never take over).
  const std::size_t m = std::min(n, kSample);
  const std::size_t spacing = m == 0 ? 1 : n / m;
  sample_seed_ = sample_seed_ * 6364136223846793005ull + 1442695040888963407ull;
  const std::size_t offset = static_cast<std::size_t>(sample_seed_ >> 33) % spacing;
  sample_index_.resize(m);
  sample_.resize(m);
  for (std::size_t k = 0; k < m; ++k) {
    sample_index_[k] = static_cast<std::uint32_t>(k * n / m + offset);
    const Aabb a = s.aabb(sample_index_[k]);
    sample_[k] = Box{{a.lo.x, a.lo.y, a.lo.z}, {a.hi.x, a.hi.y, a.hi.z}};
  }
  sample_n_ = n;
  sample_kind_ = s.kind;
  return rests;
}

Status RestSet::run(const Input& in, const StaticSet& set, StaticTree& st, int threads, std::vector<Pair>& pairs,
                    FrameStats& stats, bool& followed) {
  followed = false;
  pair_bits_ok_ = false;
  needs_validation_ = in.unvalidated;
  run_again_ = false;
  simd_ = in.simd;
  const Shapes& s = in.objects;
  const std::size_t n = s.size();
  if (n == 0 || in.active.size() * 2 < n) {
    reset();
    return {};
  }
  // New objects at the end (n above the last frame's count) are placed as objects that left
  // their bounds are, and objects gone from the end (n below it) are taken out as those are and
  // not placed again, while they are few.
  const std::size_t limit = std::max<std::size_t>(n / kGiveUp, 16);
  const bool grows = live_ && n > n_ && n - n_ <= limit;
  const bool shrinks = live_ && n < n_ && n_ - n <= limit;
  // A static set changed in a few slots since the last frame is followed too (follow_static():
  // a tree query per changed slot, so up to 1 in kStaticShare of the moving count); replaced,
  // cleared or much changed, it rebuilds.
  const StaticTree::Taken taken = st.last_changes();
  const bool static_changed = set.version() != static_version_;
  const bool static_follows = static_changed && !taken.reset && taken.from == static_version_ &&
                              taken.to == set.version() &&
                              taken.slots.size() <= std::max<std::size_t>(n / kStaticShare, 16);
  if (live_ && ((n != n_ && !grows && !shrinks) || s.kind != kind_ || in.margin != margin_ ||
                in.move_margin != move_margin_ || in.layout != layout_ || (static_changed && !static_follows)))
    reset();
  if (live_ && churned_) {  // the last frame found main due again too soon
    reset();
    churn_wait_ = churn_backoff_;
    churn_backoff_ = std::min(churn_backoff_ * 2, kChurnWaitMost);
    ++churn_giveups_;
  }
  Status status;
  if (live_) {
    Stopwatch sw;
    bool few = false;
    const std::size_t last_n = n_;
    if (n > n_) grow(n);
    n_ = n;  // (shrinking: the arrays keep the vanished objects' entries until forget_vanished())
    vanished_ = last_n > n ? last_n - n : 0;
    status = find_changes(in, threads, limit, last_n, few);
    stats.ms(Stage::cull) += sw.lap();
    if (!status) {
      reset();
      return status;
    }
    if (!few) {  // too many changed, or an invalid one: the caller validates them all
      reset();
      (void)sample_rests(s, in.margin);
      return {};
    }
    needs_validation_ = false;  // every changed object was checked
    status = update(in, set, st, threads, stats);
    if (status && static_changed) {
      Stopwatch ssw;
      follow_static(s, set, taken.slots);
      static_version_ = set.version();
      stats.ms(Stage::query) += ssw.lap();
    }
  } else {
    if (in.unvalidated) {  // nothing is built over objects not validated
      run_again_ = true;
      return {};
    }
    if (churn_wait_ > 0) {
      --churn_wait_;
      return {};
    }
    if (!sample_rests(s, in.margin)) return {};
    status = enter(in, set, st, threads, stats);
  }
  if (status) {
    Stopwatch sw;
    status = emit(in, set, threads, pairs);
    stats.ms(Stage::query) += sw.lap();
  }
  merge_ = false;
  if (status) clear_bits();
  if (status && vanished_ > 0) forget_vanished();
  if (!status) {
    reset();
    return status;
  }
  followed = true;
  stats.followed_change = true;
  stats.bits = in.bits;  // the width the frame chose; the trees keep theirs until rebuilt (exact either way)
  stats.layout = main_layout_;
  stats.pairs = pairs.size();
  return {};
}

Status RestSet::enter(const Input& in, const StaticSet& set, StaticTree& st, int threads, FrameStats& stats) {
  Stopwatch sw;
  const Shapes& s = in.objects;
  const std::size_t n = s.size();
  kind_ = s.kind;
  n_ = n;
  margin_ = in.margin;
  move_margin_ = in.move_margin;
  layout_ = in.layout;
  bits_ = in.bits;
  static_version_ = set.version();
  if (s.is_box()) {
    resize_with_headroom(cur_box_, n);
    parallel_for(n, threads, [&](std::size_t k) { cur_box_[k] = s.boxes[k]; });
    cur_sph_.clear();
  } else {
    resize_with_headroom(cur_sph_, n);
    parallel_for(n, threads, [&](std::size_t k) { cur_sph_[k] = s.spheres[k]; });
    cur_box_.clear();
  }
  const bool any_fat = fat();
  resize_with_headroom(fat_box_, any_fat && s.is_box() ? n : 0);
  resize_with_headroom(fat_sph_, any_fat && !s.is_box() ? n : 0);
  resize_with_headroom(fat_r_, any_fat && !s.is_box() ? n : 0);
  recent_bits_.assign((n + 63) / 64, 0);
  if (margin_ > 0) parallel_for(n, threads, [&](std::size_t k) { place(s, k, margin_); });
  part_of_.assign(n, kNowhere);
  changed_bits_.assign((n + 63) / 64, 0);
  left_bits_.assign((n + 63) / 64, 0);
  resize_with_headroom(local_, n);
  local_pairs_.clear();
  const std::span<const std::uint32_t> all = enter_main(threads, &local_pairs_);
  stats.ms(Stage::build) += sw.lap();
  // Main's tree ids are the object indices: its pairs are the candidates.
  resize_with_headroom(cand_, local_pairs_.size());
  resize_with_headroom(hit_, local_pairs_.size());
  parallel_for(local_pairs_.size(), threads, [&](std::size_t k) {
    const Pair p = local_pairs_[k];
    cand_[k] = pair_key(p.i, p.j);
    hit_[k] = margin_ == 0 || s.overlap(p.i, p.j);
  });
  // The static candidates: from main's lanes (fat bounds with the rest margin, else exact), each
  // tested.
  stat_.clear();
  if (!set.empty()) {
    if (!static_pairs_of(parts_[kMain].tree, all, st, threads, stat_))
      return check_pair_cap(SIZE_MAX, in.pair_memory_cap, true);
  }
  resize_with_headroom(stat_hit_, stat_.size());
  parallel_for(stat_.size(), threads,
               [&](std::size_t t) { stat_hit_[t] = static_overlap(s, set, key_i(stat_[t]), key_j(stat_[t])); });
  segs_.assign(1, Segment{0, cand_.size()});
  side_.clear();
  side_hit_.clear();
  side_unmarked_ = dropped_ = woken_ = 0;
  a_out_valid_ = false;
  count_candidates();
  packs_ = main_rebuilds_ = delta_builds_ = 0;
  pack(threads);
  stats.ms(Stage::query) += sw.lap();
  stats.moved = stats.replaced = static_cast<std::uint32_t>(n);  // every object placed
  live_ = true;
  return {};
}

namespace {

/// Whether the objects of one bitset word [first, last) that `mask` says changed are valid: each
/// one alone when few changed, else the whole word (in cache: it was just compared).
bool changed_valid(const Shapes& s, std::size_t first, std::size_t last, std::uint64_t mask) {
  if (std::popcount(mask) > 8)
    return s.is_box() ? boxes_all_valid(s.boxes.subspan(first, last - first))
                      : spheres_all_valid(s.spheres.subspan(first, last - first));
  bool ok = true;
  for (std::uint64_t m = mask; m; m &= m - 1) {
    const std::size_t k = first + static_cast<std::size_t>(std::countr_zero(m));
    ok &= s.is_box() ? box_valid(s.boxes[k]) : sphere_valid(s.spheres[k]);
  }
  return ok;
}

}  // namespace

void RestSet::grow(std::size_t n) {
  // Every per-object array to n; the new objects' entries are set by find_changes(), which takes
  // them as objects that left their bounds (their copies, fat bounds and bits).
  n_ = n;
  const std::size_t words = (n + 63) / 64;
  if (box_lanes())
    resize_with_headroom(cur_box_, n);
  else
    resize_with_headroom(cur_sph_, n);
  if (fat() && box_lanes()) {
    resize_with_headroom(fat_box_, n);
  } else if (fat()) {
    resize_with_headroom(fat_sph_, n);
    resize_with_headroom(fat_r_, n);
  }
  recent_bits_.resize(words, 0);
  changed_bits_.resize(words, 0);
  left_bits_.resize(words, 0);
  // part_of_ never shrinks: delta's ids may still name objects that vanished (not in it).
  if (part_of_.size() < n) part_of_.resize(n, kNowhere);
  resize_with_headroom(local_, n);
  if (counts_pairs()) {
    a_count_.resize(n, 0);
    a_bits_.resize(words, 0);
  }
}

void RestSet::forget_vanished() {
  const std::size_t old_n = n_ + vanished_, words = (n_ + 63) / 64;
  const auto cut = [&](std::vector<std::uint64_t>& bits) {
    if (bits.size() > words) bits.resize(words);
    if (n_ % 64 != 0 && words > 0 && bits.size() == words) bits[words - 1] &= (std::uint64_t{1} << (n_ % 64)) - 1;
  };
  if (box_lanes())
    cur_box_.resize(n_);
  else
    cur_sph_.resize(n_);
  if (fat_box_.size() > n_) fat_box_.resize(n_);
  if (fat_sph_.size() > n_) fat_sph_.resize(n_);
  if (fat_r_.size() > n_) fat_r_.resize(n_);
  std::fill(part_of_.begin() + static_cast<std::ptrdiff_t>(n_), part_of_.begin() + static_cast<std::ptrdiff_t>(old_n),
            std::uint8_t{kNowhere});
  for (auto* bits : {&recent_bits_, &changed_bits_, &left_bits_, &a_bits_, &pair_bits_}) cut(*bits);
  if (a_count_.size() > n_) {
    VISCD_ASSERT(std::all_of(a_count_.begin() + static_cast<std::ptrdiff_t>(n_), a_count_.end(),
                             [](std::uint32_t c) { return c == 0; }),
                 "a vanished object's candidates were dropped");
    a_count_.resize(n_);
  }
  vanished_ = 0;
}

Status RestSet::find_changes(const Input& in, int threads, std::size_t limit, std::size_t old_n, bool& few) {
  const Shapes& s = in.objects;
  // The last frame's objects that are still here are compared (those from old_n on are new, those
  // from n_ on vanished). A frame with a new count needs no list (docs/embedding.md): then every
  // one is compared.
  const bool listed = in.moved_listed && old_n == n_;
  const std::size_t compared = std::min(old_n, n_);
  // The objects to compare: the listed ones, or all of them, in chunks of whole bitset words (so
  // that each chunk sets the bits of its own words). A changed object's shape is taken at once.
  const std::size_t count = listed ? in.moved.size() : (compared + 63) / 64;
  const std::size_t chunks = std::max<std::size_t>(1, ranges_for(listed ? count : compared, threads));
  chunk_left_.resize(std::max(chunk_left_.size(), chunks));
  chunk_margin_.resize(std::max(chunk_margin_.size(), chunks));
  std::atomic<std::size_t> left_total{0};
  std::atomic<bool> over{false};
  const bool boxes = s.is_box();
  // Whether object k (changed: its new shape in s) stays inside its fat bounds: the rest
  // margin's, or its own in recent (move_margin). Those in recent are counted: recent is built
  // over them too.
  const bool own = move_margin_ > 0;
  const std::uint64_t* const in_recent = recent_bits_.data();
  std::atomic<std::size_t> pending_total{0};
  const auto stays = [&](std::uint32_t k, std::size_t& pending) {
    if (margin_ > 0) {
      if (!inside_fat(s, k)) return false;
      pending += own && bit(in_recent, k);
      return true;
    }
    if (!own || !bit(in_recent, k) || !inside_fat(s, k)) return false;
    ++pending;
    return true;
  };
  std::atomic<std::size_t> changed_total{0};
  for_chunks(count, chunks, [&](std::size_t b, std::size_t e, std::size_t c) {
    std::vector<std::uint32_t>& left = chunk_left_[c];
    std::vector<float>& margin = chunk_margin_[c];
    std::size_t changed_in_chunk = 0, pending = 0;
    left.clear();
    margin.clear();
    // One that left (its copy not yet taken: margin_of() reads it): its bit, list entry and
    // margin; false once the frame has too many to follow.
    const auto note_left = [&](std::uint32_t k, std::uint64_t* word) {
      *word |= std::uint64_t{1} << (k & 63);
      left.push_back(k);
      if (fat()) margin.push_back(margin_of(s, k));
      if ((left.size() & 63) == 0 && left_total.fetch_add(64, std::memory_order_relaxed) + 64 > limit) {
        over.store(true, std::memory_order_relaxed);
        return false;
      }
      return !over.load(std::memory_order_relaxed);
    };
    if (!listed) {
      // A word of 64 objects at a time: which changed (compares without branches), their shapes
      // taken, then the fat-bounds test on those alone. The chunk owns its words.
      for (std::size_t w = b; w < e; ++w) {
        const std::size_t first = w * 64, last = std::min(compared, first + 64);
        std::uint64_t mask = 0;
        if (boxes) {
          for (std::size_t k = first; k < last; ++k)
            mask |= std::uint64_t{!same_bits(s.boxes[k], cur_box_[k])} << (k - first);
        } else {
          for (std::size_t k = first; k < last; ++k)
            mask |= std::uint64_t{!same_bits(s.spheres[k], cur_sph_[k])} << (k - first);
        }
        if (mask == 0) continue;
        if (in.unvalidated && !changed_valid(s, first, last, mask)) {
          over.store(true, std::memory_order_relaxed);  // the caller names it; the set starts again
          break;
        }
        changed_bits_[w] = mask;
        changed_in_chunk += static_cast<std::size_t>(std::popcount(mask));  // the list comes from the bits
        for (std::uint64_t m = mask; m; m &= m - 1) {
          const auto k = static_cast<std::uint32_t>(first + static_cast<std::size_t>(std::countr_zero(m)));
          const bool go_on = stays(k, pending) || note_left(k, &left_bits_[w]);
          if (boxes)
            cur_box_[k] = s.boxes[k];
          else
            cur_sph_[k] = s.spheres[k];
          if (!go_on) break;
        }
        if (over.load(std::memory_order_relaxed)) break;
      }
      changed_total.fetch_add(changed_in_chunk, std::memory_order_relaxed);
      pending_total.fetch_add(pending, std::memory_order_relaxed);
      return;
    }
    // The chunk's ends moved past entries of the word before them, so that no two chunks set
    // bits in one word (the list is ascending).
    const auto word_start = [&](std::size_t t) {
      while (t > 0 && t < count && (in.moved[t] >> 6) == (in.moved[t - 1] >> 6)) ++t;
      return t;
    };
    e = word_start(e);
    constexpr std::size_t kAhead = 32;  // reads in flight: each one a miss at 10^6 objects
    const bool has_fat = fat();
    const Shapes last = objects();
    const Shapes fat_bounds =
        boxes ? Shapes(std::span<const Box>(fat_box_)) : Shapes(std::span<const Sphere>(fat_sph_));
    for (std::size_t t = word_start(b); t < e; ++t) {
      const std::uint32_t k = in.moved[t];
      if (t + kAhead < e) {  // listed objects lie scattered: their shapes, copies and fat bounds read ahead
        const std::uint32_t ahead = in.moved[t + kAhead];
        s.prefetch(ahead);
        last.prefetch(ahead);
        if (has_fat) {
          fat_bounds.prefetch(ahead);
          if (!boxes) __builtin_prefetch(fat_r_.data() + ahead);
        }
      }
      if (boxes ? same_bits(s.boxes[k], cur_box_[k]) : same_bits(s.spheres[k], cur_sph_[k])) continue;
      // The rule inline (changed_valid() is for a word's worth of objects).
      if (in.unvalidated && !(boxes ? box_valid(s.boxes[k]) : sphere_valid(s.spheres[k]))) {
        over.store(true, std::memory_order_relaxed);  // the caller names it; the set starts again
        break;
      }
      ++changed_in_chunk;
      changed_bits_[k >> 6] |= std::uint64_t{1} << (k & 63);
      const bool go_on = stays(k, pending) || note_left(k, &left_bits_[k >> 6]);
      if (boxes)
        cur_box_[k] = s.boxes[k];
      else
        cur_sph_[k] = s.spheres[k];
      if (!go_on) break;
    }
    changed_total.fetch_add(changed_in_chunk, std::memory_order_relaxed);
    pending_total.fetch_add(pending, std::memory_order_relaxed);
  });
  few = !over.load();
  // Ascending: each chunk's in order (the listed objects ascend, the words are read in order), the
  // chunks one after another.
  left_.clear();
  const std::size_t used = std::min(chunks, count);
  left_margin_.clear();
  for (std::size_t c = 0; c < used; ++c) {
    left_.insert(left_.end(), chunk_left_[c].begin(), chunk_left_[c].end());
    left_margin_.insert(left_margin_.end(), chunk_margin_[c].begin(), chunk_margin_[c].end());
  }
  // The new objects (after the last frame's count) are placed as objects that left are, with the
  // rest margin; they come last, so left_ still ascends. The caller validated them (a new count:
  // the set did not follow these objects, follows()).
  if (few)
    for (std::size_t k = old_n; k < n_; ++k) {
      if (in.unvalidated && !(boxes ? box_valid(s.boxes[k]) : sphere_valid(s.spheres[k]))) {
        few = false;  // the caller names it; the set starts again
        break;
      }
      changed_bits_[k >> 6] |= std::uint64_t{1} << (k & 63);
      left_bits_[k >> 6] |= std::uint64_t{1} << (k & 63);
      left_.push_back(static_cast<std::uint32_t>(k));
      if (fat()) left_margin_.push_back(margin_);
      if (boxes)
        cur_box_[k] = s.boxes[k];
      else
        cur_sph_[k] = s.spheres[k];
    }
  // The objects that vanished (from n_ to old_n) leave their trees and take their candidates with
  // them, as objects that left do, but are not placed again: their left bits alone (none changed),
  // and no margin. They come last, so left_ still ascends.
  if (few)
    for (std::size_t k = n_; k < old_n; ++k) {
      left_bits_[k >> 6] |= std::uint64_t{1} << (k & 63);
      left_.push_back(static_cast<std::uint32_t>(k));
    }
  // The changed objects are the bits alone, counted here. Every object in a jiggling pile
  // changes, and a list of them all cost a store per object; with a tenth of 10^6 objects listed
  // in FrameInput::moved, the list made the listed pass slower than comparing every object.
  changed_count_ = changed_total.load() + (few && n_ > old_n ? n_ - old_n : 0);
  // Recent is built over the objects that left and those of its own that moved inside their
  // bounds: both count against the limit.
  if (left_.size() + pending_total.load() > limit) few = false;
  if (listed && in.verify_moved) {
    // Every object the list leaves out must be bit for bit the previous frame's.
    std::size_t at = 0;
    for (std::uint32_t k = 0; k < n_; ++k) {  // (listed: no objects were added)
      while (at < in.moved.size() && in.moved[at] < k) ++at;
      if (at < in.moved.size() && in.moved[at] == k) continue;
      const bool same = boxes ? same_bits(s.boxes[k], cur_box_[k]) : same_bits(s.spheres[k], cur_sph_[k]);
      if (!same)
        return Status::failure(ErrorKind::invalid_input,
                               "FrameInput::moved leaves out object " + std::to_string(k) +
                                   ", whose bounds changed since the previous frame (found by Config::verify_moved)");
    }
  }
  return {};
}

bool RestSet::static_pairs_of(const BucketBroadphase& tree, std::span<const std::uint32_t> ids, StaticTree& st,
                              int threads, std::vector<std::uint64_t>& out, const std::uint16_t* search) {
  if (!st.pairs(tree, {}, false, simd_, threads, std::numeric_limits<std::size_t>::max(), out, search)) return false;
  // Tree ids to object indices: `ids` ascend, so the order stays.
  parallel_for(out.size(), threads, [&](std::size_t k) { out[k] = pair_key(ids[key_i(out[k])], key_j(out[k])); });
  return true;
}

Status RestSet::update(const Input& in, const StaticSet& set, StaticTree& st, int threads, FrameStats& stats) {
  Stopwatch sw;
  const Shapes& s = in.objects;
  // left_ ends with the objects that vanished (vanished_ of them, from n_ on): taken out of their
  // trees with their candidates, never placed.
  const std::size_t placed = left_.size() - vanished_;
  stats.moved = static_cast<std::uint32_t>(changed_count_);
  stats.replaced = static_cast<std::uint32_t>(placed);
  woken_ = 0;
  // Nothing changed: every candidate keeps its result.
  if (changed_count_ == 0 && left_.empty()) return {};
  // find_changes() took the changed shapes and set their bits. The objects that left their fat
  // bounds leave their trees, in parallel chunks (each erases its own objects' lanes; the
  // objects lie scattered over memory, and the reads ahead are prefetched). Recent is built anew
  // below over the objects that left: its own among them keep their part_of_ and are not erased
  // (objects that move frame after frame would otherwise cost two scattered writes and an erase
  // each), and its others come to rest in delta.
  parts_[kMain].tree.index_positions(threads);
  parts_[kDelta].tree.index_positions(threads);
  constexpr std::size_t kMaxChunks = 64;
  std::size_t erased[3][kMaxChunks] = {};
  const std::size_t erase_chunks = std::min(ranges_for(left_.size(), threads), kMaxChunks);
  for_chunks(left_.size(), erase_chunks, [&](std::size_t b, std::size_t e, std::size_t c) {
    constexpr std::size_t kAhead = 8;
    for (std::size_t t = b; t < e; ++t) {
      if (t + kAhead < e) {
        __builtin_prefetch(&part_of_[left_[t + kAhead]]);
        __builtin_prefetch(&local_[left_[t + kAhead]]);
      }
      const std::uint32_t k = left_[t];
      const std::uint8_t p = part_of_[k];
      if (p == kMain || p == kDelta) {
        parts_[p].tree.erase(local_[k]);
        ++erased[p][c];
        part_of_[k] = kNowhere;
      }
      if (fat() && k < n_) place(s, k, left_margin_[t]);
    }
  });
  for (std::size_t p = 0; p < 3; ++p)
    for (std::size_t c = 0; c < erase_chunks; ++c) parts_[p].erased += erased[p][c];
  // The old recent objects that did not move again come to rest in delta; with move_margin, those
  // that moved inside their own bounds stay in recent, in their order, and the objects that left
  // join them. Only the ones that left search.
  Part& delta = parts_[kDelta];
  Part& recent = parts_[kRecent];
  const bool own = move_margin_ > 0;
  const std::uint64_t* const left_bits = left_bits_.data();
  const std::uint64_t* const changed_bits = changed_bits_.data();
  scratch_.clear();
  recent_next_.clear();
  // With a rest margin, the old recent objects that did not leave again wait in recent (their
  // lanes hold their fat bounds, as delta's would; they do not search) while they are few, and go
  // to delta all at once when they pass kWaitMost: delta is then rebuilt every few frames instead
  // of every frame, and the objects that keep moving inside their own margins are not built into
  // recent frame after frame. With own margins alone, those that did not move again wait so too
  // (their lanes hold the bounds they were placed with, which hold their own; any change of
  // theirs is a leave, their own margin bit being clear), and those that moved stay in recent.
  const bool waits = margin_ > 0;
  for (std::size_t t = 0; t < recent.ids.size(); ++t) {
    if (t + 16 < recent.ids.size()) __builtin_prefetch(&part_of_[recent.ids[t + 16]]);
    const std::uint32_t o = recent.ids[t];
    if (part_of_[o] != kRecent || o >= n_) continue;  // (vanished: forgotten after the frame)
    const bool moves = bit(left_bits, o) || (own && bit(changed_bits, o));
    if (waits ? !bit(left_bits, o) : !moves)  // (waiting, those that left come from left_ below)
      scratch_.push_back(o);
    else if (!waits && own)
      recent_next_.push_back(o);  // own margins alone: it stays, in its order, while it moves
  }
  if ((waits || own) && scratch_.size() <= kWaitMost) {  // they wait in recent, after its movers
    recent_next_.insert(recent_next_.end(), scratch_.begin(), scratch_.end());
    scratch_.clear();
  }
  // Own-margin bits (margin_of()) say "moved in the last frame": set for the objects that left and
  // for those that stay in recent and changed (every one that left changed); clear for those that
  // go to delta and the waiting ones that did not change.
  if (own) {
    // Woken: not in recent, or waiting there (its candidates may have been merged into the main
    // list since); the bits still say who moved in the last frame.
    woken_ = 0;
    for (const std::uint32_t o : left_) woken_ += part_of_[o] != kRecent || !bit(recent_bits_.data(), o);
    for (const std::uint32_t o : scratch_) recent_bits_[o >> 6] &= ~(std::uint64_t{1} << (o & 63));
    for (const std::uint32_t o : recent_next_)
      recent_bits_[o >> 6] =
          (recent_bits_[o >> 6] & ~(std::uint64_t{1} << (o & 63))) | (std::uint64_t{bit(changed_bits, o)} << (o & 63));
    for (const std::uint32_t o : std::span<const std::uint32_t>(left_).first(placed))
      recent_bits_[o >> 6] |= std::uint64_t{1} << (o & 63);
  }
  // Then the objects placed again (ascending when nothing stays); with own margins alone, those
  // that were in recent are there already.
  for (const std::uint32_t o : std::span<const std::uint32_t>(left_).first(placed))
    if (waits || !own || part_of_[o] != kRecent) recent_next_.push_back(o);
  if (!scratch_.empty()) {
    for (const std::uint32_t o : delta.ids)
      if (part_of_[o] == kDelta) scratch_.push_back(o);
    build_part(delta, scratch_, kDelta, true, threads, nullptr);
    ++delta_builds_;
  }
  // The objects that left their fat bounds, placed again: their tree, and its pairs.
  // When every object of recent left, its own search finds their pairs among themselves; else
  // the ones that left search recent below, as they search main and delta.
  const bool all_search = recent_next_.size() == placed;
  local_pairs_.clear();
  build_part(recent, recent_next_, kRecent, true, threads, all_search ? &local_pairs_ : nullptr);
  stats.ms(Stage::build) += sw.lap();
  // Their new candidates: among themselves, and with main's and delta's objects.
  found_.resize(local_pairs_.size());
  for (std::size_t k = 0; k < local_pairs_.size(); ++k) {
    const std::uint32_t a = recent.ids[local_pairs_[k].i], b = recent.ids[local_pairs_[k].j];
    found_[k] = a < b ? pair_key(a, b) : pair_key(b, a);
  }
  // The lanes of recent's buckets whose objects search (all of them unless some only moved
  // inside their own bounds).
  const std::uint16_t* search = nullptr;
  if (!all_search) {
    const std::span<const std::uint32_t> by_pos = recent.objects_by_position();
    search_.assign(buckets_for(recent.count), 0);
    for (std::size_t q = 0; q < by_pos.size(); ++q)
      search_[q / kBucket] |= static_cast<std::uint16_t>(bit(left_bits, by_pos[q]) << (q % kBucket));
    search = search_.data();
  }
  if (placed > 0) {
    const std::size_t groups = (buckets_for(recent.count) + kWide - 1) / kWide;
    const std::size_t chunks = threads_for(placed * 8, threads) == 1 ? 1 : std::min<std::size_t>(groups, 4 * threads);
    if (chunk_keys_.size() < chunks) chunk_keys_.resize(chunks);
    const std::uint32_t* const mat = recent.objects_by_position().data();
    for_chunks(groups, chunks, [&](std::size_t gb, std::size_t ge, std::size_t c) {
      std::vector<std::uint64_t>& list = chunk_keys_[c];
      list.clear();
      for (const std::uint8_t p : {kMain, kDelta, kRecent}) {
        const Part& other = parts_[p];
        if (other.count == other.erased || (p == kRecent && all_search)) continue;
        const std::uint32_t* const at = other.objects_by_position().data();
        // Recent against itself: each pair once (a searching lane meets itself, and two
        // searching lanes meet each other twice).
        const bool self = p == kRecent;
        auto found = [&](std::size_t pos, std::size_t q) {
          if (self && (q == pos || ((search[q / kBucket] >> (q % kBucket)) & 1 && q < pos))) return;
          const std::uint32_t a = mat[pos], b = at[q];
          list.push_back(a < b ? pair_key(a, b) : pair_key(b, a));
        };
        auto fetch = [&](std::size_t q) { __builtin_prefetch(&at[q]); };  // a bucket's 16: one line
        const CrossWalk walk = cross_walk_for(placed, other.count - other.erased);
        for (std::size_t g = gb; g < ge; ++g) {
          if (box_lanes())
            cross_pairs_at<BoxTests>(simd_, recent.tree, other.tree, g, walk, search, found, fetch);
          else
            cross_pairs_at<SphereTests>(simd_, recent.tree, other.tree, g, walk, search, found, fetch);
        }
      }
    });
    // Sorted all at once with the pairs among the movers (found_, as one more list), as stage 8
    // sorts its pairs: bucketed by the high bits of the first index, each bucket sorted on its own
    // (sorting each chunk's list and merging the lists in turn had cost 3.8 ms at 10 % of 10^6
    // moving).
    const std::size_t used = std::min(chunks, groups);
    if (chunk_keys_.size() < used + 1) chunk_keys_.resize(used + 1);
    chunk_keys_[used].swap(found_);
    sort_chunk_keys(std::span<const std::vector<std::uint64_t>>(chunk_keys_.data(), used + 1),
                    static_cast<std::uint32_t>(n_), key_offsets_, key_scratch_, found_, threads);
  }

  // The static candidates of the objects placed again, from recent's lanes (their new bounds;
  // its objects that moved inside their own bounds keep theirs).
  stat_found_.clear();
  if (!set.empty() && placed > 0) {
    // Only the lanes of the objects placed again search (`search`, when recent holds others too).
    if (!static_pairs_of(recent.tree, recent.ids, st, threads, stat_found_, search))
      return check_pair_cap(SIZE_MAX, in.pair_memory_cap, true);
    // Recent's own objects come first, in their order: its ids need not ascend.
    if (!std::is_sorted(stat_found_.begin(), stat_found_.end())) std::sort(stat_found_.begin(), stat_found_.end());
  }

  // The candidates: those of objects that stayed in their fat bounds, tested again where one of
  // them changed, merged with the new ones (tested then): emit() does it while it writes the
  // pairs. When no object left its fat bounds (objects jiggling in place), the list stays: tested
  // again in place here. With own margins alone, the new ones and those of objects in recent live
  // in the side list (update_side()); the candidates of objects that left are dropped in place by
  // emit(), and it merges the side list into them only when it has grown (the rewrite of 10^6
  // objects' candidates had cost a fifth of a frame with 1 % moving).
  if (own_alone()) {
    update_side(s, threads);
    merge_ = side_unmarked_ + dropped_ > std::max(kSideFloor, candidate_count() / kSideShare);
  } else if (left_.empty()) {
    // Tested again in place; the candidates whose result changed kept for the counts of the
    // objects in pairs (with a rest margin: note_pairs()).
    const std::size_t nc = segs_.size();
    open_change_lists(nc);
    for_chunks(nc, nc, [&](std::size_t c, std::size_t, std::size_t) {
      std::vector<std::uint64_t>& gone = chunk_gone_[c];
      std::vector<std::uint64_t>& added = chunk_added_[c];
      for (std::size_t a = segs_[c].begin; a < segs_[c].end; ++a) {
        const std::uint32_t i = key_i(cand_[a]), j = key_j(cand_[a]);
        if (!(bit(changed_bits_.data(), i) | bit(changed_bits_.data(), j))) continue;
        const bool now = s.overlap(i, j);
        if (now != ((hit_[a] & 1) != 0)) (now ? added : gone).push_back(cand_[a]);
        hit_[a] = now;
      }
    });
    if (counts_pairs()) count_changes();
  } else {
    merge_ = true;  // emit() merges as it goes: one pass over the candidates for both
  }
  // The static candidates: those of objects placed again replaced by the ones found above, and
  // tested, the others tested again where their object changed (inside its fat bounds).
  if (!set.empty()) {
    retest_static(s, set);
    if (!left_.empty()) splice_static(s, set);
  }
  stats.ms(Stage::query) += sw.lap();

  // Main rebuilt when its lanes hold too many erased objects or too many rest outside it, over
  // the resting objects: this frame's movers stay in recent (objects that move frame after frame
  // would otherwise be built into main only to be erased from it again the next frame).
  ++frames_since_main_;
  if (++calm_frames_ >= kChurnForgive) churn_backoff_ = kChurnWait;
  if (parts_[kMain].erased + delta.count > std::max(kMainRebuildFloor, n_ / 8)) {
    if (frames_since_main_ < kChurnFrames && delta.count * 4 > std::max(kMainRebuildFloor, n_ / 8)) {
      churned_ = true;  // the next frame gives up (this one's candidates are complete already)
      calm_frames_ = 0;
      return {};
    }
    frames_since_main_ = 0;
    scratch_.clear();
    for (std::uint32_t k = 0; k < n_; ++k)
      if (part_of_[k] != kRecent) scratch_.push_back(k);
    build_part(parts_[kMain], scratch_, kMain, true, threads, nullptr);
    delta.count = delta.erased = 0;
    delta.ids.clear();
    ++main_rebuilds_;
    stats.ms(Stage::build) += sw.lap();
  }
  return {};
}

void RestSet::retest_static(const Shapes& s, const StaticSet& set) {
  const std::uint64_t* const changed = changed_bits_.data();
  const std::uint64_t* const keys = stat_.data();
  std::uint8_t* const hits = stat_hit_.data();
  const std::size_t count = stat_.size();
  if (changed_count_ * 4 > n_) {
    // Many objects changed (a settling pile, where a third to a half of them jiggle each frame):
    // whether an entry's object changed is a coin toss, so every entry is tested and the result
    // taken without a branch. A static box or sphere is read either way. (The entries of objects
    // that vanished, unchanged, are still here until splice_static(): they test object 0.)
    const std::uint32_t n = static_cast<std::uint32_t>(n_);
    for (std::size_t t = 0; t < count; ++t) {
      const std::uint32_t i = key_i(keys[t]);
      const std::uint8_t now = static_overlap(s, set, i < n ? i : 0, key_j(keys[t]));
      const auto mask = static_cast<std::uint8_t>(0u - bit(changed, i));
      hits[t] = static_cast<std::uint8_t>((now & mask) | (hits[t] & ~mask));
    }
    return;
  }
  for (std::size_t t = 0; t < count; ++t) {
    const std::uint32_t i = key_i(keys[t]);
    if (bit(changed, i)) hits[t] = static_overlap(s, set, i, key_j(keys[t]));
  }
}

void RestSet::splice_static(const Shapes& s, const StaticSet& set) {
  // Each object owns a run of the sorted list (keys {object, static index}). The run of every
  // object placed again is replaced by its new entries in stat_found_ (which holds only such
  // objects' entries: only their lanes searched; any other object found there has its run
  // replaced the same way), and the runs between are copied whole.
  const std::span<const std::uint32_t> left = left_;  // ascending (find_changes())
  VISCD_ASSERT(std::is_sorted(left.begin(), left.end()), "the objects placed again ascend");
  const std::size_t count = stat_.size(), found = stat_found_.size();
  resize_with_headroom(stat_next_, count + found);
  resize_with_headroom(stat_hit_next_, count + found);
  const std::uint64_t* const keys = stat_.data();
  std::size_t from = 0, at = 0, f = 0, l = 0;
  const auto copy_to = [&](std::size_t end) {
    std::copy(keys + from, keys + end, stat_next_.data() + at);
    std::copy(stat_hit_.data() + from, stat_hit_.data() + end, stat_hit_next_.data() + at);
    at += end - from;
    from = end;
  };
  constexpr std::uint32_t kNone = ~std::uint32_t{0};
  while (l < left.size() || f < found) {
    const std::uint32_t o = std::min(l < left.size() ? left[l] : kNone, f < found ? key_i(stat_found_[f]) : kNone);
    l += l < left.size() && left[l] == o;
    copy_to(static_cast<std::size_t>(std::lower_bound(keys + from, keys + count, pair_key(o, 0)) - keys));
    for (; f < found && key_i(stat_found_[f]) == o; ++f, ++at) {
      stat_next_[at] = stat_found_[f];
      stat_hit_next_[at] = static_overlap(s, set, o, key_j(stat_found_[f]));
    }
    while (from < count && key_i(keys[from]) == o) ++from;  // its old run, dropped
  }
  copy_to(count);
  stat_next_.resize(at);
  stat_hit_next_.resize(at);
  stat_.swap(stat_next_);
  stat_hit_.swap(stat_hit_next_);
}

void RestSet::follow_static(const Shapes& s, const StaticSet& set, std::span<const std::uint32_t> slots) {
  if (slots.empty()) return;
  // The entries naming a changed slot, of objects not placed again this frame, are dropped (an
  // object placed again searched the static trees as they are now: splice_static()).
  resize_with_headroom(static_changed_, (set.slot_count() + 63) / 64);
  std::fill(static_changed_.begin(), static_changed_.end(), std::uint64_t{0});
  for (const std::uint32_t k : slots) static_changed_[k >> 6] |= std::uint64_t{1} << (k & 63);
  const std::uint64_t* const left = left_bits_.data();
  std::size_t kept = 0;
  for (std::size_t t = 0; t < stat_.size(); ++t) {
    const std::uint64_t key = stat_[t];
    const std::uint32_t slot = static_slot(key_j(key));
    stat_[kept] = key;
    stat_hit_[kept] = stat_hit_[t];
    kept += !(bit(static_changed_.data(), slot) && !bit(left, key_i(key)));
  }
  stat_.resize(kept);
  stat_hit_.resize(kept);
  // Each changed slot that lives finds the moving objects whose bounds in their trees (fat, or
  // exact) meet it: a query of each tree with the static object, whose lane tests are the ones
  // the static trees' search of that tree's lanes makes (box lanes against a box, the sphere
  // test on sphere lanes). The objects placed again are left out: their entries are new already.
  near_.clear();
  for (const std::uint32_t k : slots) {
    if (!set.live(k)) continue;
    for (const Part& part : parts_) {
      if (part.count == part.erased) continue;
      const BucketBroadphase::Objects objects{part.by_index ? std::span<const std::uint32_t>() : part.ids, {}};
      near_hits_.clear();
      if (s.is_box())
        part.tree.overlap_box(set.box(k), objects, nullptr, near_hits_);
      else
        part.tree.overlap(set.sphere(k), objects, nullptr, near_hits_);
      for (const std::uint32_t o : near_hits_)
        if (!bit(left, o)) near_.push_back(pair_key(o, static_index(k)));
    }
  }
  if (near_.empty()) return;
  std::sort(near_.begin(), near_.end());
  near_.erase(std::unique(near_.begin(), near_.end()), near_.end());
  // Merged into the list, each tested.
  const std::size_t count = stat_.size(), found = near_.size();
  resize_with_headroom(stat_next_, count + found);
  resize_with_headroom(stat_hit_next_, count + found);
  std::size_t a = 0, b = 0, at = 0;
  while (a < count || b < found) {
    if (b == found || (a < count && stat_[a] < near_[b])) {
      stat_next_[at] = stat_[a];
      stat_hit_next_[at++] = stat_hit_[a++];
    } else {
      VISCD_ASSERT(a == count || stat_[a] != near_[b], "a changed slot's entry was dropped");
      stat_next_[at] = near_[b];
      stat_hit_next_[at++] = static_overlap(s, set, key_i(near_[b]), key_j(near_[b]));
      ++b;
    }
  }
  stat_next_.resize(at);
  stat_hit_next_.resize(at);
  stat_.swap(stat_next_);
  stat_hit_.swap(stat_hit_next_);
}

void RestSet::count_candidates() {
  a_count_.clear();
  a_bits_.clear();
  if (!counts_pairs()) return;
  a_count_.assign(n_, 0);
  a_bits_.assign((n_ + 63) / 64, 0);
  for (const Segment& g : segs_)
    for (std::size_t a = g.begin; a < g.end; ++a)
      if (hit_[a] & 1) {
        ++a_count_[key_i(cand_[a])];
        ++a_count_[key_j(cand_[a])];
      }
  for (std::uint32_t k = 0; k < n_; ++k)
    if (a_count_[k] > 0) a_bits_[k >> 6] |= std::uint64_t{1} << (k & 63);
}

template <class StaticOk>
void RestSet::note_pairs(bool known, bool all_pass, const StaticOk& static_ok) {
  count_changes();
  if (!known) return;
  // The frame's pairs: the candidates' that hold, the side list's that hold, and every static
  // pair's moving object.
  resize_with_headroom(pair_bits_, a_bits_.size());
  std::copy(a_bits_.begin(), a_bits_.end(), pair_bits_.begin());
  auto set = [&](std::uint32_t o) { pair_bits_[o >> 6] |= std::uint64_t{1} << (o & 63); };
  for (std::size_t t = 0; t < side_.size(); ++t)
    if (side_hit_[t] & 1) {
      set(key_i(side_[t]));
      set(key_j(side_[t]));
    }
  for (std::size_t t = 0; t < stat_.size(); ++t)
    if ((stat_hit_[t] & 1) && (all_pass || static_ok(stat_[t]))) set(key_i(stat_[t]));
  pair_bits_ok_ = true;
}

void RestSet::open_change_lists(std::size_t chunks) {
  // Every list, not only those of the chunks to come: a frame that failed before counting its
  // changes (the pair cap) may have left entries behind.
  if (chunk_gone_.size() < chunks) chunk_gone_.resize(chunks);
  if (chunk_added_.size() < chunks) chunk_added_.resize(chunks);
  for (auto& list : chunk_gone_) list.clear();
  for (auto& list : chunk_added_) list.clear();
}

void RestSet::count_changes() {
  // Counts first, then the bits of every object whose count moved (one may lose a candidate and
  // gain another in the same frame). Every list is emptied once counted, so that no change is
  // counted twice when the next frame has fewer chunks.
  for (const auto& list : chunk_gone_)
    for (const std::uint64_t k : list) {
      --a_count_[key_i(k)];
      --a_count_[key_j(k)];
    }
  for (const auto& list : chunk_added_)
    for (const std::uint64_t k : list) {
      ++a_count_[key_i(k)];
      ++a_count_[key_j(k)];
    }
  auto settle = [&](std::uint32_t o) {
    const std::uint64_t m = std::uint64_t{1} << (o & 63);
    a_bits_[o >> 6] = a_count_[o] > 0 ? a_bits_[o >> 6] | m : a_bits_[o >> 6] & ~m;
  };
  for (auto* lists : {&chunk_gone_, &chunk_added_})
    for (auto& list : *lists) {
      for (const std::uint64_t k : list) {
        settle(key_i(k));
        settle(key_j(k));
      }
      list.clear();
    }
}

void RestSet::update_side(const Shapes& s, int threads) {
  const std::uint64_t* const left = left_bits_.data();
  const std::uint64_t* const in_recent = recent_bits_.data();
  const std::uint64_t* const changed = changed_bits_.data();
  constexpr std::size_t kAhead = 16;  // tests whose shapes are in flight
  // found_, in chunks: each key's exact result (marked: found by a search of recent).
  found_hit_.resize(found_.size());
  for_chunks(found_.size(), ranges_for(found_.size(), threads), [&](std::size_t b, std::size_t e, std::size_t) {
    for (std::size_t t = b; t < e; ++t) {
      if (t + kAhead < e) {
        s.prefetch(key_i(found_[t + kAhead]));
        s.prefetch(key_j(found_[t + kAhead]));
      }
      found_hit_[t] = static_cast<std::uint8_t>(kRecheck | std::uint8_t{s.overlap(key_i(found_[t]), key_j(found_[t]))});
    }
  });
  // The side list in place, in chunks: an entry is dropped if one of its objects left (found anew
  // in found_); no longer marked when neither is in recent (then neither changed, and both hold
  // exact bounds: one that holds not is no candidate and is dropped); tested again when one of
  // them changed.
  std::uint8_t* const h = side_hit_.data();
  const std::uint64_t* const k = side_.data();
  for_chunks(side_.size(), ranges_for(side_.size(), threads), [&](std::size_t b, std::size_t e, std::size_t) {
    for (std::size_t t = b; t < e; ++t) {
      if (t + kAhead < e) {
        s.prefetch(key_i(k[t + kAhead]));
        s.prefetch(key_j(k[t + kAhead]));
      }
      const std::uint32_t i = key_i(k[t]), j = key_j(k[t]);
      if (bit(left, i) | bit(left, j)) {
        h[t] = kDrop;
      } else if (!(bit(in_recent, i) | bit(in_recent, j))) {
        h[t] = (h[t] & 1) != 0 ? std::uint8_t{1} : kDrop;
      } else if (bit(changed, i) | bit(changed, j)) {
        h[t] = static_cast<std::uint8_t>(kRecheck | std::uint8_t{s.overlap(i, j)});
      }
    }
  });
  // Merged with found_ (both sorted; a key is in one of them only: an entry of found_ has an
  // object that left, whose entries were dropped).
  resize_with_headroom(side_next_, side_.size() + found_.size());
  resize_with_headroom(side_hit_next_, side_.size() + found_.size());
  std::uint64_t* const nk = side_next_.data();
  std::uint8_t* const nh = side_hit_next_.data();
  std::size_t f = 0, at = 0, unmarked = 0;
  for (std::size_t t = 0; t < side_.size(); ++t) {
    if (h[t] & kDrop) continue;
    for (; f < found_.size() && found_[f] < k[t]; ++f, ++at) {
      nk[at] = found_[f];
      nh[at] = found_hit_[f];
    }
    nk[at] = k[t];
    nh[at] = h[t];
    ++at;
    unmarked += (h[t] & kRecheck) == 0;
  }
  for (; f < found_.size(); ++f, ++at) {
    nk[at] = found_[f];
    nh[at] = found_hit_[f];
  }
  side_next_.resize(at);
  side_hit_next_.resize(at);
  side_.swap(side_next_);
  side_hit_.swap(side_hit_next_);
  side_unmarked_ = unmarked;
}

Status RestSet::emit(const Input& in, const StaticSet& set, int threads, std::vector<Pair>& pairs) {
  const Shapes& shapes = in.objects;
  const bool masked = in.active.size() < n_;
  if (masked) {
    active_mask_.assign(n_, 0);
    for (const std::uint32_t k : in.active) active_mask_[k] = 1;
  }
  const std::span<const Filter> filters = in.filters;
  const std::uint8_t* const mask = active_mask_.data();
  // Whether a pair of moving objects that meet, or a pair with the static set, is reported.
  auto moving_ok = [&](std::uint32_t i, std::uint32_t j) {
    if (masked && !(mask[i] & mask[j])) return false;
    return filters.empty() || pair_passes_filter(filters[i], filters[j]);
  };
  // Unfiltered and unculled, with no static filter that refuses the default one: every static
  // pair passes (the test below is a call per entry, a fifth of a frame with a static set). The
  // flag is tested where the test is called: folded into a wrapping lambda, the frames with a
  // static set ran 10-30 % slower.
  const bool static_all = !masked && filters.empty() && set.default_refused() == 0;
  auto static_ok = [&](std::uint64_t k) {
    const std::uint32_t i = key_i(k);
    if (masked && !mask[i]) return false;
    return pair_passes_filter(filters.empty() ? Filter{} : filters[i], set.filter(static_slot(key_j(k))));
  };
  // Three sorted lists: the kept candidates (A, in segments), this frame's new ones (B: found_
  // when merging; with own margins alone the side list, always) and the static pairs (S), merged
  // chunk by chunk: chunk c takes segment c of A and the keys of B and S from the same cut. Keys
  // never reach kEnd (i < 2^31).
  constexpr std::uint64_t kEnd = ~std::uint64_t{0};
  const bool side = own_alone();
  const std::span<const std::uint64_t> b_keys = side     ? std::span<const std::uint64_t>(side_)
                                                : merge_ ? std::span<const std::uint64_t>(found_)
                                                         : std::span<const std::uint64_t>();
  const std::span<const std::uint64_t> s_keys = stat_;
  const std::size_t nc = segs_.size();
  for (auto* v : {&b_at_, &s_at_, &cand_ub_, &pair_ub_, &kept_, &out_, &drops_}) v->assign(nc + 1, 0);
  for (std::size_t c = 1; c < nc; ++c) {
    b_at_[c] = static_cast<std::size_t>(std::lower_bound(b_keys.begin(), b_keys.end(), cuts_[c]) - b_keys.begin());
    s_at_[c] = static_cast<std::size_t>(std::lower_bound(s_keys.begin(), s_keys.end(), cuts_[c]) - s_keys.begin());
  }
  b_at_[nc] = b_keys.size();
  s_at_[nc] = s_keys.size();
  // Where each chunk writes: where it would start if nothing were dropped.
  for (std::size_t c = 0; c < nc; ++c) {
    const std::size_t a = segs_[c].end - segs_[c].begin, b = b_at_[c + 1] - b_at_[c], t = s_at_[c + 1] - s_at_[c];
    cand_ub_[c + 1] = cand_ub_[c] + a + b;
    pair_ub_[c + 1] = pair_ub_[c] + a + b + t;
  }
  resize_with_headroom(pair_buf_, pair_ub_[nc]);
  if (merge_) {
    resize_with_headroom(cand_next_, cand_ub_[nc]);
    resize_with_headroom(hit_next_, cand_ub_[nc]);
  }
  // One chunk, templated on what it must do, every buffer read through a local pointer (the
  // writes of bytes may alias anything, and would reload members at every step). Each entry's
  // pair is written and the count moved past it only if it holds: no branch on the result.
  const std::uint64_t* const left = left_bits_.data();
  const std::uint64_t* const changed = changed_bits_.data();
  const bool wide = simd_ == SimdLevel::avx512;  // the direct pass's runs eight at a time
  // kRetest: 0, none (no fat bounds); 1, every candidate with an object that changed (the rest
  // margin); 2, own margins alone: B is the side list, tested by update_side(), and the candidates
  // of objects that left are dropped in place unless merging (A is never marked then).
  auto chunk = [&]<bool kMerge, bool kCheck, int kRetest, bool kDirect = false>(std::size_t c) {
    const std::uint64_t* const ak = cand_.data();
    std::uint8_t* const ah = hit_.data();
    const std::uint64_t* const bk = b_keys.data();
    const std::uint8_t* const fh = side_hit_.data();
    const std::uint64_t* const sk = s_keys.data();
    const std::uint8_t* const sh = stat_hit_.data();
    std::uint64_t* const nk = kMerge ? cand_next_.data() + cand_ub_[c] : nullptr;
    std::uint8_t* const nh = kMerge ? hit_next_.data() + cand_ub_[c] : nullptr;
    // kDirect: into the caller's list where the chunk's pairs go, never past the count expected
    // (the caller checks that it was met).
    Pair* const po = kDirect ? pairs.data() + out_[c] : pair_buf_.data() + pair_ub_[c];
    const std::size_t lim = kDirect ? out_[c + 1] - out_[c] : 0;
    auto put = [&](std::size_t at, Pair p) {
      if constexpr (kDirect) {
        if (at < lim) po[at] = p;
      } else {
        po[at] = p;
      }
    };
    std::size_t a = segs_[c].begin, b = b_at_[c], t = s_at_[c];
    const std::size_t ae = segs_[c].end, be = b_at_[c + 1], te = s_at_[c + 1];
    std::size_t kept = 0, out = 0, dropped = 0, other = 0;
    bool over = false;                                    // kDirect: the chunk's count was passed
    std::vector<std::uint64_t>& gone = chunk_gone_[c];    // candidates that held, dropped
    std::vector<std::uint64_t>& added = chunk_added_[c];  // side-list entries that hold, merged in
    // A candidate kept (when merging; a marked one stays in the side list) with its result, and
    // its pair if it holds.
    auto take = [&](std::uint64_t k, std::uint32_t i, std::uint32_t j, bool hit, std::uint8_t mark) {
      if constexpr (kMerge) {
        nk[kept] = k;
        nh[kept] = static_cast<std::uint8_t>(hit);
        kept += mark == 0;
      }
      put(out, Pair{i, j});
      if constexpr (kCheck) hit = hit && moving_ok(i, j);
      out += hit;
    };
    for (;;) {
      const std::uint64_t kb = b < be ? bk[b] : kEnd, kt = t < te ? sk[t] : kEnd;
      const std::uint64_t below = std::min(kb, kt);
      if constexpr (kDirect) {
#if VISCD_HAVE_AVX512
        if (wide)
          a = direct_run_avx512(ak, ah, a, ae, below, po, out, lim, over);
        else
#endif
          a = direct_run_scalar(ak, ah, a, ae, below, po, out, lim, over);
        if (over) break;
      }
      for (; a < ae && ak[a] < below; ++a) {
        const std::uint64_t k = ak[a];
        const std::uint32_t i = key_i(k), j = key_j(k);
        const std::uint8_t h = ah[a];
        bool hit = (h & 1) != 0;
        if constexpr (kRetest == 2) {
          if (h & kDrop) continue;
          if (bit(left, i) | bit(left, j)) {  // placed again: found anew in the side list
            if constexpr (!kMerge) {
              ah[a] = kDrop;
              ++dropped;
            }
            if (hit) gone.push_back(k);
            continue;
          }
        } else if constexpr (kMerge) {
          if (bit(left, i) | bit(left, j)) {  // placed again: found anew in B
            if constexpr (kRetest == 1)
              if (hit) gone.push_back(k);
            continue;
          }
          if constexpr (kRetest == 1)
            if (bit(changed, i) | bit(changed, j)) {
              const bool now = shapes.overlap(i, j);
              if (now != hit) (now ? added : gone).push_back(k);
              hit = now;
            }
        }
        take(k, i, j, hit, 0);
      }
      if (below == kEnd) break;
      const std::size_t before = out;
      if (kt < kb) {
        put(out, Pair{key_i(kt), key_j(kt)});
        out += (sh[t] & 1) && (static_all || static_ok(kt));
        ++t;
      } else {  // B holds keys only when merging or with the side list
        if constexpr (kRetest == 2) {
          const std::uint8_t fb = fh[b];
          take(kb, key_i(kb), key_j(kb), (fb & 1) != 0, fb & kRecheck);
          if constexpr (kMerge)
            if ((fb & 1) && !(fb & kRecheck)) added.push_back(kb);  // a candidate of cand_'s now
        } else if constexpr (kRetest == 1) {
          const bool hit = shapes.overlap(key_i(kb), key_j(kb));
          if (hit) added.push_back(kb);  // a new candidate that holds (the counts: note_pairs())
          take(kb, key_i(kb), key_j(kb), hit, 0);
        } else {
          take(kb, key_i(kb), key_j(kb), true, 0);
        }
        ++b;
      }
      other += out - before;
    }
    kept_[c] = kept;
    drops_[c] = dropped;
    if constexpr (kDirect) {
      direct_ok_[c] = !over && out == lim && dropped == 0;
    } else {
      out_[c] = out;
      a_out_[c] = out - other;
    }
  };
  const bool check = masked || !filters.empty();
  open_change_lists(nc);
  // With the side list, unfiltered, when no object woke from rest (then none of the candidates
  // is dropped: an object in recent has none but in the side list) and the candidates' pairs per
  // chunk are known from the last frame: each chunk's count is known before it runs, and the
  // pairs go straight into the caller's list. Should a chunk not meet its count, the frame is
  // merged again the usual way.
  if (side && !merge_ && !check && woken_ == 0 && a_out_valid_ && a_out_.size() == nc + 1) {
    std::size_t total = 0;
    for (std::size_t c = 0; c < nc; ++c) {
      std::size_t expect = a_out_[c];
      for (std::size_t b = b_at_[c]; b < b_at_[c + 1]; ++b) expect += side_hit_[b] & 1;
      for (std::size_t t = s_at_[c]; t < s_at_[c + 1]; ++t)
        expect += (stat_hit_[t] & 1) && (static_all || static_ok(s_keys[t]));
      out_[c] = total;
      total += expect;
    }
    out_[nc] = total;
    if (Status st = check_pair_cap(total, in.pair_memory_cap); !st) return st;
    pairs.resize(total);
    direct_ok_.assign(nc, 0);
    for_chunks(nc, nc,
               [&](std::size_t c, std::size_t, std::size_t) { chunk.template operator()<false, false, 2, true>(c); });
    if (std::all_of(direct_ok_.begin(), direct_ok_.end(), [](std::uint8_t ok) { return ok != 0; })) {
      ++direct_frames_;
      note_pairs(true, static_all, static_ok);
      return {};
    }
    ++direct_misses_;
  }
  a_out_.resize(nc + 1);
  for_chunks(nc, nc, [&](std::size_t c, std::size_t, std::size_t) {
    if (side) {
      if (merge_) {
        if (check)
          chunk.template operator()<true, true, 2>(c);
        else
          chunk.template operator()<true, false, 2>(c);
      } else if (check) {
        chunk.template operator()<false, true, 2>(c);
      } else {
        chunk.template operator()<false, false, 2>(c);
      }
    } else if (!merge_) {
      if (check)
        chunk.template operator()<false, true, 0>(c);
      else
        chunk.template operator()<false, false, 0>(c);
    } else if (margin_ > 0) {
      if (check)
        chunk.template operator()<true, true, 1>(c);
      else
        chunk.template operator()<true, false, 1>(c);
    } else {
      if (check)
        chunk.template operator()<true, true, 0>(c);
      else
        chunk.template operator()<true, false, 0>(c);
    }
  });
  if (side && !merge_)
    for (std::size_t c = 0; c < nc; ++c) dropped_ += drops_[c];
  // The candidates' pairs per chunk hold for the next frame unless they were filtered or merged.
  a_out_valid_ = side && !merge_ && !check;
  // The pairs into the caller's list, each chunk's at once.
  std::size_t total = 0;
  for (std::size_t c = 0; c < nc; ++c) {
    const std::size_t o = out_[c];
    out_[c] = total;
    total += o;
  }
  out_[nc] = total;
  if (Status s = check_pair_cap(total, in.pair_memory_cap); !s) return s;
  pairs.resize(total);
  for_chunks(nc, nc, [&](std::size_t c, std::size_t, std::size_t) {
    std::copy_n(pair_buf_.data() + pair_ub_[c], out_[c + 1] - out_[c], pairs.data() + out_[c]);
  });
  if (!merge_) {
    if (counts_pairs()) note_pairs(!check, static_all, static_ok);
    return {};
  }
  // The merged list becomes the candidates, in segments where the chunks wrote them; packed and
  // cut again when a chunk's share of the merge has grown past twice the mean.
  cand_.swap(cand_next_);
  hit_.swap(hit_next_);
  if (side) {  // its unmarked entries are candidates now; the marked ones stay
    std::size_t kept = 0;
    for (std::size_t t = 0; t < side_.size(); ++t) {
      side_[kept] = side_[t];
      side_hit_[kept] = side_hit_[t];
      kept += (side_hit_[t] & kRecheck) != 0;
    }
    side_.resize(kept);
    side_hit_.resize(kept);
    side_unmarked_ = dropped_ = 0;
  }
  if (counts_pairs()) note_pairs(!check, static_all, static_ok);
  std::size_t most = 0, sum = 0;
  for (std::size_t c = 0; c < nc; ++c) {
    segs_[c] = Segment{cand_ub_[c], cand_ub_[c] + kept_[c]};
    const std::size_t work = kept_[c] + s_at_[c + 1] - s_at_[c];
    most = std::max(most, work);
    sum += work;
  }
  if (nc != merge_chunks(sum, threads) || most > 2 * sum / nc + 4096) pack(threads);
  return {};
}

}  // namespace viscd::detail
