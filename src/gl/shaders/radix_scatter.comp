#version 450 core
// Stage 6, radix sort pass, step 3 (after the scan of the histograms): scatters each key (and
// value) to offset[digit, tile] + its rank among the tile's keys of the same digit. Invocation d
// ranks the keys of digit d in tile order, which keeps the pass stable.
#include "shared/layout.h"
layout(local_size_x = VISCD_SORT_TILE) in;
layout(std430, binding = VISCD_BIND_KEYS_IN) readonly buffer KeysIn { uvec2 keys_in[]; };
layout(std430, binding = VISCD_BIND_KEYS_OUT) writeonly buffer KeysOut { uvec2 keys_out[]; };
layout(std430, binding = VISCD_BIND_VALUES_IN) readonly buffer ValuesIn { uint values_in[]; };
layout(std430, binding = VISCD_BIND_VALUES_OUT) writeonly buffer ValuesOut { uint values_out[]; };
layout(std430, binding = VISCD_BIND_SCAN_OUT) readonly buffer Offsets { uint offsets[]; };
layout(std430, binding = VISCD_BIND_INFO) readonly buffer Info { FrameInfo info; };
uniform uint u_n;
// 1: the key count is FrameInfo.active_count (the Morton sort, dispatched over N tiles);
// 0: it is u_n (the pair sort, whose count the host has read back).
uniform uint u_n_from_info;
uniform uint u_shift;
uniform uint u_has_values;
shared uint s_digit[VISCD_SORT_TILE];
shared uint s_rank[VISCD_SORT_TILE];

uint digit(uvec2 k) { return (u_shift < 32u ? k.x >> u_shift : k.y >> (u_shift - 32u)) & 0xFFu; }

void main() {
  const uint n = u_n_from_info != 0u ? info.active_count : u_n;
  const uint t = gl_LocalInvocationID.x;
  const uint idx = gl_WorkGroupID.x * VISCD_SORT_TILE + t;
  const uvec2 key = idx < n ? keys_in[idx] : uvec2(0u);
  const uint d = idx < n ? digit(key) : 256u;  // 256: no key (matches no invocation)
  s_digit[t] = d;
  barrier();
  uint r = 0u;
  for (uint e = 0u; e < VISCD_SORT_TILE; ++e) {
    if (s_digit[e] == t) {
      s_rank[e] = r;
      ++r;
    }
  }
  barrier();
  if (idx >= n) return;
  const uint dst = offsets[d * gl_NumWorkGroups.x + gl_WorkGroupID.x] + s_rank[t];
  keys_out[dst] = key;
  if (u_has_values != 0u) values_out[dst] = values_in[idx];
}
