#include "core/static_set.hpp"

#include <algorithm>
#include <functional>
#include <limits>
#include <string>

#include "core/frame_rules.hpp"
#include "viscd/detector.hpp"

namespace viscd::detail {
namespace {

constexpr std::size_t kMaxStatic = std::numeric_limits<std::int32_t>::max();

const char* kind_name(ShapeKind k) { return k == ShapeKind::box ? "boxes" : "spheres"; }

// "static sphere: ..." from validate_spheres()'s "sphere 0: ...".
Status one_object_error(const Status& s, const char* noun) {
  std::string m = s.error();
  const std::string head = std::string(noun) + " 0";
  if (m.rfind(head, 0) == 0) m = std::string("static ") + noun + m.substr(head.size());
  return Status::failure(s.kind(), m);
}

Status filter_count_error(std::size_t filters, std::size_t objects) {
  return Status::failure(ErrorKind::invalid_input, "static set: " + std::to_string(filters) + " filters for " +
                                                       std::to_string(objects) +
                                                       " objects; give none or one per object");
}

}  // namespace

void StaticSet::touched(std::uint32_t k) {
  changed();
  if (changes_.reset) return;
  // A list longer than the set says less than a reset.
  if (changes_.slots.size() >= live_.size() + 64) {
    changes_.reset = true;
    changes_.slots.clear();
    return;
  }
  changes_.slots.push_back(k);
}

void StaticSet::replaced() {
  changed();
  changes_.reset = true;
  changes_.slots.clear();
}

StaticSet::Changes StaticSet::take_changes() {
  Changes out = std::move(changes_);
  changes_ = Changes{false, {}};
  changes_.slots.reserve(out.slots.capacity());
  return out;
}

Status StaticSet::check_kind(ShapeKind kind, const char* what) const {
  if (live_count_ == 0 || kind == kind_) return {};
  return Status::failure(ErrorKind::invalid_input, std::string(what) + ": the static set holds " + kind_name(kind_) +
                                                       "; it cannot take " + kind_name(kind) +
                                                       " (clear it first, or use a second detector)");
}

Status StaticSet::check_slot(std::uint32_t k) const {
  if (k < live_.size() && live_[k]) return {};
  return Status::failure(ErrorKind::invalid_input, "static set: no object in slot " + std::to_string(k) + " (" +
                                                       std::to_string(live_count_) + " objects in " +
                                                       std::to_string(live_.size()) + " slots)");
}

std::uint32_t StaticSet::take_slot() {
  if (!free_.empty()) {
    std::pop_heap(free_.begin(), free_.end(), std::greater<>());
    const std::uint32_t k = free_.back();
    free_.pop_back();
    return k;
  }
  const auto k = static_cast<std::uint32_t>(live_.size());
  live_.push_back(0);
  filters_.emplace_back();
  if (kind_ == ShapeKind::box)
    boxes_.emplace_back();
  else
    spheres_.emplace_back();
  return k;
}

Status StaticSet::set(std::span<const Sphere> spheres, std::span<const Filter> filters) {
  if (Status s = validate_spheres(spheres); !s) return Status::failure(s.kind(), "static set: " + s.error());
  if (!filters.empty() && filters.size() != spheres.size()) return filter_count_error(filters.size(), spheres.size());
  clear();
  kind_ = ShapeKind::sphere;
  spheres_.assign(spheres.begin(), spheres.end());
  if (filters.empty())
    filters_.assign(spheres.size(), Filter{});
  else
    filters_.assign(filters.begin(), filters.end());
  live_.assign(spheres.size(), 1);
  live_count_ = spheres.size();
  for (const Filter& f : filters_) groups_ |= f.group, masks_ |= f.mask;
  replaced();
  return {};
}

Status StaticSet::set(std::span<const Box> boxes, std::span<const Filter> filters) {
  if (Status s = validate_boxes(boxes); !s) return Status::failure(s.kind(), "static set: " + s.error());
  if (!filters.empty() && filters.size() != boxes.size()) return filter_count_error(filters.size(), boxes.size());
  clear();
  kind_ = ShapeKind::box;
  boxes_.assign(boxes.begin(), boxes.end());
  if (filters.empty())
    filters_.assign(boxes.size(), Filter{});
  else
    filters_.assign(filters.begin(), filters.end());
  live_.assign(boxes.size(), 1);
  live_count_ = boxes.size();
  for (const Filter& f : filters_) groups_ |= f.group, masks_ |= f.mask;
  replaced();
  return {};
}

Result<std::uint32_t> StaticSet::add(const Sphere& sphere, const Filter& filter) {
  if (Status s = validate_spheres({&sphere, 1}); !s)
    return Result<std::uint32_t>::failure(one_object_error(s, "sphere"));
  if (Status s = check_kind(ShapeKind::sphere, "add_static_sphere"); !s) return Result<std::uint32_t>::failure(s);
  if (live_count_ >= kMaxStatic)
    return Result<std::uint32_t>::failure(ErrorKind::invalid_input, "static set: at most 2^31 - 1 objects");
  if (live_count_ == 0 && kind_ != ShapeKind::sphere) {
    clear();
    kind_ = ShapeKind::sphere;
  }
  const std::uint32_t k = take_slot();
  spheres_[k] = sphere;
  filters_[k] = filter;
  groups_ |= filter.group, masks_ |= filter.mask;
  live_[k] = 1;
  ++live_count_;
  touched(k);
  return k;
}

Result<std::uint32_t> StaticSet::add(const Box& box, const Filter& filter) {
  if (Status s = validate_boxes({&box, 1}); !s) return Result<std::uint32_t>::failure(one_object_error(s, "box"));
  if (Status s = check_kind(ShapeKind::box, "add_static_box"); !s) return Result<std::uint32_t>::failure(s);
  if (live_count_ >= kMaxStatic)
    return Result<std::uint32_t>::failure(ErrorKind::invalid_input, "static set: at most 2^31 - 1 objects");
  if (live_count_ == 0 && kind_ != ShapeKind::box) {
    clear();
    kind_ = ShapeKind::box;
  }
  const std::uint32_t k = take_slot();
  boxes_[k] = box;
  filters_[k] = filter;
  groups_ |= filter.group, masks_ |= filter.mask;
  live_[k] = 1;
  ++live_count_;
  touched(k);
  return k;
}

Status StaticSet::move(std::uint32_t k, const Sphere& sphere) {
  if (Status s = check_slot(k); !s) return s;
  if (kind_ != ShapeKind::sphere) return check_kind(ShapeKind::sphere, "move_static_sphere");
  if (Status s = validate_spheres({&sphere, 1}); !s) return one_object_error(s, "sphere");
  spheres_[k] = sphere;
  touched(k);
  return {};
}

Status StaticSet::move(std::uint32_t k, const Box& box) {
  if (Status s = check_slot(k); !s) return s;
  if (kind_ != ShapeKind::box) return check_kind(ShapeKind::box, "move_static_box");
  if (Status s = validate_boxes({&box, 1}); !s) return one_object_error(s, "box");
  boxes_[k] = box;
  touched(k);
  return {};
}

Status StaticSet::remove(std::uint32_t k) {
  if (Status s = check_slot(k); !s) return s;
  live_[k] = 0;
  --live_count_;
  free_.push_back(k);
  std::push_heap(free_.begin(), free_.end(), std::greater<>());
  touched(k);
  return {};
}

void StaticSet::clear() {
  spheres_.clear();
  boxes_.clear();
  filters_.clear();
  live_.clear();
  free_.clear();
  live_count_ = 0;
  groups_ = masks_ = 0;
  replaced();
}

const StaticSet::Compact& StaticSet::compact() {
  if (compact_version_ == version_) return compact_;
  compact_version_ = version_;
  compact_spheres_.clear();
  compact_boxes_.clear();
  compact_filters_.clear();
  compact_slots_.clear();
  bool filtered = false;
  for (std::size_t k = 0; k < live_.size(); ++k) {
    if (!live_[k]) continue;
    if (kind_ == ShapeKind::box)
      compact_boxes_.push_back(boxes_[k]);
    else
      compact_spheres_.push_back(spheres_[k]);
    const Filter f = filters_[k];
    filtered |= f.group != Filter{}.group || f.mask != Filter{}.mask;
    compact_filters_.push_back(f);
    compact_slots_.push_back(static_cast<std::uint32_t>(k));
  }
  compact_.shapes = kind_ == ShapeKind::box ? Shapes(std::span<const Box>(compact_boxes_))
                                            : Shapes(std::span<const Sphere>(compact_spheres_));
  compact_.filters = compact_filters_;
  compact_.filtered = filtered;
  compact_.slots = compact_slots_;
  return compact_;
}

std::uint64_t StaticSet::memory_bytes() const {
  return bytes_of(spheres_) + bytes_of(boxes_) + bytes_of(filters_) + bytes_of(live_) + bytes_of(free_) +
         bytes_of(compact_spheres_) + bytes_of(compact_boxes_) + bytes_of(compact_filters_) + bytes_of(compact_slots_);
}

}  // namespace viscd::detail
