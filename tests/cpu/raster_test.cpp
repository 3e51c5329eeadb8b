// The cpu backend's tiled rasterizer against the reference ray caster (rasterize_reference: every
// pixel against every sphere with hit()), bit for bit: ids, depths, and the pixel counts it fuses
// into the tile pass against a histogram of the reference's id map. The cases aim at each path of
// the rasterizer: the tight rectangles and row spans of single spheres (random cameras, fields of
// view, sizes from sub-pixel to screen-filling), tile and map borders, many spheres in a tile,
// exact depth ties, camera inside or beside a sphere, odd and tiny maps, N = 0, 1, 2. Each case
// runs every tile kernel the CPU has (SSE2, AVX-512).
#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <random>
#include <sstream>

#include "cpu/raster.hpp"
#include "cpu/simd.hpp"
#include "cpu/visibility.hpp"
#include "test_util.hpp"
#include "viscd/scene.hpp"

namespace viscd {
namespace {

using detail::CameraRig;
using detail::TiledRasterizer;
using detail::VisibilityMap;

Camera camera_at(float ex, float ey, float ez, float tx, float ty, float tz, int w, int h, float fov = 60) {
  Camera c;
  c.eye[0] = ex, c.eye[1] = ey, c.eye[2] = ez;
  c.target[0] = tx, c.target[1] = ty, c.target[2] = tz;
  c.width = w, c.height = h;
  c.fov_y_deg = fov;
  c.near_plane = 0.1f;
  c.far_plane = 500;
  return c;
}

// The reference map and a histogram of its ids, computed here (not by count_pixels).
struct Oracle {
  VisibilityMap map;
  std::vector<std::uint32_t> counts;
};
Oracle reference(const CameraRig& rig, std::span<const Sphere> s) {
  Oracle o;
  o.map.resize(rig.map_w, rig.map_h, false);
  detail::rasterize_reference(rig, s, o.map);
  o.counts.assign(s.size(), 0);
  for (std::uint32_t id : o.map.ids)
    if (id) ++o.counts[id - 1];
  return o;
}

// Runs the tiled rasterizer with `threads` and compares with the oracle; the message names the
// first differing pixel.
::testing::AssertionResult matches_at_level(const Oracle& want, const CameraRig& rig, std::span<const Sphere> s,
                                            detail::SimdLevel level, int threads = 2) {
  VisibilityMap got;
  got.resize(rig.map_w, rig.map_h, false);
  std::fill(got.ids.begin(), got.ids.end(), 0xDEADu);  // stale content must be overwritten
  std::fill(got.depth.begin(), got.depth.end(), -7.0f);
  TiledRasterizer r;
  r.set_simd(level);
  r.run(rig, s, threads, got);
  for (std::size_t i = 0; i < got.ids.size(); ++i) {
    if (got.ids[i] != want.map.ids[i] ||
        std::bit_cast<std::uint32_t>(got.depth[i]) != std::bit_cast<std::uint32_t>(want.map.depth[i])) {
      std::ostringstream m;
      m.precision(9);
      m << "pixel (" << i % static_cast<std::size_t>(rig.map_w) << ", " << i / static_cast<std::size_t>(rig.map_w)
        << ") of " << rig.map_w << "x" << rig.map_h << ": id " << got.ids[i] << " depth " << got.depth[i]
        << ", reference id " << want.map.ids[i] << " depth " << want.map.depth[i];
      return ::testing::AssertionFailure() << m.str();
    }
  }
  if (!got.has_counts) return ::testing::AssertionFailure() << "no counts";
  if (got.counts != want.counts) {
    for (std::size_t k = 0; k < s.size(); ++k)
      if (got.counts[k] != want.counts[k])
        return ::testing::AssertionFailure()
               << "object " << k << ": " << got.counts[k] << " pixels, reference " << want.counts[k];
    return ::testing::AssertionFailure() << "count vector sizes differ";
  }
  return ::testing::AssertionSuccess();
}

// The same for each instruction set this CPU can run the rasterizer with (SSE2, and AVX-512 where
// it has it: the bounds and the tile kernel).
::testing::AssertionResult matches(const Oracle& want, const CameraRig& rig, std::span<const Sphere> s,
                                   int threads = 2) {
  ::testing::AssertionResult result = ::testing::AssertionSuccess();
  for (detail::SimdLevel level : {detail::SimdLevel::sse2, detail::SimdLevel::avx512}) {
    if (level > detail::best_simd_level()) continue;
    result = matches_at_level(want, rig, s, level, threads);
    if (!result) {
      result << " (" << detail::simd_name(level) << " kernels)";
      break;
    }
  }
  return result;
}

::testing::AssertionResult matches_reference(const Camera& cam, int w, int h, std::span<const Sphere> s,
                                             int threads = 2) {
  const CameraRig rig(cam, w, h);
  return matches(reference(rig, s), rig, s, threads);
}

TEST(Raster, SingleSpheresOfEverySizeAtRandomCameras) {
  // One sphere per frame, so a pixel the rasterizer's rectangle or span left out shows as a
  // difference (with several spheres a nearer one could hide it). Sizes from points to spheres
  // around the eye, fields of view from 0.5 to 170 degrees, maps of odd sizes.
  std::mt19937 rng(20240611);
  std::uniform_real_distribution<float> u(-1, 1), u01(0, 1);
  const float fovs[] = {0.5f, 3.0f, 30.0f, 60.0f, 90.0f, 140.0f, 170.0f};
  int hits = 0;
  for (int trial = 0; trial < 20000; ++trial) {
    const int w = 1 + static_cast<int>(u01(rng) * 90), h = 1 + static_cast<int>(u01(rng) * 70);
    const float fov = fovs[trial % 7];
    Camera cam = camera_at(50 * u(rng), 50 * u(rng), 50 * u(rng), 50 * u(rng), 50 * u(rng), 50 * u(rng), w, h, fov);
    cam.near_plane = std::pow(10.0f, -3 + 2 * u01(rng));
    cam.far_plane = cam.near_plane * std::pow(10.0f, 1 + 4 * u01(rng));
    const CameraRig rig(cam, w, h);
    // A direction inside (or a little outside) the view, a distance, a radius relative to it;
    // one in ten behind the eye, one in ten beside it (close to the eye's plane).
    const float sx = 1.3f * u(rng) * rig.tan_half_x, sy = 1.3f * u(rng) * rig.tan_half_y;
    const float fz = trial % 10 == 3 ? -1.0f : trial % 10 == 7 ? 0.05f * u(rng) : 1.0f;
    const float dist = cam.near_plane * std::pow(10.0f, -1 + 5 * u01(rng));
    const float rel = trial % 10 == 0 ? 0.0f : std::pow(10.0f, -7 + 8 * u01(rng));
    Sphere s{cam.eye[0] + dist * (fz * rig.forward.x + sx * rig.right.x + sy * rig.up.x),
             cam.eye[1] + dist * (fz * rig.forward.y + sx * rig.right.y + sy * rig.up.y),
             cam.eye[2] + dist * (fz * rig.forward.z + sx * rig.right.z + sy * rig.up.z), rel * dist};
    const std::vector<Sphere> one{s};
    const Oracle want = reference(rig, one);
    hits += want.counts[0] > 0;
    ASSERT_TRUE(matches(want, rig, one)) << "trial " << trial << ", fov " << fov << ", r/d " << rel;
  }
  EXPECT_GT(hits, 3000);  // most cases see something (the rest: clipped by near or far)
}

TEST(Raster, SubPixelSpheresNearTheAxisOfANarrowView) {
  // hit()'s float discriminant accepts rays farther from a tiny sphere's centre than its radius
  // (docs/architecture.md, "Visibility map"); the rectangle and spans must hold those pixels too.
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-1, 1), r(0, 1e-3f);
  for (float fov : {0.05f, 0.2f, 0.5f, 2.0f}) {
    for (int k = 0; k < 200; ++k) {
      const Camera cam = camera_at(1000.5f, 1003.0f, 1003.0f + u(rng), 1000.5f, 1000.5f, 1000.5f, 37, 29, fov);
      const std::vector<Sphere> one{
          {1000.5f + 0.01f * u(rng), 1000.5f + 0.01f * u(rng), 1000.5f + 0.01f * u(rng), k % 3 ? r(rng) : 0.0f}};
      ASSERT_TRUE(matches_reference(cam, 37, 29, one)) << "fov " << fov << " sphere " << k;
    }
  }
}

TEST(Raster, TileAndMapBorders) {
  // Spheres centred on tile corners and edges (tiles are 32 pixels) and past the map's edges, on
  // maps that are and are not multiples of the tile size.
  for (auto [w, h] : {std::pair{64, 64}, {96, 33}, {33, 97}, {31, 31}, {65, 1}, {1, 65}}) {
    const Camera cam = camera_at(0, 0, 20, 0, 0, 0, w, h, 50);
    const CameraRig rig(cam, w, h);
    std::vector<Sphere> s;
    for (int py = -32; py <= h + 32; py += 16)
      for (int px = -32; px <= w + 32; px += 16) {
        // Unproject the pixel corner (px, py) at depth 20.
        const float nx = (2.0f * static_cast<float>(px) / static_cast<float>(w) - 1.0f) * rig.tan_half_x;
        const float ny = (1.0f - 2.0f * static_cast<float>(py) / static_cast<float>(h)) * rig.tan_half_y;
        s.push_back({20 * nx, 20 * ny, 0, 0.02f + 0.3f * static_cast<float>((px + py + 64) % 48) / 48});
      }
    ASSERT_TRUE(matches_reference(cam, w, h, s)) << w << "x" << h;
    ASSERT_TRUE(matches_reference(cam, w, h, s, 1)) << w << "x" << h << ", one thread";
  }
}

TEST(Raster, ScreenFillingCameraInsideAndBesideSpheres) {
  const Camera cam = camera_at(0, 0, 0, 0, 0, -1, 77, 45, 90);
  // Covers the whole view; holds the eye (its far side is seen); cut by the near plane; beside
  // the eye (its projection is unbounded); behind the eye; and small ones in front of the walls.
  const std::vector<Sphere> s = {{0, 0, -30, 25}, {0, 0, 0, 60},        {0.5f, 0, -0.05f, 0.2f},
                                 {2, 0, 0, 1.5f}, {0, 0, 5, 1},         {0, -2, -3, 1},
                                 {1, 1, -10, 2},  {-3, 0.5f, -4, 0.7f}, {0, 0, -0.15f, 0.1f}};
  ASSERT_TRUE(matches_reference(cam, 77, 45, s));
  for (std::size_t k = 0; k < s.size(); ++k) {
    const std::vector<Sphere> one{s[k]};
    ASSERT_TRUE(matches_reference(cam, 77, 45, one)) << "sphere " << k;
  }
  // The eye exactly on a sphere's surface.
  const std::vector<Sphere> on{{0, 0, -2, 2}};
  ASSERT_TRUE(matches_reference(cam, 77, 45, on));
}

TEST(Raster, ManySpheresInOneTileAndExactTies) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(-1, 1), r(0.01f, 0.3f);
  const Camera cam = camera_at(0, 0, 10, 0, 0, 0, 40, 40, 20);
  std::vector<Sphere> s;
  for (int k = 0; k < 3000; ++k) s.push_back({0.6f * u(rng), 0.6f * u(rng), 2 * u(rng), r(rng)});
  // Exact copies at other indices tie at every pixel they share: the smaller id must win.
  for (int k = 0; k < 300; ++k) s.push_back(s[static_cast<std::size_t>(k * 7)]);
  s.insert(s.begin(), s[1234]);
  ASSERT_TRUE(matches_reference(cam, 40, 40, s));
  ASSERT_TRUE(matches_reference(cam, 40, 40, s, 1));
  // Different spheres reaching the same depth at some pixel: concentric, equal near point.
  const std::vector<Sphere> tie = {{0, 0, -1, 1}, {0, 0, -1.5f, 1.5f}, {0, 0, -2, 2}, {0, 0, -1, 1}};
  ASSERT_TRUE(matches_reference(cam, 40, 40, tie));
  // On a 41x41 map the centre pixel's ray is the axis (0, 0, -1), and both spheres below are hit
  // on it at t = 10 exactly (every term is exact in float: for the second, |o|^2 - r^2 = 180,
  // disc = 196 - 180 = 16). The second one's near point is nearer, so it comes first in depth
  // order and the first must take the pixel from it by the smaller id, in the kernel.
  const std::vector<Sphere> cross = {{0, 0, -1, 1}, {3, 0, -4, 5}};
  const CameraRig centre(cam, 41, 41);
  const Oracle want = reference(centre, cross);
  ASSERT_EQ(want.map.ids[20 * 41 + 20], 1u);
  ASSERT_EQ(want.map.depth[20 * 41 + 20], 10.0f);
  ASSERT_TRUE(matches(want, centre, cross));
}

