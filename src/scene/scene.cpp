#include "viscd/scene.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>

#include "viscd/io.hpp"

namespace viscd {
namespace {

constexpr float kPi = std::numbers::pi_v<float>;
// Linear speeds in world units per second, uniform in [kMinSpeed, kMaxSpeed] x mean radius.
constexpr float kMinSpeed = 2.0f, kMaxSpeed = 10.0f;

// splitmix64-seeded mt19937_64 and our own uniform mapping: std::uniform_real_distribution is
// not specified bit for bit, and scenes must be the same on every standard library.
class Rng {
 public:
  explicit Rng(std::uint64_t seed) : engine_(seed * 0x9E3779B97F4A7C15ull + 0x632BE59BD9B4E019ull) {}
  float uniform(float lo, float hi) {
    const double u = static_cast<double>(engine_() >> 11) * 0x1p-53;
    return static_cast<float>(lo + (hi - lo) * u);
  }
  float normal() {  // Box-Muller
    const float u1 = std::max(uniform(0, 1), 1e-12f), u2 = uniform(0, 1);
    return std::sqrt(-2.0f * std::log(u1)) * std::cos(2 * kPi * u2);
  }

 private:
  std::mt19937_64 engine_;
};

}  // namespace

Scene Scene::make(const SceneParams& p) {
  Scene s;
  s.params_ = p;
  const std::size_t n = p.objects;
  s.spheres_.resize(n);
  s.rho_.resize(n);
  s.theta_.resize(n);
  s.omega_.resize(n);
  Rng rng(p.seed);
  const float rm = p.mean_radius;
  // Mean of r^3 for r uniform in [0.5, 1.5] rm is 1.25 rm^3.
  const double sphere_volume = static_cast<double>(n) * 4.0 / 3.0 * std::numbers::pi * 1.25 * rm * rm * rm;
  const double world_volume = sphere_volume / std::max(1e-6f, p.packing);
  std::vector<float> y(n);

  switch (p.kind) {
    case SceneKind::ring: {
      // A flat annulus R_in = R_out / 2, centres' y within +-6 rm (6 mean diameters in all, so
      // the extended layout gives y 3 bits, as in the paper's Table 2).
      const float h = 6.0f * rm;
      const double r_out = std::sqrt(world_volume / (0.75 * std::numbers::pi * 2.0 * h));
      const auto r_in = static_cast<float>(0.5 * r_out);
      for (std::size_t k = 0; k < n; ++k) {
        // Uniform over the annulus area: rho^2 uniform.
        s.rho_[k] = std::sqrt(rng.uniform(r_in * r_in, static_cast<float>(r_out * r_out)));
        s.theta_[k] = rng.uniform(0, 2 * kPi);
        y[k] = rng.uniform(-h, h);
      }
      s.world_half_height_ = h;
      break;
    }
    case SceneKind::box:
    case SceneKind::clusters: {
      const auto half = static_cast<float>(0.5 * std::cbrt(world_volume));
      const std::size_t clusters = std::max<std::size_t>(1, n / 1000);
      std::vector<float> cx(clusters), cy(clusters), cz(clusters);
      for (std::size_t c = 0; c < clusters; ++c)
        cx[c] = rng.uniform(-half, half), cy[c] = rng.uniform(-half, half), cz[c] = rng.uniform(-half, half);
      for (std::size_t k = 0; k < n; ++k) {
        float x, z;
        if (p.kind == SceneKind::box) {
          x = rng.uniform(-half, half), y[k] = rng.uniform(-half, half), z = rng.uniform(-half, half);
        } else {
          const std::size_t c = k % clusters;
          const float sigma = 0.05f * half;
          x = std::clamp(cx[c] + sigma * rng.normal(), -half, half);
          y[k] = std::clamp(cy[c] + sigma * rng.normal(), -half, half);
          z = std::clamp(cz[c] + sigma * rng.normal(), -half, half);
        }
        s.rho_[k] = std::sqrt(x * x + z * z);
        s.theta_[k] = std::atan2(z, x);
      }
      s.world_half_height_ = half;
      break;
    }
  }
  float world = 0;
  for (std::size_t k = 0; k < n; ++k) {
    const float r = rng.uniform(0.5f * rm, 1.5f * rm);
    const float v = rng.uniform(kMinSpeed, kMaxSpeed) * rm;
    s.omega_[k] = v / std::max(s.rho_[k], rm);
    s.spheres_[k] = Sphere{s.rho_[k] * std::cos(s.theta_[k]), y[k], s.rho_[k] * std::sin(s.theta_[k]), r};
    world = std::max(world, s.rho_[k]);
  }
  s.world_radius_ = world;
  return s;
}

void Scene::step(float dt) {
  time_ += dt;
  const std::size_t n = spheres_.size();
  for (std::size_t k = 0; k < n; ++k) {
    float th = theta_[k] + omega_[k] * dt;
    if (th > 2 * kPi) th -= 2 * kPi;  // keeps theta small so cos/sin stay accurate over long runs
    theta_[k] = th;
    spheres_[k].x = rho_[k] * std::cos(th);
    spheres_[k].z = rho_[k] * std::sin(th);
  }
}

Result<SceneKind> parse_scene_kind(std::string_view name) {
  if (name == "ring") return SceneKind::ring;
  if (name == "box") return SceneKind::box;
  if (name == "clusters") return SceneKind::clusters;
  return Result<SceneKind>::failure(ErrorKind::invalid_input,
                                    "unknown scene '" + std::string(name) + "': expected ring, box or clusters");
}

std::string_view scene_kind_name(SceneKind kind) {
  switch (kind) {
    case SceneKind::ring:
      return "ring";
    case SceneKind::box:
      return "box";
    case SceneKind::clusters:
      return "clusters";
  }
  return "?";
}

Result<ShapeKind> parse_shape_kind(std::string_view name) {
  if (name == "sphere") return ShapeKind::sphere;
  if (name == "box") return ShapeKind::box;
  return Result<ShapeKind>::failure(ErrorKind::invalid_input,
                                    "unknown shape '" + printable(name) + "': expected sphere or box");
}

std::string_view shape_kind_name(ShapeKind kind) { return kind == ShapeKind::box ? "box" : "sphere"; }

Box cube_of(const Sphere& s) { return Box{{s.x - s.r, s.y - s.r, s.z - s.r}, {s.x + s.r, s.y + s.r, s.z + s.r}}; }

void cubes_of(std::span<const Sphere> spheres, std::vector<Box>& cubes) {
  cubes.resize(spheres.size());
  for (std::size_t k = 0; k < spheres.size(); ++k) cubes[k] = cube_of(spheres[k]);
}

std::vector<Sphere> static_field(const Scene& scene, std::uint32_t count) {
  std::vector<Sphere> out;
  out.reserve(count);
  // A stream of its own: the field does not change the scene's objects, nor they the field.
  Rng rng(scene.params().seed ^ 0xA5F1E1D5A7A71Cull);
  const float rm = scene.params().mean_radius;
  const float ground = -scene.world_half_height();
  const bool ring = scene.params().kind == SceneKind::ring;
  // Where the objects circle: the ring's annulus (inner radius half the outer, as Scene::make()),
  // else the square under the cube.
  const float outer = std::max(scene.world_radius(), rm);
  const float half = std::max(scene.world_half_height(), rm);
  constexpr float kPillarHeight = 12;  // mean radii: the ring slab's height
  // A feature per kFeatureArea mean radii squared of ground: the first ones fill the ground under
  // the objects, and later ones spread outward over ground that grows with them (feature f is
  // placed on the area that f features need), so a large field stays as dense near the objects as
  // a small one and its size grows the world, not the crowd under the ring.
  constexpr float kFeatureArea = 64;
  const float feature_area = kFeatureArea * rm * rm;
  for (std::uint32_t feature = 0; out.size() < count; ++feature) {
    // Every feature draws the same numbers, so that a smaller count gives a prefix of the field.
    const float needed = static_cast<float>(feature + 1) * feature_area;  // ground for features 0..f
    float x, z;
    if (ring) {
      const float inner2 = 0.25f * outer * outer;
      const float outer2 = std::max(outer * outer, inner2 + needed / kPi);
      const float rho = std::sqrt(rng.uniform(inner2, outer2));
      const float theta = rng.uniform(0, 2 * kPi);
      x = rho * std::cos(theta), z = rho * std::sin(theta);
    } else {
      const float side = std::max(half, 0.5f * std::sqrt(needed));
      x = rng.uniform(-side, side), z = rng.uniform(-side, side);
    }
    const bool pillar = rng.uniform(0, 1) < 0.25f;
    const float size = rng.uniform(0, 1);
    if (!pillar) {
      const float r = (1 + 2 * size) * rm;
      out.push_back({x, ground + 0.5f * r, z, r});  // half sunk into the ground
      continue;
    }
    const float r = (1 + 0.5f * size) * rm;
    const float step = 1.5f * r;
    const auto stack = static_cast<std::size_t>(std::ceil(kPillarHeight * rm / step)) + 1;
    for (std::size_t k = 0; k < stack && out.size() < count; ++k)
      out.push_back({x, ground + static_cast<float>(k) * step, z, r});
  }
  return out;
}

Result<Camera> camera_preset(std::string_view name, const Scene& scene, int width, int height) {
  Camera c;
  c.width = width;
  c.height = height;
  c.fov_y_deg = 60;
  const float R = std::max(scene.world_radius(), 1.0f);
  const float rm = scene.params().mean_radius;
  auto set = [&](float ex, float ey, float ez, float tx, float ty, float tz) {
    c.eye[0] = ex, c.eye[1] = ey, c.eye[2] = ez;
    c.target[0] = tx, c.target[1] = ty, c.target[2] = tz;
  };
  if (name == "zoom-out") {
    // The whole ring from just above its near edge: near objects big, the far side tiny, so
    // most objects fall below lambda (the paper's Fig. 5a).
    set(0, 0.14f * R, 1.15f * R, 0, -0.02f * R, 0.3f * R);
  } else if (name == "zoom-in") {
    // Inside the ring, just above the objects, looking along it: few, large objects.
    const float ring = 0.75f * R;
    set(0, 14 * rm, ring + 4 * rm, -30 * rm, 0, ring - 10 * rm);
  } else if (name == "orbit") {
    const double a = 2.0 * std::numbers::pi * scene.time() / 20.0;
    set(static_cast<float>(1.3 * R * std::cos(a)), 0.6f * R, static_cast<float>(1.3 * R * std::sin(a)), 0, 0, 0);
  } else {
    return Result<Camera>::failure(
        ErrorKind::invalid_input,
        "unknown camera preset '" + std::string(name) + "': expected zoom-out, zoom-in, orbit or a .json file");
  }
  c.near_plane = 0.05f * rm;
  c.far_plane = 8 * R + 100 * rm;
  return c;
}

}  // namespace viscd
