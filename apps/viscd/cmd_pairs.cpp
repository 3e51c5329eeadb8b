// `viscd pairs`: one frame from files.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <cctype>
#include <cinttypes>
#include <optional>

#include "commands.hpp"
#include "detector_choice.hpp"
#include "exit_codes.hpp"
#include "input_files.hpp"
#include "mpi_session.hpp"
#include "options.hpp"
#include "outputs.hpp"
#include "pairs_mpi.hpp"
#include "static_objects.hpp"
#include "viscd/io.hpp"

namespace viscd::app {
namespace {

struct PairsArgs {
  std::string spheres, boxes, static_objects, camera, id_map, out = "pairs.csv", stats, validate_hash;
  PipelineOptions pipeline;
};

int run_pairs(const PairsArgs& a) {
  auto config = make_config(a.pipeline);
  if (!config) return usage_fail(config.error());
  if (!a.validate_hash.empty()) {
    const bool hex16 = a.validate_hash.size() == 16 &&
                       std::all_of(a.validate_hash.begin(), a.validate_hash.end(),
                                   [](char ch) { return std::isxdigit(static_cast<unsigned char>(ch)) != 0; });
    if (!hex16) return usage_fail("--validate-hash: expected 16 hex digits, got '" + printable(a.validate_hash) + "'");
  }
  if (!a.id_map.empty() && a.pipeline.map_size.empty())
    return usage_fail("--id-map needs --map-size WxH, the size of the map in pixels");
  if (a.spheres.empty() == a.boxes.empty()) return usage_fail("give one of --spheres and --boxes");
  const bool boxes = !a.boxes.empty();
  const char* moving_option = boxes ? "--boxes" : "--spheres";
  // Refuse before anything is read or written.
  std::vector<NamedPath> inputs = {{moving_option, boxes ? a.boxes : a.spheres}}, outputs = {{"--out", a.out}};
  if (!a.static_objects.empty()) inputs.push_back({"--static", a.static_objects});
  if (!a.camera.empty()) inputs.push_back({"--camera", a.camera});
  if (!a.id_map.empty()) inputs.push_back({"--id-map", a.id_map});
  if (!a.stats.empty()) outputs.push_back({"--stats", a.stats});
  if (Status s = check_outputs(inputs, outputs); !s) return usage_fail(s.error());
  if (MpiSession::active()) {  // under mpirun: the ranks share the objects (docs/mpi.md)
    if (!a.camera.empty() || !a.id_map.empty())
      return usage_fail("under mpirun culling is off (docs/mpi.md, \"Limits\"): --camera and --id-map are not taken");
    auto request = detector_request(a.pipeline);
    if (!request) return usage_fail(request.error());
#ifdef VISCD_HAVE_MPI
    return run_pairs_across_ranks(
        {a.spheres, a.boxes, a.static_objects, a.out, a.stats, a.validate_hash, config.value(), request.value()});
#endif
  }

  auto table = read_moving_objects(a.spheres, a.boxes);
  if (!table) return fail(table.error());
  const ShapeKind kind = table.value().kind;
  const auto n = static_cast<std::uint32_t>(table.value().size());
  ObjectTable fixed;  // the static set; empty without --static
  if (!a.static_objects.empty()) {
    auto s = read_static_objects(a.static_objects, kind, moving_option, n);
    if (!s) return fail(s.error());
    fixed = std::move(s.value());
  }
  auto read = read_optional_camera(a.camera);
  if (!read) return fail(read.error());
  const std::optional<Camera>& camera = read.value();
  std::vector<std::uint32_t> ids;
  if (!a.id_map.empty()) {
    auto m = read_id_map(a.id_map, config.value().map_width, config.value().map_height);
    if (!m) return fail(m.error());
    ids = std::move(m.value());
  }
  auto request = detector_request(a.pipeline);
  if (!request) return usage_fail(request.error());
  auto chosen = make_tool_detector(request.value(), config.value());
  if (!chosen) return fail(chosen.error());
  FrameInput input;
  set_frame_objects(input, table.value());
  input.camera = camera ? &*camera : nullptr;
  if (!a.id_map.empty()) {
    input.id_map = ids;
    input.id_map_width = config.value().map_width;
    input.id_map_height = config.value().map_height;
  }
  FrameResult frame;
  if (Status s = detect_with_static(chosen.value(), request.value(), config.value(), fixed, input, frame); !s)
    return fail(s.error());
  Detector& det = *chosen.value().detector;
  det.wait_for_stage_times(frame.stats);  // one frame: its GPU times are wanted now
  number_pairs(frame.pairs, n);           // static object k is N + k

  // Both outputs are written in full to temporary files first and renamed into place only when
  // both succeeded: a failure leaves the previous files as they were and no partial output.
  auto pairs_file = AtomicFile::create(a.out);
  if (!pairs_file) return fail(pairs_file.error());
  if (Status s = write_pairs_csv(pairs_file.value(), frame.pairs); !s) return fail(s.error());
  std::optional<AtomicFile> stats_file;
  if (!a.stats.empty()) {
    auto f = AtomicFile::create(a.stats);
    if (!f) return fail(f.error());
    stats_file.emplace(std::move(f.value()));
    if (Status s = stats_file->write(stats_json(frame.stats, det.name())); !s) return fail(s.error());
  }
  if (Status s = pairs_file.value().commit(); !s) return fail(s.error());
  if (stats_file)
    if (Status s = stats_file->commit(); !s) return fail(s.error());

  const std::uint64_t hash = pairs_hash(frame.pairs);
  const std::string fixed_count =
      fixed.size() == 0 ? std::string() : " + " + std::to_string(frame.stats.static_objects) + " static";
  std::printf("%u objects%s, %u active, %" PRIu64 " pairs, m = %d (%s), hash %016" PRIx64 "\n", frame.stats.objects,
              fixed_count.c_str(), frame.stats.active, frame.stats.pairs, frame.stats.bits,
              format_layout(frame.stats.layout).c_str(), hash);
  std::printf("wrote %s%s%s\n", printable(a.out, 200).c_str(), a.stats.empty() ? "" : " and ",
              printable(a.stats, 200).c_str());
  if (!a.validate_hash.empty()) return check_pairs_hash(a.validate_hash, hash);
  return kExitOk;
}

}  // namespace

int check_pairs_hash(const std::string& validate_hash, std::uint64_t hash) {
  char expected[32];
  std::snprintf(expected, sizeof expected, "%016" PRIx64, hash);
  std::string given = validate_hash;
  for (char& ch : given) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
  if (given != expected) {
    std::fprintf(stderr, "viscd: hash mismatch: expected %s, got %s\n", given.c_str(), expected);
    return kExitHashMismatch;
  }
  std::printf("hash matches\n");
  return kExitOk;
}

void add_pairs_command(CLI::App& app, int& rc) {
  auto args = std::make_shared<PairsArgs>();
  CLI::App* cmd = app.add_subcommand(
      "pairs",
      "One frame from files: read spheres or boxes (and optionally a camera for culling, and a static\n"
      "set), write the colliding pairs as CSV (header i,j; 0-based; sorted; i < j) and the frame's\n"
      "stats as JSON. Without --camera (and without --id-map) every object is active and adaptive\n"
      "bits use 32. A CSV with group and mask columns filters pairs: i and j pair only when\n"
      "(group_i & mask_j) != 0 and (group_j & mask_i) != 0. A CSV with an always_active column\n"
      "(0 or 1) keeps the objects marked 1 active whatever their pixels. With --static, the N\n"
      "moving objects are numbered 0..N-1 and static object k is N + k. Outputs are written whole\n"
      "or not at all, and never over an input.");
  cmd->footer(
      "\nExamples:\n"
      "  viscd pairs --spheres scene.csv --out pairs.csv\n"
      "  viscd pairs --spheres scene.xyzr --out pairs.csv --stats stats.json\n"
      "  viscd pairs --spheres scene.csv --camera cam.json --lambda 50\n"
      "  viscd pairs --spheres scene.csv --id-map ids.u32 --map-size 1280x720   # your own visibility map\n"
      "  viscd pairs --boxes crates.csv --static walls.csv --camera cam.json\n"
      "\nDocs: docs/usage.md");
  cmd->add_option("--spheres", args->spheres,
                  "sphere file: XYZR text (x y z r per line, # comments) or .csv with header x,y,z,r,\n"
                  "optionally followed by group,mask and then always_active (group, mask: unsigned 32-bit,\n"
                  "decimal or 0x hex; default 1 and 0xFFFFFFFF when the columns are absent; always_active:\n"
                  "0 or 1, never culled when 1). Give --spheres or --boxes");
  cmd->add_option("--boxes", args->boxes,
                  "box file instead of --spheres: CSV (whatever its extension) with the header\n"
                  "minx,miny,minz,maxx,maxy,maxz, optionally followed by group,mask and then always_active\n"
                  "as for spheres; one axis-aligned box per line, min <= max on every axis (touching boxes\n"
                  "pair). Example line: 0,0,0,1,2,1 (a 1 x 2 x 1 box with a corner at the origin)");
  cmd->add_option("--static", args->static_objects,
                  "the detector's static set: objects that do not move (walls, terrain), in a file of the\n"
                  "same kind and format as the moving ones (spheres with --spheres, boxes with --boxes;\n"
                  "group,mask columns filter them too). Static objects are never culled, hide what is\n"
                  "behind them in the visibility map and never pair with each other. With N moving\n"
                  "objects, static object k (the file's k-th object, from 0) is numbered N + k in the pairs");
  cmd->add_option("--camera", args->camera,
                  "camera JSON {eye, target, up, fov_y_deg, near, far, width, height}: enables culling");
  cmd->add_option("--id-map", args->id_map,
                  "your own visibility map instead of viscd's: raw little-endian uint32 ids, row-major from\n"
                  "the top-left pixel, 0 = background, object index + 1 elsewhere (static objects: 0); its\n"
                  "size is --map-size WxH (the file must be W*H*4 bytes). Culls by its pixel counts (scaled\n"
                  "to --camera's screen when given, else map pixels) against --lambda");
  cmd->add_option("--out", args->out, "pairs CSV to write")->capture_default_str();
  cmd->add_option("--stats", args->stats,
                  "stats JSON to write (N, static objects, active, mu, m, layout, pairs, per-stage ms)");
  cmd->add_option("--validate-hash", args->validate_hash,
                  "expected FNV-1a hash of the pairs (16 hex digits); exit 3 if different");
  add_pipeline_options(*cmd, args->pipeline, false);
  add_cpu_kernel_options(*cmd, args->pipeline);
  cmd->callback([args, &rc] { rc = run_pairs(*args); });
}

}  // namespace viscd::app
