#include "cpu/cpu_detector.hpp"

#include "cpu/parallel.hpp"

namespace viscd {
namespace detail {

const BucketBroadphase& CpuDetector::unpaired_tree() {
  if (!unpaired_built_) {
    const ExecutorScope scope(config_.executor);
    const int threads = resolve_threads(config_.threads, config_.executor ? config_.executor->concurrency() : 0);
    const std::size_t n = unpaired_spheres_.size();
    if (iota_.size() < n) {
      const std::size_t old = iota_.size();
      iota_.resize(n);
      for (std::size_t k = old; k < n; ++k) iota_[k] = static_cast<std::uint32_t>(k);
    }
    unpaired_tree_.build(unpaired_spheres_, std::span<const std::uint32_t>(iota_.data(), n), 32, config_.layout,
                         threads, unpaired_stats_);
    unpaired_built_ = true;
  }
  return unpaired_tree_;
}

}  // namespace detail

std::unique_ptr<Detector> make_cpu_detector(const Config& config) {
  return detail::DetectorAccess::wrap(std::make_unique<detail::CpuDetector>(config));
}

}  // namespace viscd
