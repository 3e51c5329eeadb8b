// The cpu backend allocates nothing per frame once warmed up (no allocation per frame after the
// first): global operator new is counted between two points of a test.
#include <gtest/gtest.h>

#include <atomic>
#include <cstdlib>
#include <functional>
#include <new>

#include "test_util.hpp"
#include "viscd/executor.hpp"
#include "viscd/scene.hpp"

// This file replaces the global operator new/delete with malloc/free, consistently; GCC 12 still
// flags the pairing (it treats new as builtin), so its check is off here only.
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"

namespace {
std::atomic<bool> g_counting{false};
std::atomic<long> g_allocations{0};
}  // namespace

void* operator new(std::size_t size) {
  if (g_counting.load(std::memory_order_relaxed)) g_allocations.fetch_add(1, std::memory_order_relaxed);
  if (void* p = std::malloc(size ? size : 1)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
// The array and nothrow forms too: this file shares its test binary with others, and memory from
// the sanitizer's own forms must not reach free() through the replaced deletes.
void* operator new[](std::size_t size) { return ::operator new(size); }
void* operator new(std::size_t size, const std::nothrow_t&) noexcept {  // std::stable_sort's buffer
  if (g_counting.load(std::memory_order_relaxed)) g_allocations.fetch_add(1, std::memory_order_relaxed);
  return std::malloc(size ? size : 1);
}
void operator delete(void* p, const std::nothrow_t&) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }

namespace viscd {
namespace {

long allocations_during(const std::function<void()>& f) {
  g_allocations = 0;
  g_counting = true;
  f();
  g_counting = false;
  return g_allocations.load();
}

TEST(Allocation, SteadyStateFramesAllocateNothing) {
#ifdef VISCD_VALIDATE
  GTEST_SKIP() << "VISCD_VALIDATE runs validate_lbvh every frame, which allocates by design";
#endif
  Scene scene = Scene::make({.objects = 20000});
  const Camera cam = camera_preset("zoom-out", scene, 640, 360).value();
  SerialExecutor serial;
  for (const bool with_camera : {false, true}) {
    for (Bits bits : {Bits::adaptive, Bits::b16, Bits::b64}) {
      Config c;
      c.bits = bits;
      c.shade = with_camera;
      // The caller's executor on one of the runs, viscd's pool on the others.
      if (bits == Bits::b16) c.executor = &serial;
      auto det = make_cpu_detector(c);
      FrameResult f;
      // Warm up: the first frames size every buffer (pair counts vary a little as objects move).
      for (int k = 0; k < 3; ++k) {
        scene.step(1.0f / 60.0f);
        ASSERT_TRUE(det->detect(scene.spheres(), with_camera ? &cam : nullptr, f).ok());
      }
      // Several frames: each sorts from the last frame's order (the broadphase's steady path).
      Status st;
      const long n = allocations_during([&] {
        for (int k = 0; k < 4 && st.ok(); ++k) {
          scene.step(1.0f / 60.0f);
          st = det->detect(scene.spheres(), with_camera ? &cam : nullptr, f);
        }
      });
      ASSERT_TRUE(st.ok()) << st.error();
      EXPECT_EQ(n, 0) << "allocations in a steady-state frame, camera " << with_camera << ", m "
                      << static_cast<int>(bits);
    }
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
