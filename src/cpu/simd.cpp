#include "cpu/simd.hpp"

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

}  // namespace

SimdLevel best_simd_level() {
  static const SimdLevel best = detect();
  return best;
}

SimdLevel usable_simd_level(SimdLevel wanted) {
  const SimdLevel best = best_simd_level();
  return wanted < best ? wanted : best;
}

SimdLevel simd_level_for(Simd wanted) {
  switch (wanted) {
    case Simd::scalar:
      return usable_simd_level(SimdLevel::scalar);
    case Simd::sse2:
      return usable_simd_level(SimdLevel::sse2);
    case Simd::best:
      break;
  }
  return best_simd_level();
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
