#include "cpu/visibility.hpp"

#include <algorithm>
#include <atomic>
#include <bit>
#include <cmath>
#include <limits>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

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

// Runs of equal ids in ids[b, e): add(id, length) per run, ids above `bad` as `bad`. Eight pixels at
// a time: the positions where an id differs from its left neighbour come out as bits, and a run
// costs one pass of the loop over those bits (a branch per pixel would mispredict at every run).
template <class Add>
void count_runs(const std::uint32_t* p, std::size_t b, std::size_t e, std::uint32_t bad, Add&& add) {
  if (b == e) return;
  std::uint32_t cur = p[b];
  std::size_t start = b, i = b + 1;
#if defined(__SSE2__)
  for (; i + 16 <= e; i += 16) {
    const auto* q = reinterpret_cast<const __m128i*>(p + i);
    const auto* left = reinterpret_cast<const __m128i*>(p + i - 1);
    auto same = [&](int k) {
      return static_cast<std::uint32_t>(
          _mm_movemask_ps(_mm_castsi128_ps(_mm_cmpeq_epi32(_mm_loadu_si128(q + k), _mm_loadu_si128(left + k)))));
    };
    for (std::uint32_t m = (same(0) | same(1) << 4 | same(2) << 8 | same(3) << 12) ^ 0xFFFFu; m; m &= m - 1) {
      const std::size_t j = i + static_cast<std::size_t>(std::countr_zero(m));
      add(std::min(cur, bad), static_cast<std::uint32_t>(j - start));
      cur = p[j];
      start = j;
    }
  }
#endif
  for (; i < e; ++i) {
    if (p[i] == cur) continue;
    add(std::min(cur, bad), static_cast<std::uint32_t>(i - start));
    cur = p[i];
    start = i;
  }
  add(std::min(cur, bad), static_cast<std::uint32_t>(e - start));
}

}  // namespace

bool count_ids(std::span<const std::uint32_t> ids, std::size_t objects, int threads, std::vector<std::uint32_t>& hist,
               CountScratch& scratch) {
  VISCD_ASSERT(objects < 0xFFFFFFFFu - 1, "ids are 32-bit");
  const std::size_t slots = objects + 2;
  hist.assign(slots, 0u);
  const auto bad = static_cast<std::uint32_t>(objects + 1);
  const std::size_t n = ids.size();
  // In parallel only with few objects for the pixels: a range of rows after the first pays for
  // every id it touches once more when its counts are added (from another core's cache), and with
  // many objects, each covering few pixels, that costs more than the second thread saves
  // (measured on a 1280x720 map, docs/benchmarks.md: at 10^4 objects two threads took 0.40 ms and
  // one 0.44; at 5 x 10^4, 0.76 and 0.54).
  const auto tasks = static_cast<std::size_t>(slots * 32 <= n ? threads_for(n, threads) : 1);
  if (tasks == 1) {
    count_runs(ids.data(), 0, n, bad, [&](std::uint32_t id, std::uint32_t run) { hist[id] += run; });
    return hist[bad] == 0;
  }
  // The first chunk counts into `hist`; each other one into a histogram of its own, kept all zero
  // between calls, noting the ids it touches. Those are added to `hist` after and cleared again:
  // the cost follows the ids seen, not the objects, and no add is atomic. Four chunks per thread:
  // a thread that gets no core then holds up a quarter of its share, which the others take over.
  const std::size_t chunks = 4 * tasks;
  if (scratch.hist.size() < chunks - 1) {
    scratch.hist.resize(chunks - 1);
    scratch.touched.resize(chunks - 1);
  }
  for (std::size_t t = 1; t < chunks; ++t) {  // outside the tasks: may allocate
    if (scratch.hist[t - 1].size() < slots) scratch.hist[t - 1].resize(slots, 0u);
    const Chunk c = chunk_of(n, t, chunks);
    scratch.touched[t - 1].clear();
    scratch.touched[t - 1].reserve(std::min(slots, c.end - c.begin));  // a run per new id at most
  }
  for_chunks(n, chunks, [&](std::size_t b, std::size_t e, std::size_t t) {
    if (t == 0) {
      count_runs(ids.data(), b, e, bad, [&](std::uint32_t id, std::uint32_t run) { hist[id] += run; });
      return;
    }
    std::uint32_t* h = scratch.hist[t - 1].data();
    std::vector<std::uint32_t>& touched = scratch.touched[t - 1];
    count_runs(ids.data(), b, e, bad, [&](std::uint32_t id, std::uint32_t run) {
      const std::uint32_t before = h[id];
      h[id] = before + run;
      if (before == 0) touched.push_back(id);
    });
  });
  for (std::size_t t = 1; t < chunks; ++t) {
    std::uint32_t* h = scratch.hist[t - 1].data();
    for (const std::uint32_t id : scratch.touched[t - 1]) {
      hist[id] += h[id];
      h[id] = 0;
    }
  }
  return hist[bad] == 0;
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
