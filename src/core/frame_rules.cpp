#include "core/frame_rules.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/morton.hpp"
#include "core/visibility.hpp"
#include "viscd/detector.hpp"

namespace viscd::detail {

Status validate_frame(const Shapes& objects, const Camera* camera, const Config& config, bool check_objects) {
  if (config.threads < 0)
    return Status::failure(ErrorKind::invalid_input, "Config::threads = " + std::to_string(config.threads) +
                                                         ": expected 0 (all cores) or a positive count");
  if (!(config.rest_margin >= 0) || !std::isfinite(config.rest_margin))
    return Status::failure(ErrorKind::invalid_input, "Config::rest_margin = " + std::to_string(config.rest_margin) +
                                                         ": expected a finite distance >= 0");
  if (!(config.move_margin >= 0) || !std::isfinite(config.move_margin))
    return Status::failure(ErrorKind::invalid_input, "Config::move_margin = " + std::to_string(config.move_margin) +
                                                         ": expected a finite factor >= 0");
  if (check_objects)
    if (Status s = objects.is_box() ? validate_boxes(objects.boxes) : validate_spheres(objects.spheres); !s) return s;
  if (camera) {
    if (Status s = validate_camera(*camera); !s) return s;
    if (config.map_width < 0 || config.map_height < 0 || (config.map_width == 0) != (config.map_height == 0))
      return Status::failure(ErrorKind::invalid_input,
                             "visibility map size must be W x H with both positive, or 0 x 0 for the screen size");
    const MapSize map = map_size(config, *camera);
    if (Status s = validate_map_size(map.width, map.height); !s) return s;
  }
  return {};
}

bool adaptive_bits_need_pixels(const FrameInput& in, const Config& config) {
  if (config.bits != Bits::adaptive) return false;
  if (config.culling || in.camera == nullptr) return true;
  // Without culling every object is active. mu <= (screen pixels) / N, since a pixel holds one
  // object at most: below a, Eq. (1) gives 16, which more than kMostObjectsFor16Bits objects
  // raise to 32 (choose_bits()), the width of a frame without pixels.
  const std::size_t n = Shapes::of(in).size();
  const double screen = static_cast<double>(in.camera->width) * static_cast<double>(in.camera->height);
  const bool m_is_32 =
      n > kMostObjectsFor16Bits && screen < static_cast<double>(config.pixels_for_32_bits) * static_cast<double>(n);
  return !m_is_32;
}

bool renders_own_map(const FrameInput& in, const Config& config) {
  const bool map_used = config.culling || adaptive_bits_need_pixels(in, config) || config.shade || config.report_pixels;
  return in.camera != nullptr && !has_callers_map(in) && map_used;
}

bool counts_pixels(const FrameInput& in, const Config& config) {
  return has_callers_map(in) || renders_own_map(in, config);
}

Status validate_static_kind(const FrameInput& in, const StaticSet& set) {
  const Shapes objects = Shapes::of(in);
  if (set.empty() || objects.empty() || objects.kind == set.kind()) return {};
  return Status::failure(ErrorKind::invalid_input, std::string("FrameInput: the frame's objects are ") +
                                                       (objects.is_box() ? "boxes" : "spheres") +
                                                       " but the detector's static set holds " +
                                                       (set.kind() == ShapeKind::box ? "boxes" : "spheres") +
                                                       "; a frame and its static set hold the same kind");
}

Status validate_frame_input(const FrameInput& in, const Config& config, bool check_objects) {
  if (!in.spheres.empty() && !in.boxes.empty())
    return Status::failure(ErrorKind::invalid_input, "FrameInput: " + std::to_string(in.spheres.size()) +
                                                         " spheres and " + std::to_string(in.boxes.size()) +
                                                         " boxes; a frame holds spheres or boxes, not both");
  const Shapes objects = Shapes::of(in);
  const std::size_t n = objects.size();
  const char* noun = objects.is_box() ? " boxes" : " spheres";
  if (!in.id_map.empty() && in.gl_id_texture != 0)
    return Status::failure(ErrorKind::invalid_input,
                           "FrameInput: id_map and gl_id_texture are both set; give the visibility map one way");
  if (!has_callers_map(in))
    if (Status s = validate_frame(objects, in.camera, config, check_objects); !s) return s;
  if (has_callers_map(in)) {
    // The caller's map: its own size replaces Config's, so only the rest of validate_frame().
    Config own = config;
    own.map_width = own.map_height = 0;
    if (Status s = validate_frame(objects, in.camera, own, check_objects); !s) return s;
    const int w = in.id_map_width, h = in.id_map_height;
    if (w < 1 || h < 1)
      return Status::failure(ErrorKind::invalid_input,
                             "FrameInput: the id map is " + std::to_string(w) + "x" + std::to_string(h) +
                                 " pixels; id_map_width and id_map_height must be at least 1");
    if (Status s = validate_map_size(w, h); !s)
      return Status::failure(ErrorKind::invalid_input, "FrameInput: " + s.error());
    const std::uint64_t want = static_cast<std::uint64_t>(w) * static_cast<std::uint64_t>(h);
    if (!in.id_map.empty() && in.id_map.size() != want)
      return Status::failure(ErrorKind::invalid_input,
                             "FrameInput: the id map holds " + std::to_string(in.id_map.size()) + " ids, but " +
                                 std::to_string(w) + "x" + std::to_string(h) + " needs " + std::to_string(want));
  }
  if (has_callers_map(in) && config.shade)
    return Status::failure(
        ErrorKind::invalid_input,
        "Config::shade needs the detector's own visibility map (depth and normals); with the caller's id map "
        "(FrameInput::id_map or gl_id_texture) no image can be shaded");
  if (!in.always_active.empty() && in.always_active.size() != n)
    return Status::failure(ErrorKind::invalid_input, "FrameInput: " + std::to_string(in.always_active.size()) +
                                                         " always_active flags for " + std::to_string(n) + noun +
                                                         "; give none or one per object");
  if (!in.filters.empty() && in.filters.size() != n)
    return Status::failure(ErrorKind::invalid_input, "FrameInput: " + std::to_string(in.filters.size()) +
                                                         " filters for " + std::to_string(n) + noun +
                                                         "; give none or one per object");
  if (in.moved_listed) return validate_moved(in.moved, n);
  if (!in.moved.empty())
    return Status::failure(ErrorKind::invalid_input,
                           "FrameInput: moved holds " + std::to_string(in.moved.size()) +
                               " indices but moved_listed is false; set it to say the list is complete");
  return {};
}

Status validate_moved(std::span<const std::uint32_t> moved, std::size_t objects) {
  for (std::size_t k = 0; k < moved.size(); ++k) {
    const std::uint32_t v = moved[k];
    const bool bad = v >= objects || (k > 0 && v <= moved[k - 1]);
    if (!bad) continue;
    const std::string at = "FrameInput: moved[" + std::to_string(k) + "] = " + std::to_string(v);
    if (v >= objects)
      return Status::failure(ErrorKind::invalid_input,
                             at + " is not an object of this frame (it has " + std::to_string(objects) + ")");
    if (v == moved[k - 1])
      return Status::failure(ErrorKind::invalid_input, at + " repeats moved[" + std::to_string(k - 1) + "]");
    return Status::failure(ErrorKind::invalid_input, at + " is below moved[" + std::to_string(k - 1) +
                                                         "] = " + std::to_string(moved[k - 1]) +
                                                         "; the list must be sorted ascending");
  }
  return {};
}

Status id_map_error(std::span<const std::uint32_t> ids, int width, std::size_t objects) {
  for (std::size_t k = 0; k < ids.size(); ++k) {
    if (ids[k] <= objects) continue;
    const std::size_t w = static_cast<std::size_t>(width);
    return Status::failure(ErrorKind::invalid_input,
                           "id map pixel (" + std::to_string(k % w) + ", " + std::to_string(k / w) + ") holds id " +
                               std::to_string(ids[k]) + ", but the frame has " + std::to_string(objects) +
                               " objects (an id is an object index + 1, 0 is background)");
  }
  return {};
}

double map_pixel_scale(const Camera* camera, int map_width, int map_height) {
  if (!camera) return 1.0;
  return (static_cast<double>(camera->width) * camera->height) / (static_cast<double>(map_width) * map_height);
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
  return Status::failure(ErrorKind::pair_cap,
                         "frame has " + std::string(more) + std::to_string(pairs) + " colliding pairs, which need " +
                             more + std::to_string(pairs * sizeof(Pair)) + " bytes, over the pair memory cap of " +
                             std::to_string(cap) +
                             " bytes (raise it with Config::pair_memory_cap, or the tool's --max-pair-memory)");
}

ActiveExtent extent_of(const Shapes& objects, std::span<const std::uint32_t> active, std::size_t begin,
                       std::size_t end) {
  ActiveExtent e;
  auto add = [&](const Sphere& s) {
    e.bounds.grow(s.x, s.y, s.z);
    e.diameter_sum += 2.0 * s.r;
  };
  if (objects.is_box()) {
    for (std::size_t k = begin; k < end; ++k) add(box_proxy(objects.boxes[active[k]]));
  } else {
    for (std::size_t k = begin; k < end; ++k) add(objects.spheres[active[k]]);
  }
  e.count = end > begin ? end - begin : 0;
  return e;
}

}  // namespace viscd::detail
