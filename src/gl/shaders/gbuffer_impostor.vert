#version 450 core
// Stage 1, impostor geometry: one quad per sphere (instance), covering the conservative pixel
// rectangle of core/visibility.cpp sphere_rect(); the fragment shader ray-casts the sphere.
#include "shared/layout.h"
layout(std430, binding = VISCD_BIND_SPHERES) readonly buffer Spheres { vec4 spheres[]; };
uniform vec3 u_eye;
uniform vec3 u_forward;
uniform vec3 u_right;
uniform vec3 u_up;
uniform vec2 u_tan_half;  // x, y
uniform vec2 u_near_far;
uniform ivec2 u_map;
flat out uint v_index;

vec2 span_of(float lo, float hi, float dmin, float dmax, float tan_half) {
  const float vmax = (hi >= 0.0 ? hi / dmin : hi / dmax) / tan_half;
  const float vmin = (lo <= 0.0 ? lo / dmin : lo / dmax) / tan_half;
  return vec2(vmin, vmax);
}

void main() {
  const vec4 s = spheres[gl_InstanceID];
  const vec3 c = s.xyz - u_eye;
  const float cz = dot(c, u_forward), cx = dot(c, u_right), cy = dot(c, u_up);
  const float slack = 1e-4 * (abs(cz) + abs(cx) + abs(cy) + s.w) + 1e-6;
  const float r = s.w + slack;
  ivec4 rect = ivec4(0, 0, u_map);  // x0, y0, x1, y1 in pixels, rows from the top
  if (cz + r < u_near_far.x || cz - r > u_near_far.y) {
    rect = ivec4(0);
  } else if (cz - r > u_near_far.x * 0.5) {
    const float dmin = cz - r, dmax = cz + r;
    const vec2 nx = span_of(cx - r, cx + r, dmin, dmax, u_tan_half.x);
    const vec2 ny = span_of(cy - r, cy + r, dmin, dmax, u_tan_half.y);
    const vec2 map = vec2(u_map);
    rect.x = int(clamp(floor((nx.x + 1.0) * 0.5 * map.x - 0.5) - 1.0, 0.0, map.x));
    rect.z = int(clamp(ceil((nx.y + 1.0) * 0.5 * map.x - 0.5) + 2.0, 0.0, map.x));
    rect.y = int(clamp(floor((1.0 - ny.y) * 0.5 * map.y - 0.5) - 1.0, 0.0, map.y));
    rect.w = int(clamp(ceil((1.0 - ny.x) * 0.5 * map.y - 0.5) + 2.0, 0.0, map.y));
  }
  // Triangle strip corners 0..3; an empty rectangle collapses to a point (no fragments).
  const int px = (gl_VertexID & 1) != 0 ? rect.z : rect.x;
  const int py = (gl_VertexID & 2) != 0 ? rect.w : rect.y;
  gl_Position = vec4(2.0 * float(px) / float(u_map.x) - 1.0, 1.0 - 2.0 * float(py) / float(u_map.y), 0.0, 1.0);
  v_index = uint(gl_InstanceID);
}
