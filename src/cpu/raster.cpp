#include "cpu/raster.hpp"

#include <emmintrin.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <limits>

#include "cpu/parallel.hpp"

namespace viscd::detail {
namespace {

constexpr int kT = TiledRasterizer::kTile;
constexpr float kInf = std::numeric_limits<float>::infinity();
/// Pixels whose centre lies within this much of a (widened) span or extent are included.
constexpr double kPixelMargin = 1.0 / 16;

/// Depth-order key: the top 16 bits of a non-negative float, monotone in its value.
std::uint16_t depth_key(float near_depth) {
  return near_depth > 0.0f ? static_cast<std::uint16_t>(std::bit_cast<std::uint32_t>(near_depth) >> 16) : 0;
}
float key_floor(std::uint16_t key) { return std::bit_cast<float>(static_cast<std::uint32_t>(key) << 16); }

using Vec3d = std::array<double, 3>;
double dot(const Vec3d& a, const Vec3d& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

/// The directions d = f + a u + b v (u, v screen coordinates: nx or ny) whose line from the eye
/// passes within R of the centre: Q = (o.d)^2 - |d|^2 (|o|^2 - R^2) >= 0, o = eye - centre,
/// k = |o|^2 - R^2 > 0. For fixed v, Q = la u^2 + 2 (b0 + b1 v) u + (c0 + c1 v + c2 v^2); with
/// la < 0 its solutions are the u between the roots, which exist where the discriminant
/// D(v) = d0 + d1 v + d2 v^2 >= 0. All in double from the camera's float vectors.
struct Conic {
  bool bounded = false;  // la < 0 by a margin: every row (or column) is a bounded interval
  double la = 0, b0 = 0, b1 = 0, d0 = 0, d1 = 0, d2 = 0;
};
Conic conic(const Vec3d& o, double k, const Vec3d& f, const Vec3d& a, const Vec3d& b) {
  Conic q;
  const double of = dot(o, f), oa = dot(o, a), ob = dot(o, b);
  q.la = oa * oa - k * dot(a, a);
  q.bounded = q.la < -1e-6 * (oa * oa + k * dot(a, a));
  q.b0 = of * oa - k * dot(f, a);
  q.b1 = ob * oa - k * dot(b, a);
  const double c0 = of * of - k * dot(f, f), c1 = 2 * (of * ob - k * dot(f, b)), c2 = ob * ob - k * dot(b, b);
  q.d0 = q.b0 * q.b0 - q.la * c0;
  q.d1 = 2 * q.b0 * q.b1 - q.la * c1;
  q.d2 = q.b1 * q.b1 - q.la * c2;
  return q;
}
/// The v where D(v) >= 0, if that is a bounded interval (the line through the centre always
/// qualifies, so an empty one can only be rounding: then no bound).
bool v_range(const Conic& q, double& lo, double& hi) {
  if (!q.bounded || !(q.d2 < -1e-9 * (q.b1 * q.b1 + std::fabs(q.d2 - q.b1 * q.b1)))) return false;
  const double disc = q.d1 * q.d1 - 4 * q.d2 * q.d0;
  if (!(disc >= 0)) return false;
  const double sq = std::sqrt(disc), r0 = (-q.d1 - sq) / (2 * q.d2), r1 = (-q.d1 + sq) / (2 * q.d2);
  lo = std::min(r0, r1), hi = std::max(r0, r1);
  return std::isfinite(lo) && std::isfinite(hi);
}

/// Tightens the rectangle to the projection of the widened sphere and prepares its row spans.
/// R is the radius sphere_rect widens to so as to hold every ray hit() can accept
/// (docs/architecture.md, "Visibility map"), with twice its relative slack (>= 2e-4 |o|, far more
/// than the float rounding of a ray's direction); rows and columns whose centre lies within
/// kPixelMargin of the extent are kept. Where a quadratic is unbounded or ill-conditioned the
/// rectangle stays as it is (and rows use its full width).
void prepare_spans(const CameraRig& cam, const Sphere& s, TiledRasterizer::Prepared& p) {
  p.spans = false;
  const Vec3d o{static_cast<double>(cam.eye.x) - s.x, static_cast<double>(cam.eye.y) - s.y,
                static_cast<double>(cam.eye.z) - s.z};
  const double r = s.r, o2 = dot(o, o), len = std::sqrt(o2);
  const double rr = std::sqrt(r * r + 0x1p-19 * o2) + 2e-4 * (len + r) + 1e-6;
  const double k = o2 - rr * rr;
  if (!(k > 0)) return;  // the eye is inside (or at) the widened sphere
  const Vec3d f{cam.forward.x, cam.forward.y, cam.forward.z}, rt{cam.right.x, cam.right.y, cam.right.z},
      up{cam.up.x, cam.up.y, cam.up.z};
  // Pixel coordinates: px = nx * sx + (W - 1) / 2 and py = -ny * sy + (H - 1) / 2 (CameraRig::dir).
  const double sx = static_cast<double>(cam.map_w) / (2.0 * static_cast<double>(cam.tan_half_x));
  const double sy = static_cast<double>(cam.map_h) / (2.0 * static_cast<double>(cam.tan_half_y));
  const double cx = 0.5 * cam.map_w - 0.5, cy = 0.5 * cam.map_h - 0.5;
  auto clampd = [](double v, int hi) { return static_cast<int>(std::clamp(v, 0.0, static_cast<double>(hi))); };
  const Conic rows = conic(o, k, f, rt, up);  // u = nx, v = ny
  double lo = 0, hi = 0;
  if (v_range(rows, lo, hi)) {  // rows [py(hi), py(lo)]
    p.y0 = std::max(p.y0, clampd(std::ceil(-hi * sy + cy - kPixelMargin), cam.map_h));
    p.y1 = std::min(p.y1, clampd(std::floor(-lo * sy + cy + kPixelMargin) + 1, cam.map_h));
  }
  const Conic cols = conic(o, k, f, up, rt);  // u = ny, v = nx
  if (v_range(cols, lo, hi)) {
    p.x0 = std::max(p.x0, clampd(std::ceil(lo * sx + cx - kPixelMargin), cam.map_w));
    p.x1 = std::min(p.x1, clampd(std::floor(hi * sx + cx + kPixelMargin) + 1, cam.map_w));
  }
  if (!rows.bounded) return;
  // Row spans in pixels: centre m0 + m1 ny, half width squared e0 + e1 ny + e2 ny^2.
  const double sc = sx / rows.la;
  p.m0 = -rows.b0 * sc + cx;
  p.m1 = -rows.b1 * sc;
  p.e0 = rows.d0 * sc * sc;
  p.e1 = rows.d1 * sc * sc;
  p.e2 = rows.d2 * sc * sc;
  p.spans =
      std::isfinite(p.m0) && std::isfinite(p.m1) && std::isfinite(p.e0) && std::isfinite(p.e1) && std::isfinite(p.e2);
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

/// A tile's working set, on the stack of the task that rasterises it.
struct alignas(64) TileBuffers {
  float best[kT * kT];          // nearest hit so far: +inf none, -inf outside the map
  std::uint32_t id[kT * kT];    // its object id (0 none)
  std::uint32_t pad[4];         // slot[-1] is read (and ignored) by the run detection
  std::uint32_t slot[kT * kT];  // its position in the tile's list + 1 (0 none): counted per tile
  // The rays of the tile's pixels: CameraRig::dir() and |dir|^2, filled per row when first needed.
  float dx[kT * kT], dy[kT * kT], dz[kT * kT], a[kT * kT];
};

/// A sphere's hit() terms in every lane.
struct Lanes {
  __m128 ox, oy, oz, c;
  __m128i id, slot;
};
struct Planes {
  __m128 near, far;
};

/// hit() for 4 pixels of a tile row at `i`, kept where nearer (ties to the smaller id). Loads
/// aligned or not. Returns the lanes it changed.
template <bool kAligned>
inline __m128 shade_in(TileBuffers& buf, int i, const Lanes& s, const Planes& pl) {
  auto load = [](const float* q) { return kAligned ? _mm_load_ps(q) : _mm_loadu_ps(q); };
  auto load_i = [](const std::uint32_t* q) {
    return kAligned ? _mm_load_si128(reinterpret_cast<const __m128i*>(q))
                    : _mm_loadu_si128(reinterpret_cast<const __m128i*>(q));
  };
  auto store = [](float* q, __m128 v) { kAligned ? _mm_store_ps(q, v) : _mm_storeu_ps(q, v); };
  auto store_i = [](std::uint32_t* q, __m128i v) {
    kAligned ? _mm_store_si128(reinterpret_cast<__m128i*>(q), v) : _mm_storeu_si128(reinterpret_cast<__m128i*>(q), v);
  };
  const __m128 vx = load(buf.dx + i), vy = load(buf.dy + i), vz = load(buf.dz + i), va = load(buf.a + i);
  const __m128 bb = load(buf.best + i);
  // hit(): b = o.d, disc = b b - a c, t0 = (-b - sqrt(disc)) / a, else t1 = (-b + sqrt) / a; each
  // operation in the same order, so every lane rounds as hit() does.
  const __m128 b = _mm_add_ps(_mm_add_ps(_mm_mul_ps(s.ox, vx), _mm_mul_ps(s.oy, vy)), _mm_mul_ps(s.oz, vz));
  const __m128 disc = _mm_sub_ps(_mm_mul_ps(b, b), _mm_mul_ps(va, s.c));
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
  const __m128i bi = load_i(buf.id + i);
  // ids < 2^31 (validate_spheres), so the signed compare orders them.
  const __m128 smaller_id = _mm_castsi128_ps(_mm_cmplt_epi32(s.id, bi));
  const __m128 better = _mm_and_ps(hit, _mm_or_ps(_mm_cmplt_ps(hv, bb), _mm_and_ps(_mm_cmpeq_ps(hv, bb), smaller_id)));
  const __m128i better_i = _mm_castps_si128(better);
  store(buf.best + i, select(better, hv, bb));
  store_i(buf.id + i, select(better_i, s.id, bi));
  store_i(buf.slot + i, select(better_i, s.slot, load_i(buf.slot + i)));
  return better;
}

}  // namespace

std::uint64_t TiledRasterizer::memory_bytes() const {
  auto b = [](const auto& v) { return static_cast<std::uint64_t>(v.capacity()) * sizeof(v[0]); };
  std::uint64_t s = b(prep_) + b(keys_) + b(order_) + b(sort_scratch_.keys) + b(sort_scratch_.values) +
                    b(sort_scratch_.histograms) + b(chunk_tile_count_) + b(tile_offset_) + b(tile_items_) +
                    b(tile_counts_) + b(row_ny_);
  for (const auto* v : {&col_x_, &col_y_, &col_z_, &row_x_, &row_y_, &row_z_}) s += b(*v);
  return s;
}

void TiledRasterizer::run(const CameraRig& cam, std::span<const Sphere> spheres, int threads, VisibilityMap& map) {
  const std::size_t n = spheres.size();
  const int tiles_x = (map.width + kT - 1) / kT, tiles_y = (map.height + kT - 1) / kT;
  const std::size_t tiles = static_cast<std::size_t>(tiles_x) * static_cast<std::size_t>(tiles_y);

  // 1. Per sphere: rectangle, hit() terms, spans, depth key (unsorted order).
  prep_.resize(n);
  keys_.resize(n);
  order_.resize(n);
  parallel_for(n, threads, [&](std::size_t k) {
    const Sphere& s = spheres[k];
    Prepared& p = prep_[k];
    const PixelRect r = sphere_rect(cam, s);
    p.x0 = r.x0, p.y0 = r.y0, p.x1 = r.x1, p.y1 = r.y1;
    p.id = static_cast<std::uint32_t>(k + 1);
    order_[k] = static_cast<std::uint32_t>(k);
    if (r.x0 >= r.x1 || r.y0 >= r.y1) {
      keys_[k] = 0xFFFF;
      return;
    }
    // hit()'s expressions and order, so the per-pixel results match it bit for bit.
    p.ox = cam.eye.x - s.x, p.oy = cam.eye.y - s.y, p.oz = cam.eye.z - s.z;
    p.c = p.ox * p.ox + p.oy * p.oy + p.oz * p.oz - s.r * s.r;
    p.near_depth = r.near_depth;
    keys_[k] = depth_key(r.near_depth);
    p.key_floor = key_floor(keys_[k]);
    prepare_spans(cam, s, p);
    if (p.x0 >= p.x1 || p.y0 >= p.y1) keys_[k] = 0xFFFF;  // no pixel can see it
  });

  // 2. Front to back (stable: equal keys by index), then bin into tiles in that order: a count
  // per (chunk, tile), a scan in (tile, chunk) order, a scatter per chunk. Each tile's list comes
  // out sorted by key, whatever the number of chunks.
  radix_sort<std::uint16_t>(keys_, order_, 16, threads, sort_scratch_);
  const std::size_t chunks = std::max<std::size_t>(1, std::min<std::size_t>(threads_for(n, threads), n));
  chunk_tile_count_.assign(chunks * tiles, 0);
  auto for_tiles_of = [&](const Prepared& p, auto&& f) {
    for (int ty = p.y0 / kT; ty <= (p.y1 - 1) / kT; ++ty)
      for (int tx = p.x0 / kT; tx <= (p.x1 - 1) / kT; ++tx) f(static_cast<std::size_t>(ty * tiles_x + tx));
  };
  for_chunks(n, chunks, [&](std::size_t b, std::size_t e, std::size_t c) {
    std::uint32_t* cnt = chunk_tile_count_.data() + c * tiles;
    for (std::size_t i = b; i < e; ++i) {
      const Prepared& p = prep_[order_[i]];
      if (p.x0 >= p.x1 || p.y0 >= p.y1) continue;
      for_tiles_of(p, [&](std::size_t t) { ++cnt[t]; });
    }
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
  for_chunks(n, chunks, [&](std::size_t b, std::size_t e, std::size_t c) {
    std::uint32_t* cursor = chunk_tile_count_.data() + c * tiles;
    for (std::size_t i = b; i < e; ++i) {
      const std::uint32_t k = order_[i];
      const Prepared& p = prep_[k];
      if (p.x0 >= p.x1 || p.y0 >= p.y1) continue;
      for_tiles_of(p, [&](std::size_t t) { tile_items_[cursor[t]++] = k; });
    }
  });

  // 3. The rays: dir() = (forward + right nx) + up ny, per column and per row, exactly as
  // CameraRig::dir() rounds them (columns padded to whole tiles).
  const std::size_t cols = static_cast<std::size_t>(tiles_x) * kT, rows = static_cast<std::size_t>(map.height);
  col_x_.resize(cols), col_y_.resize(cols), col_z_.resize(cols);
  row_x_.resize(rows), row_y_.resize(rows), row_z_.resize(rows), row_ny_.resize(rows);
  for (std::size_t px = 0; px < cols; ++px) {
    const float nx = (2.0f * (static_cast<float>(px) + 0.5f) / static_cast<float>(cam.map_w) - 1.0f) * cam.tan_half_x;
    col_x_[px] = cam.forward.x + cam.right.x * nx;
    col_y_[px] = cam.forward.y + cam.right.y * nx;
    col_z_[px] = cam.forward.z + cam.right.z * nx;
  }
  for (std::size_t py = 0; py < rows; ++py) {
    const float ny = (1.0f - 2.0f * (static_cast<float>(py) + 0.5f) / static_cast<float>(cam.map_h)) * cam.tan_half_y;
    row_x_[py] = cam.up.x * ny, row_y_[py] = cam.up.y * ny, row_z_[py] = cam.up.z * ny;
    row_ny_[py] = ny;
  }

  // 4. Rasterise and count, one task per tile (every pixel belongs to exactly one tile).
  const bool normals = !map.normal.empty();
  const std::size_t W = static_cast<std::size_t>(map.width);
  const float far_depth = cam.far_plane;
  const Planes planes{_mm_set1_ps(cam.near_plane), _mm_set1_ps(cam.far_plane)};
  const __m128 v_far_depth = _mm_set1_ps(far_depth);
  auto tile_task = [&](std::uint32_t task) {
    const std::size_t t = task;
    const int tx = static_cast<int>(t % static_cast<std::size_t>(tiles_x)),
              ty = static_cast<int>(t / static_cast<std::size_t>(tiles_x));
    const int x0 = tx * kT, y0 = ty * kT;
    const int x1 = std::min(x0 + kT, map.width), y1 = std::min(y0 + kT, map.height);
    const int w = x1 - x0, h = y1 - y0;
    const std::uint32_t* items = tile_items_.data() + tile_offset_[t];
    const std::uint32_t m = tile_offset_[t + 1] - tile_offset_[t];
    if (m == 0) {  // background only
      for (int py = y0; py < y1; ++py) {
        const std::size_t row = static_cast<std::size_t>(py) * W + static_cast<std::size_t>(x0);
        std::fill_n(map.ids.data() + row, w, 0u);
        std::fill_n(map.depth.data() + row, w, far_depth);
        if (normals) std::fill_n(map.normal.data() + 3 * row, 3 * w, 0.0f);
      }
      return;
    }
    TileBuffers buf;
    {
      alignas(16) float first[kT];  // +inf on the map, -inf beyond its edge (never hit, never the max)
      for (int i = 0; i < kT; ++i) first[i] = i < w ? kInf : -kInf;
      const __m128i zero = _mm_setzero_si128();
      _mm_storeu_si128(reinterpret_cast<__m128i*>(buf.pad), zero);
      for (int r = 0; r < h; ++r)
        for (int i = 0; i < kT; i += 4) {
          _mm_store_ps(buf.best + r * kT + i, _mm_load_ps(first + i));
          _mm_store_si128(reinterpret_cast<__m128i*>(buf.id + r * kT + i), zero);
          _mm_store_si128(reinterpret_cast<__m128i*>(buf.slot + r * kT + i), zero);
        }
    }
    std::uint32_t dirs_ready = 0;  // bit r: row r's rays are filled
    auto fill_rays = [&](int r) {
      const std::size_t py = static_cast<std::size_t>(y0 + r);
      const float ux = row_x_[py], uy = row_y_[py], uz = row_z_[py];
      const float *cx = col_x_.data() + x0, *cy = col_y_.data() + x0, *cz = col_z_.data() + x0;
      for (int i = 0; i < kT; ++i) {
        const float ex = cx[i] + ux, ey = cy[i] + uy, ez = cz[i] + uz;
        buf.dx[r * kT + i] = ex, buf.dy[r * kT + i] = ey, buf.dz[r * kT + i] = ez;
        buf.a[r * kT + i] = ex * ex + ey * ey + ez * ez;
      }
    };
    // The largest nearest-hit depth in the tile; recomputed now and then (it only falls).
    float tile_max = kInf;
    bool changed = false;

    for (std::uint32_t j = 0; j < m; ++j) {
      const Prepared& p = prep_[items[j]];
      if (changed && (j & 7) == 0) {
        __m128 mx = _mm_set1_ps(-kInf);
        for (int q = 0; q < h * kT; q += 4) mx = _mm_max_ps(mx, _mm_load_ps(buf.best + q));
        tile_max = hmax(mx);
        changed = false;
      }
      // Every hit on this sphere has t >= near_depth, on every later one t >= key_floor: once they
      // are beyond every pixel's nearest hit so far, nothing here can change.
      if (p.near_depth > tile_max) {
        if (p.key_floor > tile_max) break;
        continue;
      }
      const Lanes lanes{_mm_set1_ps(p.ox),
                        _mm_set1_ps(p.oy),
                        _mm_set1_ps(p.oz),
                        _mm_set1_ps(p.c),
                        _mm_set1_epi32(static_cast<int>(p.id)),
                        _mm_set1_epi32(static_cast<int>(j + 1))};
      const int ra = std::max(y0, p.y0) - y0, rb = std::min(y1, p.y1) - y0;
      const int ca = std::max(x0, p.x0) - x0, cb = std::min(x1, p.x1) - x0;
      for (std::uint32_t need = ((rb - ra == 32 ? ~0u : (1u << (rb - ra)) - 1u) << ra) & ~dirs_ready; need;
           need &= need - 1)
        fill_rays(std::countr_zero(need));
      dirs_ready |= (rb - ra == 32 ? ~0u : (1u << (rb - ra)) - 1u) << ra;
      __m128 any = _mm_setzero_ps();
      if (cb - ca <= 16) {
        // Small: the same window of k groups on every row (no per-row decisions, no branches).
        const int k = (cb - ca + 3) >> 2, wa = std::min(ca, kT - 4 * k);
        for (int r = ra; r < rb; ++r)
          for (int g = 0; g < k; ++g) any = _mm_or_ps(any, shade_in<false>(buf, r * kT + wa + 4 * g, lanes, planes));
      } else {
        // Large: per row, the aligned groups around the row's span that some pixel is open in.
        const __m128 near_depth = _mm_set1_ps(p.near_depth);
        for (int r = ra; r < rb; ++r) {
          int xa = ca, xb = cb;
          if (p.spans) {
            const double ny = row_ny_[static_cast<std::size_t>(y0 + r)];
            const double e = p.e0 + ny * (p.e1 + ny * p.e2);
            if (e < 0) continue;  // the row misses the widened sphere
            if (e <= std::numeric_limits<double>::max()) {
              const double hw = std::sqrt(e), cx = p.m0 + p.m1 * ny - x0;
              const double lo = std::ceil(cx - hw - kPixelMargin), hi = std::floor(cx + hw + kPixelMargin) + 1;
              if (lo > xa) xa = static_cast<int>(std::min(lo, static_cast<double>(xb)));
              if (hi < xb) xb = static_cast<int>(std::max(hi, static_cast<double>(xa)));
            }
          }
          for (int i = xa & ~3; i < xb; i += 4) {
            if (_mm_movemask_ps(_mm_cmpge_ps(_mm_load_ps(buf.best + r * kT + i), near_depth)) == 0) continue;
            any = _mm_or_ps(any, shade_in<true>(buf, r * kT + i, lanes, planes));
          }
        }
      }
      changed |= _mm_movemask_ps(any) != 0;
    }

    // Write out row by row (background depth = far plane), and count the row's runs of equal
    // slots into the tile's counts (slot 0 is the background).
    std::uint32_t* counts = tile_counts_.data() + tile_offset_[t] + t;
    std::fill_n(counts, m + 1, 0u);
    for (int r = 0; r < h; ++r) {
      const std::size_t row = static_cast<std::size_t>(y0 + r) * W + static_cast<std::size_t>(x0);
      const float* best = buf.best + r * kT;
      const std::uint32_t* ids = buf.id + r * kT;
      std::uint32_t* out_ids = map.ids.data() + row;
      float* out_depth = map.depth.data() + row;
      int i = 0;
      for (; i + 4 <= w; i += 4) {
        const __m128i vi = _mm_load_si128(reinterpret_cast<const __m128i*>(ids + i));
        const __m128 none = _mm_castsi128_ps(_mm_cmpeq_epi32(vi, _mm_setzero_si128()));
        _mm_storeu_si128(reinterpret_cast<__m128i*>(out_ids + i), vi);
        _mm_storeu_ps(out_depth + i, select(none, v_far_depth, _mm_load_ps(best + i)));
      }
      for (; i < w; ++i) {
        out_ids[i] = ids[i];
        out_depth[i] = ids[i] ? best[i] : far_depth;
      }
      // Runs: bit i set where slot[i] differs from slot[i - 1] (bit 0 always).
      const std::uint32_t* slots = buf.slot + r * kT;
      std::uint32_t starts = 0;
      for (int g = 0; g < kT; g += 4) {
        const __m128i cur = _mm_load_si128(reinterpret_cast<const __m128i*>(slots + g));
        const __m128i prev = _mm_loadu_si128(reinterpret_cast<const __m128i*>(slots + g - 1));
        const int same = _mm_movemask_ps(_mm_castsi128_ps(_mm_cmpeq_epi32(cur, prev)));
        starts |= static_cast<std::uint32_t>(~same & 0xF) << g;
      }
      starts |= 1u;
      if (w < kT) starts &= (1u << w) - 1u;
      int start = 0;
      starts &= starts - 1u;
      while (starts) {
        const int next = std::countr_zero(starts);
        counts[slots[start]] += static_cast<std::uint32_t>(next - start);
        start = next;
        starts &= starts - 1u;
      }
      counts[slots[start]] += static_cast<std::uint32_t>(w - start);
      if (normals)
        for (int px = x0; px < x1; ++px) write_normal(cam, spheres, map, px, y0 + r);
    }
  };
  if (threads_for(tiles * kT * kT, threads) == 1) {
    for (std::size_t t = 0; t < tiles; ++t) tile_task(static_cast<std::uint32_t>(t));
  } else {
    run_tasks(static_cast<std::uint32_t>(tiles), tile_task);
  }

  // 5. Pixel counts per object: the sum of its tiles' counts.
  map.counts.assign(n, 0);
  for (std::size_t t = 0; t < tiles; ++t) {
    const std::uint32_t* counts = tile_counts_.data() + tile_offset_[t] + t + 1;
    const std::uint32_t* items = tile_items_.data() + tile_offset_[t];
    const std::uint32_t m = tile_offset_[t + 1] - tile_offset_[t];
    for (std::uint32_t j = 0; j < m; ++j) map.counts[items[j]] += counts[j];
  }
  map.has_counts = true;
}

}  // namespace viscd::detail
