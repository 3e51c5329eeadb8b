#version 450 core
// Stage 6 for a few keys: when the count is at most VISCD_LOCAL_SORT, one work group sorts all of
// them in shared memory (a bitonic network over (key, value), the value breaking ties, so the
// result equals the stable radix sort's: values start ascending) and writes them where the radix
// passes would have left them. Used by the Morton sort of a frame with few active objects and
// by the pair sort of a frame with few pairs: one dispatch instead of three per radix pass.
// With a larger count it does nothing (the radix passes run instead).
#include "shared/layout.h"
layout(local_size_x = VISCD_LOCAL_SORT / 2) in;
layout(std430, binding = VISCD_BIND_KEYS_IN) readonly buffer KeysIn { uvec2 keys_in[]; };
layout(std430, binding = VISCD_BIND_KEYS_OUT) writeonly buffer KeysOut { uvec2 keys_out[]; };
layout(std430, binding = VISCD_BIND_VALUES_IN) readonly buffer ValuesIn { uint values_in[]; };
layout(std430, binding = VISCD_BIND_VALUES_OUT) writeonly buffer ValuesOut { uint values_out[]; };
layout(std430, binding = VISCD_BIND_INFO) readonly buffer Info { FrameInfo info; };
uniform uint u_n;
uniform uint u_n_from_info;  // as radix_hist.comp
uniform uint u_has_values;
shared uvec2 s_key[VISCD_LOCAL_SORT];
shared uint s_value[VISCD_LOCAL_SORT];

// (key, value) of a before (key, value) of b; keys compare as 64-bit numbers (y high).
bool before(uint a, uint b) {
  const uvec2 ka = s_key[a], kb = s_key[b];
  if (ka.y != kb.y) return ka.y < kb.y;
  if (ka.x != kb.x) return ka.x < kb.x;
  return s_value[a] < s_value[b];
}

void main() {
  const uint n = u_n_from_info != 0u ? info.active_count : u_n;
  if (n > VISCD_LOCAL_SORT) return;
  const uint t = gl_LocalInvocationID.x;
  for (uint h = 0u; h < 2u; ++h) {
    const uint i = t + h * (VISCD_LOCAL_SORT / 2);
    // Padding sorts last: the largest key and value.
    s_key[i] = i < n ? keys_in[i] : uvec2(0xFFFFFFFFu);
    s_value[i] = i < n && u_has_values != 0u ? values_in[i] : (i < n ? i : 0xFFFFFFFFu);
  }
  barrier();
  for (uint size = 2u; size <= VISCD_LOCAL_SORT; size <<= 1u) {
    for (uint stride = size >> 1u; stride > 0u; stride >>= 1u) {
      // Invocation t compares element a (bit `stride` clear) with a + stride.
      const uint a = 2u * t - (t & (stride - 1u));
      const uint b = a + stride;
      const bool ascending = (a & size) == 0u;
      if (before(b, a) == ascending) {
        const uvec2 k = s_key[a];
        s_key[a] = s_key[b];
        s_key[b] = k;
        const uint v = s_value[a];
        s_value[a] = s_value[b];
        s_value[b] = v;
      }
      barrier();
    }
  }
  for (uint h = 0u; h < 2u; ++h) {
    const uint i = t + h * (VISCD_LOCAL_SORT / 2);
    if (i < n) {
      keys_out[i] = s_key[i];
      if (u_has_values != 0u) values_out[i] = s_value[i];
    }
  }
}
