#include "cpu/brute_force.hpp"

#include "core/geometry.hpp"
#include "viscd/detector.hpp"

namespace viscd::detail {

bool brute_force_pairs(std::span<const Sphere> spheres, std::span<const std::uint32_t> active, std::vector<Pair>& pairs,
                       std::size_t max_pairs, std::span<const Filter> filters) {
  pairs.clear();
  const std::size_t n = active.size();
  for (std::size_t a = 0; a < n; ++a) {
    const Sphere& sa = spheres[active[a]];
    for (std::size_t b = a + 1; b < n; ++b) {
      if (!overlap_exact(sa, spheres[active[b]])) continue;
      if (!filters.empty() && !pair_passes_filter(filters[active[a]], filters[active[b]])) continue;
      if (pairs.size() == max_pairs) return false;
      pairs.push_back(Pair{active[a], active[b]});
    }
  }
  return true;
}

}  // namespace viscd::detail
