#version 450 core
// Scan, step 1 of 3 (reduce-then-scan, no inter-group communication inside a dispatch, so no
// forward-progress assumption): each group scans its block of VISCD_SCAN_BLOCK elements
// (exclusive) and writes the block's total to blocks[group].
#include "shared/layout.h"
layout(local_size_x = VISCD_WG_SIZE) in;
layout(std430, binding = VISCD_BIND_SCAN_IN) readonly buffer In { uint in_data[]; };
layout(std430, binding = VISCD_BIND_SCAN_OUT) writeonly buffer Out { uint out_data[]; };
layout(std430, binding = VISCD_BIND_SCAN_BLOCKS) writeonly buffer Blocks { uint blocks[]; };
uniform uint u_n;
shared uint s_sum[VISCD_WG_SIZE];

void main() {
  const uint t = gl_LocalInvocationID.x;
  const uint base = gl_WorkGroupID.x * VISCD_SCAN_BLOCK + t * VISCD_SCAN_PER_THREAD;
  uint v[VISCD_SCAN_PER_THREAD];
  uint sum = 0u;
  for (uint i = 0u; i < VISCD_SCAN_PER_THREAD; ++i) {
    const uint idx = base + i;
    v[i] = idx < u_n ? in_data[idx] : 0u;
    sum += v[i];
  }
  s_sum[t] = sum;
  barrier();
  // Hillis-Steele inclusive scan of the per-invocation sums.
  for (uint off = 1u; off < VISCD_WG_SIZE; off <<= 1u) {
    const uint x = t >= off ? s_sum[t - off] : 0u;
    barrier();
    s_sum[t] += x;
    barrier();
  }
  uint run = s_sum[t] - sum;
  for (uint i = 0u; i < VISCD_SCAN_PER_THREAD; ++i) {
    const uint idx = base + i;
    if (idx < u_n) out_data[idx] = run;
    run += v[i];
  }
  if (t == VISCD_WG_SIZE - 1u) blocks[gl_WorkGroupID.x] = s_sum[t];
}
