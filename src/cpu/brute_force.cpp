#include "cpu/brute_force.hpp"

#include "viscd/detector.hpp"

namespace viscd::detail {

bool brute_force_pairs(const Shapes& objects, std::span<const std::uint32_t> active, std::vector<Pair>& pairs,
                       std::size_t max_pairs, std::span<const Filter> filters, std::uint32_t static_from) {
  pairs.clear();
  const std::size_t n = active.size();
  for (std::size_t a = 0; a < n; ++a) {
    if (active[a] >= static_from) break;  // active ascends: the rest are static, and pair only with moving ones
    for (std::size_t b = a + 1; b < n; ++b) {
      if (!objects.overlap(active[a], active[b])) continue;
      if (!filters.empty() && !pair_passes_filter(filters[active[a]], filters[active[b]])) continue;
      if (pairs.size() == max_pairs) return false;
      pairs.push_back(Pair{active[a], active[b]});
    }
  }
  return true;
}

}  // namespace viscd::detail
