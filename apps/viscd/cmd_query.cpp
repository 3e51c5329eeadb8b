// `viscd query`: one frame from files, then a ray or overlap query on it.
#include <CLI/CLI.hpp>
#include <cstdio>
#include <limits>
#include <optional>

#include "commands.hpp"
#include "detector_choice.hpp"
#include "exit_codes.hpp"
#include "input_files.hpp"
#include "options.hpp"
#include "outputs.hpp"
#include "static_objects.hpp"
#include "viscd/io.hpp"

namespace viscd::app {
namespace {

struct QueryArgs {
  std::string spheres, boxes, static_objects, camera, ray, overlap, overlap_box, out;
  float max_t = std::numeric_limits<float>::infinity();
  bool all = false;
  PipelineOptions pipeline;
};

int run_query(const QueryArgs& a) {
  auto config = make_config(a.pipeline);
  if (!config) return usage_fail(config.error());
  if (int{!a.ray.empty()} + int{!a.overlap.empty()} + int{!a.overlap_box.empty()} != 1)
    return usage_fail("give one of --ray and --overlap (or --overlap-box)");
  if (a.spheres.empty() == a.boxes.empty()) return usage_fail("give one of --spheres and --boxes");
  if (a.all && a.ray.empty()) return usage_fail("--all goes with --ray");
  if (!(a.max_t >= 0)) return usage_fail("--max-t: expected a number >= 0");
  Ray ray;
  Sphere probe;
  Box probe_box;
  if (!a.ray.empty()) {
    auto v = parse_numbers(a.ray, 6, "--ray", "ox,oy,oz,dx,dy,dz");
    if (!v) return usage_fail(v.error());
    const std::vector<float>& r = v.value();
    for (int k = 0; k < 3; ++k) ray.origin[k] = r[k], ray.dir[k] = r[3 + k];
    ray.max_t = a.max_t;
    if (r[3] == 0 && r[4] == 0 && r[5] == 0) return usage_fail("--ray: the direction dx,dy,dz must not be zero");
  } else if (!a.overlap_box.empty()) {
    auto v = parse_numbers(a.overlap_box, 6, "--overlap-box", "minx,miny,minz,maxx,maxy,maxz");
    if (!v) return usage_fail(v.error());
    for (int k = 0; k < 3; ++k) probe_box.min[k] = v.value()[k], probe_box.max[k] = v.value()[3 + k];
    if (Status s = validate_boxes(std::span<const Box>(&probe_box, 1)); !s)
      return usage_fail("--overlap-box: " + s.error().substr(s.error().find(": ") + 2));
  } else {
    auto v = parse_numbers(a.overlap, 4, "--overlap", "x,y,z,r");
    if (!v) return usage_fail(v.error());
    probe = {v.value()[0], v.value()[1], v.value()[2], v.value()[3]};
    if (Status s = validate_spheres(std::span<const Sphere>(&probe, 1)); !s)
      return usage_fail("--overlap: " + s.error().substr(s.error().find(": ") + 2));
  }
  const char* moving_option = a.boxes.empty() ? "--spheres" : "--boxes";
  std::vector<NamedPath> inputs = {{moving_option, a.boxes.empty() ? a.spheres : a.boxes}};
  if (!a.static_objects.empty()) inputs.push_back({"--static", a.static_objects});
  if (!a.camera.empty()) inputs.push_back({"--camera", a.camera});
  if (!a.out.empty())
    if (Status s = check_outputs(inputs, {{"--out", a.out}}); !s) return usage_fail(s.error());

  // Queries see the frame's active objects; the file's filters do not apply to them.
  auto table = read_moving_objects(a.spheres, a.boxes);
  if (!table) return fail(table.error());
  const auto n = static_cast<std::uint32_t>(table.value().size());
  ObjectTable fixed;  // the static set; empty without --static
  if (!a.static_objects.empty()) {
    auto s = read_static_objects(a.static_objects, table.value().kind, moving_option, n);
    if (!s) return fail(s.error());
    fixed = std::move(s.value());
  }
  auto read = read_optional_camera(a.camera);
  if (!read) return fail(read.error());
  const std::optional<Camera>& camera = read.value();
  auto request = detector_request(a.pipeline);
  if (!request) return usage_fail(request.error());
  auto chosen = make_tool_detector(request.value(), config.value());
  if (!chosen) return fail(chosen.error());
  FrameResult frame;
  FrameInput input;
  set_frame_objects(input, table.value());
  input.filters = {};  // the file's filters do not apply to queries; always_active does
  input.camera = camera ? &*camera : nullptr;
  if (Status s = detect_with_static(chosen.value(), request.value(), config.value(), fixed, input, frame); !s)
    return fail(s.error());
  Detector& det = *chosen.value().detector;

  std::string text;
  char line[64];
  if (!a.ray.empty()) {
    text = "i,t\n";
    std::vector<RayHit> hits;
    if (a.all) {
      det.ray_cast_all(ray, hits);
    } else if (RayHit h{}; det.ray_cast(ray, h)) {
      hits.push_back(h);
    }
    for (const RayHit& h : hits) {
      std::snprintf(line, sizeof line, "%u,%.9g\n", output_index(h.index, n), static_cast<double>(h.t));
      text += line;
    }
  } else {
    text = "i\n";
    std::vector<std::uint32_t> found;
    if (a.overlap_box.empty())
      det.overlap(probe, found);
    else
      det.overlap_box(probe_box, found);
    for (const std::uint32_t i : found) text += std::to_string(output_index(i, n)) + '\n';
  }
  if (a.out.empty()) {
    std::fputs(text.c_str(), stdout);
    return kExitOk;
  }
  if (Status s = write_text(a.out, text); !s) return fail(s.error());
  return kExitOk;
}

}  // namespace

void add_query_command(CLI::App& app, int& rc) {
  auto args = std::make_shared<QueryArgs>();
  CLI::App* cmd =
      app.add_subcommand("query",
                         "One frame from files, then a query on it: the objects (spheres or boxes) a ray hits, or the\n"
                         "objects that overlap a given sphere or box. Queries see the frame's active objects: with\n"
                         "--camera the culled ones are left out; group and mask columns of the object files do not\n"
                         "apply to queries. With --static the static set is seen too (never culled), static object k\n"
                         "printed as N + k after the N moving objects. Prints CSV to stdout (or --out): for --ray\n"
                         "`i,t` (object index, and the smallest t >= 0 at which origin + t * dir is inside or on the\n"
                         "object; 0 when the origin is inside), for --overlap and --overlap-box `i`.\n"
                         "Examples:\n"
                         "  viscd query --spheres scene.csv --ray 0,0,-50,0,0,1 --all\n"
                         "  viscd query --boxes crates.csv --static walls.csv --overlap-box 0,0,0,2,2,2");
  cmd->add_option("--spheres", args->spheres,
                  "sphere file: XYZR text or .csv with header x,y,z,r (group,mask columns allowed); give\n"
                  "--spheres or --boxes");
  cmd->add_option("--boxes", args->boxes,
                  "box file instead of --spheres: CSV with header minx,miny,minz,maxx,maxy,maxz (group,mask\n"
                  "and always_active columns allowed, as in viscd pairs)");
  cmd->add_option("--static", args->static_objects,
                  "the detector's static set, a file of the same kind as the moving objects (as in viscd\n"
                  "pairs); static object k is printed as N + k");
  cmd->add_option("--camera", args->camera, "camera JSON: culls objects below --lambda pixels first");
  cmd->add_option("--ray", args->ray,
                  "ox,oy,oz,dx,dy,dz: the ray origin + t * dir for t >= 0 (dir need not be unit length; t\n"
                  "counts in lengths of dir); prints the first hit (smallest t, ties to the smaller index)");
  cmd->add_flag("--all", args->all, "with --ray: every hit, sorted by t, then index");
  cmd->add_option("--max-t", args->max_t, "with --ray: only hits with t <= this")->capture_default_str();
  cmd->add_option("--overlap", args->overlap,
                  "x,y,z,r: the objects that overlap this sphere (touching counts; r = 0 is a point),\n"
                  "ascending");
  cmd->add_option("--overlap-box", args->overlap_box,
                  "minx,miny,minz,maxx,maxy,maxz: the objects that overlap this box (touching counts; min\n"
                  "<= max on every axis; min = max is a point), ascending");
  cmd->add_option("--out", args->out, "CSV file to write instead of stdout (whole or not at all)");
  add_pipeline_options(*cmd, args->pipeline, false);
  cmd->callback([args, &rc] { rc = run_query(*args); });
}

}  // namespace viscd::app
