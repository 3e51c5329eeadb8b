// Reading the moving objects and the static set's file, handing the static set to the detector,
// and numbering static objects N + k in the outputs.
#include "static_objects.hpp"

#include <limits>
#include <utility>

#include "viscd/scene.hpp"

namespace viscd::app {
namespace {

// What a file of each kind looks like, for the message on a file of the wrong kind.
std::string file_kind(ShapeKind kind, const std::filesystem::path& path) {
  if (kind == ShapeKind::box) return "a box file (header `minx,miny,minz,maxx,maxy,maxz`)";
  return path.extension() == ".csv" ? "a sphere file (header `x,y,z,r`)" : "a sphere file (XYZR: `x y z r` lines)";
}

std::string wanted(ShapeKind kind) {
  if (kind == ShapeKind::box)
    return "boxes too: a CSV with the header `minx,miny,minz,maxx,maxy,maxz` (and optionally `group,mask`)";
  return "spheres too: XYZR text or a CSV with the header `x,y,z,r` (and optionally `group,mask`)";
}

}  // namespace

Result<ObjectTable> read_moving_objects(const std::string& spheres, const std::string& boxes) {
  using R = Result<ObjectTable>;
  ObjectTable out;
  if (!boxes.empty()) {
    auto table = read_box_table(boxes);
    if (!table) return R::failure(table.status());
    out.kind = ShapeKind::box;
    out.boxes = std::move(table.value());
    return out;
  }
  auto table = read_sphere_table(spheres);
  if (!table) return R::failure(table.status());
  out.spheres = std::move(table.value());
  return out;
}

Result<ObjectTable> read_static_objects(const std::filesystem::path& path, ShapeKind moving,
                                        std::string_view moving_option, std::size_t moving_count) {
  using R = Result<ObjectTable>;
  auto table = read_object_table(path);
  if (!table) return R::failure(table.status());
  const ObjectTable& t = table.value();
  if (t.kind != moving && t.kind_line != 0)
    return R::failure(ErrorKind::invalid_input,
                      printable(path.string(), 200) + ":" + std::to_string(t.kind_line) + ": " +
                          file_kind(t.kind, path) + ", but the moving objects (" + std::string(moving_option) +
                          ") are " + (moving == ShapeKind::box ? "boxes" : "spheres") +
                          ": the static set holds the same kind, so --static must hold " + wanted(moving));
  // Outputs number static object k as N + k in 32 bits.
  if (t.size() > 0 && moving_count + t.size() - 1 > std::numeric_limits<std::uint32_t>::max())
    return R::failure(ErrorKind::invalid_input, printable(path.string(), 200) + ": " + std::to_string(t.size()) +
                                                    " static objects after " + std::to_string(moving_count) +
                                                    " moving ones: more than 32-bit indices number");
  return table;
}

void set_frame_objects(FrameInput& input, const ObjectTable& objects) {
  input.spheres = {};
  input.boxes = {};
  if (objects.kind == ShapeKind::box) {
    input.boxes = objects.boxes.boxes;
    input.filters = objects.boxes.filters;
    input.always_active = objects.boxes.always_active;
  } else {
    input.spheres = objects.spheres.spheres;
    input.filters = objects.spheres.filters;
    input.always_active = objects.spheres.always_active;
  }
}

Status set_static_objects(Detector& detector, const ObjectTable& objects) {
  if (objects.kind == ShapeKind::box) return detector.set_static_boxes(objects.boxes.boxes, objects.boxes.filters);
  return detector.set_static_spheres(objects.spheres.spheres, objects.spheres.filters);
}

Status detect_with_static(DetectorChoice& choice, const DetectorRequest& request, const Config& config,
                          const ObjectTable& fixed, const FrameInput& input, FrameResult& frame) {
  for (;;) {  // once, or twice when auto's gl refuses the input and cpu takes over
    Detector& det = *choice.detector;
    if (Status s = set_static_objects(det, fixed); !s) return Status::failure(s.kind(), "--static: " + s.error());
    const Status s = det.detect(input, frame);
    if (s || !fall_back_from_auto_gl(choice, request, config, s)) return s;
  }
}

Status set_static_field(Detector& detector, std::span<const Sphere> field, ShapeKind shape) {
  if (shape == ShapeKind::sphere) return detector.set_static_spheres(field);
  std::vector<Box> cubes;
  cubes_of(field, cubes);
  return detector.set_static_boxes(cubes);
}

void number_pairs(std::span<Pair> pairs, std::uint32_t n) {
  for (Pair& p : pairs) p.j = output_index(p.j, n);  // i is moving: a pair of two static objects never comes
}

}  // namespace viscd::app
