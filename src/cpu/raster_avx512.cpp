// The tile pass with AVX-512F: a sphere's rows in the tile, 16 pixels at a time (one vector for
// a rectangle up to 16 pixels wide in the tile, two for a wider one), hit() in one pass with
// masks. The operations are the SSE2 kernel's, lane for lane (sub, mul, add, sqrt, div, no FMA:
// the library is compiled with -ffp-contract=off), so both give the same bits. Called only when
// the detector's level (Config::simd) is avx512 and the CPU has it; nothing here runs on another CPU.

#include "cpu/raster_tile.hpp"

#if VISCD_HAVE_AVX512

#include <immintrin.h>

#include <algorithm>
#include <limits>

// GCC 12 takes the undefined pass-through operands inside some AVX-512 intrinsics (max, the
// reductions) for uninitialised variables.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif

namespace viscd::detail {
namespace {

constexpr int kT = kTileSide;
constexpr float kInf = std::numeric_limits<float>::infinity();

/// A sphere's hit() terms in every lane.
struct Lanes {
  __m512 ox, oy, oz, c, near_depth;
  __m512i id, slot;
};

/// hit() for the 16 pixels at `i`, kept where nearer than the pixel's best (ties to the smaller
/// id). A row of 16 in which no pixel can change (disc < 0, or best nearer than the sphere's near
/// bound) costs no square root or division. Returns the lanes that changed.
VISCD_AVX512_TARGET inline __mmask16 hit16(TileBuffers& buf, int i, const Lanes& s, __m512 near_plane,
                                           __m512 far_plane) {
  const __m512 vx = _mm512_loadu_ps(buf.dx + i), vy = _mm512_loadu_ps(buf.dy + i), vz = _mm512_loadu_ps(buf.dz + i);
  const __m512 va = _mm512_loadu_ps(buf.a + i), bb = _mm512_loadu_ps(buf.best + i);
  const __m512 b =
      _mm512_add_ps(_mm512_add_ps(_mm512_mul_ps(s.ox, vx), _mm512_mul_ps(s.oy, vy)), _mm512_mul_ps(s.oz, vz));
  const __m512 disc = _mm512_sub_ps(_mm512_mul_ps(b, b), _mm512_mul_ps(va, s.c));
  const __mmask16 real = _mm512_cmp_ps_mask(disc, _mm512_setzero_ps(), _CMP_GE_OQ);
  if (_mm512_mask_cmp_ps_mask(real, bb, s.near_depth, _CMP_GE_OQ) == 0) return 0;
  const __m512 sq = _mm512_maskz_sqrt_ps(real, disc);
  const __m512 nb =
      _mm512_castsi512_ps(_mm512_xor_si512(_mm512_castps_si512(b), _mm512_castps_si512(_mm512_set1_ps(-0.0f))));
  const __m512 t0 = _mm512_div_ps(_mm512_sub_ps(nb, sq), va);
  const __mmask16 in0 =
      _mm512_mask_cmp_ps_mask(_mm512_cmp_ps_mask(t0, near_plane, _CMP_GE_OQ), t0, far_plane, _CMP_LE_OQ);
  __m512 hv = t0;
  __mmask16 hit = real & in0;
  if ((real & ~in0) != 0) [[unlikely]] {  // the front root is clipped: the back one, if in range
    const __m512 t1 = _mm512_div_ps(_mm512_add_ps(nb, sq), va);
    const __mmask16 in1 =
        _mm512_mask_cmp_ps_mask(_mm512_cmp_ps_mask(t1, near_plane, _CMP_GE_OQ), t1, far_plane, _CMP_LE_OQ);
    hv = _mm512_mask_blend_ps(in0, t1, t0);
    hit = real & (in0 | in1);
  }
  const __m512i bi = _mm512_loadu_si512(buf.id + i);
  // ids < 2^31 (validate_spheres), so the signed compare orders them.
  const __mmask16 nearer = _mm512_mask_cmp_ps_mask(hit, hv, bb, _CMP_LT_OQ);
  const __mmask16 tie = _mm512_mask_cmplt_epi32_mask(_mm512_mask_cmp_ps_mask(hit, hv, bb, _CMP_EQ_OQ), s.id, bi);
  const __mmask16 better = nearer | tie;
  _mm512_mask_storeu_ps(buf.best + i, better, hv);
  _mm512_mask_storeu_epi32(buf.id + i, better, s.id);
  _mm512_mask_storeu_epi32(buf.slot + i, better, s.slot);
  return better;
}

/// Row r's rays (as CameraRig::dir() rounds them) and |dir|^2, in the sum order of hit().
VISCD_AVX512_TARGET inline void fill_rays16(const TileJob& job, TileBuffers& buf, int x0, int y0, int r) {
  const auto py = static_cast<std::size_t>(y0 + r);
  const __m512 ux = _mm512_set1_ps(job.row_x[py]), uy = _mm512_set1_ps(job.row_y[py]),
               uz = _mm512_set1_ps(job.row_z[py]);
  for (int i = 0; i < kT; i += 16) {
    const __m512 ex = _mm512_add_ps(_mm512_loadu_ps(job.col_x + x0 + i), ux),
                 ey = _mm512_add_ps(_mm512_loadu_ps(job.col_y + x0 + i), uy),
                 ez = _mm512_add_ps(_mm512_loadu_ps(job.col_z + x0 + i), uz);
    const int at = r * kT + i;
    _mm512_store_ps(buf.dx + at, ex);
    _mm512_store_ps(buf.dy + at, ey);
    _mm512_store_ps(buf.dz + at, ez);
    _mm512_store_ps(buf.a + at,
                    _mm512_add_ps(_mm512_add_ps(_mm512_mul_ps(ex, ex), _mm512_mul_ps(ey, ey)), _mm512_mul_ps(ez, ez)));
  }
}

/// The largest of the first `count` (a multiple of 32) depths.
VISCD_AVX512_TARGET inline float max_depth(const float* best, int count) {
  __m512 m0 = _mm512_load_ps(best), m1 = _mm512_load_ps(best + 16);
  for (int q = 32; q < count; q += 32) {
    m0 = _mm512_max_ps(m0, _mm512_load_ps(best + q));
    m1 = _mm512_max_ps(m1, _mm512_load_ps(best + q + 16));
  }
  return _mm512_reduce_max_ps(_mm512_max_ps(m0, m1));
}

}  // namespace

VISCD_AVX512_FLATTEN void raster_tile_avx512(const TileJob& job, std::uint32_t t) {
  const std::uint32_t* items = job.items + job.offset[t];
  const std::uint32_t m = job.offset[t + 1] - job.offset[t];
  if (m == 0) return write_background_tile(job, t);
  const CameraRig& cam = *job.cam;
  VisibilityMap& map = *job.map;
  const TileRect tr = tile_rect(job, t);
  const int x0 = tr.x0, y0 = tr.y0, x1 = tr.x1, y1 = tr.y1;
  const int w = x1 - x0, h = y1 - y0;
  const __m512 near_plane = _mm512_set1_ps(cam.near_plane), far_plane = _mm512_set1_ps(cam.far_plane);
  const std::uint32_t on_map = w == kT ? ~0u : (1u << w) - 1u;  // bit i: column i is on the map
  TileBuffers buf;
  {
    // best: +inf on the map, -inf beyond its edge (never hit, never the max). id needs no start
    // value: it is read only where slot is set, or compared where best is +inf or -inf, where
    // the depth alone decides.
    const __m512 first0 =
                     _mm512_mask_blend_ps(static_cast<__mmask16>(on_map), _mm512_set1_ps(-kInf), _mm512_set1_ps(kInf)),
                 first1 = _mm512_mask_blend_ps(static_cast<__mmask16>(on_map >> 16), _mm512_set1_ps(-kInf),
                                               _mm512_set1_ps(kInf));
    const __m512i zero = _mm512_setzero_si512();
    _mm512_store_si512(buf.pad, zero);
    for (int r = 0; r < h; ++r) {
      _mm512_store_ps(buf.best + r * kT, first0);
      _mm512_store_ps(buf.best + r * kT + 16, first1);
      _mm512_store_si512(buf.slot + r * kT, zero);
      _mm512_store_si512(buf.slot + r * kT + 16, zero);
    }
    if (job.occluder_ids != nullptr) {
      // An occluded pixel starts at the occluder's depth, with kOccluderId.
      const __m512i occluder_id = _mm512_set1_epi32(static_cast<int>(kOccluderId));
      for (int r = 0; r < h; ++r) {
        const std::size_t row = static_cast<std::size_t>(y0 + r) * static_cast<std::size_t>(map.width) + x0;
        for (int g = 0; g < kT; g += 16) {
          const auto lanes = static_cast<__mmask16>(on_map >> g);
          const __m512i ids = _mm512_maskz_loadu_epi32(lanes, job.occluder_ids + row + g);
          const __mmask16 occluded = _mm512_test_epi32_mask(ids, ids);
          float* best = buf.best + r * kT + g;
          _mm512_store_ps(best, _mm512_mask_loadu_ps(_mm512_load_ps(best), occluded, job.occluder_depth + row + g));
          _mm512_store_si512(buf.id + r * kT + g, occluder_id);
        }
      }
    }
  }
  std::uint32_t dirs_ready = 0;  // bit r: row r's rays are filled
  DepthCut cut;
  for (std::uint32_t j = 0; j < m; ++j) {
    const TiledRasterizer::Prepared& p = job.prep[items[j]];
    if (j + 1 < m) _mm_prefetch(reinterpret_cast<const char*>(&job.prep[items[j + 1]]), _MM_HINT_T0);
    if (cut.stale(j)) cut.refresh(max_depth(buf.best, h * kT));
    const DepthCut::Verdict verdict = cut.verdict(j, p);
    if (verdict == DepthCut::Verdict::stop) break;
    if (verdict == DepthCut::Verdict::skip) continue;
    const Lanes lanes{_mm512_set1_ps(p.ox),
                      _mm512_set1_ps(p.oy),
                      _mm512_set1_ps(p.oz),
                      _mm512_set1_ps(p.c),
                      _mm512_set1_ps(p.near_depth),
                      _mm512_set1_epi32(static_cast<int>(p.id)),
                      _mm512_set1_epi32(static_cast<int>(j + 1))};
    const TileSpan span = tile_span(tr, p);
    const int ra = span.ra, rb = span.rb, ca = span.ca, cb = span.cb;
    for (std::uint32_t need = span.rows & ~dirs_ready; need; need &= need - 1)
      fill_rays16(job, buf, x0, y0, __builtin_ctz(need));
    dirs_ready |= span.rows;
    // The same window on every row: 16 pixels from min(ca, 16) when the rectangle fits, else the
    // whole row. Pixels of the window outside the rectangle are tested too (hit() misses them).
    __mmask16 any = 0;
    if (cb - ca <= 16) {
      const int wa = std::min(ca, kT - 16);
      for (int r = ra; r < rb; ++r) any |= hit16(buf, r * kT + wa, lanes, near_plane, far_plane);
    } else {
      for (int r = ra; r < rb; ++r)
        any |= static_cast<__mmask16>(hit16(buf, r * kT, lanes, near_plane, far_plane) |
                                      hit16(buf, r * kT + 16, lanes, near_plane, far_plane));
    }
    if (any) cut.changed();
  }

  // Write out row by row (background depth = far plane), and count the row's runs of equal
  // slots into the tile's counts (slot 0 is the background).
  TileCounts counts(job, t, m);
  const __m512 far_depth = _mm512_set1_ps(cam.far_plane);
  for (int r = 0; r < h; ++r) {
    const std::size_t row = static_cast<std::size_t>(y0 + r) * static_cast<std::size_t>(map.width) + x0;
    std::uint32_t* out_ids = map.ids.data() + row;
    float* out_depth = map.depth.data() + row;
    const float* best = buf.best + r * kT;
    const std::uint32_t* ids = buf.id + r * kT;
    const std::uint32_t* slots = buf.slot + r * kT;
    // Runs: bit i set where slot[i] differs from slot[i - 1] (bit 0 always).
    std::uint32_t starts = 1;
    // A whole row on whole cache lines (ids and depth are 64-byte aligned, so both rows reach a
    // line boundary together) is streamed past the caches: nothing reads the map again this
    // frame. Else the row is stored as usual, masked to the map.
    const bool stream = w == kT && (reinterpret_cast<std::uintptr_t>(out_ids) & 63) == 0;
    for (int g = 0; g < kT; g += 16) {
      const __m512i cur = _mm512_load_si512(slots + g);
      starts |= static_cast<std::uint32_t>(_mm512_cmpneq_epi32_mask(cur, _mm512_loadu_si512(slots + g - 1))) << g;
      const __mmask16 hit = _mm512_test_epi32_mask(cur, cur);
      const __m512i vi = _mm512_maskz_loadu_epi32(hit, ids + g);
      const __m512 vd = _mm512_mask_loadu_ps(far_depth, hit, best + g);
      if (stream) {
        _mm512_stream_si512(reinterpret_cast<__m512i*>(out_ids + g), vi);
        _mm512_stream_ps(out_depth + g, vd);
      } else {
        const auto lanes = static_cast<__mmask16>(on_map >> g);
        _mm512_mask_storeu_epi32(out_ids + g, lanes, vi);
        _mm512_mask_storeu_ps(out_depth + g, lanes, vd);
      }
    }
    add_runs(starts, slots, w, counts.data());
    if (!map.normal.empty())
      for (int px = x0; px < x1; ++px) write_normal(cam, job.spheres, map, px, y0 + r);
  }
  counts.finish();
  _mm_sfence();  // the streamed rows are visible before the task counts as done
}

}  // namespace viscd::detail

#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic pop
#endif

#endif  // VISCD_HAVE_AVX512
