// Conformance, contact events: over moving sequences (small motion, teleports, N growing and
// shrinking, a camera culling objects in and out), FrameResult::began and ::ended must equal the
// set differences of the oracle's pair sets of consecutive frames, computed here with
// std::set_difference. Also reset_events(), events switched off and on, and failed frames.
#include <limits>
#include <random>

#include "conformance/conformance.hpp"

namespace viscd::conformance {
namespace {

// A detector with contact events on, and the oracle's pairs of its previous frame.
class Events {
 public:
  Events(Detector& d, Config c) : d_(d), config_(c) {
    config_.contact_events = true;
    d_.set_config(config_);
  }
  // One frame: pairs against the oracle, events against the set differences of the oracle's pairs.
  void frame(std::span<const Sphere> s, const Camera* cam, const std::string& what) {
    SCOPED_TRACE(std::string(d_.name()) + ": " + what + " (N = " + std::to_string(s.size()) + ")");
    const Status st = d_.detect(s, cam, out_);
    ASSERT_TRUE(st.ok()) << st.error();
    const Expected want = expect_frame(s, cam, config_, cam != nullptr);
    check_frame(out_, s, cam, config_, want);
    std::vector<Pair> began, ended;
    test::oracle_events(previous_, want.pairs, began, ended);
    EXPECT_TRUE(test::same_pairs(out_.began, began)) << "began";
    EXPECT_TRUE(test::same_pairs(out_.ended, ended)) << "ended";
    previous_ = want.pairs;
  }
  void forget() { previous_.clear(); }
  const FrameResult& out() const { return out_; }

