#pragma once
// Cost follows change (Config::follow_change): the cpu backend's broadphase for frames in which
// most objects keep their bounds. Every object sits in one of three trees of the bucket
// broadphase's kind, kept across frames: `main` (every object, built at some frame), `delta`
// (objects that moved since main was built and came to rest) and `recent` (the objects that moved
// in the last frame, and with Config::move_margin those that keep moving inside margins of their
// own). The candidate pairs of every two objects (their fat bounds overlap) are kept, sorted, with
// the exact result of each, and so are the exact pairs with the static set.
//
// A frame finds the objects that changed (FrameInput::moved, or a pass comparing bounds) and of
// those the ones that left their fat bounds (with Config::rest_margin 0: every one that changed).
// Those are taken out of their trees (their lanes become padding) and placed again (one that left
// from recent with a margin of its own, move_margin times its last move): recent is built over them
// and over its objects that moved inside their own margins, and only the ones placed again search
// it, main and delta for their new candidates; the objects of the old `recent` that did not move
// again join delta with their exact bounds (with a rest margin, every one of the old recent that
// did not leave again, and with own margins alone every one that did not change, waits in recent,
// not searching, until more than kWaitMost (rest_set.cpp) wait, and then they join delta
// together). Candidates of objects that changed but stayed inside their fat bounds are tested
// again (with own margins alone, the candidates found by searches of recent live in a side list,
// and only its marked entries are looked at: update_side(); the others are rewritten only when
// the side list is merged into them); the rest keep their result. The
// frame's pairs are the candidates that hold, whose objects are both active and whose filters
// accept each other: exactly the pairs of a frame that rebuilt everything (filters, culling and
// never-culled flags are applied to the carried candidates each frame, so they may change
// freely). When delta and the objects taken out of main pass an eighth of the objects, main is
// rebuilt over the resting ones (the frame's movers stay in recent).
//
// A frame costs the pass over the bounds (none with FrameInput::moved), the movers' tree and its
// searches, and one merging pass over the candidates and pairs. Objects added at the end (a count
// above the last frame's, by at most 1 in 5) are placed as objects that left are, and objects gone
// from the end (a count below it, by at most 1 in 5) leave their trees and candidates as those do
// and are not placed again; such a frame compares every object it kept (a new count needs no
// moved list). When more than 1 in 5 objects leave their fat bounds or move inside margins of
// their own in a frame, when their kind, the layout or the margin change, when the static set is
// replaced or changes in more slots than that (fewer are followed: follow_static()), when culling leaves
// fewer than half of the objects active (the candidates of culled objects would cost more than a
// culled rebuild saves), or when main comes due again within 3 frames of its last build with many
// objects come to rest in delta (new objects start and stop moving every frame), the set lets the
// frame rebuild and starts again later: while it is not in use it watches a sample of 256 objects
// (a new one each frame; objects added or removed since do not spoil it), and takes over when 5 in 6 of them
// rest (after such a give-up for churn, only after a wait that doubles each time).
// docs/architecture.md, "Resting objects".

#include <cstdint>
#include <span>
#include <vector>

#include "core/shapes.hpp"
#include "core/static_set.hpp"
#include "cpu/bucket_broadphase.hpp"
#include "cpu/static_tree.hpp"
#include "viscd/config.hpp"
#include "viscd/frame.hpp"
#include "viscd/result.hpp"
#include "viscd/types.hpp"

namespace viscd::detail {

class RestSet {
 public:
  /// What one frame gives.
  struct Input {
    Shapes objects;                         ///< the frame's moving objects (N)
    std::span<const std::uint32_t> active;  ///< ascending, below N
    std::span<const Filter> filters;        ///< empty or one per object
    std::span<const std::uint32_t> moved;   ///< FrameInput::moved, checked already
    bool moved_listed = false;              ///< FrameInput::moved_listed
    bool verify_moved = false;              ///< Config::verify_moved
    bool unvalidated = false;               ///< the objects are not validated yet (see needs_validation())
    float margin = 0;                       ///< Config::rest_margin
    float move_margin = 0;                  ///< Config::move_margin
    Layout layout = Layout::extended;       ///< Config::layout
    int bits = 32;                          ///< the frame's Morton width: reported, and used by trees built this frame
    std::size_t pair_memory_cap = 0;        ///< Config::pair_memory_cap
    SimdLevel simd = SimdLevel::scalar;     ///< simd_level_for(Config::simd): the trees' and searches' kernels
  };

