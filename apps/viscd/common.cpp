#include "common.hpp"

#include <fcntl.h>
#include <sys/resource.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>

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
  cmd.add_option("--geometry", o.geometry, "gl backend: sphere geometry in the visibility map, impostor | mesh")
      ->capture_default_str();
  cmd.add_option("--counter", o.counter, "gl backend: pixel counting, ssbo (any N) | atomic_uint (the paper's)")
      ->capture_default_str();
}

void add_scene_options(CLI::App& cmd, SceneOptions& o) {
  cmd.add_option("--objects,-n", o.objects, "number of objects N (at most 100 000 000)")
      ->check(CLI::Range(std::uint32_t{0}, kMaxObjects))
      ->capture_default_str();
  cmd.add_option("--scene", o.kind, "ring (the paper's flat world) | box | clusters")->capture_default_str();
  cmd.add_option("--seed", o.seed, "scene seed (same seed, same scene)")->capture_default_str();
  cmd.add_option("--dt", o.dt, "simulated seconds per frame")->capture_default_str();
}

Result<SceneParams> make_scene_params(const SceneOptions& o) {
  auto kind = parse_scene_kind(o.kind);
  if (!kind) return Result<SceneParams>::failure(kind.status());
  if (!(o.dt >= 0 && std::isfinite(o.dt)))
    return Result<SceneParams>::failure(ErrorKind::invalid_input,
                                        "--dt: expected a finite number >= 0, got " + std::to_string(o.dt));
  return SceneParams{.kind = kind.value(), .objects = o.objects, .seed = o.seed};
}

Result<GlOptions> make_gl_options(const PipelineOptions& o) {
  GlOptions g;
  if (o.geometry == "impostor")
    g.geometry = GlGeometry::impostor;
  else if (o.geometry == "mesh")
    g.geometry = GlGeometry::mesh;
  else
    return Result<GlOptions>::failure(ErrorKind::invalid_input,
                                      "--geometry: expected impostor or mesh, got '" + printable(o.geometry) + "'");
  if (o.counter == "ssbo")
    g.counter = GlCounter::ssbo;
  else if (o.counter == "atomic_uint")
    g.counter = GlCounter::atomic_uint;
  else
    return Result<GlOptions>::failure(ErrorKind::invalid_input,
                                      "--counter: expected ssbo or atomic_uint, got '" + printable(o.counter) + "'");
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
  if (!g) return R::failure(g.status());
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
        ErrorKind::invalid_input,
        std::string(option) + ": expected WIDTHxHEIGHT such as 1280x720, got '" + printable(text) + "'");
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
    return Result<Config>::failure(ErrorKind::invalid_input,
                                   "--bits: expected adaptive, 16, 32 or 64, got '" + printable(o.bits) + "'");
  if (o.layout == "extended")
    c.layout = Layout::extended;
  else if (o.layout == "plain")
    c.layout = Layout::plain;
  else
    return Result<Config>::failure(ErrorKind::invalid_input,
                                   "--layout: expected extended or plain, got '" + printable(o.layout) + "'");
  if (!(o.lambda >= 0 && std::isfinite(o.lambda)))
    return Result<Config>::failure(ErrorKind::invalid_input, "--lambda: expected a finite number >= 0");
  if (!(o.a >= 0 && o.b >= o.a && std::isfinite(o.b)))
    return Result<Config>::failure(ErrorKind::invalid_input, "-a/-b: expected 0 <= a <= b");
  if (o.threads < 0)
    return Result<Config>::failure(ErrorKind::invalid_input, "--threads: expected 0 (all cores) or a positive count");
  if (o.backend != "cpu" && o.backend != "reference" && o.backend != "gl" && o.backend != "auto")
    return Result<Config>::failure(
        ErrorKind::invalid_input, "--backend: expected cpu, reference, gl or auto, got '" + printable(o.backend) + "'");
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
  // VISCD_SIMD and VISCD_KEEP_ORDER, for measurements (docs/usage.md).
  if (Status s = apply_environment(c); !s) return Result<Config>::failure(s);
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

int fail(const std::string& message) {
  std::fprintf(stderr, "viscd: error: %s\n", message.c_str());
  return kExitFailed;
}

