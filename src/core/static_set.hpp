#pragma once
// The detector's static set (Detector::set_static_spheres and the rest): objects in slots, each
// live or free, with a filter. Changes cost O(1) each (plus O(log) for the free slots). Backends
// read the set two ways: compact() lists the live objects in slot order (rebuilt on the first call
// after a change: O(live objects)), and version() tells a backend that keeps structures of its own
// over the set whether anything changed since it last looked.

#include <cstdint>
#include <span>
#include <vector>

#include "core/shapes.hpp"
#include "viscd/result.hpp"
#include "viscd/types.hpp"

namespace viscd::detail {

class StaticSet {
 public:
  [[nodiscard]] ShapeKind kind() const { return kind_; }
  [[nodiscard]] std::size_t size() const { return live_count_; }
  [[nodiscard]] bool empty() const { return live_count_ == 0; }
  /// Bumped by every change.
  [[nodiscard]] std::uint64_t version() const { return version_; }

  [[nodiscard]] Status set(std::span<const Sphere> spheres, std::span<const Filter> filters);
  [[nodiscard]] Status set(std::span<const Box> boxes, std::span<const Filter> filters);
  [[nodiscard]] Result<std::uint32_t> add(const Sphere& sphere, const Filter& filter);
  [[nodiscard]] Result<std::uint32_t> add(const Box& box, const Filter& filter);
  [[nodiscard]] Status move(std::uint32_t k, const Sphere& sphere);
  [[nodiscard]] Status move(std::uint32_t k, const Box& box);
  [[nodiscard]] Status remove(std::uint32_t k);
  void clear();

  /// The live objects in slot order, their filters and slots.
  struct Compact {
    Shapes shapes;
    std::span<const Filter> filters;  ///< one per live object
    bool filtered = false;            ///< some filter is not Filter{}
    std::span<const std::uint32_t> slots;
  };
  [[nodiscard]] const Compact& compact();

  /// The slots added, moved or removed since the last take_changes() (with repeats), or `reset`
  /// when the set was replaced or cleared (or too much changed to list): then all of it is new.
  struct Changes {
    bool reset = true;
    std::vector<std::uint32_t> slots;
  };
  /// Hands the changes over in `out` and starts a new list in the memory `out` held (the two lists
  /// trade places, so a steady state allocates nothing).
  void take_changes(Changes& out);
  /// The live object in slot k (of the set's kind), and its filter.
  [[nodiscard]] const Sphere& sphere(std::uint32_t k) const { return spheres_[k]; }
  [[nodiscard]] const Box& box(std::uint32_t k) const { return boxes_[k]; }
  [[nodiscard]] const Filter& filter(std::uint32_t k) const { return filters_[k]; }
  [[nodiscard]] bool live(std::uint32_t k) const { return k < live_.size() && live_[k] != 0; }
  /// Slots in use or free (every slot is below this).
  [[nodiscard]] std::size_t slot_count() const { return live_.size(); }
  /// The OR of the groups and of the masks of every filter the set held since it was last
  /// replaced or cleared: never less than the live objects' (the filters' pre-pass needs no more).
  [[nodiscard]] std::uint32_t groups() const { return groups_; }
  [[nodiscard]] std::uint32_t masks() const { return masks_; }
  /// Live objects whose filter refuses Filter{} (the moving objects' filter when none is given):
  /// with none, every static pair of an unfiltered frame passes.
  [[nodiscard]] std::size_t default_refused() const { return default_refused_; }

  [[nodiscard]] std::uint64_t memory_bytes() const;

 private:
  template <class Shape>
  std::vector<Shape>& store();
  template <class Shape>
  Status set_all(std::span<const Shape> objects, std::span<const Filter> filters);
  template <class Shape>
  Result<std::uint32_t> add_one(const Shape& object, const Filter& filter);
  template <class Shape>
  Status move_one(std::uint32_t k, const Shape& object);
  [[nodiscard]] Status check_kind(ShapeKind kind, const char* what) const;
  [[nodiscard]] Status check_slot(std::uint32_t k) const;
  std::uint32_t take_slot();
  void changed() { ++version_; }
  void touched(std::uint32_t k);
  void replaced();

  ShapeKind kind_ = ShapeKind::sphere;
  std::vector<Sphere> spheres_;  // by slot (sphere sets)
  std::vector<Box> boxes_;       // by slot (box sets)
  std::vector<Filter> filters_;  // by slot
  std::vector<std::uint8_t> live_;
  std::vector<std::uint32_t> free_;  // free slots, a min-heap
  std::size_t live_count_ = 0;
  std::size_t default_refused_ = 0;  // live objects whose filter refuses Filter{}
  std::uint64_t version_ = 0, compact_version_ = ~std::uint64_t{0};
  Changes changes_;
  std::uint32_t groups_ = 0, masks_ = 0;

  std::vector<Sphere> compact_spheres_;
  std::vector<Box> compact_boxes_;
  std::vector<Filter> compact_filters_;
  std::vector<std::uint32_t> compact_slots_;
  Compact compact_;
};

}  // namespace viscd::detail
