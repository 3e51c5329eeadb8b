#pragma once
/// \file scene.hpp
/// Scene generators shared by the tests, the benchmarks, `viscd run` and the viewer.
///
/// Every scene moves its spheres in circles about the vertical (y) axis through the origin, each
/// object at its own angular speed (the paper's experiment, §IV): a scene is its objects' polar
/// coordinates (rho, theta, y), angular speeds and radii. Generation is deterministic in `seed`.

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

/// Camera presets framing a scene (paper Fig. 5):
/// "zoom-out" sees the whole world from afar (most objects small, many culled),
/// "zoom-in" a close view inside the world (few, large objects),
/// "orbit" circles the world once every 20 s of scene time, at mid distance.
[[nodiscard]] Result<Camera> camera_preset(std::string_view name, const Scene& scene, int width, int height);

}  // namespace viscd
