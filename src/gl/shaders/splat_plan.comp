#version 450 core
// Stage 1, splat geometry, first pass: one invocation per sphere computes its conservative pixel
// rectangle (core/visibility.hpp sphere_rect(), in double) and the nearest depth any of its hits
// can have, and cuts the rectangle into chunks of VISCD_SPLAT_CHUNK pixels, listed as (sphere,
// chunk) entries: splat.comp then runs one work group per chunk, so that a sphere covering the
// screen spreads over the whole GPU and a sphere covering one pixel costs one group. Entries past
// u_capacity are counted, not written: the host reads the count, grows the list and plans again.
#include "shared/layout.h"
layout(local_size_x = VISCD_WG_SIZE) in;
layout(std430, binding = VISCD_BIND_SPHERES) readonly buffer Spheres { vec4 spheres[]; };
layout(std430, binding = VISCD_BIND_SPLAT_RECTS) writeonly buffer Rects { uvec4 rects[]; };  // x0 | y0 << 16, width, height, near bits
layout(std430, binding = VISCD_BIND_SPLAT_CHUNKS) writeonly buffer Chunks { uvec2 chunks[]; };  // sphere, chunk
layout(std430, binding = VISCD_BIND_SPLAT_COUNT) buffer Count { uint chunk_count; };
uniform vec3 u_eye;
uniform vec3 u_forward;
uniform vec3 u_right;
uniform vec3 u_up;
uniform vec2 u_tan_half;
uniform vec2 u_near_far;
uniform ivec2 u_map;
uniform uint u_objects;
uniform uint u_capacity;

int clamp_pixel(double v, int hi) {  // int(std::clamp(v, 0.0, hi))
  const double h = double(hi);
  return int(v < 0.0lf ? 0.0lf : (h < v ? h : v));
}

// The slopes of the two tangents from the eye to the circle (cv, cz) of radius r, over tan_half.
void span_of(float cv, float cz, float r, float tan_half, out double lo, out double hi) {
  const double v = double(cv), z = double(cz), rr = double(r);
  const double q = v * v + z * z - rr * rr;
  const double t = sqrt(q < 0.0lf ? 0.0lf : q);
  lo = (v * t - rr * z) / (z * t + v * rr) / double(tan_half);
  hi = (v * t + rr * z) / (z * t - v * rr) / double(tan_half);
}

void main() {
  const uint k = gl_GlobalInvocationID.y * (gl_NumWorkGroups.x * VISCD_WG_SIZE) + gl_GlobalInvocationID.x;
  if (k >= u_objects) return;
  const vec4 s = spheres[k];
  // sphere_rect(): the centre in camera axes, the radius widened for hit()'s rounding.
  precise float c0 = s.x - u_eye.x, c1 = s.y - u_eye.y, c2 = s.z - u_eye.z;
  precise float cz = c0 * u_forward.x + c1 * u_forward.y + c2 * u_forward.z;
  precise float cx = c0 * u_right.x + c1 * u_right.y + c2 * u_right.z;
  precise float cy = c0 * u_up.x + c1 * u_up.y + c2 * u_up.z;
  const double o2 = double(cz) * double(cz) + double(cx) * double(cx) + double(cy) * double(cy);
  precise float l1f = abs(cz) + abs(cx) + abs(cy);
  const double rs = double(s.w);
  const float r = float(sqrt(rs * rs + 1.9073486328125e-06lf * o2) + 1e-4lf * (double(l1f) + rs) + 1e-6lf);
  precise float front = cz + r, back = cz - r;
  if (front < u_near_far.x || back > u_near_far.y) return;
  int x0 = 0, y0 = 0, x1 = u_map.x, y1 = u_map.y;
  uint near_bits = 0u;  // every hit has t >= back when the sphere is wholly in front
  if (back > u_near_far.x * 0.5) {
    double nx0, nx1, ny0, ny1;
    span_of(cx, cz, r, u_tan_half.x, nx0, nx1);
    span_of(cy, cz, r, u_tan_half.y, ny0, ny1);
    x0 = clamp_pixel(floor((nx0 + 1.0lf) * 0.5lf * double(u_map.x) - 0.5lf) - 1.0lf, u_map.x);
    x1 = clamp_pixel(ceil((nx1 + 1.0lf) * 0.5lf * double(u_map.x) - 0.5lf) + 2.0lf, u_map.x);
    y0 = clamp_pixel(floor((1.0lf - ny1) * 0.5lf * double(u_map.y) - 0.5lf) - 1.0lf, u_map.y);
    y1 = clamp_pixel(ceil((1.0lf - ny0) * 0.5lf * double(u_map.y) - 0.5lf) + 2.0lf, u_map.y);
    near_bits = floatBitsToUint(back);
  }
  if (x0 >= x1 || y0 >= y1) return;
  const uint w = uint(x1 - x0), pixels = w * uint(y1 - y0);
  rects[k] = uvec4(uint(x0) | (uint(y0) << 16), w, uint(y1 - y0), near_bits);  // map sides < 2^16
  const uint n = (pixels + VISCD_SPLAT_CHUNK - 1u) / VISCD_SPLAT_CHUNK;
  const uint base = atomicAdd(chunk_count, n);
  for (uint c = 0u; c < n && base + c < u_capacity; ++c) chunks[base + c] = uvec2(k, c);
}
