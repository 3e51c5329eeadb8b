#pragma once
// Stage 8 of the reference backend: every pair of the active set tested, O(n^2). The oracle the
// other backends are tested against.

#include <cstddef>
#include <cstdint>
#include <limits>
#include <span>
#include <vector>

#include "core/shapes.hpp"
#include "viscd/types.hpp"

namespace viscd::detail {

/// O(n^2) brute force over the active set (spheres or boxes): the oracle. Pairs come out sorted.
/// Stops and returns false when there are more than `max_pairs`. `filters`: empty, or one per
/// object, and then only pairs with pair_passes_filter() count. Objects from `static_from` on
/// are static: no pair of two of them.
bool brute_force_pairs(const Shapes& objects, std::span<const std::uint32_t> active, std::vector<Pair>& pairs,
                       std::size_t max_pairs = SIZE_MAX, std::span<const Filter> filters = {},
                       std::uint32_t static_from = std::numeric_limits<std::uint32_t>::max());

}  // namespace viscd::detail
