#include "cpu/simd.hpp"

#include <atomic>
#include <cstdlib>
#include <cstring>

namespace viscd::detail {
namespace {

SimdLevel detect() {
#if VISCD_HAVE_AVX512
  __builtin_cpu_init();
  if (__builtin_cpu_supports("avx512f")) return SimdLevel::avx512;
#endif
#if defined(__SSE2__)
  return SimdLevel::sse2;
#else
  return SimdLevel::scalar;
#endif
}

SimdLevel from_environment(SimdLevel best) {
  const char* v = std::getenv("VISCD_SIMD");
  if (!v) return best;
  SimdLevel wanted = best;
  if (std::strcmp(v, "scalar") == 0) wanted = SimdLevel::scalar;
  if (std::strcmp(v, "sse2") == 0) wanted = SimdLevel::sse2;
  return wanted < best ? wanted : best;
}

std::atomic<SimdLevel>& level() {
  static std::atomic<SimdLevel> l{from_environment(best_simd_level())};
  return l;
}

}  // namespace

SimdLevel best_simd_level() {
  static const SimdLevel best = detect();
  return best;
}

SimdLevel simd_level() { return level().load(std::memory_order_relaxed); }

SimdLevel set_simd_level(SimdLevel wanted) {
  const SimdLevel best = best_simd_level();
  const SimdLevel use = wanted < best ? wanted : best;
  level().store(use, std::memory_order_relaxed);
  return use;
}

const char* simd_name(SimdLevel l) {
  switch (l) {
    case SimdLevel::scalar:
      return "scalar";
    case SimdLevel::sse2:
      return "sse2";
    case SimdLevel::avx512:
      return "avx512";
  }
  return "?";
}

}  // namespace viscd::detail
