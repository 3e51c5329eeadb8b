#include "cpu/pipeline.hpp"

#include <algorithm>
#include <new>
#include <optional>

#include "core/stopwatch.hpp"
#include "cpu/broadphase.hpp"
#include "cpu/parallel.hpp"

namespace viscd::detail {

std::uint64_t PipelineDetector::memory_bytes() const {
  std::uint64_t b = map_.memory_bytes() + bytes_of(counts_) + bytes_of(active_);
  for (const auto& s : count_scratch_) b += bytes_of(s);
  return b + backend_memory_bytes();
}

Status PipelineDetector::detect(std::span<const Sphere> spheres, const Camera* camera, FrameResult& out) {
  try {
    return detect_frame(spheres, camera, out);
  } catch (const std::bad_alloc&) {
    return Status::failure(out_of_memory_message(spheres.size(), camera, config_));
  }
}

Status PipelineDetector::detect_frame(std::span<const Sphere> spheres, const Camera* camera, FrameResult& out) {
  if (Status s = validate_frame(spheres, camera, config_); !s) return s;
  // Every parallel stage of this frame runs on the caller's executor, or on viscd's pool.
  const ExecutorScope scope(config_.executor);
  const int threads = resolve_threads(config_.threads, config_.executor ? config_.executor->concurrency() : 0);
  const std::size_t n = spheres.size();
  FrameStats& stats = out.stats;
  std::string layout = std::move(stats.layout);  // keep its buffer: no allocation per frame
  stats = FrameStats{};
  stats.layout = std::move(layout);
  stats.objects = static_cast<std::uint32_t>(n);
  stats.has_camera = camera != nullptr;
  auto ms = [&](Stage s) -> double& { return stats.stage_ms[static_cast<std::size_t>(s)]; };
  Stopwatch sw;

  int bits = 0;
  std::optional<CameraRig> rig;
  if (camera) {
    const MapSize map = map_size(config_, *camera);
    rig.emplace(*camera, map.width, map.height);
    map_.resize(map.width, map.height, config_.shade);
    rasterize(*rig, spheres, threads);
    ms(Stage::visibility) = sw.lap();
    count_pixels(map_, n, threads, counts_, count_scratch_);
    ms(Stage::count) = sw.lap();
    bits = cull_and_choose_bits(counts_, rig->pixel_scale, config_, out.pixels, active_, stats);
    ms(Stage::cull) = sw.lap();
  } else {
    map_ = VisibilityMap{};
    out.pixels.clear();
    active_.resize(n);
    for (std::size_t k = 0; k < n; ++k) active_[k] = static_cast<std::uint32_t>(k);
    stats.active = static_cast<std::uint32_t>(n);
    bits = choose_bits(config_, false, 0.0);
  }

  if (Status s = broadphase(spheres, active_, bits, threads, out.pairs, stats); !s) return s;
  stats.pairs = out.pairs.size();

  sw.lap();
  out.state.assign(n, ObjectState::culled);
  for (std::uint32_t k : active_) out.state[k] = ObjectState::free;
  for (const Pair& p : out.pairs) out.state[p.i] = out.state[p.j] = ObjectState::colliding;
  ms(Stage::query) += sw.lap();

  if (camera && config_.shade) {
    shade(*rig, map_, out.state, threads, out.image);
    out.image_width = map_.width;
    out.image_height = map_.height;
    ms(Stage::shade) = sw.lap();
  } else {
    out.image.clear();
    out.image_width = out.image_height = 0;
  }
  return {};
}

}  // namespace viscd::detail
