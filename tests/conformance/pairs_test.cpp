// Conformance, pair cases: every backend, every Morton width (adaptive, 16, 32, 64) and layout
// (extended, plain), against brute force over the active set and the reference backend.
// Degenerate inputs: none to two spheres, identical centres, touching spheres, huge and tiny
// radii, collinear centres, large coordinates up to kMaxCoordinate, float-boundary touches,
// counts around work-group sizes, pair-buffer overflow, culling with a camera, and frames in a
// row on one detector with the scene changing.
#include <cmath>
#include <random>

#include "conformance/conformance.hpp"

namespace viscd::conformance {
namespace {

TEST_P(ConformancePairs, NoneOneTwo) {
  check({}, "N = 0");
  check(std::vector<Sphere>{{1, 2, 3, 1}}, "N = 1");
  check(std::vector<Sphere>{{0, 0, 0, 0}}, "N = 1, a point");
  check(std::vector<Sphere>{{0, 0, 0, 1}, {3, 0, 0, 1}}, "N = 2 apart");
  check(std::vector<Sphere>{{0, 0, 0, 1}, {2, 0, 0, 1}}, "N = 2 touching exactly (2 <= 1 + 1)");
  check(std::vector<Sphere>{{0, 0, 0, 1}, {std::nextafter(2.0f, 3.0f), 0, 0, 1}}, "N = 2 one ulp apart");
  check(std::vector<Sphere>{{0, 0, 0, 1}, {1.5f, 0, 0, 1}}, "N = 2 overlapping");
  check(std::vector<Sphere>{{5, -2, 1, 1}, {5, -2, 1, 1}}, "N = 2 identical");
  check(std::vector<Sphere>{{0, 0, 0, 0}, {0, 0, 0, 0}}, "N = 2 points at one place (0 <= 0)");
  check(std::vector<Sphere>{{0, 0, 0, 3}, {0.5f, 0.5f, 0, 0.1f}}, "N = 2 one inside the other");
  check(std::vector<Sphere>{{1, 1, 1, -0.0f}, {1, 1, 1, 0}}, "N = 2 points, r = -0 and 0");
}

TEST_P(ConformancePairs, AllCentresIdentical) {
  std::vector<Sphere> s(500, Sphere{3.25f, -1.5f, 7.0f, 0.5f});
  check(s, "500 identical spheres: 124750 pairs");
  EXPECT_EQ(frame_.pairs.size(), 124750u);
  s.assign(100, Sphere{0, 0, 0, 0});
  check(s, "100 points at one place");
  EXPECT_EQ(frame_.pairs.size(), 100u * 99 / 2);
}

TEST_P(ConformancePairs, TouchingOnAGrid) {
  // Radius 0.5 at integer spacing: axis neighbours touch exactly (1 <= 0.5 + 0.5), diagonals miss.
  std::vector<Sphere> s;
  for (int x = 0; x < 10; ++x)
    for (int y = 0; y < 10; ++y)
      for (int z = 0; z < 10; ++z) s.push_back({float(x), float(y), float(z), 0.5f});
  check(s, "touching grid, r = 0.5");
  EXPECT_EQ(frame_.pairs.size(), 3u * 10 * 10 * 9);
  // Radii 0.25 and 0.75 alternating along x: x neighbours touch exactly; odd columns overlap more.
  for (Sphere& sp : s) sp.r = (static_cast<int>(sp.x) % 2) ? 0.75f : 0.25f;
  check(s, "touching grid, r = 0.25 / 0.75");
  // Non-dyadic spacing away from the origin: whether a touch counts is up to float rounding,
  // and every backend must round as the oracle does.
  for (Sphere& sp : s) sp = {37.0f + sp.x * 0.1f, -11.0f + sp.y * 0.1f, 5.0f + sp.z * 0.1f, 0.05f};
  check(s, "touching grid, spacing 0.1");
}

TEST_P(ConformancePairs, TouchingAtTheFloatBoundary) {
  // Pairs whose float test sits exactly at equality or one ulp to either side, near 1e5.
  check(test::float_boundary_pairs(300, 11), "float boundary");
}

TEST_P(ConformancePairs, HugeAndTinyRadii) {
  std::vector<Sphere> s = random_cloud(800, 5, 100.0f, 1e-4f, 1e-2f);
  s[17] = {0, 0, 0, 40};                       // swallows a part of the cloud
  s[123] = {50, 50, 50, 30};                   // overlaps the first
  s[400] = {-1e4f, 0, 0, 1e4f};                // reaches the origin: half the world
  s[401] = {5e5f, 5e5f, 5e5f, 1e3f};           // far from everything
  s[402] = {0, 0, 0, 0};                       // a point inside two huge spheres
  s[799] = {1e-3f, 0, 0, 1e-30f};              // a tiny sphere near the point
  for (int k = 600; k < 640; ++k) s[k].r = 0;  // points
  check(s, "huge among tiny");
  // Subnormal distances and radii: squares underflow.
  s.clear();
  for (int k = 0; k < 400; ++k) {
    const float base = 1e-20f * float(k % 50);
    s.push_back({base, base * 0.5f, 0, 1e-21f * float(k % 7)});
  }
  check(s, "subnormal distances");
}

TEST_P(ConformancePairs, SpheresOnALine) {
  std::vector<Sphere> s;
  for (int k = 0; k < 1500; ++k) s.push_back({0.3f * float(k) - 200.0f, 0, 0, 0.2f + 0.001f * float(k % 7)});
  check(s, "on the x axis");
  for (Sphere& sp : s) sp = {0, 0, sp.x, sp.r};
  check(s, "on the z axis");
  for (int k = 0; k < 1500; ++k) {
    const float t = 0.1f * float(k);
    s[static_cast<std::size_t>(k)] = {t, -t, 2.0f * t, 0.12f + 0.01f * float(k % 5)};
  }
  check(s, "on a diagonal");
  s.assign(1000, Sphere{});
  for (int k = 0; k < 1000; ++k) s[static_cast<std::size_t>(k)] = {0, 0, 0.5f * float(k / 10), 0.25f};  // stacked
  check(s, "ten per point on a line");
}

TEST_P(ConformancePairs, CoordinatesAround1e5) {
  auto s = random_cloud(1500, 9, 30.0f, 0.5f, 2.0f);
  for (Sphere& sp : s) sp.x += 1e5f, sp.y -= 1e5f, sp.z += 1e5f;
  check(s, "around (1e5, -1e5, 1e5)");
}

TEST_P(ConformancePairs, CoordinatesAround1e18) {
  const float m = kMaxCoordinate;
  // Random centres over the whole valid range, radii up to 4e17.
  check(random_cloud(400, 18, m, 1e16f, 4e17f), "random in [-1e18, 1e18]^3");
  // The corners of the range with r = 1e18: edge neighbours touch exactly (2e18 <= 1e18 + 1e18).
  std::vector<Sphere> s;
  for (float x : {-m, m})
    for (float y : {-m, m})
      for (float z : {-m, m}) s.push_back({x, y, z, m});
  check(s, "corners, r = 1e18");
  EXPECT_EQ(frame_.pairs.size(), 12u);
  // A small cluster at the corner: spacing of a few ulps (an ulp of 1e18 is 2^36).
  std::mt19937 rng(3);
  std::uniform_int_distribution<int> ulps(0, 40);
  s.clear();
  for (int k = 0; k < 300; ++k) {
    auto near_max = [&] {
      float v = m;
      for (int u = ulps(rng); u > 0; --u) v = std::nextafter(v, 0.0f);
      return v;
    };
    s.push_back({near_max(), -near_max(), near_max(), 0x1p36f * static_cast<float>(ulps(rng) % 8)});
  }
  s.push_back({0, 0, 0, m});  // the origin with r = 1e18: reaches every face centre
  s.push_back({m, 0, 0, 0});
  check(s, "cluster at the corner, r of a few ulps");
}

TEST_P(ConformancePairs, CountsAroundWorkGroupSizes) {
  // One detector, N changing every frame: buffers grow and are reused.
  for (std::size_t n : {63u, 64u, 65u, 127u, 128u, 129u, 255u, 256u, 257u, 1023u, 1024u, 1025u, 2047u, 2048u, 2049u})
    check(random_cloud(n, n, 2.5f * std::cbrt(static_cast<float>(n))), "random");
}

TEST_P(ConformancePairs, PairBufferOverflow) {
  // Far more pairs than objects: more than the gl backend's initial pair capacity, so its first
  // query overflows, grows the buffer and runs again. A fresh detector: nothing has grown yet.
  const std::vector<Sphere> s = random_cloud(1000, 42, 5.0f, 1.2f, 2.6f);
  const std::vector<Pair> want = test::oracle_pairs(s);
  ASSERT_GT(want.size(), GlOptions{}.initial_pair_capacity);
  check(s, "dense cluster");
  check(random_cloud(1000, 43, 60.0f), "sparse after dense");
}

TEST_P(ConformancePairs, CullingWithACamera) {
  const CameraScene scene = camera_scene(300, 5);
  const std::vector<Sphere>& s = scene.spheres;
  const Camera& cam = scene.camera;
  Config c = config();
  c.lambda = scene.lambda;
  FrameResult probe;
  ASSERT_TRUE(make_reference_detector(c)->detect(s, &cam, probe).ok());
  // The scene must have all three: objects kept, objects culled though visible, objects unseen.
  std::size_t kept = 0, culled_visible = 0, culled_unseen = 0;
  for (float px : probe.pixels) {
    if (px >= c.lambda)
      ++kept;
    else if (px > 0)
      ++culled_visible;
    else
      ++culled_unseen;
  }
  ASSERT_GE(kept, 20u);
  ASSERT_GE(culled_visible, 20u);
  ASSERT_GE(culled_unseen, 20u);

  detector_->set_config(c);
  check(s, "culling on", &cam);
  ASSERT_GT(frame_.pairs.size(), 0u);
  EXPECT_LT(frame_.pairs.size(), test::oracle_pairs(s).size());  // culling removed pairs
  c.culling = false;
  detector_->set_config(c);
  check(s, "culling off, with a camera", &cam);
  check(s, "no camera", nullptr);
  c.culling = true;
  detector_->set_config(c);
  check(s, "culling on again", &cam);

  // Adaptive width from mu, with thresholds far from it: each of 16, 32 and 64.
  if (c.bits == Bits::adaptive) {
    const auto mu = static_cast<float>(probe.stats.mean_pixels);
    ASSERT_GT(mu, 0.0f);
    const struct {
      float a, b;
      int bits;
    } widths[] = {{4 * mu, 8 * mu, 16}, {mu / 4, 4 * mu, 32}, {mu / 8, mu / 4, 64}};
    for (const auto& w : widths) {
      c.pixels_for_32_bits = w.a;
      c.pixels_for_64_bits = w.b;
      detector_->set_config(c);
      check(s, "adaptive width " + std::to_string(w.bits), &cam);
      EXPECT_EQ(frame_.stats.bits, w.bits);
    }
  }
}

TEST_P(ConformancePairs, FramesInARow) {
  // One detector and one FrameResult over a changing scene: N grows and shrinks, spheres move a
  // little or teleport, the camera comes and goes, the pair count jumps past the pair buffer.
  auto culled_frame = [&](const std::vector<Sphere>& s, const Camera& cam, float lambda, const std::string& what) {
    Config c = config();
    c.lambda = lambda;
    detector_->set_config(c);
    check(s, what, &cam);
    detector_->set_config(config());
  };
  std::vector<Sphere> s;
  check(s, "empty");
  s = {{0, 0, 0, 1}};
  check(s, "one");
  s = random_cloud(300, 1, 12.0f);
  check(s, "300 random");
  for (Sphere& sp : s) sp.x += 0.05f * sp.r;
  check(s, "300 moved a little");
  for (std::size_t k = 0; k < s.size(); k += 10) s[k] = {1e4f + float(k), -3e4f, 7e3f, 2.0f};  // teleport out
  for (std::size_t k = 5; k < s.size(); k += 10) s[k] = s[k - 5];                              // onto each other
  check(s, "300, a fifth teleported");
  s.resize(50);
  for (std::size_t k = 0; k < s.size(); ++k) s[k] = {float(k), 0, 0, 0.6f};
  check(s, "50 in a chain: 49 pairs");  // few objects and pairs, then more of both
  s = random_cloud(2000, 2, 25.0f);
  check(s, "grown to 2000");
  for (Sphere& sp : s) sp.x *= 0.5f, sp.y *= 0.5f, sp.z *= 0.5f;
  check(s, "2000 squeezed together");
  s.resize(50);
  check(s, "shrunk to 50");
  CameraScene scene = camera_scene(300, 7, 35.0f);
  ASSERT_NO_FATAL_FAILURE(culled_frame(scene.spheres, scene.camera, scene.lambda, "300 seen by a camera, culling"));
  for (Sphere& sp : scene.spheres) sp.y += 0.3f;
  clear_lambda_band(scene.spheres, scene.camera, scene.lambda);
  ASSERT_NO_FATAL_FAILURE(culled_frame(scene.spheres, scene.camera, scene.lambda, "300 moved, culling"));
  check(scene.spheres, "300 without the camera");
  ASSERT_NO_FATAL_FAILURE(culled_frame({}, scene.camera, scene.lambda, "empty with a camera"));
  s.assign(370, Sphere{1, 2, 3, 0.5f});
  check(s, "370 identical: 68265 pairs, past the gl backend's initial pair buffer");
  s = random_cloud(400, 3, 30.0f);
  check(s, "400 sparse");
  s = random_cloud(400, 4, 30.0f);
  for (Sphere& sp : s) sp.x -= 1e4f;
  check(s, "400 teleported together");
}

}  // namespace
}  // namespace viscd::conformance
