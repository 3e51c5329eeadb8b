#pragma once
// The cpu backend's visibility map (stage 1) with the pixel counts (stage 2) fused into it.
// Spheres are sorted front to back by a coarse depth key and binned into 32x32-pixel tiles by a
// conservative rectangle (the projection of the sphere widened as hit()'s rounding requires);
// tiles are rasterised in parallel, by an SSE2 or an AVX-512 kernel (cpu/raster_tile.hpp) that
// runs hit() over each sphere's rectangle in the tile, skipping the pixels outside the disc or
// already nearer before the square root and division. The expressions are hit()'s,
// so the map equals the reference's bit for bit (nearest hit, ties to the smaller id). Each tile
// counts its pixels per object while it streams its rows to the map; background tiles it wrote
// in the last frame are left as they are while the map still holds them (VisibilityMap::stamp).

#include <cstdint>
#include <span>
#include <vector>

#include "cpu/simd.hpp"
#include "cpu/visibility.hpp"

namespace viscd::detail {

class TiledRasterizer {
 public:
  /// Tile edge in pixels.
  static constexpr int kTile = 32;
  /// Fills map (already sized to the rig's map) from the spheres, and map.counts with the pixels
  /// of each sphere (map.has_counts). Not thread-safe. With an occluder (a layer of the same size
  /// drawn with the same rig: the static set's), each pixel starts at the occluder's depth where
  /// it has an object, and a sphere takes the pixel only when it is as near or nearer (a tie goes
  /// to the sphere, as in the merged map): the map and counts are then the spheres' visible
  /// pixels, with the occluded ones as background.
  void run(const CameraRig& cam, std::span<const Sphere> spheres, int threads, VisibilityMap& map,
           const VisibilityMap* occluder = nullptr);
  /// Bytes of the binning buffers.
  [[nodiscard]] std::uint64_t memory_bytes() const;
  /// After run(): whether tile t (row-major, kTile x kTile pixels, ceil(width / kTile) to a row)
  /// holds no sphere's pixel: it is all background.
  [[nodiscard]] bool tile_is_background(std::size_t t) const { return background_[t] != 0; }
  /// The tile kernel's instruction set (Config::simd; default: the best this CPU has). The
  /// kernels give the same map bit for bit; below SSE2 the SSE2 kernel runs.
  void set_simd(SimdLevel level) { simd_ = usable_simd_level(level); }

  /// What a tile needs of a sphere, prepared once per frame.
  struct Prepared {
    // hit()'s per-sphere terms (eye - centre, and |eye - centre|^2 - r^2), same float expressions.
    float ox, oy, oz, c;
    /// Lower bound of any hit's depth; and of every later sphere's in the depth order.
    float near_depth, key_floor;
    std::uint32_t id;  // index + 1
    std::int32_t x0, y0, x1, y1;
  };

 private:
  SimdLevel simd_ = best_simd_level();
  /// A sphere's rectangle and depth bound, by sphere index.
  struct Bound {
    std::uint16_t x0, y0, x1, y1;
    float near_depth;
  };
  std::vector<Bound> bounds_;
  std::vector<Prepared> prep_;  // the visible spheres in depth order
  std::vector<std::uint16_t> keys_;
  std::vector<std::uint32_t> order_;
  std::vector<std::uint16_t> key_range_;  // per chunk: smallest and largest key seen
  std::vector<std::uint32_t> bucket_count_;
  std::vector<std::uint32_t> chunk_tile_count_, tile_offset_, tile_items_, tile_counts_;
  std::vector<float> col_x_, col_y_, col_z_, row_x_, row_y_, row_z_;
  // Tiles written as background only (ids 0, depth far, normals 0) under stamp_.
  std::vector<std::uint8_t> background_;
  std::uint64_t stamp_ = 0;
  float background_far_ = 0;
};

}  // namespace viscd::detail
