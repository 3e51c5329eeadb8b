// The gl backend allocates nothing on the host per frame once warmed up: global operator new is
// counted (in every thread of the process, the driver's included) over several steady frames.
#include <gtest/gtest.h>

#include "counting_new.hpp"
#include "gl_test_util.hpp"
#include "viscd/scene.hpp"

namespace viscd::test {
namespace {

TEST(GlAllocation, CounterSeesAnAllocation) {
  // The counter's control: a frame that grows its result vectors does allocate.
  VISCD_GL_OR_SKIP(gl, Config{});
  const std::vector<Sphere> s = random_spheres_by_edge(500, 5.0f, 0.2f, 0.5f, 3);
  FrameResult f;
  Status st;
  const long n = allocations_during([&] { st = gl->detect(s, nullptr, f); });
  ASSERT_TRUE(st.ok()) << st.error();
  EXPECT_GT(n, 0);
}

TEST(GlAllocation, SteadyStateFramesAllocateNothing) {
  VISCD_GL_OR_SKIP(gl);
  Scene scene = Scene::make({.objects = 6000, .seed = 9});
  const Camera cam = small_camera(scene, "zoom-out");
  for (const bool sync : {false, true}) {
    for (const bool with_camera : {false, true}) {
      SCOPED_TRACE(std::string(sync ? "sync_layout" : "default mode") + (with_camera ? ", camera" : ", no camera"));
      Config c;
      c.map_width = 256;
      c.map_height = 144;
      c.shade = with_camera;
      c.lambda = 10;  // enough active objects to have pairs
      GlOptions o;
      o.sync_layout = sync;
      gl = gl_detector(c, o);
      FrameResult f;
      // The warm-up frames also let the driver build what it caches.
      const auto [n, st] = steady_state_allocations([&] {
        scene.step(1.0f / 60.0f);
        return gl->detect(scene.spheres(), with_camera ? &cam : nullptr, f);
      });
      ASSERT_TRUE(st.ok()) << st.error();
      EXPECT_GT(f.pairs.size(), 0u);
      EXPECT_EQ(n, 0) << "allocations in 4 steady-state frames";
    }
  }
}

}  // namespace
}  // namespace viscd::test
