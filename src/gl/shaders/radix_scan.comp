#version 450 core
// Stage 6, radix sort pass, step 2 of 3, one work group (one dispatch, no inter-group
// communication): turns the tile-major digit counts into output offsets in place,
//   offset[tile][d] = (keys of digits < d) + (keys of digit d in tiles < tile),
// so that the scatter keeps tiles in order: the pass is stable. Invocation d walks its digit
// down the tiles (consecutive invocations read consecutive words), the group scans the 256
// digit totals, and invocation d adds its digit's base.
#include "shared/layout.h"
layout(local_size_x = 256) in;
layout(std430, binding = VISCD_BIND_SCAN_IN) buffer Hist { uint hist[]; };
layout(std430, binding = VISCD_BIND_INFO) readonly buffer Info { FrameInfo info; };
uniform uint u_n;
uniform uint u_n_from_info;  // as radix_hist.comp
shared uint s_sum[256];

void main() {
  const uint n = u_n_from_info != 0u ? info.active_count : u_n;
  if (n <= VISCD_LOCAL_SORT) return;  // sort_local.comp sorted them; no tile ran
  const uint tiles = (n + VISCD_SORT_TILE - 1u) / VISCD_SORT_TILE;
  const uint d = gl_LocalInvocationID.x;
  uint total = 0u;
  for (uint t = 0u; t < tiles; ++t) {
    const uint v = hist[t * 256u + d];
    hist[t * 256u + d] = total;
    total += v;
  }
  s_sum[d] = total;
  barrier();
  // Hillis-Steele inclusive scan of the digit totals.
  for (uint off = 1u; off < 256u; off <<= 1u) {
    const uint x = d >= off ? s_sum[d - off] : 0u;
    barrier();
    s_sum[d] += x;
    barrier();
  }
  const uint base = s_sum[d] - total;
  if (base == 0u) return;
  for (uint t = 0u; t < tiles; ++t) hist[t * 256u + d] += base;
}
