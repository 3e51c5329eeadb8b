#pragma once
// The visibility rules every backend shares: the camera and its map (stage 1's rays), the ray-sphere
// hit every CPU rasterizer evaluates per pixel (both resolve depth ties by the smaller object id,
// so their id maps are equal bit for bit), the conservative screen rectangle of a sphere, culling
// and m (stage 3), the map size and the shading model (stage 9).

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <span>
#include <utility>
#include <vector>

#include "core/geometry.hpp"
#include "viscd/config.hpp"
#include "viscd/frame.hpp"
#include "viscd/types.hpp"

namespace viscd::detail {

/// A camera prepared for ray casting over a map of map_w x map_h pixels. The ray through the
/// centre of pixel (px, py) (row 0 at the top) is eye + t * dir(px, py), where dir has unit
/// component along `forward`, so t is the view depth of the point it reaches.
struct CameraRig {
  Vec3 eye, forward, right, up;
  float tan_half_x = 1, tan_half_y = 1, near_plane = 0.1f, far_plane = 1000;
  int map_w = 1, map_h = 1;
  /// Screen pixels per map pixel: (screen area) / (map area).
  double pixel_scale = 1;

  CameraRig(const Camera& camera, int map_width, int map_height);
  [[nodiscard]] Vec3 dir(int px, int py) const {
    const float nx = (2.0f * (static_cast<float>(px) + 0.5f) / static_cast<float>(map_w) - 1.0f) * tan_half_x;
    const float ny = (1.0f - 2.0f * (static_cast<float>(py) + 0.5f) / static_cast<float>(map_h)) * tan_half_y;
    return {forward.x + right.x * nx + up.x * ny, forward.y + right.y * nx + up.y * ny,
            forward.z + right.z * nx + up.z * ny};
  }
};

/// Nearest visible intersection of the ray eye + t d with a sphere: the smaller root t with
/// near <= t <= far, else the larger root in that range (the camera is inside the sphere or the
/// front is clipped by the near plane, as a mesh without back-face culling would show), else a
/// negative number (miss).
inline float hit(const CameraRig& cam, const Vec3& d, const Sphere& s) {
  const float ox = cam.eye.x - s.x, oy = cam.eye.y - s.y, oz = cam.eye.z - s.z;
  const float a = d.x * d.x + d.y * d.y + d.z * d.z;
  const float b = ox * d.x + oy * d.y + oz * d.z;
  const float c = ox * ox + oy * oy + oz * oz - s.r * s.r;
  const float disc = b * b - a * c;
  if (!(disc >= 0.0f)) return -1.0f;
  const float sq = std::sqrt(disc);
  const float t0 = (-b - sq) / a;
  if (t0 >= cam.near_plane && t0 <= cam.far_plane) return t0;
  const float t1 = (-b + sq) / a;
  if (t1 >= cam.near_plane && t1 <= cam.far_plane) return t1;
  return -1.0f;
}

/// Nearest visible intersection of the ray eye + t d with a box, by slabs in float: along an axis
/// with d = 0 the eye must lie within [min, max]; else the slab is entered at (min - eye) / d and
/// left at (max - eye) / d (swapped for d < 0). With t0 the largest entry and t1 the smallest exit
/// (a miss when t0 > t1): t0 when near <= t0 <= far, else t1 when near <= t1 <= far (the camera
/// inside the box or the front clipped by the near plane, as for spheres), else a negative number.
inline float hit_box(const CameraRig& cam, const Vec3& d, const Box& b) {
  const float e[3] = {cam.eye.x, cam.eye.y, cam.eye.z}, dd[3] = {d.x, d.y, d.z};
  float t0 = -std::numeric_limits<float>::infinity(), t1 = std::numeric_limits<float>::infinity();
  for (int k = 0; k < 3; ++k) {
    if (dd[k] == 0.0f) {
      if (e[k] < b.min[k] || e[k] > b.max[k]) return -1.0f;
      continue;
    }
    float a = (b.min[k] - e[k]) / dd[k], c = (b.max[k] - e[k]) / dd[k];
    if (a > c) std::swap(a, c);
    t0 = std::max(t0, a);
    t1 = std::min(t1, c);
  }
  if (!(t0 <= t1)) return -1.0f;
  if (t0 >= cam.near_plane && t0 <= cam.far_plane) return t0;
  if (t1 >= cam.near_plane && t1 <= cam.far_plane) return t1;
  return -1.0f;
}

/// Conservative map-pixel rectangle [x0, x1) x [y0, y1) that contains every pixel whose centre
/// ray can hit the sphere; empty (x0 >= x1) when the sphere is wholly outside near..far.
struct PixelRect {
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  /// A lower bound of the depth t of any hit on the sphere (for early depth rejection).
  float near_depth = 0;
};
[[nodiscard]] PixelRect sphere_rect(const CameraRig& cam, const Sphere& s);
/// The same for a box: the rectangle of its bounding sphere (centre, half diagonal), which holds
/// every pixel hit_box() can accept (its rounding is far inside sphere_rect()'s slack).
[[nodiscard]] PixelRect box_rect(const CameraRig& cam, const Box& b);

/// Stage 3: screen-scaled pixels, mu over all N, active set (pixels >= lambda, or a non-zero
/// `always_active` flag when there are flags, or all when culling is off), and m from Eq. (1) or
/// Config::bits. Fills stats.active/mean_pixels. mu = (the sum of the counts, exact in 64 bits) x
/// pixel_scale / N, so that any split of the objects into ranges (the cpu backend's threads) gives
/// the same bits.
int cull_and_choose_bits(std::span<const std::uint32_t> counts, double pixel_scale, const Config& config,
                         std::span<const std::uint8_t> always_active, std::vector<float>& pixels,
                         std::vector<std::uint32_t>& active, FrameStats& stats);

/// Stage 3 over the objects [b, e): pixels[k] = counts[k] x pixel_scale (as float) and the active
/// ones appended to `active` in ascending order; returns the sum of their counts.
inline std::uint64_t cull_range(std::span<const std::uint32_t> counts, double pixel_scale, const Config& config,
                                std::span<const std::uint8_t> always_active, std::size_t b, std::size_t e,
                                float* pixels, std::vector<std::uint32_t>& active) {
  std::uint64_t counted = 0;
  const float lambda = config.lambda;
  const bool flags = !always_active.empty();
  for (std::size_t k = b; k < e; ++k) {
    counted += counts[k];
    // The rule compares the count as FrameResult::pixels reports it (a float): a caller who
    // checks pixels[k] >= lambda sees the state the detector gave, also where the double
    // product lies just below a float that rounds up to lambda (1989 x (1 / 1989) < 1).
    const float px = static_cast<float>(static_cast<double>(counts[k]) * pixel_scale);
    pixels[k] = px;
    if (!config.culling || px >= lambda || (flags && always_active[k] != 0))
      active.push_back(static_cast<std::uint32_t>(k));
  }
  return counted;
}

/// Stage 3's end: mu from the counts' sum, stats.active, and m.
int finish_cull(const Config& config, std::size_t objects, std::uint64_t counted, double pixel_scale,
                std::size_t active, FrameStats& stats);

/// Stage 1's map size: Config::map_width x map_height, or the camera's screen when they are 0.
struct MapSize {
  int width = 0, height = 0;
};
[[nodiscard]] inline MapSize map_size(const Config& config, const Camera& camera) {
  return config.map_width ? MapSize{config.map_width, config.map_height} : MapSize{camera.width, camera.height};
}

/// Stage 9's light: brightness = ambient + diffuse * max(0, n.light) + rim * max(0, n.view),
/// times the state colour (viscd::state_colour), rounded and clamped to 255. Every backend
/// shades with these numbers.
struct ShadingModel {
  Vec3 light;  ///< unit vector towards the light, world space
  float ambient = 0.25f, diffuse = 0.6f, rim = 0.15f;
};
[[nodiscard]] const ShadingModel& shading_model();

}  // namespace viscd::detail
