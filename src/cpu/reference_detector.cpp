// The reference backend: per-pixel ray casting against every object and brute-force pairs.
// Deliberately simple; every other backend is tested against it.

#include "core/stopwatch.hpp"
#include "cpu/brute_force.hpp"
#include "cpu/morton_order.hpp"
#include "cpu/pipeline.hpp"

namespace viscd {
namespace detail {
namespace {

class ReferenceDetector final : public PipelineDetector {
 public:
  explicit ReferenceDetector(const Config& config) : PipelineDetector(config) {}
  [[nodiscard]] std::string_view name() const override { return "reference"; }
  [[nodiscard]] std::uint64_t backend_memory_bytes() const override { return 0; }

 private:
  Status rasterize(const CameraRig& cam, const Shapes& objects, int) override {
    rasterize_reference(cam, objects, map_);
    return {};
  }
  // Queries: the base class's brute force over the active spheres (answers_queries() is false).
  Status broadphase(const Shapes& objects, std::span<const std::uint32_t> active, std::span<const std::uint32_t>,
                    std::span<const Filter> filters, std::uint32_t static_from, int bits, int threads,
                    std::vector<Pair>& pairs, FrameStats& stats) override {
    // Report the same m and layout as the LBVH backends would, so stats compare one to one.
    ActiveExtent extent;
    (void)layout_stage(objects, active, bits, config_.layout, threads, extent, stats);
    Stopwatch sw;
    const bool complete =
        brute_force_pairs(objects, active, pairs, pairs_within_cap(config_.pair_memory_cap), filters, static_from);
    stats.ms(Stage::query) = sw.lap();
    if (!complete) return check_pair_cap(pairs.size() + 1, config_.pair_memory_cap, true);
    return {};
  }
};

}  // namespace
}  // namespace detail

std::unique_ptr<Detector> make_reference_detector(const Config& config) {
  return detail::DetectorAccess::wrap(std::make_unique<detail::ReferenceDetector>(config));
}

}  // namespace viscd
