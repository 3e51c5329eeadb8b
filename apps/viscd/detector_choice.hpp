#pragma once
// Which detector a command runs: the one place that turns --backend into a detector, resolves
// `auto` (gl on a hardware GPU, else cpu) and falls back from gl to cpu where a command allows it,
// and says which backend it got and why.

#include <memory>
#include <string>

#include "options.hpp"
#include "viscd/gl.hpp"
#include "viscd/result.hpp"
#include "viscd/viscd.hpp"

namespace viscd::app {

/// What happens when the gl backend was asked for by name and cannot start.
enum class GlFallback {
  none,  ///< an error naming the reason (run, pairs, query, bench)
  cpu,   ///< the cpu backend instead, with a message (view, whose panel can try gl again)
};

/// The detector a command asks for.
struct DetectorRequest {
  std::string backend = "cpu";             ///< cpu | reference | gl | auto
  GlOptions gl;                            ///< the gl backend's options
  GlFallback fallback = GlFallback::none;  ///< for a gl backend asked for by name
  std::string tool = "viscd";              ///< starts the message on stderr ("viscd view")
  bool quiet = false;                      ///< no message
};

/// The detector a command got, the backend it runs and why that one.
struct DetectorChoice {
  std::unique_ptr<Detector> detector;
  std::string backend;  ///< cpu, reference or gl
  /// Empty when the backend is the one asked for by name; for auto what decided it ("hardware
  /// OpenGL: <device>", "no OpenGL 4.5 context (<reason>)", ...); after a fallback
  /// gl_unavailable(<reason>).
  std::string why;
  bool fell_back = false;  ///< gl was asked for and could not start; this is the cpu backend
};

/// The request the pipeline options name (--backend, --geometry, --counter); the error names a
/// bad --geometry or --counter.
[[nodiscard]] Result<DetectorRequest> detector_request(const PipelineOptions& options);

/// "gl backend unavailable: <error>": why a command runs cpu although gl was asked for.
[[nodiscard]] std::string gl_unavailable(const std::string& error);

/// Makes the detector `request` asks for, with `config`. `auto` creates an OpenGL context once
/// to see the device: gl on a hardware GPU, cpu where the only OpenGL is a software renderer
/// (the cpu backend is faster there) or there is none. A gl backend that cannot start is an
/// error, or with GlFallback::cpu the cpu backend. Unless quiet, prints to stderr which backend
/// auto picked and why ("viscd: backend auto -> cpu: <why>"), or the fallback ("viscd view: gl
/// backend unavailable: <error>; staying on cpu"); nothing when the named backend starts.
[[nodiscard]] Result<DetectorChoice> make_tool_detector(const DetectorRequest& request, const Config& config);

/// After a frame failed with `status`: when `choice` runs gl because `auto` picked it and the gl
/// backend refused the frame's input as ErrorKind::unsupported_input (input it does not take yet,
/// such as boxes or a static set), replaces the detector with cpu (made with `config`), prints
/// "<tool>: backend auto -> cpu: <why>" unless quiet, and returns true: hand the new detector
/// the static set and run the frame again. Otherwise returns false (report the error). A gl
/// asked for by name never falls back here: the error says what to use instead.
[[nodiscard]] bool fall_back_from_auto_gl(DetectorChoice& choice, const DetectorRequest& request, const Config& config,
                                          const Status& status);

}  // namespace viscd::app
