#pragma once
// The tile pass of the cpu rasterizer (cpu/raster.hpp): one task per 32x32-pixel tile runs
// hit() for the tile's spheres in depth order, writes the tile's pixels to the map and counts
// them per sphere. Two kernels give the same bits: SSE2 (every x86-64; groups of 4 pixels) and
// AVX-512 (rows of 16 pixels), chosen at run time by the detector's level (Config::simd, cpu/simd.hpp). What both
// share is here.

#include <algorithm>
#include <cstdint>
#include <limits>
#include <span>

#include "cpu/raster.hpp"
#include "cpu/simd.hpp"
#include "cpu/visibility.hpp"

namespace viscd::detail {

/// What every tile task reads (and where it writes), set up once per frame by run().
struct TileJob {
  const CameraRig* cam;
  std::span<const Sphere> spheres;  // for the normals
  VisibilityMap* map;
  int tiles_x;
  const TiledRasterizer::Prepared* prep;  // the visible spheres in depth order
  const std::uint32_t* items;             // per tile, its spheres (indices into prep) in depth order
  const std::uint32_t* offset;            // tile t's items are [offset[t], offset[t + 1])
  std::uint32_t* counts;                  // tile t's pixels per item at offset[t] + t (+1: 0 is background)
  // The rays: dir() = (forward + right nx) + up ny, per column (padded to whole tiles) and row.
  const float *col_x, *col_y, *col_z, *row_x, *row_y, *row_z;
  const std::uint8_t* background;  // tiles written as background only by the last run
  bool keep_background;            // ... and the map still holds them
  // The occluder's ids and depth (TiledRasterizer::run()), rows of the map's width; null: none.
  const std::uint32_t* occluder_ids = nullptr;
  const float* occluder_depth = nullptr;
};

/// The id an occluded pixel starts with: above every sphere's (ids < 2^31), so that a sphere at
/// the occluder's depth takes the pixel.
inline constexpr std::uint32_t kOccluderId = 0x7FFFFFFFu;

/// Tile edge in pixels.
inline constexpr int kTileSide = TiledRasterizer::kTile;
/// Slots a tile counts on its stack (longer lists count in place).
inline constexpr std::uint32_t kLocalCounts = 1024;

/// A tile's working set, on the stack of the task that rasterises it.
struct alignas(64) TileBuffers {
  static constexpr int kT = kTileSide;
  float best[kT * kT];          // nearest hit so far: +inf none, -inf outside the map
  std::uint32_t id[kT * kT];    // its object id (0 none)
  std::uint32_t pad[16];        // zero: slot[-1] is read (and ignored) by the run detection
  std::uint32_t slot[kT * kT];  // its position in the tile's list + 1 (0 none): counted per tile
  // The rays of the tile's pixels: CameraRig::dir() and |dir|^2, filled per row when first needed.
  float dx[kT * kT], dy[kT * kT], dz[kT * kT], a[kT * kT];
};

/// Tile t's pixels: columns [x0, x1), rows [y0, y1).
struct TileRect {
  int x0, y0, x1, y1;
};
[[nodiscard]] TileRect tile_rect(const TileJob& job, std::uint32_t t);

/// Writes tile t as background (id 0, depth = far plane, normal 0) unless the last run left it
/// so and the map still holds it.
void write_background_tile(const TileJob& job, std::uint32_t t);

/// The order in which a tile's kernel works through its spheres (front to back) lets it stop
/// early: every hit on a sphere has t >= near_depth, on every later one t >= key_floor, so once
/// they lie beyond every pixel's nearest hit so far nothing can change. The tile's largest
/// nearest-hit depth is recomputed every 8 spheres once it is finite, and ever less often while
/// some pixel has no hit (it only falls).
class DepthCut {
 public:
  enum class Verdict { draw, skip, stop };
  /// Whether the kernel must give refresh() the tile's largest depth before sphere j.
  [[nodiscard]] bool stale(std::uint32_t j) const { return changed_ && j == next_check_; }
  void refresh(float tile_max) { tile_max_ = tile_max, changed_ = false; }
  /// What to do with sphere j (after any refresh).
  Verdict verdict(std::uint32_t j, const TiledRasterizer::Prepared& p) {
    if (j == next_check_) next_check_ = tile_max_ == kInfinity ? 2 * j : j + 8;
    if (p.near_depth > tile_max_) return p.key_floor > tile_max_ ? Verdict::stop : Verdict::skip;
    return Verdict::draw;
  }
  /// Some pixel got a nearer hit.
  void changed() { changed_ = true; }

 private:
  static constexpr float kInfinity = std::numeric_limits<float>::infinity();
  float tile_max_ = kInfinity;
  bool changed_ = false;
  std::uint32_t next_check_ = 8;
};

/// A sphere's rectangle in a tile, in tile coordinates: rows [ra, rb), columns [ca, cb); bit r of
/// `rows` set for its rows.
struct TileSpan {
  int ra, rb, ca, cb;
  std::uint32_t rows;
};
inline TileSpan tile_span(const TileRect& tr, const TiledRasterizer::Prepared& p) {
  TileSpan s{std::max(tr.y0, p.y0) - tr.y0, std::min(tr.y1, p.y1) - tr.y0, std::max(tr.x0, p.x0) - tr.x0,
             std::min(tr.x1, p.x1) - tr.x0, 0};
  s.rows = (s.rb - s.ra == kTileSide ? ~0u : (1u << (s.rb - s.ra)) - 1u) << s.ra;
  return s;
}

/// Adds one row's runs of equal slots to counts: bit i of `starts` is set where slots[i] differs
/// from slots[i - 1] (and bit 0), for the row's first w pixels.
inline void add_runs(std::uint32_t starts, const std::uint32_t* slots, int w, std::uint32_t* counts) {
  if (w < kTileSide) starts &= (1u << w) - 1u;
  int start = 0;
  starts &= starts - 1u;
  while (starts) {
    const int next = __builtin_ctz(starts);
    counts[slots[start]] += static_cast<std::uint32_t>(next - start);
    start = next;
    starts &= starts - 1u;
  }
  counts[slots[start]] += static_cast<std::uint32_t>(w - start);
}

/// A tile's pixel counts per item (slot 0: the background). Counted on the task's stack and
/// copied out by finish(): the regions of tiles side by side share cache lines, and counting
/// there from two threads would move them between the cores at every run. Lists of
/// kLocalCounts items or more count in place.
class TileCounts {
 public:
  TileCounts(const TileJob& job, std::uint32_t t, std::uint32_t m)
      : out_(job.counts + job.offset[t] + t), counts_(m < kLocalCounts ? local_ : out_), size_(m + 1) {
    std::fill_n(counts_, size_, 0u);
  }
  TileCounts(const TileCounts&) = delete;
  TileCounts& operator=(const TileCounts&) = delete;
  [[nodiscard]] std::uint32_t* data() { return counts_; }
  void finish() {
    if (counts_ != out_) std::copy_n(counts_, size_, out_);
  }

 private:
  std::uint32_t local_[kLocalCounts];
  std::uint32_t* out_;
  std::uint32_t* counts_;
  std::uint32_t size_;
};

/// The tile pass for tile t with SSE2.
void raster_tile_sse2(const TileJob& job, std::uint32_t t);
#if VISCD_HAVE_AVX512
/// The same with AVX-512F; call only when best_simd_level() is avx512.
void raster_tile_avx512(const TileJob& job, std::uint32_t t);
#endif

}  // namespace viscd::detail
