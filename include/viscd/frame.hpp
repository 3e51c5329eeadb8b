#pragma once
/// \file frame.hpp
/// What a detector reports for one frame.

#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "viscd/types.hpp"

namespace viscd {

/// Pipeline stages timed by detectors (docs/architecture.md, "Where each stage lives"; stage 0,
/// simulation, is the caller's). The stages are the paper's; where a backend does a stage its own
/// way, the line says so (reference = brute force, the test oracle).
enum class Stage : std::uint8_t {
  visibility,  ///< 1: id map + depth. reference: a ray per pixel; cpu: tiled sphere rasterizer; gl: instanced draw
  count,       ///< 2: pixels per object from the id map (all backends; gl: SSBO or atomic-counter atomics)
  cull,        ///< 3: active set (pixels >= lambda) and mu; the bit count m from mu
  layout,      ///< 4: extent of the active centres and the Morton layout (all backends; reference only reports it)
  codes,       ///< 5: Morton codes. cpu: also gathers the objects in the last frame's order; reference: none
  sort,        ///< 6: (code, object) by code, ties by object. cpu: from the last order, or LSD radix; gl: radix passes
  build,       ///< 7a: gl: the Karras hierarchy over the sorted codes; cpu: the objects into buckets of 16 lanes
  fit,         ///< 7b: gl: bottom-up AABB fit; cpu: the 16-wide tree over the bucket boxes
  query,       ///< 8: exact overlap tests, sorted pairs, object states. reference: all pairs; cpu: bucket search; gl:
               ///< traversal
  shade,       ///< 9: shaded image: red colliding, blue free, yellow culled
  count_       ///< number of stages (not a stage)
};
inline constexpr std::size_t kStageCount = static_cast<std::size_t>(Stage::count_);

/// Short lowercase name of a stage ("visibility", "sort", ...).
[[nodiscard]] std::string_view stage_name(Stage s);

/// Everything one frame takes (Detector::detect). Spans need only live for the call.
struct FrameInput {
  /// The moving objects as bounding spheres; an object's index is its position here, and keeps
  /// its meaning from frame to frame (contact events compare pairs by index).
  std::span<const Sphere> spheres;
  /// Or the moving objects as axis-aligned boxes (validate_boxes()); a frame holds spheres or
  /// boxes, never both. Every stage takes boxes: Morton codes from box centres, the layout rule
  /// with the boxes' mean size (the mean of their three side lengths stands for a sphere's
  /// diameter), the exact box test boxes_overlap(), boxes drawn as boxes in the detector's own
  /// map. The per-object spans below then have one entry per box. The detector's static set, when
  /// not empty, must hold the same kind.
  std::span<const Box> boxes;
  /// The camera for visibility culling; nullptr: no culling (unless `id_map` is given).
  const Camera* camera = nullptr;
  /// Empty: no filtering. Else one Filter per object: a pair is reported only when both objects'
  /// filters accept each other (Filter).
  std::span<const Filter> filters;
  /// Never culled. Empty: culling alone decides. Else one flag per object: an object whose flag is
  /// not 0 is active whatever its pixels, even covering none (the player, the vehicle the camera
  /// sits in, a projectile the game must not lose; docs/embedding.md, "What culling does to
  /// gameplay"). Its pixels are still counted and still enter mu. Every backend.
  std::span<const std::uint8_t> always_active;
  /// The caller's own visibility map, id_map_width x id_map_height object ids, row-major from the
  /// top-left pixel: 0 = background, object index + 1 elsewhere. When given, the detector renders
  /// nothing: it counts pixels per object from this map, then culls and picks the Morton width from
  /// the counts as from a map of its own. With `camera` counts are scaled by screen area / map
  /// area; without one they are map pixels. The map's size replaces Config::map_width x
  /// map_height and follows validate_map_size(); an id above the number of objects is an error
  /// (static objects are not counted: write them as 0, background).
  /// Every backend; the gl backend also takes the map as a texture (`gl_id_texture`).
  std::span<const std::uint32_t> id_map;
  int id_map_width = 0, id_map_height = 0;
  /// gl backend only: the caller's R32UI texture holding such a map (GlOptions::use_current_context
  /// shares the caller's context, where the texture lives; its size in id_map_width x
  /// id_map_height); 0 = none. The other backends refuse a frame that sets it.
  unsigned gl_id_texture = 0;
  /// The objects whose bounds changed since this detector's previous frame, when the caller knows
  /// them (PhysX's updated handles, Jolt's NotifyBodiesAABBChanged): sorted ascending, no repeats,
  /// each below the frame's object count; read only when `moved_listed` is true. With the list the
  /// cpu backend (Config::follow_change) compares no bounds of unlisted objects and checks only the
  /// listed ones for NaN and range: an object left out that did change makes that frame's results
  /// unspecified (docs/embedding.md, "Telling the detector what moved"; Config::verify_moved checks
  /// the list). Listing an object that did not change costs a compare. Objects beyond the last
  /// frame's count are new and need no listing; in such a frame the cpu backend checks the list
  /// and compares every old object. Other backends check the list and then compare nothing:
  /// they rebuild every frame.
  std::span<const std::uint32_t> moved;
  bool moved_listed = false;
};

/// The Morton layout a frame used (stage 4), as data: which axis supplies the code's bits first,
/// and how many bits each axis got. format_layout() prints it as the paper's Table 2 does.
struct MortonLayoutInfo {
  std::array<std::uint8_t, 3> order{0, 1, 2};  ///< axes (0 = x, 1 = y, 2 = z), largest extent first
  std::array<std::uint8_t, 3> axis_bits{};     ///< bits per axis, indexed by axis (x, y, z); all 0: none
  [[nodiscard]] int total_bits() const { return axis_bits[0] + axis_bits[1] + axis_bits[2]; }
  friend bool operator==(const MortonLayoutInfo&, const MortonLayoutInfo&) = default;
};

/// "x(7)→z(6)→y(3)": the axes in `order` with their bit counts (an axis with no bits is left out;
/// "" when no axis has any). `ascii` writes "->" for the arrow.
[[nodiscard]] std::string format_layout(const MortonLayoutInfo& layout, bool ascii = false);

/// Numbers describing one frame.
struct FrameStats {
  std::uint32_t objects = 0;                   ///< N, the frame's moving objects (spheres or boxes)
  std::uint32_t static_objects = 0;            ///< objects in the detector's static set this frame
  std::uint32_t active = 0;                    ///< objects not culled (N when culling is off)
  bool has_camera = false;                     ///< a camera was given
  bool has_pixels = false;                     ///< pixels were counted (a camera or the caller's id map): mu is defined
  double mean_pixels = 0;                      ///< mu: total covered screen pixels / N (0 without pixels)
  int bits = 0;                                ///< Morton width m used this frame: 16, 32 or 64
  MortonLayoutInfo layout;                     ///< the Morton layout used; format_layout() prints it
  std::uint64_t pairs = 0;                     ///< number of colliding pairs
  bool order_kept = false;                     ///< cpu: the last frame's object order was kept (no stages 4-6)
  bool followed_change = false;                ///< cpu: the frame updated the resting objects' trees, not a rebuild
  std::uint32_t moved = 0;                     ///< with followed_change: objects whose bounds changed this frame
  std::uint32_t replaced = 0;                  ///< with followed_change: of those, the ones that left their fat bounds
  std::array<double, kStageCount> stage_ms{};  ///< wall (cpu) or GPU (gl) milliseconds per stage, by Stage
  /// Milliseconds of one stage.
  [[nodiscard]] double& ms(Stage s) { return stage_ms[static_cast<std::size_t>(s)]; }
  [[nodiscard]] double ms(Stage s) const { return stage_ms[static_cast<std::size_t>(s)]; }
  [[nodiscard]] double total_ms() const;
};

/// Result of one frame. Reuse one FrameResult across frames: its buffers keep their capacity,
/// so a steady state allocates nothing.
struct FrameResult {
  /// Every overlapping pair among active objects, (i < j), sorted, unique: the pairs of moving
  /// objects, and of each active moving object i with each static object k as
  /// {i, static_index(k)} (never two static objects; is_static_index() tells them apart).
  std::vector<Pair> pairs;
  /// State of each of the N moving objects (static objects have none: never culled).
  std::vector<ObjectState> state;
  /// Screen pixels covered by each moving object (after map-to-screen scaling); empty when no pixels
  /// were counted (no camera and no id map).
  std::vector<float> pixels;
  /// With Config::contact_events: the pairs of `pairs` that the previous frame of this detector
  /// did not report (began), and the previous frame's pairs that this one does not report
  /// (ended); both sorted by (i, j). Without contact events both are empty.
  std::vector<Pair> began;
  std::vector<Pair> ended;
  /// Shaded RGBA8 image (stage 9), image_width x image_height, rows top to bottom; filled only
  /// when Config::shade is set and a camera is given.
  std::vector<std::uint8_t> image;
  int image_width = 0;
  int image_height = 0;
  FrameStats stats;
};

}  // namespace viscd
