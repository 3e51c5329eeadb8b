#include "core/visibility.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "core/frame_rules.hpp"
#include "core/morton.hpp"

namespace viscd::detail {
namespace {

Vec3 sub(Vec3 a, Vec3 b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
float dot(Vec3 a, Vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
Vec3 cross(Vec3 a, Vec3 b) { return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x}; }
Vec3 normalize(Vec3 a) {
  const float l = std::sqrt(dot(a, a));
  return {a.x / l, a.y / l, a.z / l};
}

}  // namespace

CameraRig::CameraRig(const Camera& c, int map_width, int map_height) {
  eye = {c.eye[0], c.eye[1], c.eye[2]};
  forward = normalize(sub({c.target[0], c.target[1], c.target[2]}, eye));
  right = normalize(cross(forward, {c.up[0], c.up[1], c.up[2]}));
  up = cross(right, forward);
  map_w = map_width;
  map_h = map_height;
  tan_half_y = static_cast<float>(std::tan(c.fov_y_deg * std::numbers::pi / 360.0));
  // The screen's aspect ratio, not the map's: a smaller map samples the same view.
  tan_half_x = tan_half_y * static_cast<float>(c.width) / static_cast<float>(c.height);
  near_plane = c.near_plane;
  far_plane = c.far_plane;
  pixel_scale = map_pixel_scale(&c, map_w, map_h);
}

PixelRect sphere_rect(const CameraRig& cam, const Sphere& s) {
  const Vec3 c = sub({s.x, s.y, s.z}, cam.eye);
  const float cz = dot(c, cam.forward), cx = dot(c, cam.right), cy = dot(c, cam.up);
  // hit() decides on disc = b*b - a*c in float, which cancels badly for rays that pass close to
  // the centre of a sphere much smaller than its distance |o| from the eye: with the roundings of
  // the dot products it accepts rays up to sqrt(r^2 + k * 2^-24 * |o|^2) from the centre, k about
  // 15 by a first-order error bound (7.7 the largest seen in 20 million random rays aimed at tiny
  // spheres). The rectangle must hold every pixel hit() can accept, or the cpu map would differ
  // from the reference's (a point sphere seen through a 0.5 degree field of view did). So the
  // radius is widened in quadrature by e, e^2 = 2^-19 |o|^2 (k = 32): spheres larger than e grow
  // by less than e^2 / 2r, only sub-pixel ones get a wider rectangle. Then the margin for the
  // rounding of this bound itself.
  const double o2 = static_cast<double>(cz) * cz + static_cast<double>(cx) * cx + static_cast<double>(cy) * cy;
  const double l1 = static_cast<double>(std::fabs(cz) + std::fabs(cx) + std::fabs(cy));
  const double rs = static_cast<double>(s.r);
  const float r = static_cast<float>(std::sqrt(rs * rs + 0x1p-19 * o2) + 1e-4 * (l1 + rs) + 1e-6);
  if (cz + r < cam.near_plane || cz - r > cam.far_plane) return {};
  const float dmin = cz - r;
  if (!(dmin > cam.near_plane * 0.5f)) return {0, 0, cam.map_w, cam.map_h, 0.0f};  // reaches the near plane or the eye
  // Exact extent of the projection along one screen axis: the slopes v/z of the two lines from
  // the eye tangent to the circle (centre (cv, cz), radius r) in the plane of that axis and the
  // view direction. With the circle wholly in front (cz - r > 0) and t = sqrt(cv^2 + cz^2 - r^2):
  //   slope = tan(phi -+ alpha) = (cv t -+ r cz) / (cz t +- cv r).
  // Computed in double; the slack in r and the pixel margin below absorb the float rounding.
  auto span_of = [&](float cv, float tan_half) {
    const double v = cv, z = cz, rr = r;
    const double t = std::sqrt(std::max(0.0, v * v + z * z - rr * rr));
    const double lo = (v * t - rr * z) / (z * t + v * rr), hi = (v * t + rr * z) / (z * t - v * rr);
    return std::pair{lo / tan_half, hi / tan_half};  // normalised device coordinates
  };
  const auto [nx0, nx1] = span_of(cx, cam.tan_half_x);
  const auto [ny0, ny1] = span_of(cy, cam.tan_half_y);
  // Pixel centre px + 0.5 = (ndc + 1) / 2 * W; rows count down from ndc_y = 1.
  auto clampi = [](double v, int hi) { return static_cast<int>(std::clamp(v, 0.0, static_cast<double>(hi))); };
  PixelRect rect;
  rect.x0 = clampi(std::floor((nx0 + 1.0) * 0.5 * cam.map_w - 0.5) - 1, cam.map_w);
  rect.x1 = clampi(std::ceil((nx1 + 1.0) * 0.5 * cam.map_w - 0.5) + 2, cam.map_w);
  rect.y0 = clampi(std::floor((1.0 - ny1) * 0.5 * cam.map_h - 0.5) - 1, cam.map_h);
  rect.y1 = clampi(std::ceil((1.0 - ny0) * 0.5 * cam.map_h - 0.5) + 2, cam.map_h);
  rect.near_depth = dmin;  // r includes the slack, so every hit has t >= dmin
  return rect;
}

PixelRect box_rect(const CameraRig& cam, const Box& b) {
  const double hx = 0.5 * (double{b.max[0]} - b.min[0]), hy = 0.5 * (double{b.max[1]} - b.min[1]),
               hz = 0.5 * (double{b.max[2]} - b.min[2]);
  const double cx = 0.5 * (double{b.min[0]} + b.max[0]), cy = 0.5 * (double{b.min[1]} + b.max[1]),
               cz = 0.5 * (double{b.min[2]} + b.max[2]);
  // The half diagonal, plus what rounding the centre to float can move it (2^-24 |c| per axis).
  const double rd = std::sqrt(hx * hx + hy * hy + hz * hz) + 0x1p-22 * (std::fabs(cx) + std::fabs(cy) + std::fabs(cz));
  const Sphere bound{static_cast<float>(cx), static_cast<float>(cy), static_cast<float>(cz),
                     static_cast<float>(rd * (1.0 + 0x1p-20))};
  return sphere_rect(cam, bound);
}

const ShadingModel& shading_model() {
  static const ShadingModel model{normalize({0.4f, 0.8f, 0.45f})};
  return model;
}

int cull_and_choose_bits(std::span<const std::uint32_t> counts, double pixel_scale, const Config& config,
                         std::span<const std::uint8_t> always_active, std::vector<float>& pixels,
                         std::vector<std::uint32_t>& active, FrameStats& stats) {
  const std::size_t n = counts.size();
  pixels.resize(n);
  active.clear();
  active.reserve(n);  // at most every object: no allocation as the active count changes
  const std::uint64_t counted = cull_range(counts, pixel_scale, config, always_active, 0, n, pixels.data(), active);
  return finish_cull(config, n, counted, pixel_scale, active.size(), stats);
}

int finish_cull(const Config& config, std::size_t objects, std::uint64_t counted, double pixel_scale,
                std::size_t active, FrameStats& stats) {
  stats.mean_pixels = objects ? static_cast<double>(counted) * pixel_scale / static_cast<double>(objects) : 0.0;
  stats.active = static_cast<std::uint32_t>(active);
  return choose_bits(config, true, stats.mean_pixels, active);
}

}  // namespace viscd::detail
