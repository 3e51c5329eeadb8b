#pragma once
// Summary statistics of measured times: the median the tools report.

#include <vector>

namespace viscd::app {

/// Median of a copy of v (0 for empty; the mean of the two middle values for an even count).
[[nodiscard]] double median(std::vector<double> v);

}  // namespace viscd::app
