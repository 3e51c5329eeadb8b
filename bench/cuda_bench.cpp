// The cuda backend on a GPU (docs/gpu.md, "The cuda backend"):
//   dense   N objects of the dense ring (0.6 pairs an object), every object active, 32-bit codes:
//           detect() wall time, and the GPU time of each part from CUDA events: the upload of
//           the objects, codes, sort, build, fit, query (traversal), pair sort, the pairs' download.
//           "on the GPU" = codes + sort + build + fit + query + pair sort: the frame with its data
//           already on the device, the way a GPU engine would hold it.
//   frame   N objects of the paper's ring with the camera (zoom-out, 1280x720, lambda = 200,
//           adaptive bits): detect() wall time and the splat, counting and map download.
//   device  N objects of the dense ring through CudaBroadphase (viscd/cuda.hpp): objects already on
//           the device, the frame enqueued on a stream (GPU time between events, and the host's
//           time to enqueue it) and the same frame captured once into a CUDA graph and replayed;
//           the two alternate frame by frame.
// Medians over --frames frames after --warmup; the scene moves every frame.
#include <cuda_runtime.h>

#include <CLI/CLI.hpp>
#include <algorithm>
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
  double pageable_upload = 0;      // the same bytes as the upload, copied from pageable memory (the former path)
  double layout = 0, outside = 0;  // detect(): the host's layout stage; wall time outside every stage
  double stream_gpu = 0, stream_enqueue = 0, graph_gpu = 0, graph_launch = 0;  // device part
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
  std::vector<double> wall, upload, codes, sort, build, fit, query, pair_sort, download, splat, count, map_download,
      layout, outside, pageable;
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
    {  // what the upload cost from pageable memory, before the pinned staging
      void* dst = nullptr;
      const std::size_t bytes = sizeof(Sphere) * n;
      if (cudaMalloc(&dst, bytes) == cudaSuccess) {
        const auto p0 = bench::Clock::now();
        (void)cudaMemcpy(dst, scene.spheres().data(), bytes, cudaMemcpyHostToDevice);
        pageable.push_back(bench::ms_since(p0));
        cudaFree(dst);
      }
    }
    const cuda::Times& t = *detail::cuda_times(d);
    const cuda::SplatTimes& st = *detail::cuda_splat_times(d);
    wall.push_back(ms);
    upload.push_back(t.upload), codes.push_back(t.codes), sort.push_back(t.sort), build.push_back(t.build);
    fit.push_back(t.fit), query.push_back(t.query), pair_sort.push_back(t.pair_sort), download.push_back(t.download);
    splat.push_back(st.splat), count.push_back(st.count), map_download.push_back(st.map_download);
    layout.push_back(out.stats.ms(Stage::layout));
    double staged = 0;
    for (double x : out.stats.stage_ms) staged += x;
    outside.push_back(ms - staged);
  }
  row.pairs = out.pairs.size();
  row.active = out.stats.active;
  using bench::median;
  row.wall = median(wall), row.upload = median(upload), row.codes = median(codes), row.sort = median(sort);
  row.build = median(build), row.fit = median(fit), row.query = median(query), row.pair_sort = median(pair_sort);
  row.download = median(download), row.splat = median(splat), row.count = median(count);
  row.map_download = median(map_download);
  row.layout = median(layout), row.outside = median(outside);
  row.pageable_upload = pageable.empty() ? 0.0 : median(pageable);
  return row;
}

void check(cudaError_t e, const char* what) {
  if (e == cudaSuccess) return;
  std::fprintf(stderr, "viscd_cuda_bench: %s: %s\n", what, cudaGetErrorString(e));
  std::exit(1);
}

void check(const Status& s) {
  if (s) return;
  std::fprintf(stderr, "viscd_cuda_bench: %s\n", s.error().c_str());
  std::exit(1);
}

