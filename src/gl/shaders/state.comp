#version 450 core
// Object states: phase 0 all culled, phase 1 active ones free, phase 2 both objects of every
// pair colliding (equal values written concurrently: no race on the result).
#include "shared/layout.h"
layout(local_size_x = VISCD_WG_SIZE) in;
layout(std430, binding = VISCD_BIND_ACTIVE) readonly buffer Active { uint active_ids[]; };
layout(std430, binding = VISCD_BIND_PAIRS) readonly buffer Pairs { uvec2 pairs[]; };
layout(std430, binding = VISCD_BIND_STATE) writeonly buffer State { uint state[]; };
layout(std430, binding = VISCD_BIND_INFO) readonly buffer Info { FrameInfo info; };
uniform uint u_n;  // phase 0: N, phase 2: the pair count; phase 1 reads n from FrameInfo
uniform uint u_phase;

void main() {
  const uint k = gl_GlobalInvocationID.x;
  if (k >= (u_phase == 1u ? info.active_count : u_n)) return;
  if (u_phase == 0u) {
    state[k] = VISCD_STATE_CULLED;
  } else if (u_phase == 1u) {
    state[active_ids[k]] = VISCD_STATE_FREE;
  } else {
    state[pairs[k].x] = VISCD_STATE_COLLIDING;
    state[pairs[k].y] = VISCD_STATE_COLLIDING;
  }
}