  /// Runs the frame's broadphase (stages 4-8) by following change, when it can. Returns true with
  /// `pairs` sorted (moving pairs and, as {i, static_index(k)}, pairs with the static set; filters
  /// and the active set applied) and stats (moved, replaced, stage times); false when this frame
  /// must rebuild (nothing written, the set is then out of use until its sample says the objects
  /// rest). `st` must be up to date with `set`. A failed Status (the pair cap, a moved list that
  /// Config::verify_moved finds short) leaves the set out of use.
  [[nodiscard]] Status run(const Input& in, const StaticSet& set, StaticTree& st, int threads, std::vector<Pair>& pairs,
                           FrameStats& stats, bool& followed);
  /// After run() with Input::unvalidated: whether the caller must still validate the objects
  /// (and, when run() did not follow the frame because of it, run it again). run() checks the
  /// objects only where it compares them with their last copies (every one, or the listed ones:
  /// the others are bit for bit the same): an object bit for bit the same was valid then, and each
  /// changed one is checked as it is found. Anywhere else (the set not following, giving up, or
  /// finding an invalid object) it leaves them to the caller, and before it builds anything over
  /// them.
  [[nodiscard]] bool needs_validation() const { return needs_validation_; }
  /// After needs_validation(): whether run() left the frame untouched for the caller to run it
  /// again with the objects validated (else the frame rebuilds).
  [[nodiscard]] bool run_again() const { return run_again_; }
  /// Stops following: the next frames rebuild until the sample says the objects rest.
  void reset();
  /// Whether the set follows these objects: the last frame was followed and had as many of this
  /// kind.
  [[nodiscard]] bool follows(const Shapes& s) const { return live_ && s.size() == n_ && s.kind == kind_; }
  /// The last followed frame's objects (for the queries after it).
  [[nodiscard]] Shapes objects() const {
    return kind_ == ShapeKind::box ? Shapes(std::span<const Box>(cur_box_)) : Shapes(std::span<const Sphere>(cur_sph_));
  }
  [[nodiscard]] std::uint64_t memory_bytes() const;
  /// The objects in the last followed frame's pairs, one bit each, when the set knew them without
  /// a pass over the pairs (own margins alone, nothing filtered or culled); else null.
  [[nodiscard]] const std::uint64_t* pair_bits() const { return pair_bits_ok_ ? pair_bits_.data() : nullptr; }
  /// For tests: the segments the candidates lie in now, and how often they were packed and cut
  /// again since the set last started following.
  [[nodiscard]] std::size_t segments() const { return segs_.size(); }
  [[nodiscard]] std::size_t packs() const { return packs_; }
  /// For tests: how often main was rebuilt over the resting objects since then.
  [[nodiscard]] std::size_t main_rebuilds() const { return main_rebuilds_; }
  /// For tests: how often delta was rebuilt (objects joining it) since then.
  [[nodiscard]] std::size_t delta_builds() const { return delta_builds_; }
  /// For tests: how often the set gave up because main came due again within a few frames (new
  /// objects starting and stopping every frame), since the detector was made.
  [[nodiscard]] std::size_t churn_giveups() const { return churn_giveups_; }
  /// For tests: how often emit() wrote the pairs straight into the caller's list, and how often
  /// such a pass missed the counts it expected (then it merged again), since the detector was made.
  [[nodiscard]] std::size_t direct_frames() const { return direct_frames_; }
  [[nodiscard]] std::size_t direct_misses() const { return direct_misses_; }

 private:
  // One tree and what its objects are: the shapes its lanes hold (sphere lanes: `spheres`; box
  // lanes: `boxes`, with their proxies in `spheres` for the Morton order), and per tree id the
  // object's index.
  struct Part {
    BucketBroadphase tree;
    std::vector<Sphere> spheres;
    std::vector<Box> boxes;
    std::vector<std::uint32_t> ids, iota;
    std::vector<std::uint32_t> at;  // delta and recent: the object index at each sorted position
    std::size_t count = 0, erased = 0;
    bool by_index = false;  // main: the tree's ids are the object indices (build_main())
    /// The object index at each sorted position, for the movers' searches (cross_pairs() reports
    /// those): main's tree holds them itself.
    [[nodiscard]] std::span<const std::uint32_t> objects_by_position() const {
      return by_index ? tree.sorted_objects() : std::span<const std::uint32_t>(at);
    }
    [[nodiscard]] std::uint64_t memory_bytes() const;
  };
  enum : std::uint8_t { kMain = 0, kDelta = 1, kRecent = 2, kNowhere = 3 };