// CudaBroadphase over the dense ring: the frame enqueued on a stream and replayed as a graph,
// alternating; GPU times between events, host times around the enqueue and the launch.
Row measure_device(std::uint32_t n, int frames, int warmup) {
  Scene scene = Scene::make(SceneParams{.objects = n, .seed = 1, .packing = 0.18f});
  Config c;
  c.bits = Bits::b32;
  auto made = make_cuda_broadphase(c);
  check(made.status());
  CudaBroadphase& bp = *made.value();
  Sphere* spheres = nullptr;
  Pair* pairs = nullptr;
  CudaReport* report = nullptr;
  ObjectState* states = nullptr;
  const std::uint64_t capacity = 2 * std::uint64_t{n};
  check(cudaMalloc(&spheres, sizeof(Sphere) * n), "cudaMalloc");
  check(cudaMalloc(&pairs, sizeof(Pair) * capacity), "cudaMalloc");
  check(cudaMalloc(&report, sizeof(CudaReport)), "cudaMalloc");
  check(cudaMalloc(&states, n), "cudaMalloc");
  cudaStream_t stream = nullptr;
  check(cudaStreamCreateWithFlags(&stream, cudaStreamNonBlocking), "cudaStreamCreate");
  cudaEvent_t ev[2];
  for (cudaEvent_t& e : ev) check(cudaEventCreate(&e), "cudaEventCreate");
  CudaObjects o;
  o.spheres = spheres;
  o.count = n;
  CudaResults r;
  r.pairs = pairs;
  r.capacity = capacity;
  r.report = report;
  r.states = states;
  check(bp.reserve(n, false));
  cudaGraph_t graph = nullptr;
  cudaGraphExec_t exec = nullptr;
  check(cudaStreamBeginCapture(stream, cudaStreamCaptureModeThreadLocal), "cudaStreamBeginCapture");
  check(bp.enqueue(o, r, stream));
  check(cudaStreamEndCapture(stream, &graph), "cudaStreamEndCapture");
  check(cudaGraphInstantiate(&exec, graph, 0), "cudaGraphInstantiate");
  std::vector<double> sg, se, gg, gl;
  CudaReport rep{};
  Row row{"device", n};
  for (int f = 0; f < warmup + frames; ++f) {
    scene.step(1.0f / 60.0f);
    check(cudaMemcpy(spheres, scene.spheres().data(), sizeof(Sphere) * n, cudaMemcpyHostToDevice), "upload");
    for (int as_graph = 0; as_graph < 2; ++as_graph) {
      check(cudaEventRecord(ev[0], stream), "cudaEventRecord");
      const auto t0 = bench::Clock::now();
      if (as_graph)
        check(cudaGraphLaunch(exec, stream), "cudaGraphLaunch");
      else
        check(bp.enqueue(o, r, stream));
      const double host = bench::ms_since(t0);
      check(cudaEventRecord(ev[1], stream), "cudaEventRecord");
      check(cudaEventSynchronize(ev[1]), "cudaEventSynchronize");
      float gpu = 0;
      check(cudaEventElapsedTime(&gpu, ev[0], ev[1]), "cudaEventElapsedTime");
      check(cudaMemcpy(&rep, report, sizeof rep, cudaMemcpyDeviceToHost), "report");
      if (rep.pairs > capacity) {
        std::fprintf(stderr, "viscd_cuda_bench: %llu pairs past the capacity %llu\n", rep.pairs,
                     static_cast<unsigned long long>(capacity));
        std::exit(1);
      }
      if (f < warmup) continue;
      (as_graph ? gg : sg).push_back(gpu);
      (as_graph ? gl : se).push_back(host);
    }
  }
  row.pairs = rep.pairs;
  row.active = n;
  using bench::median;
  row.stream_gpu = median(sg), row.stream_enqueue = median(se), row.graph_gpu = median(gg);
  row.graph_launch = median(gl);
  cudaGraphExecDestroy(exec);
  cudaGraphDestroy(graph);
  for (cudaEvent_t e : ev) cudaEventDestroy(e);
  cudaStreamDestroy(stream);
  cudaFree(spheres), cudaFree(pairs), cudaFree(report), cudaFree(states);
  return row;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app("viscd_cuda_bench: the cuda backend's stages on the GPU (docs/gpu.md)");
  std::vector<std::uint32_t> dense_sizes = {10000, 100000, 1000000, 10000000};
  std::vector<std::uint32_t> frame_sizes = {10000, 100000, 1000000};
  std::vector<std::uint32_t> device_sizes = {10000, 100000, 1000000, 10000000};
  int frames = 20, warmup = 3;
  std::vector<std::string> parts = {"dense", "frame", "device"};
  std::string csv;
  app.add_option("--dense", dense_sizes, "object counts of the dense frames")->delimiter(',')->capture_default_str();
  app.add_option("--frame", frame_sizes, "object counts of the frames with the camera")
      ->delimiter(',')
      ->capture_default_str();
  app.add_option("--device", device_sizes, "object counts of the device-resident frames (CudaBroadphase)")
      ->delimiter(',')
      ->capture_default_str();
  app.add_option("--parts", parts, "which parts to run")
      ->delimiter(',')
      ->check(CLI::IsMember({"dense", "frame", "device"}))
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
  auto wanted = [&](const char* part) { return std::find(parts.begin(), parts.end(), part) != parts.end(); };
  if (wanted("dense"))
    for (std::uint32_t n : dense_sizes) rows.push_back(measure("dense", n, frames, warmup));
  if (wanted("frame"))
    for (std::uint32_t n : frame_sizes) rows.push_back(measure("frame", n, frames, warmup));
  if (wanted("device"))
    for (std::uint32_t n : device_sizes) rows.push_back(measure_device(n, frames, warmup));
  const char* head =
      "part,objects,active,pairs,detect_ms,on_gpu_ms,upload_ms,codes_ms,sort_ms,build_ms,fit_ms,query_ms,pair_sort_ms,"
      "download_ms,splat_ms,count_ms,map_download_ms,pageable_upload_ms,layout_ms,outside_stages_ms,stream_gpu_ms,"
      "stream_enqueue_ms,graph_gpu_ms,"
      "graph_launch_ms";
  std::printf("%s\n", head);
  std::ofstream file;
  if (!csv.empty()) {
    file.open(csv);
    file << head << "\n";
  }
  for (const Row& r : rows) {
    char line[768];
    std::snprintf(
        line, sizeof line,
        "%s,%u,%u,%llu,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,"
        "%.4f,%.4f",
        r.part.c_str(), r.objects, r.active, static_cast<unsigned long long>(r.pairs), r.wall, r.on_gpu(), r.upload,
        r.codes, r.sort, r.build, r.fit, r.query, r.pair_sort, r.download, r.splat, r.count, r.map_download,
        r.pageable_upload, r.layout, r.outside, r.stream_gpu, r.stream_enqueue, r.graph_gpu, r.graph_launch);
    std::printf("%s\n", line);
    if (file) file << line << "\n";
  }
  return 0;
}
