#version 450 core
// Stage 3, step 1 (paper Fig. 3): screen-scaled pixels (a double product rounded to float, as
// core/visibility.hpp does), the active flag (pixels >= lambda or a non-zero always_active byte,
// or every object without culling or camera), the object's first
// state (free when active, culled otherwise; the pair pass later marks colliding ones), the
// integer pixel total, the count of active objects and, with filters, the OR of their groups and
// of their masks (pairable.comp's inputs). Objects from u_moving on are the static set's: always
// active, not counted (no pixels, not in the pixel total nor in visible_count), but their filters
// enter the OR, as the cpu backend's split_by_filters sees them.
#include "shared/layout.h"
layout(local_size_x = VISCD_WG_SIZE) in;
layout(std430, binding = VISCD_BIND_COUNTS) readonly buffer Counts { uint counts[]; };
layout(std430, binding = VISCD_BIND_PIXELS) writeonly buffer Pixels { float pixels[]; };
layout(std430, binding = VISCD_BIND_FLAGS) writeonly buffer Flags { uint flags[]; };
layout(std430, binding = VISCD_BIND_STATE) writeonly buffer State { uint state[]; };
layout(std430, binding = VISCD_BIND_INFO) buffer Info { FrameInfo info; };
layout(std430, binding = VISCD_BIND_FILTERS) readonly buffer Filters { uvec2 filters[]; };
// FrameInput::always_active as uploaded: byte k of the array is byte k % 4 of word k / 4.
layout(std430, binding = VISCD_BIND_ALWAYS) readonly buffer Always { uint always[]; };
uniform uint u_n;
uniform uint u_moving;  // N: the frame's moving objects, the rest of u_n are static
uniform uint u_has_filters;
uniform uint u_has_always;  // FrameInput::always_active was given
uniform uint u_has_counts;  // 0: no camera, every object active
uniform uint u_culling;
uniform double u_scale;  // screen pixels per map pixel
uniform double u_lambda;
shared uint s_total, s_active, s_group, s_mask;

void main() {
  const uint k = gl_GlobalInvocationID.x;
  if (gl_LocalInvocationID.x == 0u) {
    s_total = 0u;
    s_active = 0u;
    s_group = 0u;
    s_mask = 0u;
  }
  barrier();
  if (k < u_n) {
    const bool moving = k < u_moving;
    uint flag = 1u;
    if (moving && u_has_counts != 0u) {
      const uint c = counts[k];
      // Rounded to float before the test, as the cpu backend does: the rule reads the count
      // as FrameResult::pixels reports it.
      const float px = float(double(c) * u_scale);
      pixels[k] = px;
      const bool kept = u_has_always != 0u && ((always[k >> 2u] >> (8u * (k & 3u))) & 0xFFu) != 0u;
      if (u_culling != 0u && !(double(px) >= u_lambda) && !kept) flag = 0u;
      atomicAdd(s_total, c);
    }
    flags[k] = flag;
    state[k] = flag != 0u ? VISCD_STATE_FREE : VISCD_STATE_CULLED;
    if (flag != 0u) {
      if (moving) atomicAdd(s_active, 1u);
      if (u_has_filters != 0u) {
        atomicOr(s_group, filters[k].x);
        atomicOr(s_mask, filters[k].y);
      }
    }
  }
  barrier();
  if (gl_LocalInvocationID.x != 0u) return;
  if (s_total != 0u) atomicAdd(info.total_pixels, s_total);
  if (s_active != 0u) atomicAdd(info.visible_count, s_active);
  if (s_group != 0u) atomicOr(info.filter_or.x, s_group);
  if (s_mask != 0u) atomicOr(info.filter_or.y, s_mask);
}
