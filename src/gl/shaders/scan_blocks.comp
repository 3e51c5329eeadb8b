#version 450 core
// Scan, step 2 of 3: one group scans the block totals (exclusive, in place), any count, in
// chunks with a running carry; the grand total goes to blocks[u_count].
#include "shared/layout.h"
layout(local_size_x = VISCD_WG_SIZE) in;
layout(std430, binding = VISCD_BIND_SCAN_BLOCKS) buffer Blocks { uint blocks[]; };
uniform uint u_count;
shared uint s_sum[VISCD_WG_SIZE];

void main() {
  const uint t = gl_LocalInvocationID.x;
  uint carry = 0u;
  for (uint start = 0u; start < u_count; start += VISCD_WG_SIZE) {
    const uint idx = start + t;
    const uint v = idx < u_count ? blocks[idx] : 0u;
    s_sum[t] = v;
    barrier();
    for (uint off = 1u; off < VISCD_WG_SIZE; off <<= 1u) {
      const uint x = t >= off ? s_sum[t - off] : 0u;
      barrier();
      s_sum[t] += x;
      barrier();
    }
    if (idx < u_count) blocks[idx] = carry + s_sum[t] - v;
    carry += s_sum[VISCD_WG_SIZE - 1u];
    barrier();
  }
  if (t == 0u) blocks[u_count] = carry;
}
