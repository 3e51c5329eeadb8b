// Conformance, failure cases: every backend must refuse (with a non-empty error, never a partial
// or truncated result) a frame whose pairs exceed Config::pair_memory_cap, and invalid input
// (NaN, infinities, a negative radius, a magnitude beyond kMaxCoordinate, an invalid camera or
// map size). After a refused frame the same detector must go on to produce exact frames.
#include <cmath>
#include <limits>

#include "conformance/conformance.hpp"

namespace viscd::conformance {
namespace {

// A valid frame on `d` after a refused one: exact, as if nothing had happened.
void expect_recovers(Detector& d, const std::string& what) {
  SCOPED_TRACE("valid frame after: " + what);
  const std::vector<Sphere> s = random_cloud(200, 8, 6.0f);
  FrameResult f;
  const Status st = d.detect(s, nullptr, f);
  ASSERT_TRUE(st.ok()) << st.error();
  check_frame(f, s, nullptr, d.config(), expect_frame(s, nullptr, d.config(), false));
}

TEST_P(ConformanceFrames, PairMemoryCapIsAnError) {
  FrameResult f;
  const std::vector<Sphere> dense(100, Sphere{0, 0, 0, 1});  // 4950 pairs = 39600 bytes
  Config c;
  c.pair_memory_cap = 4950 * sizeof(Pair);
  detector_->set_config(c);
  Status st = detector_->detect(dense, nullptr, f);
  ASSERT_TRUE(st.ok()) << "a cap the pairs fit exactly: " << st.error();
  EXPECT_TRUE(test::same_pairs(f.pairs, test::oracle_pairs(dense)));

  c.pair_memory_cap = 4950 * sizeof(Pair) - 1;
  detector_->set_config(c);
  st = detector_->detect(dense, nullptr, f);
  ASSERT_FALSE(st.ok()) << "4950 pairs over a cap of one byte less";
  EXPECT_FALSE(st.error().empty());
  EXPECT_EQ(st.kind(), ErrorKind::pair_cap) << error_kind_name(st.kind());

  // Far over the cap (and over the gl backend's initial pair buffer).
  const std::vector<Sphere> denser(500, Sphere{1, 2, 3, 1});  // 124750 pairs
  c.pair_memory_cap = 1000 * sizeof(Pair);
  detector_->set_config(c);
  st = detector_->detect(denser, nullptr, f);
  ASSERT_FALSE(st.ok()) << "124750 pairs over a cap of 1000";
  EXPECT_FALSE(st.error().empty());
  EXPECT_EQ(st.kind(), ErrorKind::pair_cap) << error_kind_name(st.kind());

  // With a camera: culling off, so the count is the whole scene's.
  const CameraScene scene = camera_scene(300, 5);
  const std::vector<Sphere>& cloud = scene.spheres;
  const Camera& cam = scene.camera;
  const std::vector<Pair> all = test::oracle_pairs(cloud);
  const std::size_t pairs = all.size();
  ASSERT_GT(pairs, 1u);
  c.culling = false;
  c.pair_memory_cap = (pairs - 1) * sizeof(Pair);
  detector_->set_config(c);
  st = detector_->detect(cloud, &cam, f);
  ASSERT_FALSE(st.ok()) << pairs << " pairs with a camera over a cap of one pair less";
  EXPECT_FALSE(st.error().empty());
  EXPECT_EQ(st.kind(), ErrorKind::pair_cap) << error_kind_name(st.kind());
  c.pair_memory_cap = pairs * sizeof(Pair);
  detector_->set_config(c);
  st = detector_->detect(cloud, &cam, f);
  ASSERT_TRUE(st.ok()) << st.error();
  EXPECT_TRUE(test::same_pairs(f.pairs, all)) << "a cap the pairs fit exactly, with a camera";

  detector_->set_config(Config{});
  expect_recovers(*detector_, "pair memory cap");
}

TEST_P(ConformanceFrames, InvalidSpheresAreErrors) {
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  const float beyond = std::nextafter(kMaxCoordinate, inf);
  const std::pair<Sphere, const char*> bad[] = {
      {{nan, 0, 0, 1}, "x = NaN"},
      {{0, nan, 0, 1}, "y = NaN"},
      {{0, 0, nan, 1}, "z = NaN"},
      {{0, 0, 0, nan}, "r = NaN"},
      {{inf, 0, 0, 1}, "x = +Inf"},
      {{0, -inf, 0, 1}, "y = -Inf"},
      {{0, 0, inf, 1}, "z = +Inf"},
      {{0, 0, 0, inf}, "r = +Inf"},
      {{0, 0, 0, -1}, "r = -1"},
      {{0, 0, 0, -std::numeric_limits<float>::denorm_min()}, "r = -denorm_min"},
      {{beyond, 0, 0, 1}, "x one ulp beyond 1e18"},
      {{0, -beyond, 0, 1}, "y one ulp below -1e18"},
      {{0, 0, -2e18f, 1}, "z = -2e18"},
      {{0, 0, 0, beyond}, "r one ulp beyond 1e18"},
      {{3e38f, 0, 0, 1}, "x = 3e38"},
  };
  const Camera cam = scene_camera();
  FrameResult f;
  for (const auto& [sphere, what] : bad) {
    for (std::size_t n : {1u, 10u}) {
      for (std::size_t at : {std::size_t{0}, n / 2, n - 1}) {
        for (const Camera* camera : {static_cast<const Camera*>(nullptr), &cam}) {
          std::vector<Sphere> s = random_cloud(n, 1, 5.0f);
          s[at] = sphere;
          const Status st = detector_->detect(s, camera, f);
          EXPECT_FALSE(st.ok()) << backend() << " accepted " << what << " at " << at << " of " << n
                                << (camera ? " with a camera" : "");
          EXPECT_FALSE(st.error().empty()) << what;
          EXPECT_EQ(st.kind(), ErrorKind::invalid_input) << what << ": " << error_kind_name(st.kind());
        }
      }
    }
    expect_recovers(*detector_, what);
  }
}

TEST_P(ConformanceFrames, InvalidCameraIsAnError) {
  const std::vector<Sphere> s = random_cloud(20, 2, 5.0f);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  std::vector<std::pair<Camera, const char*>> bad;
  auto add = [&](const char* what, auto change) {
    Camera c = scene_camera();
    change(c);
    bad.emplace_back(c, what);
  };
  add("fov 0", [](Camera& c) { c.fov_y_deg = 0; });
  add("fov 180", [](Camera& c) { c.fov_y_deg = 180; });
  add("width 0", [](Camera& c) { c.width = 0; });
  add("height -1", [](Camera& c) { c.height = -1; });
  add("near 0", [](Camera& c) { c.near_plane = 0; });
  add("near = far", [](Camera& c) { c.far_plane = c.near_plane; });
  add("eye = target", [](Camera& c) { c.target[0] = c.eye[0], c.target[1] = c.eye[1], c.target[2] = c.eye[2]; });
  add("up parallel to the view", [](Camera& c) {
    c.up[0] = c.target[0] - c.eye[0], c.up[1] = c.target[1] - c.eye[1], c.up[2] = c.target[2] - c.eye[2];
  });
  add("eye NaN", [nan](Camera& c) { c.eye[1] = nan; });
  FrameResult f;
  for (const auto& [camera, what] : bad) {
    const Status st = detector_->detect(s, &camera, f);
    EXPECT_FALSE(st.ok()) << backend() << " accepted a camera with " << what;
    EXPECT_FALSE(st.error().empty()) << what;
    EXPECT_EQ(st.kind(), ErrorKind::invalid_input) << what << ": " << error_kind_name(st.kind());
  }
  // A map of W x 0 pixels.
  Config c;
  c.map_width = 64;
  c.map_height = 0;
  detector_->set_config(c);
  const Camera cam = scene_camera();
  const Status st = detector_->detect(s, &cam, f);
  EXPECT_FALSE(st.ok()) << backend() << " accepted a 64 x 0 visibility map";
  EXPECT_FALSE(st.error().empty());
  detector_->set_config(Config{});
  expect_recovers(*detector_, "invalid cameras");
}

}  // namespace
}  // namespace viscd::conformance
