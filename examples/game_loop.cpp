// A game loop that hands viscd its objects and camera every frame and reads the pairs back.
// Built in CI against an installed viscd through find_package (tests/install/). docs/embedding.md
// It links viscd::viscd alone: the objects and their motion are the example's own.
#include <viscd/viscd.hpp>

#include <cmath>
#include <cstddef>
#include <cstdio>
#include <numbers>
#include <random>
#include <vector>

namespace {

// Your engine's objects: here 20 000 spheres of radius 0.25 to 0.75 in a flat ring (radius 75 to
// 150, 6 units thick), each circling the vertical axis at its own speed.
struct Ring {
  static constexpr float kInner = 75, kOuter = 150, kHalfHeight = 3;
  std::vector<viscd::Sphere> spheres;
  std::vector<float> rho, theta, omega;  // distance from the axis, angle, angular speed

  explicit Ring(std::size_t objects) : spheres(objects), rho(objects), theta(objects), omega(objects) {
    std::mt19937 rng(1);
    std::uniform_real_distribution<float> unit(0.0f, 1.0f);
    for (std::size_t k = 0; k < objects; ++k) {
      rho[k] = std::sqrt(kInner * kInner + (kOuter * kOuter - kInner * kInner) * unit(rng));  // even over the area
      theta[k] = 2 * std::numbers::pi_v<float> * unit(rng);
      omega[k] = (1 + 4 * unit(rng)) / rho[k];  // 1 to 5 units per second
      spheres[k].y = kHalfHeight * (2 * unit(rng) - 1);
      spheres[k].r = 0.25f + 0.5f * unit(rng);
    }
    step(0);
  }
  void step(float dt) {  // your physics moves the objects
    for (std::size_t k = 0; k < spheres.size(); ++k) {
      theta[k] += omega[k] * dt;
      spheres[k].x = rho[k] * std::cos(theta[k]);
      spheres[k].z = rho[k] * std::sin(theta[k]);
    }
  }
};

}  // namespace

int main() {
  Ring world(20000);

  viscd::Config config;  // the paper's defaults: lambda = 200 px, adaptive 16/32/64-bit codes
  config.lambda = 100;   // cull objects covering fewer than 100 screen pixels
  auto detector = viscd::make_cpu_detector(config);  // or make_gl_detector(config) for the GPU
  viscd::FrameResult frame;                          // reused every frame: no allocations once warmed up

  for (int tick = 0; tick < 120; ++tick) {
    world.step(1.0f / 60.0f);
    viscd::Camera camera;  // your camera, as eye/target/up + projection + screen size
    const float angle = 0.01f * static_cast<float>(tick);
    const float r = Ring::kOuter, c = std::cos(angle), s = std::sin(angle);
    camera.eye[0] = 1.15f * r * c, camera.eye[1] = 0.14f * r, camera.eye[2] = 1.15f * r * s;
    camera.target[0] = 0.3f * r * c, camera.target[1] = 0, camera.target[2] = 0.3f * r * s;
    camera.far_plane = 4 * r;

    if (viscd::Status status = detector->detect(world.spheres, &camera, frame); !status) {
      std::fprintf(stderr, "collision detection failed: %s\n", status.error().c_str());
      return 1;
    }
    for (const viscd::Pair& p : frame.pairs) {
      (void)p;  // resolve the contact between objects p.i and p.j (p.i < p.j)
    }
    if (tick % 40 == 0)
      std::printf("tick %3d: %u of %u objects visible enough, %llu pairs, %d-bit codes %s\n", tick, frame.stats.active,
                  frame.stats.objects, static_cast<unsigned long long>(frame.stats.pairs), frame.stats.bits,
                  viscd::format_layout(frame.stats.layout).c_str());
  }
  return 0;
}
