#pragma once
// The branch-free 16-lane tests of the cpu broadphase's stage 8, for two instruction sets chosen
// at run time: SSE2 (every x86-64; 4 steps of 4 lanes) and AVX-512 (1 step of 16 lanes). Other
// machines get the scalar loops. Each kernel is a static member of an instruction-set struct; code
// that runs the AVX-512 kernels is instantiated with that struct inside a function compiled for
// AVX-512 (VISCD_AVX512_FLATTEN: everything it calls is inlined into it), and is only entered
// when the detector's level (Config::simd, simd_level_for()) is AVX-512 and the CPU has it. Nothing
// is compiled for AVX-512 outside such functions. The same level picks the rasterizer's kernels
// (cpu/raster_tile.hpp), built the same way.
//
// The ray queries' slab tests against 16 lanes or 16 children (ray_lanes(), ray_children(), at the
// end) are here too; they run in double, two lanes at a time with SSE2 (every x86-64 has it), so
// they are compiled for the baseline and not dispatched.
//
// Exactness: sphere_lanes() performs overlap_exact()'s float operations in its order (sub, mul,
// add, no FMA: the library is compiled with -ffp-contract=off), and every comparison is an
// ordered <=, false on NaN, as in C++. So each level gives the same bits as the scalar test.

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "core/geometry.hpp"
#include "viscd/types.hpp"

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define VISCD_HAVE_AVX512 1
#include <immintrin.h>
#define VISCD_AVX512_TARGET __attribute__((target("avx512f")))
#define VISCD_AVX512_FLATTEN __attribute__((target("avx512f"), flatten))
#else
#define VISCD_HAVE_AVX512 0
#endif

#include "viscd/config.hpp"

