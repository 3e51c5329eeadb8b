#version 450 core
// Stage 3, step 2 (after an exclusive scan of the flags): active_ids[scan[k]] = k. The scan keeps
// the active list ascending, as the cpu backend's, so that the stable sort breaks Morton ties by
// object index in both backends (an atomic-counter append would give a scheduling-dependent
// order).
#include "shared/layout.h"
layout(local_size_x = VISCD_WG_SIZE) in;
layout(std430, binding = VISCD_BIND_FLAGS) readonly buffer Flags { uint flags[]; };
layout(std430, binding = VISCD_BIND_SCAN_OUT) readonly buffer Scan { uint scan[]; };
layout(std430, binding = VISCD_BIND_ACTIVE) writeonly buffer Active { uint active_ids[]; };
uniform uint u_n;

void main() {
  const uint k = gl_GlobalInvocationID.x;
  if (k < u_n && flags[k] != 0u) active_ids[scan[k]] = k;
}
