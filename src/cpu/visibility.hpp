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
#include "cpu/simd.hpp"

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

/// count_ids()'s buffers, kept between frames.
struct CountScratch {
  /// Ids per histogram segment: a segment (256 KiB) stays in a core's cache while it is counted.
  static constexpr std::size_t kSegment = std::size_t{1} << 17;
  /// One block's runs (ids, start pixels, lengths; bucket entries), per range of pixels.
  struct Runs {
    std::vector<std::uint32_t> id, start, len;
    std::vector<std::uint64_t> entry;
  };
  std::vector<Runs> runs;
  /// Few objects: per range of pixels but the first, a histogram of its own.
  std::vector<std::vector<std::uint32_t>> hist;
  /// Many objects: per range of pixels and segment, its runs but the background's as
  /// (id << 32 | length), and where they end; per range, the pixels of those runs.
  std::vector<std::vector<std::uint64_t>> buckets;
  std::vector<std::uint64_t*> ends;
  std::vector<std::uint64_t> foreground;
  [[nodiscard]] std::uint64_t memory_bytes() const {
    std::uint64_t b = ends.capacity() * sizeof(std::uint64_t*) + foreground.capacity() * sizeof(std::uint64_t);
    for (const auto& r : runs)
      b += (r.id.capacity() + r.start.capacity() + r.len.capacity()) * sizeof(std::uint32_t) +
           r.entry.capacity() * sizeof(std::uint64_t);
    for (const auto& v : hist) b += v.capacity() * sizeof(std::uint32_t);
    for (const auto& v : buckets) b += v.capacity() * sizeof(std::uint64_t);
    return b;
  }
};

/// Stage 2 over an id map (the detector's own or the caller's): hist[id] = the pixels holding id,
/// for id in [0, objects] (0 = background), and hist[objects + 1] = the pixels whose id exceeds
/// `objects`. Returns false when there are any. The map is read once, as runs of equal ids found
/// a block at a time without branches (16 pixels a step with AVX-512 when `simd` allows it), in
/// ranges of pixels on `threads` threads. With few objects (at most CountScratch::kSegment slots)
/// each range adds its runs into a histogram of its own, summed after; with more, the runs are
/// sorted into segments of ids first and each segment is counted while it stays in cache
/// (docs/architecture.md, "Counting pixels"). Needs objects < 2^32 - 2 and fewer than 2^32 pixels.
[[nodiscard]] bool count_ids(std::span<const std::uint32_t> ids, std::size_t objects, int threads,
                             std::vector<std::uint32_t>& hist, CountScratch& scratch,
                             SimdLevel simd = SimdLevel::avx512);

/// cull_in_parallel()'s buffers, kept between frames: per range of objects, its active ones and
/// the sum of its counts.
struct CullScratch {
  std::vector<std::vector<std::uint32_t>> active;
  std::vector<std::uint64_t> counted;
  [[nodiscard]] std::uint64_t memory_bytes() const {
    std::uint64_t b = counted.capacity() * sizeof(std::uint64_t);
    for (const auto& v : active) b += v.capacity() * sizeof(std::uint32_t);
    return b;
  }
};

/// Stage 3 as cull_and_choose_bits(), on `threads` threads: ranges of objects each cull into a
/// list of their own (cull_range()), concatenated in order. The same pixels, active set, mu and m.
int cull_in_parallel(std::span<const std::uint32_t> counts, double pixel_scale, const Config& config,
                     std::span<const std::uint8_t> always_active, int threads, std::vector<float>& pixels,
                     std::vector<std::uint32_t>& active, CullScratch& scratch, FrameStats& stats);

/// Stage 2: pixels per object over the map: the rasterizer's counts when it left them for
/// `objects` objects, else count_ids() over the id map (`hist`, `scratch`: its buffers, reused).
void count_pixels(const VisibilityMap& map, std::size_t objects, int threads, std::vector<std::uint32_t>& counts,
                  std::vector<std::uint32_t>& hist, CountScratch& scratch);

/// Stage 9: lit objects, red colliding, blue free, yellow culled, grey static (ids above
/// state.size()); dark background. RGBA8.
void shade(const CameraRig& cam, const VisibilityMap& map, std::span<const ObjectState> state, int threads,
           std::vector<std::uint8_t>& rgba);

}  // namespace viscd::detail
