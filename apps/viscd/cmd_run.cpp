// `viscd run`: the demo. Simulates the paper's scene headless and reports per-stage times.
#include <CLI/CLI.hpp>
#include <chrono>
#include <cinttypes>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>
#include <string>

#include "commands.hpp"
#include "detector_choice.hpp"
#include "exit_codes.hpp"
#include "options.hpp"
#include "outputs.hpp"
#include "progress.hpp"
#include "static_objects.hpp"
#include "statistics.hpp"
#include "viscd/io.hpp"
#include "viscd/scene.hpp"

namespace viscd::app {
namespace {

// A "Key:   123 kB" line of /proc/self/status, in bytes; nothing where there is no such file.
std::optional<std::uint64_t> proc_status_bytes(const std::string& key) {
  std::ifstream in("/proc/self/status");
  for (std::string line; std::getline(in, line);)
    if (line.rfind(key, 0) == 0) {
      std::istringstream fields(line.substr(key.size()));
      std::uint64_t kb = 0;
      if (fields >> kb) return kb * 1024;
    }
  return std::nullopt;
}

// Resets the kernel's high-water mark of this process's resident set (VmHWM) to its present size.
bool reset_peak_rss() {
  std::ofstream out("/proc/self/clear_refs");
  out << "5";
  out.flush();
  return static_cast<bool>(out);
}

struct RunArgs {
  PipelineOptions pipeline;
  SceneOptions world;
  ObjectOptions objects;
  int frames = 300;
  std::string camera = "zoom-out";
  std::string size = "1280x720";
  std::string out_dir = "viscd-out";
  std::string screenshot, csv, json, events, pairs_dir;
  bool quiet = false;
};

using Clock = std::chrono::steady_clock;

// Medians over the last kWindow frames: a run of any length keeps a fixed amount of memory.
constexpr std::size_t kWindow = 10000;
class RecentValues {
 public:
  void add(double v) {
    if (values_.size() < kWindow) {
      values_.push_back(v);
    } else {
      values_[next_] = v;
      next_ = (next_ + 1) % kWindow;
    }
  }
  [[nodiscard]] double median() const { return app::median(values_); }