int usage_fail(const std::string& message) {
  std::fprintf(stderr, "viscd: error: %s\n", message.c_str());
  return kExitUsage;
}

std::uint64_t available_memory_bytes() {
  std::uint64_t best = 0;
  auto consider = [&](std::uint64_t v) {
    if (v > 0 && (best == 0 || v < best)) best = v;
  };
  {
    std::ifstream meminfo("/proc/meminfo");
    std::string key;
    std::uint64_t kib = 0;
    std::string unit;
    while (meminfo >> key >> kib >> unit)
      if (key == "MemAvailable:") consider(kib * 1024);
  }
  rlimit as{};
  if (getrlimit(RLIMIT_AS, &as) == 0 && as.rlim_cur != RLIM_INFINITY) {
    // The limit counts the address space already mapped too.
    std::ifstream status("/proc/self/status");
    std::uint64_t used_kib = 0;
    std::string line;
    while (std::getline(status, line))
      if (line.rfind("VmSize:", 0) == 0) used_kib = std::strtoull(line.c_str() + 7, nullptr, 10);
    const std::uint64_t limit = as.rlim_cur, used = used_kib * 1024;
    consider(limit > used ? limit - used : 1);
  }
  {
    std::ifstream max_file("/sys/fs/cgroup/memory.max"), current_file("/sys/fs/cgroup/memory.current");
    std::string max_text;
    std::uint64_t current = 0;
    if (max_file >> max_text && max_text != "max" && current_file >> current) {
      const std::uint64_t max = std::strtoull(max_text.c_str(), nullptr, 10);
      if (max > 0) consider(max > current ? max - current : 1);
    }
  }
  return best;
}

std::uint64_t default_pair_memory_cap() {
  static const std::uint64_t cap = available_memory_bytes() / 8;
  return cap;
}

