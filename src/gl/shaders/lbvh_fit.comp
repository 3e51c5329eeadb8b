#version 450 core
// Stage 7b: leaf boxes (a sphere's core/geometry.hpp conservative_box, bit for bit with
// `precise`; a box itself, core's box_aabb: the box test is the node test's comparisons, so no
// margin is needed) and the bottom-up fit, one invocation per leaf. At each internal node the first invocation to arrive
// stops and the second merges both child boxes and climbs. The node buffer is `coherent` and the
// box write is made visible (memoryBarrierBuffer) before the arrival atomicAdd, so the second
// arrival reads the first one's box. No invocation waits for another: no forward-progress
// assumption.
#include "shared/layout.h"
layout(local_size_x = VISCD_WG_SIZE) in;
layout(std430, binding = VISCD_BIND_SPHERES) readonly buffer Spheres { vec4 spheres[]; };
layout(std430, binding = VISCD_BIND_VALUES_IN) readonly buffer Values { uint sorted_ids[]; };
layout(std430, binding = VISCD_BIND_SORTED) writeonly buffer Sorted { vec4 sorted_spheres[]; };
layout(std430, binding = VISCD_BIND_LEAF_BOXES) writeonly buffer LeafBoxes { LeafBox leaf_boxes[]; };
layout(std430, binding = VISCD_BIND_NODES) coherent buffer Nodes { LbvhNode nodes[]; };
layout(std430, binding = VISCD_BIND_PARENT) readonly buffer Parent { uint parent[]; };
layout(std430, binding = VISCD_BIND_ARRIVALS) coherent buffer Arrivals { uint arrivals[]; };
layout(std430, binding = VISCD_BIND_INFO) buffer Info { FrameInfo info; };
layout(std430, binding = VISCD_BIND_BOXES) readonly buffer Boxes { LeafBox boxes[]; };
uniform uint u_boxes;  // the objects are boxes (`spheres` holds their proxies)

void main() {
  const uint n = info.active_count;  // from the GPU: the dispatch is sized from it (indirect)
  const uint p = gl_GlobalInvocationID.x;
  if (p >= n) return;
  const uint id = sorted_ids[p];
  const vec4 s = spheres[id];
  sorted_spheres[p] = s;
  precise vec3 lo, hi;
  if (u_boxes != 0u) {
    lo = vec3(boxes[id].v[0], boxes[id].v[1], boxes[id].v[2]);
    hi = vec3(boxes[id].v[3], boxes[id].v[4], boxes[id].v[5]);
  } else {
    // conservative_box: r + (max|c| + r) * 2^-19 + 1e-21, evaluated in the same order.
    precise float m = max(max(abs(s.x), abs(s.y)), abs(s.z));
    precise float r = s.w + (m + s.w) * 1.9073486328125e-06 + 1e-21;
    lo = vec3(s.x - r, s.y - r, s.z - r);
    hi = vec3(s.x + r, s.y + r, s.z + r);
  }
  leaf_boxes[p].v[0] = lo.x; leaf_boxes[p].v[1] = lo.y; leaf_boxes[p].v[2] = lo.z;
  leaf_boxes[p].v[3] = hi.x; leaf_boxes[p].v[4] = hi.y; leaf_boxes[p].v[5] = hi.z;
  if (n == 1u) {
    info.root_lo = vec4(lo, 0.0);
    info.root_hi = vec4(hi, 0.0);
    return;
  }
  uint child = p | VISCD_LEAF_BIT;
  uint node = parent[n - 1u + p];
  for (;;) {
    const uint side = nodes[node].child[0] == child ? 0u : 6u;
    nodes[node].box[side + 0u] = lo.x; nodes[node].box[side + 1u] = lo.y; nodes[node].box[side + 2u] = lo.z;
    nodes[node].box[side + 3u] = hi.x; nodes[node].box[side + 4u] = hi.y; nodes[node].box[side + 5u] = hi.z;
    memoryBarrierBuffer();
    if (atomicAdd(arrivals[node], 1u) == 0u) return;  // first arrival: the sibling's invocation merges
    memoryBarrierBuffer();
    const uint other = 6u - side;
    lo = min(lo, vec3(nodes[node].box[other + 0u], nodes[node].box[other + 1u], nodes[node].box[other + 2u]));
    hi = max(hi, vec3(nodes[node].box[other + 3u], nodes[node].box[other + 4u], nodes[node].box[other + 5u]));
    if (node == 0u) {
      info.root_lo = vec4(lo, 0.0);
      info.root_hi = vec4(hi, 0.0);
      return;
    }
    child = node;
    node = parent[node];
  }
}