TEST(Raster, DepthsOverManyOctaves) {
  // Spheres from just past the near plane to far away, all in front of each other on a small
  // map: the depth keys span more values than the sort has buckets (its order is then coarser)
  // and tiles stop early once every pixel has a hit nearer than the rest.
  std::mt19937 rng(13);
  std::uniform_real_distribution<float> u(-1, 1), e(0, 1);
  Camera cam = camera_at(0, 0, 0, 0, 0, -1, 48, 40, 30);
  cam.near_plane = 0.01f;
  cam.far_plane = 1e7f;
  for (int trial = 0; trial < 4; ++trial) {
    std::vector<Sphere> s;
    for (int k = 0; k < 2000; ++k) {
      const float d = 0.02f * std::pow(10.0f, 8 * e(rng));  // 0.02 .. 2e6
      s.push_back({0.3f * d * u(rng), 0.3f * d * u(rng), -d, d * (0.02f + 0.3f * e(rng))});
    }
    if (trial == 3) s.push_back({0, 0, -5, 1e3f});  // one hiding everything behind it
    ASSERT_TRUE(matches_reference(cam, 48, 40, s)) << "trial " << trial;
    ASSERT_TRUE(matches_reference(cam, 48, 40, s, 1)) << "trial " << trial << ", one thread";
  }
  // Depths from 0.05 to 9e5 make the sort's buckets hold 4 keys each. A wall at depth 4 fills a
  // one-tile map; behind it a sphere A (depth key 0x4081: near depth 4.03..4.06), then spheres B
  // in front of it (key 0x407F: 3.97..4.0), in the same bucket in some trials (where buckets
  // start moves with the nearest sphere's depth). When the tile comes to A every pixel has a hit
  // nearer than 4.0011, but B's are nearer still: the tile may stop only at a bound that holds
  // for B too (the bucket's, not A's own key's; a test of that bound fails here).
  Camera one = cam;
  one.width = one.height = 32;
  for (int trial = 0; trial < 8; ++trial) {
    const float near_key = 0.05f * std::exp2(static_cast<float>(trial) / 128);  // a key further each trial
    std::vector<Sphere> s = {{0, 0, -near_key - 0.001f, 0.0005f}, {0, 0, -1e6f, 1e5f}, {0, 0, -1004, 1000}};
    // Nearer than A, enough of them that the tile has taken stock of its depths before A.
    for (int k = 0; k < 24; ++k)
      s.push_back({-0.6f + 0.05f * static_cast<float>(k), 0.6f, k < 8 ? -3.0f : -3.8f, 0.01f});
    s.push_back({0, 0, -4.3f, 0.25f});  // A: hidden behind the wall
    for (int k = 0; k < 9; ++k)         // B: caps in front of the wall, apart from each other
      s.push_back({-0.6f + 0.6f * static_cast<float>(k % 3), -0.6f + 0.6f * static_cast<float>(k / 3), -4.19f, 0.2f});
    ASSERT_TRUE(matches_reference(one, 32, 32, s)) << "wall, trial " << trial;
  }
}

