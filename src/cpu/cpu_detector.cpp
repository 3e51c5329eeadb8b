#include "cpu/cpu_detector.hpp"

namespace viscd {

std::unique_ptr<Detector> make_cpu_detector(const Config& config) {
  return std::make_unique<detail::CpuDetector>(config);
}

}  // namespace viscd
