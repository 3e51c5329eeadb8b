#version 450 core
// Stage 6, radix sort pass, step 3 of 3: scatters each key (and value) of the tile to its
// digit's offset (radix_scan.comp) plus its rank among the tile's earlier keys of that digit.
// The tile is ranked VISCD_SORT_GROUP keys at a time: invocation d ranks the round's keys of
// digit d in index order and carries the count into the next round, which keeps the pass stable.
#include "shared/layout.h"
layout(local_size_x = VISCD_SORT_GROUP) in;
layout(std430, binding = VISCD_BIND_KEYS_IN) readonly buffer KeysIn { uvec2 keys_in[]; };
layout(std430, binding = VISCD_BIND_KEYS_OUT) writeonly buffer KeysOut { uvec2 keys_out[]; };
layout(std430, binding = VISCD_BIND_VALUES_IN) readonly buffer ValuesIn { uint values_in[]; };
layout(std430, binding = VISCD_BIND_VALUES_OUT) writeonly buffer ValuesOut { uint values_out[]; };
layout(std430, binding = VISCD_BIND_SCAN_IN) readonly buffer Offsets { uint offsets[]; };
layout(std430, binding = VISCD_BIND_INFO) readonly buffer Info { FrameInfo info; };
uniform uint u_n;
uniform uint u_n_from_info;  // as radix_hist.comp
uniform uint u_shift;
uniform uint u_has_values;
shared uint s_digit[VISCD_SORT_GROUP];
shared uint s_rank[VISCD_SORT_GROUP];
shared uint s_next[256];  // per digit: the tile's output position of its next key

uint digit(uvec2 k) { return (u_shift < 32u ? k.x >> u_shift : k.y >> (u_shift - 32u)) & 0xFFu; }

void main() {
  const uint n = u_n_from_info != 0u ? info.active_count : u_n;
  const uint t = gl_LocalInvocationID.x;
  const uint tile = gl_WorkGroupID.x;
  s_next[t] = offsets[tile * 256u + t];
  for (uint r = 0u; r < VISCD_SORT_ROUNDS; ++r) {
    const uint idx = tile * VISCD_SORT_TILE + r * VISCD_SORT_GROUP + t;
    if (tile * VISCD_SORT_TILE + r * VISCD_SORT_GROUP >= n) break;  // uniform across the group
    const uvec2 key = idx < n ? keys_in[idx] : uvec2(0u);
    const uint d = idx < n ? digit(key) : 256u;  // 256: no key (matches no invocation)
    s_digit[t] = d;
    barrier();
    uint rank = 0u;
    for (uint e = 0u; e < VISCD_SORT_GROUP; ++e) {
      if (s_digit[e] == t) {
        s_rank[e] = rank;
        ++rank;
      }
    }
    barrier();
    if (idx < n) {
      const uint dst = s_next[d] + s_rank[t];
      keys_out[dst] = key;
      if (u_has_values != 0u) values_out[dst] = values_in[idx];
    }
    barrier();
    s_next[t] += rank;
    barrier();
  }
}
