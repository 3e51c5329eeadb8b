#version 450 core
// Stage 2, default mode: pixels per object with SSBO atomicAdd (no limit on the object count).
#include "shared/layout.h"
layout(local_size_x = VISCD_WG_SIZE) in;
layout(binding = VISCD_UNIT_IDS) uniform usampler2D u_ids;
layout(std430, binding = VISCD_BIND_COUNTS) buffer Counts { uint counts[]; };
uniform ivec2 u_map;

void main() {
  const uint k = gl_GlobalInvocationID.x;
  if (k >= uint(u_map.x) * uint(u_map.y)) return;
  const uint id = texelFetch(u_ids, ivec2(int(k % uint(u_map.x)), int(k / uint(u_map.x))), 0).r;
  if (id > 0u) atomicAdd(counts[id - 1u], 1u);
}
