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

// GPU drivers may flush subnormal floats to zero (NVIDIA's does; GLSL allows it), which changes
// the float test when an input is tiny. With every input 0 or at least 2^-39 in magnitude no
// intermediate of the test can be subnormal (differences are 0 or >= 2^-62, squares >= 2^-124,
// sums of non-negative normals stay normal), so the float test below is IEEE's. Otherwise the
// test runs in double, each float operation rounded to float with gradual underflow
// (round_float): sums and differences of floats are exact in double whenever a float rounding
// could tie, and products of floats always are, so the result is the IEEE float test's.
bool tiny(float v) {
  const uint m = floatBitsToUint(v) & 0x7FFFFFFFu;  // bits: a flushing compare would see 0
  return m != 0u && m < 0x2C000000u;                // 0 < |v| < 2^-39
}

double exact_value(float v) {  // the float's value, subnormals included, whatever the driver flushes
  const uint b = floatBitsToUint(v);
  const uint e = (b >> 23) & 0xFFu, m = b & 0x7FFFFFu;
  if (e == 0xFFu) return double(v);  // inf, NaN
  const double x = e == 0u ? ldexp(double(m), -149) : ldexp(double(m | 0x800000u), int(e) - 150);
  return (b >> 31) != 0u ? -x : x;
}

double round_float(double v) {  // to the nearest float, ties to even, subnormals as IEEE
  if (v == 0.0lf || isinf(v) || isnan(v)) return v;
  int e;
  frexp(v, e);  // |v| = f 2^e, f in [0.5, 1): a float's last bit weighs 2^(e - 24), at least 2^-149
  const int q = max(e - 24, -149);
  const double r = ldexp(roundEven(ldexp(v, -q)), q);
  if (abs(r) >= ldexp(1.0lf, 128)) return packDouble2x32(uvec2(0u, r > 0.0lf ? 0x7FF00000u : 0xFFF00000u));
  return r;
}

bool overlap_exact_ieee(vec4 a, vec4 b) {
  const double dx = round_float(exact_value(a.x) - exact_value(b.x));
  const double dy = round_float(exact_value(a.y) - exact_value(b.y));
  const double dz = round_float(exact_value(a.z) - exact_value(b.z));
  const double s = round_float(exact_value(a.w) + exact_value(b.w));
  const double d2 = round_float(round_float(round_float(dx * dx) + round_float(dy * dy)) + round_float(dz * dz));
  return d2 <= round_float(s * s);
}

bool overlap_exact(vec4 a, vec4 b) {
  if (tiny(a.x) || tiny(a.y) || tiny(a.z) || tiny(a.w) || tiny(b.x) || tiny(b.y) || tiny(b.z) || tiny(b.w))
    return overlap_exact_ieee(a, b);
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
