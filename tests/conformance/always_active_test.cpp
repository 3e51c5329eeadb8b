// Conformance, never-culled objects (FrameInput::always_active): an object flagged non-zero is
// active whatever its pixels, with the detector's own map and with the caller's; its pixels are
// counted as before; flags change nothing without culling; queries see flagged objects; a flag
// array of the wrong size is an invalid-input error.
#include <algorithm>
#include <vector>

#include "conformance/conformance.hpp"

namespace viscd::conformance {
namespace {

// Every third object flagged, whatever the camera makes of it.
std::vector<std::uint8_t> every_third(std::size_t n) {
  std::vector<std::uint8_t> f(n, 0);
  for (std::size_t k = 0; k < n; k += 3) f[k] = 1;
  return f;
}

TEST_P(ConformanceFrames, AlwaysActiveObjectsAreNeverCulled) {
  const CameraScene scene = camera_scene(240, 11);
  const std::vector<Sphere>& s = scene.spheres;
  const Camera& cam = scene.camera;
  Config c;
  c.lambda = scene.lambda;
  detector_->set_config(c);

  // Without flags: the objects below lambda (off screen, behind the eye, hidden, small) are culled.
  FrameResult plain;
  ASSERT_TRUE(detector_->detect(s, &cam, plain).ok());
  const Expected culled = expect_frame(s, &cam, c, true);
  check_frame(plain, s, &cam, c, culled);
  ASSERT_LT(culled.active.size(), s.size()) << "the scene must cull something";

  // With flags: the active set is the culled frame's plus every flagged object.
  const std::vector<std::uint8_t> flags = every_third(s.size());
  std::vector<std::uint32_t> active;
  for (std::uint32_t k = 0; k < s.size(); ++k)
    if (flags[k] || std::binary_search(culled.active.begin(), culled.active.end(), k)) active.push_back(k);
  ASSERT_GT(active.size(), culled.active.size()) << "some flagged objects must be below lambda";
  const std::vector<Pair> want = test::oracle_pairs(s, &active);
  FrameInput in;
  in.spheres = s;
  in.camera = &cam;
  in.always_active = flags;
  FrameResult got;
  const Status st = detector_->detect(in, got);
  ASSERT_TRUE(st.ok()) << st.error();
  EXPECT_TRUE(test::same_pairs(got.pairs, want)) << backend() << ": pairs with flagged objects";
  EXPECT_EQ(got.stats.active, active.size());
  ASSERT_EQ(got.state.size(), s.size());
  for (std::uint32_t k = 0; k < s.size(); ++k) {
    const bool is_active = std::binary_search(active.begin(), active.end(), k);
    EXPECT_EQ(got.state[k] != ObjectState::culled, is_active) << "object " << k;
  }
  // Pixels and mu are counted as without flags: the flag decides activity only.
  EXPECT_EQ(got.pixels, plain.pixels);
  EXPECT_EQ(got.stats.mean_pixels, plain.stats.mean_pixels);
  EXPECT_EQ(got.stats.bits, plain.stats.bits);

  // Queries see a flagged object that the camera would cull.
  const auto hidden = std::find_if(active.begin(), active.end(), [&](std::uint32_t k) {
    return !std::binary_search(culled.active.begin(), culled.active.end(), k) && s[k].r > 0;
  });
  ASSERT_NE(hidden, active.end());
  std::vector<std::uint32_t> hits;
  detector_->overlap(Sphere{s[*hidden].x, s[*hidden].y, s[*hidden].z, 0.0f}, hits);
  EXPECT_TRUE(std::find(hits.begin(), hits.end(), *hidden) != hits.end())
      << backend() << ": overlap misses never-culled object " << *hidden;

  // All flags set: nothing is culled.
  const std::vector<std::uint8_t> all(s.size(), 1);
  in.always_active = all;
  ASSERT_TRUE(detector_->detect(in, got).ok());
  EXPECT_EQ(got.stats.active, s.size());
  EXPECT_TRUE(test::same_pairs(got.pairs, test::oracle_pairs(s)));

  // Culling off: the flags change nothing.
  c.culling = false;
  detector_->set_config(c);
  in.always_active = flags;
  ASSERT_TRUE(detector_->detect(in, got).ok());
  EXPECT_EQ(got.stats.active, s.size());
  EXPECT_TRUE(test::same_pairs(got.pairs, test::oracle_pairs(s)));
}

TEST_P(ConformanceFrames, AlwaysActiveWithTheCallersMap) {
  // Four objects, all overlapping; the map (no camera: map pixels) shows object 0 on 6 pixels,
  // object 1 on 2, and nothing of objects 2 and 3. With lambda 4 only object 0 is visible enough;
  // flags on 2 and 3 make {0, 2, 3} active.
  const std::vector<Sphere> s = {{0, 0, 0, 1}, {0.5f, 0, 0, 1}, {1, 0, 0, 1}, {1.5f, 0, 0, 1}};
  const std::vector<std::uint32_t> map = {1, 1, 1, 1, 1, 1, 2, 2, 0, 0, 0, 0};
  const std::vector<std::uint8_t> flags = {0, 0, 1, 1};
  Config c;
  c.lambda = 4;
  detector_->set_config(c);
  FrameInput in;
  in.spheres = s;
  in.id_map = map;
  in.id_map_width = 4;
  in.id_map_height = 3;
  in.always_active = flags;
  FrameResult got;
  const Status st = detector_->detect(in, got);
  ASSERT_TRUE(st.ok()) << st.error();
  EXPECT_EQ(got.stats.active, 3u);
  EXPECT_EQ(got.pairs, (std::vector<Pair>{{0, 2}, {0, 3}, {2, 3}}));
  ASSERT_EQ(got.state.size(), 4u);
  EXPECT_EQ(got.state[1], ObjectState::culled);
  EXPECT_EQ(got.pixels, (std::vector<float>{6, 2, 0, 0}));
}

TEST_P(ConformanceFrames, AlwaysActiveOfTheWrongSizeIsAnError) {
  const std::vector<Sphere> s = random_cloud(10, 3, 4.0f);
  const std::vector<std::uint8_t> short_flags(9, 1);
  FrameInput in;
  in.spheres = s;
  in.always_active = short_flags;
  FrameResult got;
  const Status st = detector_->detect(in, got);
  ASSERT_FALSE(st.ok());
  EXPECT_EQ(st.kind(), ErrorKind::invalid_input);
  EXPECT_NE(st.error().find("always_active"), std::string::npos) << st.error();
  // Without a camera every object is active anyway; flags of the right size change nothing.
  const std::vector<std::uint8_t> flags(10, 0);
  in.always_active = flags;
  ASSERT_TRUE(detector_->detect(in, got).ok());
  EXPECT_EQ(got.stats.active, 10u);
  EXPECT_TRUE(test::same_pairs(got.pairs, test::oracle_pairs(s)));
}

}  // namespace
}  // namespace viscd::conformance
