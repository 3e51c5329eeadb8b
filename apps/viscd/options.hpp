#pragma once
// The command-line options the commands share, and their parsing into viscd::Config, GlOptions
// and SceneParams: the pipeline options (--backend, --bits, --lambda, ...), the cpu kernel options
// of run and pairs (--simd, --keep-order), the scene and object options of run and view, and the parsers of
// option values (sizes, lists of numbers). Every error names the option; the commands turn it
// into exit code 2.

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "viscd/gl.hpp"
#include "viscd/result.hpp"
#include "viscd/scene.hpp"
#include "viscd/viscd.hpp"

// CLI11 is declared only: its header costs a TU seconds of compile time (more under the
// sanitizers), so only the files that register options include it.
namespace CLI {
class App;
}  // namespace CLI

namespace viscd::app {

/// Upper bound of --objects: beyond it a frame needs tens of gigabytes.
inline constexpr std::uint32_t kMaxObjects = 100'000'000;

/// Options every frame-running command shares.
struct PipelineOptions {
  std::string backend = "cpu";
  std::string bits = "adaptive";
  std::string layout = "extended";
  float lambda = 200, a = 100, b = 400;
  bool no_culling = false;
  std::string map_size;  ///< "WxH" or empty
  int threads = 0;
  std::string geometry = "impostor";  ///< gl only
  std::string counter = "ssbo";       ///< gl only
  std::string max_pair_memory = "auto";
  std::string simd;           ///< best | sse2 | scalar; empty: VISCD_SIMD or best (run and pairs only)
  std::string keep_order;     ///< on | off; empty: VISCD_KEEP_ORDER or on (run and pairs only)
  std::string follow_change;  ///< on | off; empty: on (run and pairs only)
  float rest_margin = 0;      ///< Config::rest_margin (run and pairs only)
  float move_margin = 8;      ///< Config::move_margin (run and pairs only)
};

/// Registers the pipeline options on `cmd`; `backend_auto` offers --backend auto in the help.
void add_pipeline_options(CLI::App& cmd, PipelineOptions& o, bool backend_auto);
/// Registers --simd, --keep-order, --follow-change, --rest-margin and --move-margin (the cpu
/// backend's) on `cmd`.
void add_cpu_kernel_options(CLI::App& cmd, PipelineOptions& o);

/// The simulated scene's options, shared by `run` and `view`.
struct SceneOptions {
  std::uint32_t objects = 10000;
  std::string kind = "ring";
  std::uint64_t seed = 1;
  float dt = 1.0f / 60.0f;  ///< simulated seconds per frame
  float packing = 0.04f;    ///< volume fraction of the spheres (SceneParams::packing)
};
/// Registers the scene options (--objects, --scene, --seed, --dt, --packing) on `cmd`.
void add_scene_options(CLI::App& cmd, SceneOptions& o);
/// SceneParams from the options; the error names the bad option (--scene, --dt).
[[nodiscard]] Result<SceneParams> make_scene_params(const SceneOptions& o);

/// What the simulated scene's objects are handed to the detector as, shared by `run` and `view`:
/// the shape of the moving objects, and the static field under them.
struct ObjectOptions {
  std::string shape = "sphere";    ///< sphere | box (each sphere's cube, cube_of())
  std::uint32_t static_count = 0;  ///< K objects of static_field() in the detector's static set
};
/// Registers --shape and --static on `cmd`; `static_note` ends the help of --static (what the
/// command does with the static objects).
void add_object_options(CLI::App& cmd, ObjectOptions& o, std::string_view static_note = {});

/// The gl backend's options (--geometry, --counter); the error names the bad option.
[[nodiscard]] Result<GlOptions> make_gl_options(const PipelineOptions& o);
/// Config from the options, then the environment (VISCD_SIMD, VISCD_KEEP_ORDER), then --simd and
/// --keep-order when given. Checks every option, --backend and the gl options included, whatever
/// the backend: a typo must not pass silently. The error names the bad option.
[[nodiscard]] Result<Config> make_config(const PipelineOptions& o);

/// Parses "1280x720"; the error names `option`.
[[nodiscard]] Result<std::pair<int, int>> parse_size(std::string_view text, std::string_view option);
/// A visibility map of width x height within kMaxMapSide and kMaxMapPixels; the error names the option.
[[nodiscard]] Status check_map_size(int width, int height, std::string_view option);
/// Parses `count` comma-separated finite numbers ("1,2.5,-3"); the error names the option and
/// shows `form` ("ox,oy,oz,dx,dy,dz").
[[nodiscard]] Result<std::vector<float>> parse_numbers(std::string_view text, std::size_t count,
                                                       std::string_view option, std::string_view form);

}  // namespace viscd::app
