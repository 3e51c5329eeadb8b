#version 450 core
// Stage 1, mesh geometry: id (Listing 1, line 40), view depth and normal.
#include "shared/layout.h"
flat in uint v_index;
in vec3 v_normal;
in float v_depth;
layout(location = 0) out uint o_id;
layout(location = 1) out float o_depth;
layout(location = 2) out vec4 o_normal;

void main() {
  o_id = v_index + 1u;
  o_depth = v_depth;
  o_normal = vec4(normalize(v_normal), 0.0);
}
