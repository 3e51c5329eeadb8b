#pragma once
// The CPU side of the visibility map: the map itself, the reference ray caster (the oracle),
// pixel counts (stage 2) and shading (stage 9), shared by the reference and cpu backends. The cpu
// backend's fast rasterizer is cpu/raster.hpp; the camera, hit() and the culling rule are
// core/visibility.hpp.

#include <cstddef>
#include <cstdint>
#include <new>
#include <span>
#include <vector>

#include "core/shapes.hpp"
#include "core/visibility.hpp"

namespace viscd::detail {

/// Storage in whole cache lines (64-byte aligned), so that the rasterizer can stream map rows
/// to memory line by line.
template <class T>
struct CacheAligned {
  using value_type = T;
  static constexpr std::align_val_t kAlign{64};
  CacheAligned() = default;
  template <class U>
  CacheAligned(const CacheAligned<U>&) noexcept {}  // NOLINT(google-explicit-constructor)
  T* allocate(std::size_t n) { return static_cast<T*>(::operator new(n * sizeof(T), kAlign)); }
  void deallocate(T* p, std::size_t) noexcept { ::operator delete(p, kAlign); }
  template <class U>
  bool operator==(const CacheAligned<U>&) const noexcept {
    return true;
  }
};

/// The id map (object index + 1, 0 = background) and view depth of each map pixel; normals
/// (unit, world space, 3 floats per pixel) only when asked for (shading). A rasterizer that counts
/// pixels per object while writing the map (the cpu backend's) leaves them in `counts` and sets
/// `has_counts`; resize() clears it, so counts never outlive the map they were taken from.
/// `stamp` names the content: the cpu rasterizer sets a new one whenever it writes the map, and
/// next time leaves alone the background tiles it wrote if the stamp is still its own. Anything
/// else that writes the map must set it to 0 (resize() does when the size or the normals change).
struct VisibilityMap {
  int width = 0, height = 0;
  std::vector<std::uint32_t, CacheAligned<std::uint32_t>> ids;
  std::vector<float, CacheAligned<float>> depth;
  std::vector<float> normal;
  std::vector<std::uint32_t> counts;
  bool has_counts = false;
  std::uint64_t stamp = 0;
  void resize(int w, int h, bool with_normals);
  /// Bytes held (capacities).
  [[nodiscard]] std::uint64_t memory_bytes() const {
    return (ids.capacity() + counts.capacity()) * sizeof(std::uint32_t) +
           (depth.capacity() + normal.capacity()) * sizeof(float);
  }
};

/// Fills the normal of a map pixel from its id and depth (a box: the normal of the face nearest
/// the hit point).
void write_normal(const CameraRig& cam, const Shapes& objects, VisibilityMap& map, int px, int py);

/// The reference rasterizer: for every pixel, every object (hit(), hit_box()). O(W H N); the oracle.
void rasterize_reference(const CameraRig& cam, const Shapes& objects, VisibilityMap& map);

/// The cpu backend's map of boxes: each box's conservative rectangle (box_rect()), the boxes
/// binned by bands of kBand rows, and per band, in parallel, hit_box() over each box's pixels in
/// index order, so the map equals the reference's bit for bit (nearest hit, ties to the smaller
/// id). O(N + the pixels of the rectangles). Counts are left to count_pixels().
class BoxRasterizer {
 public:
  static constexpr int kBand = 16;
  void run(const CameraRig& cam, std::span<const Box> boxes, int threads, VisibilityMap& map);
  [[nodiscard]] std::uint64_t memory_bytes() const {
    return rects_.capacity() * sizeof(PixelRect) + (band_start_.capacity() + fill_.capacity()) * sizeof(std::size_t) +
           items_.capacity() * sizeof(std::uint32_t);
  }

 private:
  std::vector<PixelRect> rects_;
  std::vector<std::size_t> band_start_, fill_;
  std::vector<std::uint32_t> items_;
};

/// count_ids()'s buffers, kept between frames: per range of rows but the first, a histogram (all
/// zero between calls) and the ids it touched.
struct CountScratch {
  std::vector<std::vector<std::uint32_t>> hist, touched;
  [[nodiscard]] std::uint64_t memory_bytes() const {
    std::uint64_t b = 0;
    for (const auto& v : hist) b += v.capacity() * sizeof(std::uint32_t);
    for (const auto& v : touched) b += v.capacity() * sizeof(std::uint32_t);
    return b;
  }
};

/// Stage 2 over an id map (the detector's own or the caller's): hist[id] = the pixels holding id,
/// for id in [0, objects] (0 = background), and hist[objects + 1] = the pixels whose id exceeds
/// `objects`. Returns false when there are any. Counts runs of equal ids, 16 pixels at a time.
/// With few objects for the pixels (objects + 2 <= pixels / 32) in parallel, four contiguous
/// ranges of rows per thread: the first adds into `hist`, the others into histograms of their own
/// whose touched entries are added after; else on the calling thread. Needs objects < 2^32 - 2.
[[nodiscard]] bool count_ids(std::span<const std::uint32_t> ids, std::size_t objects, int threads,
                             std::vector<std::uint32_t>& hist, CountScratch& scratch);

/// Stage 2: pixels per object over the map: the rasterizer's counts when it left them for
/// `objects` objects, else count_ids() over the id map (`hist`, `scratch`: its buffers, reused).
void count_pixels(const VisibilityMap& map, std::size_t objects, int threads, std::vector<std::uint32_t>& counts,
                  std::vector<std::uint32_t>& hist, CountScratch& scratch);

/// Stage 9: lit objects, red colliding, blue free, yellow culled, grey static (ids above
/// state.size()); dark background. RGBA8.
void shade(const CameraRig& cam, const VisibilityMap& map, std::span<const ObjectState> state, int threads,
           std::vector<std::uint8_t>& rgba);

}  // namespace viscd::detail