namespace viscd::detail {

enum class SimdLevel { scalar, sse2, avx512 };

/// The best level this CPU (and build) has.
[[nodiscard]] SimdLevel best_simd_level();
/// The level a detector uses: `wanted` (Config::simd), or the best this CPU has when that is lower.
[[nodiscard]] SimdLevel simd_level_for(Simd wanted);
/// `wanted`, or the best this CPU has when that is lower.
[[nodiscard]] SimdLevel usable_simd_level(SimdLevel wanted);
[[nodiscard]] const char* simd_name(SimdLevel level);

/// 16 lanes of spheres (x, y, z, r) and their conservative half extents h, as arrays of 16.
/// Lanes with NaN centres (and h) pass no test.
template <class L>
concept Lanes16 = requires(const L& l) {
  l.x[15];
  l.y[15];
  l.z[15];
  l.r[15];
  l.h[15];
};

struct SimdScalar {
  /// Bit l set when the sphere (x, y, z, r) passes overlap_exact() with lane l.
  template <Lanes16 L>
  static std::uint32_t sphere_lanes(const L& b, float x, float y, float z, float r) {
    std::uint32_t mask = 0;
    for (std::uint32_t l = 0; l < 16; ++l) {
      const float dx = x - b.x[l], dy = y - b.y[l], dz = z - b.z[l];
      const float s = r + b.r[l];
      mask |= static_cast<std::uint32_t>(dx * dx + dy * dy + dz * dz <= s * s) << l;
    }
    return mask;
  }
  /// Bit l set when lane l's conservative box (centre -/+ h) overlaps `box`.
  template <Lanes16 L>
  static std::uint32_t box_lanes(const L& b, const Aabb& box) {
    std::uint32_t mask = 0;
    for (std::uint32_t l = 0; l < 16; ++l) {
      const float h = b.h[l];
      const bool o = (b.x[l] - h <= box.hi.x) & (box.lo.x <= b.x[l] + h) & (b.y[l] - h <= box.hi.y) &
                     (box.lo.y <= b.y[l] + h) & (b.z[l] - h <= box.hi.z) & (box.lo.z <= b.z[l] + h);
      mask |= static_cast<std::uint32_t>(o) << l;
    }
    return mask;
  }
  /// Bit l set when the box (lo_x[l] .. hi_z[l]) overlaps `box` by overlaps().
  template <class N>
  static std::uint32_t node_children(const N& n, const Aabb& box) {
    std::uint32_t mask = 0;
    for (std::uint32_t l = 0; l < 16; ++l) {
      const bool o = (n.lo_x[l] <= box.hi.x) & (box.lo.x <= n.hi_x[l]) & (n.lo_y[l] <= box.hi.y) &
                     (box.lo.y <= n.hi_y[l]) & (n.lo_z[l] <= box.hi.z) & (box.lo.z <= n.hi_z[l]);
      mask |= static_cast<std::uint32_t>(o) << l;
    }
    return mask;
  }
};

#if defined(__SSE2__)
struct SimdSse2 {
  template <Lanes16 L>
  static std::uint32_t sphere_lanes(const L& b, float x, float y, float z, float r) {
    const __m128 px = _mm_set1_ps(x), py = _mm_set1_ps(y), pz = _mm_set1_ps(z), pr = _mm_set1_ps(r);
    std::uint32_t mask = 0;
    for (std::uint32_t l = 0; l < 16; l += 4) {
      const __m128 dx = _mm_sub_ps(px, _mm_loadu_ps(b.x + l));
      const __m128 dy = _mm_sub_ps(py, _mm_loadu_ps(b.y + l));
      const __m128 dz = _mm_sub_ps(pz, _mm_loadu_ps(b.z + l));
      const __m128 s = _mm_add_ps(pr, _mm_loadu_ps(b.r + l));
      const __m128 d2 = _mm_add_ps(_mm_add_ps(_mm_mul_ps(dx, dx), _mm_mul_ps(dy, dy)), _mm_mul_ps(dz, dz));
      mask |= static_cast<std::uint32_t>(_mm_movemask_ps(_mm_cmple_ps(d2, _mm_mul_ps(s, s)))) << l;
    }
    return mask;
  }
  template <Lanes16 L>
  static std::uint32_t box_lanes(const L& b, const Aabb& box) {
    std::uint32_t mask = 0;
    for (std::uint32_t l = 0; l < 16; l += 4) {
      const __m128 h = _mm_loadu_ps(b.h + l);
      const __m128 x = _mm_loadu_ps(b.x + l), y = _mm_loadu_ps(b.y + l), z = _mm_loadu_ps(b.z + l);
      mask |= boxes4(_mm_sub_ps(x, h), _mm_sub_ps(y, h), _mm_sub_ps(z, h), _mm_add_ps(x, h), _mm_add_ps(y, h),
                     _mm_add_ps(z, h), box)
              << l;
    }
    return mask;
  }
  template <class N>
  static std::uint32_t node_children(const N& n, const Aabb& box) {
    std::uint32_t mask = 0;
    for (std::uint32_t l = 0; l < 16; l += 4)
      mask |= boxes4(_mm_loadu_ps(n.lo_x + l), _mm_loadu_ps(n.lo_y + l), _mm_loadu_ps(n.lo_z + l),
                     _mm_loadu_ps(n.hi_x + l), _mm_loadu_ps(n.hi_y + l), _mm_loadu_ps(n.hi_z + l), box)
              << l;
    return mask;
  }

