#include "cpu/visibility.hpp"

#include <algorithm>
#include <atomic>
#include <bit>
#include <cmath>
#include <limits>
#include <new>

#include "cpu/parallel.hpp"
#include "viscd/assert.hpp"

namespace viscd::detail {
namespace {

float dot(Vec3 a, Vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }

}  // namespace

void VisibilityMap::resize(int w, int h, bool with_normals) {
  if (w != width || h != height || with_normals != !normal.empty()) stamp = 0;
  width = w;
  height = h;
  const auto n = static_cast<std::size_t>(w) * static_cast<std::size_t>(h);
  ids.resize(n);
  depth.resize(n);
  normal.resize(with_normals ? 3 * n : 0);
  has_counts = false;
}

void write_normal(const CameraRig& cam, const Shapes& objects, VisibilityMap& map, int px, int py) {
  const std::size_t i =
      static_cast<std::size_t>(py) * static_cast<std::size_t>(map.width) + static_cast<std::size_t>(px);
  float* n = &map.normal[3 * i];
  const std::uint32_t id = map.ids[i];
  if (id == 0) {
    n[0] = n[1] = n[2] = 0;
    return;
  }
  const Vec3 d = cam.dir(px, py);
  const float t = map.depth[i];
  const Vec3 hit_point = {cam.eye.x + t * d.x, cam.eye.y + t * d.y, cam.eye.z + t * d.z};
  if (objects.is_box()) {
    // The face nearest the hit point.
    const Box& b = objects.boxes[id - 1];
    const float p[3] = {hit_point.x, hit_point.y, hit_point.z};
    int axis = 0;
    float sign = -1, best = std::numeric_limits<float>::infinity();
    for (int k = 0; k < 3; ++k) {
      const float to_min = std::fabs(p[k] - b.min[k]), to_max = std::fabs(p[k] - b.max[k]);
      if (to_min < best) best = to_min, axis = k, sign = -1;
      if (to_max < best) best = to_max, axis = k, sign = 1;
    }
    n[0] = n[1] = n[2] = 0;
    n[axis] = sign;
    return;
  }
  const Sphere& s = objects.spheres[id - 1];
  const Vec3 p = {hit_point.x - s.x, hit_point.y - s.y, hit_point.z - s.z};
  const float l = std::sqrt(dot(p, p));
  if (l > 0) {
    n[0] = p.x / l, n[1] = p.y / l, n[2] = p.z / l;
  } else {
    n[0] = -d.x, n[1] = -d.y, n[2] = -d.z;  // a point sphere (r = 0) faces the viewer
  }
}

void rasterize_reference(const CameraRig& cam, const Shapes& objects, VisibilityMap& map) {
  map.stamp = 0;  // (bookkeeping: the content is no longer the cpu rasterizer's)
  for (int py = 0; py < map.height; ++py) {
    for (int px = 0; px < map.width; ++px) {
      const Vec3 d = cam.dir(px, py);
      float best = std::numeric_limits<float>::infinity();
      std::uint32_t best_id = 0;
      for (std::size_t k = 0; k < objects.size(); ++k) {
        const float t = objects.is_box() ? hit_box(cam, d, objects.boxes[k]) : hit(cam, d, objects.spheres[k]);
        if (t >= 0.0f && t < best) {  // ascending k: ties keep the smaller id
          best = t;
          best_id = static_cast<std::uint32_t>(k + 1);
        }
      }
      const std::size_t i =
          static_cast<std::size_t>(py) * static_cast<std::size_t>(map.width) + static_cast<std::size_t>(px);
      map.ids[i] = best_id;
      map.depth[i] = best_id ? best : cam.far_plane;
      if (!map.normal.empty()) write_normal(cam, objects, map, px, py);
    }
  }
}

void BoxRasterizer::run(const CameraRig& cam, std::span<const Box> boxes, int threads, VisibilityMap& map) {
  map.stamp = 0;
  map.has_counts = false;
  const int bands = (map.height + kBand - 1) / kBand;
  // Each box's rectangle, and the boxes binned by band of rows (in ascending index in each band:
  // a counting sort), so that each band's pixels see their boxes in index order.
  rects_.resize(boxes.size());
  parallel_for(boxes.size(), threads, [&](std::size_t k) { rects_[k] = box_rect(cam, boxes[k]); });
  band_start_.assign(static_cast<std::size_t>(bands) + 1, 0);
  for (const PixelRect& r : rects_)
    if (r.x0 < r.x1 && r.y0 < r.y1)
      for (int b = r.y0 / kBand; b <= (r.y1 - 1) / kBand; ++b) ++band_start_[static_cast<std::size_t>(b) + 1];
  for (std::size_t b = 0; b < static_cast<std::size_t>(bands); ++b) band_start_[b + 1] += band_start_[b];
  items_.resize(band_start_.back());
  fill_.assign(band_start_.begin(), band_start_.end() - 1);
  for (std::size_t k = 0; k < rects_.size(); ++k) {
    const PixelRect& r = rects_[k];
    if (r.x0 < r.x1 && r.y0 < r.y1)
      for (int b = r.y0 / kBand; b <= (r.y1 - 1) / kBand; ++b)
        items_[fill_[static_cast<std::size_t>(b)]++] = static_cast<std::uint32_t>(k);
  }
  const std::size_t w = static_cast<std::size_t>(map.width);
  const Shapes objects(boxes);
  parallel_for(static_cast<std::size_t>(bands), threads, [&](std::size_t band) {
    const int y_begin = static_cast<int>(band) * kBand, y_end = std::min(map.height, y_begin + kBand);
    for (int y = y_begin; y < y_end; ++y) {
      std::fill_n(&map.ids[static_cast<std::size_t>(y) * w], w, 0u);
      std::fill_n(&map.depth[static_cast<std::size_t>(y) * w], w, std::numeric_limits<float>::infinity());
    }
    for (std::size_t item = band_start_[band]; item < band_start_[band + 1]; ++item) {
      const std::uint32_t k = items_[item];
      const PixelRect& r = rects_[k];
      const int y0 = std::max(r.y0, y_begin), y1 = std::min(r.y1, y_end);
      for (int y = y0; y < y1; ++y)
        for (int x = r.x0; x < r.x1; ++x) {
          const float t = hit_box(cam, cam.dir(x, y), boxes[k]);
          const std::size_t i = static_cast<std::size_t>(y) * w + static_cast<std::size_t>(x);
          if (t >= 0.0f && t < map.depth[i]) {  // ascending k: ties keep the smaller id
            map.depth[i] = t;
            map.ids[i] = k + 1;
          }
        }
    }
    for (int y = y_begin; y < y_end; ++y)
      for (int x = 0; x < map.width; ++x) {
        const std::size_t i = static_cast<std::size_t>(y) * w + static_cast<std::size_t>(x);
        if (map.ids[i] == 0) map.depth[i] = cam.far_plane;
        if (!map.normal.empty()) write_normal(cam, objects, map, x, y);
      }
  });
}

namespace {

// Runs of equal ids, a block of pixels at a time: ids[b, e) becomes runs r = 0..count-1, run r
// holding id[r] from pixel start[r] to start[r + 1] (start[count] = e). A run that crosses a
// block's edge is counted as two: their lengths add up the same. Without branches: every pixel
// writes its id and position, and the write position advances where the id differs from its left
// neighbour (a branch per run would mispredict at every run). The buffers hold kBlock + 17 entries.
constexpr std::size_t kBlock = 2048;

std::size_t block_runs_scalar(const std::uint32_t* p, std::size_t b, std::size_t e, std::uint32_t* id,
                              std::uint32_t* start) {
  id[0] = p[b];
  start[0] = static_cast<std::uint32_t>(b);
  std::size_t r = 1;
  for (std::size_t i = b + 1; i < e; ++i) {
    id[r] = p[i];
    start[r] = static_cast<std::uint32_t>(i);
    r += p[i] != p[i - 1] ? 1 : 0;
  }
  start[r] = static_cast<std::uint32_t>(e);
  return r;
}

#if VISCD_HAVE_AVX512
// 16 pixels from `at` (`cur`), `m` the lanes where a run starts: their ids and positions are
// compressed into the front of a register each, stored whole at run r (the tail past the runs
// is overwritten by the next step). Returns the runs so far.
VISCD_AVX512_TARGET inline std::size_t runs_step(std::size_t at, __m512i cur, __mmask16 m, __m512i lane,
                                                 std::uint32_t* id, std::uint32_t* start, std::size_t r) {
  const __m512i pos = _mm512_add_epi32(lane, _mm512_set1_epi32(static_cast<int>(at)));
  _mm512_storeu_si512(id + r, _mm512_maskz_compress_epi32(m, cur));
  _mm512_storeu_si512(start + r, _mm512_maskz_compress_epi32(m, pos));
  return r + static_cast<std::size_t>(std::popcount(static_cast<unsigned>(m)));
}

// The same, 16 pixels a step (runs_step()).
VISCD_AVX512_TARGET std::size_t block_runs_avx512(const std::uint32_t* p, std::size_t b, std::size_t e,
                                                  std::uint32_t* id, std::uint32_t* start) {
  id[0] = p[b];
  start[0] = static_cast<std::uint32_t>(b);
  std::size_t r = 1, i = b + 1;
  const __m512i lane = _mm512_set_epi32(15, 14, 13, 12, 11, 10, 9, 8, 7, 6, 5, 4, 3, 2, 1, 0);
  // 64 pixels a step where no run starts (most of the background, and large objects) cost
  // loads and compares only.
  for (; i + 64 <= e; i += 64) {
    __m512i cur[4];
    __mmask16 m[4];
    for (int q = 0; q < 4; ++q) {
      cur[q] = _mm512_loadu_si512(p + i + 16 * q);
      m[q] = _mm512_cmpneq_epi32_mask(cur[q], _mm512_loadu_si512(p + i + 16 * q - 1));
    }
    if ((m[0] | m[1] | m[2] | m[3]) == 0) continue;
    for (int q = 0; q < 4; ++q) r = runs_step(i + 16 * static_cast<std::size_t>(q), cur[q], m[q], lane, id, start, r);
  }
  for (; i + 16 <= e; i += 16) {
    const __m512i cur = _mm512_loadu_si512(p + i), left = _mm512_loadu_si512(p + i - 1);
    r = runs_step(i, cur, _mm512_cmpneq_epi32_mask(cur, left), lane, id, start, r);
  }
  for (; i < e; ++i) {
    id[r] = p[i];
    start[r] = static_cast<std::uint32_t>(i);
    r += p[i] != p[i - 1] ? 1 : 0;
  }
  start[r] = static_cast<std::uint32_t>(e);
  return r;
}
#endif

// The runs of ids[b, e), a block at a time: add(id, start, len, count) over the block's run arrays
// (ids and start pixels filled, start[count] the block's end; `len` room for a length per run,
// and all three the add's to overwrite).
// The buffers are sized by size_runs() beforehand (outside the tasks: it may allocate).
void size_runs(CountScratch& scratch, std::size_t chunks) {
  if (scratch.runs.size() < chunks) scratch.runs.resize(chunks);
  for (std::size_t c = 0; c < chunks; ++c) {
    CountScratch::Runs& buf = scratch.runs[c];
    buf.id.resize(kBlock + 17);
    buf.start.resize(kBlock + 17);
    buf.len.resize(kBlock + 17);
    buf.entry.resize(kBlock + 17);
  }
}

template <class Add>
void for_runs(std::span<const std::uint32_t> ids, std::size_t b, std::size_t e, bool avx512, CountScratch::Runs& buf,
              Add&& add) {
  for (std::size_t at = b; at < e; at += kBlock) {
    const std::size_t end = std::min(e, at + kBlock);
#if VISCD_HAVE_AVX512
    const std::size_t runs = avx512 ? block_runs_avx512(ids.data(), at, end, buf.id.data(), buf.start.data())
                                    : block_runs_scalar(ids.data(), at, end, buf.id.data(), buf.start.data());
#else
    (void)avx512;
    const std::size_t runs = block_runs_scalar(ids.data(), at, end, buf.id.data(), buf.start.data());
#endif
    add(buf.id.data(), buf.start.data(), buf.len.data(), runs);
  }
}

// Ways per range and segment (count_ids(), many objects): four buckets taken by consecutive runs in
// turn. A run's write waits for its bucket's end from the run before; four buckets keep four such
// chains apart.
constexpr std::size_t kWays = 4;

// Range c of the map, ids[b, e), sorted into its buckets (kWays per segment of kSegment ids): each
// run but the background's as (id << 32 | length). The range's foreground pixels go to
// scratch.foreground[c]. Buckets grow as needed (may throw std::bad_alloc).
void bucket_runs(std::span<const std::uint32_t> ids, std::size_t b, std::size_t e, std::size_t c, std::size_t per_chunk,
                 std::uint32_t bad, bool avx512, CountScratch& scratch) {
  std::vector<std::uint64_t>* bucket = &scratch.buckets[c * per_chunk];
  // Each bucket's end, as a pointer (a run's write, a std::uint64_t, cannot alias it).
  std::uint64_t** end = &scratch.ends[c * per_chunk];
  for (std::size_t s = 0; s < per_chunk; ++s) end[s] = bucket[s].data();
  std::uint64_t foreground = 0;
  for_runs(ids, b, e, avx512, scratch.runs[c],
           [&](std::uint32_t* id, const std::uint32_t* start, std::uint32_t* keep, std::size_t r) {
             for (std::size_t s = 0; s < per_chunk; ++s) {  // room for every run of the block in any bucket
               const auto filled = static_cast<std::size_t>(end[s] - bucket[s].data());
               if (bucket[s].size() < filled + r) {
                 bucket[s].resize(std::max(filled + r, 2 * bucket[s].size()));
                 end[s] = bucket[s].data() + filled;
               }
             }
             // First, without a store to a bucket (so it vectorises): each run's bucket (in
             // place of its id), its entry, and whether it is kept (in `keep`). Background runs
             // are written but not kept (the end stays): the background's count is what the
             // others leave. Then the writes alone.
             std::uint64_t* entry = scratch.runs[c].entry.data();
             for (std::size_t k = 0; k < r; ++k) {
               const std::uint32_t v = std::min(id[k], bad), len = start[k + 1] - start[k];
               const std::uint32_t kept = static_cast<std::uint32_t>((std::uint64_t{v} + 0xFFFFFFFFu) >> 32);  // v != 0
               id[k] = static_cast<std::uint32_t>(v / CountScratch::kSegment * kWays + (k & (kWays - 1)));
               entry[k] = std::uint64_t{v} << 32 | len;
               keep[k] = kept;
               foreground += len & (0u - kept);
             }
             for (std::size_t k = 0; k < r; ++k) {
               std::uint64_t*& to = end[id[k]];
               std::uint64_t* at = to;
               *at = entry[k];
               to = at + keep[k];
             }
           });
  scratch.foreground[c] = foreground;
}

// count_ids() with more than CountScratch::kSegment slots: a histogram of all of them is larger
// than a core's cache, and adding runs into it at random would wait on memory at every run. So
// the runs are first sorted into segments of kSegment ids (kWays buckets per range of pixels and
// segment, written in order), then each segment of `hist` is counted from its buckets while it
// stays in cache. hist[0] is left to the caller (from scratch.foreground).
void count_many(std::span<const std::uint32_t> ids, std::size_t slots, std::size_t chunks, std::size_t used,
                int threads, bool avx512, std::vector<std::uint32_t>& hist, CountScratch& scratch) {
  const std::size_t n = ids.size();
  const auto bad = static_cast<std::uint32_t>(slots - 1);
  const std::size_t segments = (slots + CountScratch::kSegment - 1) / CountScratch::kSegment;
  const std::size_t per_chunk = segments * kWays;
  hist.resize(slots);
  if (scratch.buckets.size() < chunks * per_chunk) scratch.buckets.resize(chunks * per_chunk);
  if (scratch.ends.size() < chunks * per_chunk) scratch.ends.resize(chunks * per_chunk);
  // A bucket that must grow does so inside a task; std::bad_alloc there is carried out to the
  // caller (detect() reports it), not left to end a worker thread.
  std::atomic<bool> out_of_memory{false};
  for_chunks(n, chunks, [&](std::size_t b, std::size_t e, std::size_t c) {
    try {
      bucket_runs(ids, b, e, c, per_chunk, bad, avx512, scratch);
    } catch (const std::bad_alloc&) {
      out_of_memory.store(true, std::memory_order_relaxed);
    }
  });
  if (out_of_memory.load(std::memory_order_relaxed)) throw std::bad_alloc();
  for_chunks(segments, 2 * static_cast<std::size_t>(std::max(1, threads)),
             [&](std::size_t sb, std::size_t se, std::size_t) {
               for (std::size_t s = sb; s < se; ++s) {
                 const std::size_t lo = s * CountScratch::kSegment, hi = std::min(slots, lo + CountScratch::kSegment);
                 std::uint32_t* h = hist.data() + lo;
                 std::fill(h, hist.data() + hi, 0u);
                 for (std::size_t c = 0; c < used; ++c)
                   for (std::size_t w = 0; w < kWays; ++w) {
                     const std::size_t at = c * per_chunk + s * kWays + w;
                     const std::uint64_t* run = scratch.buckets[at].data();
                     for (const std::uint64_t* run_end = scratch.ends[at]; run != run_end; ++run)
                       h[static_cast<std::uint32_t>(*run >> 32) - lo] += static_cast<std::uint32_t>(*run);
                   }
               }
             });
}

}  // namespace

bool count_ids(std::span<const std::uint32_t> ids, std::size_t objects, int threads, std::vector<std::uint32_t>& hist,
               CountScratch& scratch, SimdLevel simd) {
  VISCD_ASSERT(objects < 0xFFFFFFFFu - 1, "ids are 32-bit");
  VISCD_ASSERT(ids.size() <= 0xFFFFFFFFu, "pixel positions are 32-bit");
  const std::size_t slots = objects + 2, n = ids.size();
  const auto bad = static_cast<std::uint32_t>(objects + 1);
  const bool avx512 = usable_simd_level(simd) == SimdLevel::avx512;
  const std::size_t chunks = ranges_for(n, threads);  // ranges of pixels
  // The ranges that get pixels (none of an empty map: nothing is read from the buffers then).
  const std::size_t used = std::min(chunks, n);
  size_runs(scratch, chunks);
  scratch.foreground.assign(chunks, 0);

  if (slots <= CountScratch::kSegment) {
    // Few objects: each range of pixels adds its runs into a histogram of its own (the first
    // into `hist`), all small enough to stay in the core's cache; they are summed after.
    hist.assign(slots + 8, 0u);  // 8 spare counters, cut off at the end
    if (scratch.hist.size() < chunks - 1) scratch.hist.resize(chunks - 1);
    for (std::size_t c = 1; c < chunks; ++c) scratch.hist[c - 1].assign(slots + 8, 0u);
    for_chunks(n, chunks, [&](std::size_t b, std::size_t e, std::size_t c) {
      std::uint32_t* h = c == 0 ? hist.data() : scratch.hist[c - 1].data();
      // Every other run is the background's: adding them all into h[0] would make each wait for
      // the one before (a chain through memory). They go to eight spare counters past the
      // objects' in turn instead (chosen by arithmetic, not a branch), and the background's count
      // is what the other runs leave.
      std::uint64_t foreground = 0;
      for_runs(ids, b, e, avx512, scratch.runs[c],
               [&](std::uint32_t* id, const std::uint32_t* start, std::uint32_t* len, std::size_t r) {
                 // First, without a store to the histogram (so it vectorises): each run's counter
                 // and length, in place of its id and in `len`; then the adds alone.
                 std::uint32_t* slot = id;
                 for (std::size_t k = 0; k < r; ++k) {
                   const std::uint32_t v = std::min(id[k], bad), l = start[k + 1] - start[k];
                   const std::uint32_t background = 0u - static_cast<std::uint32_t>(v == 0);  // all ones or 0
                   slot[k] = v + (background & static_cast<std::uint32_t>(slots + (k & 7)));
                   len[k] = l;
                   foreground += l & ~background;
                 }
                 for (std::size_t k = 0; k < r; ++k) h[slot[k]] += len[k];
               });
      scratch.foreground[c] = foreground;
    });
    if (used > 1)
      for_chunks(slots, slots >= kParallelThreshold ? static_cast<std::size_t>(threads) : 1,
                 [&](std::size_t b, std::size_t e, std::size_t) {
                   for (std::size_t c = 1; c < used; ++c) {
                     const std::uint32_t* h = scratch.hist[c - 1].data();
                     for (std::size_t k = b; k < e; ++k) hist[k] += h[k];
                   }
                 });
    hist.resize(slots);
  } else {
    count_many(ids, slots, chunks, used, threads, avx512, hist, scratch);
  }
  // The background: the pixels that the other runs leave.
  std::uint64_t foreground = 0;
  for (std::size_t c = 0; c < used; ++c) foreground += scratch.foreground[c];
  hist[0] = static_cast<std::uint32_t>(n - foreground);
  return hist[bad] == 0;
}

int cull_in_parallel(std::span<const std::uint32_t> counts, double pixel_scale, const Config& config,
                     std::span<const std::uint8_t> always_active, int threads, std::vector<float>& pixels,
                     std::vector<std::uint32_t>& active, CullScratch& scratch, FrameStats& stats) {
  const std::size_t n = counts.size();
  const std::size_t chunks = ranges_for(n, threads);
  if (chunks == 1) return cull_and_choose_bits(counts, pixel_scale, config, always_active, pixels, active, stats);
  pixels.resize(n);
  if (scratch.active.size() < chunks) scratch.active.resize(chunks);
  scratch.counted.assign(chunks, 0);
  // Room for every object of its range (outside the tasks: may allocate): no allocation as the
  // active count changes (memory that is reserved but never written takes no pages).
  for (std::size_t c = 0; c < chunks; ++c) {
    const Chunk range = chunk_of(n, c, chunks);
    scratch.active[c].reserve(range.end - range.begin);
  }
  for_chunks(n, chunks, [&](std::size_t b, std::size_t e, std::size_t c) {
    std::vector<std::uint32_t>& part = scratch.active[c];
    part.clear();
    scratch.counted[c] = cull_range(counts, pixel_scale, config, always_active, b, e, pixels.data(), part);
  });
  std::uint64_t counted = 0;
  std::size_t total = 0;
  for (std::size_t c = 0; c < chunks; ++c) {
    counted += scratch.counted[c];
    total += scratch.active[c].size();
  }
  active.reserve(n);  // at most every object: no allocation as the active count changes
  active.resize(total);
  std::size_t at = 0;
  for (std::size_t c = 0; c < chunks; ++c) {
    std::copy(scratch.active[c].begin(), scratch.active[c].end(), active.begin() + static_cast<std::ptrdiff_t>(at));
    at += scratch.active[c].size();
  }
  return finish_cull(config, n, counted, pixel_scale, total, stats);
}

void count_pixels(const VisibilityMap& map, std::size_t objects, int threads, std::vector<std::uint32_t>& counts,
                  std::vector<std::uint32_t>& hist, CountScratch& scratch) {
  if (map.has_counts && map.counts.size() == objects) {  // counted while rasterising
    counts.assign(map.counts.begin(), map.counts.end());
    return;
  }
  const bool ids_valid =
      count_ids(std::span<const std::uint32_t>(map.ids.data(), map.ids.size()), objects, threads, hist, scratch);
  VISCD_ASSERT(ids_valid, "a rasterizer writes ids of the frame's objects only");
  (void)ids_valid;
  counts.assign(hist.begin() + 1, hist.begin() + 1 + static_cast<std::ptrdiff_t>(objects));
}

void shade(const CameraRig& cam, const VisibilityMap& map, std::span<const ObjectState> state, int threads,
           std::vector<std::uint8_t>& rgba) {
  const std::size_t n = map.ids.size();
  VISCD_ASSERT(map.normal.size() == 3 * n, "shading needs the normal map");
  rgba.resize(4 * n);
  const ShadingModel& model = shading_model();
  const Vec3 view = {-cam.forward.x, -cam.forward.y, -cam.forward.z};
  parallel_for(n, threads, [&](std::size_t i) {
    std::uint8_t* out = &rgba[4 * i];
    out[3] = 255;
    const std::uint32_t id = map.ids[i];
    if (id == 0) {
      out[0] = kBackgroundColour.r, out[1] = kBackgroundColour.g, out[2] = kBackgroundColour.b;
      return;
    }
    // Ids beyond the moving objects' are the static set's (drawn after them).
    const Rgb8 base = id <= state.size() ? state_colour(state[id - 1]) : kStaticColour;
    const Vec3 nrm = {map.normal[3 * i], map.normal[3 * i + 1], map.normal[3 * i + 2]};
    // Lambert plus a little ambient and a rim from the view direction, so spheres read as round.
    const float diffuse = std::max(0.0f, dot(nrm, model.light));
    const float facing = std::max(0.0f, dot(nrm, view));
    const float k = model.ambient + model.diffuse * diffuse + model.rim * facing;
    const float rgb[3] = {static_cast<float>(base.r), static_cast<float>(base.g), static_cast<float>(base.b)};
    for (int ch = 0; ch < 3; ++ch) out[ch] = static_cast<std::uint8_t>(std::min(255.0f, rgb[ch] * k + 0.5f));
  });
}

}  // namespace viscd::detail
