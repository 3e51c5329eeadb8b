#version 450 core
// After culling, one invocation turns FrameInfo.active_count into the work-group counts of the
// passes that follow (DispatchArgs), so that they are sized by the active objects without the
// host waiting for their number.
#include "shared/layout.h"
layout(local_size_x = 1) in;
layout(std430, binding = VISCD_BIND_INFO) readonly buffer Info { FrameInfo info; };
layout(std430, binding = VISCD_BIND_DISPATCH) writeonly buffer Args { DispatchArgs args; };

uint groups(uint items, uint size) { return items / size + (items % size != 0u ? 1u : 0u); }

void main() {
  const uint n = info.active_count;
  args.per_object = uvec4(groups(n, VISCD_WG_SIZE), 1u, 1u, 0u);
  args.per_node = uvec4(groups(n > 0u ? n - 1u : 0u, VISCD_WG_SIZE), 1u, 1u, 0u);
  // A count sort_local.comp takes needs no radix pass.
  args.sort_tiles = uvec4(n > VISCD_LOCAL_SORT ? groups(n, VISCD_SORT_TILE) : 0u, 1u, 1u, 0u);
}
