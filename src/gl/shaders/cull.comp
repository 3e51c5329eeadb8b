#version 450 core
// Stage 3: cull and compact (paper Fig. 3).
// Phase 0: screen-scaled pixels (double, as core/visibility.cpp), active flag
// (pixels >= lambda, or every object without culling / camera) and the integer pixel total.
// Phase 1 (after an exclusive scan of the flags): active_ids[scan[k]] = k. The scan keeps the active
// list ascending, as the cpu backend's, so that the stable sort breaks Morton ties by object
// index in both backends (an atomic-counter append would give a scheduling-dependent order).
#include "shared/layout.h"
layout(local_size_x = VISCD_WG_SIZE) in;
layout(std430, binding = VISCD_BIND_COUNTS) readonly buffer Counts { uint counts[]; };
layout(std430, binding = VISCD_BIND_PIXELS) writeonly buffer Pixels { float pixels[]; };
layout(std430, binding = VISCD_BIND_FLAGS) buffer Flags { uint flags[]; };
layout(std430, binding = VISCD_BIND_SCAN_OUT) readonly buffer Scan { uint scan[]; };
layout(std430, binding = VISCD_BIND_ACTIVE) writeonly buffer Active { uint active_ids[]; };
layout(std430, binding = VISCD_BIND_INFO) buffer Info { FrameInfo info; };
uniform uint u_n;
uniform uint u_phase;
uniform uint u_has_counts;  // 0: no camera, every object active
uniform uint u_culling;
uniform double u_scale;     // screen pixels per map pixel
uniform double u_lambda;
shared uint s_total;

void main() {
  const uint k = gl_GlobalInvocationID.x;
  if (u_phase == 1u) {
    if (k < u_n && flags[k] != 0u) active_ids[scan[k]] = k;
    return;
  }
  if (gl_LocalInvocationID.x == 0u) s_total = 0u;
  barrier();
  if (k < u_n) {
    uint flag = 1u;
    if (u_has_counts != 0u) {
      const uint c = counts[k];
      const double px = double(c) * u_scale;
      pixels[k] = float(px);
      if (u_culling != 0u && !(px >= u_lambda)) flag = 0u;
      atomicAdd(s_total, c);
    }
    flags[k] = flag;
  }
  barrier();
  if (gl_LocalInvocationID.x == 0u && s_total != 0u) atomicAdd(info.total_pixels, s_total);
}
