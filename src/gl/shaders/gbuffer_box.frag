#version 450 core
// Stage 1, boxes: the ray through the pixel centre against the box by slabs, exactly
// core/visibility.hpp's CameraRig::dir() and hit_box() (same float operations, `precise`, no
// FMA; GLSL's max and min pick as std::max and std::min do), so the id map matches the cpu
// rasterizer's up to the rounding of GPU division. The nearest hit t with near <= t <= far, else
// the far side (camera inside, or the front clipped by the near plane), else no fragment.
// gl_FragDepth = t / far: the depth test keeps the nearest hit, equal depths the first drawn
// instance (smaller id), as the cpu rasterizer's tie rule. The normal is that of the face nearest
// the hit point, as the cpu's write_normal().
#include "shared/layout.h"
layout(std430, binding = VISCD_BIND_BOXES) readonly buffer Boxes { LeafBox boxes[]; };
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
  const vec3 lo = vec3(boxes[v_index].v[0], boxes[v_index].v[1], boxes[v_index].v[2]);
  const vec3 hi = vec3(boxes[v_index].v[3], boxes[v_index].v[4], boxes[v_index].v[5]);
  const float inf = uintBitsToFloat(0x7f800000u);
  precise float t0 = -inf, t1 = inf;
  for (int a = 0; a < 3; ++a) {
    if (d[a] == 0.0) {
      if (u_eye[a] < lo[a] || u_eye[a] > hi[a]) discard;
      continue;
    }
    precise float enter = (lo[a] - u_eye[a]) / d[a];
    precise float leave = (hi[a] - u_eye[a]) / d[a];
    if (enter > leave) {
      const float swap = enter;
      enter = leave;
      leave = swap;
    }
    t0 = max(t0, enter);
    t1 = min(t1, leave);
  }
  if (!(t0 <= t1)) discard;
  float t;
  if (t0 >= u_near_far.x && t0 <= u_near_far.y) {
    t = t0;
  } else if (t1 >= u_near_far.x && t1 <= u_near_far.y) {
    t = t1;
  } else {
    discard;
  }
  gl_FragDepth = t / u_near_far.y;
  o_id = v_index + 1u;
  o_depth = t;
  precise vec3 p = vec3(u_eye.x + t * d.x, u_eye.y + t * d.y, u_eye.z + t * d.z);
  int axis = 0;
  float sign = -1.0, best = inf;
  for (int a = 0; a < 3; ++a) {
    const float to_min = abs(p[a] - lo[a]), to_max = abs(p[a] - hi[a]);
    if (to_min < best) {
      best = to_min;
      axis = a;
      sign = -1.0;
    }
    if (to_max < best) {
      best = to_max;
      axis = a;
      sign = 1.0;
    }
  }
  vec3 n = vec3(0.0);
  n[axis] = sign;
  o_normal = vec4(n, 0.0);
}
