#version 450 core
// Stage 2, the paper's mode (Listing 2): one atomic_uint per object, incremented by a
// full-screen fragment pass over the id map. The array size is fixed at compile time, so the
// program is built for the frame's N (VISCD_AC_COUNT, inserted by the host), and N is limited by
// GL_MAX_FRAGMENT_ATOMIC_COUNTERS. As in the paper, the counter index is not dynamically
// uniform, which GLSL leaves undefined for opaque arrays; Mesa handles it (tests check it).
#include "shared/layout.h"
#ifndef VISCD_AC_COUNT
#define VISCD_AC_COUNT 1
#endif
layout(binding = VISCD_BIND_ATOMIC_COUNTERS, offset = 0) uniform atomic_uint u_counters[VISCD_AC_COUNT];
layout(binding = VISCD_UNIT_IDS) uniform usampler2D u_ids;

void main() {
  const uint id = texelFetch(u_ids, ivec2(gl_FragCoord.xy), 0).r;
  if (id > 0u) atomicCounterIncrement(u_counters[id - 1u]);
}
