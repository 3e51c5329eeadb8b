#version 450 core
// Stage 3 with filters, after cull.comp: an active object goes into the tree only if its filter
// can accept some active object's: (mask & OR of the groups) != 0 and (group & OR of the masks)
// != 0 (core's split_by_filters rule, as the cpu backend). The others stay active (visible,
// free, seen by queries) but cost the broadphase nothing.
#include "shared/layout.h"
layout(local_size_x = VISCD_WG_SIZE) in;
layout(std430, binding = VISCD_BIND_FLAGS) buffer Flags { uint flags[]; };
layout(std430, binding = VISCD_BIND_FILTERS) readonly buffer Filters { uvec2 filters[]; };
layout(std430, binding = VISCD_BIND_INFO) readonly buffer Info { FrameInfo info; };
uniform uint u_n;

void main() {
  const uint k = gl_GlobalInvocationID.x;
  if (k >= u_n || flags[k] == 0u) return;
  const uvec2 f = filters[k];
  if ((f.y & info.filter_or.x) == 0u || (f.x & info.filter_or.y) == 0u) flags[k] = 0u;
}
