#include "cpu/keep_order.hpp"

#include <algorithm>
#include <cmath>

#include "cpu/grow.hpp"

namespace viscd::detail {

bool KeepOrderPolicy::may_keep(std::size_t objects, std::span<const std::uint32_t> active, Layout layout) const {
  if (!enabled_ || sort_next_ || layout != previous_layout_ || active.size() < 2 || !std::isfinite(sorted_box_sum_))
    return false;
  // The same active set as the last sorted frame (and every frame since): all objects of as many,
  // or the same ids. active is ascending and distinct, so n == objects means all of them.
  if (active.size() == objects) return previous_all_ && previous_objects_ == objects;
  return !previous_all_ && std::equal(active.begin(), active.end(), previous_active_.begin(), previous_active_.end());
}

void KeepOrderPolicy::remember_sorted(std::size_t objects, std::span<const std::uint32_t> active, Layout layout,
                                      double box_sum) {
  previous_all_ = active.size() == objects;
  previous_objects_ = objects;
  previous_layout_ = layout;
  if (previous_all_) {
    previous_active_.clear();
  } else {
    resize_with_headroom(previous_active_, active.size());
    std::copy(active.begin(), active.end(), previous_active_.begin());
  }
  sorted_box_sum_ = box_sum;
  sorted_bucket_pairs_ = 0;  // until this frame's search counts it
  sort_next_ = false;
}

void KeepOrderPolicy::after_search(bool kept, std::uint64_t bucket_pairs) {
  if (!kept)
    sorted_bucket_pairs_ = bucket_pairs;
  else if (sorted_bucket_pairs_ != 0 &&
           static_cast<double>(bucket_pairs) > (1 + kStaleness) * static_cast<double>(sorted_bucket_pairs_))
    sort_next_ = true;
}

}  // namespace viscd::detail
