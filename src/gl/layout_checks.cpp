// Compile-time checks that tie the header shared with the shaders (shaders/shared/layout.h) to
// the C++ types and constants it mirrors, so that changing one side without the other fails to
// build. layout.h pins its own structs' std430 sizes and offsets; this file checks that they
// agree with the host's types, which the gl backend reads back byte for byte. Nothing here runs.

#include <cstddef>
#include <type_traits>

#include "core/geometry.hpp"
#include "core/lbvh.hpp"
#include "gl/shaders/shared/layout.h"
#include "viscd/frame.hpp"
#include "viscd/types.hpp"

namespace viscd::gl::shader {

// Object states: state.comp writes them into a uint per object, the host casts each to ObjectState.
static_assert(VISCD_STATE_CULLED == static_cast<uint>(ObjectState::culled));
static_assert(VISCD_STATE_FREE == static_cast<uint>(ObjectState::free));
static_assert(VISCD_STATE_COLLIDING == static_cast<uint>(ObjectState::colliding));

// Tree: the leaf flag of child ids and the traversal stack, as the cpu backend's (core/lbvh.hpp).
static_assert(VISCD_LEAF_BIT == detail::kLeafBit);
static_assert(VISCD_STACK_DEPTH == detail::kStackDepth);
static_assert(VISCD_STACK_DEPTH >= 64 + 32, "the deepest Karras tree over 64-bit keys");

// Internal nodes are read back into core's BvhNode, leaf boxes into core's Aabb (read_tree).
static_assert(sizeof(LbvhNode) == sizeof(detail::BvhNode));
static_assert(sizeof(LbvhNode::box) == sizeof(detail::BvhNode::box));
static_assert(offsetof(LbvhNode, child) == offsetof(detail::BvhNode, child));
static_assert(offsetof(LbvhNode, last) == offsetof(detail::BvhNode, last));
static_assert(sizeof(LeafBox) == sizeof(detail::Aabb));
static_assert(offsetof(detail::Aabb, lo) == 0 && offsetof(detail::Aabb, hi) == 3 * sizeof(float));
static_assert(sizeof(detail::Vec3) == 3 * sizeof(float));

// Spheres upload unchanged as vec4 (x, y, z, r).
static_assert(sizeof(Sphere) == sizeof(vec4));
static_assert(offsetof(Sphere, x) == offsetof(vec4, x) && offsetof(Sphere, y) == offsetof(vec4, y) &&
              offsetof(Sphere, z) == offsetof(vec4, z) && offsetof(Sphere, r) == offsetof(vec4, w));
static_assert(std::is_same_v<decltype(Sphere::x), float>);

// Boxes upload unchanged as LeafBox (min xyz, max xyz), the layout of the leaf boxes they become.
static_assert(sizeof(Box) == sizeof(LeafBox));
static_assert(offsetof(Box, min) == 0 && offsetof(Box, max) == 3 * sizeof(float));
static_assert(std::is_same_v<std::remove_extent_t<decltype(Box::min)>, float>);

// Pairs are stored as uvec2 (x = j, y = i), read back into Pair {i, j} and swapped.
static_assert(sizeof(Pair) == 2 * sizeof(uint));
static_assert(offsetof(Pair, i) == 0 && offsetof(Pair, j) == sizeof(uint));
static_assert(std::is_same_v<decltype(Pair::i), uint> && std::is_same_v<decltype(Pair::j), uint>);

// Screen-scaled pixel counts: one float per object, read back into FrameResult::pixels.
static_assert(std::is_same_v<decltype(FrameResult::pixels)::value_type, float>);

}  // namespace viscd::gl::shader
