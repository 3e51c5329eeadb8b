#version 450 core
// Stage 2, default mode: pixels per object with SSBO atomicAdd (no limit on the object count).
// The map may be the caller's: an id above N is not counted but reported (FrameInfo.id_check,
// with the first such pixel by row-major index), and the frame fails.
#include "shared/layout.h"
layout(local_size_x = VISCD_TILE_SIDE, local_size_y = VISCD_TILE_SIDE) in;
layout(binding = VISCD_UNIT_IDS) uniform usampler2D u_ids;
layout(std430, binding = VISCD_BIND_COUNTS) buffer Counts { uint counts[]; };
layout(std430, binding = VISCD_BIND_INFO) buffer Info { FrameInfo info; };
uniform ivec2 u_map;
uniform uint u_n;

void main() {
  const ivec2 texel = ivec2(gl_GlobalInvocationID.xy);  // one invocation per map pixel, 2D grid
  if (texel.x >= u_map.x || texel.y >= u_map.y) return;
  const uint id = texelFetch(u_ids, texel, 0).r;
  if (id == 0u) return;
  if (id <= u_n) {
    atomicAdd(counts[id - 1u], 1u);
  } else {
    atomicAdd(info.id_check.x, 1u);
    atomicMin(info.id_check.y, uint(texel.y) * uint(u_map.x) + uint(texel.x));
  }
}