 private:
  std::vector<double> values_;
  std::size_t next_ = 0;
};

int run_run(RunArgs a) {
  auto config = make_config(a.pipeline);
  if (!config) return usage_fail(config.error());
  auto params = make_scene_params(a.world);
  if (!params) return usage_fail(params.error());
  auto shape = parse_shape_kind(a.objects.shape);
  if (!shape) return usage_fail("--shape: " + shape.error());
  auto size = parse_size(a.size, "--size");
  if (!size) return usage_fail(size.error());
  if (config.value().map_width == 0)  // the map is the screen
    if (Status s = check_map_size(size.value().first, size.value().second, "--size"); !s) return usage_fail(s.error());
  const bool file_camera = a.camera.size() > 5 && a.camera.ends_with(".json");

  const std::filesystem::path out(a.out_dir);
  const std::filesystem::path shot =
      a.screenshot.empty() ? out / "screenshot.png" : std::filesystem::path(a.screenshot);
  const std::filesystem::path csv = a.csv.empty() ? out / "frames.csv" : std::filesystem::path(a.csv);
  const std::filesystem::path json = a.json.empty() ? out / "summary.json" : std::filesystem::path(a.json);
  std::vector<NamedPath> inputs;
  if (file_camera) inputs.push_back({"--camera", a.camera});
  std::vector<NamedPath> outputs = {{"--screenshot", shot}, {"--csv", csv}, {"--json", json}};
  if (!a.events.empty()) outputs.push_back({"--events", a.events});
  if (Status s = check_outputs(inputs, outputs); !s) return usage_fail(s.error());
  if (!a.pairs_dir.empty()) {
    std::vector<NamedPath> others = inputs;
    others.insert(others.end(), outputs.begin(), outputs.end());
    if (Status s = check_folder_output({"--pairs-dir", a.pairs_dir}, others); !s) return usage_fail(s.error());
  }
  if (!a.events.empty()) {  // the events need the detector to keep the last frame's pairs
    config.value().contact_events = true;
  }

  auto request = detector_request(a.pipeline);
  if (!request) return usage_fail(request.error());
  request.value().quiet = a.quiet;
  auto chosen = make_tool_detector(request.value(), config.value());
  if (!chosen) return fail(chosen.error());
  Detector* det = chosen.value().detector.get();  // cpu instead when auto's gl refuses the input

  Scene scene = Scene::make(params.value());
  // The static set is handed over once, before the frames (again to a cpu that takes over).
  const std::vector<Sphere> field = static_field(scene, a.objects.static_count);
  if (Status s = set_static_field(*det, field, shape.value()); !s) return fail("--static: " + s.error());
  std::vector<Box> cubes;  // --shape box: the scene's spheres as cubes, each frame
  Camera camera;
  if (file_camera) {
    auto c = read_camera(a.camera);
    if (!c) return fail(c.error());
    camera = c.value();
  }
  auto camera_now = [&]() -> Result<Camera> {
    if (file_camera) return camera;
    return camera_preset(a.camera, scene, size.value().first, size.value().second);
  };
  if (auto c = camera_now(); !c) return usage_fail(c.error());

  if (!a.quiet)
    std::printf("viscd run: %s backend, %u %s (%s scene, seed %" PRIu64 ")%s, %dx%d, camera %s, %d frames\n",
                std::string(det->name()).c_str(), a.world.objects,
                shape.value() == ShapeKind::box ? "boxes" : "objects", a.world.kind.c_str(), a.world.seed,
                field.empty() ? "" : (" + " + std::to_string(field.size()) + " static").c_str(),
                camera_now().value().width, camera_now().value().height, printable(a.camera, 200).c_str(), a.frames);

  // The per-frame CSV streams into its temporary file as the run goes (renamed at the end).
  auto csv_file = AtomicFile::create(csv);
  if (!csv_file) return fail(csv_file.error());
  // So do the events; the pairs files go into a folder that replaces --pairs-dir at the end.
  std::optional<AtomicFile> events_file;
  std::string events_rows;
  if (!a.events.empty()) {
    auto f = AtomicFile::create(a.events);
    if (!f) return fail(f.error());
    events_file.emplace(std::move(f.value()));
    events_rows = "frame,i,j,event\n";
  }
  std::optional<StagedFolder> pairs_dir;
  std::size_t pairs_digits = 6;  // frame_000000.csv: names sort in frame order
  if (!a.pairs_dir.empty()) {
    auto d = StagedFolder::create(a.pairs_dir, "--pairs-dir", "frame_", ".csv");
    if (!d) return usage_fail(d.error());
    pairs_dir.emplace(std::move(d.value()));
    for (int f = a.frames - 1; f >= 1000000; f /= 10) ++pairs_digits;
  }
  std::ostringstream rows;
  rows << "frame,time_s,objects,static_objects,active,mean_pixels,bits,layout,pairs,simulate_ms";
  for (std::size_t s = 0; s < kStageCount; ++s) rows << ',' << stage_name(static_cast<Stage>(s)) << "_ms";
  rows << ",frame_ms\n";

  RecentValues sim_ms, frame_ms;
  std::array<RecentValues, kStageCount> stage_ms;
  FrameResult frame;
  // The memory the frames add to the scene's: the peak resident set during the frames (the
  // kernel's high-water mark, reset here) above the resident set now.
  const bool peak_reset = reset_peak_rss();
  const std::optional<std::uint64_t> rss_before = proc_status_bytes("VmRSS:");
  std::optional<std::uint64_t> rss_peak;
  Progress progress("frames", static_cast<std::size_t>(a.frames), a.quiet);
  for (int f = 0; f < a.frames; ++f) {
    const bool last = f == a.frames - 1;
    // The last frame also renders and shades the screenshot: the peak is taken before it.
    if (last && f > 0 && peak_reset) rss_peak = proc_status_bytes("VmHWM:");
    if (last) {  // shade only the screenshot frame
      Config c = det->config();
      c.shade = true;
      det->set_config(c);
    }
    const auto t0 = Clock::now();
    scene.step(a.world.dt);
    FrameInput input;
    if (shape.value() == ShapeKind::box) {
      cubes_of(scene.spheres(), cubes);
      input.boxes = cubes;
    } else {
      input.spheres = scene.spheres();
    }
    const double sim = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
    const Camera cam = camera_now().value();
    input.camera = &cam;
    Status detected = det->detect(input, frame);
    if (!detected && f == 0 && fall_back_from_auto_gl(chosen.value(), request.value(), config.value(), detected)) {
      det = chosen.value().detector.get();
      if (last) {
        Config c = det->config();
        c.shade = true;
        det->set_config(c);
      }
      if (Status s = set_static_field(*det, field, shape.value()); !s) {
        progress.finish();
        return fail("--static: " + s.error());
      }
      detected = det->detect(input, frame);
    }
    if (!detected) {
      progress.finish();
      return fail("frame " + std::to_string(f) + ": " + detected.error());
    }
    if (!field.empty()) {  // the outputs number static object k as N + k
      for (std::vector<Pair>* list : {&frame.pairs, &frame.began, &frame.ended}) number_pairs(*list, a.world.objects);
    }
    if (events_file) {
      // Sorted by frame, then begin before end, then (i, j): began and ended are sorted.
      for (const auto& [list, kind] : {std::pair{&frame.began, ",begin\n"}, std::pair{&frame.ended, ",end\n"}})
        for (const Pair& p : *list)
          events_rows += std::to_string(f) + ',' + std::to_string(p.i) + ',' + std::to_string(p.j) + kind;
      if (events_rows.size() > (1 << 20) || last) {
        if (Status s = events_file->write(events_rows); !s) {
          progress.finish();
          return fail(s.error());
        }
        events_rows.clear();
      }
    }
    if (pairs_dir) {
      const std::string number = std::to_string(f);
      const std::string name =
          "frame_" + std::string(pairs_digits - std::min(pairs_digits, number.size()), '0') + number + ".csv";
      if (Status s = write_pairs_csv(pairs_dir->file(name), frame.pairs); !s) {
        progress.finish();
        return fail(s.error());
      }
    }
    const FrameStats& st = frame.stats;
    double total = sim;
    for (std::size_t s = 0; s < kStageCount; ++s) {
      if (static_cast<Stage>(s) == Stage::shade && !last) continue;
      if (static_cast<Stage>(s) != Stage::shade) stage_ms[s].add(st.stage_ms[s]);
      if (static_cast<Stage>(s) != Stage::shade) total += st.stage_ms[s];
    }
    sim_ms.add(sim);
    frame_ms.add(total);
    rows << f << ',' << scene.time() << ',' << st.objects << ',' << st.static_objects << ',' << st.active << ','
         << st.mean_pixels << ',' << st.bits << ',' << format_layout(st.layout) << ',' << st.pairs << ',' << sim;
    for (std::size_t s = 0; s < kStageCount; ++s) rows << ',' << st.stage_ms[s];
    rows << ',' << total << '\n';
    if (rows.tellp() > (1 << 16) || last) {
      if (Status s = csv_file.value().write(rows.str()); !s) {
        progress.finish();
        return fail(s.error());
      }
      rows.str({});
    }
    char note[64];
    std::snprintf(note, sizeof note, "%.2f ms/frame", total);
    progress.update(static_cast<std::size_t>(f + 1), note);
  }
  progress.finish();

  det->wait_for_stage_times(frame.stats);  // the screenshot frame's GPU times (shading), now
  const FrameStats& st = frame.stats;
  const double med_frame = frame_ms.median(), med_sim = sim_ms.median();
  std::array<double, kStageCount> med_stage{};  // shading ran on the last frame only: not a median
  for (std::size_t s = 0; s < kStageCount; ++s)
    if (static_cast<Stage>(s) != Stage::shade) med_stage[s] = stage_ms[s].median();
  nlohmann::ordered_json summary;
  summary["backend"] = det->name();
  summary["objects"] = a.world.objects;
  summary["shape"] = shape_kind_name(shape.value());
  summary["static_objects"] = field.size();
  summary["frames"] = a.frames;
  summary["camera"] = a.camera;
  summary["culling"] = !a.pipeline.no_culling;
  summary["median_over_frames"] = std::min<std::size_t>(static_cast<std::size_t>(a.frames), kWindow);
  summary["median_ms"]["simulate"] = med_sim;
  for (std::size_t s = 0; s < kStageCount; ++s)
    if (static_cast<Stage>(s) != Stage::shade)
      summary["median_ms"][std::string(stage_name(static_cast<Stage>(s)))] = med_stage[s];
  summary["median_frame_ms"] = med_frame;
  summary["fps"] = med_frame > 0 ? 1000.0 / med_frame : 0.0;
  summary["last_frame"] = nlohmann::ordered_json::parse(stats_json(st, det->name()));
  if (peak_reset && a.frames == 1) rss_peak = proc_status_bytes("VmHWM:");
  const std::uint64_t tally = det->memory_bytes();
  const bool have_rss = rss_before && rss_peak;
  const std::uint64_t added = have_rss && *rss_peak > *rss_before ? *rss_peak - *rss_before : 0;
  const double added_per_object =
      a.world.objects ? static_cast<double>(added) / static_cast<double>(a.world.objects) : 0.0;
  summary["memory"]["detector_bytes"] = tally;
  if (have_rss) {
    summary["memory"]["rss_before_frames_bytes"] = *rss_before;
    summary["memory"]["peak_rss_bytes"] = *rss_peak;
    summary["memory"]["added_bytes_per_object"] = added_per_object;
  }

  if (!a.quiet) {
    std::printf("\n  %-12s %10s\n", "stage", "median ms");
    std::printf("  %-12s %10.3f\n", "simulate", med_sim);
    for (std::size_t s = 0; s < kStageCount; ++s) {
      if (static_cast<Stage>(s) == Stage::shade) continue;
      std::printf("  %-12s %10.3f\n", std::string(stage_name(static_cast<Stage>(s))).c_str(), med_stage[s]);
    }
    std::printf("  %-12s %10.3f   (%.0f frames per second)\n", "frame", med_frame,
                med_frame > 0 ? 1000.0 / med_frame : 0.0);
    std::printf("  (shading ran on the screenshot frame only: %.3f ms)\n\n", st.ms(Stage::shade));
    if (have_rss) {
      std::printf(
          "memory: peak resident %.1f MB during the frames%s, %.1f MB above the %.1f MB before them (%.0f "
          "bytes per object); the detector's buffers %.1f MB\n",
          static_cast<double>(*rss_peak) / 1e6, a.frames > 1 ? " before the screenshot's" : "",
          static_cast<double>(added) / 1e6, static_cast<double>(*rss_before) / 1e6, added_per_object,
          static_cast<double>(tally) / 1e6);
    } else {
      std::printf("memory: the detector's buffers %.1f MB\n", static_cast<double>(tally) / 1e6);
    }
    std::printf("last frame: %u of %u objects active (%.1f %%)%s, mu = %.1f px, m = %d bits %s, %" PRIu64 " pairs\n",
                st.active, st.objects, st.objects ? 100.0 * st.active / st.objects : 0.0,
                field.empty() ? "" : (", " + std::to_string(st.static_objects) + " static").c_str(), st.mean_pixels,
                st.bits, format_layout(st.layout).c_str(), st.pairs);
  }
  // All three are written to temporary files first and renamed into place only when all succeeded.
  auto shot_file = AtomicFile::create(shot);
  if (!shot_file) return fail(shot_file.error());
  if (Status s = write_png(shot_file.value(), frame.image, frame.image_width, frame.image_height); !s)
    return fail(s.error());
  auto json_file = AtomicFile::create(json);
  if (!json_file) return fail(json_file.error());
  if (Status s = json_file.value().write(summary.dump(2) + "\n"); !s) return fail(s.error());
  for (AtomicFile* f : {&shot_file.value(), &csv_file.value(), &json_file.value()})
    if (Status s = f->commit(); !s) return fail(s.error());
  if (events_file)
    if (Status s = events_file->commit(); !s) return fail(s.error());
  if (pairs_dir)
    if (Status s = pairs_dir->commit(); !s) return fail(s.error());
  if (!a.quiet)
    std::printf("wrote %s, %s, %s\n", printable(shot.string(), 200).c_str(), printable(csv.string(), 200).c_str(),
                printable(json.string(), 200).c_str());
  return kExitOk;
}

}  // namespace

void add_run_command(CLI::App& app, int& rc) {
  auto args = std::make_shared<RunArgs>();
  args->pipeline.backend = "auto";
  CLI::App* cmd = app.add_subcommand(
      "run",
      "The demo, headless: simulate the paper's scene (objects circling the vertical axis, each at its\n"
      "own speed), and each frame build the visibility map, count pixels per object, cull objects\n"
      "below lambda, choose the Morton width from the mean pixel count and find every colliding pair\n"
      "among the rest. Prints per-stage median times and frames per second; writes a screenshot\n"
      "(red colliding, blue visible and free, yellow culled, grey static), a CSV of frames and a\n"
      "JSON summary. The objects are spheres, or their cubes with --shape box; --static K adds a\n"
      "field of static rocks and pillars under them.");
  add_scene_options(*cmd, args->world);
  add_object_options(*cmd, args->objects, ": in --events and --pairs-dir static object k is N + k");
  cmd->add_option("--frames", args->frames, "frames to simulate")
      ->check(CLI::Range(1, 1'000'000'000))
      ->capture_default_str();
  cmd->add_option("--camera", args->camera, "zoom-out | zoom-in | orbit | FILE.json")->capture_default_str();
  cmd->add_option("--size", args->size, "screen WxH for the preset cameras")->capture_default_str();
  cmd->add_option("--out", args->out_dir, "output folder for the screenshot, CSV and summary")->capture_default_str();
  cmd->add_option("--screenshot", args->screenshot, "screenshot PNG path (default OUT/screenshot.png)");
  cmd->add_option("--csv", args->csv, "per-frame CSV path (default OUT/frames.csv)");
  cmd->add_option("--json", args->json, "summary JSON path (default OUT/summary.json)");
  cmd->add_option("--events", args->events,
                  "contact events CSV to write: frame,i,j,event with event begin (the pair overlaps now and\n"
                  "did not in the frame before) or end (the other way round; also when an object is\n"
                  "culled); sorted by frame, then begin before end, then i, j. Frame 0's pairs all begin");
  cmd->add_option("--pairs-dir", args->pairs_dir,
                  "folder to write every frame's pairs into, as frame_000000.csv, frame_000001.csv, ...\n"
                  "(header i,j; the names sort in frame order). The folder is replaced as a whole at the\n"
                  "end; an existing one may hold only frame_*.csv files");
  cmd->add_flag("--quiet,-q", args->quiet, "print nothing but errors");
  add_pipeline_options(*cmd, args->pipeline, true);
  add_cpu_kernel_options(*cmd, args->pipeline);
  cmd->callback([args, &rc] { rc = run_run(*args); });
}

}  // namespace viscd::app
