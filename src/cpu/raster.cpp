#include "cpu/raster.hpp"

#include <emmintrin.h>
#include <xmmintrin.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <bit>
#include <cmath>
#include <limits>

#include "cpu/grow.hpp"
#include "cpu/parallel.hpp"
#include "cpu/raster_tile.hpp"
#include "viscd/assert.hpp"

namespace viscd::detail {
namespace {

constexpr int kT = TiledRasterizer::kTile;
constexpr float kInf = std::numeric_limits<float>::infinity();
/// Pixels whose centre lies within this much of the extent of a (widened) sphere are included.
constexpr double kPixelMargin = 1.0 / 16;

/// Depth-order key: the top 16 bits of a non-negative float, monotone in its value; kCulled for
/// spheres no pixel can see.
constexpr std::uint16_t kCulled = 0xFFFF;
/// Buckets of the depth sort.
constexpr std::size_t kBuckets = 1024;
/// Spheres below which the depth sort runs on the calling thread. Measured on 2 threads (cycle
/// counters around the stage): 10 000 spheres sort in about 0.1 M cycles alone and 0.2 M in
/// parallel; at 50 000 both take 0.4-0.6 M.
constexpr std::size_t kSerialSort = 1 << 16;
std::uint16_t depth_key(float near_depth) {
  return near_depth > 0.0f ? static_cast<std::uint16_t>(std::bit_cast<std::uint32_t>(near_depth) >> 16) : 0;
}
float key_floor(std::uint16_t key) { return std::bit_cast<float>(static_cast<std::uint32_t>(key) << 16); }

/// The camera in double, for the per-sphere bounds.
struct View {
  double ex, ey, ez;
  double f[3], rt[3], up[3];
  double ff, rr, uu, fr, fu, ur;  // dot products of the (float, so not exactly orthonormal) axes
  double near_plane, far_plane;
  // Pixel coordinates of a direction: px = nx * sx + cx, py = -ny * sy + cy (CameraRig::dir).
  double sx, sy, cx, cy;
  int w, h;
  explicit View(const CameraRig& cam) {
    ex = cam.eye.x, ey = cam.eye.y, ez = cam.eye.z;
    const Vec3* axes[3] = {&cam.forward, &cam.right, &cam.up};
    double* out[3] = {f, rt, up};
    for (int i = 0; i < 3; ++i) out[i][0] = axes[i]->x, out[i][1] = axes[i]->y, out[i][2] = axes[i]->z;
    auto dot = [](const double* a, const double* b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; };
    ff = dot(f, f), rr = dot(rt, rt), uu = dot(up, up), fr = dot(f, rt), fu = dot(f, up), ur = dot(up, rt);
    near_plane = cam.near_plane, far_plane = cam.far_plane;
    sx = static_cast<double>(cam.map_w) / (2.0 * static_cast<double>(cam.tan_half_x));
    sy = static_cast<double>(cam.map_h) / (2.0 * static_cast<double>(cam.tan_half_y));
    cx = 0.5 * cam.map_w - 0.5, cy = 0.5 * cam.map_h - 0.5;
    w = cam.map_w, h = cam.map_h;
  }
};

/// Two spheres at a time (SSE2 double lanes): the sphere widened to the radius R that holds every
/// ray hit() can accept, and its projection. hit() decides on a float discriminant that cancels
/// near the centre of spheres small against their distance |o|, so R = sqrt(r^2 + 2^-19 |o|^2) as
/// sphere_rect (docs/architecture.md, "Visibility map"), plus 2e-4 (|o|_1 + r): twice
/// sphere_rect's slack, and far more than the float rounding of a ray's direction or of the
/// depth t (relative 1e-5 at most, at a 179.9 degree field of view).
///
/// The projection: the directions d = f + a u + b v (u, v screen coordinates, nx or ny) whose
/// line from the eye passes within R of the centre, Q = (o.d)^2 - |d|^2 k >= 0 with o = eye -
/// centre and k = |o|^2 - R^2 > 0. For fixed v, Q = la u^2 + 2 (b0 + b1 v) u + (c0 + c1 v +
/// c2 v^2); with la < 0 its solutions are the u between the roots, which exist where the
/// discriminant D(v) = d0 + d1 v + d2 v^2 >= 0: for d2 < 0 an interval of v, the extent of the
/// projection along that screen axis. Bounded exactly when the widened sphere lies wholly in
/// front of (or behind) the eye's plane; else (or where rounding could make it unreliable: la or
/// d2 not clearly negative, no real roots, a root not finite) that axis is not bounded.
/// The pixel rectangle of each lane is the extent's pixels, those whose centre lies within
/// kPixelMargin of it (the whole map along an axis that is not bounded).
struct Bounds2 {
  alignas(16) double rr[2], cz[2];                  // R, view depth of the centre
  alignas(16) std::int32_t first[2][4], end[2][4];  // [axis: 0 rows, 1 columns][lane]: pixels [first, end)
};
inline void bounds2(const View& v, const Sphere& s0, const Sphere& s1, Bounds2& out) {
  auto pair = [](double a, double b) { return _mm_set_pd(b, a); };  // lane 0 = a
  auto c = [](double x) { return _mm_set1_pd(x); };
  const __m128d sign = c(-0.0), zero = _mm_setzero_pd();
  auto abs = [&](__m128d x) { return _mm_andnot_pd(sign, x); };
  auto add = [](__m128d x, __m128d y) { return _mm_add_pd(x, y); };
  auto sub = [](__m128d x, __m128d y) { return _mm_sub_pd(x, y); };
  auto mul = [](__m128d x, __m128d y) { return _mm_mul_pd(x, y); };
  const __m128d ox = sub(c(v.ex), pair(s0.x, s1.x)), oy = sub(c(v.ey), pair(s0.y, s1.y)),
                oz = sub(c(v.ez), pair(s0.z, s1.z)), r = pair(s0.r, s1.r);
  const __m128d o2 = add(add(mul(ox, ox), mul(oy, oy)), mul(oz, oz));
  const __m128d l1 = add(add(abs(ox), abs(oy)), abs(oz));
  const __m128d rr = add(add(_mm_sqrt_pd(add(mul(r, r), mul(c(0x1p-19), o2))), mul(c(2e-4), add(l1, r))), c(1e-6));
  const __m128d k = sub(o2, mul(rr, rr));
  auto dot = [&](const double* a) { return add(add(mul(ox, c(a[0])), mul(oy, c(a[1]))), mul(oz, c(a[2]))); };
  const __m128d of = dot(v.f), ou = dot(v.up), orr = dot(v.rt);
  _mm_store_pd(out.rr, rr);
  _mm_store_pd(out.cz, _mm_xor_pd(of, sign));
  const __m128d k_pos = _mm_cmpgt_pd(k, zero);  // else the eye is inside (or at) the widened sphere
  auto extent = [&](int axis, __m128d oa, __m128d ob, double aa, double bb, double fa, double fb, double ab) {
    const __m128d oa2 = mul(oa, oa), kaa = mul(k, c(aa));
    const __m128d la = sub(oa2, kaa);
    __m128d ok = _mm_and_pd(k_pos, _mm_cmplt_pd(la, mul(c(-1e-6), add(oa2, kaa))));
    const __m128d b0 = sub(mul(of, oa), mul(k, c(fa))), b1 = sub(mul(ob, oa), mul(k, c(ab)));
    const __m128d c0 = sub(mul(of, of), mul(k, c(v.ff))), c1 = mul(c(2), sub(mul(of, ob), mul(k, c(fb)))),
                  c2 = sub(mul(ob, ob), mul(k, c(bb)));
    const __m128d b1b1 = mul(b1, b1);
    const __m128d d0 = sub(mul(b0, b0), mul(la, c0)), d1 = sub(mul(c(2), mul(b0, b1)), mul(la, c1)),
                  d2 = sub(b1b1, mul(la, c2));
    ok = _mm_and_pd(ok, _mm_cmplt_pd(d2, mul(c(-1e-9), add(b1b1, abs(sub(d2, b1b1))))));
    const __m128d disc = sub(mul(d1, d1), mul(c(4), mul(d2, d0)));
    ok = _mm_and_pd(ok, _mm_cmpge_pd(disc, zero));
    const __m128d sq = _mm_sqrt_pd(_mm_max_pd(disc, zero)), inv = _mm_div_pd(c(0.5), d2);
    const __m128d nd1 = _mm_xor_pd(d1, sign);
    const __m128d r0 = mul(sub(nd1, sq), inv), r1 = mul(add(nd1, sq), inv);
    const __m128d lo = _mm_min_pd(r0, r1), hi = _mm_max_pd(r0, r1);
    const __m128d inf = c(std::numeric_limits<double>::infinity());
    ok = _mm_and_pd(ok, _mm_and_pd(_mm_cmplt_pd(abs(lo), inf), _mm_cmplt_pd(abs(hi), inf)));
    // Pixel coordinates: px = nx sx + cx, py = -ny sy + cy (rows run down).
    const double scale = axis == 0 ? -v.sy : v.sx, centre = axis == 0 ? v.cy : v.cx;
    const auto n = static_cast<double>(axis == 0 ? v.h : v.w);
    const __m128d p0 = add(mul(axis == 0 ? hi : lo, c(scale)), c(centre)),
                  p1 = add(mul(axis == 0 ? lo : hi, c(scale)), c(centre));
    // Clamped to [-1, n] (so the conversions below cannot overflow); then ceil and floor from
    // the truncation (SSE2 has no rounding to an integer), and the first and one-past-last pixel.
    const __m128d q0 = _mm_min_pd(_mm_max_pd(sub(p0, c(kPixelMargin)), c(-1)), c(n)),
                  q1 = _mm_min_pd(_mm_max_pd(add(p1, c(kPixelMargin)), c(-1)), c(n));
    const __m128d t0 = _mm_cvtepi32_pd(_mm_cvttpd_epi32(q0)), t1 = _mm_cvtepi32_pd(_mm_cvttpd_epi32(q1));
    const __m128d ceil0 = add(t0, _mm_and_pd(_mm_cmplt_pd(t0, q0), c(1))),
                  floor1 = sub(t1, _mm_and_pd(_mm_cmpgt_pd(t1, q1), c(1)));
    const __m128d first = _mm_max_pd(ceil0, zero), end = _mm_min_pd(add(floor1, c(1)), c(n));
    auto select_pd = [](__m128d m, __m128d a, __m128d b) { return _mm_or_pd(_mm_and_pd(m, a), _mm_andnot_pd(m, b)); };
    _mm_store_si128(reinterpret_cast<__m128i*>(out.first[axis]), _mm_cvttpd_epi32(select_pd(ok, first, zero)));
    _mm_store_si128(reinterpret_cast<__m128i*>(out.end[axis]), _mm_cvttpd_epi32(select_pd(ok, end, c(n))));
  };
  extent(0, orr, ou, v.rr, v.uu, v.fr, v.fu, v.ur);  // rows: u = nx, v = ny
  extent(1, ou, orr, v.uu, v.rr, v.fu, v.fr, v.ur);  // columns: u = ny, v = nx
}
/// A lower bound of hit()'s t on the sphere (float, rounded down).
inline float near_depth(double cz, double rr) {
  const double d = cz - rr;
  if (!(d > 0)) return 0.0f;
  const auto f = static_cast<float>(d);  // > 0: d is at least the float's half ulp
  return static_cast<double>(f) > d ? std::bit_cast<float>(std::bit_cast<std::uint32_t>(f) - 1) : f;
}

inline __m128 select(__m128 mask, __m128 a, __m128 b) { return _mm_or_ps(_mm_and_ps(mask, a), _mm_andnot_ps(mask, b)); }
inline __m128i select(__m128i mask, __m128i a, __m128i b) {
  return _mm_or_si128(_mm_and_si128(mask, a), _mm_andnot_si128(mask, b));
}
inline float hmax(__m128 v) {
  v = _mm_max_ps(v, _mm_shuffle_ps(v, v, _MM_SHUFFLE(1, 0, 3, 2)));
  v = _mm_max_ps(v, _mm_shuffle_ps(v, v, _MM_SHUFFLE(2, 3, 0, 1)));
  return _mm_cvtss_f32(v);
}

/// A sphere's hit() terms in every lane.
struct Lanes {
  __m128 ox, oy, oz, c;
  __m128i id, slot;
};
struct Planes {
  __m128 near, far;
};

/// Writes w pixels of a map row, 4 at a time from quad(i) -> (ids, depths) of pixels i..i+3
/// (read past w only within the tile). Whole cache lines (ids and depth are 64-byte aligned, so
/// both rows reach a line boundary together) are streamed past the caches: nothing reads the
/// map again this frame, and a line is written by one tile only, so it never moves between cores.
/// The partial lines at either end, shared with the next tile, are stored as usual.
template <class Quad>
inline void stream_row(std::uint32_t* ids, float* depth, int w, Quad&& quad) {
  auto store = [&](int i, int count) {
    const auto [vi, vd] = quad(i);
    alignas(16) std::uint32_t qi[4];
    alignas(16) float qd[4];
    _mm_store_si128(reinterpret_cast<__m128i*>(qi), vi);
    _mm_store_ps(qd, vd);
    for (int k = 0; k < count; ++k) ids[i + k] = qi[k], depth[i + k] = qd[k];
  };
  const auto misalign = static_cast<int>(reinterpret_cast<std::uintptr_t>(ids) & 63) / 4;
  const int head = std::min(w, misalign ? 16 - misalign : 0);
  int i = 0;
  for (; i + 4 <= head; i += 4) store(i, 4);
  if (i < head) store(i, head - i), i = head;
  for (; i + 16 <= w; i += 16)
    for (int k = 0; k < 16; k += 4) {
      const auto [vi, vd] = quad(i + k);
      _mm_stream_si128(reinterpret_cast<__m128i*>(ids + i + k), vi);
      _mm_stream_ps(depth + i + k, vd);
    }
  for (; i < w; i += 4) store(i, std::min(4, w - i));
}

/// The groups of 4 pixels of one sphere that some lane may change, with hit()'s b and
/// discriminant for them: a first pass over the sphere's pixels finds them, a second finishes
/// hit() (sqrt, division) and keeps the nearer hits only for those.
struct Candidates {
  static constexpr int kMax = kT * kT / 4;
  int n = 0;
  alignas(16) int at[kMax];
  __m128 b[kMax], disc[kMax];
};

/// First pass for the group at `i`: hit()'s b = o.d and disc = b b - a c, each operation in
/// hit()'s order so every lane rounds as it does. The group is kept if a lane has disc >= 0 (else
/// hit() misses) where the pixel's nearest hit so far is not nearer than near_depth (else nothing
/// on this sphere can beat it: every hit has t >= near_depth). Branch-free.
inline void screen(const TileBuffers& buf, int i, const Lanes& s, __m128 near_depth, Candidates& c) {
  const __m128 vx = _mm_loadu_ps(buf.dx + i), vy = _mm_loadu_ps(buf.dy + i), vz = _mm_loadu_ps(buf.dz + i);
  const __m128 b = _mm_add_ps(_mm_add_ps(_mm_mul_ps(s.ox, vx), _mm_mul_ps(s.oy, vy)), _mm_mul_ps(s.oz, vz));
  const __m128 disc = _mm_sub_ps(_mm_mul_ps(b, b), _mm_mul_ps(_mm_loadu_ps(buf.a + i), s.c));
  const __m128 open =
      _mm_and_ps(_mm_cmpge_ps(disc, _mm_setzero_ps()), _mm_cmpge_ps(_mm_loadu_ps(buf.best + i), near_depth));
  c.at[c.n] = i;
  c.b[c.n] = b;
  c.disc[c.n] = disc;
  c.n += _mm_movemask_ps(open) != 0;
}

/// Second pass: the rest of hit() for each kept group (t0 = (-b - sqrt(disc)) / a if in
/// [near, far], else t1 = (-b + sqrt(disc)) / a if in range, else a miss), kept where nearer than
/// the pixel's best, ties to the smaller id. Returns whether any pixel changed.
inline bool resolve(TileBuffers& buf, const Candidates& c, const Lanes& s, const Planes& pl) {
  __m128 any = _mm_setzero_ps();
  for (int e = 0; e < c.n; ++e) {
    const int i = c.at[e];
    const __m128 b = c.b[e], disc = c.disc[e], va = _mm_loadu_ps(buf.a + i);
    const __m128 real = _mm_cmpge_ps(disc, _mm_setzero_ps());
    const __m128 sq = _mm_sqrt_ps(_mm_and_ps(disc, real));
    const __m128 nb = _mm_xor_ps(b, _mm_set1_ps(-0.0f));
    const __m128 t0 = _mm_div_ps(_mm_sub_ps(nb, sq), va);
    const __m128 in0 = _mm_and_ps(_mm_cmpge_ps(t0, pl.near), _mm_cmple_ps(t0, pl.far));
    __m128 hv = t0, hit = _mm_and_ps(real, in0);
    if (_mm_movemask_ps(_mm_andnot_ps(in0, real)) != 0) [[unlikely]] {  // the front root is clipped
      const __m128 t1 = _mm_div_ps(_mm_add_ps(nb, sq), va);
      const __m128 in1 = _mm_and_ps(_mm_cmpge_ps(t1, pl.near), _mm_cmple_ps(t1, pl.far));
      hv = select(in0, t0, t1);
      hit = _mm_and_ps(real, _mm_or_ps(in0, in1));
    }
    // hit() returns a root in [near, far] (near > 0) or -1: a hit is a lane with `hit` set.
    const __m128 bb = _mm_loadu_ps(buf.best + i);
    const __m128i bi = _mm_loadu_si128(reinterpret_cast<const __m128i*>(buf.id + i));
    // ids < 2^31 (validate_spheres), so the signed compare orders them.
    const __m128 smaller_id = _mm_castsi128_ps(_mm_cmplt_epi32(s.id, bi));
    const __m128 better =
        _mm_and_ps(hit, _mm_or_ps(_mm_cmplt_ps(hv, bb), _mm_and_ps(_mm_cmpeq_ps(hv, bb), smaller_id)));
    const __m128i better_i = _mm_castps_si128(better);
    _mm_storeu_ps(buf.best + i, select(better, hv, bb));
    _mm_storeu_si128(reinterpret_cast<__m128i*>(buf.id + i), select(better_i, s.id, bi));
    __m128i* slot = reinterpret_cast<__m128i*>(buf.slot + i);
    _mm_storeu_si128(slot, select(better_i, s.slot, _mm_loadu_si128(slot)));
    any = _mm_or_ps(any, better);
  }
  return _mm_movemask_ps(any) != 0;
}

/// Chunks for a loop over n spheres: a few per thread, so that a worker that wakes late still
/// takes its share (the caller starts alone), but none below 512 spheres; one below
/// kParallelThreshold.
std::size_t chunks_for(std::size_t n, int threads) {
  if (threads_for(n, threads) == 1) return 1;
  return std::clamp<std::size_t>(n / 512, 1, 4 * static_cast<std::size_t>(threads));
}

}  // namespace

TileRect tile_rect(const TileJob& job, std::uint32_t t) {
  const int tx = static_cast<int>(t % static_cast<std::uint32_t>(job.tiles_x)),
            ty = static_cast<int>(t / static_cast<std::uint32_t>(job.tiles_x));
  const int x0 = tx * kT, y0 = ty * kT;
  return {x0, y0, std::min(x0 + kT, job.map->width), std::min(y0 + kT, job.map->height)};
}

void write_background_tile(const TileJob& job, std::uint32_t t) {
  if (job.keep_background && job.background[t]) return;  // still there from the last run
  VisibilityMap& map = *job.map;
  const TileRect tr = tile_rect(job, t);
  const int w = tr.x1 - tr.x0;
  const __m128 far_depth = _mm_set1_ps(job.cam->far_plane);
  for (int py = tr.y0; py < tr.y1; ++py) {
    const std::size_t row = static_cast<std::size_t>(py) * static_cast<std::size_t>(map.width) + tr.x0;
    stream_row(map.ids.data() + row, map.depth.data() + row, w, [&](int) {
      return std::pair{_mm_setzero_si128(), far_depth};
    });
    if (!map.normal.empty()) std::fill_n(map.normal.data() + 3 * row, 3 * w, 0.0f);
  }
  _mm_sfence();  // the streamed rows are visible before the task counts as done
}

void raster_tile_sse2(const TileJob& job, std::uint32_t t) {
  const std::uint32_t* items = job.items + job.offset[t];
  const std::uint32_t m = job.offset[t + 1] - job.offset[t];
  if (m == 0) return write_background_tile(job, t);
  const CameraRig& cam = *job.cam;
  VisibilityMap& map = *job.map;
  const TileRect tr = tile_rect(job, t);
  const int x0 = tr.x0, y0 = tr.y0, x1 = tr.x1, y1 = tr.y1;
  const int w = x1 - x0, h = y1 - y0;
  const Planes planes{_mm_set1_ps(cam.near_plane), _mm_set1_ps(cam.far_plane)};
  const __m128 v_far_depth = _mm_set1_ps(cam.far_plane);
  TileBuffers buf;
  Candidates cand;
  {
    alignas(16) float first[kT];  // +inf on the map, -inf beyond its edge (never hit, never the max)
    for (int i = 0; i < kT; ++i) first[i] = i < w ? kInf : -kInf;
    const __m128i zero = _mm_setzero_si128();
    for (int i = 0; i < 16; i += 4) _mm_store_si128(reinterpret_cast<__m128i*>(buf.pad + i), zero);
    // (id needs no start value: it is read only where slot is set, or compared where best is
    // +inf or -inf, where the depth alone decides; an occluded pixel starts at the occluder's
    // depth with kOccluderId.)
    for (int r = 0; r < h; ++r)
      for (int i = 0; i < kT; i += 4) {
        _mm_store_ps(buf.best + r * kT + i, _mm_load_ps(first + i));
        _mm_store_si128(reinterpret_cast<__m128i*>(buf.slot + r * kT + i), zero);
      }
    if (job.occluder_ids != nullptr)
      for (int r = 0; r < h; ++r) {
        const std::size_t row = static_cast<std::size_t>(y0 + r) * static_cast<std::size_t>(map.width) + x0;
        for (int i = 0; i < w; ++i)
          if (job.occluder_ids[row + i] != 0) {
            buf.best[r * kT + i] = job.occluder_depth[row + i];
            buf.id[r * kT + i] = kOccluderId;
          }
      }
  }
  std::uint32_t dirs_ready = 0;  // bit r: row r's rays are filled
  auto fill_rays = [&](int r) {
    const std::size_t py = static_cast<std::size_t>(y0 + r);
    const float ux = job.row_x[py], uy = job.row_y[py], uz = job.row_z[py];
    const float *cx = job.col_x + x0, *cy = job.col_y + x0, *cz = job.col_z + x0;
    for (int i = 0; i < kT; ++i) {
      const float ex = cx[i] + ux, ey = cy[i] + uy, ez = cz[i] + uz;
      buf.dx[r * kT + i] = ex, buf.dy[r * kT + i] = ey, buf.dz[r * kT + i] = ez;
      buf.a[r * kT + i] = ex * ex + ey * ey + ez * ez;
    }
  };
  DepthCut cut;
  for (std::uint32_t j = 0; j < m; ++j) {
    const TiledRasterizer::Prepared& p = job.prep[items[j]];
    if (j + 1 < m) _mm_prefetch(reinterpret_cast<const char*>(&job.prep[items[j + 1]]), _MM_HINT_T0);
    if (cut.stale(j)) {
      __m128 m0 = _mm_load_ps(buf.best), m1 = _mm_load_ps(buf.best + 4), m2 = _mm_load_ps(buf.best + 8),
             m3 = _mm_load_ps(buf.best + 12);
      for (int q = 16; q < h * kT; q += 16) {
        m0 = _mm_max_ps(m0, _mm_load_ps(buf.best + q));
        m1 = _mm_max_ps(m1, _mm_load_ps(buf.best + q + 4));
        m2 = _mm_max_ps(m2, _mm_load_ps(buf.best + q + 8));
        m3 = _mm_max_ps(m3, _mm_load_ps(buf.best + q + 12));
      }
      cut.refresh(hmax(_mm_max_ps(_mm_max_ps(m0, m1), _mm_max_ps(m2, m3))));
    }
    const DepthCut::Verdict verdict = cut.verdict(j, p);
    if (verdict == DepthCut::Verdict::stop) break;
    if (verdict == DepthCut::Verdict::skip) continue;
    const Lanes lanes{_mm_set1_ps(p.ox),
                      _mm_set1_ps(p.oy),
                      _mm_set1_ps(p.oz),
                      _mm_set1_ps(p.c),
                      _mm_set1_epi32(static_cast<int>(p.id)),
                      _mm_set1_epi32(static_cast<int>(j + 1))};
    const TileSpan span = tile_span(tr, p);
    const int ra = span.ra, rb = span.rb, ca = span.ca, cb = span.cb;
    for (std::uint32_t need = span.rows & ~dirs_ready; need; need &= need - 1) fill_rays(std::countr_zero(need));
    dirs_ready |= span.rows;
    const __m128 near_depth = _mm_set1_ps(p.near_depth);
    cand.n = 0;
    // The same window of k groups on every row of the rectangle in the tile: no per-row
    // decisions; the first pass drops the groups outside the disc or behind nearer hits.
    const int k = (cb - ca + 3) >> 2, wa = std::min(ca, kT - 4 * k);
    for (int r = ra; r < rb; ++r)
      for (int g = 0; g < k; ++g) screen(buf, r * kT + wa + 4 * g, lanes, near_depth, cand);
    if (resolve(buf, cand, lanes, planes)) cut.changed();
  }

  // Write out row by row (background depth = far plane), and count the row's runs of equal
  // slots into the tile's counts (slot 0 is the background).
  TileCounts counts(job, t, m);
  for (int r = 0; r < h; ++r) {
    const std::size_t row = static_cast<std::size_t>(y0 + r) * static_cast<std::size_t>(map.width) + x0;
    const float* best = buf.best + r * kT;
    const std::uint32_t* ids = buf.id + r * kT;
    const std::uint32_t* slots = buf.slot + r * kT;
    stream_row(map.ids.data() + row, map.depth.data() + row, w, [&](int i) {
      const __m128i none =
          _mm_cmpeq_epi32(_mm_loadu_si128(reinterpret_cast<const __m128i*>(slots + i)), _mm_setzero_si128());
      const __m128i vi = _mm_andnot_si128(none, _mm_loadu_si128(reinterpret_cast<const __m128i*>(ids + i)));
      return std::pair{vi, select(_mm_castsi128_ps(none), v_far_depth, _mm_loadu_ps(best + i))};
    });
    // Runs: bit i set where slot[i] differs from slot[i - 1] (bit 0 always).
    std::uint32_t starts = 0;
    for (int g = 0; g < kT; g += 4) {
      const __m128i cur = _mm_load_si128(reinterpret_cast<const __m128i*>(slots + g));
      const __m128i prev = _mm_loadu_si128(reinterpret_cast<const __m128i*>(slots + g - 1));
      const int same = _mm_movemask_ps(_mm_castsi128_ps(_mm_cmpeq_epi32(cur, prev)));
      starts |= static_cast<std::uint32_t>(~same & 0xF) << g;
    }
    add_runs(starts | 1u, slots, w, counts.data());
    if (!map.normal.empty())
      for (int px = x0; px < x1; ++px) write_normal(cam, job.spheres, map, px, y0 + r);
  }
  counts.finish();
  _mm_sfence();  // the streamed rows are visible before the task counts as done
}

std::uint64_t TiledRasterizer::memory_bytes() const {
  auto b = [](const auto& v) { return static_cast<std::uint64_t>(v.capacity()) * sizeof(v[0]); };
  std::uint64_t s = b(prep_) + b(bounds_) + b(keys_) + b(order_) + b(key_range_) + b(bucket_count_) +
                    b(chunk_tile_count_) + b(tile_offset_) + b(tile_items_) + b(tile_counts_) + b(background_);
  for (const auto* v : {&col_x_, &col_y_, &col_z_, &row_x_, &row_y_, &row_z_}) s += b(*v);
  return s;
}

void TiledRasterizer::run(const CameraRig& cam, std::span<const Sphere> spheres, int threads, VisibilityMap& map,
                          const VisibilityMap* occluder) {
  const std::size_t n = spheres.size();
  const int tiles_x = (map.width + kT - 1) / kT, tiles_y = (map.height + kT - 1) / kT;
  const std::size_t tiles = static_cast<std::size_t>(tiles_x) * static_cast<std::size_t>(tiles_y);

  // 1. Per sphere, in index order (the spheres are read in memory order): the depth bound and
  // key and the rectangle. Spheres no pixel can see (wholly before near or beyond far, or off
  // the map) get the last key and are left out.
  static_assert(kMaxMapSide <= 0xFFFF, "map coordinates are kept in 16 bits");
  VISCD_ASSERT(map.width <= kMaxMapSide && map.height <= kMaxMapSide, "visibility map larger than kMaxMapSide");
  const View view(cam);
  bounds_.resize(n);
  keys_.resize(n);
  order_.resize(n);
  const std::size_t sphere_chunks = chunks_for(n, threads);
  key_range_.assign(2 * sphere_chunks, 0);
  for_chunks(n, sphere_chunks, [&](std::size_t b, std::size_t e, std::size_t chunk) {
    std::uint16_t lo = kCulled, hi = 0;
    Bounds2 q;
    for (std::size_t k0 = b; k0 < e; k0 += 2) {
      bounds2(view, spheres[k0], spheres[std::min(k0 + 1, e - 1)], q);
      for (std::size_t lane = 0; lane < 2 && k0 + lane < e; ++lane) {
        const std::size_t k = k0 + lane;
        const std::int32_t x0 = q.first[1][lane], y0 = q.first[0][lane], x1 = q.end[1][lane], y1 = q.end[0][lane];
        const bool seen = !(q.cz[lane] + q.rr[lane] < view.near_plane || q.cz[lane] - q.rr[lane] > view.far_plane) &&
                          x0 < x1 && y0 < y1;
        const float depth = near_depth(q.cz[lane], q.rr[lane]);
        bounds_[k] = {static_cast<std::uint16_t>(x0), static_cast<std::uint16_t>(y0), static_cast<std::uint16_t>(x1),
                      static_cast<std::uint16_t>(y1), depth};
        const std::uint16_t key = seen ? depth_key(depth) : kCulled;
        keys_[k] = key;
        if (seen) lo = std::min(lo, key), hi = std::max(hi, key);
      }
    }
    key_range_[2 * chunk] = lo, key_range_[2 * chunk + 1] = hi;
  });

  // 2. Front to back: a counting sort of the seen spheres by key (stable: equal keys by index),
  // per chunk a histogram, a scan in (bucket, chunk) order, a scatter. Keys span few values in a
  // frame (7 bits an octave of depth), so one pass of kBuckets buckets holds them all, or all but
  // their lowest bits (then the order is coarser, and key_floor the floor of the bucket).
  std::uint16_t kmin = kCulled, kmax = 0;
  for (std::size_t c = 0; c < sphere_chunks; ++c)
    kmin = std::min(kmin, key_range_[2 * c]), kmax = std::max(kmax, key_range_[2 * c + 1]);
  int shift = 0;
  while (kmin <= kmax && static_cast<std::size_t>((kmax - kmin) >> shift) >= kBuckets) ++shift;
  auto bucket = [&](std::uint16_t key) { return static_cast<std::size_t>((key - kmin) >> shift); };
  // (On one chunk below kSerialSort spheres: two parallel passes of a few cycles per sphere cost
  // more to start and join than they save.)
  const std::size_t sort_chunks = n < kSerialSort ? 1 : sphere_chunks;
  bucket_count_.assign(sort_chunks * kBuckets, 0);
  for_chunks(n, sort_chunks, [&](std::size_t b, std::size_t e, std::size_t chunk) {
    std::uint32_t* h = bucket_count_.data() + chunk * kBuckets;
    for (std::size_t k = b; k < e; ++k)
      if (keys_[k] != kCulled) ++h[bucket(keys_[k])];
  });
  std::uint32_t seen = 0;
  for (std::size_t u = 0; u < kBuckets; ++u)
    for (std::size_t c = 0; c < sort_chunks; ++c) {
      const std::uint32_t v = bucket_count_[c * kBuckets + u];
      bucket_count_[c * kBuckets + u] = seen;  // becomes the chunk's cursor
      seen += v;
    }
  for_chunks(n, sort_chunks, [&](std::size_t b, std::size_t e, std::size_t chunk) {
    std::uint32_t* cursor = bucket_count_.data() + chunk * kBuckets;
    for (std::size_t k = b; k < e; ++k)
      if (keys_[k] != kCulled) order_[cursor[bucket(keys_[k])]++] = static_cast<std::uint32_t>(k);
  });
  auto floor_of = [&](std::uint16_t key) {  // a lower bound of the depth of every later sphere
    return key_floor(static_cast<std::uint16_t>(((key - kmin) >> shift << shift) + kmin));
  };

  // 3. In that order what a tile needs of each sphere (in memory order for the tiles), and
  // binning into tiles: a count per (chunk, tile), a scan in (tile, chunk) order, a scatter per
  // chunk, so each tile's list is in depth order whatever the number of chunks (and no atomics).
  const std::size_t visible = seen;
  const std::size_t chunks = chunks_for(visible, threads);
  // (Both follow the visible count, which changes from frame to frame: grown with headroom.)
  resize_with_headroom(chunk_tile_count_, chunks * tiles);
  std::fill(chunk_tile_count_.begin(), chunk_tile_count_.end(), 0u);
  resize_with_headroom(prep_, visible);
  auto for_tiles_of = [&](const Prepared& p, auto&& f) {
    for (int ty = p.y0 / kT; ty <= (p.y1 - 1) / kT; ++ty)
      for (int tx = p.x0 / kT; tx <= (p.x1 - 1) / kT; ++tx) f(static_cast<std::size_t>(ty * tiles_x + tx));
  };
  for_chunks(visible, chunks, [&](std::size_t b, std::size_t e, std::size_t c) {
    for (std::size_t i = b; i < e; ++i) {
      if (i + 16 < e) {  // the reads below are in depth order, so at random: fetch ahead
        _mm_prefetch(reinterpret_cast<const char*>(&spheres[order_[i + 16]]), _MM_HINT_T0);
        _mm_prefetch(reinterpret_cast<const char*>(&bounds_[order_[i + 16]]), _MM_HINT_T0);
      }
      const std::uint32_t k = order_[i];
      const Sphere& s = spheres[k];
      const Bound& bd = bounds_[k];
      Prepared& p = prep_[i];
      // hit()'s expressions and order, so the per-pixel results match it bit for bit.
      p.ox = cam.eye.x - s.x, p.oy = cam.eye.y - s.y, p.oz = cam.eye.z - s.z;
      p.c = p.ox * p.ox + p.oy * p.oy + p.oz * p.oz - s.r * s.r;
      p.near_depth = bd.near_depth;
      p.key_floor = floor_of(keys_[k]);
      p.id = k + 1;
      p.x0 = bd.x0, p.y0 = bd.y0, p.x1 = bd.x1, p.y1 = bd.y1;
    }
    std::uint32_t* cnt = chunk_tile_count_.data() + c * tiles;
    for (std::size_t i = b; i < e; ++i) for_tiles_of(prep_[i], [&](std::size_t t) { ++cnt[t]; });
  });
  tile_offset_.resize(tiles + 1);
  std::uint32_t sum = 0;
  for (std::size_t t = 0; t < tiles; ++t) {
    tile_offset_[t] = sum;
    for (std::size_t c = 0; c < chunks; ++c) {
      const std::uint32_t v = chunk_tile_count_[c * tiles + t];
      chunk_tile_count_[c * tiles + t] = sum;  // becomes the chunk's cursor
      sum += v;
    }
  }
  tile_offset_[tiles] = sum;
  if (tile_items_.size() < sum) tile_items_.resize(sum + sum / 4);  // headroom: lists vary per frame
  if (tile_counts_.size() < sum + tiles) tile_counts_.resize(sum + tiles + (sum + tiles) / 4);
  for_chunks(visible, chunks, [&](std::size_t b, std::size_t e, std::size_t c) {
    std::uint32_t* cursor = chunk_tile_count_.data() + c * tiles;
    for (std::size_t i = b; i < e; ++i)
      for_tiles_of(prep_[i], [&](std::size_t t) { tile_items_[cursor[t]++] = static_cast<std::uint32_t>(i); });
  });

  // 4. The rays: dir() = (forward + right nx) + up ny, per column and per row, exactly as
  // CameraRig::dir() rounds them (columns padded to whole tiles).
  const std::size_t cols = static_cast<std::size_t>(tiles_x) * kT, rows = static_cast<std::size_t>(map.height);
  col_x_.resize(cols), col_y_.resize(cols), col_z_.resize(cols);
  row_x_.resize(rows), row_y_.resize(rows), row_z_.resize(rows);
  for (std::size_t px = 0; px < cols; ++px) {
    const float nx = (2.0f * (static_cast<float>(px) + 0.5f) / static_cast<float>(cam.map_w) - 1.0f) * cam.tan_half_x;
    col_x_[px] = cam.forward.x + cam.right.x * nx;
    col_y_[px] = cam.forward.y + cam.right.y * nx;
    col_z_[px] = cam.forward.z + cam.right.z * nx;
  }
  for (std::size_t py = 0; py < rows; ++py) {
    const float ny = (1.0f - 2.0f * (static_cast<float>(py) + 0.5f) / static_cast<float>(cam.map_h)) * cam.tan_half_y;
    row_x_[py] = cam.up.x * ny, row_y_[py] = cam.up.y * ny, row_z_[py] = cam.up.z * ny;
  }

  // 5. Rasterise and count, one task per tile (every pixel belongs to exactly one tile).
  // Tiles this rasterizer left as background in this map, unchanged since (same stamp, size,
  // far plane and normals), are not written again.
  const bool keep_background =
      map.stamp != 0 && map.stamp == stamp_ && background_.size() == tiles && background_far_ == cam.far_plane;
  map.stamp = 0;  // until this run is complete
  background_.resize(tiles);
  const TileJob job{&cam,
                    spheres,
                    &map,
                    tiles_x,
                    prep_.data(),
                    tile_items_.data(),
                    tile_offset_.data(),
                    tile_counts_.data(),
                    col_x_.data(),
                    col_y_.data(),
                    col_z_.data(),
                    row_x_.data(),
                    row_y_.data(),
                    row_z_.data(),
                    background_.data(),
                    keep_background,
                    occluder != nullptr ? occluder->ids.data() : nullptr,
                    occluder != nullptr ? occluder->depth.data() : nullptr};
  void (*kernel)(const TileJob&, std::uint32_t) = raster_tile_sse2;
#if VISCD_HAVE_AVX512
  if (simd_ == SimdLevel::avx512) kernel = raster_tile_avx512;
#endif
  auto tile_task = [&job, kernel](std::uint32_t t) { kernel(job, t); };
  if (threads_for(tiles * kT * kT, threads) == 1) {
    for (std::size_t t = 0; t < tiles; ++t) tile_task(static_cast<std::uint32_t>(t));
  } else {
    run_tasks(static_cast<std::uint32_t>(tiles), tile_task);
  }

  for (std::size_t t = 0; t < tiles; ++t) background_[t] = tile_offset_[t] == tile_offset_[t + 1];
  background_far_ = cam.far_plane;

  // 6. Pixel counts per object: the sum of its tiles' counts.
  map.counts.assign(n, 0);
  for (std::size_t t = 0; t < tiles; ++t) {
    const std::uint32_t* counts = tile_counts_.data() + tile_offset_[t] + t + 1;
    const std::uint32_t* items = tile_items_.data() + tile_offset_[t];
    const std::uint32_t m = tile_offset_[t + 1] - tile_offset_[t];
    for (std::uint32_t j = 0; j < m; ++j) map.counts[order_[items[j]]] += counts[j];
  }
  map.has_counts = true;
  static std::atomic<std::uint64_t> stamps{0};
  map.stamp = stamp_ = ++stamps;
}

}  // namespace viscd::detail
