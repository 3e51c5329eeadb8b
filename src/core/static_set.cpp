#include "core/static_set.hpp"

#include <algorithm>
#include <functional>
#include <limits>
#include <string>
#include <type_traits>

#include "core/frame_rules.hpp"
#include "viscd/detector.hpp"

namespace viscd::detail {
namespace {

bool refuses_default(const Filter& f) { return !pair_passes_filter(Filter{}, f); }

constexpr std::size_t kMaxStatic = std::numeric_limits<std::int32_t>::max();

const char* kind_name(ShapeKind k) { return k == ShapeKind::box ? "boxes" : "spheres"; }

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

void StaticSet::take_changes(Changes& out) {
  out.reset = changes_.reset;
  out.slots.swap(changes_.slots);
  changes_.reset = false;
  changes_.slots.clear();
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

namespace {
// What differs between the two kinds: the checks and the words of the messages.
Status validate(std::span<const Sphere> s) { return validate_spheres(s); }
Status validate(std::span<const Box> b) { return validate_boxes(b); }
// One object, named "static sphere" or "static box" in the message.
Status validate_one(const Sphere& s) { return sphere_problem(s, "static sphere"); }
Status validate_one(const Box& b) { return box_problem(b, "static box"); }
template <class Shape>
constexpr ShapeKind kind_of() {
  return std::is_same_v<Shape, Box> ? ShapeKind::box : ShapeKind::sphere;
}
}  // namespace

template <class Shape>
std::vector<Shape>& StaticSet::store() {
  if constexpr (std::is_same_v<Shape, Box>)
    return boxes_;
  else
    return spheres_;
}

template <class Shape>
Status StaticSet::set_all(std::span<const Shape> objects, std::span<const Filter> filters) {
  if (Status s = validate(objects); !s) return Status::failure(s.kind(), "static set: " + s.error());
  if (!filters.empty() && filters.size() != objects.size()) return filter_count_error(filters.size(), objects.size());
  clear();
  kind_ = kind_of<Shape>();
  store<Shape>().assign(objects.begin(), objects.end());
  if (filters.empty())
    filters_.assign(objects.size(), Filter{});
  else
    filters_.assign(filters.begin(), filters.end());
  live_.assign(objects.size(), 1);
  live_count_ = objects.size();
  for (const Filter& f : filters_) {
    groups_ |= f.group, masks_ |= f.mask;
    default_refused_ += refuses_default(f);
  }
  replaced();
  return {};
}

template <class Shape>
Result<std::uint32_t> StaticSet::add_one(const Shape& object, const Filter& filter) {
  constexpr ShapeKind kind = kind_of<Shape>();
  if (Status s = validate_one(object); !s) return Result<std::uint32_t>::failure(s);
  if (Status s = check_kind(kind, kind == ShapeKind::box ? "add_static_box" : "add_static_sphere"); !s)
    return Result<std::uint32_t>::failure(s);
  if (live_count_ >= kMaxStatic)
    return Result<std::uint32_t>::failure(ErrorKind::invalid_input, "static set: at most 2^31 - 1 objects");
  if (live_count_ == 0 && kind_ != kind) {
    clear();
    kind_ = kind;
  }
  const std::uint32_t k = take_slot();
  store<Shape>()[k] = object;
  filters_[k] = filter;
  groups_ |= filter.group, masks_ |= filter.mask;
  default_refused_ += refuses_default(filter);
  live_[k] = 1;
  ++live_count_;
  touched(k);
  return k;
}

template <class Shape>
Status StaticSet::move_one(std::uint32_t k, const Shape& object) {
  constexpr ShapeKind kind = kind_of<Shape>();
  if (Status s = check_slot(k); !s) return s;
  if (kind_ != kind) return check_kind(kind, kind == ShapeKind::box ? "move_static_box" : "move_static_sphere");
  if (Status s = validate_one(object); !s) return s;
  store<Shape>()[k] = object;
  touched(k);
  return {};
}

Status StaticSet::set(std::span<const Sphere> spheres, std::span<const Filter> filters) {
  return set_all(spheres, filters);
}
Status StaticSet::set(std::span<const Box> boxes, std::span<const Filter> filters) { return set_all(boxes, filters); }
Result<std::uint32_t> StaticSet::add(const Sphere& sphere, const Filter& filter) { return add_one(sphere, filter); }
Result<std::uint32_t> StaticSet::add(const Box& box, const Filter& filter) { return add_one(box, filter); }
Status StaticSet::move(std::uint32_t k, const Sphere& sphere) { return move_one(k, sphere); }
Status StaticSet::move(std::uint32_t k, const Box& box) { return move_one(k, box); }

Status StaticSet::remove(std::uint32_t k) {
  if (Status s = check_slot(k); !s) return s;
  live_[k] = 0;
  --live_count_;
  default_refused_ -= refuses_default(filters_[k]);
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
  live_count_ = default_refused_ = 0;
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