 private:
  Detector& d_;
  Config config_;
  FrameResult out_;
  std::vector<Pair> previous_;
};

TEST_P(ConformanceFrames, ContactEventsOverAMovingScene) {
  Events ev(*detector_, Config{});
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<float> u(-1, 1);
  std::vector<Sphere> s;
  ASSERT_NO_FATAL_FAILURE(ev.frame(s, nullptr, "empty"));
  s = random_cloud(400, 1, 9.0f, 0.2f, 1.2f);
  ASSERT_NO_FATAL_FAILURE(ev.frame(s, nullptr, "first frame: every pair begins"));
  EXPECT_EQ(ev.out().began.size(), ev.out().pairs.size());
  ASSERT_NO_FATAL_FAILURE(ev.frame(s, nullptr, "unchanged: no events"));
  EXPECT_TRUE(ev.out().began.empty() && ev.out().ended.empty());
  for (int f = 0; f < 12; ++f) {
    for (Sphere& x : s) x.x += 0.15f * u(rng), x.y += 0.15f * u(rng), x.z += 0.15f * u(rng);
    if (f == 3)
      for (std::size_t k = 0; k < s.size(); k += 7) s[k] = {9 * u(rng), 9 * u(rng), 9 * u(rng), s[k].r};  // teleport
    if (f == 5) s.resize(250);  // pairs with indices >= 250 end
    if (f == 7) {
      const auto more = random_cloud(300, 77, 9.0f, 0.2f, 1.2f);
      s.insert(s.end(), more.begin(), more.end());  // new indices begin
    }
    if (f == 9) s.assign(s.size(), Sphere{0, 0, 0, 1});             // every pair at once
    if (f == 10) s = random_cloud(s.size(), 5, 40.0f, 0.1f, 0.2f);  // almost every pair ends
    ASSERT_NO_FATAL_FAILURE(ev.frame(s, nullptr, "frame " + std::to_string(f)));
  }
  s.clear();
  ASSERT_NO_FATAL_FAILURE(ev.frame(s, nullptr, "empty again: every pair ends"));
  EXPECT_TRUE(ev.out().began.empty());
}

TEST_P(ConformanceFrames, ContactEventsWhenFewObjectsMove) {
  // Most pairs persist: the events are a few pairs at any place in long lists (at their start and
  // end too), and the lists agree over long stretches between them.
  Events ev(*detector_, Config{});
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<float> u(-1, 1);
  std::vector<Sphere> s = random_cloud(600, 21, 10.0f, 0.3f, 1.0f);
  ASSERT_NO_FATAL_FAILURE(ev.frame(s, nullptr, "first frame"));
  ASSERT_GT(ev.out().pairs.size(), 200u) << "the scene should hold long pair lists";
  const std::size_t n = s.size();
  const std::size_t picks[] = {0, 1, n / 3, n / 2, n - 2, n - 1};
  for (int f = 0; f < 24; ++f) {
    // One to three objects move a little or jump; the first and last objects now and then.
    const int count = 1 + f % 3;
    for (int k = 0; k < count; ++k) {
      const std::size_t o = f % 4 == 0 ? picks[static_cast<std::size_t>(f / 4 + k) % std::size(picks)]
                                       : static_cast<std::size_t>(rng() % n);
      if (f % 2)
        s[o] = {10 * u(rng), 10 * u(rng), 10 * u(rng), s[o].r};
      else
        s[o].x += 0.5f * u(rng), s[o].y += 0.5f * u(rng);
    }
    ASSERT_NO_FATAL_FAILURE(ev.frame(s, nullptr, "few moved, frame " + std::to_string(f)));
  }
  ASSERT_NO_FATAL_FAILURE(ev.frame(s, nullptr, "unchanged: no events"));
  EXPECT_TRUE(ev.out().began.empty() && ev.out().ended.empty());
}

TEST_P(ConformanceFrames, ContactEventsWithCulling) {
  // Objects culled in or out end or begin their pairs; the camera comes and goes.
  CameraScene scene = camera_scene(300, 13, 20.0f);
  Config c;
  c.lambda = scene.lambda;
  Events ev(*detector_, c);
  ASSERT_NO_FATAL_FAILURE(ev.frame(scene.spheres, &scene.camera, "culled"));
  for (int f = 0; f < 4; ++f) {
    for (Sphere& x : scene.spheres) x.y += 0.4f, x.r *= (f % 2 ? 1.3f : 0.8f);
    clear_lambda_band(scene.spheres, scene.camera, scene.lambda);
    ASSERT_NO_FATAL_FAILURE(ev.frame(scene.spheres, &scene.camera, "moved, culled, frame " + std::to_string(f)));
  }
  ASSERT_NO_FATAL_FAILURE(ev.frame(scene.spheres, nullptr, "without the camera: culled pairs begin"));
  ASSERT_NO_FATAL_FAILURE(ev.frame(scene.spheres, &scene.camera, "the camera again: they end"));
}

TEST_P(ConformanceFrames, ContactEventsResetOffAndFailedFrames) {
  Events ev(*detector_, Config{});
  std::vector<Sphere> s = random_cloud(200, 2, 6.0f);
  ASSERT_NO_FATAL_FAILURE(ev.frame(s, nullptr, "first"));
  // reset_events(): the next frame's began holds every pair.
  detector_->reset_events();
  ev.forget();
  ASSERT_NO_FATAL_FAILURE(ev.frame(s, nullptr, "after reset_events()"));
  EXPECT_EQ(ev.out().began.size(), ev.out().pairs.size());
  // A failed frame leaves the previous frame as it was.
  std::vector<Sphere> bad = s;
  bad[3].x = std::numeric_limits<float>::quiet_NaN();
  FrameResult f;
  ASSERT_FALSE(detector_->detect(bad, nullptr, f).ok());
  for (Sphere& x : s) x.x += 0.3f;
  ASSERT_NO_FATAL_FAILURE(ev.frame(s, nullptr, "after a failed frame: against the last good frame"));
  // Events off: began and ended stay empty, and the previous frame is not kept.
  Config off;
  detector_->set_config(off);
  for (int k = 0; k < 2; ++k) {
    for (Sphere& x : s) x.z -= 0.2f;
    ASSERT_TRUE(detector_->detect(s, nullptr, f).ok());
    EXPECT_TRUE(f.began.empty() && f.ended.empty()) << "events off";
  }
  // On again: starts afresh.
  Events again(*detector_, Config{});
  ASSERT_NO_FATAL_FAILURE(again.frame(s, nullptr, "events on again: every pair begins"));
  EXPECT_EQ(again.out().began.size(), again.out().pairs.size());
}

}  // namespace
}  // namespace viscd::conformance