 private:
  // Bit l set when box l of four overlaps `box` (overlaps(): closed intervals).
  static std::uint32_t boxes4(__m128 lx, __m128 ly, __m128 lz, __m128 hx, __m128 hy, __m128 hz, const Aabb& box) {
    const __m128 ox = _mm_and_ps(_mm_cmple_ps(lx, _mm_set1_ps(box.hi.x)), _mm_cmple_ps(_mm_set1_ps(box.lo.x), hx));
    const __m128 oy = _mm_and_ps(_mm_cmple_ps(ly, _mm_set1_ps(box.hi.y)), _mm_cmple_ps(_mm_set1_ps(box.lo.y), hy));
    const __m128 oz = _mm_and_ps(_mm_cmple_ps(lz, _mm_set1_ps(box.hi.z)), _mm_cmple_ps(_mm_set1_ps(box.lo.z), hz));
    return static_cast<std::uint32_t>(_mm_movemask_ps(_mm_and_ps(_mm_and_ps(ox, oy), oz)));
  }
};
/// The kernels code uses when it is not dispatched (queries, and the build of the default path).
using SimdBaseline = SimdSse2;
#else
using SimdBaseline = SimdScalar;
#endif

#if VISCD_HAVE_AVX512
struct SimdAvx512 {
  template <Lanes16 L>
  VISCD_AVX512_TARGET static std::uint32_t sphere_lanes(const L& b, float x, float y, float z, float r) {
    const __m512 dx = _mm512_sub_ps(_mm512_set1_ps(x), _mm512_loadu_ps(b.x));
    const __m512 dy = _mm512_sub_ps(_mm512_set1_ps(y), _mm512_loadu_ps(b.y));
    const __m512 dz = _mm512_sub_ps(_mm512_set1_ps(z), _mm512_loadu_ps(b.z));
    const __m512 s = _mm512_add_ps(_mm512_set1_ps(r), _mm512_loadu_ps(b.r));
    const __m512 d2 = _mm512_add_ps(_mm512_add_ps(_mm512_mul_ps(dx, dx), _mm512_mul_ps(dy, dy)), _mm512_mul_ps(dz, dz));
    return _mm512_cmp_ps_mask(d2, _mm512_mul_ps(s, s), _CMP_LE_OQ);
  }
  template <Lanes16 L>
  VISCD_AVX512_TARGET static std::uint32_t box_lanes(const L& b, const Aabb& box) {
    const __m512 h = _mm512_loadu_ps(b.h);
    const __m512 x = _mm512_loadu_ps(b.x), y = _mm512_loadu_ps(b.y), z = _mm512_loadu_ps(b.z);
    return boxes16(_mm512_sub_ps(x, h), _mm512_sub_ps(y, h), _mm512_sub_ps(z, h), _mm512_add_ps(x, h),
                   _mm512_add_ps(y, h), _mm512_add_ps(z, h), box);
  }
  template <class N>
  VISCD_AVX512_TARGET static std::uint32_t node_children(const N& n, const Aabb& box) {
    return boxes16(_mm512_loadu_ps(n.lo_x), _mm512_loadu_ps(n.lo_y), _mm512_loadu_ps(n.lo_z), _mm512_loadu_ps(n.hi_x),
                   _mm512_loadu_ps(n.hi_y), _mm512_loadu_ps(n.hi_z), box);
  }

