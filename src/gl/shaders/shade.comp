#version 450 core
// Stage 9, deferred shading from the G-buffer with the shared shading model (core/visibility.hpp
// ShadingModel, the cpu backend's too): ambient plus Lambert plus a view rim times the state
// colour; red colliding, blue free, yellow culled, grey static (ids above the moving objects':
// the static set is drawn after them), dark background. Output is packed RGBA8, rows top to
// bottom (the id texture is bottom-up, GL's convention).
#include "shared/layout.h"
layout(local_size_x = VISCD_TILE_SIDE, local_size_y = VISCD_TILE_SIDE) in;
layout(binding = VISCD_UNIT_IDS) uniform usampler2D u_ids;
layout(binding = VISCD_UNIT_NORMAL) uniform sampler2D u_normal;
layout(std430, binding = VISCD_BIND_STATE) readonly buffer State { uint state[]; };
layout(std430, binding = VISCD_BIND_IMAGE) writeonly buffer Image { uint image[]; };
uniform ivec2 u_map;
uniform vec3 u_light;
uniform vec3 u_terms;  // ambient, diffuse and rim weights
uniform vec3 u_view;
uniform vec3 u_colour[5];  // colliding, free, culled, background, static (0..255)
uniform uint u_moving;     // N: ids above it are static objects

void main() {
  const int x = int(gl_GlobalInvocationID.x), row = int(gl_GlobalInvocationID.y);  // 2D grid
  if (x >= u_map.x || row >= u_map.y) return;
  const uint k = uint(row) * uint(u_map.x) + uint(x);
  const ivec2 texel = ivec2(x, u_map.y - 1 - row);
  const uint id = texelFetch(u_ids, texel, 0).r;
  vec3 c;
  if (id == 0u) {
    c = u_colour[3];
  } else {
    vec3 base = u_colour[4];
    if (id <= u_moving) {
      const uint st = state[id - 1u];
      base = st == VISCD_STATE_COLLIDING ? u_colour[0] : st == VISCD_STATE_FREE ? u_colour[1] : u_colour[2];
    }
    const vec3 n = texelFetch(u_normal, texel, 0).xyz;
    const float diffuse = max(0.0, dot(n, u_light));
    const float facing = max(0.0, dot(n, u_view));
    const float kk = u_terms.x + u_terms.y * diffuse + u_terms.z * facing;
    c = min(vec3(255.0), base * kk + 0.5);
  }
  const uvec3 b = uvec3(c);
  image[k] = b.r | (b.g << 8u) | (b.b << 16u) | (255u << 24u);
}
