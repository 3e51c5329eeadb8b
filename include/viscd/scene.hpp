#pragma once
/// \file scene.hpp
/// Scene generators shared by the tests, the benchmarks, `viscd run` and the viewer.
///
/// Every scene moves its spheres in circles about the vertical (y) axis through the origin, each
/// object at its own angular speed (the paper's experiment, §IV): a scene is its objects' polar
/// coordinates (rho, theta, y), angular speeds and radii. Generation is deterministic in `seed`.
/// The same scene runs as boxes (cubes_of(): each sphere's cube) and may stand on a field of
/// static objects (static_field()).

#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "viscd/result.hpp"
#include "viscd/types.hpp"

namespace viscd {

enum class SceneKind : std::uint8_t {
  ring,      ///< the paper's flat ring world: y spread of 6 mean diameters, many collisions
  box,       ///< uniform in a cube
  clusters,  ///< dense Gaussian clusters inside a cube: very uneven density
};

/// Parameters of a generated scene.
struct SceneParams {
  SceneKind kind = SceneKind::ring;
  std::uint32_t objects = 10000;  ///< N
  std::uint64_t seed = 1;         ///< same seed, same scene, on every machine
  float mean_radius = 0.5f;       ///< radii are uniform in [0.5, 1.5] x mean_radius, world units
  /// Volume fraction of the spheres in the scene's volume; sets the world size so that the
  /// density (and hence the share of colliding objects) is the same for every N. Default 0.04.
  float packing = 0.04f;
};

/// A moving scene of spheres.
class Scene {
 public:
  /// Generates a scene. The world grows with N so that the density stays fixed.
  [[nodiscard]] static Scene make(const SceneParams& params);
  /// Current spheres (centres and radii). Valid until the next step().
  [[nodiscard]] std::span<const Sphere> spheres() const { return spheres_; }
  /// Advances every object by its angular speed times dt seconds.
  void step(float dt);
  /// Simulated time in seconds.
  [[nodiscard]] double time() const { return time_; }
  /// Radius of a cylinder about the y axis containing every centre; used to place cameras.
  [[nodiscard]] float world_radius() const { return world_radius_; }
  /// Half height of the slab containing every centre.
  [[nodiscard]] float world_half_height() const { return world_half_height_; }
  [[nodiscard]] const SceneParams& params() const { return params_; }

 private:
  SceneParams params_;
  std::vector<Sphere> spheres_;
  std::vector<float> rho_, theta_, omega_;
  double time_ = 0;
  float world_radius_ = 0;
  float world_half_height_ = 0;
};

/// Parses "ring", "box" or "clusters".
[[nodiscard]] Result<SceneKind> parse_scene_kind(std::string_view name);
[[nodiscard]] std::string_view scene_kind_name(SceneKind kind);

/// Parses "sphere" or "box": the shape a scene's objects are handed to the detector as.
[[nodiscard]] Result<ShapeKind> parse_shape_kind(std::string_view name);
[[nodiscard]] std::string_view shape_kind_name(ShapeKind kind);

/// The cube a sphere stands for when a scene runs as boxes: the centre minus and plus r on every
/// axis (the sphere's bounding box; a sphere of r = 0 is a point box).
[[nodiscard]] Box cube_of(const Sphere& sphere);
/// cube_of() of every sphere, into `cubes` (resized to match; its capacity is kept).
void cubes_of(std::span<const Sphere> spheres, std::vector<Box>& cubes);

/// A field of `count` static objects on the scene's ground, for the detector's static set
/// (`viscd run --static K`, `viscd view --static K`). The ground is the floor of the slab that
/// holds the moving objects' centres (y = -world_half_height()), first under where they circle
/// (the ring's annulus, the square under a box or clusters scene), then around it. About three features in four are
/// rocks, single spheres of radius 1 to 3 mean radii half sunk into the ground; the rest are
/// pillars, stacks of spheres of radius 1 to 1.5 mean radii, each 1.5 radii above the one below,
/// standing 12 mean radii tall (through the whole ring slab), so that the moving objects run into
/// them. Every sphere of a stack is one object; the last pillar is cut short to make `count`.
/// Features stand one per 64 mean radii squared of ground: once the ground under the objects is
/// full, later features spread outward over ground that grows with them, so a field of a million
/// is as dense near the objects as one of a thousand (and the frame's cost follows what is near).
/// Deterministic in the scene's seed (its own stream: the moving objects stay as they were), the
/// world's size and `count`; the first k objects of a field are the field of k. For a box scene take cubes_of() the
/// field: rocks become blocks and pillars stacks of blocks.
[[nodiscard]] std::vector<Sphere> static_field(const Scene& scene, std::uint32_t count);

/// Camera presets framing a scene (paper Fig. 5):
/// "zoom-out" sees the whole world from afar (most objects small, many culled),
/// "zoom-in" a close view inside the world (few, large objects),
/// "orbit" circles the world once every 20 s of scene time, at mid distance.
[[nodiscard]] Result<Camera> camera_preset(std::string_view name, const Scene& scene, int width, int height);

}  // namespace viscd
