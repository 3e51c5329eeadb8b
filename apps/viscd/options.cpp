// Registering the shared options and turning their values into Config, GlOptions and
// SceneParams, with messages that name the option.
#include "options.hpp"

#include <CLI/CLI.hpp>
#include <charconv>
#include <cmath>
#include <initializer_list>
#include <string>
#include <string_view>
#include <utility>

#include "memory.hpp"
#include "viscd/io.hpp"

namespace viscd::app {
namespace {

// The value named `text` among `choices`, or the error "OPTION: expected a, b or c, got 'text'".
template <class T>
Result<T> choose(std::string_view option, std::string_view text,
                 std::initializer_list<std::pair<std::string_view, T>> choices) {
  std::string names;
  std::size_t k = 0;
  for (const auto& [name, value] : choices) {
    if (name == text) return value;
    names += (k == 0 ? "" : k + 1 == choices.size() ? " or " : ", ") + std::string(name);
    ++k;
  }
  return Result<T>::failure(ErrorKind::invalid_input,
                            std::string(option) + ": expected " + names + ", got '" + printable(text) + "'");
}

}  // namespace

void add_pipeline_options(CLI::App& cmd, PipelineOptions& o, bool backend_auto) {
  cmd.add_option("--backend", o.backend,
                 backend_auto
                     ? "cpu | reference | gl | cuda | auto (auto: gl on a hardware GPU, else cpu; cuda only by name)"
                     : "cpu | reference | gl | cuda")
      ->capture_default_str();
  cmd.add_option("--bits", o.bits, "Morton width: adaptive (Eq. 1 from mu, a, b) | 16 | 32 | 64")
      ->capture_default_str();
  cmd.add_option("--layout", o.layout, "Morton layout: extended (paper Table 2) | plain (10/10/10 style)")
      ->capture_default_str();
  cmd.add_option("--lambda", o.lambda, "culling threshold in screen pixels")->capture_default_str();
  cmd.add_option("-a", o.a, "adaptive bits: m = 16 below this mean pixel count")->capture_default_str();
  cmd.add_option("-b", o.b, "adaptive bits: m = 64 from this mean pixel count (32 between a and b)")
      ->capture_default_str();
  cmd.add_flag("--no-culling", o.no_culling,
               "keep every object active (no lambda culling); with a fixed --bits no visibility map is\n"
               "rendered (the paper's baseline)");
  cmd.add_option("--map-size", o.map_size,
                 "visibility map WxH (default: the screen size); counts are scaled to screen pixels");
  cmd.add_option("--threads", o.threads,
                 "worker threads for the cpu backend (0 = all cores; more than the machine has are clamped)")
      ->check(CLI::Range(0, 1 << 16))
      ->capture_default_str();
  const std::uint64_t cap = default_pair_memory_cap();
  cmd.add_option("--max-pair-memory", o.max_pair_memory,
                 "cap on the memory a frame's pairs may take (8 bytes a pair), e.g. 512M, 4G, or 0 for none; a "
                 "frame over it fails naming its pair count. auto = 1/8 of the memory available when viscd "
                 "starts" +
                     (cap ? " (here " + format_bytes(cap) + ")" : std::string(" (unknown here: no cap)")))
      ->capture_default_str();
  cmd.add_option(
         "--geometry", o.geometry,
         "gl backend: sphere geometry in the visibility map, impostor | mesh | splat (compute shaders, no raster)")
      ->capture_default_str();
  cmd.add_option("--counter", o.counter, "gl backend: pixel counting, ssbo (any N) | atomic_uint (the paper's)")
      ->capture_default_str();
}

void add_cpu_kernel_options(CLI::App& cmd, PipelineOptions& o) {
  cmd.add_option("--simd", o.simd,
                 "cpu backend: best | sse2 | scalar, the widest SIMD kernels it may use (best: AVX-512 or\n"
                 "SSE2, as the CPU has). The pairs are the same either way. Default: VISCD_SIMD, else best");
  cmd.add_option("--keep-order", o.keep_order,
                 "cpu backend: on | off. on keeps the last frame's object order while it stays good, off\n"
                 "sorts every frame. The pairs are the same either way. Default: VISCD_KEEP_ORDER, else on");
  cmd.add_option("--follow-change", o.follow_change,
                 "cpu backend: on | off. on keeps objects that keep their bounds in trees across frames, so\n"
                 "that a frame costs what moved (docs/architecture.md, \"Resting objects\"); off rebuilds\n"
                 "every frame. The pairs are the same either way. Default: VISCD_FOLLOW_CHANGE, else on");
  cmd.add_option("--rest-margin", o.rest_margin,
                 "cpu backend: how far (world units) an object may stray and still rest; 0 = only bit-for-bit\n"
                 "unchanged bounds rest")
      ->capture_default_str();
  cmd.add_option("--move-margin", o.move_margin,
                 "cpu backend: margins of their own for moving objects: an object that leaves its bounds two\n"
                 "frames in a row is placed again with this many times its last move as margin (at most half\n"
                 "its size), so that a body that keeps moving is placed again every few frames; 0 = every\n"
                 "frame it changes")
      ->capture_default_str();
}

void add_scene_options(CLI::App& cmd, SceneOptions& o) {
  cmd.add_option("--objects,-n", o.objects, "number of objects N (at most 100 000 000)")
      ->check(CLI::Range(std::uint32_t{0}, kMaxObjects))
      ->capture_default_str();
  cmd.add_option("--scene", o.kind, "ring (the paper's flat world) | box | clusters")->capture_default_str();
  cmd.add_option("--seed", o.seed, "scene seed (same seed, same scene)")->capture_default_str();
  cmd.add_option("--dt", o.dt, "simulated seconds per frame")->capture_default_str();
  cmd.add_option("--packing", o.packing,
                 "volume fraction of the spheres, 0.001 to 0.5 (0.04: 0.135 pairs per object in the ring;\n"
                 "0.18: the dense ring of docs/benchmarks.md, 0.6 pairs per object)")
      ->check(CLI::Range(0.001f, 0.5f))
      ->capture_default_str();
}

void add_object_options(CLI::App& cmd, ObjectOptions& o, std::string_view static_note) {
  cmd.add_option("--shape", o.shape,
                 "sphere | box: the moving objects as spheres, or as boxes, each sphere's cube (its centre\n"
                 "minus and plus r on every axis): the same scene and motion, found by the box test.\n"
                 "Example: --shape box --static 300")
      ->capture_default_str();
  cmd.add_option("--static", o.static_count,
                 "K static objects in the detector's static set, handed over once before the frames: rocks\n"
                 "(single spheres) and pillars (stacks of spheres, 12 mean radii tall) on the ground under\n"
                 "the scene, deterministic in --seed; cubes of them with --shape box. They are never\n"
                 "culled, hide what is behind them (grey in the image) and pair with the moving objects\n"
                 "that touch them" +
                     std::string(static_note))
      ->check(CLI::Range(std::uint32_t{0}, kMaxObjects))
      ->capture_default_str();
}

Result<SceneParams> make_scene_params(const SceneOptions& o) {
  auto kind = parse_scene_kind(o.kind);
  if (!kind) return Result<SceneParams>::failure(kind.status());
  if (!(o.dt >= 0 && std::isfinite(o.dt)))
    return Result<SceneParams>::failure(ErrorKind::invalid_input,
                                        "--dt: expected a finite number >= 0, got " + std::to_string(o.dt));
  return SceneParams{.kind = kind.value(), .objects = o.objects, .seed = o.seed, .packing = o.packing};
}

Result<GlOptions> make_gl_options(const PipelineOptions& o) {
  GlOptions g;
  auto geometry = choose<GlGeometry>(
      "--geometry", o.geometry,
      {{"impostor", GlGeometry::impostor}, {"mesh", GlGeometry::mesh}, {"splat", GlGeometry::splat}});
  if (!geometry) return Result<GlOptions>::failure(geometry.status());
  g.geometry = geometry.value();
  auto counter =
      choose<GlCounter>("--counter", o.counter, {{"ssbo", GlCounter::ssbo}, {"atomic_uint", GlCounter::atomic_uint}});
  if (!counter) return Result<GlOptions>::failure(counter.status());
  g.counter = counter.value();
  return g;
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
        ErrorKind::invalid_input,
        std::string(option) + ": expected WIDTHxHEIGHT such as 1280x720, got '" + printable(text) + "'");
  return std::pair{w, h};
}

