#pragma once
// When the cpu broadphase keeps the last frame's object order instead of sorting (Config::keep_order).
//
// Objects move little from frame to frame, so the last frame's Morton order stays nearly right:
// refilling the buckets in it and rebuilding the tree over their boxes finds the same pairs
// (any grouping of the objects into buckets does) without stages 4-6. The order goes stale as
// objects drift: the bucket boxes grow, and so does the number of bucket pairs whose boxes
// overlap. The policy: a frame may keep the order when its active set, bit count and layout kind
// are the last sorted frame's; it keeps it while the summed size of its bucket boxes stays within
// kStaleness of that frame's (checked before the search: the frame sorts at once), and the next
// frame sorts when the search's bucket-pair count grows past kStaleness of that frame's (known
// only after the search). docs/architecture.md, "The cpu broadphase, stage by stage".

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "viscd/config.hpp"

namespace viscd::detail {

/// A kept order stays while the bucket boxes' summed size, and the count of bucket pairs whose
/// boxes overlap, exceed those of the last sorted frame by at most this fraction.
inline constexpr double kStaleness = 1.0 / 16;

class KeepOrderPolicy {
 public:
  /// Off: every frame sorts. Default on.
  void set_enabled(bool on) { enabled_ = on; }
  [[nodiscard]] bool enabled() const { return enabled_; }

  /// Whether a frame over `objects` objects with this active set (ascending) and layout kind may
  /// try to keep the last sorted frame's order. The caller also checks that the order it holds is
  /// of this frame's bit count and object count.
  [[nodiscard]] bool may_keep(std::size_t objects, std::span<const std::uint32_t> active, Layout layout) const;
  /// Whether a frame whose bucket boxes sum to `box_sum` (their side lengths added) keeps it.
  [[nodiscard]] bool keeps(double box_sum) const { return box_sum <= (1 + kStaleness) * sorted_box_sum_; }

  /// After a sorted frame: what the next frames compare with.
  void remember_sorted(std::size_t objects, std::span<const std::uint32_t> active, Layout layout, double box_sum);
  /// After a frame's search: `bucket_pairs` bucket pairs had overlapping boxes. A sorted frame's
  /// count is the reference; a kept frame past it by more than kStaleness makes the next frame sort.
  void after_search(bool kept, std::uint64_t bucket_pairs);
  /// The next frame sorts (its search stopped early, so its count says nothing).
  void sort_next() { sort_next_ = true; }

  [[nodiscard]] std::uint64_t memory_bytes() const { return previous_active_.capacity() * sizeof(std::uint32_t); }

 private:
  bool enabled_ = true;
  bool sort_next_ = true;  // nothing sorted yet
  bool previous_all_ = false;
  std::size_t previous_objects_ = 0;
  Layout previous_layout_ = Layout::extended;
  std::vector<std::uint32_t> previous_active_;  // the last sorted frame's active set, unless all
  double sorted_box_sum_ = 0;
  std::uint64_t sorted_bucket_pairs_ = 0;  // 0: not known yet
};

}  // namespace viscd::detail
