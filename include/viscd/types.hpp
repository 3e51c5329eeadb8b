#pragma once
/// \file types.hpp
/// Plain value types shared by every part of viscd: spheres, pairs, cameras, object states.

#include <compare>
#include <cstdint>
#include <limits>

namespace viscd {

/// A bounding sphere: centre (x, y, z) and radius r, in world units (any unit, used consistently).
/// Laid out as a `vec4` (16 bytes) so that arrays of spheres upload to the GPU unchanged.
/// Valid spheres have finite coordinates with magnitude at most kMaxCoordinate and 0 <= r <= kMaxCoordinate;
/// r = 0 is a point and allowed.
struct Sphere {
  float x = 0, y = 0, z = 0, r = 0;
};
static_assert(sizeof(Sphere) == 16, "Sphere must match GLSL vec4");

/// Largest magnitude of a coordinate or radius viscd accepts. Squares of sums of such values stay
/// finite in float (4e18^2 = 1.6e37 < 3.4e38), so the overlap test never sees an overflow.
inline constexpr float kMaxCoordinate = 1e18f;

/// Largest visibility map viscd renders: each side at most kMaxMapSide pixels and at most
/// kMaxMapPixels pixels in all (8192 x 8192; a map costs 8 to 28 bytes per pixel). A larger
/// screen is fine: set a smaller map (Config::map_width, map_height) and counts are scaled.
inline constexpr int kMaxMapSide = 16384;
inline constexpr std::uint64_t kMaxMapPixels = std::uint64_t{1} << 26;

/// An unordered pair of colliding objects, stored with i < j, as 0-based indices into the input.
struct Pair {
  std::uint32_t i = 0, j = 0;
  friend constexpr auto operator<=>(const Pair&, const Pair&) = default;
};

/// An object's collision filter. Objects i and j are reported as a pair only when
/// `(group_i & mask_j) != 0 && (group_j & mask_i) != 0` (pair_passes_filter() in detector.hpp).
/// The default (group 1, every mask bit) pairs with every other default object. Filters decide
/// which pairs are reported, never which objects are active; queries see them only when given a
/// filter of their own (Detector::ray_cast, overlap).
struct Filter {
  std::uint32_t group = 1;           ///< the groups the object belongs to (bits)
  std::uint32_t mask = 0xFFFFFFFFu;  ///< the groups it may collide with (bits)
};

/// A ray for Detector::ray_cast: the points origin + t * dir for 0 <= t <= max_t. `dir` need not be
/// unit length (t is then in units of |dir|); a zero `dir` hits nothing.
struct Ray {
  float origin[3] = {0, 0, 0};
  float dir[3] = {0, 0, 1};
  float max_t = std::numeric_limits<float>::infinity();
};

/// An object a ray hits: its index (static_index(k) for a static object) and the smallest t >= 0
/// of the ray inside or on it (0 when the ray starts inside or on it).
struct RayHit {
  std::uint32_t index = 0;
  float t = 0;
  friend constexpr bool operator==(const RayHit&, const RayHit&) = default;
};

/// An axis-aligned box, in world units: the points p with min[k] <= p[k] <= max[k] on every axis k
/// (closed: its faces belong to it). A box with min = max is a point. Boxes are objects
/// (FrameInput::boxes, the static set) and query shapes (Detector::overlap_box). As an object a
/// box must be valid (validate_boxes(): finite, |value| <= kMaxCoordinate, min <= max); as a query
/// shape an invalid box overlaps nothing. Two boxes overlap by boxes_overlap(), a sphere and a box
/// by sphere_overlaps_box() (detector.hpp).
struct Box {
  float min[3] = {0, 0, 0};
  float max[3] = {0, 0, 0};
};
static_assert(sizeof(Box) == 24, "Box is six floats");

/// What a frame's objects are (FrameInput::spheres or FrameInput::boxes; the static set's kind).
enum class ShapeKind : std::uint8_t { sphere, box };

/// Static objects (Detector::add_static_sphere and the rest) are reported by an index with this
/// bit set: static_index(k) for the object in slot k of the static set. Moving objects' indices
/// stay below it (a frame holds at most 2^31 - 1 objects), so in a Pair {i, j} with i < j a static
/// object is always j, and pairs sort moving pairs of i before i's pairs with static objects.
inline constexpr std::uint32_t kStaticBit = 0x80000000u;
/// The index under which pairs, events and queries report static object k.
[[nodiscard]] constexpr std::uint32_t static_index(std::uint32_t k) { return k | kStaticBit; }
/// Whether a reported index names a static object.
[[nodiscard]] constexpr bool is_static_index(std::uint32_t index) { return (index & kStaticBit) != 0; }
/// The static set's slot k of a reported static index (static_index(k) -> k).
[[nodiscard]] constexpr std::uint32_t static_slot(std::uint32_t index) { return index & ~kStaticBit; }

/// What one frame decided about an object.
enum class ObjectState : std::uint8_t {
  culled = 0,     ///< fewer than lambda screen pixels: not given to the broadphase
  free = 1,       ///< active (visible enough) and overlapping nothing active
  colliding = 2,  ///< active and overlapping at least one other active object
};

/// An sRGB colour, 0 to 255 per channel.
struct Rgb8 {
  std::uint8_t r = 0, g = 0, b = 0;
};
/// The colour the shaded image (FrameResult::image) gives an object: red colliding, blue free,
/// yellow culled (the paper's), so that an application's own debug view can match it.
[[nodiscard]] constexpr Rgb8 state_colour(ObjectState s) {
  switch (s) {
    case ObjectState::colliding:
      return {220, 40, 40};
    case ObjectState::free:
      return {50, 90, 230};
    case ObjectState::culled:
      break;
  }
  return {235, 200, 40};
}
/// The colour the shaded image gives static objects (Detector::set_static_spheres and the rest).
inline constexpr Rgb8 kStaticColour{140, 140, 150};
/// The shaded image's background (pixels no object covers).
inline constexpr Rgb8 kBackgroundColour{18, 18, 24};

/// A pinhole camera: right-handed look-at, OpenGL clip space (the view looks down -z).
/// `width` x `height` is the screen in pixels; pixel counts are always given in screen pixels.
struct Camera {
  float eye[3] = {0, 0, 10};    ///< position, world units
  float target[3] = {0, 0, 0};  ///< point looked at, world units
  float up[3] = {0, 1, 0};      ///< up direction (need not be unit length)
  float fov_y_deg = 60;         ///< vertical field of view, degrees, in (0, 180)
  float near_plane = 0.1f;      ///< distance of the near plane along the view direction, > 0
  float far_plane = 1000;       ///< distance of the far plane, > near_plane
  int width = 1280;             ///< screen width in pixels, >= 1
  int height = 720;             ///< screen height in pixels, >= 1

  /// Every field equal (floats by ==).
  friend bool operator==(const Camera&, const Camera&) = default;
};

}  // namespace viscd
