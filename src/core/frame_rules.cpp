#include "core/frame_rules.hpp"

#include <algorithm>
#include <limits>

#include "core/visibility.hpp"
#include "viscd/detector.hpp"

namespace viscd::detail {

Status validate_frame(std::span<const Sphere> spheres, const Camera* camera, const Config& config) {
  if (config.threads < 0)
    return Status::failure("Config::threads = " + std::to_string(config.threads) +
                           ": expected 0 (all cores) or a positive count");
  if (Status s = validate_spheres(spheres); !s) return s;
  if (camera) {
    if (Status s = validate_camera(*camera); !s) return s;
    if (config.map_width < 0 || config.map_height < 0 || (config.map_width == 0) != (config.map_height == 0))
      return Status::failure("visibility map size must be W x H with both positive, or 0 x 0 for the screen size");
    const MapSize map = map_size(config, *camera);
    if (Status s = validate_map_size(map.width, map.height); !s) return s;
  }
  return {};
}

std::string out_of_memory_message(std::size_t objects, const Camera* camera, const Config& config) {
  std::string m = "out of memory in a frame of " + std::to_string(objects) + " objects";
  if (camera) {
    const MapSize map = map_size(config, *camera);
    m += " with a " + std::to_string(map.width) + "x" + std::to_string(map.height) + " visibility map";
  }
  m += config.pair_memory_cap
           ? " (pair memory cap " + std::to_string(config.pair_memory_cap) +
                 " bytes: a lower cap makes such a frame fail early; or free memory)"
           : " (no pair memory cap is set: Config::pair_memory_cap, the tool's --max-pair-memory, makes a frame "
             "with too many pairs fail early)";
  return m;
}

std::size_t pairs_within_cap(std::size_t cap) {
  return cap == 0 ? std::numeric_limits<std::size_t>::max() : cap / sizeof(Pair);
}

Status check_pair_cap(std::size_t pairs, std::size_t cap, bool at_least) {
  if (!at_least && pairs <= pairs_within_cap(cap)) return {};
  const char* more = at_least ? "at least " : "";
  return Status::failure("frame has " + std::string(more) + std::to_string(pairs) + " colliding pairs, which need " +
                         more + std::to_string(pairs * sizeof(Pair)) + " bytes, over the pair memory cap of " +
                         std::to_string(cap) +
                         " bytes (raise it with Config::pair_memory_cap, or the tool's --max-pair-memory)");
}

ActiveExtent extent_of(std::span<const Sphere> spheres, std::span<const std::uint32_t> active, std::size_t begin,
                       std::size_t end) {
  ActiveExtent e;
  for (std::size_t k = begin; k < end; ++k) {
    const Sphere& s = spheres[active[k]];
    e.bounds.grow(s.x, s.y, s.z);
    e.diameter_sum += 2.0 * s.r;
  }
  e.count = end > begin ? end - begin : 0;
  return e;
}

}  // namespace viscd::detail