TEST(Raster, TinyMapsAndFewObjects) {
  const Camera cam = camera_at(0, 3, 12, 0, 0, 0, 1280, 720);
  const auto many = test::random_spheres_by_half_extent(400, 17, 6.0f, 0.2f, 1.5f);
  for (auto [w, h] : {std::pair{1, 1}, {1, 2}, {2, 1}, {3, 3}, {32, 32}, {33, 1}}) {
    for (std::size_t n : {0u, 1u, 2u, 400u}) {
      const std::span<const Sphere> s(many.data(), n);
      ASSERT_TRUE(matches_reference(cam, w, h, s)) << w << "x" << h << ", " << n << " objects";
    }
  }
}

TEST(Raster, DemoSceneOnASmallMapAndThreadCounts) {
  // The demo's ring scene and zoom-out camera, many small spheres front to back, on a map small
  // enough for the reference; the result must not depend on the number of threads.
  Scene scene = Scene::make({.objects = 3000});
  for (int k = 0; k < 10; ++k) scene.step(1.0f / 60.0f);
  const Camera cam = camera_preset("zoom-out", scene, 1280, 720).value();
  for (auto [w, h] : {std::pair{160, 90}, {203, 117}}) {
    const CameraRig rig(cam, w, h);
    const Oracle want = reference(rig, scene.spheres());
    for (int threads : {1, 2, 3}) ASSERT_TRUE(matches(want, rig, scene.spheres(), threads)) << threads << " threads";
  }
}

