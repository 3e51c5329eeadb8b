// The library's limits on hostile settings: thread counts, camera magnitudes, visibility-map
// sizes, and a pair cap that is enforced before the pairs' memory is taken.
#include <gtest/gtest.h>

#include <limits>
#include <string>
#include <thread>
#include <vector>

#include "cpu/parallel.hpp"
#include "test_util.hpp"
#include "viscd/viscd.hpp"

namespace viscd {
namespace {

using test::oracle_pairs;
using test::random_spheres_by_half_extent;
using test::same_pairs;

std::vector<Sphere> coincident(std::size_t n) { return std::vector<Sphere>(n, Sphere{0, 0, 0, 1}); }

TEST(Threads, MoreThanTheMachineHasAreClamped) {
  EXPECT_LE(detail::resolve_threads(100000), static_cast<int>(std::max(1u, std::thread::hardware_concurrency())));
  EXPECT_GE(detail::resolve_threads(100000), 1);
  EXPECT_EQ(detail::resolve_threads(1), 1);
  Config c;
  c.threads = 100000;
  const auto spheres = random_spheres_by_half_extent(20000, 7, 40);
  Camera cam;
  cam.eye[2] = 120;
  cam.width = 320;
  cam.height = 180;
  c.lambda = 0;
  auto det = make_cpu_detector(c);
  FrameResult f;
  ASSERT_TRUE(det->detect(spheres, &cam, f).ok());
  std::vector<std::uint32_t> active;
  for (std::uint32_t k = 0; k < spheres.size(); ++k)
    if (f.state[k] != ObjectState::culled) active.push_back(k);
  EXPECT_TRUE(same_pairs(f.pairs, oracle_pairs(spheres, &active)));
}

TEST(Threads, NegativeIsAnError) {
  for (const char* backend : {"cpu", "reference"}) {
    Config c;
    c.threads = -1;
    auto det = make_detector(backend, c);
    ASSERT_TRUE(det.ok());
    FrameResult f;
    const Status s = det.value()->detect(coincident(3), nullptr, f);
    ASSERT_FALSE(s.ok()) << backend;
    EXPECT_NE(s.error().find("Config::threads"), std::string::npos) << s.error();
  }
}

// The cpu backend checks the objects in ranges on its threads: with more objects than the
// parallel threshold, a bad sphere or box anywhere gives validate_spheres()'s or
// validate_boxes()'s error, naming the first bad one.
TEST(Validation, InRangesTheFirstBadObjectIsNamed) {
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  for (int threads : {1, 2, 3}) {
    Config c;
    c.threads = threads;
    auto d = make_cpu_detector(c);
    FrameResult f;
    constexpr std::size_t n = 100003;
    std::vector<Sphere> s(n);
    std::vector<Box> b(n);
    for (std::size_t k = 0; k < n; ++k) {  // apart: no pairs
      const float x = 3.0f * static_cast<float>(k);
      s[k] = {x, 2, 3, 0.5f};
      b[k] = {{x, 0, 0}, {x + 1, 1, 1}};
    }
    ASSERT_TRUE(d->detect(s, nullptr, f).ok());
    for (std::size_t at : {std::size_t{0}, std::size_t{4095}, n / 2, n - 1}) {
      for (const Sphere bad :
           {Sphere{nan, 0, 0, 1}, Sphere{0, 0, inf, 1}, Sphere{0, 0, 0, -0.5f}, Sphere{0, 2e18f, 0, 1}}) {
        std::vector<Sphere> t = s;
        t[at] = bad;
        t[n - 1 - at / 2] = Sphere{0, 0, 0, -1};  // a second bad one, later unless at is the last
        const Status st = d->detect(t, nullptr, f);
        ASSERT_FALSE(st.ok()) << at;
        EXPECT_EQ(st.error(), validate_spheres(t).error()) << at;
        EXPECT_NE(st.error().find("sphere " + std::to_string(std::min(at, n - 1 - at / 2))), std::string::npos)
            << st.error();
      }
      std::vector<Box> t = b;
      t[at].max[1] = -1;  // min > max
      FrameInput in;
      in.boxes = t;
      const Status st = d->detect(in, f);
      ASSERT_FALSE(st.ok()) << at;
      EXPECT_EQ(st.error(), validate_boxes(t).error()) << at;
      EXPECT_NE(st.error().find("box " + std::to_string(at)), std::string::npos) << st.error();
    }
    ASSERT_TRUE(d->detect(s, nullptr, f).ok()) << "recovers";
  }
}

TEST(CameraLimits, CoordinatesBeyond1e18AreRejected) {
  Camera c;
  EXPECT_TRUE(validate_camera(c).ok());
  c.eye[1] = 1e30f;
  EXPECT_FALSE(validate_camera(c).ok());
  c = Camera{};
  c.target[0] = -2e18f;
  EXPECT_FALSE(validate_camera(c).ok());
  c = Camera{};
  c.up[1] = 1e19f;
  EXPECT_FALSE(validate_camera(c).ok());
  c = Camera{};
  c.far_plane = 1e30f;
  EXPECT_FALSE(validate_camera(c).ok());
  c = Camera{};
  c.eye[0] = c.eye[1] = c.eye[2] = 1e18f;
  c.far_plane = 1e18f;
  EXPECT_TRUE(validate_camera(c).ok());
}

TEST(MapLimits, OversizedMapsFailAtOnceWithTheSize) {
  auto det = make_cpu_detector();
  Camera cam;
  cam.width = 20000;
  cam.height = 20000;
  FrameResult f;
  const auto spheres = coincident(2);
  Status s = det->detect(spheres, &cam, f);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().find("20000x20000"), std::string::npos) << s.error();
  // The same screen with a map inside the bounds works; counts are scaled to the screen.
  Config c;
  c.map_width = 640;
  c.map_height = 640;
  det->set_config(c);
  s = det->detect(spheres, &cam, f);
  EXPECT_TRUE(s.ok()) << s.error();
  // Too many pixels in all, though each side is allowed.
  c.map_width = 16384;
  c.map_height = 8192;
  det->set_config(c);
  EXPECT_FALSE(det->detect(spheres, &cam, f).ok());
}

TEST(PairCap, EnforcedBeforeThePairsMemoryIsTaken) {
  // 3000 coincident spheres: 4 498 500 pairs, 36 MB of pairs (and several times that in the
  // buffers behind them). A 64 KiB cap must fail long before.
  const auto spheres = coincident(3000);
  constexpr std::size_t kCap = 64 * 1024;
  for (const char* backend : {"cpu", "reference"}) {
    Config c;
    c.pair_memory_cap = kCap;
    auto det = make_detector(backend, c);
    ASSERT_TRUE(det.ok());
    FrameResult f;
    const Status s = det.value()->detect(spheres, nullptr, f);
    ASSERT_FALSE(s.ok()) << backend;
    EXPECT_NE(s.error().find("pair memory cap"), std::string::npos) << s.error();
    EXPECT_LT(det.value()->memory_bytes(), kCap + (2u << 20)) << backend;
    EXPECT_LT(f.pairs.capacity() * sizeof(Pair), kCap + (1u << 20)) << backend;
  }
}

TEST(PairCap, ExactlyAtTheCapPasses) {
  // 100 coincident spheres: 4950 pairs = 39 600 bytes.
  const auto spheres = coincident(100);
  for (const char* backend : {"cpu", "reference"}) {
    Config c;
    c.pair_memory_cap = 4950 * sizeof(Pair);
    auto det = make_detector(backend, c);
    ASSERT_TRUE(det.ok());
    FrameResult f;
    Status s = det.value()->detect(spheres, nullptr, f);
    ASSERT_TRUE(s.ok()) << backend << ": " << s.error();
    EXPECT_EQ(f.pairs.size(), 4950u);
    c.pair_memory_cap -= 1;
    det.value()->set_config(c);
    s = det.value()->detect(spheres, nullptr, f);
    EXPECT_FALSE(s.ok()) << backend;
  }
}

TEST(StageTimes, WaitingIsANoOpOnCpuBackends) {
  auto det = make_cpu_detector();
  FrameResult f;
  const auto spheres = random_spheres_by_half_extent(100, 3);
  ASSERT_TRUE(det->detect(spheres, nullptr, f).ok());
  const FrameStats before = f.stats;
  det->wait_for_stage_times(f.stats);
  EXPECT_EQ(before.stage_ms, f.stats.stage_ms);
}

}  // namespace
}  // namespace viscd
