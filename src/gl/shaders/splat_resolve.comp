#version 450 core
// Stage 1, splat geometry, second half: one invocation per map pixel writes the G-buffer from
// splat.comp's nearest depth and id: the id, the view depth (the far plane on the background)
// and the unit normal at the hit, as gbuffer_impostor.frag writes them. Map rows count from the
// top (CameraRig); the textures' from the bottom.
#include "shared/layout.h"
layout(local_size_x = VISCD_TILE_SIDE, local_size_y = VISCD_TILE_SIDE) in;
layout(std430, binding = VISCD_BIND_SPHERES) readonly buffer Spheres { vec4 spheres[]; };
layout(std430, binding = VISCD_BIND_SPLAT_DEPTH) readonly buffer Depth { uint depth_bits[]; };
layout(std430, binding = VISCD_BIND_SPLAT_IDS) readonly buffer Ids { uint ids[]; };
layout(binding = 0, r32ui) uniform writeonly uimage2D u_id_image;
layout(binding = 1, r32f) uniform writeonly image2D u_depth_image;
layout(binding = 2, rgba32f) uniform writeonly image2D u_normal_image;
uniform vec3 u_eye;
uniform vec3 u_forward;
uniform vec3 u_right;
uniform vec3 u_up;
uniform vec2 u_tan_half;
uniform vec2 u_near_far;
uniform ivec2 u_map;

void main() {
  const int px = int(gl_GlobalInvocationID.x), py = int(gl_GlobalInvocationID.y);
  if (px >= u_map.x || py >= u_map.y) return;
  const ivec2 texel = ivec2(px, u_map.y - 1 - py);
  const uint p = uint(py) * uint(u_map.x) + uint(px);
  const uint bits = depth_bits[p];
  if (bits == 0xFFFFFFFFu) {
    imageStore(u_id_image, texel, uvec4(0u));
    imageStore(u_depth_image, texel, vec4(u_near_far.y, 0.0, 0.0, 0.0));
    imageStore(u_normal_image, texel, vec4(0.0));
    return;
  }
  const uint id = ids[p];
  const float t = uintBitsToFloat(bits);
  precise float nx = (2.0 * (float(px) + 0.5) / float(u_map.x) - 1.0) * u_tan_half.x;
  precise float ny = (1.0 - 2.0 * (float(py) + 0.5) / float(u_map.y)) * u_tan_half.y;
  precise vec3 d = u_forward + u_right * nx + u_up * ny;
  const vec4 s = spheres[id - 1u];
  precise vec3 h = vec3(u_eye.x + t * d.x - s.x, u_eye.y + t * d.y - s.y, u_eye.z + t * d.z - s.z);
  const float l = sqrt(dot(h, h));
  imageStore(u_id_image, texel, uvec4(id, 0u, 0u, 0u));
  imageStore(u_depth_image, texel, vec4(t, 0.0, 0.0, 0.0));
  imageStore(u_normal_image, texel, vec4(l > 0.0 ? h / l : -d, 0.0));
}
