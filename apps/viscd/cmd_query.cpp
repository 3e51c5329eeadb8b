// `viscd query`: one frame from files, then a ray or overlap query on it.
#include <cstdio>
#include <limits>
#include <optional>

#include "commands.hpp"
#include "detector_choice.hpp"
#include "exit_codes.hpp"
#include "input_files.hpp"
#include "options.hpp"
#include "outputs.hpp"
#include "viscd/io.hpp"

namespace viscd::app {
namespace {

struct QueryArgs {
  std::string spheres, camera, ray, overlap, out;
  float max_t = std::numeric_limits<float>::infinity();
  bool all = false;
  PipelineOptions pipeline;
};

int run_query(const QueryArgs& a) {
  auto config = make_config(a.pipeline);
  if (!config) return usage_fail(config.error());
  if (a.ray.empty() == a.overlap.empty()) return usage_fail("give one of --ray and --overlap");
  if (a.all && a.ray.empty()) return usage_fail("--all goes with --ray");
  if (!(a.max_t >= 0)) return usage_fail("--max-t: expected a number >= 0");
  Ray ray;
  Sphere probe;
  if (!a.ray.empty()) {
    auto v = parse_numbers(a.ray, 6, "--ray", "ox,oy,oz,dx,dy,dz");
    if (!v) return usage_fail(v.error());
    const std::vector<float>& r = v.value();
    for (int k = 0; k < 3; ++k) ray.origin[k] = r[k], ray.dir[k] = r[3 + k];
    ray.max_t = a.max_t;
    if (r[3] == 0 && r[4] == 0 && r[5] == 0) return usage_fail("--ray: the direction dx,dy,dz must not be zero");
  } else {
    auto v = parse_numbers(a.overlap, 4, "--overlap", "x,y,z,r");
    if (!v) return usage_fail(v.error());
    probe = {v.value()[0], v.value()[1], v.value()[2], v.value()[3]};
    if (Status s = validate_spheres(std::span<const Sphere>(&probe, 1)); !s)
      return usage_fail("--overlap: " + s.error().substr(s.error().find(": ") + 2));
  }
  std::vector<NamedPath> inputs = {{"--spheres", a.spheres}};
  if (!a.camera.empty()) inputs.push_back({"--camera", a.camera});
  if (!a.out.empty())
    if (Status s = check_outputs(inputs, {{"--out", a.out}}); !s) return usage_fail(s.error());

  // Queries see the frame's active objects; the file's filters do not apply to them.
  auto table = read_sphere_table(a.spheres);
  if (!table) return fail(table.error());
  auto read = read_optional_camera(a.camera);
  if (!read) return fail(read.error());
  const std::optional<Camera>& camera = read.value();
  auto request = detector_request(a.pipeline);
  if (!request) return usage_fail(request.error());
  auto chosen = make_tool_detector(request.value(), config.value());
  if (!chosen) return fail(chosen.error());
  Detector& det = *chosen.value().detector;
  FrameResult frame;
  FrameInput input;
  input.spheres = table.value().spheres;
  input.camera = camera ? &*camera : nullptr;
  input.always_active = table.value().always_active;  // objects marked 1 are never culled
  if (Status s = det.detect(input, frame); !s) return fail(s.error());

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
      std::snprintf(line, sizeof line, "%u,%.9g\n", h.index, static_cast<double>(h.t));
      text += line;
    }
  } else {
    text = "i\n";
    std::vector<std::uint32_t> found;
    det.overlap(probe, found);
    for (const std::uint32_t i : found) text += std::to_string(i) + '\n';
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
  CLI::App* cmd = app.add_subcommand(
      "query",
      "One frame from files, then a query on it: the spheres a ray hits, or the spheres that overlap\n"
      "a given sphere. Queries see the frame's active objects: with --camera the culled ones are left\n"
      "out; group and mask columns of the sphere file do not apply to queries. Prints CSV to stdout\n"
      "(or --out): for --ray `i,t` (object index, and the smallest t >= 0 at which origin + t * dir\n"
      "is inside or on the sphere; 0 when the origin is inside), for --overlap `i`.");
  cmd->add_option("--spheres", args->spheres,
                  "sphere file: XYZR text or .csv with header x,y,z,r (group,mask columns allowed)")
      ->required();
  cmd->add_option("--camera", args->camera, "camera JSON: culls objects below --lambda pixels first");
  cmd->add_option("--ray", args->ray,
                  "ox,oy,oz,dx,dy,dz: the ray origin + t * dir for t >= 0 (dir need not be unit length; t\n"
                  "counts in lengths of dir); prints the first hit (smallest t, ties to the smaller index)");
  cmd->add_flag("--all", args->all, "with --ray: every hit, sorted by t, then index");
  cmd->add_option("--max-t", args->max_t, "with --ray: only hits with t <= this")->capture_default_str();
  cmd->add_option("--overlap", args->overlap,
                  "x,y,z,r: the objects whose spheres overlap this one (touching counts; r = 0 is a point),\n"
                  "ascending");
  cmd->add_option("--out", args->out, "CSV file to write instead of stdout (whole or not at all)");
  add_pipeline_options(*cmd, args->pipeline, false);
  cmd->callback([args, &rc] { rc = run_query(*args); });
}

}  // namespace viscd::app