  [[nodiscard]] bool box_lanes() const { return kind_ == ShapeKind::box; }
  /// Whether objects have fat bounds: all of them (rest margin), or those placed again (their own).
  [[nodiscard]] bool fat() const { return margin_ > 0 || move_margin_ > 0; }
  /// Places object k with margin m: its fat box, or its fat sphere and that sphere's radius.
  void place(const Shapes& s, std::size_t k, float m);
  /// The margin object k is placed again with: the rest margin, or its own when larger. Reads its
  /// last copy (call before taking the new shape).
  [[nodiscard]] float margin_of(const Shapes& s, std::size_t k) const;
  /// Whether object k of `s` lies inside its fat bounds (margin > 0).
  [[nodiscard]] bool inside_fat(const Shapes& s, std::size_t k) const;
  /// Builds `part` over `objs` (object indices): their fat bounds (`fat`) or their exact shapes
  /// (cur_), and the pairs among them when `pairs` is not null. `which` (unless kNowhere) records
  /// the part as the objects' home.
  void build_part(Part& part, std::span<const std::uint32_t> objs, std::uint8_t which, bool fat, int threads,
                  std::vector<Pair>* pairs);
  /// build_part() for main: its tree's ids are the object indices.
  void build_main(std::span<const std::uint32_t> objs, int threads, std::vector<Pair>* pairs);
  /// Builds main over every object (their fat bounds; the pairs among them when `pairs` is not
  /// null) and empties delta and recent. Returns the object indices 0..N-1 (in scratch_).
  std::span<const std::uint32_t> enter_main(int threads, std::vector<Pair>* pairs);
  /// Starts following: every object placed now, every candidate found.
  [[nodiscard]] Status enter(const Input& in, const StaticSet& set, StaticTree& st, int threads, FrameStats& stats);
  /// Takes n objects where the last frame had fewer: every per-object array sized.
  void grow(std::size_t n);
  /// Finds the objects that changed (changed_bits_) and left their fat bounds (left_), the new
  /// objects from `old_n` (the last frame's count) on among them; `few` false when more than
  /// `limit` left.
  [[nodiscard]] Status find_changes(const Input& in, int threads, std::size_t limit, std::size_t old_n, bool& few);
  /// Clears this frame's bits of the changed objects and of left_.
  void clear_bits();
  /// After a followed frame with fewer objects than the last (vanished_ fewer): the vanished objects'
  /// entries (copies, fat bounds, bits, counts) dropped or cleared. update() took them out of
  /// their trees and emit() dropped their candidates.
  void forget_vanished();
  /// Follows one frame of changes.
  [[nodiscard]] Status update(const Input& in, const StaticSet& set, StaticTree& st, int threads, FrameStats& stats);
  /// The static pairs of the objects in `tree` (ids through `ids`; with `search`, of those in its
  /// lanes that search), unfiltered, sorted: with fat bounds in its lanes, the static candidates
  /// of those objects.
  [[nodiscard]] bool static_pairs_of(const BucketBroadphase& tree, std::span<const std::uint32_t> ids, StaticTree& st,
                                     int threads, std::vector<std::uint64_t>& out,
                                     const std::uint16_t* search = nullptr);
  /// The frame's pairs from the candidates and static pairs; with merge_, also the next list of
  /// candidates (those of objects placed again dropped, found_ merged in, re-tested where changed).
  [[nodiscard]] Status emit(const Input& in, const StaticSet& set, int threads, std::vector<Pair>& pairs);
  /// Whether objects have own margins and no rest margin: the candidates of objects in recent then
  /// live in the side list.
  [[nodiscard]] bool own_alone() const { return margin_ == 0 && move_margin_ > 0; }
  /// With own margins alone: found_ tested (found_hit_); the side list's entries dropped (an
  /// object left), unmarked (neither object in recent) or tested again (one changed), then merged
  /// with found_. Each a tight loop whose scattered reads are fetched ahead.
  void update_side(const Shapes& s, int threads);
  /// The static candidates tested again in place where their object changed (this frame's bits).
  void retest_static(const Shapes& s, const StaticSet& set);
  /// With objects placed again: their static candidates replaced by stat_found_ (tested), the
  /// runs of the others copied whole.
  void splice_static(const Shapes& s, const StaticSet& set);
  /// The static set changed in `slots` (sorted, each once) since the last frame: their entries
  /// dropped, and the moving objects now near each one that lives found in the trees and tested
  /// (objects placed again this frame have theirs already).
  void follow_static(const Shapes& s, const StaticSet& set, std::span<const std::uint32_t> slots);
  /// The candidates: how many, over the segments.
  [[nodiscard]] std::size_t candidate_count() const;
  /// Packs the candidates into one run and cuts them (and the static pairs) into segments for
  /// `threads`.
  void pack(int threads);
  /// Whether the sample says the objects rest; takes a new sample.
  bool sample_rests(const Shapes& s, float margin);

