#pragma once
// A frame's moving objects followed by the static set's live objects (in slot order), as one
// array: the way a backend without a structure of its own for the static set takes part in it.
// Object k < moving is moving object k; object moving + s is the static object in slots[s]. The
// backend marks the static objects always active, leaves them out of mu, skips pairs of two of
// them, and report() turns the pairs' indices into static_index(k).

#include <cstdint>
#include <span>
#include <vector>

#include "core/shapes.hpp"
#include "core/static_set.hpp"
#include "viscd/frame.hpp"
#include "viscd/types.hpp"

namespace viscd::detail {

class WithStatic {
 public:
  /// The frame's objects and the set's (a view of the input, no copy, when the set is null or
  /// empty).
  void build(const FrameInput& in, StaticSet* set);

  Shapes objects;                        ///< moving, then static
  std::span<const Filter> filters;       ///< one per object, or empty when neither the frame nor the set has any
  std::size_t moving = 0;                ///< the frame's objects
  std::span<const std::uint32_t> slots;  ///< the static objects' slots

  [[nodiscard]] std::size_t total() const { return objects.size(); }
  /// Rewrites the pairs' second indices to reported(); pairs stay sorted (slots ascend).
  void report(std::vector<Pair>& pairs) const;
  [[nodiscard]] std::uint64_t memory_bytes() const {
    return spheres_.capacity() * sizeof(Sphere) + boxes_.capacity() * sizeof(Box) +
           filters_.capacity() * sizeof(Filter);
  }

 private:
  std::vector<Sphere> spheres_;
  std::vector<Box> boxes_;
  std::vector<Filter> filters_;
};

}  // namespace viscd::detail
