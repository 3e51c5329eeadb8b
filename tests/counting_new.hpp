#pragma once
// Counts global operator new between two points of a test: this header REPLACES the global
// operator new and delete (every form, with malloc/free, consistently), so include it in exactly
// one source file of a test binary. The count covers every thread of the process.
#include <atomic>
#include <cstdlib>
#include <functional>
#include <new>

// GCC 12 flags the replaced new/delete pairing (it treats new as builtin); the pairing is
// consistent (malloc/free throughout), so its check is off where this header is included.
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"

namespace viscd::test {
inline std::atomic<bool> g_counting{false};
inline std::atomic<long> g_allocations{0};

/// Allocations (operator new, any form) while f runs.
inline long allocations_during(const std::function<void()>& f) {
  g_allocations = 0;
  g_counting = true;
  f();
  g_counting = false;
  return g_allocations.load();
}

/// A detector's steady state: frame() three times to warm up (the first frames size every buffer;
/// pair counts vary a little as objects move), then the allocations of four more. `status` is the
/// first failing frame's (then `allocations` counts only what ran), else ok.
template <class Frame>
auto steady_state_allocations(Frame&& frame) {
  struct Result {
    long allocations = 0;
    decltype(frame()) status;
  };
  Result r;
  for (int k = 0; k < 3; ++k)
    if (!(r.status = frame()).ok()) return r;
  r.allocations = allocations_during([&] {
    for (int k = 0; k < 4 && r.status.ok(); ++k) r.status = frame();
  });
  return r;
}
}  // namespace viscd::test

void* operator new(std::size_t size) {
  if (viscd::test::g_counting.load(std::memory_order_relaxed))
    viscd::test::g_allocations.fetch_add(1, std::memory_order_relaxed);
  if (void* p = std::malloc(size ? size : 1)) return p;
  throw std::bad_alloc();
}
void* operator new(std::size_t size, const std::nothrow_t&) noexcept {  // std::stable_sort's buffer
  if (viscd::test::g_counting.load(std::memory_order_relaxed))
    viscd::test::g_allocations.fetch_add(1, std::memory_order_relaxed);
  return std::malloc(size ? size : 1);
}
// The array forms too: the binary holds other tests, and memory from any form must come back
// through a matching delete (the sanitizers check).
void* operator new[](std::size_t size) { return ::operator new(size); }
void* operator new[](std::size_t size, const std::nothrow_t& t) noexcept { return ::operator new(size, t); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete(void* p, const std::nothrow_t&) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, const std::nothrow_t&) noexcept { std::free(p); }
