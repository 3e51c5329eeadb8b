// A Bullet world on viscd's broadphase: a pile of spheres and boxes falls into a walled bin with
// pillars. The one line that differs from a stock Bullet program is the broadphase's type
// (docs/adapters.md). Built and run by the tests (ctest -R example.bullet_world); it prints
// "bullet_world: ok" when every body came to rest inside the bin, above its floor.
#include <btBulletDynamicsCommon.h>
#include <viscd/bullet.hpp>

#include <chrono>
#include <cstdio>
#include <memory>
#include <utility>
#include <vector>

namespace {

constexpr float kHalfWidth = 6;   // the bin's inner half width (x and z), metres
constexpr float kWallHeight = 8;  // walls from y = 0 to 8
constexpr int kLayers = 12, kPerSide = 6;

}  // namespace

int main() {
  btDefaultCollisionConfiguration configuration;
  btCollisionDispatcher dispatcher(&configuration);
  viscd::BulletBroadphase broadphase;  // instead of btDbvtBroadphase broadphase;
  btSequentialImpulseConstraintSolver solver;
  btDiscreteDynamicsWorld world(&dispatcher, &broadphase, &solver, &configuration);
  world.setGravity(btVector3(0, -9.81f, 0));

  std::vector<std::unique_ptr<btCollisionShape>> shapes;
  std::vector<std::unique_ptr<btDefaultMotionState>> motions;
  std::vector<std::unique_ptr<btRigidBody>> bodies;
  const auto add_body = [&](btCollisionShape* shape, const btVector3& at, float mass) {
    btVector3 inertia(0, 0, 0);
    if (mass > 0) shape->calculateLocalInertia(mass, inertia);
    btTransform transform;
    transform.setIdentity();
    transform.setOrigin(at);
    motions.push_back(std::make_unique<btDefaultMotionState>(transform));
    btRigidBody::btRigidBodyConstructionInfo info(mass, motions.back().get(), shape, inertia);
    info.m_friction = 0.6f;
    bodies.push_back(std::make_unique<btRigidBody>(info));
    world.addRigidBody(bodies.back().get());  // static bodies (mass 0) go to viscd's static set
    return bodies.back().get();
  };
  const auto keep = [&](std::unique_ptr<btCollisionShape> shape) {
    shapes.push_back(std::move(shape));
    return shapes.back().get();
  };
  const auto box_shape = [&](float x, float y, float z) {
    return keep(std::make_unique<btBoxShape>(btVector3(x, y, z)));
  };

  // The bin: a floor (top at y = 0), four walls, four pillars inside.
  add_body(box_shape(kHalfWidth + 1, 0.5f, kHalfWidth + 1), btVector3(0, -0.5f, 0), 0);
  btCollisionShape* wall_x = box_shape(0.5f, kWallHeight / 2, kHalfWidth + 1);
  btCollisionShape* wall_z = box_shape(kHalfWidth + 1, kWallHeight / 2, 0.5f);
  add_body(wall_x, btVector3(kHalfWidth + 0.5f, kWallHeight / 2, 0), 0);
  add_body(wall_x, btVector3(-kHalfWidth - 0.5f, kWallHeight / 2, 0), 0);
  add_body(wall_z, btVector3(0, kWallHeight / 2, kHalfWidth + 0.5f), 0);
  add_body(wall_z, btVector3(0, kWallHeight / 2, -kHalfWidth - 0.5f), 0);
  btCollisionShape* pillar = box_shape(0.4f, 2.5f, 0.4f);
  for (const float x : {-2.5f, 2.5f})
    for (const float z : {-2.5f, 2.5f}) add_body(pillar, btVector3(x, 2.5f, z), 0);
  const std::size_t fixed = bodies.size();

  // The pile: layers of spheres and boxes, alternating, dropped from 6 m up.
  btCollisionShape* sphere = keep(std::make_unique<btSphereShape>(0.35f));
  btCollisionShape* cube = box_shape(0.3f, 0.3f, 0.3f);
  const float spacing = 2 * (kHalfWidth - 0.6f) / (kPerSide - 1);
  for (int layer = 0; layer < kLayers; ++layer)
    for (int i = 0; i < kPerSide; ++i)
      for (int k = 0; k < kPerSide; ++k) {
        const btVector3 at(-kHalfWidth + 0.6f + spacing * static_cast<float>(i) + 0.05f * static_cast<float>(layer % 3),
                           6 + 0.9f * static_cast<float>(layer), -kHalfWidth + 0.6f + spacing * static_cast<float>(k));
        add_body((i + k + layer) % 2 ? sphere : cube, at, 1);
      }
  std::printf("bullet_world: %zu bodies (%zu static), %zu proxies in viscd's static set\n", bodies.size(), fixed,
              broadphase.static_proxy_count());

  const auto start = std::chrono::steady_clock::now();
  const int steps = 360;  // 6 s at 60 Hz
  for (int step = 1; step <= steps; ++step) {
    world.stepSimulation(1.0f / 60, 1, 1.0f / 60);
    if (!broadphase.last_status()) {
      std::printf("bullet_world: viscd failed: %s\n", broadphase.last_status().error().c_str());
      return 1;
    }
    if (step % 60 == 0)
      std::printf("t = %d s: %d pairs in the cache, %d manifolds\n", step / 60,
                  broadphase.getOverlappingPairCache()->getNumOverlappingPairs(), dispatcher.getNumManifolds());
  }
  const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();

  int outside = 0;
  for (std::size_t b = fixed; b < bodies.size(); ++b) {
    const btVector3 p = bodies[b]->getCenterOfMassPosition();
    if (p.y() < 0 || p.y() > kWallHeight + 10 || btFabs(p.x()) > kHalfWidth || btFabs(p.z()) > kHalfWidth) ++outside;
  }
  std::printf("bullet_world: %d steps in %.0f ms, %d bodies outside the bin or below its floor\n", steps, ms, outside);
  for (auto& body : bodies) world.removeRigidBody(body.get());
  if (outside != 0) return 1;
  std::printf("bullet_world: ok\n");
  return 0;
}
