#pragma once
// Shared pieces of the viscd subcommands: option parsing helpers, printing, progress.

#include <CLI/CLI.hpp>
#include <cstdio>
#include <string>
#include <string_view>
#include <vector>

#include "viscd/viscd.hpp"

namespace viscd::app {

/// Options every frame-running command shares.
struct PipelineOptions {
  std::string backend = "cpu";
  std::string bits = "adaptive";
  std::string layout = "extended";
  float lambda = 200, a = 100, b = 400;
  bool no_culling = false;
  std::string map_size;  // "WxH" or empty
  int threads = 0;
  std::string geometry = "impostor";  // gl only
  std::string counter = "ssbo";       // gl only
};

void add_pipeline_options(CLI::App& cmd, PipelineOptions& o, bool backend_auto);

/// The simulated scene's options, shared by `run` and `view`.
struct SceneOptions {
  std::uint32_t objects = 10000;
  std::string kind = "ring";
  std::uint64_t seed = 1;
  float dt = 1.0f / 60.0f;  // simulated seconds per frame
};
void add_scene_options(CLI::App& cmd, SceneOptions& o);
/// SceneParams from the options; the error names the bad option (--scene, --dt).
Result<SceneParams> make_scene_params(const SceneOptions& o);
/// The gl backend's options (--geometry, --counter); the error names the bad option.
Result<GlOptions> make_gl_options(const PipelineOptions& o);
/// Config from the options; the error names the bad option.
Result<Config> make_config(const PipelineOptions& o);
/// The detector the options name. "auto" picks gl on a hardware GPU and cpu where the only
/// OpenGL is a software renderer or there is none, and says which and why on stderr unless quiet.
Result<std::unique_ptr<Detector>> make_backend(const PipelineOptions& o, const Config& config, bool quiet);
/// Parses "1280x720".
Result<std::pair<int, int>> parse_size(std::string_view text, std::string_view option);

/// Prints "viscd: error: <msg>" to stderr and returns the exit code 1.
int fail(const std::string& message);

/// A progress bar on a terminal (stderr), plain lines every 10 % otherwise.
class Progress {
 public:
  Progress(std::string label, std::size_t total, bool quiet);
  void update(std::size_t done, const std::string& note);
  void finish();

 private:
  std::string label_;
  std::size_t total_;
  bool tty_, quiet_;
  int last_decile_ = -1;
};

/// Median of a copy of v (0 for empty).
double median(std::vector<double> v);

/// Each subcommand registers itself on the app; its callback stores the exit code in `rc`.
void add_pairs_command(CLI::App& app, int& rc);
void add_run_command(CLI::App& app, int& rc);
void add_bench_command(CLI::App& app, int& rc);
#ifdef VISCD_HAVE_VIEWER
void add_view_command(CLI::App& app, int& rc);
#endif

}  // namespace viscd::app