TEST(Raster, ManySpheresSortedAndBinnedInChunks) {
  // Enough spheres that the depth sort and the binning both run in several chunks (the sort
  // stays on one below 2^16), on a map small enough for the reference.
  Scene scene = Scene::make({.objects = 70000});
  scene.step(1.0f / 60.0f);
  const Camera cam = camera_preset("zoom-out", scene, 1280, 720).value();
  const CameraRig rig(cam, 64, 36);
  const Oracle want = reference(rig, scene.spheres());
  for (int threads : {1, 2, 3}) ASSERT_TRUE(matches(want, rig, scene.spheres(), threads)) << threads << " threads";
}

TEST(Raster, CountsFollowTheMapAcrossFramesAndResizes) {
  // One rasterizer reused over frames of different sizes and sphere counts (buffers are reused).
  TiledRasterizer r;
  std::mt19937 rng(9);
  std::uniform_int_distribution<int> side(1, 150);
  for (int frame = 0; frame < 20; ++frame) {
    const int w = side(rng), h = side(rng);
    const auto s =
        test::random_spheres_by_half_extent(static_cast<std::size_t>(50 * frame), 100 + frame, 8.0f, 0.05f, 2.0f);
    const Camera cam = camera_at(0, 4, 18, 0, 0, 0, w, h);
    const CameraRig rig(cam, w, h);
    const Oracle want = reference(rig, s);
    VisibilityMap got;
    got.resize(w, h, false);
    r.run(rig, s, 2, got);
    ASSERT_EQ(got.ids, want.map.ids) << "frame " << frame;
    ASSERT_EQ(got.counts, want.counts) << "frame " << frame;
  }
  // resize() drops the counts, so count_pixels cannot use counts of another map.
  VisibilityMap m;
  m.resize(4, 4, false);
  m.counts = {16};
  m.has_counts = true;
  m.resize(4, 4, false);
  EXPECT_FALSE(m.has_counts);
}

