#version 450 core
// Stage 1, boxes: one cube per box (instance), 12 triangles from gl_VertexID, the box grown by a
// margin so that the rasterised cube covers every pixel whose centre ray hits the box; the
// fragment shader then ray-casts the box itself, so the margin decides only which pixels are
// tested, never which are drawn. The margin is two pixels' worth of view angle at the distance of
// the box's farthest corner (growing a box by e moves its silhouette out by at least e / distance
// in angle, and a pixel spans at most 2 tan_half / map side in the image plane), plus rounding
// room for coordinates far from the origin. Clip z is 0: the draw clamps depth (no near or far
// clipping) and the fragment writes its own depth.
#include "shared/layout.h"
layout(std430, binding = VISCD_BIND_BOXES) readonly buffer Boxes { LeafBox boxes[]; };
uniform vec3 u_eye;
uniform vec3 u_forward;
uniform vec3 u_right;
uniform vec3 u_up;
uniform vec2 u_tan_half;
uniform ivec2 u_map;
flat out uint v_index;

// The cube's 12 triangles as corner numbers: bit 0 picks max x, bit 1 max y, bit 2 max z.
const int kCorner[36] = int[](0, 2, 6, 0, 6, 4,   // -x
                              1, 5, 7, 1, 7, 3,   // +x
                              0, 4, 5, 0, 5, 1,   // -y
                              2, 3, 7, 2, 7, 6,   // +y
                              0, 1, 3, 0, 3, 2,   // -z
                              4, 6, 7, 4, 7, 5);  // +z

void main() {
  const uint k = uint(gl_InstanceID);
  const vec3 lo = vec3(boxes[k].v[0], boxes[k].v[1], boxes[k].v[2]);
  const vec3 hi = vec3(boxes[k].v[3], boxes[k].v[4], boxes[k].v[5]);
  const float dist = length(max(abs(lo - u_eye), abs(hi - u_eye)));
  const float pixel = 2.0 * max(u_tan_half.x / float(u_map.x), u_tan_half.y / float(u_map.y));
  const vec3 mag = max(max(abs(lo), abs(hi)), abs(u_eye));
  const float margin = 2.0 * pixel * dist + 1e-5 * max(max(mag.x, mag.y), mag.z) + 1e-30;
  const int c = kCorner[gl_VertexID];
  const vec3 corner = vec3((c & 1) != 0 ? hi.x + margin : lo.x - margin, (c & 2) != 0 ? hi.y + margin : lo.y - margin,
                           (c & 4) != 0 ? hi.z + margin : lo.z - margin);
  const vec3 rel = corner - u_eye;
  gl_Position = vec4(dot(rel, u_right) / u_tan_half.x, dot(rel, u_up) / u_tan_half.y, 0.0, dot(rel, u_forward));
  v_index = k;
}
