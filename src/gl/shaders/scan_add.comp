#version 450 core
// Scan, step 3 of 3: adds each block's offset to its elements.
#include "shared/layout.h"
layout(local_size_x = VISCD_WG_SIZE) in;
layout(std430, binding = VISCD_BIND_SCAN_OUT) buffer Out { uint out_data[]; };
layout(std430, binding = VISCD_BIND_SCAN_BLOCKS) readonly buffer Blocks { uint blocks[]; };
uniform uint u_n;

void main() {
  const uint idx = gl_GlobalInvocationID.x;
  if (idx < u_n) out_data[idx] += blocks[idx / VISCD_SCAN_BLOCK];
}
