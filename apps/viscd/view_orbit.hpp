#pragma once
// The camera of `viscd view`: an orbit around a target point (yaw, pitch, distance), driven by
// mouse drags and the wheel, turned into a viscd::Camera each frame. World up is +y.

#include <algorithm>
#include <cmath>

#include "viscd/types.hpp"

namespace viscd::app {

class OrbitCamera {
 public:
  /// Takes eye, target, field of view and clip planes from `c`; `world_radius` bounds the
  /// scene, so that the far plane always reaches past it however far the camera zooms out.
  void reset(const Camera& c, float world_radius) {
    for (int k = 0; k < 3; ++k) target_[k] = c.target[k];
    const float v[3] = {c.eye[0] - c.target[0], c.eye[1] - c.target[1], c.eye[2] - c.target[2]};
    distance_ = std::max(std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]), 1e-6f);
    pitch_ = std::clamp(std::asin(std::clamp(v[1] / distance_, -1.0f, 1.0f)), -kMaxPitch, kMaxPitch);
    yaw_ = std::atan2(v[0], v[2]);
    fov_y_deg_ = c.fov_y_deg;
    near_ = c.near_plane;
    far_ = c.far_plane;
    world_radius_ = world_radius;
    max_distance_ = std::max({20.0f * world_radius, 2.0f * distance_, 4.0f * near_});
  }

  /// Left drag by (dx, dy) window pixels: turn around the target (drag down looks from higher up).
  void orbit(float dx, float dy) {
    yaw_ -= dx * kRadiansPerPixel;
    pitch_ = std::clamp(pitch_ + dy * kRadiansPerPixel, -kMaxPitch, kMaxPitch);
  }

  /// Right or middle drag by (dx, dy) window pixels in a window `height` pixels high: move the
  /// target (and the eye with it) so that the point under the cursor follows the cursor.
  void pan(float dx, float dy, int height) {
    float f[3], r[3], u[3];
    basis(f, r, u);
    const float world_per_pixel =
        2.0f * distance_ * std::tan(0.5f * fov_y_deg_ * kPi / 180.0f) / static_cast<float>(std::max(height, 1));
    for (int k = 0; k < 3; ++k) target_[k] += (-dx * r[k] + dy * u[k]) * world_per_pixel;
  }

  /// Wheel: `steps` > 0 moves closer (each step 15 %), < 0 farther (at most 20 world radii away).
  void zoom(float steps) { distance_ = std::clamp(distance_ * std::pow(0.85f, steps), 4.0f * near_, max_distance_); }

  /// The camera for a screen of width x height pixels.
  [[nodiscard]] Camera camera(int width, int height) const {
    Camera c;
    float f[3], r[3], u[3];
    basis(f, r, u);
    for (int k = 0; k < 3; ++k) {
      c.target[k] = target_[k];
      c.eye[k] = target_[k] - distance_ * f[k];
    }
    c.up[0] = 0, c.up[1] = 1, c.up[2] = 0;
    c.fov_y_deg = fov_y_deg_;
    c.near_plane = near_;
    c.far_plane = std::max(far_, 2.0f * (distance_ + 2.0f * world_radius_));
    c.width = std::max(width, 1);
    c.height = std::max(height, 1);
    return c;
  }

  [[nodiscard]] float distance() const { return distance_; }

 private:
  static constexpr float kPi = 3.14159265358979f;
  static constexpr float kMaxPitch = 1.55f;  // just short of straight up/down, where up is parallel
  static constexpr float kRadiansPerPixel = 0.005f;

  // f: view direction (eye to target), r: right, u: camera up.
  void basis(float f[3], float r[3], float u[3]) const {
    const float cp = std::cos(pitch_), sp = std::sin(pitch_), cy = std::cos(yaw_), sy = std::sin(yaw_);
    f[0] = -cp * sy, f[1] = -sp, f[2] = -cp * cy;
    r[0] = cy, r[1] = 0, r[2] = -sy;  // normalize(cross(f, +y))
    u[0] = r[1] * f[2] - r[2] * f[1], u[1] = r[2] * f[0] - r[0] * f[2], u[2] = r[0] * f[1] - r[1] * f[0];
  }

  float target_[3] = {0, 0, 0};
  float distance_ = 10, yaw_ = 0, pitch_ = 0;
  float fov_y_deg_ = 60, near_ = 0.1f, far_ = 1000, world_radius_ = 1, max_distance_ = 1000;
};

}  // namespace viscd::app
