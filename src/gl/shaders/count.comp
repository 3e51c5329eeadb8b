#version 450 core
// Stage 2, default mode: pixels per object with SSBO atomicAdd (no limit on the object count).
#include "shared/layout.h"
layout(local_size_x = VISCD_TILE_SIDE, local_size_y = VISCD_TILE_SIDE) in;
layout(binding = VISCD_UNIT_IDS) uniform usampler2D u_ids;
layout(std430, binding = VISCD_BIND_COUNTS) buffer Counts { uint counts[]; };
uniform ivec2 u_map;

void main() {
  const ivec2 texel = ivec2(gl_GlobalInvocationID.xy);  // one invocation per map pixel, 2D grid
  if (texel.x >= u_map.x || texel.y >= u_map.y) return;
  const uint id = texelFetch(u_ids, texel, 0).r;
  if (id > 0u) atomicAdd(counts[id - 1u], 1u);
}
