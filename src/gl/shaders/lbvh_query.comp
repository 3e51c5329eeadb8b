#version 450 core
// Stage 8: one invocation per leaf p (sorted position) walks the tree for leaves q > p whose box
// overlaps its own (core/lbvh.hpp for_each_overlap_after), then applies the exact test
// (docs/architecture.md, "Contracts"): spheres' with `precise` (no FMA), boxes' on the leaf boxes
// (which are the boxes). A pair of two static objects (ids from u_static_from on) is skipped. Every pair is counted in info.pair_count; pairs are stored only
// while the count is below u_capacity, and the host grows the buffer and re-runs on overflow:
// no pair is ever dropped. The stack holds VISCD_STACK_DEPTH >= 64 + 32 entries, the deepest
// possible tree (core/lbvh.hpp), so it cannot overflow.
#include "shared/layout.h"
layout(local_size_x = VISCD_WG_SIZE) in;
layout(std430, binding = VISCD_BIND_VALUES_IN) readonly buffer Values { uint sorted_ids[]; };
layout(std430, binding = VISCD_BIND_SORTED) readonly buffer Sorted { vec4 sorted_spheres[]; };
layout(std430, binding = VISCD_BIND_LEAF_BOXES) readonly buffer LeafBoxes { LeafBox leaf_boxes[]; };
layout(std430, binding = VISCD_BIND_NODES) readonly buffer Nodes { LbvhNode nodes[]; };
layout(std430, binding = VISCD_BIND_PAIRS) writeonly buffer Pairs { uvec2 pairs[]; };
layout(std430, binding = VISCD_BIND_INFO) buffer Info { FrameInfo info; };
layout(std430, binding = VISCD_BIND_FILTERS) readonly buffer Filters { uvec2 filters[]; };
uniform uint u_capacity;
uniform uint u_has_filters;  // pairs also need (group_i & mask_j) != 0 && (group_j & mask_i) != 0
uniform uint u_boxes;        // the objects are boxes
uniform uint u_static_from;  // objects from here on are static: never paired with each other

bool overlap_exact(vec4 a, vec4 b) {
  precise float dx = a.x - b.x, dy = a.y - b.y, dz = a.z - b.z;
  precise float s = a.w + b.w;
  precise float d2 = dx * dx + dy * dy + dz * dz;
  precise float s2 = s * s;
  return d2 <= s2;
}

// core/geometry.hpp box_overlap_exact of two leaves' boxes (closed: touching counts).
bool leaf_boxes_overlap(uint p, uint q) {
  for (uint a = 0u; a < 3u; ++a)
    if (!(leaf_boxes[p].v[a] <= leaf_boxes[q].v[a + 3u] && leaf_boxes[q].v[a] <= leaf_boxes[p].v[a + 3u])) return false;
  return true;
}

bool box_overlap(uint node, uint side, vec3 lo, vec3 hi) {
  const uint o = side * 6u;
  return nodes[node].box[o + 0u] <= hi.x && lo.x <= nodes[node].box[o + 3u] &&
         nodes[node].box[o + 1u] <= hi.y && lo.y <= nodes[node].box[o + 4u] &&
         nodes[node].box[o + 2u] <= hi.z && lo.z <= nodes[node].box[o + 5u];
}

void main() {
  const uint n = info.active_count;  // from the GPU: the dispatch is sized from it (indirect)
  const uint p = gl_GlobalInvocationID.x;
  if (p >= n || n < 2u) return;
  const vec4 a = sorted_spheres[p];
  const uint ia = sorted_ids[p];
  const vec3 lo = vec3(leaf_boxes[p].v[0], leaf_boxes[p].v[1], leaf_boxes[p].v[2]);
  const vec3 hi = vec3(leaf_boxes[p].v[3], leaf_boxes[p].v[4], leaf_boxes[p].v[5]);
  uint stack[VISCD_STACK_DEPTH];
  int sp = 0;
  uint node = 0u;
  for (;;) {
    uint next = 0xFFFFFFFFu;
    for (uint c = 0u; c < 2u; ++c) {
      if (!(nodes[node].last[c] > p && box_overlap(node, c, lo, hi))) continue;
      const uint ch = nodes[node].child[c];
      if ((ch & VISCD_LEAF_BIT) != 0u) {
        const uint q = ch & ~VISCD_LEAF_BIT;
        if (u_boxes != 0u ? leaf_boxes_overlap(p, q) : overlap_exact(a, sorted_spheres[q])) {
          const uint ib = sorted_ids[q];
          if (ia >= u_static_from && ib >= u_static_from) continue;
          if (u_has_filters != 0u) {
            const uvec2 fa = filters[ia], fb = filters[ib];
            if ((fa.x & fb.y) == 0u || (fb.x & fa.y) == 0u) continue;
          }
          const uint slot = atomicAdd(info.pair_count, 1u);
          if (slot < u_capacity) pairs[slot] = uvec2(max(ia, ib), min(ia, ib));  // x = j, y = i
        }
      } else if (next == 0xFFFFFFFFu) {
        next = ch;
      } else {
        stack[sp++] = ch;
      }
    }
    if (next != 0xFFFFFFFFu) node = next;
    else if (sp > 0) node = stack[--sp];
    else return;
  }
}
