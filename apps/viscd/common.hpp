#pragma once
// Shared pieces of the viscd subcommands: option parsing helpers, printing, progress.

#include <CLI/CLI.hpp>
#include <cstdio>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "viscd/io.hpp"
#include "viscd/scene.hpp"
#include "viscd/viscd.hpp"

namespace viscd::app {

/// Exit codes of the tool (docs/usage.md).
inline constexpr int kExitOk = 0;
inline constexpr int kExitFailed = 1;        ///< bad input file, or a run that failed
inline constexpr int kExitUsage = 2;         ///< unknown option, bad option value
inline constexpr int kExitHashMismatch = 3;  ///< --validate-hash differs

/// Upper bound of --objects: beyond it a frame needs tens of gigabytes.
inline constexpr std::uint32_t kMaxObjects = 100'000'000;

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
  std::string max_pair_memory = "auto";
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
/// A visibility map of width x height within kMaxMapSide and kMaxMapPixels; the error names the option.
Status check_map_size(int width, int height, std::string_view option);

/// Prints "viscd: error: <msg>" to stderr and returns kExitFailed.
int fail(const std::string& message);
/// Prints "viscd: error: <msg>" to stderr and returns kExitUsage (a bad option or value).
int usage_fail(const std::string& message);

/// Memory this process may still use, in bytes: the least of the system's available memory
/// (MemAvailable), the address-space limit and the cgroup's limit. 0 when none can be read.
[[nodiscard]] std::uint64_t available_memory_bytes();
/// The default pair memory cap: 1/8 of available_memory_bytes() (a frame's pair buffers take
/// several times the pairs' own 8 bytes), or 0 (no cap) when that is unknown.
[[nodiscard]] std::uint64_t default_pair_memory_cap();
/// Parses a byte size: "0", "1048576", "512K", "64M", "1.5G", "2T" (binary units); "auto".
[[nodiscard]] Result<std::uint64_t> parse_bytes(std::string_view text, std::string_view option);
/// "1.5 GiB".
[[nodiscard]] std::string format_bytes(std::uint64_t bytes);

/// A file the command reads or writes, with the option that names it (for messages).
struct NamedPath {
  std::string option;
  std::filesystem::path path;
};
/// Refuses, before anything is read or written: an output that is the same file as an input
/// (also through links), two outputs naming the same file, and an output that is a folder.
[[nodiscard]] Status check_outputs(const std::vector<NamedPath>& inputs, const std::vector<NamedPath>& outputs);

/// Refuses, before anything is read or written, a folder output that will be replaced as a whole
/// (`--pairs-dir`) when any other input or output names it or lies inside it.
[[nodiscard]] Status check_folder_output(const NamedPath& folder, const std::vector<NamedPath>& others);

/// A folder written whole or not at all: files go into a hidden folder beside the destination,
/// and commit() puts it in the destination's place in one step (exchanged with an existing
/// folder, which is then removed), so a reader sees the old folder or the new one. A destination
/// that exists must be a folder holding only files whose names start with `prefix` and end with
/// `suffix` (an earlier run's): anything else is refused rather than deleted. Destroyed
/// uncommitted, it removes what it wrote. Move-only.
class StagedFolder {
 public:
  [[nodiscard]] static Result<StagedFolder> create(const std::filesystem::path& dest, const std::string& option,
                                                   std::string_view prefix, std::string_view suffix);
  StagedFolder(StagedFolder&& o) noexcept;
  StagedFolder& operator=(StagedFolder&&) = delete;
  StagedFolder(const StagedFolder&) = delete;
  ~StagedFolder();
  /// Where a file of the folder is written until commit().
  [[nodiscard]] std::filesystem::path file(std::string_view name) const { return staging_ / name; }
  [[nodiscard]] Status commit();

 private:
  StagedFolder(std::filesystem::path dest, std::filesystem::path staging)
      : dest_(std::move(dest)), staging_(std::move(staging)) {}
  std::filesystem::path dest_, staging_;
  bool done_ = false;
};

/// Reads a camera JSON file, or nothing when `path` is empty (the option was not given).
[[nodiscard]] Result<std::optional<Camera>> read_optional_camera(const std::string& path);
/// Reads a raw id map: width x height little-endian uint32 ids, row-major from the top-left. A
/// file of another size than width * height * 4 bytes is an error naming both sizes.
[[nodiscard]] Result<std::vector<std::uint32_t>> read_id_map(const std::filesystem::path& path, int width, int height);
/// Parses `count` comma-separated finite numbers ("1,2.5,-3"); the error names the option.
[[nodiscard]] Result<std::vector<float>> parse_numbers(std::string_view text, std::size_t count,
                                                       std::string_view option, std::string_view form);

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
void add_query_command(CLI::App& app, int& rc);
#ifdef VISCD_HAVE_VIEWER
void add_view_command(CLI::App& app, int& rc);
#endif

}  // namespace viscd::app
