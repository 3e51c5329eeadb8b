#pragma once
// The frame's rules that do not depend on where a stage runs, shared by every backend: input
// validation, the pair-memory cap, the active set's extent (stage 4's inputs) and the message of
// a frame that ran out of memory.

#include <cmath>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "core/geometry.hpp"
#include "core/shapes.hpp"
#include "core/static_set.hpp"
#include "viscd/config.hpp"
#include "viscd/frame.hpp"
#include "viscd/result.hpp"
#include "viscd/types.hpp"

namespace viscd::detail {

/// Capacity of a vector in bytes (what it holds, not what it uses).
template <class T>
std::uint64_t bytes_of(const std::vector<T>& v) {
  return static_cast<std::uint64_t>(v.capacity()) * sizeof(T);
}

/// The checks every backend makes on a frame's input: objects, camera, the map size, threads.
/// `check_objects` false leaves out the objects themselves (the caller checks them: Backend::validate_objects()).
[[nodiscard]] Status validate_frame(const Shapes& objects, const Camera* camera, const Config& config,
                                    bool check_objects = true);
/// A frame's objects and a non-empty static set must be of one kind.
[[nodiscard]] Status validate_static_kind(const FrameInput& input, const StaticSet& set);
/// FrameInput::moved: ascending, no repeats, every entry below `objects`; the error names the
/// first bad entry.
[[nodiscard]] Status validate_moved(std::span<const std::uint32_t> moved, std::size_t objects);
/// validate_frame() for a whole FrameInput (Detector::detect() runs it before run_frame()): also
/// the filter count, and the id map's size (which then replaces Config's map size); an id map
/// and a gl texture together are an error; so is FrameInput::moved out of order. The ids themselves are checked where
/// they are counted (id_map_error()).
[[nodiscard]] Status validate_frame_input(const FrameInput& input, const Config& config, bool check_objects = true);

/// The rule validate_spheres() and validate_boxes() apply to one shape, without branches: every
/// coordinate (and radius) finite with magnitude at most kMaxCoordinate; a radius >= 0; a box's min
/// <= max on each axis. NaN fails every comparison.
[[nodiscard]] inline bool sphere_valid(const Sphere& o) {
  const float ax = std::fabs(o.x), ay = std::fabs(o.y), az = std::fabs(o.z), ar = std::fabs(o.r);
  return (ax <= kMaxCoordinate) & (ay <= kMaxCoordinate) & (az <= kMaxCoordinate) & (ar <= kMaxCoordinate) & (o.r >= 0);
}
[[nodiscard]] inline bool box_valid(const Box& b) {
  bool ok = true;
  for (int k = 0; k < 3; ++k) {
    const float lo = std::fabs(b.min[k]), hi = std::fabs(b.max[k]);
    ok &= (lo <= kMaxCoordinate) & (hi <= kMaxCoordinate) & (b.min[k] <= b.max[k]);
  }
  return ok;
}
/// validate_spheres()'s and validate_boxes()'s pass over every shape, without branches: true when
/// all are valid (only then is the first bad one not searched for).
[[nodiscard]] bool spheres_all_valid(std::span<const Sphere> spheres);
[[nodiscard]] bool boxes_all_valid(std::span<const Box> boxes);
/// Why one object is not valid, as "<name>: <what>" (validate_spheres()'s and validate_boxes()'s
/// words; ok when it is valid), for callers that name their objects otherwise ("static box").
[[nodiscard]] Status sphere_problem(const Sphere& s, const std::string& name);
[[nodiscard]] Status box_problem(const Box& b, const std::string& name);

/// Whether the frame brings the caller's visibility map (FrameInput::id_map or gl_id_texture).
[[nodiscard]] inline bool has_callers_map(const FrameInput& input) {
  return !input.id_map.empty() || input.gl_id_texture != 0;
}
/// Whether adaptive bits need this frame's pixels to choose m: adaptive, with a camera, and
/// either culling, or too few objects to know m without mu. Without culling, with more than
/// kMostObjectsFor16Bits objects and fewer screen pixels than pixels_for_32_bits per object, m is
/// 32 whatever the map shows (choose_bits()), so the map is not needed for it.
[[nodiscard]] bool adaptive_bits_need_pixels(const FrameInput& input, const Config& config);
/// Whether this frame renders a visibility map of its own (stage 1): a camera, no caller's map,
/// and something that uses the map (culling, adaptive bits that need pixels, shading,
/// Config::report_pixels).
[[nodiscard]] bool renders_own_map(const FrameInput& input, const Config& config);
/// Whether this frame counts pixels (stage 2): its own map, or the caller's.
[[nodiscard]] bool counts_pixels(const FrameInput& input, const Config& config);
/// The error of an id map holding an id above `objects`: names the first such pixel (x, y).
[[nodiscard]] Status id_map_error(std::span<const std::uint32_t> ids, int width, std::size_t objects);
/// The culling rules' view of the screen: screen pixels per map pixel, (screen area) / (map area),
/// as CameraRig computes it; 1 without a camera (counts are then map pixels).
[[nodiscard]] double map_pixel_scale(const Camera* camera, int map_width, int map_height);
/// The error of a frame that ran out of memory: its size, and what to change.
[[nodiscard]] std::string out_of_memory_message(std::size_t objects, const Camera* camera, const Config& config);

/// The pair-memory cap of Config (0 = none): an error naming the count when `pairs` exceed it.
/// `at_least`: the search stopped at the cap, so the frame has `pairs` or more.
[[nodiscard]] Status check_pair_cap(std::size_t pairs, std::size_t cap, bool at_least = false);
/// Pairs the cap allows (0 = no cap: the largest count).
[[nodiscard]] std::size_t pairs_within_cap(std::size_t cap);

/// The filters' pre-pass rule, every backend's: with `groups` the OR of the groups and `masks` the
/// OR of the masks over the active objects, an object can pair with another only when
/// (mask & groups) != 0 and (group & masks) != 0; the others stay out of the tree.
[[nodiscard]] constexpr bool may_pair(const Filter& f, std::uint32_t groups, std::uint32_t masks) {
  return (f.mask & groups) != 0 && (f.group & masks) != 0;
}

/// Bounds of the active centres and the sum of their diameters; partial extents of parts of the
/// active set merge in any grouping to the same bounds (the sum is a double: merged in a fixed
/// order, it is the same for every executor).
struct ActiveExtent {
  Aabb bounds;
  double diameter_sum = 0;
  std::size_t count = 0;

  void merge(const ActiveExtent& e) {
    bounds.grow(e.bounds);
    diameter_sum += e.diameter_sum;
    count += e.count;
  }
  [[nodiscard]] float mean_diameter() const {
    return count ? static_cast<float>(diameter_sum / static_cast<double>(count)) : 0.f;
  }
};
/// The extent of objects[active[k]] for k in [begin, end) (boxes by box_proxy()).
[[nodiscard]] ActiveExtent extent_of(const Shapes& objects, std::span<const std::uint32_t> active, std::size_t begin,
                                     std::size_t end);

}  // namespace viscd::detail
