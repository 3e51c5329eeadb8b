// `viscd bench paper` and `viscd bench peers`: the paper's experiments, and the peer comparison.
#include <sys/wait.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <cerrno>
#include <cstring>

#include <chrono>
#include <cinttypes>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "commands.hpp"
#include "detector_choice.hpp"
#include "exit_codes.hpp"
#include "options.hpp"
#include "progress.hpp"
#include "statistics.hpp"
#include "viscd/cuda.hpp"
#include "viscd/io.hpp"
#include "viscd/scene.hpp"

#ifndef VISCD_SOURCE_DIR
#define VISCD_SOURCE_DIR "."
#endif

namespace viscd::app {
namespace {

using Clock = std::chrono::steady_clock;

struct BenchArgs {
  std::vector<std::string> backends;  // empty: every backend available here
  std::vector<std::uint32_t> sizes = {1000, 2000, 5000, 10000, 20000, 50000, 100000};
  int frames = 20;
  int warmup = 3;
  std::string out = "viscd-results";
  bool no_plots = false;
  std::vector<std::string> peer_args;
};

// The detector of one measurement: the backend by name, default gl options, no message.
Result<std::unique_ptr<Detector>> make_bench_detector(const std::string& backend, const Config& config) {
  DetectorRequest request;
  request.backend = backend;
  request.quiet = true;
  auto chosen = make_tool_detector(request, config);
  if (!chosen) return Result<std::unique_ptr<Detector>>::failure(chosen.status());
  return std::move(chosen.value().detector);
}

struct Point {
  double frame_ms = 0;  // median wall time of step + detect
  FrameStats last;
  std::array<double, kStageCount> stage_ms{};  // medians
  std::uint64_t memory = 0;
};

// Runs `frames` frames (after warm-up) of the ring scene and returns medians.
Result<Point> measure(const std::string& backend, Config config, std::uint32_t n, const std::string& camera, int frames,
                      int warmup) {
  auto det = make_bench_detector(backend, config);
  if (!det) return Result<Point>::failure(det.status());
  Scene scene = Scene::make({.objects = n});
  std::vector<double> wall;
  std::array<std::vector<double>, kStageCount> stages;
  FrameResult f;
  for (int k = 0; k < warmup + frames; ++k) {
    const auto t0 = Clock::now();
    scene.step(1.0f / 60.0f);
    auto cam = camera_preset(camera, scene, 1280, 720);
    if (!cam) return Result<Point>::failure(cam.status());
    if (Status s = det.value()->detect(scene.spheres(), &cam.value(), f); !s) return Result<Point>::failure(s);
    const double ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
    if (k < warmup) continue;
    wall.push_back(ms);
    for (std::size_t s = 0; s < kStageCount; ++s) stages[s].push_back(f.stats.stage_ms[s]);
  }
  Point p;
  p.frame_ms = median(wall);
  p.last = f.stats;
  for (std::size_t s = 0; s < kStageCount; ++s) p.stage_ms[s] = median(stages[s]);
  p.memory = det.value()->memory_bytes();
  return p;
}

std::vector<std::string> available_backends() {
  std::vector<std::string> b = {"cpu"};
  if (gl_device()) b.push_back("gl");
  if (cuda_device()) b.push_back("cuda");
  return b;
}

// A file that ships with viscd: installed under <prefix>/share/viscd beside <prefix>/bin/viscd,
// or in the source tree of this build. Empty when neither exists.
std::filesystem::path shipped_file(const std::string& name) {
  namespace fs = std::filesystem;
  std::error_code ec;
  const fs::path self = fs::read_symlink("/proc/self/exe", ec);
  for (const fs::path& candidate :
       {self.parent_path().parent_path() / "share" / "viscd" / name, fs::path(VISCD_SOURCE_DIR) / "bench" / name})
    if (!self.empty() && fs::exists(candidate, ec)) return candidate;
  return {};
}

int run_paper(const BenchArgs& a) {
  namespace fs = std::filesystem;
  const std::vector<std::string> backends = a.backends.empty() ? available_backends() : a.backends;
  const fs::path out(a.out);
  std::error_code ec;
  fs::create_directories(out, ec);
  if (ec) return fail(out.string() + ": cannot create folder: " + ec.message());

  std::ostringstream t1, t2, f6, f7, f8;
  t1 << "backend,stage,median_ms,share_of_build\n";
  t2 << "backend,objects,bits,layout,sort_ms,ratio_to_16\n";
  f6 << "backend,objects,culling,frame_ms,fps,active,mean_pixels,bits\n";
  f7 << "backend,objects,mode,frame_ms,fps,bits\n";
  f8 << "backend,objects,culling,memory_bytes\n";

  const std::size_t steps = backends.size() * (1 + 6 + 2 + a.sizes.size() * 5);
  Progress progress("bench paper", steps, false);
  std::size_t done = 0;
  auto tick = [&](const std::string& what) { progress.update(++done, what); };
  auto check = [&](const Result<Point>& p, const std::string& what) -> bool {
    if (!p) {
      progress.finish();
      fail(what + ": " + p.error());
    }
    return p.ok();
  };

  for (const std::string& be : backends) {
    // Table 1: split of the LBVH construction, 2000 objects, 32-bit codes, all active.
    Config c;
    c.bits = Bits::b32;
    c.culling = false;
    auto p = measure(be, c, 2000, "zoom-out", a.frames, a.warmup);
    if (!check(p, be + " table 1")) return 1;
    const Stage build_stages[] = {Stage::codes, Stage::sort, Stage::build, Stage::fit};
    double build_total = 0;
    for (Stage s : build_stages) build_total += p.value().stage_ms[static_cast<std::size_t>(s)];
    for (Stage s : build_stages) {
      const double ms = p.value().stage_ms[static_cast<std::size_t>(s)];
      t1 << be << ',' << stage_name(s) << ',' << ms << ',' << (build_total > 0 ? ms / build_total : 0) << '\n';
    }
    tick(be + " table 1");

    // Table 2: sort time by bit count, at the paper's 2000 objects and at 100 000.
    for (std::uint32_t n : {2000u, 100000u}) {
      double sort16 = 0;
      for (Bits bits : {Bits::b16, Bits::b32, Bits::b64}) {
        Config cb;
        cb.bits = bits;
        cb.culling = false;
        auto q = measure(be, cb, n, "zoom-out", a.frames, a.warmup);
        if (!check(q, be + " table 2")) return 1;
        const double ms = q.value().stage_ms[static_cast<std::size_t>(Stage::sort)];
        if (bits == Bits::b16) sort16 = ms;
        t2 << be << ',' << n << ',' << static_cast<int>(bits) << ',' << format_layout(q.value().last.layout) << ','
           << ms << ',' << (sort16 > 0 ? ms / sort16 : 0) << '\n';
        tick(be + " table 2");
      }
    }

    // Fig. 5: screenshots, 2000 objects, zoom-out and zoom-in.
    for (const char* cam : {"zoom-out", "zoom-in"}) {
      Config cs;
      cs.shade = true;
      auto det = make_bench_detector(be, cs);
      if (!det) return fail(det.error());
      Scene scene = Scene::make({.objects = 2000});
      scene.step(1.0f / 60.0f);
      const Camera camera = camera_preset(cam, scene, 1280, 720).value();
      FrameResult f;
      if (Status s = det.value()->detect(scene.spheres(), &camera, f); !s) return fail(s.error());
      const fs::path png = out / ("fig5_" + be + "_" + cam + ".png");
      if (Status s = write_png(png, f.image, f.image_width, f.image_height); !s) return fail(s.error());
      tick(be + " fig 5");
    }

    // Fig. 6 (culling on/off), Fig. 7 (adaptive vs fixed 32 / 64), Fig. 8 (memory): N sweep.
    for (std::uint32_t n : a.sizes) {
      for (bool culling : {true, false}) {
        // Off is the paper's baseline: every object, fixed 64-bit codes, and so no visibility map.
        Config cc;
        cc.culling = culling;
        if (!culling) cc.bits = Bits::b64;
        auto q = measure(be, cc, n, "zoom-out", a.frames, a.warmup);
        if (!check(q, be + " fig 6")) return 1;
        const Point& pt = q.value();
        f6 << be << ',' << n << ',' << (culling ? "on" : "off") << ',' << pt.frame_ms << ',' << 1000.0 / pt.frame_ms
           << ',' << pt.last.active << ',' << pt.last.mean_pixels << ',' << pt.last.bits << '\n';
        f8 << be << ',' << n << ',' << (culling ? "on" : "off") << ',' << pt.memory << '\n';
        if (culling)  // the adaptive point of Fig. 7 is the culled frame with adaptive bits
          f7 << be << ',' << n << ",adaptive," << pt.frame_ms << ',' << 1000.0 / pt.frame_ms << ',' << pt.last.bits
             << '\n';
        tick(be + " N=" + std::to_string(n));
      }
      for (Bits bits : {Bits::b32, Bits::b64}) {
        Config cf;
        cf.bits = bits;
        auto q = measure(be, cf, n, "zoom-out", a.frames, a.warmup);
        if (!check(q, be + " fig 7")) return 1;
        f7 << be << ',' << n << ",fixed" << static_cast<int>(bits) << ',' << q.value().frame_ms << ','
           << 1000.0 / q.value().frame_ms << ',' << static_cast<int>(bits) << '\n';
        tick(be + " N=" + std::to_string(n));
      }
    }
  }
  progress.finish();

  const std::pair<const char*, std::ostringstream*> files[] = {
      {"table1.csv", &t1}, {"table2.csv", &t2}, {"fig6.csv", &f6}, {"fig7.csv", &f7}, {"fig8.csv", &f8}};
  for (const auto& [name, text] : files)
    if (Status s = write_text(out / name, text->str()); !s) return fail(s.error());
  std::printf("wrote table1.csv, table2.csv, fig5_*.png, fig6.csv, fig7.csv, fig8.csv into %s\n", out.c_str());
  if (!a.no_plots) {
    const fs::path script = shipped_file("plot_paper.py");
    if (script.empty()) {
      std::fprintf(stderr, "viscd: plots skipped: plot_paper.py is neither in <prefix>/share/viscd nor in %s/bench\n",
                   VISCD_SOURCE_DIR);
    } else {
      // Debian's matplotlib belongs to the system python; prefer it over another python3 on PATH.
      // Arguments go through fork/exec, not a shell: no quoting of the paths is needed.
      const std::string python = fs::exists("/usr/bin/python3") ? "/usr/bin/python3" : "python3";
      std::fflush(stdout);
      const pid_t pid = fork();
      if (pid == 0) {
        execlp(python.c_str(), python.c_str(), script.c_str(), out.c_str(), static_cast<char*>(nullptr));
        _exit(127);
      }
      int status = 0;
      if (pid < 0 || waitpid(pid, &status, 0) < 0 || !WIFEXITED(status) || WEXITSTATUS(status) != 0)
        std::fprintf(stderr, "viscd: plots skipped (needs python3 with matplotlib: scripts/setup.sh installs it)\n");
    }
  }
  return kExitOk;
}

int run_peers(const BenchArgs& a) {
  // The peers driver links Bullet and FCL; it lives next to this binary (bench/, VISCD_BUILD_BENCH).
  namespace fs = std::filesystem;
  std::error_code ec;
  const fs::path self = fs::read_symlink("/proc/self/exe", ec);
  const fs::path dir = self.parent_path();
  for (const fs::path& candidate :
       {dir / "viscd_peers", dir / "bench" / "viscd_peers", dir.parent_path() / "libexec" / "viscd" / "viscd_peers"}) {
    if (!fs::exists(candidate)) continue;
    std::vector<std::string> args = {candidate.string()};
    args.insert(args.end(), a.peer_args.begin(), a.peer_args.end());
    std::vector<char*> argv;
    for (auto& s : args) argv.push_back(s.data());
    argv.push_back(nullptr);
    std::fflush(stdout);
    execv(argv[0], argv.data());
    return fail("cannot run " + printable(candidate.string(), 200) + ": " + std::strerror(errno));
  }
  return fail(
      "viscd_peers not found beside viscd nor in <prefix>/libexec/viscd: build with -DVISCD_BUILD_BENCH=ON (needs "
      "libbullet-dev, libfcl-dev)");
}

}  // namespace

void add_bench_command(CLI::App& app, int& rc) {
  auto args = std::make_shared<BenchArgs>();
  CLI::App* bench =
      app.add_subcommand("bench", "The paper's experiments and the peer comparison, as CSV and PNG plots.");
  bench->require_subcommand(1);
  CLI::App* paper = bench->add_subcommand(
      "paper",
      "For each backend on this machine (cpu; gl when an OpenGL 4.5 context exists; cuda with a GPU): Table 1 (stage\n"
      "split of the LBVH build, 2000 objects, 32 bits), Table 2 (sort time for 16/32/64 bits), Fig. 5\n"
      "(screenshots zoom-out and zoom-in), Fig. 6 (FPS against N with culling, lambda = 200, and without:\n"
      "every object, 64-bit codes, no visibility map),\n"
      "Fig. 7 (adaptive bits against fixed 32 and 64, a = 100, b = 400) and Fig. 8 (memory against N).\n"
      "Writes CSVs and PNG plots into --out. Frame times are wall-clock medians of simulate + detect.");
  paper
      ->add_option("--backend", args->backends,
                   "backends to run, of cpu, reference, gl, cuda (default: every one available)")
      ->delimiter(',')
      ->check(CLI::IsMember({"cpu", "reference", "gl", "cuda"}));
  paper->add_option("--sizes", args->sizes, "object counts for Figs. 6-8, each 1 to 100 000 000")
      ->delimiter(',')
      ->check(CLI::Range(std::uint32_t{1}, kMaxObjects))
      ->capture_default_str();
  paper->add_option("--frames", args->frames, "measured frames per point (median), at least 1")
      ->check(CLI::Range(1, 1'000'000))
      ->capture_default_str();
  paper->add_option("--warmup", args->warmup, "unmeasured frames before each point")
      ->check(CLI::Range(0, 1'000'000))
      ->capture_default_str();
  paper->add_option("--out", args->out, "results folder")->capture_default_str();
  paper->add_flag("--no-plots", args->no_plots, "write CSVs only");
  paper->callback([args, &rc] { rc = run_paper(*args); });
  CLI::App* peers = bench->add_subcommand(
      "peers",
      "viscd against Bullet (btDbvtBroadphase, bt32BitAxisSweep3) and FCL (DynamicAABBTree) on the\n"
      "same moving scene, in one process; arguments after -- go to the driver (try -- --help).");
  // Everything after `peers` (main() drops a `--` right after it) belongs to the driver, --help
  // too: the driver's help lists its options (`viscd bench --help` describes the command).
  peers->prefix_command();
  peers->set_help_flag();
  peers->callback([args, peers, &rc] {
    args->peer_args = peers->remaining();
    rc = run_peers(*args);
  });
}

}  // namespace viscd::app
