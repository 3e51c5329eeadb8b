// A game loop that hands viscd its objects and camera every frame and reads the pairs back.
// Built in CI against an installed viscd through find_package (tests/install/). docs/embedding.md
#include <viscd/viscd.hpp>

#include <cmath>
#include <cstdio>
#include <vector>

int main() {
  // Your engine's objects: here 20 000 spheres on a ring, moving in circles.
  viscd::Scene world = viscd::Scene::make({.kind = viscd::SceneKind::ring, .objects = 20000});

  viscd::Config config;  // the paper's defaults: lambda = 200 px, adaptive 16/32/64-bit codes
  config.lambda = 100;   // cull objects covering fewer than 100 screen pixels
  auto detector = viscd::make_cpu_detector(config);  // or make_gl_detector(config) for the GPU
  viscd::FrameResult frame;                          // reused every frame: no allocations once warmed up

  for (int tick = 0; tick < 120; ++tick) {
    world.step(1.0f / 60.0f);  // your physics moves the objects
    viscd::Camera camera;      // your camera, as eye/target/up + projection + screen size
    const float angle = 0.01f * static_cast<float>(tick);
    const float r = world.world_radius(), c = std::cos(angle), s = std::sin(angle);
    camera.eye[0] = 1.15f * r * c, camera.eye[1] = 0.14f * r, camera.eye[2] = 1.15f * r * s;
    camera.target[0] = 0.3f * r * c, camera.target[1] = 0, camera.target[2] = 0.3f * r * s;
    camera.far_plane = 4 * r;

    if (viscd::Status s = detector->detect(world.spheres(), &camera, frame); !s) {
      std::fprintf(stderr, "collision detection failed: %s\n", s.error().c_str());
      return 1;
    }
    for (const viscd::Pair& p : frame.pairs) {
      (void)p;  // resolve the contact between objects p.i and p.j (p.i < p.j)
    }
    if (tick % 40 == 0)
      std::printf("tick %3d: %u of %u objects visible enough, %llu pairs, %d-bit codes %s\n", tick, frame.stats.active,
                  frame.stats.objects, static_cast<unsigned long long>(frame.stats.pairs), frame.stats.bits,
                  frame.stats.layout.c_str());
  }
  return 0;
}
