// The checks of the caller's input every backend applies: objects, map size, camera.
#include <cmath>
#include <limits>
#include <string>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "core/frame_rules.hpp"
#include "viscd/detector.hpp"

namespace viscd {

namespace detail {

// |v| <= 1e18 is false for NaN and infinities too.
bool spheres_all_valid(std::span<const Sphere> spheres) {
#if defined(__SSE2__)
  // A sphere is one register (x, y, z, r); two accumulators of "every lane so far valid".
  const __m128 limit = _mm_set1_ps(kMaxCoordinate), sign = _mm_set1_ps(-0.0f), zero = _mm_setzero_ps();
  __m128 ok0 = _mm_cmpeq_ps(zero, zero), ok1 = ok0, radius0 = ok0, radius1 = ok0;
  const float* p = reinterpret_cast<const float*>(spheres.data());
  std::size_t k = 0;
  for (; k + 2 <= spheres.size(); k += 2) {
    const __m128 a = _mm_loadu_ps(p + 4 * k), b = _mm_loadu_ps(p + 4 * k + 4);
    ok0 = _mm_and_ps(ok0, _mm_cmple_ps(_mm_andnot_ps(sign, a), limit));
    ok1 = _mm_and_ps(ok1, _mm_cmple_ps(_mm_andnot_ps(sign, b), limit));
    radius0 = _mm_and_ps(radius0, _mm_cmpge_ps(a, zero));
    radius1 = _mm_and_ps(radius1, _mm_cmpge_ps(b, zero));
  }
  if (k < spheres.size()) {
    const __m128 a = _mm_loadu_ps(p + 4 * k);
    ok0 = _mm_and_ps(ok0, _mm_cmple_ps(_mm_andnot_ps(sign, a), limit));
    radius0 = _mm_and_ps(radius0, _mm_cmpge_ps(a, zero));
  }
  const int ok = _mm_movemask_ps(_mm_and_ps(ok0, ok1)), radius = _mm_movemask_ps(_mm_and_ps(radius0, radius1));
  return ok == 0xF && (radius & 0x8) != 0;  // lane 3: r >= 0
#else
  bool all_valid = true;
  for (const Sphere& s : spheres) all_valid &= sphere_valid(s);
  return all_valid;
#endif
}

bool boxes_all_valid(std::span<const Box> boxes) {
  bool all_valid = true;
  for (const Box& b : boxes) all_valid &= box_valid(b);
  return all_valid;
}

}  // namespace detail

namespace detail {

Status sphere_problem(const Sphere& s, const std::string& name) {
  const float v[4] = {s.x, s.y, s.z, s.r};
  for (int c = 0; c < 4; ++c) {
    if (!std::isfinite(v[c]))
      return Status::failure(ErrorKind::invalid_input, name + ": " + "xyzr"[c] + " is not a finite number");
    if (std::fabs(v[c]) > kMaxCoordinate)
      return Status::failure(ErrorKind::invalid_input,
                             name + ": |" + "xyzr"[c] + "| = " + std::to_string(v[c]) + " exceeds the supported 1e18");
  }
  if (s.r < 0) return Status::failure(ErrorKind::invalid_input, name + ": negative radius " + std::to_string(s.r));
  return {};
}

Status box_problem(const Box& b, const std::string& name) {
  static constexpr const char* kNames[2][3] = {{"minx", "miny", "minz"}, {"maxx", "maxy", "maxz"}};
  for (int side = 0; side < 2; ++side)
    for (int k = 0; k < 3; ++k) {
      const float v = side ? b.max[k] : b.min[k];
      if (!std::isfinite(v))
        return Status::failure(ErrorKind::invalid_input, name + ": " + kNames[side][k] + " is not a finite number");
      if (std::fabs(v) > kMaxCoordinate)
        return Status::failure(ErrorKind::invalid_input, name + ": |" + kNames[side][k] + "| = " + std::to_string(v) +
                                                             " exceeds the supported 1e18");
    }
  for (int k = 0; k < 3; ++k)
    if (!(b.min[k] <= b.max[k]))
      return Status::failure(ErrorKind::invalid_input, name + ": " + kNames[0][k] + " = " + std::to_string(b.min[k]) +
                                                           " exceeds " + kNames[1][k] + " = " +
                                                           std::to_string(b.max[k]));
  return {};
}

}  // namespace detail

Status validate_spheres(std::span<const Sphere> spheres) {
  if (spheres.size() > static_cast<std::size_t>(std::numeric_limits<std::int32_t>::max()))
    return Status::failure(ErrorKind::invalid_input,
                           "too many spheres: " + std::to_string(spheres.size()) + " (at most 2^31 - 1)");
  // A pass without branches first (every frame pays it). Only a failing set is searched for its
  // first bad sphere.
  if (detail::spheres_all_valid(spheres)) return {};
  for (std::size_t k = 0; k < spheres.size(); ++k)
    if (!detail::spheres_all_valid(spheres.subspan(k, 1)))
      return detail::sphere_problem(spheres[k], "sphere " + std::to_string(k));
  return {};
}

Status validate_boxes(std::span<const Box> boxes) {
  if (boxes.size() > static_cast<std::size_t>(std::numeric_limits<std::int32_t>::max()))
    return Status::failure(ErrorKind::invalid_input,
                           "too many boxes: " + std::to_string(boxes.size()) + " (at most 2^31 - 1)");
  if (detail::boxes_all_valid(boxes)) return {};  // without branches, as validate_spheres()
  for (std::size_t i = 0; i < boxes.size(); ++i)
    if (!detail::boxes_all_valid(boxes.subspan(i, 1))) return detail::box_problem(boxes[i], "box " + std::to_string(i));
  return {};
}

Status validate_map_size(int width, int height) {
  if (width <= kMaxMapSide && height <= kMaxMapSide &&
      static_cast<std::uint64_t>(width) * static_cast<std::uint64_t>(height) <= kMaxMapPixels)
    return {};
  return Status::failure(ErrorKind::invalid_input,
                         "visibility map " + std::to_string(width) + "x" + std::to_string(height) +
                             " is too large: at most " + std::to_string(kMaxMapSide) + " pixels a side and " +
                             std::to_string(kMaxMapPixels) + " pixels in all (8192x8192); a smaller map works, " +
                             "its counts are scaled to the screen");
}

Status validate_camera(const Camera& c) {
  auto finite3 = [](const float* v) { return std::isfinite(v[0]) && std::isfinite(v[1]) && std::isfinite(v[2]); };
  if (!finite3(c.eye) || !finite3(c.target) || !finite3(c.up))
    return Status::failure(ErrorKind::invalid_input, "camera: eye, target and up must be finite");
  // Bounded like spheres: squared distances stay finite in float, so no projection overflows.
  auto bounded3 = [](const float* v) {
    return std::fabs(v[0]) <= kMaxCoordinate && std::fabs(v[1]) <= kMaxCoordinate && std::fabs(v[2]) <= kMaxCoordinate;
  };
  if (!bounded3(c.eye) || !bounded3(c.target) || !bounded3(c.up))
    return Status::failure(ErrorKind::invalid_input,
                           "camera: eye, target and up must lie within the supported magnitude 1e18");
  if (c.width < 1 || c.height < 1)
    return Status::failure(ErrorKind::invalid_input, "camera: width and height must be at least 1 pixel");
  if (!(c.fov_y_deg > 0 && c.fov_y_deg < 180))
    return Status::failure(ErrorKind::invalid_input, "camera: fov_y_deg must be in (0, 180)");
  if (!(c.near_plane > 0 && c.far_plane > c.near_plane && c.far_plane <= kMaxCoordinate))
    return Status::failure(ErrorKind::invalid_input, "camera: need 0 < near < far <= 1e18");
  const double f[3] = {double(c.target[0]) - c.eye[0], double(c.target[1]) - c.eye[1], double(c.target[2]) - c.eye[2]};
  const double fl = std::sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2]);
  if (!(fl > 0)) return Status::failure(ErrorKind::invalid_input, "camera: eye and target coincide");
  const double u[3] = {c.up[0], c.up[1], c.up[2]};
  const double cx = f[1] * u[2] - f[2] * u[1], cy = f[2] * u[0] - f[0] * u[2], cz = f[0] * u[1] - f[1] * u[0];
  const double ul = std::sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
  if (!(std::sqrt(cx * cx + cy * cy + cz * cz) > 1e-6 * fl * ul))
    return Status::failure(ErrorKind::invalid_input, "camera: up is zero or parallel to the view direction");
  return {};
}

}  // namespace viscd
