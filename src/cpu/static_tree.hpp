#pragma once
// The cpu backend's own structure for the static set, so that a frame costs what its moving
// objects and the static objects near them cost, not what the static count costs.
//
// Two trees of the bucket broadphase's kind (stages 4-7 only): `main`, built over every static
// object at some point, and `delta`, over the objects added or moved since. Removing or moving an
// object takes it out of main in place (its lane becomes padding, BucketBroadphase::erase());
// a moved or added one joins delta, which is rebuilt on the next frame: O(d log d) for d objects
// in it. When delta and the objects taken out of main pass an eighth of main (and a floor), main
// is rebuilt from the whole set, so each change costs O(log) amortised and the trees stay tight.
//
// Each frame the moving objects' tree (already built) meets both trees: per group of 16 moving
// buckets, a walk of each static tree with the group's box for candidate static buckets, each
// moving bucket's box against those, then per static bucket met, the moving lanes that reach it
// tested against all 16 static lanes at once (the exact test of the frame's kind). Pairs come out
// as (moving object, static_index(slot)), sorted.

#include <cstdint>
#include <span>
#include <vector>

#include "core/static_set.hpp"
#include "cpu/bucket_broadphase.hpp"
#include "viscd/config.hpp"
#include "viscd/result.hpp"

namespace viscd::detail {

class StaticTree {
 public:
  /// Brings the trees up to date with the set's changes since the last call.
  void update(StaticSet& set, Layout layout, int threads);
  /// Appends to `out` every pair of an object of `moving` (its last tree) with a static object
  /// that overlaps it and, when `filtered`, whose filters accept each other (`moving_filters`: the
  /// moving objects' filters in the moving tree's sorted order, or empty: Filter{} each), as keys
  /// i << 32 | static_index(slot), i the moving tree's id; `out` is then sorted. Fails when they
  /// exceed `max_pairs`. `simd`: the kernels (a usable level). `search` (when not null): per bucket
  /// of `moving`, the lanes whose objects search; the others report nothing.
  [[nodiscard]] bool pairs(const BucketBroadphase& moving, std::span<const Filter> moving_filters, bool filtered,
                           SimdLevel simd, int threads, std::size_t max_pairs, std::vector<std::uint64_t>& out,
                           const std::uint16_t* search = nullptr);
  /// The static filter of a reported static index's slot (for pairs found unfiltered).
  [[nodiscard]] static const Filter& filter_of(const StaticSet& set, std::uint32_t reported) {
    return set.filter(static_slot(reported));
  }
  /// The trees, for queries: each tree's objects are reported as static_index(slot), with the
  /// slot's filter. None for an empty set.
  struct Part {
    const BucketBroadphase* tree;
    BucketBroadphase::Objects objects;
  };
  [[nodiscard]] std::size_t parts(Part out[2]) const;
  /// What the last update() took from the set: the slots added, moved or removed (sorted, each
  /// once) between the set's versions `from` and `to`, or `reset` (replaced, cleared, or too much
  /// to list). A structure kept over the set as it was at version `from` follows it to `to`
  /// through them (cpu/rest_set.hpp).
  struct Taken {
    std::uint64_t from = 0, to = 0;
    bool reset = true;
    std::span<const std::uint32_t> slots;
  };
  [[nodiscard]] Taken last_changes() const { return {taken_from_, taken_to_, changes_.reset, changes_.slots}; }
  [[nodiscard]] std::size_t size() const { return live_; }
  [[nodiscard]] std::uint64_t memory_bytes() const;

 private:
  // One tree and what its objects are: shapes gathered in build order, their slots' reported
  // indices and filters.
  struct Side {
    BucketBroadphase tree;
    std::vector<Sphere> spheres;  // sphere sets: the objects; box sets: their proxies
    std::vector<Box> boxes;       // box sets
    std::vector<std::uint32_t> reported, iota;
    std::vector<Filter> filters;
    std::vector<std::uint32_t> reported_at;  // reported, by the tree's sorted position
    std::vector<Filter> filter_at;           // filters, by sorted position
    bool rejects_default = false;            // some filter rejects the default Filter{}
    std::size_t count = 0;
    void build(const StaticSet& set, std::span<const std::uint32_t> slots, Layout layout, int threads);
    [[nodiscard]] std::uint64_t memory_bytes() const;
  };
  void rebuild_all(StaticSet& set, Layout layout, int threads);

  Side main_, delta_;
  std::vector<std::uint32_t> main_index_;  // per slot: its index in main, or ~0u (not there)
  std::vector<std::uint8_t> in_delta_;     // per slot
  std::vector<std::uint32_t> delta_slots_;
  StaticSet::Changes changes_;                   // update(): the set's changes, taken in place
  std::uint64_t taken_from_ = 0, taken_to_ = 0;  // the set's versions before and after them
  std::vector<std::uint32_t> merged_;            // update(): delta's slots, old and new
  std::size_t erased_ = 0, live_ = 0;
  bool boxes_ = false;
  std::vector<std::vector<std::uint64_t>> lists_;  // pairs(): per chunk
};

}  // namespace viscd::detail
