// viscd gl backend: the one header shared by C++ and GLSL.
//
// Holds the binding indices, the work-group sizes and the std430 structs that both sides read.
// GLSL sees it textually inlined after `#version` (the build inlines it, see src/gl/CMakeLists.txt);
// C++ includes it normally and pins every struct's size and offsets with static_assert (below);
// src/gl/layout_checks.cpp ties the constants and structs to their C++ twins (ObjectState,
// core/lbvh.hpp, Sphere, Pair). Structs use vec4/uvec4 or explicit padding, never a bare vec3
// (std430 would pad it differently).
#ifndef VISCD_GL_LAYOUT_H
#define VISCD_GL_LAYOUT_H

#ifdef __cplusplus
#include <cstddef>
#include <cstdint>
namespace viscd::gl::shader {
using uint = std::uint32_t;
struct vec4 {
  float x, y, z, w;
};
struct uvec4 {
  uint x, y, z, w;
};
struct dvec2 {
  double x, y;
};
#endif

// ---- work-group sizes (local_size_x of each kind of compute shader) ----
// Element-wise kernels (codes, cull, build, fit, query, states, shading, counting).
#define VISCD_WG_SIZE 256
// Passes over the map's pixels (counting, shading) run 2D work groups of this many pixels a
// side, so that any map within kMaxMapSide fits the minimum work-group count limit (65535).
#define VISCD_TILE_SIDE 16
// The splat (GlGeometry::splat): one work group per chunk of this many pixels of a sphere.
#define VISCD_SPLAT_CHUNK 256
// Radix sort: a work group of VISCD_SORT_GROUP invocations (one per 8-bit digit: the stable
// local ranking gives each invocation one digit) handles a tile of VISCD_SORT_TILE keys per pass,
// VISCD_SORT_GROUP at a time. Larger tiles mean fewer tiles for the one-group offset scan.
#define VISCD_SORT_GROUP 256
#define VISCD_SORT_ROUNDS 4
#define VISCD_SORT_TILE (VISCD_SORT_GROUP * VISCD_SORT_ROUNDS)
// Counts up to this many keys are sorted by one work group in shared memory (sort_local.comp;
// 12 bytes a key, and VISCD_LOCAL_SORT / 2 invocations, within GL's guaranteed minimums).
#define VISCD_LOCAL_SORT 1024
// Scan: each invocation scans this many consecutive elements, so a block is 256 * 4 elements.
#define VISCD_SCAN_PER_THREAD 4
#define VISCD_SCAN_BLOCK (VISCD_WG_SIZE * VISCD_SCAN_PER_THREAD)

// ---- SSBO binding points ----
// N counts every object of the frame: its moving objects, then the static set's (FrameData).
#define VISCD_BIND_SPHERES 0   // vec4 spheres[N]: x, y, z, r (viscd::Sphere; a box frame's box_proxy())
#define VISCD_BIND_COUNTS 1    // uint counts[N]: map pixels per object (also the atomic_uint buffer)
#define VISCD_BIND_PIXELS 2    // float pixels[N]: screen-scaled counts
#define VISCD_BIND_FLAGS 3     // uint flags[N]: 1 = active, scan input
#define VISCD_BIND_ACTIVE 4    // uint active[n]: active object ids, ascending
#define VISCD_BIND_INFO 5      // FrameInfo
#define VISCD_BIND_PARTIALS 6  // BoundsPartial per work group
#define VISCD_BIND_KEYS_IN 7   // uvec2 keys[n] (x = low 32 bits, y = high 32 bits)
#define VISCD_BIND_KEYS_OUT 8
#define VISCD_BIND_VALUES_IN 9  // uint values[n]
#define VISCD_BIND_VALUES_OUT 10
#define VISCD_BIND_SCAN_IN 11  // generic scan: input, output, block sums
#define VISCD_BIND_SCAN_OUT 12
#define VISCD_BIND_SCAN_BLOCKS 13
#define VISCD_BIND_NODES 14         // LbvhNode nodes[n - 1]
#define VISCD_BIND_PARENT 15        // uint parent[n - 1] (internal nodes), then leaf_parent[n]
#define VISCD_BIND_ARRIVALS 16      // uint arrivals[n - 1]: fit arrival counters
#define VISCD_BIND_SORTED 17        // vec4 sorted_spheres[n]
#define VISCD_BIND_LEAF_BOXES 18    // LeafBox leaf_boxes[n]
#define VISCD_BIND_PAIRS 19         // uvec2 pairs[capacity]: (x = j, y = i), i < j
#define VISCD_BIND_STATE 20         // uint state[N]: ObjectState
#define VISCD_BIND_IMAGE 21         // uint rgba8[W * H], rows top to bottom
#define VISCD_BIND_DISPATCH 22      // DispatchArgs: indirect dispatch sizes from the active count
#define VISCD_BIND_FILTERS 23       // uvec2 filters[N]: x = group, y = mask (viscd::Filter)
#define VISCD_BIND_ALWAYS 24        // uint always[(N + 3) / 4]: FrameInput::always_active, 4 bytes a word
#define VISCD_BIND_BOXES 25         // LeafBox boxes[N]: a box frame's boxes (viscd::Box: min xyz, max xyz)
#define VISCD_BIND_SPLAT_DEPTH 26   // uint depth_bits[W * H]: the splat's nearest depth (float bits), rows top down
#define VISCD_BIND_SPLAT_IDS 27     // uint ids[W * H]: the splat's smallest id at that depth
#define VISCD_BIND_SPLAT_RECTS 28   // uvec4 rects[N]: each sphere's pixel rectangle and nearest depth bits
#define VISCD_BIND_SPLAT_CHUNKS 29  // uvec2 chunks[]: (sphere, chunk of VISCD_SPLAT_CHUNK pixels)
#define VISCD_BIND_SPLAT_COUNT 30   // uint: the chunks listed
// Atomic counter buffer binding of the paper's atomic_uint counting mode.
#define VISCD_BIND_ATOMIC_COUNTERS 0
// Texture units.
#define VISCD_UNIT_IDS 0
#define VISCD_UNIT_NORMAL 1

// ---- ObjectState values (viscd::ObjectState) ----
#define VISCD_STATE_CULLED 0u
#define VISCD_STATE_FREE 1u
#define VISCD_STATE_COLLIDING 2u

// Leaf flag of LbvhNode child ids (core/lbvh.hpp kLeafBit).
#define VISCD_LEAF_BIT 0x80000000u
// Traversal stack entries: the deepest Karras tree over 64-bit keys is 64 + 32 (core/lbvh.hpp).
#define VISCD_STACK_DEPTH 128

// Per-frame values the CPU reads back once after culling, and the pair counter.
struct FrameInfo {
  uint active_count;   // objects in the tree, n: the active ones that may pair (all active without filters)
  uint total_pixels;   // sum of map pixel counts over all objects
  uint pair_count;     // pairs found by the query (may exceed the pair buffer's capacity)
  uint visible_count;  // active objects (not culled), filters aside
  vec4 lo;             // bounds of the active centres (xyz)
  vec4 hi;
  vec4 root_lo;  // root box of the fitted tree (xyz)
  vec4 root_hi;
  dvec2 diameter_sum;  // x = sum of 2r over the active objects (double, as core/broadphase.cpp)
  uvec4 filter_or;     // x = OR of the groups, y = OR of the masks of the active objects (with filters)
  uvec4 id_check;      // x = map pixels whose id exceeds N, y = the first such pixel (row-major index)
};

// Work-group counts of the passes after culling, written on the GPU from FrameInfo.active_count
// (dispatch_args.comp) and read by glDispatchComputeIndirect: the host never waits for n.
// Each member is one DispatchIndirectCommand (x, y, z groups) padded to 16 bytes.
struct DispatchArgs {
  uvec4 per_object;  // ceil(n / VISCD_WG_SIZE): codes, bounds, fit, query
  uvec4 per_node;    // ceil((n - 1) / VISCD_WG_SIZE): build (n - 1 internal nodes)
  uvec4 sort_tiles;  // ceil(n / VISCD_SORT_TILE) radix tiles, 0 when n <= VISCD_LOCAL_SORT
};

// Per-work-group partial of the active-centre bounds and the diameter sum.
struct BoundsPartial {
  vec4 lo;
  vec4 hi;
  dvec2 diameter_sum;  // x = sum of 2r over the group's objects, y unused
};

// One internal LBVH node, byte for byte core/lbvh.hpp's BvhNode: box[2] as 2 x (lo xyz, hi xyz),
// then child[2], then last[2].
struct LbvhNode {
  float box[12];
  uint child[2];
  uint last[2];
};

// A leaf box, byte for byte core/geometry.hpp's Aabb (lo xyz, hi xyz).
struct LeafBox {
  float v[6];
};

#ifdef __cplusplus
static_assert(sizeof(FrameInfo) == 128 && offsetof(FrameInfo, lo) == 16 && offsetof(FrameInfo, root_lo) == 48 &&
              offsetof(FrameInfo, diameter_sum) == 80 && offsetof(FrameInfo, filter_or) == 96 &&
              offsetof(FrameInfo, id_check) == 112);
static_assert(sizeof(BoundsPartial) == 48 && offsetof(BoundsPartial, diameter_sum) == 32);
static_assert(sizeof(LbvhNode) == 64 && offsetof(LbvhNode, child) == 48 && offsetof(LbvhNode, last) == 56);
static_assert(sizeof(LeafBox) == 24);
static_assert(sizeof(DispatchArgs) == 48 && offsetof(DispatchArgs, per_node) == 16 &&
              offsetof(DispatchArgs, sort_tiles) == 32);
static_assert(VISCD_SORT_GROUP == 256, "one invocation per 8-bit digit");
}  // namespace viscd::gl::shader
#endif

#endif  // VISCD_GL_LAYOUT_H
