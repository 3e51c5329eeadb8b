#include "cpu/visibility.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>

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

void write_normal(const CameraRig& cam, std::span<const Sphere> spheres, VisibilityMap& map, int px, int py) {
  const std::size_t i =
      static_cast<std::size_t>(py) * static_cast<std::size_t>(map.width) + static_cast<std::size_t>(px);
  float* n = &map.normal[3 * i];
  const std::uint32_t id = map.ids[i];
  if (id == 0) {
    n[0] = n[1] = n[2] = 0;
    return;
  }
  const Sphere& s = spheres[id - 1];
  const Vec3 d = cam.dir(px, py);
  const float t = map.depth[i];
  const Vec3 p = {cam.eye.x + t * d.x - s.x, cam.eye.y + t * d.y - s.y, cam.eye.z + t * d.z - s.z};
  const float l = std::sqrt(dot(p, p));
  if (l > 0) {
    n[0] = p.x / l, n[1] = p.y / l, n[2] = p.z / l;
  } else {
    n[0] = -d.x, n[1] = -d.y, n[2] = -d.z;  // a point sphere (r = 0) faces the viewer
  }
}

void rasterize_reference(const CameraRig& cam, std::span<const Sphere> spheres, VisibilityMap& map) {
  map.stamp = 0;  // (bookkeeping: the content is no longer the cpu rasterizer's)
  for (int py = 0; py < map.height; ++py) {
    for (int px = 0; px < map.width; ++px) {
      const Vec3 d = cam.dir(px, py);
      float best = std::numeric_limits<float>::infinity();
      std::uint32_t best_id = 0;
      for (std::size_t k = 0; k < spheres.size(); ++k) {
        const float t = hit(cam, d, spheres[k]);
        if (t >= 0.0f && t < best) {  // ascending k: ties keep the smaller id
          best = t;
          best_id = static_cast<std::uint32_t>(k + 1);
        }
      }
      const std::size_t i =
          static_cast<std::size_t>(py) * static_cast<std::size_t>(map.width) + static_cast<std::size_t>(px);
      map.ids[i] = best_id;
      map.depth[i] = best_id ? best : cam.far_plane;
      if (!map.normal.empty()) write_normal(cam, spheres, map, px, py);
    }
  }
}

bool count_ids(std::span<const std::uint32_t> ids, std::size_t objects, int threads, std::vector<std::uint32_t>& hist) {
  VISCD_ASSERT(objects < 0xFFFFFFFFu, "ids are 32-bit");
  hist.assign(objects + 2, 0u);
  const auto bad = static_cast<std::uint32_t>(objects + 1);
  const std::size_t n = ids.size();
  const int tasks = threads_for(n, threads);
  // Runs of equal ids (++hist[id] per pixel would wait on its own store along a run).
  auto count_range = [&](std::size_t b, std::size_t e, auto add) {
    const std::uint32_t* p = ids.data();
    std::uint32_t cur = p[b], run = 0;
    std::size_t i = b;
    while (i < e) {
#if defined(__SSE2__)
      if (i + 4 <= e) {
        const __m128i same = _mm_cmpeq_epi32(_mm_loadu_si128(reinterpret_cast<const __m128i*>(p + i)),
                                             _mm_set1_epi32(static_cast<int>(cur)));
        if (_mm_movemask_epi8(same) == 0xFFFF) {
          i += 4, run += 4;
          continue;
        }
      }
#endif
      const std::size_t stop = std::min(e, i + 4);
      for (; i < stop; ++i) {
        const std::uint32_t id = p[i];
        if (id != cur) {
          add(std::min(cur, bad), run);
          cur = id, run = 0;
        }
        ++run;
      }
    }
    add(std::min(cur, bad), run);
  };
  if (tasks == 1) {
    if (n) count_range(0, n, [&](std::uint32_t id, std::uint32_t run) { hist[id] += run; });
  } else {
    // Rows of different tasks rarely share an id, so the atomic adds do not contend.
    for_chunks(n, static_cast<std::size_t>(tasks), [&](std::size_t b, std::size_t e, std::size_t) {
      count_range(b, e, [&](std::uint32_t id, std::uint32_t run) {
        std::atomic_ref<std::uint32_t>(hist[id]).fetch_add(run, std::memory_order_relaxed);
      });
    });
  }
  return hist[bad] == 0;
}

void count_pixels(const VisibilityMap& map, std::size_t objects, int threads, std::vector<std::uint32_t>& counts,
                  std::vector<std::uint32_t>& hist) {
  if (map.has_counts && map.counts.size() == objects) {  // counted while rasterising
    counts.assign(map.counts.begin(), map.counts.end());
    return;
  }
  const bool ids_valid =
      count_ids(std::span<const std::uint32_t>(map.ids.data(), map.ids.size()), objects, threads, hist);
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
    const Rgb8 base = state_colour(state[id - 1]);
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
