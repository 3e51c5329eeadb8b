#version 450 core
// Stage 4's inputs on the GPU, step 1: one partial per work group of the bounds of the active
// centres and the sum of their diameters, over active_ids[0..n). n is read from FrameInfo
// (written by the compaction) and the pass is dispatched indirectly from it: the host does not
// wait for the active count.
#include "shared/layout.h"
layout(local_size_x = VISCD_WG_SIZE) in;
layout(std430, binding = VISCD_BIND_SPHERES) readonly buffer Spheres { vec4 spheres[]; };
layout(std430, binding = VISCD_BIND_ACTIVE) readonly buffer Active { uint active_ids[]; };
layout(std430, binding = VISCD_BIND_PARTIALS) writeonly buffer Partials { BoundsPartial partials[]; };
layout(std430, binding = VISCD_BIND_INFO) readonly buffer Info { FrameInfo info; };
shared vec3 s_lo[VISCD_WG_SIZE];
shared vec3 s_hi[VISCD_WG_SIZE];
shared double s_d[VISCD_WG_SIZE];

void main() {
  const uint t = gl_LocalInvocationID.x;
  const float inf = uintBitsToFloat(0x7f800000u);
  const uint k = gl_GlobalInvocationID.x;
  vec3 lo = vec3(inf), hi = vec3(-inf);
  double d = 0.0lf;
  if (k < info.active_count) {
    const vec4 s = spheres[active_ids[k]];
    lo = s.xyz;
    hi = s.xyz;
    d = 2.0lf * double(s.w);
  }
  s_lo[t] = lo;
  s_hi[t] = hi;
  s_d[t] = d;
  barrier();
  for (uint off = VISCD_WG_SIZE / 2u; off > 0u; off >>= 1u) {
    if (t < off) {
      s_lo[t] = min(s_lo[t], s_lo[t + off]);
      s_hi[t] = max(s_hi[t], s_hi[t + off]);
      s_d[t] += s_d[t + off];
    }
    barrier();
  }
  if (t != 0u) return;
  partials[gl_WorkGroupID.x].lo = vec4(s_lo[0], 0.0);
  partials[gl_WorkGroupID.x].hi = vec4(s_hi[0], 0.0);
  partials[gl_WorkGroupID.x].diameter_sum = dvec2(s_d[0], 0.0lf);
}
