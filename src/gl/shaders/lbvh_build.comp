#version 450 core
// Stage 7a: Karras 2012 ("Maximizing Parallelism in the Construction of BVHs, Octrees, and k-d
// Trees"), one invocation per internal node, as core/lbvh.cpp: equal keys are split by
// position, delta = m + clz32(i ^ j), with clz over the key width m (u_bits).
// parent[] holds the internal nodes' parents at [0, n-1) and the leaves' at [n-1, 2n-1).
// Positions are int: n < 2^29 keeps i + 2n in range. Each node's fit arrival counter is zeroed
// here (the fit runs after a barrier), so no clear sized by anything but n is needed.
#include "shared/layout.h"
layout(local_size_x = VISCD_WG_SIZE) in;
layout(std430, binding = VISCD_BIND_KEYS_IN) readonly buffer Keys { uvec2 keys[]; };
layout(std430, binding = VISCD_BIND_NODES) writeonly buffer Nodes { LbvhNode nodes[]; };
layout(std430, binding = VISCD_BIND_PARENT) writeonly buffer Parent { uint parent[]; };
layout(std430, binding = VISCD_BIND_ARRIVALS) writeonly buffer Arrivals { uint arrivals[]; };
layout(std430, binding = VISCD_BIND_INFO) readonly buffer Info { FrameInfo info; };
int g_n;  // n = FrameInfo.active_count (the dispatch is sized from it on the GPU, or by the host's bound)
uniform int u_bits;

int delta(int i, int j) {
  if (j < 0 || j >= g_n) return -1;
  const uvec2 a = keys[i], b = keys[j];
  if (a != b) {
    const uvec2 x = a ^ b;
    const int clz64 = x.y != 0u ? 31 - findMSB(x.y) : 63 - findMSB(x.x);
    return clz64 - (64 - u_bits);
  }
  return u_bits + 31 - findMSB(uint(i ^ j));
}

void main() {
  g_n = int(info.active_count);
  const int i = int(gl_GlobalInvocationID.x);
  if (i >= g_n - 1) return;
  arrivals[i] = 0u;
  const int d = delta(i, i + 1) - delta(i, i - 1) > 0 ? 1 : -1;
  const int delta_min = delta(i, i - d);
  int lmax = 2;
  while (delta(i, i + lmax * d) > delta_min) lmax *= 2;
  int l = 0;
  for (int t = lmax / 2; t >= 1; t /= 2)
    if (delta(i, i + (l + t) * d) > delta_min) l += t;
  const int j = i + l * d;
  const int delta_node = delta(i, j);
  int s = 0;
  int t = l;
  do {
    t = (t + 1) / 2;
    if (delta(i, i + (s + t) * d) > delta_node) s += t;
  } while (t > 1);
  const int gamma = i + s * d + min(d, 0);
  const int first = min(i, j), last = max(i, j);
  const uint leaf_base = uint(g_n - 1);
  if (first == gamma) {
    nodes[i].child[0] = uint(gamma) | VISCD_LEAF_BIT;
    parent[leaf_base + uint(gamma)] = uint(i);
  } else {
    nodes[i].child[0] = uint(gamma);
    parent[gamma] = uint(i);
  }
  if (last == gamma + 1) {
    nodes[i].child[1] = uint(gamma + 1) | VISCD_LEAF_BIT;
    parent[leaf_base + uint(gamma + 1)] = uint(i);
  } else {
    nodes[i].child[1] = uint(gamma + 1);
    parent[gamma + 1] = uint(i);
  }
  nodes[i].last[0] = uint(gamma);
  nodes[i].last[1] = uint(last);
  if (i == 0) parent[0] = 0xFFFFFFFFu;
}