 private:
  // Bit l set when box l overlaps `box` (overlaps(): closed intervals).
  VISCD_AVX512_TARGET static std::uint32_t boxes16(__m512 lx, __m512 ly, __m512 lz, __m512 hx, __m512 hy, __m512 hz,
                                                   const Aabb& box) {
    __mmask16 m = _mm512_cmp_ps_mask(lx, _mm512_set1_ps(box.hi.x), _CMP_LE_OQ);
    m = _mm512_mask_cmp_ps_mask(m, _mm512_set1_ps(box.lo.x), hx, _CMP_LE_OQ);
    m = _mm512_mask_cmp_ps_mask(m, ly, _mm512_set1_ps(box.hi.y), _CMP_LE_OQ);
    m = _mm512_mask_cmp_ps_mask(m, _mm512_set1_ps(box.lo.y), hy, _CMP_LE_OQ);
    m = _mm512_mask_cmp_ps_mask(m, lz, _mm512_set1_ps(box.hi.z), _CMP_LE_OQ);
    return _mm512_mask_cmp_ps_mask(m, _mm512_set1_ps(box.lo.z), hz, _CMP_LE_OQ);
  }
};
#endif

// ---- ray queries: slab tests in double, two lanes at a time with SSE2 ----

// A ray prepared for slab tests against boxes widened by ray_box_margin(), in double (see there).
// Along an axis the widened slab [lo - margin, hi + margin] is entered at (lo - (o + margin)) / d
// and left at (hi - (o - margin)) / d for d > 0 (the other way round for d < 0); along an axis
// with d = 0 the origin must lie in the slab.
struct RaySetup {
  double lo_shift[3], hi_shift[3], inv[3];  // o + margin, o - margin, 1 / d
  bool flat[3], negative[3];
  /// `extra`: a further widening, for trees whose boxes are the objects' own (box frames).
  explicit RaySetup(const Ray& r, double extra = 0) {
    const double margin = ray_box_margin(r.origin) + extra;
    for (int k = 0; k < 3; ++k) {
      lo_shift[k] = double{r.origin[k]} + margin;
      hi_shift[k] = double{r.origin[k]} - margin;
      flat[k] = r.dir[k] == 0;
      negative[k] = r.dir[k] < 0;
      inv[k] = flat[k] ? 0.0 : 1.0 / double{r.dir[k]};
    }
  }
};

// Where the segment t in [0, t_hi] enters the widened box; false when it misses it.
// (Used by the builds without SSE2; the SSE2 ones test two boxes at a time with slab2().)
[[maybe_unused]] inline bool ray_box(const RaySetup& q, const Aabb& b, double t_hi, double& t_enter) {
  const float lo[3] = {b.lo.x, b.lo.y, b.lo.z}, hi[3] = {b.hi.x, b.hi.y, b.hi.z};
  double t0 = 0, t1 = t_hi;
  for (int k = 0; k < 3; ++k) {
    const double a = (double{lo[k]} - q.lo_shift[k]) * q.inv[k], c = (double{hi[k]} - q.hi_shift[k]) * q.inv[k];
    if (q.flat[k]) {
      if (double{lo[k]} > q.lo_shift[k] || double{hi[k]} < q.hi_shift[k]) return false;
    } else {
      t0 = std::max(t0, q.negative[k] ? c : a);
      t1 = std::min(t1, q.negative[k] ? a : c);
    }
  }
  t_enter = t0;
  return t0 <= t1;
}

#if defined(__SSE2__)
// One axis of the slab test of ray_box() on two boxes at once ([lo, hi] per lane, in double):
// narrows [t0, t1], or along an axis the ray does not move, clears `inside` where the origin
// lies outside the widened slab.
inline void slab2(const RaySetup& q, int k, __m128d lo, __m128d hi, __m128d& t0, __m128d& t1, __m128d& inside) {
  if (q.flat[k]) {
    inside = _mm_and_pd(
        inside, _mm_and_pd(_mm_cmple_pd(lo, _mm_set1_pd(q.lo_shift[k])), _mm_cmpge_pd(hi, _mm_set1_pd(q.hi_shift[k]))));
    return;
  }
  const __m128d inv = _mm_set1_pd(q.inv[k]);
  const __m128d a = _mm_mul_pd(_mm_sub_pd(lo, _mm_set1_pd(q.lo_shift[k])), inv);
  const __m128d e = _mm_mul_pd(_mm_sub_pd(hi, _mm_set1_pd(q.hi_shift[k])), inv);
  t0 = _mm_max_pd(t0, q.negative[k] ? e : a);
  t1 = _mm_min_pd(t1, q.negative[k] ? a : e);
}

// Two floats into two doubles (the 64-bit load reads through a may_alias type).
inline __m128d two_doubles(const float* f) {
  return _mm_cvtps_pd(_mm_castsi128_ps(_mm_loadl_epi64(reinterpret_cast<const __m128i*>(f))));
}
#endif

// The lanes of a bucket whose conservative boxes (centre -/+ h, in double) the segment t in
// [0, t_hi] meets, widened as ray_box(): only those need the exact test. Padding lanes (NaN) fail.
template <Lanes16 L>
inline std::uint32_t ray_lanes(const RaySetup& q, const L& b, double t_hi) {
  std::uint32_t mask = 0;
#if defined(__SSE2__)
  const float* axis[3] = {b.x, b.y, b.z};
  for (std::uint32_t l = 0; l < 16; l += 2) {
    const __m128d h = two_doubles(b.h + l);
    __m128d t0 = _mm_setzero_pd(), t1 = _mm_set1_pd(t_hi);
    __m128d inside = _mm_cmpeq_pd(h, h);  // all set, but NaN lanes clear
    for (int k = 0; k < 3; ++k) {
      const __m128d c = two_doubles(axis[k] + l);
      slab2(q, k, _mm_sub_pd(c, h), _mm_add_pd(c, h), t0, t1, inside);
    }
    mask |= static_cast<std::uint32_t>(_mm_movemask_pd(_mm_and_pd(inside, _mm_cmple_pd(t0, t1)))) << l;
  }
#else
  for (std::uint32_t l = 0; l < 16; ++l) {
    const float h = b.h[l];
    const Aabb box{{b.x[l] - h, b.y[l] - h, b.z[l] - h}, {b.x[l] + h, b.y[l] + h, b.z[l] + h}};
    double te = 0;
    if (!std::isnan(h) && ray_box(q, box, t_hi, te)) mask |= 1u << l;
  }
#endif
  return mask;
}

// The children of a wide node whose boxes the segment t in [0, t_hi] meets, widened as ray_box();
// t_enter[l] is where it enters child l's box (set for every lane). Empty children fail.
template <class N>
inline std::uint32_t ray_children(const RaySetup& q, const N& n, double t_hi, double* t_enter) {
  std::uint32_t mask = 0;
#if defined(__SSE2__)
  const float* lo_axis[3] = {n.lo_x, n.lo_y, n.lo_z};
  const float* hi_axis[3] = {n.hi_x, n.hi_y, n.hi_z};
  for (std::uint32_t l = 0; l < 16; l += 2) {
    __m128d t0 = _mm_setzero_pd(), t1 = _mm_set1_pd(t_hi);
    __m128d inside = _mm_castsi128_pd(_mm_set1_epi32(-1));
    for (int k = 0; k < 3; ++k) slab2(q, k, two_doubles(lo_axis[k] + l), two_doubles(hi_axis[k] + l), t0, t1, inside);
    _mm_storeu_pd(t_enter + l, t0);
    mask |= static_cast<std::uint32_t>(_mm_movemask_pd(_mm_and_pd(inside, _mm_cmple_pd(t0, t1)))) << l;
  }
#else
  for (std::uint32_t l = 0; l < 16; ++l)
    if (ray_box(q, n.child(l), t_hi, t_enter[l])) mask |= 1u << l;
#endif
  return mask;
}

#if VISCD_HAVE_AVX512
// ray_children() eight children at a time in double (AVX-512F), the same operations in the same
// order per lane, so both give the same mask and entry points; NaN and empty children fail alike.
template <class N>
VISCD_AVX512_TARGET inline std::uint32_t ray_children_avx512(const RaySetup& q, const N& n, double t_hi,
                                                             double* t_enter) {
  std::uint32_t mask = 0;
  const float* lo_axis[3] = {n.lo_x, n.lo_y, n.lo_z};
  const float* hi_axis[3] = {n.hi_x, n.hi_y, n.hi_z};
  for (std::uint32_t l = 0; l < 16; l += 8) {
    __m512d t0 = _mm512_setzero_pd(), t1 = _mm512_set1_pd(t_hi);
    __mmask8 inside = 0xFF;
    for (int k = 0; k < 3; ++k) {
      // The zero-masked forms (all lanes kept): GCC 12 warns of its own undefined operand in the
      // plain ones.
      const __m512d lo = _mm512_maskz_cvtps_pd(0xFF, _mm256_loadu_ps(lo_axis[k] + l));
      const __m512d hi = _mm512_maskz_cvtps_pd(0xFF, _mm256_loadu_ps(hi_axis[k] + l));
      if (q.flat[k]) {
        inside = _mm512_mask_cmp_pd_mask(inside, lo, _mm512_set1_pd(q.lo_shift[k]), _CMP_LE_OQ);
        inside = _mm512_mask_cmp_pd_mask(inside, hi, _mm512_set1_pd(q.hi_shift[k]), _CMP_GE_OQ);
        continue;
      }
      const __m512d inv = _mm512_set1_pd(q.inv[k]);
      const __m512d a = _mm512_mul_pd(_mm512_sub_pd(lo, _mm512_set1_pd(q.lo_shift[k])), inv);
      const __m512d e = _mm512_mul_pd(_mm512_sub_pd(hi, _mm512_set1_pd(q.hi_shift[k])), inv);
      // max/min return their second operand when one is NaN, as SSE2's do: NaN lanes stay NaN.
      t0 = _mm512_maskz_max_pd(0xFF, t0, q.negative[k] ? e : a);
      t1 = _mm512_maskz_min_pd(0xFF, t1, q.negative[k] ? a : e);
    }
    _mm512_storeu_pd(t_enter + l, t0);
    mask |= static_cast<std::uint32_t>(_mm512_mask_cmp_pd_mask(inside, t0, t1, _CMP_LE_OQ)) << l;
  }
  return mask;
}
#endif

}  // namespace viscd::detail
