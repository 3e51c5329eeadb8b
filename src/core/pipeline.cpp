#include "core/pipeline.hpp"

#include <algorithm>
#include <new>
#include <optional>

#include "core/broadphase.hpp"
#include "core/parallel.hpp"
#include "core/stopwatch.hpp"

namespace viscd::detail {

std::uint64_t PipelineDetector::memory_bytes() const {
  std::uint64_t b =
      bytes_of(map_.ids) + bytes_of(map_.depth) + bytes_of(map_.normal) + bytes_of(counts_) + bytes_of(active_);
  for (const auto& s : count_scratch_) b += bytes_of(s);
  return b + backend_memory_bytes();
}

Status validate_frame(std::span<const Sphere> spheres, const Camera* camera, const Config& config) {
  if (config.threads < 0)
    return Status::failure("Config::threads = " + std::to_string(config.threads) +
                           ": expected 0 (all cores) or a positive count");
  if (Status s = validate_spheres(spheres); !s) return s;
  if (camera) {
    if (Status s = validate_camera(*camera); !s) return s;
    if (config.map_width < 0 || config.map_height < 0 || (config.map_width == 0) != (config.map_height == 0))
      return Status::failure("visibility map size must be W x H with both positive, or 0 x 0 for the screen size");
    const int w = config.map_width ? config.map_width : camera->width;
    const int h = config.map_height ? config.map_height : camera->height;
    if (Status s = validate_map_size(w, h); !s) return s;
  }
  return {};
}

std::string out_of_memory_message(std::size_t objects, const Camera* camera, const Config& config) {
  std::string m = "out of memory in a frame of " + std::to_string(objects) + " objects";
  if (camera) {
    const int w = config.map_width ? config.map_width : camera->width;
    const int h = config.map_height ? config.map_height : camera->height;
    m += " with a " + std::to_string(w) + "x" + std::to_string(h) + " visibility map";
  }
  m += config.pair_memory_cap
           ? " (pair memory cap " + std::to_string(config.pair_memory_cap) +
                 " bytes: a lower cap makes such a frame fail early; or free memory)"
           : " (no pair memory cap is set: Config::pair_memory_cap, the tool's --max-pair-memory, makes a frame "
             "with too many pairs fail early)";
  return m;
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

  int bits = 32;  // without a camera mu is undefined; adaptive falls back to the paper's 32 bits
  std::optional<CameraRig> rig;
  if (camera) {
    const int mw = config_.map_width ? config_.map_width : camera->width;
    const int mh = config_.map_height ? config_.map_height : camera->height;
    rig.emplace(*camera, mw, mh);
    map_.resize(mw, mh, config_.shade);
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
    if (config_.bits != Bits::adaptive) bits = static_cast<int>(config_.bits);
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