  bool live_ = false;
  bool needs_validation_ = false;  // run(): see needs_validation()
  bool run_again_ = false;         // run(): see run_again()
  ShapeKind kind_ = ShapeKind::sphere;
  std::size_t n_ = 0;
  float margin_ = 0;
  float move_margin_ = 0;  // Input::move_margin
  Layout layout_ = Layout::extended;
  int bits_ = 32;
  SimdLevel simd_ = SimdLevel::scalar;  // this frame's kernels (Input::simd)
  MortonLayoutInfo main_layout_;        // the layout main was built with, reported by the frames
  std::uint64_t static_version_ = 0;

  std::vector<Sphere> cur_sph_;  // the last frame's objects
  std::vector<Box> cur_box_;
  // margin > 0: each object's fat bounds. Boxes: the box grown by the margin. Spheres: the sphere
  // about the centre it was placed at, of radius fat_r_ (its conservative extent plus the
  // margin), held in the trees with that radius widened by conservative_half_extent(), so that
  // the float test between two fat spheres accepts every pair whose fat spheres truly meet.
  std::vector<Box> fat_box_;
  std::vector<Sphere> fat_sph_;
  std::vector<float> fat_r_;
  std::vector<std::uint64_t> recent_bits_;  // move_margin > 0: the objects in recent, as a bitset
  // With fat bounds: the margin each object of left_ is placed with (the vanished, last, have none).
  std::vector<float> left_margin_;
  std::vector<std::vector<float>> chunk_margin_;  // find_changes(): left_margin_, per chunk
  std::vector<std::uint32_t> recent_next_;        // update(): recent's objects for this frame
  std::vector<std::uint16_t> search_;             // update(): per bucket of recent, the lanes that search
  std::vector<std::uint8_t> part_of_;
  std::vector<std::uint64_t> changed_bits_, left_bits_;  // this frame's changed objects and left_, as bitsets
  std::vector<std::uint32_t> local_;                     // the object's id in its tree
  Part parts_[3];
  std::vector<std::uint32_t> left_, scratch_;
  std::size_t changed_count_ = 0;  // this frame's changed objects
  std::size_t vanished_ = 0;       // this frame's objects gone from the end (the last ones in left_)
  std::vector<std::vector<std::uint32_t>> chunk_left_;  // find_changes(): left_, per chunk

