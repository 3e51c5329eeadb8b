#version 450 core
// Object states, after the pairs are sorted: both objects of every pair become colliding (equal
// values written concurrently: no race on the result). The cull pass wrote free / culled.
#include "shared/layout.h"
layout(local_size_x = VISCD_WG_SIZE) in;
layout(std430, binding = VISCD_BIND_PAIRS) readonly buffer Pairs { uvec2 pairs[]; };
layout(std430, binding = VISCD_BIND_STATE) writeonly buffer State { uint state[]; };
uniform uint u_pairs;

void main() {
  const uint k = gl_GlobalInvocationID.x;
  if (k >= u_pairs) return;
  state[pairs[k].x] = VISCD_STATE_COLLIDING;
  state[pairs[k].y] = VISCD_STATE_COLLIDING;
}
