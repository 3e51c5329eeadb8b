// The cpu backend allocates nothing per frame once warmed up (no allocation per frame after the
// first): global operator new is counted between two points of a test.
#include <gtest/gtest.h>

#include <cstdlib>

#include "counting_new.hpp"
#include "test_util.hpp"
#include "viscd/executor.hpp"
#include "viscd/scene.hpp"

namespace viscd {
namespace {

using test::allocations_during;
using test::steady_state_allocations;

TEST(Allocation, SteadyStateFramesAllocateNothing) {
#ifdef VISCD_VALIDATE
  GTEST_SKIP() << "VISCD_VALIDATE checks the tree every frame, whose diagnostics may allocate";
#endif
  Scene scene = Scene::make({.objects = 20000});
  const Camera cam = camera_preset("zoom-out", scene, 640, 360).value();
  SerialExecutor serial;
  // Without a camera the counted frames keep the last order (the broadphase's steady path); with
  // keeping switched off (Config::keep_order), and with a camera
  // (objects cross lambda, so the active set changes), they sort from the last frame's order.
  for (const bool keep : {true, false}) {
    for (const bool with_camera : {false, true}) {
      for (Bits bits : {Bits::adaptive, Bits::b16, Bits::b64}) {
        Config c;
        c.bits = bits;
        c.keep_order = keep;
        c.shade = with_camera;
        // The caller's executor on one of the runs, viscd's pool on the others.
        if (bits == Bits::b16) c.executor = &serial;
        auto det = make_cpu_detector(c);
        FrameResult f;
        int kept = 0;
        const auto [n, st] = steady_state_allocations([&] {
          scene.step(1.0f / 60.0f);
          const Status s = det->detect(scene.spheres(), with_camera ? &cam : nullptr, f);
          kept += f.stats.order_kept;
          return s;
        });
        ASSERT_TRUE(st.ok()) << st.error();
        EXPECT_EQ(n, 0) << "allocations in a steady-state frame, keep " << keep << ", camera " << with_camera << ", m "
                        << static_cast<int>(bits);
        if (!with_camera) {
          EXPECT_EQ(kept, keep ? 6 : 0) << "frames after the first keep the order unless it is switched off";
        }
      }
    }
  }
}

TEST(Allocation, SteadyStateFramesWithFiltersAndEventsAllocateNothing) {
#ifdef VISCD_VALIDATE
  GTEST_SKIP() << "VISCD_VALIDATE checks the tree every frame, whose diagnostics may allocate";
#endif
  Scene scene = Scene::make({.objects = 20000});
  const Camera cam = camera_preset("zoom-out", scene, 640, 360).value();
  // A third pairs with nothing (out of the tree), a third only among themselves, the rest default.
  std::vector<Filter> filters(scene.spheres().size());
  for (std::size_t k = 0; k < filters.size(); k += 3) filters[k] = {4, 0};
  for (std::size_t k = 1; k < filters.size(); k += 3) filters[k] = {2, 2};
  for (const bool with_camera : {false, true}) {
    Config c;
    c.contact_events = true;
    auto det = make_cpu_detector(c);
    FrameResult f;
    auto frame = [&] {
      scene.step(1.0f / 60.0f);
      FrameInput in;
      in.spheres = scene.spheres();
      in.camera = with_camera ? &cam : nullptr;
      in.filters = filters;
      return det->detect(in, f);
    };
    const auto [n, st] = steady_state_allocations(frame);
    ASSERT_TRUE(st.ok()) << st.error();
    EXPECT_EQ(n, 0) << "allocations in a steady-state frame with filters and events, camera " << with_camera;
    if (!with_camera) {
      EXPECT_GT(f.pairs.size(), 0u);
    }
  }
}

TEST(Allocation, SteadyStateFramesFromTheCallersIdMapAllocateNothing) {
#ifdef VISCD_VALIDATE
  GTEST_SKIP() << "VISCD_VALIDATE checks the tree every frame, whose diagnostics may allocate";
#endif
  Scene scene = Scene::make({.objects = 20000});
  const Camera cam = camera_preset("zoom-out", scene, 640, 360).value();
  // A map from a frame of the detector's own, then given back frame after frame.
  auto own = make_cpu_detector(Config{});
  FrameResult f;
  ASSERT_TRUE(own->detect(scene.spheres(), &cam, f).ok());
  std::vector<std::uint32_t> map(640 * 360);
  for (std::size_t k = 0; k < map.size(); ++k)
    map[k] = k % 97 == 0 ? 0 : 1 + static_cast<std::uint32_t>(k / 13 % 20000);
  Config c;
  c.lambda = 5;
  c.contact_events = true;
  auto det = make_cpu_detector(c);
  const auto [n, st] = steady_state_allocations([&] {
    scene.step(1.0f / 60.0f);
    return det->detect(test::id_map_input(scene.spheres(), &cam, map, 640, 360), f);
  });
  ASSERT_TRUE(st.ok()) << st.error();
  EXPECT_EQ(n, 0) << "allocations in a steady-state frame from the caller's id map";
}

TEST(Allocation, QueriesAllocateNothingOnceTheirOutputsHaveRoom) {
  Scene scene = Scene::make({.objects = 20000});
  std::vector<Filter> filters(scene.spheres().size());
  for (std::size_t k = 0; k < filters.size(); k += 2) filters[k] = {4, 0};
  auto det = make_cpu_detector(Config{});
  FrameInput in;
  in.spheres = scene.spheres();
  in.filters = filters;
  FrameResult f;
  ASSERT_TRUE(det->detect(in, f).ok());
  std::vector<RayHit> hits;
  std::vector<std::uint32_t> idx;
  hits.reserve(20000);
  idx.reserve(20000);
  Ray r;
  r.origin[0] = -scene.world_radius(), r.origin[1] = 0, r.origin[2] = 0;
  r.dir[0] = 1, r.dir[1] = 0, r.dir[2] = 0.01f;
  RayHit h{};
  ASSERT_TRUE(det->ray_cast(r, h));  // the first query builds the tree of the filtered-out objects
  const long n = allocations_during([&] {
    for (int k = 0; k < 10; ++k) {
      (void)det->ray_cast(r, h);
      det->ray_cast_all(r, hits);
      det->overlap({0, 0, scene.world_radius() * 0.5f, 3}, idx);
    }
  });
  EXPECT_EQ(n, 0);
  EXPECT_GT(hits.size(), 1u);
}

TEST(Allocation, FollowedFramesAllocateNothing) {
#ifdef VISCD_VALIDATE
  GTEST_SKIP() << "VISCD_VALIDATE checks the tree every frame, whose diagnostics may allocate";
#endif
  // A world at rest but for 1 % of its objects, which move every frame (Config::follow_change),
  // spheres and boxes, bounds compared or listed, with and without a margin.
  for (const bool boxes : {false, true}) {
    for (const bool listed : {false, true}) {
      for (const float margin : {0.0f, 0.02f}) {
        std::vector<Sphere> s = test::random_spheres_by_half_extent(20000, 4, 40, 0.3f, 0.6f);
        std::vector<Box> b(s.size());
        std::vector<std::uint32_t> moved;
        for (std::uint32_t k = 37; k < s.size(); k += 101) moved.push_back(k);
        Config c;
        c.rest_margin = margin;
        auto det = make_cpu_detector(c);
        FrameResult f;
        int followed = 0, step = 0;
        auto frame = [&] {
          ++step;
          for (const std::uint32_t k : moved) s[k].x += (step % 2 ? 0.05f : -0.05f);
          for (std::size_t k = 0; k < s.size(); ++k)
            b[k] = Box{{s[k].x - s[k].r, s[k].y - s[k].r, s[k].z - s[k].r},
                       {s[k].x + s[k].r, s[k].y + s[k].r, s[k].z + s[k].r}};
          FrameInput in;
          if (boxes)
            in.boxes = b;
          else
            in.spheres = s;
          in.moved = moved;
          in.moved_listed = listed;
          if (!listed) in.moved = {};
          const Status status = det->detect(in, f);
          followed += f.stats.followed_change;
          return status;
        };
        // Following warms up over its first frames too: a sample, the frame that places every
        // object, the first frames that take movers out of each tree.
        for (int k = 0; k < 4; ++k) ASSERT_TRUE(frame().ok());
        const auto [n, st] = steady_state_allocations(frame);
        ASSERT_TRUE(st.ok()) << st.error();
        EXPECT_EQ(n, 0) << "boxes " << boxes << ", listed " << listed << ", margin " << margin;
        EXPECT_GE(followed, 5) << "the frames must follow change";
      }
    }
  }
}

// A static set of which the same few objects move every frame (doors, platforms): the set's change
// list, the static trees' update and the frame allocate nothing once warmed up, rebuilding or
// following. (Moving ever more objects grows the delta tree, whose buffers then grow as vectors
// do: a few allocations, amortised, until main is rebuilt.)
TEST(Allocation, FramesWithMovingStaticObjectsAllocateNothing) {
#ifdef VISCD_VALIDATE
  GTEST_SKIP() << "VISCD_VALIDATE checks the tree every frame, whose diagnostics may allocate";
#endif
  const std::vector<Sphere> moving = test::random_spheres_by_half_extent(5000, 5, 60.0f, 0.2f, 1.0f);
  std::vector<Sphere> fixed = test::random_spheres_by_half_extent(20000, 6, 60.0f, 0.2f, 1.0f);
  for (const bool follow : {false, true}) {
    Config c;
    c.follow_change = follow;
    auto det = make_cpu_detector(c);
    ASSERT_TRUE(det->set_static_spheres(fixed).ok());
    FrameInput in;
    in.spheres = moving;
    FrameResult f;
    float shift = 0.01f;
    const auto [n, st] = steady_state_allocations([&] {
      shift = -shift;  // back and forth
      for (const std::uint32_t k : {17u, 7919u, 15000u}) {
        fixed[k].x += shift;
        if (Status s = det->move_static_sphere(k, fixed[k]); !s) return s;
      }
      return det->detect(in, f);
    });
    ASSERT_TRUE(st.ok()) << st.error();
    EXPECT_EQ(n, 0) << n << " allocations in four frames after static objects moved, follow_change " << follow;
  }
}

TEST(Allocation, CounterSeesAllocations) {
  // The instrument works: a vector of 1000 ints allocates.
  const long n = allocations_during([] {
    std::vector<int> v(1000);
    (void)v;
  });
  EXPECT_GE(n, 1);
}

}  // namespace
}  // namespace viscd