  // The candidates, sorted, with each one's exact result (hit_): in segments, one per chunk of
  // emit()'s merge. Segment c holds the keys in [cuts_[c], cuts_[c + 1]) (the last one: every key
  // from cuts_[c] up) at cand_[segs_[c].begin, segs_[c].end). emit() writes each chunk's merged
  // list where the chunk would start if nothing were dropped, so that the chunks write at once
  // without counting first; the gaps stay until the segments grow uneven, when the list is packed
  // and cut again (pack()).
  struct Segment {
    std::size_t begin = 0, end = 0;
  };
  std::vector<std::uint64_t> cand_, cand_next_, found_, stat_, stat_next_, stat_found_;
  std::vector<std::uint8_t> hit_, hit_next_, found_hit_;  // found_hit_: found_'s exact results (own margins)
  // The static candidates, stat_ (sorted keys {object, static_index(slot)}): each object with the
  // static objects its bounds in its tree (fat, or exact) meet, found when it was placed, with
  // each one's exact result; tested again when the object changes inside its fat bounds.
  std::vector<std::uint8_t> stat_hit_, stat_hit_next_;
  // follow_static(): the changed slots as a bitset, the new entries, one query's objects.
  std::vector<std::uint64_t> static_changed_, near_;
  std::vector<std::uint32_t> near_hits_;
  // With own margins alone, the side list: sorted keys with their bytes (bit 0 the exact result,
  // kRecheck while an object is in recent), the candidates found by searches of recent and those
  // no longer marked since; merged into cand_ by emit() when merge_. The candidates in cand_ are
  // then never marked; those dropped in place (kDrop) are counted in dropped_.
  std::vector<std::uint64_t> side_, side_next_;
  std::vector<std::uint8_t> side_hit_, side_hit_next_;
  std::size_t side_unmarked_ = 0, dropped_ = 0;
  std::size_t woken_ = 0;  // update(): objects that left and were not in recent (woke from rest)
  // emit() with the side list: the pairs of the candidates per chunk at the last frame (valid
  // while they were not merged or filtered since), each chunk's check in the direct pass, and how
  // often that pass was taken and missed.
  std::vector<std::size_t> a_out_;
  bool a_out_valid_ = false;
  std::vector<std::uint8_t> direct_ok_;
  std::size_t direct_frames_ = 0, direct_misses_ = 0;
  // With the side list or a rest margin (counts_pairs()): per object, how many of cand_'s live
  // candidates that hold it is in, and the objects in one or more as a bitset (kept as candidates
  // are dropped, merged and tested again: emit()'s chunks and update()'s retests in place list
  // those that stop or start holding in chunk_gone_ and chunk_added_); the frame's pair_bits()
  // from them.
  std::vector<std::uint32_t> a_count_;
  std::vector<std::uint64_t> a_bits_, pair_bits_;
  std::vector<std::vector<std::uint64_t>> chunk_gone_, chunk_added_;
  bool pair_bits_ok_ = false;
  /// a_count_ and a_bits_ over cand_ (enter()).
  void count_candidates();
  /// count_changes(); then the frame's pair_bits_ when `known` (static pairs: every one with
  /// `all_pass`, else those `static_ok` accepts).
  template <class StaticOk>
  void note_pairs(bool known, bool all_pass, const StaticOk& static_ok);
  /// The candidates in chunk_gone_ and chunk_added_ taken into a_count_ and a_bits_; the lists
  /// emptied.
  void count_changes();
  /// chunk_gone_ and chunk_added_ for `chunks` chunks, every list empty.
  void open_change_lists(std::size_t chunks);
  /// Whether a_count_ and a_bits_ are kept (own margins alone, or a rest margin).
  [[nodiscard]] bool counts_pairs() const { return own_alone() || margin_ > 0; }
  std::vector<Segment> segs_;
  std::vector<std::uint64_t> cuts_;
  std::vector<std::vector<std::uint64_t>> chunk_keys_;
  std::vector<std::uint32_t> key_offsets_;  // update(): the sort of the movers' new candidates
  std::vector<std::uint64_t> key_scratch_;
  std::vector<Pair> local_pairs_, pair_buf_;
  std::vector<std::uint8_t> active_mask_;
  // emit()'s chunks: where each starts in found_ and stat_, where its output may start (the sizes
  // before it), and what it kept and emitted.
  std::vector<std::size_t> b_at_, s_at_, cand_ub_, pair_ub_, kept_, out_, drops_, pack_at_;
  bool merge_ = false;             // this frame's emit() merges found_ into the candidates
  std::size_t packs_ = 0;          // pack() calls since enter()
  std::size_t main_rebuilds_ = 0;  // main rebuilt by update() since enter()
  std::size_t delta_builds_ = 0;   // delta rebuilt by update() since enter()
  // Churn (rest_set.cpp, kChurnFrames): followed frames since main was built; whether the last
  // frame found it due again too soon; frames still to wait, and the next wait; followed frames
  // since the last such find; give-ups for churn (for tests).
  std::size_t frames_since_main_ = 0;
  bool churned_ = false;
  std::size_t churn_wait_ = 0, churn_backoff_ = 8, calm_frames_ = 0, churn_giveups_ = 0;

  // The sample watched while the set is out of use.
  std::vector<std::uint32_t> sample_index_;
  std::vector<Box> sample_;  // each sampled object's box (Shapes::aabb) when taken
  std::size_t sample_n_ = 0;
  std::uint64_t sample_seed_ = 1;  // picks each sample's offset
  ShapeKind sample_kind_ = ShapeKind::sphere;
};

}  // namespace viscd::detail
