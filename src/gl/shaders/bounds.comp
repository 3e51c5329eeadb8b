#version 450 core
// Stage 4's inputs on the GPU: bounds of the active centres and the sum of their diameters.
// Phase 0: one partial per group over active_ids[0..n); phase 1: one group folds the partials in a
// fixed order (deterministic). n is read from FrameInfo (written by the compaction), so the host
// dispatches over N without waiting for the active count.
#include "shared/layout.h"
layout(local_size_x = VISCD_WG_SIZE) in;
layout(std430, binding = VISCD_BIND_SPHERES) readonly buffer Spheres { vec4 spheres[]; };
layout(std430, binding = VISCD_BIND_ACTIVE) readonly buffer Active { uint active_ids[]; };
layout(std430, binding = VISCD_BIND_PARTIALS) buffer Partials { BoundsPartial partials[]; };
layout(std430, binding = VISCD_BIND_INFO) buffer Info { FrameInfo info; };
uniform uint u_phase;
shared vec3 s_lo[VISCD_WG_SIZE];
shared vec3 s_hi[VISCD_WG_SIZE];
shared double s_d[VISCD_WG_SIZE];

void reduce(uint t) {
  barrier();
  for (uint off = VISCD_WG_SIZE / 2u; off > 0u; off >>= 1u) {
    if (t < off) {
      s_lo[t] = min(s_lo[t], s_lo[t + off]);
      s_hi[t] = max(s_hi[t], s_hi[t + off]);
      s_d[t] += s_d[t + off];
    }
    barrier();
  }
}

void main() {
  const uint t = gl_LocalInvocationID.x;
  const float inf = uintBitsToFloat(0x7f800000u);
  const uint n = info.active_count;
  vec3 lo = vec3(inf), hi = vec3(-inf);
  double d = 0.0lf;
  if (u_phase == 0u) {
    const uint k = gl_GlobalInvocationID.x;
    if (k < n) {
      const vec4 s = spheres[active_ids[k]];
      lo = s.xyz;
      hi = s.xyz;
      d = 2.0lf * double(s.w);
    }
  } else {
    const uint groups = (n + VISCD_WG_SIZE - 1u) / VISCD_WG_SIZE;
    for (uint g = t; g < groups; g += VISCD_WG_SIZE) {
      lo = min(lo, partials[g].lo.xyz);
      hi = max(hi, partials[g].hi.xyz);
      d += partials[g].diameter_sum.x;
    }
  }
  s_lo[t] = lo;
  s_hi[t] = hi;
  s_d[t] = d;
  reduce(t);
  if (t != 0u) return;
  if (u_phase == 0u) {
    if (gl_WorkGroupID.x * VISCD_WG_SIZE < n) {
      partials[gl_WorkGroupID.x].lo = vec4(s_lo[0], 0.0);
      partials[gl_WorkGroupID.x].hi = vec4(s_hi[0], 0.0);
      partials[gl_WorkGroupID.x].diameter_sum = dvec2(s_d[0], 0.0lf);
    }
  } else {
    info.lo = vec4(s_lo[0], 0.0);
    info.hi = vec4(s_hi[0], 0.0);
    info.diameter_sum = dvec2(s_d[0], 0.0lf);
  }
}
