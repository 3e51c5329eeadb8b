#version 450 core
// Stage 6, radix sort pass, step 1: per-tile histograms of the 8-bit digit at u_shift, written
// digit-major (hist[digit * groups + group]) so that one exclusive scan of the whole array gives
// every (digit, tile) its output offset, tiles in order: the pass is stable.
#include "shared/layout.h"
layout(local_size_x = VISCD_SORT_TILE) in;
layout(std430, binding = VISCD_BIND_KEYS_IN) readonly buffer Keys { uvec2 keys[]; };
layout(std430, binding = VISCD_BIND_SCAN_IN) writeonly buffer Hist { uint hist[]; };
layout(std430, binding = VISCD_BIND_INFO) readonly buffer Info { FrameInfo info; };
uniform uint u_n;
// 1: the key count is FrameInfo.active_count (the Morton sort, dispatched over N tiles);
// 0: it is u_n (the pair sort, whose count the host has read back).
uniform uint u_n_from_info;
uniform uint u_shift;
shared uint s_count[256];

uint digit(uvec2 k) { return (u_shift < 32u ? k.x >> u_shift : k.y >> (u_shift - 32u)) & 0xFFu; }

void main() {
  const uint n = u_n_from_info != 0u ? info.active_count : u_n;
  const uint t = gl_LocalInvocationID.x;
  const uint idx = gl_WorkGroupID.x * VISCD_SORT_TILE + t;
  s_count[t] = 0u;
  barrier();
  if (idx < n) atomicAdd(s_count[digit(keys[idx])], 1u);
  barrier();
  hist[t * gl_NumWorkGroups.x + gl_WorkGroupID.x] = s_count[t];
}
