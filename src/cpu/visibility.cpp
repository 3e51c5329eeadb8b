#include "cpu/visibility.hpp"

#include <algorithm>
#include <cmath>

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

void count_pixels(const VisibilityMap& map, std::size_t objects, int threads, std::vector<std::uint32_t>& counts,
                  std::vector<std::vector<std::uint32_t>>& scratch) {
  if (map.has_counts && map.counts.size() == objects) {  // counted while rasterising
    counts.assign(map.counts.begin(), map.counts.end());
    return;
  }
  const std::size_t n = map.ids.size();
  const int t_count = threads_for(n, threads);
  if (scratch.size() < static_cast<std::size_t>(t_count)) scratch.resize(static_cast<std::size_t>(t_count));
  counts.assign(objects, 0);
  const auto chunks = static_cast<std::size_t>(t_count);
  for (std::size_t t = 0; t < chunks; ++t) scratch[t].resize(objects + 1);  // outside the tasks: may allocate
  for_chunks(n, chunks, [&](std::size_t b, std::size_t e, std::size_t t) {
    auto& h = scratch[t];
    std::fill(h.begin(), h.end(), 0u);
    // By runs of equal ids (++h[id] per pixel would wait on its own store along a run).
    std::uint32_t cur = map.ids[b], run = 0;
    for (std::size_t i = b; i < e; ++i) {
      const std::uint32_t id = map.ids[i];
      if (id != cur) {
        h[cur] += run;
        cur = id, run = 0;
      }
      ++run;
    }
    h[cur] += run;
  });
  if (chunks == 1) {
    std::copy(scratch[0].begin() + 1, scratch[0].end(), counts.begin());
    return;
  }
  parallel_for(objects, t_count, [&](std::size_t k) {
    std::uint32_t sum = 0;
    for (std::size_t u = 0; u < chunks; ++u) sum += scratch[u][k + 1];
    counts[k] = sum;
  });
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
