#version 450 core
// Stage 1, mesh geometry (the paper's GPU instancing, Listing 1): a tessellated unit sphere
// scaled and moved per instance, projected with the camera's OpenGL clip space.
#include "shared/layout.h"
layout(std430, binding = VISCD_BIND_SPHERES) readonly buffer Spheres { vec4 spheres[]; };
layout(location = 0) in vec3 a_position;  // on the unit sphere
uniform vec3 u_eye;
uniform vec3 u_forward;
uniform vec3 u_right;
uniform vec3 u_up;
uniform vec2 u_tan_half;
uniform vec2 u_near_far;
flat out uint v_index;
out vec3 v_normal;
out float v_depth;

void main() {
  const vec4 s = spheres[gl_InstanceID];
  const vec3 rel = s.xyz + s.w * a_position - u_eye;
  const float w = dot(rel, u_forward);
  const float n = u_near_far.x, f = u_near_far.y;
  gl_Position = vec4(dot(rel, u_right) / u_tan_half.x, dot(rel, u_up) / u_tan_half.y,
                     (f + n) / (f - n) * w - 2.0 * f * n / (f - n), w);
  v_index = uint(gl_InstanceID);
  v_normal = a_position;
  v_depth = w;
}
