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

TEST(GlAllocation, SteadyStateFramesWithBoxesAndAStaticSetAllocateNothing) {
  for (const bool boxes : {false, true}) {
    SCOPED_TRACE(boxes ? "boxes" : "spheres");
    Config c;
    c.map_width = 256;
    c.map_height = 144;
    c.shade = true;
    c.lambda = 10;
    VISCD_GL_OR_SKIP(gl, c);
    Detector& d = gl->detector();
    d.clear_static();
    std::vector<Sphere> spheres = random_spheres_by_edge(3000, 40.0f, 0.3f, 1.5f, 4);
    std::vector<Box> moving(spheres.size());
    for (std::size_t k = 0; k < spheres.size(); ++k)
      for (int a = 0; a < 3; ++a) {
        const float centre = a == 0 ? spheres[k].x : a == 1 ? spheres[k].y : spheres[k].z;
        moving[k].min[a] = centre - spheres[k].r;
        moving[k].max[a] = centre + spheres[k].r;
      }
    const std::vector<Sphere> static_spheres = random_spheres_by_edge(500, 40.0f, 0.5f, 3.0f, 5);
    std::vector<Box> static_boxes(static_spheres.size());
    for (std::size_t k = 0; k < static_boxes.size(); ++k)
      for (int a = 0; a < 3; ++a) {
        const float centre = a == 0 ? static_spheres[k].x : a == 1 ? static_spheres[k].y : static_spheres[k].z;
        static_boxes[k].min[a] = centre - static_spheres[k].r;
        static_boxes[k].max[a] = centre + static_spheres[k].r;
      }
    ASSERT_TRUE((boxes ? d.set_static_boxes(static_boxes) : d.set_static_spheres(static_spheres)).ok());
    Camera cam;
    cam.eye[2] = 60;
    cam.width = 256;
    cam.height = 144;
    FrameResult f;
    std::vector<RayHit> hits;
    // Each frame moves the objects and queries once (the query copy is read back per frame).
    const auto [n, st] = steady_state_allocations([&] {
      for (Sphere& s : spheres) s.x += 0.01f;
      for (Box& b : moving) b.min[0] += 0.01f, b.max[0] += 0.01f;
      FrameInput in;
      in.camera = &cam;
      if (boxes)
        in.boxes = moving;
      else
        in.spheres = spheres;
      const Status s = d.detect(in, f);
      d.ray_cast_all(Ray{{0, 0, 60}, {0, 0, -1}}, hits);
      return s;
    });
    d.clear_static();
    ASSERT_TRUE(st.ok()) << st.error();
    EXPECT_GT(f.pairs.size(), 0u);
    EXPECT_GT(f.stats.static_objects, 0u);
    EXPECT_EQ(n, 0) << "allocations in 4 steady-state frames";
  }
}

}  // namespace
}  // namespace viscd::test