Result<std::uint64_t> parse_bytes(std::string_view text, std::string_view option) {
  using R = Result<std::uint64_t>;
  if (text == "auto") return default_pair_memory_cap();
  double v = 0;
  const auto [p, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
  std::string_view unit = text.substr(static_cast<std::size_t>(p - text.data()));
  if (unit.ends_with("iB") || unit.ends_with("ib")) unit.remove_suffix(2);
  if (unit.size() == 2 && (unit[1] == 'B' || unit[1] == 'b')) unit.remove_suffix(1);
  double scale = 0;
  if (unit.empty() || unit == "B" || unit == "b")
    scale = 1;
  else if (unit == "K" || unit == "k")
    scale = 1024.0;
  else if (unit == "M" || unit == "m")
    scale = 1024.0 * 1024;
  else if (unit == "G" || unit == "g")
    scale = 1024.0 * 1024 * 1024;
  else if (unit == "T" || unit == "t")
    scale = 1024.0 * 1024 * 1024 * 1024;
  const double bytes = v * scale;
  if (ec != std::errc() || p == text.data() || scale == 0 || !(bytes >= 0) || bytes > 9.0e18)
    return R::failure(
        ErrorKind::invalid_input,
        std::string(option) + ": expected a size such as 512M, 4G or 0 (no cap), got '" + printable(text) + "'");
  return static_cast<std::uint64_t>(bytes);
}

std::string format_bytes(std::uint64_t bytes) {
  char buf[32];
  const char* units[] = {"bytes", "KiB", "MiB", "GiB", "TiB"};
  double v = static_cast<double>(bytes);
  int u = 0;
  while (v >= 1024 && u < 4) v /= 1024, ++u;
  std::snprintf(buf, sizeof buf, u == 0 ? "%.0f %s" : "%.1f %s", v, units[u]);
  return buf;
}

Status check_outputs(const std::vector<NamedPath>& inputs, const std::vector<NamedPath>& outputs) {
  namespace fs = std::filesystem;
  std::error_code ec;
  auto same = [&](const fs::path& a, const fs::path& b) {
    if (fs::exists(a, ec) && fs::exists(b, ec)) return fs::equivalent(a, b, ec);
    // A file that does not exist yet: compare where the two names lead.
    const fs::path ca = fs::weakly_canonical(fs::absolute(a, ec), ec);
    const fs::path cb = fs::weakly_canonical(fs::absolute(b, ec), ec);
    return !ca.empty() && ca == cb;
  };
  for (std::size_t k = 0; k < outputs.size(); ++k) {
    const NamedPath& out = outputs[k];
    const std::string shown = printable(out.path.string(), 200);
    if (out.path.empty()) return Status::failure(ErrorKind::invalid_input, out.option + ": expected a file name");
    if (fs::is_directory(out.path, ec))
      return Status::failure(ErrorKind::invalid_input,
                             out.option + " " + shown + ": is a folder, expected a file name");
    for (const NamedPath& in : inputs)
      if (!in.path.empty() && same(in.path, out.path))
        return Status::failure(ErrorKind::invalid_input, out.option + " " + shown + " is the same file as " +
                                                             in.option + " " + printable(in.path.string(), 200) +
                                                             ": refusing to overwrite an input");
    for (std::size_t j = 0; j < k; ++j)
      if (same(outputs[j].path, out.path))
        return Status::failure(ErrorKind::invalid_input,
                               out.option + " and " + outputs[j].option + " name the same file " + shown);
  }
  return {};
}

Status check_folder_output(const NamedPath& folder, const std::vector<NamedPath>& others) {
  namespace fs = std::filesystem;
  std::error_code ec;
  const std::string shown = printable(folder.path.string(), 200);
  if (folder.path.empty()) return Status::failure(ErrorKind::invalid_input, folder.option + ": expected a folder name");
  if (fs::exists(folder.path, ec) && !fs::is_directory(folder.path, ec))
    return Status::failure(ErrorKind::invalid_input, folder.option + " " + shown + ": is a file, expected a folder");
  // Where a name leads (through links, also for names that do not exist yet), without a trailing "/".
  auto where = [&](const fs::path& x) {
    fs::path c = fs::weakly_canonical(fs::absolute(x, ec), ec).lexically_normal();
    if (!c.has_filename() && c != c.root_path()) c = c.parent_path();
    return c;
  };
  const fs::path dir = where(folder.path);
  for (const NamedPath& other : others) {
    if (other.path.empty()) continue;
    const fs::path p = where(other.path);
    if (std::mismatch(dir.begin(), dir.end(), p.begin(), p.end()).first == dir.end())
      return Status::failure(ErrorKind::invalid_input, other.option + " " + printable(other.path.string(), 200) +
                                                           " lies in " + folder.option + " " + shown +
                                                           ", which is replaced as a whole: name a file elsewhere");
  }
  return {};
}

Result<StagedFolder> StagedFolder::create(const std::filesystem::path& dest, const std::string& option,
                                          std::string_view prefix, std::string_view suffix) {
  namespace fs = std::filesystem;
  using R = Result<StagedFolder>;
  std::error_code ec;
  const std::string shown = printable(dest.string(), 200);
  if (fs::exists(dest, ec)) {
    if (!fs::is_directory(dest, ec))
      return R::failure(ErrorKind::invalid_input, option + " " + shown + ": is a file, expected a folder");
    for (const auto& entry : fs::directory_iterator(dest, ec)) {
      const std::string name = entry.path().filename().string();
      if (!entry.is_regular_file(ec) || !name.starts_with(prefix) || !name.ends_with(suffix))
        return R::failure(ErrorKind::invalid_input,
                          option + " " + shown + " holds " + printable(name, 100) + ", which is not a file " +
                              std::string(prefix) + "*" + std::string(suffix) +
                              " of an earlier run: refusing to replace the folder (name a new or empty one)");
    }
    if (ec)
      return R::failure(ErrorKind::io_failure, option + " " + shown + ": cannot list the folder: " + ec.message());
  }
  const fs::path abs = fs::absolute(dest, ec);
  const fs::path parent = abs.parent_path();
  fs::create_directories(parent, ec);
  if (ec)
    return R::failure(ErrorKind::io_failure,
                      option + " " + shown + ": cannot create its parent folder: " + ec.message());
  std::string tmpl = (parent / ("." + abs.filename().string() + ".tmp-XXXXXX")).string();
  if (!::mkdtemp(tmpl.data()))
    return R::failure(ErrorKind::io_failure,
                      option + " " + shown + ": cannot create a folder beside it: " + std::strerror(errno));
  return StagedFolder(abs, tmpl);
}

StagedFolder::StagedFolder(StagedFolder&& o) noexcept
    : dest_(std::move(o.dest_)), staging_(std::move(o.staging_)), done_(o.done_) {
  o.done_ = true;
}

StagedFolder::~StagedFolder() {
  if (done_) return;
  std::error_code ec;
  std::filesystem::remove_all(staging_, ec);
}

Status StagedFolder::commit() {
  namespace fs = std::filesystem;
  std::error_code ec;
  const std::string shown = printable(dest_.string(), 200);
  // The staged files are durable (AtomicFile syncs each); make the folder's entries so too.
  if (const int fd = ::open(staging_.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC); fd >= 0) {
    ::fsync(fd);
    ::close(fd);
  }
  if (fs::exists(dest_, ec)) {
    if (::renameat2(AT_FDCWD, staging_.c_str(), AT_FDCWD, dest_.c_str(), RENAME_EXCHANGE) == 0) {
      fs::remove_all(staging_, ec);  // now the old folder
      done_ = true;
      return {};
    }
    // No exchange on this file system: move the old folder aside, the new one in, the old one out.
    const fs::path old = staging_.string() + ".old";
    if (::rename(dest_.c_str(), old.c_str()) != 0)
      return Status::failure(ErrorKind::io_failure, shown + ": cannot replace the folder: " + std::strerror(errno));
    if (::rename(staging_.c_str(), dest_.c_str()) != 0) {
      const int e = errno;
      (void)::rename(old.c_str(), dest_.c_str());
      return Status::failure(ErrorKind::io_failure, shown + ": cannot replace the folder: " + std::strerror(e));
    }
    fs::remove_all(old, ec);
    done_ = true;
    return {};
  }
  if (::rename(staging_.c_str(), dest_.c_str()) != 0)
    return Status::failure(ErrorKind::io_failure, shown + ": cannot create the folder: " + std::strerror(errno));
  done_ = true;
  return {};
}

Result<std::optional<Camera>> read_optional_camera(const std::string& path) {
  using R = Result<std::optional<Camera>>;
  if (path.empty()) return std::optional<Camera>{};
  auto c = read_camera(path);
  if (!c) return R::failure(c.status());
  return std::optional<Camera>(c.value());
}

Result<std::vector<std::uint32_t>> read_id_map(const std::filesystem::path& path, int width, int height) {
  using R = Result<std::vector<std::uint32_t>>;
  const std::string name = printable(path.string(), 200);
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec))
    return R::failure(ErrorKind::invalid_input, name + ": is a folder, expected a file");
  std::ifstream in(path, std::ios::binary);
  if (!in) return R::failure(ErrorKind::io_failure, name + ": cannot open for reading: " + std::strerror(errno));
  in.seekg(0, std::ios::end);
  const auto size = static_cast<std::uint64_t>(in.tellg());
  const std::uint64_t want = static_cast<std::uint64_t>(width) * static_cast<std::uint64_t>(height) * 4;
  if (size != want)
    return R::failure(ErrorKind::invalid_input, name + ": " + std::to_string(size) + " bytes, but a " +
                                                    std::to_string(width) + "x" + std::to_string(height) +
                                                    " id map of 32-bit ids has " + std::to_string(want) + " bytes");
  in.seekg(0);
  std::vector<unsigned char> bytes(static_cast<std::size_t>(size));
  if (!in.read(reinterpret_cast<char*>(bytes.data()), static_cast<std::streamsize>(size)))
    return R::failure(ErrorKind::io_failure, name + ": read error: " + std::strerror(errno));
  std::vector<std::uint32_t> ids(bytes.size() / 4);
  for (std::size_t k = 0; k < ids.size(); ++k)  // little-endian whatever the host
    ids[k] = std::uint32_t{bytes[4 * k]} | std::uint32_t{bytes[4 * k + 1]} << 8 |
             std::uint32_t{bytes[4 * k + 2]} << 16 | std::uint32_t{bytes[4 * k + 3]} << 24;
  return ids;
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