Result<Config> make_config(const PipelineOptions& o) {
  Config c;
  auto bits = choose<Bits>("--bits", o.bits,
                           {{"adaptive", Bits::adaptive}, {"16", Bits::b16}, {"32", Bits::b32}, {"64", Bits::b64}});
  if (!bits) return Result<Config>::failure(bits.status());
  c.bits = bits.value();
  auto layout = choose<Layout>("--layout", o.layout, {{"extended", Layout::extended}, {"plain", Layout::plain}});
  if (!layout) return Result<Config>::failure(layout.status());
  c.layout = layout.value();
  if (!(o.lambda >= 0 && std::isfinite(o.lambda)))
    return Result<Config>::failure(ErrorKind::invalid_input, "--lambda: expected a finite number >= 0");
  if (!(o.a >= 0 && o.b >= o.a && std::isfinite(o.b)))
    return Result<Config>::failure(ErrorKind::invalid_input, "-a/-b: expected 0 <= a <= b");
  if (o.threads < 0)
    return Result<Config>::failure(ErrorKind::invalid_input, "--threads: expected 0 (all cores) or a positive count");
  if (auto be =
          choose<int>("--backend", o.backend, {{"cpu", 0}, {"reference", 0}, {"gl", 0}, {"cuda", 0}, {"auto", 0}});
      !be)
    return Result<Config>::failure(be.status());
  // The gl options are checked whatever the backend: a typo must not pass silently.
  if (auto g = make_gl_options(o); !g) return Result<Config>::failure(g.status());
  auto cap = parse_bytes(o.max_pair_memory, "--max-pair-memory");
  if (!cap) return Result<Config>::failure(cap.status());
  c.pair_memory_cap = static_cast<std::size_t>(cap.value());
  c.lambda = o.lambda;
  c.pixels_for_32_bits = o.a;
  c.pixels_for_64_bits = o.b;
  c.culling = !o.no_culling;
  c.threads = o.threads;
  // VISCD_SIMD, VISCD_KEEP_ORDER and VISCD_FOLLOW_CHANGE, for measurements (docs/usage.md); the options, when given,
  // override them: the command line is the more specific request.
  if (Status s = apply_environment(c); !s) return Result<Config>::failure(s);
  if (!o.simd.empty()) {  // empty: not given
    auto simd = choose<Simd>("--simd", o.simd, {{"best", Simd::best}, {"sse2", Simd::sse2}, {"scalar", Simd::scalar}});
    if (!simd) return Result<Config>::failure(simd.status());
    c.simd = simd.value();
  }
  if (!o.keep_order.empty()) {
    auto keep = choose<bool>("--keep-order", o.keep_order, {{"on", true}, {"off", false}});
    if (!keep) return Result<Config>::failure(keep.status());
    c.keep_order = keep.value();
  }
  if (!o.follow_change.empty()) {
    auto follow = choose<bool>("--follow-change", o.follow_change, {{"on", true}, {"off", false}});
    if (!follow) return Result<Config>::failure(follow.status());
    c.follow_change = follow.value();
  }
  c.rest_margin = o.rest_margin;
  if (!(std::isfinite(c.rest_margin) && c.rest_margin >= 0))
    return Result<Config>::failure(ErrorKind::invalid_input, "--rest-margin " + std::to_string(c.rest_margin) +
                                                                 ": expected a finite distance >= 0");
  c.move_margin = o.move_margin;
  if (!(std::isfinite(c.move_margin) && c.move_margin >= 0))
    return Result<Config>::failure(
        ErrorKind::invalid_input, "--move-margin " + std::to_string(c.move_margin) + ": expected a finite factor >= 0");
  if (!o.map_size.empty()) {
    auto s = parse_size(o.map_size, "--map-size");
    if (!s) return Result<Config>::failure(s.status());
    c.map_width = s.value().first;
    c.map_height = s.value().second;
    if (auto m = check_map_size(c.map_width, c.map_height, "--map-size"); !m) return Result<Config>::failure(m);
  }
  return c;
}

