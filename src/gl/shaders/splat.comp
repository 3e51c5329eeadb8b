#version 450 core
// Stage 1, splat geometry (GlGeometry::splat): the visibility map of spheres without the raster
// pipeline, for GPUs whose graphics units are few (docs/gpu.md). One work group per chunk of
// VISCD_SPLAT_CHUNK pixels of a sphere's rectangle (splat_plan.comp), one invocation per pixel:
// the pixel's ray as CameraRig::dir() and hit() (the impostor's float operations, `precise`),
// and the nearest hit kept with 32-bit atomics in two passes: u_pass 0 the smallest depth
// (non-negative floats order as their bits), u_pass 1 the smallest id among the hits at that
// depth, which is the CPU rasterizers' tie rule. A pixel whose depth so far is below the sphere's
// nearest possible hit is skipped early. splat_resolve.comp then writes the G-buffer.
#include "shared/layout.h"
layout(local_size_x = VISCD_SPLAT_CHUNK) in;
layout(std430, binding = VISCD_BIND_SPHERES) readonly buffer Spheres { vec4 spheres[]; };
layout(std430, binding = VISCD_BIND_SPLAT_DEPTH) buffer Depth { uint depth_bits[]; };
layout(std430, binding = VISCD_BIND_SPLAT_IDS) buffer Ids { uint ids[]; };
layout(std430, binding = VISCD_BIND_SPLAT_RECTS) readonly buffer Rects { uvec4 rects[]; };
layout(std430, binding = VISCD_BIND_SPLAT_CHUNKS) readonly buffer Chunks { uvec2 chunks[]; };
uniform vec3 u_eye;
uniform vec3 u_forward;
uniform vec3 u_right;
uniform vec3 u_up;
uniform vec2 u_tan_half;
uniform vec2 u_near_far;
uniform ivec2 u_map;
uniform uint u_chunks;
uniform uint u_pass;

void main() {
  const uint e = gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x;
  if (e >= u_chunks) return;
  const uint k = chunks[e].x;
  const uvec4 rect = rects[k];  // x0 | y0 << 16, width, height, near bits
  const uint i = chunks[e].y * VISCD_SPLAT_CHUNK + gl_LocalInvocationID.x;
  if (i >= rect.y * rect.z) return;
  const int px = int((rect.x & 0xFFFFu) + i % rect.y), py = int((rect.x >> 16) + i / rect.y);
  const uint p = uint(py) * uint(u_map.x) + uint(px);
  if (depth_bits[p] < rect.w) return;  // something nearer than any hit of this sphere
  const vec4 s = spheres[k];
  precise float nx = (2.0 * (float(px) + 0.5) / float(u_map.x) - 1.0) * u_tan_half.x;
  precise float ny = (1.0 - 2.0 * (float(py) + 0.5) / float(u_map.y)) * u_tan_half.y;
  precise vec3 d = u_forward + u_right * nx + u_up * ny;
  precise float ox = u_eye.x - s.x, oy = u_eye.y - s.y, oz = u_eye.z - s.z;
  precise float a = d.x * d.x + d.y * d.y + d.z * d.z;
  precise float b = ox * d.x + oy * d.y + oz * d.z;
  precise float c = ox * ox + oy * oy + oz * oz - s.w * s.w;
  precise float disc = b * b - a * c;
  if (!(disc >= 0.0)) return;
  precise float sq = sqrt(disc);
  precise float t = (-b - sq) / a;
  if (!(t >= u_near_far.x && t <= u_near_far.y)) {
    t = (-b + sq) / a;
    if (!(t >= u_near_far.x && t <= u_near_far.y)) return;
  }
  const uint bits = floatBitsToUint(t);
  if (u_pass == 0u)
    atomicMin(depth_bits[p], bits);
  else if (depth_bits[p] == bits)
    atomicMin(ids[p], k + 1u);
}
