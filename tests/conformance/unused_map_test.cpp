// Conformance: a frame renders and counts a visibility map of its own only when something uses
// it (culling, adaptive bits, shading, Config::report_pixels). Without any of them a frame with a
// camera is the paper's baseline: every object active, no pixels; with any of them the pixels
// are the same as ever.
#include <vector>

#include "conformance/conformance.hpp"

namespace viscd::conformance {
namespace {

TEST_P(ConformanceFrames, NoMapWhenNothingUsesIt) {
  const CameraScene scene = camera_scene(200, 21);
  const std::vector<Sphere>& s = scene.spheres;
  const Camera& cam = scene.camera;
  const std::vector<Pair> all = test::oracle_pairs(s);

  // The reference pixels: culling on, the map rendered and counted.
  Config on;
  on.lambda = scene.lambda;
  detector_->set_config(on);
  FrameResult counted;
  ASSERT_TRUE(detector_->detect(s, &cam, counted).ok());
  ASSERT_TRUE(counted.stats.has_pixels);
  ASSERT_EQ(counted.pixels.size(), s.size());

  // Culling off, fixed bits, no shading: no map.
  Config baseline;
  baseline.culling = false;
  baseline.bits = Bits::b64;
  detector_->set_config(baseline);
  FrameResult got;
  Status st = detector_->detect(s, &cam, got);
  ASSERT_TRUE(st.ok()) << st.error();
  EXPECT_TRUE(got.stats.has_camera);
  EXPECT_FALSE(got.stats.has_pixels) << backend() << ": pixels counted though nothing uses them";
  EXPECT_TRUE(got.pixels.empty());
  EXPECT_EQ(got.stats.mean_pixels, 0.0);
  EXPECT_EQ(got.stats.active, s.size());
  EXPECT_EQ(got.stats.bits, 64);
  EXPECT_TRUE(test::same_pairs(got.pairs, all));
  for (ObjectState x : got.state) EXPECT_NE(x, ObjectState::culled);
  detector_->wait_for_stage_times(got.stats);
  EXPECT_EQ(got.stats.ms(Stage::visibility), 0.0) << backend() << ": a map was rendered";

  // Each user of the map brings it back, with the same pixels as before.
  struct Use {
    const char* what;
    Config config;
  };
  std::vector<Use> uses;
  Config pixels = baseline;
  pixels.report_pixels = true;
  uses.push_back({"report_pixels", pixels});
  Config adaptive = baseline;
  adaptive.bits = Bits::adaptive;
  uses.push_back({"adaptive bits", adaptive});
  Config shaded = baseline;
  shaded.shade = true;
  uses.push_back({"shading", shaded});
  for (const Use& u : uses) {
    detector_->set_config(u.config);
    st = detector_->detect(s, &cam, got);
    ASSERT_TRUE(st.ok()) << u.what << ": " << st.error();
    EXPECT_TRUE(got.stats.has_pixels) << u.what;
    EXPECT_EQ(got.pixels, counted.pixels) << backend() << ": " << u.what;
    EXPECT_EQ(got.stats.active, s.size()) << u.what;
    EXPECT_TRUE(test::same_pairs(got.pairs, all)) << u.what;
  }
  EXPECT_FALSE(got.image.empty()) << "the shaded frame has its image";

  // The caller's id map is counted whatever the settings (the count checks its ids).
  const std::vector<std::uint32_t> map = {1, 1, 2, 0};
  FrameInput in;
  in.spheres = std::span<const Sphere>(s).first(3);
  in.id_map = map;
  in.id_map_width = 2;
  in.id_map_height = 2;
  detector_->set_config(baseline);
  st = detector_->detect(in, got);
  ASSERT_TRUE(st.ok()) << st.error();
  EXPECT_TRUE(got.stats.has_pixels);
  EXPECT_EQ(got.pixels, (std::vector<float>{2, 1, 0}));
}

}  // namespace
}  // namespace viscd::conformance
