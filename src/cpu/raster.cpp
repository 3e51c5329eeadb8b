#include "cpu/raster.hpp"

#include <algorithm>
#include <atomic>
#include <limits>

#include "cpu/parallel.hpp"

namespace viscd::detail {

void TiledRasterizer::run(const CameraRig& cam, std::span<const Sphere> spheres, int threads, VisibilityMap& map) {
  const std::size_t n = spheres.size();
  const int tiles_x = (map.width + kTile - 1) / kTile, tiles_y = (map.height + kTile - 1) / kTile;
  const std::size_t tiles = static_cast<std::size_t>(tiles_x) * static_cast<std::size_t>(tiles_y);
  rects_.resize(n);
  tile_count_.assign(tiles, 0);
  tile_offset_.resize(tiles + 1);

  // Bin: rectangle per sphere, count per tile, scan, scatter. The order inside a bin is not
  // deterministic; the (depth, id) comparison below makes the result independent of it.
  parallel_for(n, threads, [&](std::size_t k) {
    const PixelRect r = sphere_rect(cam, spheres[k]);
    rects_[k] = r;
    if (r.x0 >= r.x1 || r.y0 >= r.y1) return;
    for (int ty = r.y0 / kTile; ty <= (r.y1 - 1) / kTile; ++ty)
      for (int tx = r.x0 / kTile; tx <= (r.x1 - 1) / kTile; ++tx)
        std::atomic_ref<std::uint32_t>(tile_count_[static_cast<std::size_t>(ty * tiles_x + tx)])
            .fetch_add(1, std::memory_order_relaxed);
  });
  std::uint32_t sum = 0;
  for (std::size_t t = 0; t < tiles; ++t) {
    tile_offset_[t] = sum;
    sum += tile_count_[t];
  }
  tile_offset_[tiles] = sum;
  tile_items_.resize(sum);
  std::copy(tile_offset_.begin(), tile_offset_.end() - 1, tile_count_.begin());  // becomes the cursor
  parallel_for(n, threads, [&](std::size_t k) {
    const PixelRect r = rects_[k];
    if (r.x0 >= r.x1 || r.y0 >= r.y1) return;
    for (int ty = r.y0 / kTile; ty <= (r.y1 - 1) / kTile; ++ty)
      for (int tx = r.x0 / kTile; tx <= (r.x1 - 1) / kTile; ++tx) {
        const std::uint32_t slot =
            std::atomic_ref<std::uint32_t>(tile_count_[static_cast<std::size_t>(ty * tiles_x + tx)])
                .fetch_add(1, std::memory_order_relaxed);
        tile_items_[slot] = static_cast<std::uint32_t>(k);
      }
  });

  // Rasterise tiles in parallel; every pixel belongs to exactly one tile.
  const bool normals = !map.normal.empty();
  const std::size_t W = static_cast<std::size_t>(map.width);
  // One task per tile: tiles differ a lot in work, and small tasks balance it.
  auto tile_task = [&](std::uint32_t task) {
    const std::size_t t = task;
    const int tx = static_cast<int>(t % static_cast<std::size_t>(tiles_x)),
              ty = static_cast<int>(t / static_cast<std::size_t>(tiles_x));
    const int x0 = tx * kTile, y0 = ty * kTile;
    const int x1 = std::min(x0 + kTile, map.width), y1 = std::min(y0 + kTile, map.height);
    float best[kTile * kTile];
    std::uint32_t best_id[kTile * kTile];
    std::fill(best, best + kTile * kTile, std::numeric_limits<float>::infinity());
    std::fill(best_id, best_id + kTile * kTile, 0u);
    // Front to back, so that the early depth test below rejects most hidden work.
    std::uint32_t* items = tile_items_.data() + tile_offset_[t];
    std::uint32_t* items_end = tile_items_.data() + tile_offset_[t + 1];
    std::sort(items, items_end, [&](std::uint32_t p, std::uint32_t q) {
      return rects_[p].near_depth < rects_[q].near_depth || (rects_[p].near_depth == rects_[q].near_depth && p < q);
    });
    // The map pixel's ray direction factors, with exactly CameraRig::dir()'s expressions.
    float nxs[kTile], nys[kTile];
    for (int i = 0; i < kTile; ++i) {
      nxs[i] = (2.0f * (static_cast<float>(x0 + i) + 0.5f) / static_cast<float>(cam.map_w) - 1.0f) * cam.tan_half_x;
      nys[i] = (1.0f - 2.0f * (static_cast<float>(y0 + i) + 0.5f) / static_cast<float>(cam.map_h)) * cam.tan_half_y;
    }
    const Vec3 f = cam.forward, rt = cam.right, up = cam.up;
    const float near = cam.near_plane, far = cam.far_plane;
    for (const std::uint32_t* item = items; item != items_end; ++item) {
      const std::uint32_t k = *item;
      const Sphere& s = spheres[k];
      const PixelRect& r = rects_[k];
      const std::uint32_t id = k + 1;
      // hit()'s per-sphere terms, same expressions and order, so results match it bit for bit.
      const float ox = cam.eye.x - s.x, oy = cam.eye.y - s.y, oz = cam.eye.z - s.z;
      const float c = ox * ox + oy * oy + oz * oz - s.r * s.r;
      const int xa = std::max(x0, r.x0) - x0, xb = std::min(x1, r.x1) - x0;
      for (int py = std::max(y0, r.y0); py < std::min(y1, r.y1); ++py) {
        float* brow = best + (py - y0) * kTile;
        std::uint32_t* irow = best_id + (py - y0) * kTile;
        // Early depth test per row: skip it when every pixel already has a nearer hit.
        bool open = false;
        for (int i = xa; i < xb; ++i) open |= !(brow[i] < r.near_depth);
        if (!open) continue;
        const float ny = nys[py - y0];
        // Branch-free body (vectorises): both roots, then the same choice hit() makes.
        for (int i = xa; i < xb; ++i) {
          const float nx = nxs[i];
          const float dx = f.x + rt.x * nx + up.x * ny, dy = f.y + rt.y * nx + up.y * ny,
                      dz = f.z + rt.z * nx + up.z * ny;
          const float a = dx * dx + dy * dy + dz * dz;
          const float b = ox * dx + oy * dy + oz * dz;
          const float disc = b * b - a * c;
          const bool real = disc >= 0.0f;
          const float sq = std::sqrt(real ? disc : 0.0f);
          const float t0 = (-b - sq) / a, t1 = (-b + sq) / a;
          // Bitwise & and | (no short circuit) keep the body free of branches.
          const bool in0 = (t0 >= near) & (t0 <= far);
          const bool in1 = (t1 >= near) & (t1 <= far);
          const float h = in0 ? t0 : (in1 ? t1 : -1.0f);
          const float bb = brow[i];
          const std::uint32_t bi = irow[i];
          const bool better = real & (h >= 0.0f) & ((h < bb) | ((h == bb) & (id < bi)));
          brow[i] = better ? h : bb;
          irow[i] = better ? id : bi;
        }
      }
    }
    // Copy out row by row; branch-free so it vectorises (background depth = far plane).
    const float far_depth = cam.far_plane;
    for (int py = y0; py < y1; ++py) {
      const std::size_t row = static_cast<std::size_t>(py) * W;
      const float* brow = best + (py - y0) * kTile;
      const std::uint32_t* irow = best_id + (py - y0) * kTile;
      std::uint32_t* ids = map.ids.data() + row + x0;
      float* depth = map.depth.data() + row + x0;
      for (int i = 0; i < x1 - x0; ++i) {
        ids[i] = irow[i];
        depth[i] = irow[i] ? brow[i] : far_depth;
      }
      if (normals)
        for (int px = x0; px < x1; ++px) write_normal(cam, spheres, map, px, py);
    }
  };
  if (threads_for(tiles * kTile * kTile, threads) == 1) {
    for (std::size_t t = 0; t < tiles; ++t) tile_task(static_cast<std::uint32_t>(t));
  } else {
    run_tasks(static_cast<std::uint32_t>(tiles), tile_task);
  }
}

}  // namespace viscd::detail
