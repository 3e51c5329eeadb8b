#include "core/with_static.hpp"

namespace viscd::detail {

void WithStatic::build(const FrameInput& in, StaticSet* static_set) {
  const Shapes frame = Shapes::of(in);
  moving = frame.size();
  if (static_set == nullptr || static_set->empty()) {
    objects = frame;
    filters = in.filters;
    slots = {};
    return;
  }
  const StaticSet::Compact& st = static_set->compact();
  const std::size_t k = st.shapes.size();
  if (st.shapes.is_box()) {
    boxes_.resize(moving + k);
    std::copy(frame.boxes.begin(), frame.boxes.end(), boxes_.begin());
    std::copy(st.shapes.boxes.begin(), st.shapes.boxes.end(), boxes_.begin() + static_cast<std::ptrdiff_t>(moving));
    objects = Shapes(std::span<const Box>(boxes_));
  } else {
    spheres_.resize(moving + k);
    std::copy(frame.spheres.begin(), frame.spheres.end(), spheres_.begin());
    std::copy(st.shapes.spheres.begin(), st.shapes.spheres.end(),
              spheres_.begin() + static_cast<std::ptrdiff_t>(moving));
    objects = Shapes(std::span<const Sphere>(spheres_));
  }
  if (in.filters.empty() && !st.filtered) {
    filters = {};
  } else {
    filters_.resize(moving + k);
    for (std::size_t i = 0; i < moving; ++i) filters_[i] = in.filters.empty() ? Filter{} : in.filters[i];
    std::copy(st.filters.begin(), st.filters.end(), filters_.begin() + static_cast<std::ptrdiff_t>(moving));
    filters = filters_;
  }
  slots = st.slots;
}

void WithStatic::report(std::vector<Pair>& pairs) const {
  if (slots.empty()) return;
  for (Pair& p : pairs)
    if (p.j >= moving) p.j = static_index(slots[p.j - moving]);
}

}  // namespace viscd::detail