Status check_map_size(int width, int height, std::string_view option) {
  if (Status s = validate_map_size(width, height); !s)
    return Status::failure(ErrorKind::invalid_input, std::string(option) + ": " + s.error());
  return {};
}

Result<std::vector<float>> parse_numbers(std::string_view text, std::size_t count, std::string_view option,
                                         std::string_view form) {
  using R = Result<std::vector<float>>;
  std::vector<float> v;
  std::size_t start = 0;
  for (;;) {
    const std::size_t comma = text.find(',', start);
    const std::string_view field = text.substr(start, comma == std::string_view::npos ? text.npos : comma - start);
    float x = 0;
    const auto [p, ec] = std::from_chars(field.data(), field.data() + field.size(), x);
    if (field.empty() || ec != std::errc() || p != field.data() + field.size() || !std::isfinite(x))
      return R::failure(ErrorKind::invalid_input,
                        std::string(option) + ": expected " + std::string(form) + " (" + std::to_string(count) +
                            " finite numbers separated by commas), got '" + printable(text) + "'");
    v.push_back(x);
    if (comma == std::string_view::npos) break;
    start = comma + 1;
  }
  if (v.size() != count)
    return R::failure(ErrorKind::invalid_input, std::string(option) + ": expected " + std::string(form) + " (" +
                                                    std::to_string(count) + " numbers), got " +
                                                    std::to_string(v.size()) + " in '" + printable(text) + "'");
  return v;
}

}  // namespace viscd::app
