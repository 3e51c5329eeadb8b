#pragma once
// Stage 8 of the reference backend: every pair of the active set tested, O(n^2). The oracle the
// other backends are tested against.

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "viscd/types.hpp"

namespace viscd::detail {

/// O(n^2) brute force over the active set: the oracle. Pairs come out sorted. Stops and returns
/// false when there are more than `max_pairs`. `filters`: empty, or one per sphere, and then only
/// pairs with pair_passes_filter() count.
bool brute_force_pairs(std::span<const Sphere> spheres, std::span<const std::uint32_t> active, std::vector<Pair>& pairs,
                       std::size_t max_pairs = SIZE_MAX, std::span<const Filter> filters = {});

}  // namespace viscd::detail