TEST(Raster, BackgroundTilesAreKeptOnlyWhileTheyStillHoldIt) {
  // One map and rasterizer over frames: background tiles of the last frame are not rewritten, so
  // every way the map's content or the background can change must make them be written again.
  const Camera base = camera_at(0, 0, 30, 0, 0, 0, 150, 100, 40);
  TiledRasterizer r, other;
  VisibilityMap map;
  map.resize(150, 100, false);
  auto frame = [&](TiledRasterizer& rr, const Camera& cam, std::span<const Sphere> s, const char* what) {
    const CameraRig rig(cam, map.width, map.height);
    const Oracle want = reference(rig, s);
    rr.run(rig, s, 2, map);
    ASSERT_EQ(map.ids, want.map.ids) << what;
    for (std::size_t i = 0; i < map.depth.size(); ++i)
      ASSERT_EQ(std::bit_cast<std::uint32_t>(map.depth[i]), std::bit_cast<std::uint32_t>(want.map.depth[i]))
          << what << ", pixel " << i;
    ASSERT_EQ(map.counts, want.counts) << what;
  };
  // A cluster that moves across the view, leaving tiles empty behind it and covering new ones.
  for (int step = 0; step < 8; ++step) {
    std::vector<Sphere> s;
    for (int k = 0; k < 30; ++k)
      s.push_back({-12.0f + 3.0f * static_cast<float>(step) + 0.3f * static_cast<float>(k % 6),
                   -2.0f + 0.7f * static_cast<float>(k / 6), 0, 0.8f});
    ASSERT_NO_FATAL_FAILURE(frame(r, base, s, "moving cluster"));
  }
  const std::vector<Sphere> few = {{-8, 3, 0, 1}, {6, -4, 0, 2}};
  ASSERT_NO_FATAL_FAILURE(frame(r, base, few, "few"));
  ASSERT_NO_FATAL_FAILURE(frame(r, base, {}, "none"));
  // Another far plane changes the background depth everywhere.
  Camera far = base;
  far.far_plane = 250;
  ASSERT_NO_FATAL_FAILURE(frame(r, far, few, "other far plane"));
  ASSERT_NO_FATAL_FAILURE(frame(r, base, few, "far plane back"));
  // Another writer in between: the reference, another rasterizer, a caller who sets stamp 0.
  const std::vector<Sphere> big = {{0, 0, 0, 9}};
  {
    const CameraRig rig(base, map.width, map.height);
    detail::rasterize_reference(rig, big, map);
  }
  ASSERT_NO_FATAL_FAILURE(frame(r, base, few, "after the reference wrote the map"));
  ASSERT_NO_FATAL_FAILURE(frame(other, base, big, "another rasterizer"));
  ASSERT_NO_FATAL_FAILURE(frame(r, base, few, "after another rasterizer"));
  std::fill(map.ids.begin(), map.ids.end(), 77u);
  map.stamp = 0;
  ASSERT_NO_FATAL_FAILURE(frame(r, base, few, "after a caller's write"));
  // Resized (content undefined) and back.
  map.resize(64, 64, false);
  ASSERT_NO_FATAL_FAILURE(frame(r, base, few, "resized"));
  map.resize(150, 100, false);
  ASSERT_NO_FATAL_FAILURE(frame(r, base, few, "resized back"));
}

}  // namespace
}  // namespace viscd
