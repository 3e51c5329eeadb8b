#version 450 core
// Stage 6, radix sort pass, step 1 of 3: each work group counts the 8-bit digit at u_shift over
// its tile of VISCD_SORT_TILE keys and writes the counts tile-major (hist[tile * 256 + digit]).
#include "shared/layout.h"
layout(local_size_x = VISCD_SORT_GROUP) in;
layout(std430, binding = VISCD_BIND_KEYS_IN) readonly buffer Keys { uvec2 keys[]; };
layout(std430, binding = VISCD_BIND_SCAN_IN) writeonly buffer Hist { uint hist[]; };
layout(std430, binding = VISCD_BIND_INFO) readonly buffer Info { FrameInfo info; };
uniform uint u_n;
// 1: the key count is FrameInfo.active_count (the Morton sort, dispatched indirectly from it);
// 0: it is u_n (the pair sort, whose count the host has read back).
uniform uint u_n_from_info;
uniform uint u_shift;
shared uint s_count[256];

uint digit(uvec2 k) { return (u_shift < 32u ? k.x >> u_shift : k.y >> (u_shift - 32u)) & 0xFFu; }

void main() {
  const uint n = u_n_from_info != 0u ? info.active_count : u_n;
  const uint t = gl_LocalInvocationID.x;
  s_count[t] = 0u;
  barrier();
  const uint base = gl_WorkGroupID.x * VISCD_SORT_TILE + t;
  for (uint r = 0u; r < VISCD_SORT_ROUNDS; ++r) {
    const uint idx = base + r * VISCD_SORT_GROUP;
    if (idx < n) atomicAdd(s_count[digit(keys[idx])], 1u);
  }
  barrier();
  hist[gl_WorkGroupID.x * 256u + t] = s_count[t];
}
