#version 450 core
// Stage 4's inputs on the GPU, step 2: one work group folds the partials of bounds.comp in a
// fixed order (deterministic) into FrameInfo's bounds and diameter sum.
#include "shared/layout.h"
layout(local_size_x = VISCD_WG_SIZE) in;
layout(std430, binding = VISCD_BIND_PARTIALS) readonly buffer Partials { BoundsPartial partials[]; };
layout(std430, binding = VISCD_BIND_INFO) buffer Info { FrameInfo info; };
shared vec3 s_lo[VISCD_WG_SIZE];
shared vec3 s_hi[VISCD_WG_SIZE];
shared double s_d[VISCD_WG_SIZE];

void main() {
  const uint t = gl_LocalInvocationID.x;
  const float inf = uintBitsToFloat(0x7f800000u);
  const uint groups = (info.active_count + VISCD_WG_SIZE - 1u) / VISCD_WG_SIZE;
  vec3 lo = vec3(inf), hi = vec3(-inf);
  double d = 0.0lf;
  for (uint g = t; g < groups; g += VISCD_WG_SIZE) {
    lo = min(lo, partials[g].lo.xyz);
    hi = max(hi, partials[g].hi.xyz);
    d += partials[g].diameter_sum.x;
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
  info.lo = vec4(s_lo[0], 0.0);
  info.hi = vec4(s_hi[0], 0.0);
  info.diameter_sum = dvec2(s_d[0], 0.0lf);
}
