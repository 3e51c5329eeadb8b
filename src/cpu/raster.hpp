#pragma once
// The cpu backend's visibility map: spheres binned into 32x32-pixel tiles by a conservative
// screen rectangle, tiles rasterised in parallel. Each pixel keeps the nearest hit, ties to the
// smaller id, with the same hit() as the reference, so both maps are equal bit for bit.

#include <cstdint>
#include <span>
#include <vector>

#include "cpu/visibility.hpp"

namespace viscd::detail {

class TiledRasterizer {
 public:
  /// Tile edge in pixels.
  static constexpr int kTile = 32;
  /// Fills map (already sized to the rig's map) from the spheres. Not thread-safe.
  void run(const CameraRig& cam, std::span<const Sphere> spheres, int threads, VisibilityMap& map);
  /// Bytes of the binning buffers.
  [[nodiscard]] std::uint64_t memory_bytes() const {
    return rects_.capacity() * sizeof(PixelRect) +
           (tile_count_.capacity() + tile_offset_.capacity() + tile_items_.capacity()) * sizeof(std::uint32_t);
  }

 private:
  std::vector<PixelRect> rects_;
  std::vector<std::uint32_t> tile_count_, tile_offset_, tile_items_;
};

}  // namespace viscd::detail
