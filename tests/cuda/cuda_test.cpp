// The cuda backend beyond the conformance suite: large frames against the cpu backend, the pair
// buffer's growth, the splatted map against the reference ray caster, and the error without a
// device. On a machine without a usable GPU every test but the last skips, saying why.
#include <gtest/gtest.h>

#include <cstdlib>
#include <string>
#include <vector>

#include "cpu/pipeline.hpp"
#include "cuda/cuda_detector.hpp"
#include "test_util.hpp"
#include "viscd/cuda.hpp"
#include "viscd/scene.hpp"
#include "viscd/viscd.hpp"

namespace viscd {
namespace {

// The detector, or a skip naming why there is none.
#define VISCD_CUDA_OR_SKIP(name, config)                                             \
  auto name##_made = make_cuda_detector(config);                                     \
  if (!name##_made) GTEST_SKIP() << "no cuda backend here: " << name##_made.error(); \
  Detector& name = *name##_made.value()

TEST(Cuda, DeviceOrClearError) {
  const auto device = cuda_device();
  const auto made = make_cuda_detector();
  ASSERT_EQ(device.ok(), made.ok());
  if (device) {
    EXPECT_NE(device.value().find("sm_"), std::string::npos) << device.value();
    EXPECT_EQ(made.value()->name(), "cuda");
  } else {
    // Without a device (or without CUDA in the build) the factory names the reason.
    EXPECT_FALSE(made.error().empty());
    EXPECT_NE(made.error().find("CUDA"), std::string::npos) << made.error();
    EXPECT_FALSE(make_detector("cuda").ok());
  }
}

// A dense moving scene (0.6 pairs an object) against the cpu backend, frame after frame.
TEST(Cuda, DenseScenesMatchCpu) {
  Config c;
  c.bits = Bits::b32;
  VISCD_CUDA_OR_SKIP(gpu, c);
  auto cpu = make_cpu_detector(c);
  for (std::uint32_t n : {255u, 256u, 257u, 20000u, 300000u}) {
    Scene scene = Scene::make(SceneParams{.objects = n, .seed = 7, .packing = 0.18f});
    for (int frame = 0; frame < 3; ++frame) {
      const FrameResult want = test::run_frame(*cpu, scene.spheres());
      const FrameResult got = test::run_frame(gpu, scene.spheres());
      ASSERT_TRUE(test::same_pairs(got.pairs, want.pairs)) << "N = " << n << ", frame " << frame;
      EXPECT_EQ(got.state, want.state);
      scene.step(1.0f / 60.0f);
    }
  }
}

// Every object at one point: n(n-1)/2 pairs, far beyond the first pair buffer (65 536); the
// buffer grows to the count and the query runs again. Then a frame with few pairs.
TEST(Cuda, PairBufferGrowsAndNothingIsLost) {
  VISCD_CUDA_OR_SKIP(gpu, Config{});
  const std::uint32_t n = 3000;
  std::vector<Sphere> same(n, Sphere{1, 2, 3, 0.5f});
  const FrameResult all = test::run_frame(gpu, same);
  ASSERT_EQ(all.pairs.size(), max_pairs_bound(n));
  std::size_t k = 0;
  for (std::uint32_t i = 0; i < n; ++i)
    for (std::uint32_t j = i + 1; j < n; ++j, ++k) ASSERT_EQ(all.pairs[k], (Pair{i, j}));
  const std::vector<Sphere> few = test::random_spheres_by_half_extent(2000, 3, 50.0f);
  EXPECT_TRUE(test::same_pairs(test::run_frame(gpu, few).pairs, test::oracle_pairs(few)));
}

// The splat's map against the reference ray caster's, for spheres and their cubes, from three
// cameras: the same ray model, the same float operations and the same tie rule (the smaller id),
// so the ids agree pixel for pixel, and so do the pixel counts and the pairs.
void expect_reference_maps(Detector& gpu, std::uint64_t seed) {
  Config c = gpu.config();
  auto ref = make_reference_detector(c);
  Scene scene = Scene::make(SceneParams{.objects = 600, .seed = seed});
  std::vector<Box> boxes;
  for (const Sphere& s : scene.spheres())
    boxes.push_back(Box{{s.x - s.r, s.y - s.r, s.z - s.r}, {s.x + s.r, s.y + s.r, s.z + s.r}});
  for (const char* preset : {"zoom-out", "zoom-in", "orbit"}) {
    const auto cam = camera_preset(preset, scene, 1280, 720);
    ASSERT_TRUE(cam.ok()) << cam.error();
    for (bool as_boxes : {false, true}) {
      SCOPED_TRACE(std::string(preset) + (as_boxes ? ", boxes" : ", spheres"));
      FrameInput in;
      if (as_boxes)
        in.boxes = boxes;
      else
        in.spheres = scene.spheres();
      in.camera = &cam.value();
      FrameResult got, want;
      ASSERT_TRUE(gpu.detect(in, got).ok());
      ASSERT_TRUE(ref->detect(in, want).ok());
      const auto& a = detail::backend_as<detail::PipelineDetector>(gpu).visibility_map();
      const auto& b = detail::backend_as<detail::PipelineDetector>(*ref).visibility_map();
      ASSERT_EQ(a.ids.size(), b.ids.size());
      std::size_t differ = 0;
      for (std::size_t i = 0; i < a.ids.size(); ++i) differ += a.ids[i] != b.ids[i];
      EXPECT_EQ(differ, 0u);
      EXPECT_EQ(got.pixels, want.pixels);
      EXPECT_TRUE(test::same_pairs(got.pairs, want.pairs));
    }
  }
}

Config small_map() {
  Config c;
  c.map_width = 160;
  c.map_height = 90;
  return c;
}

// The splat as it runs: a plan cuts each object's rectangle into chunks, a block a chunk.
TEST(Cuda, SplatMatchesReferenceMap) {
  VISCD_CUDA_OR_SKIP(gpu, small_map());
  expect_reference_maps(gpu, 11);
}

// Its fallback for frames whose rectangles would need too long a chunk list (a warp per object),
// forced by the test hook's limit of 0 chunks.
TEST(Cuda, SplatFallbackMatchesReferenceMap) {
  VISCD_CUDA_OR_SKIP(gpu, small_map());
  ASSERT_TRUE(detail::set_cuda_chunk_limit(gpu, 0));
  expect_reference_maps(gpu, 13);
}

// Boxes, a static set and filters together, against the cpu backend.
TEST(Cuda, BoxesStaticSetAndFiltersMatchCpu) {
  Config c;
  c.bits = Bits::b64;
  VISCD_CUDA_OR_SKIP(gpu, c);
  auto cpu = make_cpu_detector(c);
  Scene scene = Scene::make(SceneParams{.objects = 50000, .seed = 5, .packing = 0.18f});
  std::vector<Box> boxes;
  for (const Sphere& s : scene.spheres())
    boxes.push_back(Box{{s.x - s.r, s.y - s.r, s.z - s.r}, {s.x + s.r, s.y + s.r, s.z + s.r}});
  std::vector<Box> walls;
  for (std::size_t k = 0; k < boxes.size(); k += 97) walls.push_back(boxes[k]);
  const std::vector<Filter> filters = test::random_filters(boxes.size(), 9);
  for (Detector* d : {&gpu, cpu.get()}) ASSERT_TRUE(d->set_static_boxes(walls).ok());
  FrameInput in;
  in.boxes = boxes;
  in.filters = filters;
  FrameResult got, want;
  ASSERT_TRUE(gpu.detect(in, got).ok());
  ASSERT_TRUE(cpu->detect(in, want).ok());
  EXPECT_GT(want.pairs.size(), 1000u);
  EXPECT_TRUE(test::same_pairs(got.pairs, want.pairs));
  EXPECT_EQ(got.state, want.state);
}

}  // namespace
}  // namespace viscd
