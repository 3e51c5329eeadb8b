#include "common.hpp"

#include <unistd.h>

#include <algorithm>
#include <charconv>

namespace viscd::app {

void add_pipeline_options(CLI::App& cmd, PipelineOptions& o, bool backend_auto) {
  cmd.add_option(
         "--backend", o.backend,
         backend_auto ? "cpu | reference | gl | auto (auto: gl on a hardware GPU, else cpu)" : "cpu | reference | gl")
      ->capture_default_str();
  cmd.add_option("--bits", o.bits, "Morton width: adaptive (Eq. 1 from mu, a, b) | 16 | 32 | 64")
      ->capture_default_str();
  cmd.add_option("--layout", o.layout, "Morton layout: extended (paper Table 2) | plain (10/10/10 style)")
      ->capture_default_str();
  cmd.add_option("--lambda", o.lambda, "culling threshold in screen pixels")->capture_default_str();
  cmd.add_option("-a", o.a, "adaptive bits: m = 16 below this mean pixel count")->capture_default_str();
  cmd.add_option("-b", o.b, "adaptive bits: m = 64 from this mean pixel count (32 between a and b)")
      ->capture_default_str();
  cmd.add_flag("--no-culling", o.no_culling, "keep every object active (no lambda culling)");
  cmd.add_option("--map-size", o.map_size,
                 "visibility map WxH (default: the screen size); counts are scaled to screen pixels");
  cmd.add_option("--threads", o.threads, "worker threads for the cpu backend (0 = all cores)")->capture_default_str();
  cmd.add_option("--geometry", o.geometry, "gl backend: sphere geometry in the visibility map, impostor | mesh")
      ->capture_default_str();
  cmd.add_option("--counter", o.counter, "gl backend: pixel counting, ssbo (any N) | atomic_uint (the paper's)")
      ->capture_default_str();
}

void add_scene_options(CLI::App& cmd, SceneOptions& o) {
  cmd.add_option("--objects,-n", o.objects, "number of objects N")->capture_default_str();
  cmd.add_option("--scene", o.kind, "ring (the paper's flat world) | box | clusters")->capture_default_str();
  cmd.add_option("--seed", o.seed, "scene seed (same seed, same scene)")->capture_default_str();
  cmd.add_option("--dt", o.dt, "simulated seconds per frame")->capture_default_str();
}

Result<SceneParams> make_scene_params(const SceneOptions& o) {
  auto kind = parse_scene_kind(o.kind);
  if (!kind) return Result<SceneParams>::failure(kind.error());
  if (!(o.dt >= 0)) return Result<SceneParams>::failure("--dt: expected a number >= 0");
  return SceneParams{.kind = kind.value(), .objects = o.objects, .seed = o.seed};
}

Result<GlOptions> make_gl_options(const PipelineOptions& o) {
  GlOptions g;
  if (o.geometry == "impostor")
    g.geometry = GlGeometry::impostor;
  else if (o.geometry == "mesh")
    g.geometry = GlGeometry::mesh;
  else
    return Result<GlOptions>::failure("--geometry: expected impostor or mesh, got '" + o.geometry + "'");
  if (o.counter == "ssbo")
    g.counter = GlCounter::ssbo;
  else if (o.counter == "atomic_uint")
    g.counter = GlCounter::atomic_uint;
  else
    return Result<GlOptions>::failure("--counter: expected ssbo or atomic_uint, got '" + o.counter + "'");
  return g;
}

Result<std::unique_ptr<Detector>> make_backend(const PipelineOptions& o, const Config& config, bool quiet) {
  using R = Result<std::unique_ptr<Detector>>;
  std::string backend = o.backend;
  if (backend == "auto") {
    auto device = gl_device();
    std::string why;
    if (!device) {
      backend = "cpu";
      why = "no OpenGL 4.5 context (" + device.error() + ")";
    } else if (is_software_renderer(device.value())) {
      backend = "cpu";
      why = "the only OpenGL is a software renderer, " + device.value() + "; --backend gl forces it";
    } else {
      backend = "gl";
      why = "hardware OpenGL: " + device.value();
    }
    if (!quiet) std::fprintf(stderr, "viscd: backend auto -> %s: %s\n", backend.c_str(), why.c_str());
  }
  if (backend != "gl") return make_detector(backend, config);
  auto g = make_gl_options(o);
  if (!g) return R::failure(g.error());
  return make_gl_detector(config, g.value());
}

Result<std::pair<int, int>> parse_size(std::string_view text, std::string_view option) {
  const auto x = text.find('x');
  int w = 0, h = 0;
  auto num = [](std::string_view s, int& v) {
    const auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
    return ec == std::errc() && p == s.data() + s.size() && v >= 1 && v <= 65536;
  };
  if (x == std::string_view::npos || !num(text.substr(0, x), w) || !num(text.substr(x + 1), h))
    return Result<std::pair<int, int>>::failure(
        std::string(option) + ": expected WIDTHxHEIGHT such as 1280x720, got '" + std::string(text) + "'");
  return std::pair{w, h};
}

Result<Config> make_config(const PipelineOptions& o) {
  Config c;
  if (o.bits == "adaptive")
    c.bits = Bits::adaptive;
  else if (o.bits == "16")
    c.bits = Bits::b16;
  else if (o.bits == "32")
    c.bits = Bits::b32;
  else if (o.bits == "64")
    c.bits = Bits::b64;
  else
    return Result<Config>::failure("--bits: expected adaptive, 16, 32 or 64, got '" + o.bits + "'");
  if (o.layout == "extended")
    c.layout = Layout::extended;
  else if (o.layout == "plain")
    c.layout = Layout::plain;
  else
    return Result<Config>::failure("--layout: expected extended or plain, got '" + o.layout + "'");
  if (!(o.lambda >= 0)) return Result<Config>::failure("--lambda: expected a number >= 0");
  if (!(o.a >= 0 && o.b >= o.a)) return Result<Config>::failure("-a/-b: expected 0 <= a <= b");
  c.lambda = o.lambda;
  c.a = o.a;
  c.b = o.b;
  c.culling = !o.no_culling;
  c.threads = o.threads;
  if (!o.map_size.empty()) {
    auto s = parse_size(o.map_size, "--map-size");
    if (!s) return Result<Config>::failure(s.error());
    c.map_width = s.value().first;
    c.map_height = s.value().second;
  }
  return c;
}

int fail(const std::string& message) {
  std::fprintf(stderr, "viscd: error: %s\n", message.c_str());
  return 1;
}

Progress::Progress(std::string label, std::size_t total, bool quiet)
    : label_(std::move(label)), total_(total), tty_(isatty(STDERR_FILENO) != 0), quiet_(quiet) {}

void Progress::update(std::size_t done, const std::string& note) {
  if (quiet_ || total_ == 0) return;
  if (tty_) {
    constexpr int kWidth = 30;
    const int filled = static_cast<int>(kWidth * done / total_);
    std::fprintf(stderr, "\r%s [%s%s] %zu/%zu %s\x1b[K", label_.c_str(), std::string(filled, '#').c_str(),
                 std::string(kWidth - filled, ' ').c_str(), done, total_, note.c_str());
    std::fflush(stderr);
  } else {
    const int decile = static_cast<int>(10 * done / total_);
    if (decile != last_decile_) {
      last_decile_ = decile;
      std::fprintf(stderr, "%s %zu/%zu %s\n", label_.c_str(), done, total_, note.c_str());
    }
  }
}

void Progress::finish() {
  if (!quiet_ && tty_) std::fprintf(stderr, "\n");
}

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  if (v.size() % 2) return *mid;
  return 0.5 * (*mid + *std::max_element(v.begin(), mid));
}

}  // namespace viscd::app
