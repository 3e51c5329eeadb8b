#version 450 core
// Stage 1, impostor geometry: the ray through the pixel centre, exactly core/visibility.hpp's
// CameraRig::dir() and hit() (same float operations, `precise`, no FMA), so the id map matches
// the cpu rasterizer's up to the rounding of GPU division and square root at silhouette edges.
// gl_FragDepth = t / far: the depth test keeps the nearest hit; equal depths keep the first
// drawn instance (smaller id), as the cpu rasterizer's tie rule.
#include "shared/layout.h"
layout(std430, binding = VISCD_BIND_SPHERES) readonly buffer Spheres { vec4 spheres[]; };
uniform vec3 u_eye;
uniform vec3 u_forward;
uniform vec3 u_right;
uniform vec3 u_up;
uniform vec2 u_tan_half;
uniform vec2 u_near_far;
uniform ivec2 u_map;
flat in uint v_index;
layout(location = 0) out uint o_id;
layout(location = 1) out float o_depth;
layout(location = 2) out vec4 o_normal;

void main() {
  const int px = int(gl_FragCoord.x);
  const int py = u_map.y - 1 - int(gl_FragCoord.y);  // rows from the top, as CameraRig
  precise float nx = (2.0 * (float(px) + 0.5) / float(u_map.x) - 1.0) * u_tan_half.x;
  precise float ny = (1.0 - 2.0 * (float(py) + 0.5) / float(u_map.y)) * u_tan_half.y;
  precise vec3 d = u_forward + u_right * nx + u_up * ny;
  const vec4 s = spheres[v_index];
  precise float ox = u_eye.x - s.x, oy = u_eye.y - s.y, oz = u_eye.z - s.z;
  precise float a = d.x * d.x + d.y * d.y + d.z * d.z;
  precise float b = ox * d.x + oy * d.y + oz * d.z;
  precise float c = ox * ox + oy * oy + oz * oz - s.w * s.w;
  precise float disc = b * b - a * c;
  if (!(disc >= 0.0)) discard;
  precise float sq = sqrt(disc);
  precise float t = (-b - sq) / a;
  if (!(t >= u_near_far.x && t <= u_near_far.y)) {
    t = (-b + sq) / a;
    if (!(t >= u_near_far.x && t <= u_near_far.y)) discard;
  }
  gl_FragDepth = t / u_near_far.y;
  o_id = v_index + 1u;
  o_depth = t;
  precise vec3 p = vec3(u_eye.x + t * d.x - s.x, u_eye.y + t * d.y - s.y, u_eye.z + t * d.z - s.z);
  const float l = sqrt(dot(p, p));
  o_normal = vec4(l > 0.0 ? p / l : -d, 0.0);
}
