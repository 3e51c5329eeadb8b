// The cuda backend on a GPU (docs/gpu.md, "The cuda backend"):
//   dense   N objects of the dense ring (0.6 pairs an object), every object active, 32-bit codes:
//           detect() wall time, and the GPU time of each part from CUDA events: the upload of
//           the objects, codes, sort, build, fit, query (traversal), pair sort, the pairs' download.
//           "on the GPU" = codes + sort + build + fit + query + pair sort: the frame with its data
//           already on the device, the way a GPU engine would hold it.
//   frame   N objects of the paper's ring with the camera (zoom-out, 1280x720, lambda = 200,
//           adaptive bits): detect() wall time and the splat, counting and map download.
// Medians over --frames frames after --warmup; the scene moves every frame.
#include <CLI/CLI.hpp>
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include "bench_util.hpp"
#include "cuda/cuda_detector.hpp"
#include "viscd/cuda.hpp"
#include "viscd/scene.hpp"
#include "viscd/viscd.hpp"

namespace {

using namespace viscd;

struct Row {
  std::string part;
  std::uint32_t objects = 0;
  std::uint64_t pairs = 0;
  std::uint32_t active = 0;
  double wall = 0, upload = 0, codes = 0, sort = 0, build = 0, fit = 0, query = 0, pair_sort = 0, download = 0,
         splat = 0, count = 0, map_download = 0;
  [[nodiscard]] double on_gpu() const { return codes + sort + build + fit + query + pair_sort; }
};

Row measure(const std::string& part, std::uint32_t n, int frames, int warmup) {
  const bool dense = part == "dense";
  Scene scene = Scene::make(SceneParams{.objects = n, .seed = 1, .packing = dense ? 0.18f : 0.04f});
  Config c = bench::bench_config();
  if (dense) {
    c.culling = false;
    c.bits = Bits::b32;
  }
  auto made = make_cuda_detector(c);
  if (!made) {
    std::fprintf(stderr, "viscd_cuda_bench: %s\n", made.error().c_str());
    std::exit(1);
  }
  Detector& d = *made.value();
  Camera cam;
  if (!dense) {
    auto preset = camera_preset("zoom-out", scene, 1280, 720);
    if (!preset) {
      std::fprintf(stderr, "viscd_cuda_bench: %s\n", preset.error().c_str());
      std::exit(1);
    }
    cam = preset.value();
  }
  std::vector<double> wall, upload, codes, sort, build, fit, query, pair_sort, download, splat, count, map_download;
  Row row{part, n};
  FrameResult out;
  for (int f = 0; f < warmup + frames; ++f) {
    scene.step(1.0f / 60.0f);
    FrameInput in;
    in.spheres = scene.spheres();
    if (!dense) in.camera = &cam;
    const auto t0 = bench::Clock::now();
    if (Status s = d.detect(in, out); !s) {
      std::fprintf(stderr, "viscd_cuda_bench: %s\n", s.error().c_str());
      std::exit(1);
    }
    const double ms = bench::ms_since(t0);
    if (f < warmup) continue;
    const cuda::Times& t = *detail::cuda_times(d);
    wall.push_back(ms);
    upload.push_back(t.upload), codes.push_back(t.codes), sort.push_back(t.sort), build.push_back(t.build);
    fit.push_back(t.fit), query.push_back(t.query), pair_sort.push_back(t.pair_sort), download.push_back(t.download);
    splat.push_back(t.splat), count.push_back(t.count), map_download.push_back(t.map_download);
  }
  row.pairs = out.pairs.size();
  row.active = out.stats.active;
  using bench::median;
  row.wall = median(wall), row.upload = median(upload), row.codes = median(codes), row.sort = median(sort);
  row.build = median(build), row.fit = median(fit), row.query = median(query), row.pair_sort = median(pair_sort);
  row.download = median(download), row.splat = median(splat), row.count = median(count);
  row.map_download = median(map_download);
  return row;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app("viscd_cuda_bench: the cuda backend's stages on the GPU (docs/gpu.md)");
  std::vector<std::uint32_t> dense_sizes = {10000, 100000, 1000000, 10000000};
  std::vector<std::uint32_t> frame_sizes = {10000, 100000, 1000000};
  int frames = 20, warmup = 3;
  std::string csv;
  app.add_option("--dense", dense_sizes, "object counts of the dense frames")->delimiter(',')->capture_default_str();
  app.add_option("--frame", frame_sizes, "object counts of the frames with the camera")
      ->delimiter(',')
      ->capture_default_str();
  app.add_option("--frames", frames, "timed frames per point")->check(CLI::PositiveNumber)->capture_default_str();
  app.add_option("--warmup", warmup, "untimed frames first")->check(CLI::NonNegativeNumber)->capture_default_str();
  app.add_option("--csv", csv, "also write the table here");
  CLI11_PARSE(app, argc, argv);
  const auto device = cuda_device();
  if (!device) {
    std::fprintf(stderr, "viscd_cuda_bench: %s\n", device.error().c_str());
    return 1;
  }
  std::printf("device: %s\n", device.value().c_str());
  std::vector<Row> rows;
  for (std::uint32_t n : dense_sizes) rows.push_back(measure("dense", n, frames, warmup));
  for (std::uint32_t n : frame_sizes) rows.push_back(measure("frame", n, frames, warmup));
  const char* head =
      "part,objects,active,pairs,detect_ms,on_gpu_ms,upload_ms,codes_ms,sort_ms,build_ms,fit_ms,query_ms,pair_sort_ms,"
      "download_ms,splat_ms,count_ms,map_download_ms";
  std::printf("%s\n", head);
  std::ofstream file;
  if (!csv.empty()) {
    file.open(csv);
    file << head << "\n";
  }
  for (const Row& r : rows) {
    char line[512];
    std::snprintf(line, sizeof line, "%s,%u,%u,%llu,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f",
                  r.part.c_str(), r.objects, r.active, static_cast<unsigned long long>(r.pairs), r.wall, r.on_gpu(),
                  r.upload, r.codes, r.sort, r.build, r.fit, r.query, r.pair_sort, r.download, r.splat, r.count,
                  r.map_download);
    std::printf("%s\n", line);
    if (file) file << line << "\n";
  }
  return 0;
}
