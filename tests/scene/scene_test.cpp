// Tests of the scene generators (the paper's circular motion, box, clusters) and camera presets.
#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <numbers>
#include <set>
#include <vector>

#include "viscd/detector.hpp"
#include "viscd/scene.hpp"

namespace viscd {
namespace {

constexpr double kTwoPi = 2.0 * std::numbers::pi;

bool bitwise_equal(std::span<const Sphere> a, std::span<const Sphere> b) {
  return a.size() == b.size() && (a.empty() || std::memcmp(a.data(), b.data(), a.size_bytes()) == 0);
}

double rho_of(const Sphere& s) { return std::hypot(static_cast<double>(s.x), static_cast<double>(s.z)); }
double angle_of(const Sphere& s) { return std::atan2(static_cast<double>(s.z), static_cast<double>(s.x)); }
// The angle from a to b in (-pi, pi].
double angle_diff(double a, double b) {
  double d = std::fmod(b - a, kTwoPi);
  if (d <= -std::numbers::pi) d += kTwoPi;
  if (d > std::numbers::pi) d -= kTwoPi;
  return d;
}

SceneParams params(SceneKind kind, std::uint32_t n, std::uint64_t seed = 1, float mean_radius = 0.5f) {
  SceneParams p;
  p.kind = kind;
  p.objects = n;
  p.seed = seed;
  p.mean_radius = mean_radius;
  return p;
}

constexpr SceneKind kKinds[] = {SceneKind::ring, SceneKind::box, SceneKind::clusters};

TEST(Scene, DefaultsAreThePapersSetup) {
  const SceneParams p;
  EXPECT_EQ(p.kind, SceneKind::ring);
  EXPECT_EQ(p.objects, 10000u);
  EXPECT_EQ(p.mean_radius, 0.5f);
  EXPECT_EQ(p.packing, 0.04f);
}

TEST(Scene, DeterministicForASeed) {
  for (SceneKind kind : kKinds) {
    const Scene a = Scene::make(params(kind, 3000, 77));
    const Scene b = Scene::make(params(kind, 3000, 77));
    ASSERT_EQ(a.spheres().size(), 3000u);
    EXPECT_TRUE(bitwise_equal(a.spheres(), b.spheres())) << scene_kind_name(kind);
    EXPECT_EQ(a.world_radius(), b.world_radius());
    EXPECT_EQ(a.world_half_height(), b.world_half_height());
  }
}

TEST(Scene, DeterministicAfterSteps) {
  Scene a = Scene::make(params(SceneKind::ring, 2000, 5));
  Scene b = Scene::make(params(SceneKind::ring, 2000, 5));
  for (int f = 0; f < 10; ++f) {
    a.step(1.0f / 60.0f);
    b.step(1.0f / 60.0f);
  }
  EXPECT_TRUE(bitwise_equal(a.spheres(), b.spheres()));
}

TEST(Scene, DiffersAcrossSeeds) {
  for (SceneKind kind : kKinds) {
    const Scene a = Scene::make(params(kind, 1000, 1));
    const Scene b = Scene::make(params(kind, 1000, 2));
    ASSERT_EQ(a.spheres().size(), b.spheres().size());
    EXPECT_FALSE(bitwise_equal(a.spheres(), b.spheres())) << scene_kind_name(kind);
    // Not just one sphere: nearly all differ.
    std::size_t same = 0;
    for (std::size_t k = 0; k < a.spheres().size(); ++k)
      same += std::memcmp(&a.spheres()[k], &b.spheres()[k], sizeof(Sphere)) == 0;
    EXPECT_LT(same, 10u) << scene_kind_name(kind);
  }
}

TEST(Scene, ParamsAreKept) {
  const SceneParams p = params(SceneKind::box, 123, 9, 2.0f);
  const Scene s = Scene::make(p);
  EXPECT_EQ(s.params().kind, SceneKind::box);
  EXPECT_EQ(s.params().objects, 123u);
  EXPECT_EQ(s.params().seed, 9u);
  EXPECT_EQ(s.params().mean_radius, 2.0f);
  EXPECT_EQ(s.spheres().size(), 123u);
  EXPECT_EQ(s.time(), 0.0);
}

TEST(Scene, ZeroObjects) {
  for (SceneKind kind : kKinds) {
    Scene s = Scene::make(params(kind, 0));
    EXPECT_TRUE(s.spheres().empty());
    EXPECT_TRUE(std::isfinite(s.world_radius()));
    EXPECT_GE(s.world_radius(), 0.0f);
    s.step(0.5f);
    EXPECT_TRUE(s.spheres().empty());
    EXPECT_DOUBLE_EQ(s.time(), 0.5);
  }
}

TEST(Scene, OneObject) {
  for (SceneKind kind : kKinds) {
    Scene s = Scene::make(params(kind, 1));
    ASSERT_EQ(s.spheres().size(), 1u) << scene_kind_name(kind);
    const Sphere a = s.spheres()[0];
    EXPECT_TRUE(validate_spheres(s.spheres()).ok());
    EXPECT_GE(a.r, 0.25f);
    EXPECT_LE(a.r, 0.75f);
    s.step(0.1f);
    ASSERT_EQ(s.spheres().size(), 1u);
    EXPECT_TRUE(validate_spheres(s.spheres()).ok());
    EXPECT_EQ(s.spheres()[0].y, a.y);
    EXPECT_NEAR(rho_of(s.spheres()[0]), rho_of(a), 1e-4 * std::max(1.0, rho_of(a)));
  }
}

TEST(Scene, RadiiWithinHalfToOneAndAHalfMean) {
  for (SceneKind kind : kKinds) {
    for (float rm : {0.5f, 2.0f, 0.01f}) {
      const Scene s = Scene::make(params(kind, 5000, 3, rm));
      float lo = 1e30f, hi = 0;
      double sum = 0;
      for (const Sphere& sp : s.spheres()) {
        ASSERT_GE(sp.r, 0.5f * rm) << scene_kind_name(kind) << " rm " << rm;
        ASSERT_LE(sp.r, 1.5f * rm) << scene_kind_name(kind) << " rm " << rm;
        lo = std::min(lo, sp.r), hi = std::max(hi, sp.r);
        sum += sp.r;
      }
      // Uniform: the range is used and the mean is the mean radius.
      EXPECT_LT(lo, 0.55f * rm);
      EXPECT_GT(hi, 1.45f * rm);
      EXPECT_NEAR(sum / 5000.0, rm, 0.02 * rm);
    }
  }
}

TEST(Scene, SpheresAreValidInput) {
  for (SceneKind kind : kKinds) {
    Scene s = Scene::make(params(kind, 20000, 11));
    EXPECT_TRUE(validate_spheres(s.spheres()).ok()) << scene_kind_name(kind);
    s.step(0.25f);
    EXPECT_TRUE(validate_spheres(s.spheres()).ok()) << scene_kind_name(kind);
  }
}

TEST(Scene, RingIsAFlatAnnulus) {
  for (float rm : {0.5f, 1.0f}) {
    const Scene s = Scene::make(params(SceneKind::ring, 10000, 4, rm));
    const double R = s.world_radius();
    ASSERT_GT(R, 0.0);
    EXPECT_FLOAT_EQ(s.world_half_height(), 6.0f * rm);
    double max_rho = 0, min_rho = 1e30, max_y = 0;
    for (const Sphere& sp : s.spheres()) {
      const double rho = rho_of(sp);
      ASSERT_LE(std::fabs(sp.y), 6.0 * rm) << "y = " << sp.y;
      ASSERT_LE(rho, R * (1 + 1e-5)) << "rho = " << rho << ", R = " << R;
      ASSERT_GE(rho, 0.5 * R * (1 - 1e-5)) << "rho = " << rho << ", R = " << R;
      max_rho = std::max(max_rho, rho), min_rho = std::min(min_rho, rho);
      max_y = std::max(max_y, static_cast<double>(std::fabs(sp.y)));
    }
    // The annulus and the slab are filled, not just bounded.
    EXPECT_GT(max_rho, 0.99 * R);
    EXPECT_LT(min_rho, 0.52 * R);
    EXPECT_GT(max_y, 5.9 * rm);
    // A flat world: far wider than high.
    EXPECT_GT(R, 10.0 * 6.0 * rm);
  }
}

TEST(Scene, RingAreaUniform) {
  // rho^2 uniform over [R^2/4, R^2]: half the objects lie beyond rho^2 = 5/8 R^2.
  const Scene s = Scene::make(params(SceneKind::ring, 20000, 8));
  const double R = s.world_radius();
  std::size_t outer = 0;
  for (const Sphere& sp : s.spheres()) outer += rho_of(sp) * rho_of(sp) > 0.625 * R * R;
  EXPECT_NEAR(static_cast<double>(outer) / 20000.0, 0.5, 0.02);
}

TEST(Scene, WorldGrowsWithNAtFixedDensity) {
  // The ring's height is fixed, so its area (and R^2) grows linearly with N.
  const Scene a = Scene::make(params(SceneKind::ring, 10000, 1));
  const Scene b = Scene::make(params(SceneKind::ring, 40000, 1));
  EXPECT_NEAR(b.world_radius() / a.world_radius(), 2.0, 0.05);
  // The box's volume grows linearly with N: its side by the cube root.
  const Scene c = Scene::make(params(SceneKind::box, 10000, 1));
  const Scene d = Scene::make(params(SceneKind::box, 80000, 1));
  EXPECT_NEAR(d.world_half_height() / c.world_half_height(), 2.0, 1e-3);
}

TEST(Scene, BoxAndClustersInsideTheirCube) {
  for (SceneKind kind : {SceneKind::box, SceneKind::clusters}) {
    Scene s = Scene::make(params(kind, 10000, 6));
    const double half = s.world_half_height();
    ASSERT_GT(half, 0.0);
    const double tol = half * 1e-5;
    double extent[3] = {0, 0, 0};
    for (const Sphere& sp : s.spheres()) {
      ASSERT_LE(std::fabs(sp.x), half + tol) << scene_kind_name(kind);
      ASSERT_LE(std::fabs(sp.y), half + tol) << scene_kind_name(kind);
      ASSERT_LE(std::fabs(sp.z), half + tol) << scene_kind_name(kind);
      ASSERT_LE(rho_of(sp), s.world_radius() * (1 + 1e-5));
      extent[0] = std::max(extent[0], static_cast<double>(std::fabs(sp.x)));
      extent[1] = std::max(extent[1], static_cast<double>(std::fabs(sp.y)));
      extent[2] = std::max(extent[2], static_cast<double>(std::fabs(sp.z)));
    }
    if (kind == SceneKind::box) {
      for (double e : extent) {
        EXPECT_GT(e, 0.98 * half);
      }
    }
    EXPECT_LE(s.world_radius(), std::sqrt(2.0) * half * (1 + 1e-5));
    // Moving about the y axis keeps them in the cylinder around the cube and in its slab.
    for (int f = 0; f < 30; ++f) s.step(0.1f);
    for (const Sphere& sp : s.spheres()) {
      ASSERT_LE(std::fabs(sp.y), half + tol);
      ASSERT_LE(rho_of(sp), s.world_radius() * (1 + 1e-4) + 1e-4);
    }
  }
}

TEST(Scene, ClustersAreDenserThanBox) {
  // Same N and world: clusters pack objects together, so far more of them collide.
  auto colliding_share = [](SceneKind kind) {
    const Scene s = Scene::make(params(kind, 10000, 2));
    auto det = make_cpu_detector();
    FrameResult frame;
    EXPECT_TRUE(det->detect(s.spheres(), nullptr, frame).ok());
    std::set<std::uint32_t> in_pair;
    for (const Pair& p : frame.pairs) in_pair.insert(p.i), in_pair.insert(p.j);
    return static_cast<double>(in_pair.size()) / 10000.0;
  };
  EXPECT_GT(colliding_share(SceneKind::clusters), colliding_share(SceneKind::box));
}

TEST(Scene, StepKeepsRhoAndYAndAdvancesAngles) {
  for (SceneKind kind : kKinds) {
    Scene s = Scene::make(params(kind, 5000, 12));
    const std::vector<Sphere> s0(s.spheres().begin(), s.spheres().end());
    const float dt = 0.01f;
    s.step(dt);
    const std::vector<Sphere> s1(s.spheres().begin(), s.spheres().end());
    s.step(dt);
    const std::vector<Sphere> s2(s.spheres().begin(), s.spheres().end());
    EXPECT_NEAR(s.time(), 2.0 * dt, 1e-9);
    std::size_t moved = 0;
    for (std::size_t k = 0; k < s0.size(); ++k) {
      SCOPED_TRACE(std::string(scene_kind_name(kind)) + " object " + std::to_string(k));
      const double rho = rho_of(s0[k]);
      const double tol = 1e-5 * std::max(1.0, rho);
      // Radius, height and distance from the axis stay.
      ASSERT_EQ(s1[k].r, s0[k].r);
      ASSERT_EQ(s2[k].r, s0[k].r);
      ASSERT_EQ(s1[k].y, s0[k].y);
      ASSERT_EQ(s2[k].y, s0[k].y);
      ASSERT_NEAR(rho_of(s1[k]), rho, tol);
      ASSERT_NEAR(rho_of(s2[k]), rho, tol);
      if (rho < 1e-3) continue;  // the angle of a point on the axis is meaningless
      // Each object turns at its own constant speed: equal steps, equal advances.
      const double d1 = angle_diff(angle_of(s0[k]), angle_of(s1[k]));
      const double d2 = angle_diff(angle_of(s1[k]), angle_of(s2[k]));
      const double angle_tol = 4e-6 * std::max(1.0, rho) / rho + 1e-6;
      ASSERT_NEAR(d1, d2, 2 * angle_tol) << "rho " << rho;
      // Objects move (in the direction of increasing atan2(z, x)) at a bounded speed.
      ASSERT_GT(d1, 0.0) << "rho " << rho;
      const double omega = d1 / dt;
      ASSERT_LT(omega * std::min(rho, 1.0), 1e3);
      moved += d1 > 0;
    }
    EXPECT_GT(moved, s0.size() / 2);
  }
}

TEST(Scene, AngularSpeedsDiffer) {
  // "each object at its own angular speed": not a rigid rotation.
  Scene s = Scene::make(params(SceneKind::ring, 1000, 3));
  const std::vector<Sphere> s0(s.spheres().begin(), s.spheres().end());
  s.step(0.05f);
  std::vector<double> omega;
  for (std::size_t k = 0; k < s0.size(); ++k)
    omega.push_back(angle_diff(angle_of(s0[k]), angle_of(s.spheres()[k])) / 0.05);
  const auto [lo, hi] = std::minmax_element(omega.begin(), omega.end());
  EXPECT_GT(*hi, 1.5 * *lo);
}

TEST(Scene, OneLongStepEqualsTwoShortOnes) {
  // theta advances by omega * dt: stepping 2 dt once lands where two steps of dt do.
  Scene a = Scene::make(params(SceneKind::ring, 2000, 21));
  Scene b = Scene::make(params(SceneKind::ring, 2000, 21));
  a.step(0.02f);
  a.step(0.02f);
  b.step(0.04f);
  for (std::size_t k = 0; k < 2000; ++k) {
    const Sphere& p = a.spheres()[k];
    const Sphere& q = b.spheres()[k];
    const double rho = rho_of(p);
    ASSERT_NEAR(p.x, q.x, 2e-5 * rho + 1e-5) << k;
    ASSERT_NEAR(p.z, q.z, 2e-5 * rho + 1e-5) << k;
    ASSERT_EQ(p.y, q.y);
  }
  EXPECT_NEAR(a.time(), b.time(), 1e-9);
}

TEST(Scene, LongRunsKeepTheOrbit) {
  // Many steps (theta wraps many times) keep every object on its circle.
  Scene s = Scene::make(params(SceneKind::box, 500, 4));
  const std::vector<Sphere> s0(s.spheres().begin(), s.spheres().end());
  for (int f = 0; f < 20000; ++f) s.step(1.0f / 60.0f);
  EXPECT_NEAR(s.time(), 20000.0 * static_cast<double>(1.0f / 60.0f), 1e-6);
  for (std::size_t k = 0; k < s0.size(); ++k) {
    const double rho = rho_of(s0[k]);
    ASSERT_NEAR(rho_of(s.spheres()[k]), rho, 1e-5 * std::max(1.0, rho)) << k;
    ASSERT_EQ(s.spheres()[k].y, s0[k].y);
  }
}

TEST(Scene, ZeroStepChangesNothing) {
  Scene s = Scene::make(params(SceneKind::ring, 1000, 1));
  const std::vector<Sphere> s0(s.spheres().begin(), s.spheres().end());
  s.step(0.0f);
  for (std::size_t k = 0; k < s0.size(); ++k) {
    ASSERT_NEAR(s.spheres()[k].x, s0[k].x, 1e-5 * std::max(1.0, rho_of(s0[k])));
    ASSERT_NEAR(s.spheres()[k].z, s0[k].z, 1e-5 * std::max(1.0, rho_of(s0[k])));
  }
}

TEST(SceneKindNames, ParseAndName) {
  for (SceneKind kind : kKinds) {
    auto r = parse_scene_kind(scene_kind_name(kind));
    ASSERT_TRUE(r.ok()) << r.error();
    EXPECT_EQ(r.value(), kind);
  }
  EXPECT_EQ(scene_kind_name(SceneKind::ring), "ring");
  EXPECT_EQ(scene_kind_name(SceneKind::box), "box");
  EXPECT_EQ(scene_kind_name(SceneKind::clusters), "clusters");
}

TEST(SceneKindNames, UnknownIsAnError) {
  for (const char* name : {"donut", "", "Ring", "ring "}) {
    auto r = parse_scene_kind(name);
    ASSERT_FALSE(r.ok()) << "'" << name << "'";
    EXPECT_NE(r.error().find(std::string("'") + name + "'"), std::string::npos) << r.error();
  }
  auto r = parse_scene_kind("donut");
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().find("donut"), std::string::npos) << r.error();
  EXPECT_NE(r.error().find("ring"), std::string::npos) << r.error();
}

TEST(CameraPreset, PresetsAreValidCameras) {
  for (SceneKind kind : kKinds) {
    for (std::uint32_t n : {0u, 1u, 100u, 10000u}) {
      for (const char* name : {"zoom-out", "zoom-in", "orbit"}) {
        Scene s = Scene::make(params(kind, n));
        for (int f = 0; f < 3; ++f) {
          auto c = camera_preset(name, s, 1280, 720);
          ASSERT_TRUE(c.ok()) << name << ": " << c.error();
          Status v = validate_camera(c.value());
          EXPECT_TRUE(v.ok()) << name << " " << scene_kind_name(kind) << " N " << n << ": " << v.error();
          EXPECT_EQ(c.value().width, 1280);
          EXPECT_EQ(c.value().height, 720);
          s.step(3.0f);
        }
      }
    }
  }
}

TEST(CameraPreset, ScreenSizeIsTaken) {
  const Scene s = Scene::make(params(SceneKind::ring, 100));
  auto c = camera_preset("zoom-in", s, 320, 180);
  ASSERT_TRUE(c.ok()) << c.error();
  EXPECT_EQ(c.value().width, 320);
  EXPECT_EQ(c.value().height, 180);
}

TEST(CameraPreset, OrbitMovesWithSceneTime) {
  Scene s = Scene::make(params(SceneKind::ring, 1000));
  auto a = camera_preset("orbit", s, 640, 360);
  s.step(5.0f);
  auto b = camera_preset("orbit", s, 640, 360);
  ASSERT_TRUE(a.ok() && b.ok());
  const bool same = a.value().eye[0] == b.value().eye[0] && a.value().eye[2] == b.value().eye[2];
  EXPECT_FALSE(same);
  // A quarter turn after 5 s of a 20 s orbit: the eye keeps its height and distance from the axis.
  EXPECT_FLOAT_EQ(a.value().eye[1], b.value().eye[1]);
  EXPECT_NEAR(std::hypot(a.value().eye[0], a.value().eye[2]), std::hypot(b.value().eye[0], b.value().eye[2]),
              1e-4 * std::hypot(a.value().eye[0], a.value().eye[2]));
}

TEST(CameraPreset, ZoomOutSeesTheWorldFromOutside) {
  const Scene s = Scene::make(params(SceneKind::ring, 10000));
  auto c = camera_preset("zoom-out", s, 1280, 720);
  ASSERT_TRUE(c.ok());
  const Camera& cam = c.value();
  // The far plane reaches across the whole world.
  const double eye_dist = std::hypot(cam.eye[0], cam.eye[1], cam.eye[2]);
  EXPECT_GT(cam.far_plane, eye_dist + s.world_radius());
}

TEST(CameraPreset, UnknownNameIsAnError) {
  const Scene s = Scene::make(params(SceneKind::ring, 10));
  auto c = camera_preset("nope", s, 1280, 720);
  ASSERT_FALSE(c.ok());
  EXPECT_NE(c.error().find("nope"), std::string::npos) << c.error();
  EXPECT_FALSE(camera_preset("", s, 1280, 720).ok());
  EXPECT_FALSE(camera_preset("Zoom-In", s, 1280, 720).ok());
}

TEST(RingScene, ARealShareCollides) {
  // The demo relies on this: at the default density a 10 000-object ring has many collisions.
  const Scene s = Scene::make(SceneParams{});
  ASSERT_EQ(s.spheres().size(), 10000u);
  auto det = make_cpu_detector();
  FrameResult frame;
  Status st = det->detect(s.spheres(), nullptr, frame);
  ASSERT_TRUE(st.ok()) << st.error();
  std::vector<bool> in_pair(10000, false);
  for (const Pair& p : frame.pairs) {
    ASSERT_LT(p.i, p.j);
    ASSERT_LT(p.j, 10000u);
    in_pair[p.i] = in_pair[p.j] = true;
  }
  const auto colliding = static_cast<std::size_t>(std::count(in_pair.begin(), in_pair.end(), true));
  RecordProperty("colliding_objects", static_cast<int>(colliding));
  EXPECT_GE(colliding, 500u) << "only " << colliding << " of 10000 objects collide";
  EXPECT_EQ(frame.stats.pairs, frame.pairs.size());
  EXPECT_EQ(frame.stats.objects, 10000u);
  EXPECT_EQ(frame.stats.active, 10000u);
  // And it stays so while the scene moves.
  Scene moving = Scene::make(SceneParams{});
  for (int f = 0; f < 60; ++f) moving.step(1.0f / 60.0f);
  ASSERT_TRUE(det->detect(moving.spheres(), nullptr, frame).ok());
  std::fill(in_pair.begin(), in_pair.end(), false);
  for (const Pair& p : frame.pairs) in_pair[p.i] = in_pair[p.j] = true;
  EXPECT_GE(std::count(in_pair.begin(), in_pair.end(), true), 500);
}

// ---------------------------------------------------------------------------------------------
// Shapes: the scene as cubes, and the static field.

TEST(ShapeKindNames, ParseAndName) {
  ASSERT_TRUE(parse_shape_kind("sphere").ok());
  EXPECT_EQ(parse_shape_kind("sphere").value(), ShapeKind::sphere);
  EXPECT_EQ(parse_shape_kind("box").value(), ShapeKind::box);
  EXPECT_EQ(shape_kind_name(ShapeKind::sphere), "sphere");
  EXPECT_EQ(shape_kind_name(ShapeKind::box), "box");
  for (const char* bad : {"", "cube", "Box", "spheres", "box "}) {
    auto k = parse_shape_kind(bad);
    ASSERT_FALSE(k.ok()) << bad;
    EXPECT_NE(k.error().find("expected sphere or box"), std::string::npos) << k.error();
  }
}

TEST(CubesOf, EachSphereBecomesItsCentrePlusMinusR) {
  const Box b = cube_of({1, -2, 3.5f, 0.5f});
  EXPECT_EQ(b.min[0], 0.5f);
  EXPECT_EQ(b.min[1], -2.5f);
  EXPECT_EQ(b.min[2], 3.0f);
  EXPECT_EQ(b.max[0], 1.5f);
  EXPECT_EQ(b.max[1], -1.5f);
  EXPECT_EQ(b.max[2], 4.0f);
  const Box point = cube_of({7, 8, 9, 0});
  EXPECT_EQ(point.min[0], 7.0f);
  EXPECT_EQ(point.max[2], 9.0f);

  const Scene s = Scene::make(params(SceneKind::clusters, 3000, 4));
  std::vector<Box> cubes(5);  // resized to the scene
  cubes_of(s.spheres(), cubes);
  ASSERT_EQ(cubes.size(), s.spheres().size());
  EXPECT_TRUE(validate_boxes(cubes).ok());
  for (std::size_t k = 0; k < cubes.size(); ++k) {
    const Sphere& sp = s.spheres()[k];
    EXPECT_EQ(cubes[k].min[1], sp.y - sp.r) << k;
    EXPECT_EQ(cubes[k].max[2], sp.z + sp.r) << k;
    // The cube holds its sphere: the sphere overlaps only boxes its cube overlaps.
    EXPECT_TRUE(sphere_overlaps_box(sp, cubes[k])) << k;
  }
  cubes_of({}, cubes);
  EXPECT_TRUE(cubes.empty());
}

TEST(StaticField, CountValidDeterministicAndAPrefix) {
  const Scene s = Scene::make(params(SceneKind::ring, 5000, 3));
  const std::vector<Sphere> field = static_field(s, 400);
  ASSERT_EQ(field.size(), 400u);
  EXPECT_TRUE(validate_spheres(field).ok());
  EXPECT_TRUE(bitwise_equal(field, static_field(s, 400)));
  for (std::uint32_t k : {0u, 1u, 7u, 123u, 399u}) {
    const std::vector<Sphere> fewer = static_field(s, k);
    ASSERT_EQ(fewer.size(), k);
    EXPECT_TRUE(bitwise_equal(fewer, std::span<const Sphere>(field).first(k))) << k;
  }
  // Another seed, another field; the moving objects are those of a scene without one.
  const Scene other = Scene::make(params(SceneKind::ring, 5000, 4));
  EXPECT_FALSE(bitwise_equal(field, static_field(other, 400)));
  EXPECT_TRUE(bitwise_equal(s.spheres(), Scene::make(params(SceneKind::ring, 5000, 3)).spheres()));
}

TEST(StaticField, RocksAndPillarsOnTheRingsGround) {
  const Scene s = Scene::make(params(SceneKind::ring, 10000, 1));
  const std::vector<Sphere> field = static_field(s, 2000);
  const float rm = s.params().mean_radius, ground = -s.world_half_height(), outer = s.world_radius();
  std::set<std::pair<float, float>> columns;  // (x, z) of each feature
  std::size_t stacked = 0;
  for (std::size_t k = 0; k < field.size(); ++k) {
    const Sphere& f = field[k];
    EXPECT_GE(f.r, rm) << k;
    EXPECT_LE(f.r, 3 * rm * 1.0001f) << k;
    EXPECT_GE(f.y, ground) << k;               // standing on the ground, not under it
    EXPECT_LE(f.y, ground + 14.3f * rm) << k;  // a pillar: 12 mean radii, and at most a step more
    const double rho = rho_of(f);
    EXPECT_GE(rho, 0.5 * outer * 0.999) << k;  // in the annulus the objects circle over
    EXPECT_LE(rho, outer * 1.001) << k;
    if (!columns.insert({f.x, f.z}).second) ++stacked;
  }
  // About a quarter of the features are pillars of several spheres each: many objects share a column.
  EXPECT_GT(stacked, field.size() / 4);
  EXPECT_GT(columns.size(), field.size() / 10);
  // Pillars rise through the slab the moving objects fill: some sphere reaches its top.
  EXPECT_TRUE(std::any_of(field.begin(), field.end(), [&](const Sphere& f) { return f.y >= -ground; }));
  // And the moving objects run into the field.
  auto det = make_cpu_detector();
  ASSERT_TRUE(det->set_static_spheres(field).ok());
  FrameResult frame;
  ASSERT_TRUE(det->detect(s.spheres(), nullptr, frame).ok());
  EXPECT_GT(std::count_if(frame.pairs.begin(), frame.pairs.end(), [](const Pair& p) { return is_static_index(p.j); }),
            50);
}

TEST(StaticField, ALargeFieldSpreadsOutInsteadOfCrowdingTheRing) {
  // Ten times the field: about as many static objects meet the moving ones (the field grows the
  // ground, not the crowd under the ring).
  const Scene s = Scene::make(params(SceneKind::ring, 5000, 1));
  auto static_pairs = [&](std::uint32_t count) {
    auto det = make_cpu_detector();
    const std::vector<Sphere> field = static_field(s, count);
    EXPECT_TRUE(det->set_static_spheres(field).ok());
    FrameResult frame;
    EXPECT_TRUE(det->detect(s.spheres(), nullptr, frame).ok());
    return std::count_if(frame.pairs.begin(), frame.pairs.end(), [](const Pair& p) { return is_static_index(p.j); });
  };
  const auto small = static_pairs(20000), large = static_pairs(200000);
  EXPECT_GT(small, 50);
  EXPECT_LT(large, 2 * small) << small << " static pairs with 20 000, " << large << " with 200 000";
}

TEST(StaticField, BoxAndClusterScenesUseTheSquareUnderTheirCube) {
  for (SceneKind kind : {SceneKind::box, SceneKind::clusters}) {
    const Scene s = Scene::make(params(kind, 2000, 2));
    const std::vector<Sphere> field = static_field(s, 300);
    ASSERT_EQ(field.size(), 300u);
    // The square under the cube, or the larger square 300 features of 64 rm^2 need.
    const float rm = s.params().mean_radius;
    const float half = std::max(s.world_half_height(), 0.5f * std::sqrt(300.0f * 64.0f) * rm);
    for (const Sphere& f : field) {
      EXPECT_LE(std::fabs(f.x), half * 1.0001f);
      EXPECT_LE(std::fabs(f.z), half * 1.0001f);
      EXPECT_GE(f.y, -s.world_half_height());
    }
    std::vector<Box> cubes;
    cubes_of(field, cubes);
    EXPECT_TRUE(validate_boxes(cubes).ok());
  }
  // No objects: a field still stands on a world of at least a mean radius.
  const Scene empty = Scene::make(params(SceneKind::ring, 0));
  const std::vector<Sphere> field = static_field(empty, 10);
  ASSERT_EQ(field.size(), 10u);
  EXPECT_TRUE(validate_spheres(field).ok());
}

}  // namespace
}  // namespace viscd
