// Resolving --backend into a detector: auto's probe of the OpenGL device and the gl -> cpu
// fallback, written once for every command.
#include "detector_choice.hpp"

#include <cstdio>
#include <utility>

namespace viscd::app {

Result<DetectorRequest> detector_request(const PipelineOptions& options) {
  auto gl = make_gl_options(options);
  if (!gl) return Result<DetectorRequest>::failure(gl.status());
  DetectorRequest r;
  r.backend = options.backend;
  r.gl = gl.value();
  return r;
}

std::string gl_unavailable(const std::string& error) { return "gl backend unavailable: " + error; }

Result<DetectorChoice> make_tool_detector(const DetectorRequest& request, const Config& config) {
  using R = Result<DetectorChoice>;
  DetectorChoice choice;
  choice.backend = request.backend;
  if (request.backend == "auto") {
    auto device = gl_device();
    if (!device) {
      choice.backend = "cpu";
      choice.why = "no OpenGL 4.5 context (" + device.error() + ")";
    } else if (is_software_renderer(device.value())) {
      choice.backend = "cpu";
      choice.why = "the only OpenGL is a software renderer, " + device.value() + "; --backend gl forces it";
    } else {
      choice.backend = "gl";
      choice.why = "hardware OpenGL: " + device.value();
    }
    if (!request.quiet)
      std::fprintf(stderr, "%s: backend auto -> %s: %s\n", request.tool.c_str(), choice.backend.c_str(),
                   choice.why.c_str());
  }
  if (choice.backend != "gl") {
    auto d = make_detector(choice.backend, config);
    if (!d) return R::failure(d.status());
    choice.detector = std::move(d.value());
    return choice;
  }
  auto d = make_gl_detector(config, request.gl);
  if (d) {
    choice.detector = std::move(d.value());
    return choice;
  }
  // Only a gl backend asked for by name falls back: auto chose gl because a hardware device
  // answered, and a gl that then does not start is a fault to report, not a choice to hide.
  if (request.fallback == GlFallback::none || request.backend != "gl") return R::failure(d.status());
  choice.backend = "cpu";
  choice.why = gl_unavailable(d.error());
  choice.fell_back = true;
  choice.detector = make_cpu_detector(config);
  if (!request.quiet) std::fprintf(stderr, "%s: %s; staying on cpu\n", request.tool.c_str(), choice.why.c_str());
  return choice;
}

bool fall_back_from_auto_gl(DetectorChoice& choice, const DetectorRequest& request, const Config& config,
                            const Status& status) {
  if (request.backend != "auto" || choice.backend != "gl" || status.kind() != ErrorKind::unsupported_input)
    return false;
  choice.backend = "cpu";
  choice.why = "the gl backend refused the input (" + status.error() + ")";
  choice.detector = make_cpu_detector(config);
  if (!request.quiet) std::fprintf(stderr, "%s: backend auto -> cpu: %s\n", request.tool.c_str(), choice.why.c_str());
  return true;
}

}  // namespace viscd::app
