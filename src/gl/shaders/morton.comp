#version 450 core
// Stage 5: Morton codes of the active centres, bit for bit core/morton.hpp's MortonEncoder:
// the quantisation q = (v - lo) * scale is done in double with the host's lo, scale and
// max_cell (the host computes them exactly as MortonEncoder does), and each axis bit b goes to
// code bit u_position[axis * 32 + b]. Keys are uvec2 (x = low 32 bits, y = high 32 bits) for
// every width m, so 16/32/64-bit codes share one sort.
// n is read from FrameInfo.active_count (written on the GPU by the compaction), and the pass is
// dispatched indirectly from it: the host never waits for n. With a previous frame's lo/scale (GlOptions::sync_layout
// false) a centre may lie outside the bounds: quantize() clamps it to the border cell
// (q <= 0 or NaN -> 0, q >= max_cell -> max_cell), as MortonEncoder does.
#include "shared/layout.h"
layout(local_size_x = VISCD_WG_SIZE) in;
layout(std430, binding = VISCD_BIND_SPHERES) readonly buffer Spheres { vec4 spheres[]; };
layout(std430, binding = VISCD_BIND_ACTIVE) readonly buffer Active { uint active_ids[]; };
layout(std430, binding = VISCD_BIND_KEYS_OUT) writeonly buffer Keys { uvec2 keys[]; };
layout(std430, binding = VISCD_BIND_VALUES_OUT) writeonly buffer Values { uint values[]; };
layout(std430, binding = VISCD_BIND_INFO) readonly buffer Info { FrameInfo info; };
uniform dvec3 u_lo;
uniform dvec3 u_scale;
uniform dvec3 u_max_cell;
uniform ivec3 u_axis_bits;
uniform int u_position[96];

uint quantize(double v, double lo, double scale, double max_cell) {
  precise double q = (v - lo) * scale;
  if (!(q > 0.0lf)) return 0u;  // also NaN
  return q >= max_cell ? uint(max_cell) : uint(q);
}

void scatter(int axis, uint q, inout uvec2 key) {
  for (int b = 0; b < u_axis_bits[axis]; ++b) {
    if (((q >> uint(b)) & 1u) == 0u) continue;
    const int p = u_position[axis * 32 + b];
    if (p < 32) key.x |= 1u << uint(p);
    else key.y |= 1u << uint(p - 32);
  }
}

void main() {
  const uint k = gl_GlobalInvocationID.x;
  if (k >= info.active_count) return;
  const uint id = active_ids[k];
  const vec4 s = spheres[id];
  uvec2 key = uvec2(0u);
  scatter(0, quantize(double(s.x), u_lo.x, u_scale.x, u_max_cell.x), key);
  scatter(1, quantize(double(s.y), u_lo.y, u_scale.y, u_max_cell.y), key);
  scatter(2, quantize(double(s.z), u_lo.z, u_scale.z, u_max_cell.z), key);
  keys[k] = key;
  values[k] = id;
}
