// Stages 1-3 and 9 of the cpu backend against the reference backend (per-pixel ray casting over
// every sphere) and hand-worked cases.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <numeric>

#include "cpu/pipeline.hpp"
#include "test_util.hpp"
#include "viscd/io.hpp"

namespace viscd {
namespace {

using test::oracle_pairs;
using test::random_spheres_by_half_extent;
using test::same_pairs;

Camera camera_at(float ex, float ey, float ez, float tx, float ty, float tz, int w, int h) {
  Camera c;
  c.eye[0] = ex, c.eye[1] = ey, c.eye[2] = ez;
  c.target[0] = tx, c.target[1] = ty, c.target[2] = tz;
  c.width = w, c.height = h;
  c.near_plane = 0.1f;
  c.far_plane = 500;
  return c;
}

const detail::VisibilityMap& map_of(Detector& d) {
  return detail::backend_as<detail::PipelineDetector>(d).visibility_map();
}

// Runs cpu and reference on the same frame and checks ids, counts, active set and pairs.
void check_against_reference(const std::vector<Sphere>& s, const Camera& cam, Config c, const std::string& what) {
  auto cpu = make_cpu_detector(c), ref = make_reference_detector(c);
  const FrameResult fc = test::run_frame(*cpu, s, &cam), fr = test::run_frame(*ref, s, &cam);
  ASSERT_EQ(map_of(*cpu).ids, map_of(*ref).ids) << what << ": id maps differ";
  ASSERT_EQ(map_of(*cpu).depth, map_of(*ref).depth) << what << ": depth maps differ";
  ASSERT_EQ(fc.pixels, fr.pixels) << what;
  EXPECT_EQ(fc.stats.active, fr.stats.active) << what;
  EXPECT_DOUBLE_EQ(fc.stats.mean_pixels, fr.stats.mean_pixels) << what;
  EXPECT_EQ(fc.stats.bits, fr.stats.bits) << what;
  EXPECT_EQ(fc.stats.layout, fr.stats.layout) << what;
  // Pairs: brute force over the active set, computed here from the reference's pixel counts.
  std::vector<std::uint32_t> active;
  for (std::uint32_t k = 0; k < s.size(); ++k)
    if (!c.culling || fr.pixels[k] >= c.lambda) active.push_back(k);
  const auto want = oracle_pairs(s, &active);
  EXPECT_TRUE(same_pairs(fc.pairs, want)) << what;
  EXPECT_TRUE(same_pairs(fr.pairs, want)) << what;
  for (std::uint32_t k = 0; k < s.size(); ++k) {
    const bool is_active = std::binary_search(active.begin(), active.end(), k);
    if (!is_active)
      ASSERT_EQ(fc.state[k], ObjectState::culled) << what << " object " << k;
    else
      ASSERT_NE(fc.state[k], ObjectState::culled) << what << " object " << k;
  }
}

TEST(Visibility, CpuEqualsReferenceOnRandomScenesAndCameras) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(-1, 1);
  for (int trial = 0; trial < 12; ++trial) {
    const auto s = random_spheres_by_half_extent(40 + 30 * trial, 100 + trial, 10.0f, 0.2f, 2.5f);
    const int w = 97 + 13 * trial, h = 53 + 7 * trial;  // odd sizes: tiles cut at the edges
    const Camera cam = camera_at(30 * u(rng), 30 * u(rng), 30 * u(rng), 3 * u(rng), 3 * u(rng), 3 * u(rng), w, h);
    Config c;
    c.lambda = 20;
    check_against_reference(s, cam, c, "trial " + std::to_string(trial));
    c.culling = false;
    check_against_reference(s, cam, c, "trial " + std::to_string(trial) + " unculled");
  }
}

TEST(Visibility, SubPixelSpheresThroughANarrowFieldOfView) {
  // Found by fuzzing: hit() cancels badly for rays near the centre of a sphere much smaller than
  // its distance, and accepted pixels the rectangle of the cpu rasterizer did not cover (a point
  // at fov 0.5 degrees: reference 7 pixels, cpu 5).
  Camera c = camera_at(1000.5f, 1003.0f, 1003.0f, 1000.5f, 1000.5f, 1000.5f, 9, 1);
  c.fov_y_deg = 0.5f;
  c.near_plane = 0.025f;
  c.far_plane = 250.0f;
  Config cfg;
  cfg.culling = false;
  cfg.map_width = cfg.map_height = 63;
  check_against_reference({{std::nextafter(1000.5f, 0.0f), 998.5f, 998.5f, 0.0f}}, c, cfg, "point, fov 0.5");
  // Many tiny and point spheres around the view axis, at a few narrow fields of view.
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(-1, 1), r(0, 1e-3f);
  std::vector<Sphere> s;
  for (int k = 0; k < 300; ++k) s.push_back({0.02f * u(rng), 0.02f * u(rng), 0.02f * u(rng), k % 3 ? r(rng) : 0.0f});
  for (float fov : {0.2f, 0.5f, 2.0f}) {
    Camera n = camera_at(0, 0, 3, 0, 0, 0, 101, 77);
    n.fov_y_deg = fov;
    n.near_plane = 0.01f;
    check_against_reference(s, n, cfg, "tiny spheres, fov " + std::to_string(fov));
  }
}

TEST(Visibility, ScaledMapsAndDegenerateSizes) {
  const auto s = random_spheres_by_half_extent(300, 8, 10.0f, 0.3f, 2.0f);
  const Camera cam = camera_at(0, 5, 35, 0, 0, 0, 1280, 720);
  Config c;
  c.map_width = 64, c.map_height = 36;  // 400 screen pixels per map pixel
  check_against_reference(s, cam, c, "64x36 map");
  auto cpu = make_cpu_detector(c);
  const FrameResult f = test::run_frame(*cpu, s, &cam);
  double total = 0;
  for (float p : f.pixels) {
    EXPECT_EQ(std::fmod(p, 400.0f), 0.0f);
    total += p;
  }
  EXPECT_LE(total, 1280.0 * 720.0);
  c.map_width = c.map_height = 1;  // 1x1 map: one object gets the whole screen
  check_against_reference(s, cam, c, "1x1 map");
  const FrameResult one = test::run_frame(*make_cpu_detector(c), s, &cam);
  const double sum = std::accumulate(one.pixels.begin(), one.pixels.end(), 0.0);
  EXPECT_TRUE(sum == 0.0 || sum == 1280.0 * 720.0);
  // More objects than pixels.
  c.map_width = 8, c.map_height = 6;
  check_against_reference(random_spheres_by_half_extent(2000, 4, 10.0f, 0.05f, 0.5f), cam, c, "8x6 map, 2000 objects");
}

TEST(Visibility, CameraInsideASphereSeesItsInside) {
  // The camera at the centre of a big sphere: every pixel sees its far side (one object).
  const std::vector<Sphere> s = {{0, 0, 0, 50}, {0, 0, -10, 1}};
  const Camera cam = camera_at(0, 0, 0, 0, 0, -1, 20, 10);
  Config c;
  c.culling = false;
  check_against_reference(s, cam, c, "inside");
  const FrameResult f = test::run_frame(*make_cpu_detector(c), s, &cam);
  // The small sphere at z = -10 is in front of the far wall (t = 50) where the view meets it.
  EXPECT_GT(f.pixels[1], 0.0f);
  EXPECT_EQ(f.pixels[0] + f.pixels[1], 200.0f);
}

TEST(Visibility, BehindTheCameraAndBeyondFarAreInvisible) {
  const std::vector<Sphere> s = {{0, 0, 20, 1},    // behind the eye (looking down -z)
                                 {0, 0, -600, 5},  // beyond far = 500
                                 {0, 0, -20, 1}};  // visible
  const Camera cam = camera_at(0, 0, 0, 0, 0, -1, 64, 48);
  Config c;
  c.lambda = 1;
  check_against_reference(s, cam, c, "behind/far");
  const FrameResult f = test::run_frame(*make_cpu_detector(c), s, &cam);
  EXPECT_EQ(f.pixels[0], 0.0f);
  EXPECT_EQ(f.pixels[1], 0.0f);
  EXPECT_GT(f.pixels[2], 0.0f);
  EXPECT_EQ(f.state[0], ObjectState::culled);
  EXPECT_EQ(f.state[2], ObjectState::free);
}

TEST(Visibility, MeanPixelsAndBitsAtTheThresholds) {
  // One sphere around the camera covers all 20 x 10 = 200 pixels; a second is hidden: mu = 100.
  const std::vector<Sphere> s = {{0, 0, 0, 50}, {0, 0, -100, 1}};
  const Camera cam = camera_at(0, 0, 0, 0, 0, -1, 20, 10);
  auto bits_for = [&](float a, float b) {
    Config c;
    c.pixels_for_32_bits = a, c.pixels_for_64_bits = b;
    const FrameResult f = test::run_frame(*make_cpu_detector(c), s, &cam);
    EXPECT_DOUBLE_EQ(f.stats.mean_pixels, 100.0);
    return f.stats.bits;
  };
  EXPECT_EQ(bits_for(100, 400), 32);      // mu == a
  EXPECT_EQ(bits_for(100.01f, 400), 16);  // mu just below a
  EXPECT_EQ(bits_for(50, 100), 64);       // mu == b
  EXPECT_EQ(bits_for(50, 100.01f), 32);   // mu just below b
  Config fixed;
  fixed.bits = Bits::b64;
  EXPECT_EQ(test::run_frame(*make_cpu_detector(fixed), s, &cam).stats.bits, 64);
}

TEST(Visibility, AllCulledAndNoneCulled) {
  const auto s = random_spheres_by_half_extent(500, 21, 5.0f, 0.5f, 1.5f);
  const Camera cam = camera_at(0, 0, 30, 0, 0, 0, 160, 90);
  Config c;
  c.lambda = 1e9f;
  const FrameResult all = test::run_frame(*make_cpu_detector(c), s, &cam);
  EXPECT_EQ(all.stats.active, 0u);
  EXPECT_TRUE(all.pairs.empty());
  for (ObjectState st : all.state) EXPECT_EQ(st, ObjectState::culled);
  c.lambda = 0;  // pixels >= 0 always: nobody is culled, hidden objects included
  const FrameResult none = test::run_frame(*make_cpu_detector(c), s, &cam);
  EXPECT_EQ(none.stats.active, 500u);
  EXPECT_TRUE(same_pairs(none.pairs, oracle_pairs(s)));
}

// One detector, the same objects: frames with a camera that culls some of them, without a camera
// (every object active: the list of all of them is kept between such frames), and with a static
// object appended; each frame's active objects and pairs are checked, so that a list left over
// from another kind of frame shows.
TEST(Visibility, ActiveListsAcrossFramesWithAndWithoutCamera) {
  const auto s = random_spheres_by_half_extent(700, 22, 6.0f, 0.3f, 1.0f);
  const Camera cam = camera_at(0, 0, 30, 0, 0, 0, 160, 90);
  Config c;
  c.lambda = 6;
  c.follow_change = false;  // every frame runs the broadphase on the list
  auto d = make_cpu_detector(c);
  for (int f = 0; f < 7; ++f) {
    SCOPED_TRACE("frame " + std::to_string(f));
    if (f == 5) {
      ASSERT_TRUE(d->add_static_sphere(Sphere{0, 0, 0, 2}).ok());
    }
    const bool culls = f % 3 == 1;
    const FrameResult r = test::run_frame(*d, s, culls ? &cam : nullptr);
    std::vector<std::uint32_t> active;
    for (std::uint32_t k = 0; k < s.size(); ++k)
      if (r.state[k] != ObjectState::culled) active.push_back(k);
    EXPECT_EQ(r.stats.active, active.size());
    if (culls) {
      EXPECT_LT(active.size(), s.size());
      EXPECT_GT(active.size(), 20u);
    } else {
      EXPECT_EQ(active.size(), s.size());
    }
    std::vector<Pair> moving;
    for (const Pair& p : r.pairs)
      if (p.j < s.size()) moving.push_back(p);
    EXPECT_TRUE(same_pairs(moving, oracle_pairs(s, &active)));
  }
}

// Culling off, adaptive bits, 2^17 + 1 objects on a 640x360 screen (fewer pixels than a = 100
// per object): m is 32 whatever a map would show, so none is rendered; the pairs are a 32-bit
// frame's. With 2^17 objects 16 bits stay possible and the map is rendered.
TEST(Visibility, NoMapWhereItCannotChangeTheBits) {
  const std::size_t many = (std::size_t{1} << 17) + 1;
  const auto s = random_spheres_by_half_extent(many, 5, 60.0f, 0.05f, 0.2f);
  const Camera cam = camera_at(0, 0, 150, 0, 0, 0, 640, 360);
  Config c;
  c.culling = false;
  auto d = make_cpu_detector(c);
  const FrameResult f = test::run_frame(*d, s, &cam);
  EXPECT_FALSE(f.stats.has_pixels);
  EXPECT_TRUE(f.pixels.empty());
  EXPECT_EQ(f.stats.bits, 32);
  EXPECT_EQ(f.stats.ms(Stage::visibility), 0.0);
  EXPECT_EQ(f.stats.active, many);
  Config fixed = c;
  fixed.bits = Bits::b32;
  const FrameResult g = test::run_frame(*make_cpu_detector(fixed), s, nullptr);
  EXPECT_TRUE(same_pairs(f.pairs, g.pairs));
  const std::span<const Sphere> fewer = std::span<const Sphere>(s).first(many - 1);
  const FrameResult h = test::run_frame(*d, std::vector<Sphere>(fewer.begin(), fewer.end()), &cam);
  EXPECT_TRUE(h.stats.has_pixels);
  EXPECT_EQ(h.pixels.size(), many - 1);
  EXPECT_EQ(h.stats.bits, 16);
}

TEST(Visibility, InvalidCameraAndMapAreErrors) {
  const auto s = random_spheres_by_half_extent(10, 1);
  Camera cam = camera_at(0, 0, 10, 0, 0, 10, 64, 48);  // eye == target
  FrameResult f;
  EXPECT_FALSE(make_cpu_detector()->detect(s, &cam, f).ok());
  cam = camera_at(0, 0, 10, 0, 0, 0, 64, 48);
  cam.near_plane = 0;
  EXPECT_FALSE(make_cpu_detector()->detect(s, &cam, f).ok());
  cam.near_plane = 0.1f;
  Config c;
  c.map_width = 10;  // height missing
  const Status st = make_cpu_detector(c)->detect(s, &cam, f);
  ASSERT_FALSE(st.ok());
  EXPECT_NE(st.error().find("map"), std::string::npos);
}

// Hue class of a shaded pixel.
char hue(const std::uint8_t* p) {
  const int r = p[0], g = p[1], b = p[2];
  if (r < 40 && g < 40 && b < 40) return '.';
  if (r > 2 * g && r > 2 * b) return 'R';
  if (b > r && b > g) return 'B';
  if (r > b + 40 && g > b + 40) return 'Y';
  return '?';
}

TEST(Shading, PaperColoursWhereTheSceneSaysSo) {
  // Left: two overlapping spheres (red). Right: one free sphere (blue). Far back: one tiny
  // sphere below lambda (yellow). The camera looks down -z from z = 20.
  const std::vector<Sphere> s = {{-6, 0, 0, 2}, {-3.5f, 0, 0, 1.5f}, {6, 0, 0, 2.5f}, {0, 4, -150, 1.5f}};
  const Camera cam = camera_at(0, 0, 20, 0, 0, 0, 320, 180);
  Config c;
  c.lambda = 60;
  c.shade = true;
  auto det = make_cpu_detector(c);
  const FrameResult f = test::run_frame(*det, s, &cam);
  ASSERT_EQ(f.image_width, 320);
  ASSERT_EQ(f.image.size(), 320u * 180 * 4);
  EXPECT_EQ(f.state[0], ObjectState::colliding);
  EXPECT_EQ(f.state[2], ObjectState::free);
  EXPECT_EQ(f.state[3], ObjectState::culled);
  // Project each centre to a pixel and read its colour class.
  const detail::CameraRig rig(cam, 320, 180);
  auto pixel_of = [&](const Sphere& sp) {
    const float dx = sp.x - rig.eye.x, dy = sp.y - rig.eye.y, dz = sp.z - rig.eye.z;
    const float z = dx * rig.forward.x + dy * rig.forward.y + dz * rig.forward.z;
    const float x = (dx * rig.right.x + dy * rig.right.y + dz * rig.right.z) / z / rig.tan_half_x;
    const float y = (dx * rig.up.x + dy * rig.up.y + dz * rig.up.z) / z / rig.tan_half_y;
    const int px = static_cast<int>((x + 1) * 0.5f * 320), py = static_cast<int>((1 - y) * 0.5f * 180);
    return &f.image[4 * (static_cast<std::size_t>(py) * 320 + px)];
  };
  EXPECT_EQ(hue(pixel_of(s[0])), 'R');
  EXPECT_EQ(hue(pixel_of(s[2])), 'B');
  EXPECT_EQ(hue(pixel_of(s[3])), 'Y');
  EXPECT_EQ(hue(&f.image[0]), '.');  // background corner
  // And the PNG writer produces a PNG.
  const std::string path = ::testing::TempDir() + "/viscd_shade.png";
  ASSERT_TRUE(write_png(path, f.image, f.image_width, f.image_height).ok());
  std::ifstream in(path, std::ios::binary);
  char magic[8] = {};
  in.read(magic, 8);
  EXPECT_EQ(std::string(magic + 1, 3), "PNG");
}

}  // namespace
}  // namespace viscd

namespace viscd {
namespace {

TEST(Memory, TallyCoversTheMapAndGrowsWithN) {
  const Camera cam = camera_at(0, 5, 40, 0, 0, 0, 320, 180);
  auto det = make_cpu_detector();
  EXPECT_EQ(det->memory_bytes(), 0u);
  test::run_frame(*det, random_spheres_by_half_extent(1000, 1), &cam);
  const std::uint64_t small = det->memory_bytes();
  EXPECT_GE(small, 320u * 180 * (4 + 4));  // id + depth map at least
  test::run_frame(*det, random_spheres_by_half_extent(50000, 2, 30.0f), &cam);
  EXPECT_GT(det->memory_bytes(), small + 50000u * (sizeof(Sphere) + 4));  // sorted spheres + ids
}

}  // namespace
}  // namespace viscd
