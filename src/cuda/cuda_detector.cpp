// The cuda backend (viscd/cuda.hpp, docs/gpu.md): the CPU pipeline's frame (pipeline.hpp) with
// stage 1 (and the counting of stage 2) and stages 4-8 on the GPU (gpu.hpp).
#include <algorithm>
#include <cstddef>
#include <cstring>
#include <string>
#include <utility>
#include <vector>

#include "core/frame_rules.hpp"
#include "core/morton.hpp"
#include "core/stopwatch.hpp"
#include "cpu/morton_order.hpp"
#include "cpu/parallel.hpp"
#include "cpu/pipeline.hpp"
#include "cuda/cuda_detector.hpp"
#include "cuda/gpu.hpp"
#include "viscd/cuda.hpp"

namespace viscd {
namespace detail {
namespace {

static_assert(sizeof(Sphere) == 16 && sizeof(Box) == 24 && sizeof(Filter) == 8 && sizeof(Pair) == 8);

cuda::Rig to_rig(const CameraRig& c) {
  cuda::Rig r{};
  const Vec3* v[4] = {&c.eye, &c.forward, &c.right, &c.up};
  float* out[4] = {r.eye, r.forward, r.right, r.up};
  for (int k = 0; k < 4; ++k) {
    out[k][0] = v[k]->x;
    out[k][1] = v[k]->y;
    out[k][2] = v[k]->z;
  }
  r.tan_half_x = c.tan_half_x;
  r.tan_half_y = c.tan_half_y;
  r.near_plane = c.near_plane;
  r.far_plane = c.far_plane;
  r.map_w = c.map_w;
  r.map_h = c.map_h;
  return r;
}

cuda::Grid to_grid(const MortonLayout& layout, const Aabb& bounds) {
  const MortonGrid g = morton_grid(layout, bounds);
  cuda::Grid out{};
  for (int a = 0; a < 3; ++a) {
    out.lo[a] = g.lo[static_cast<std::size_t>(a)];
    out.scale[a] = g.scale[static_cast<std::size_t>(a)];
    out.max_cell[a] = g.max_cell[static_cast<std::size_t>(a)];
    out.axis_bits[a] = layout.axis_bits[static_cast<std::size_t>(a)];
    for (int b = 0; b < 32; ++b)
      out.position[a][b] = layout.position[static_cast<std::size_t>(a)][static_cast<std::size_t>(b)];
  }
  out.bits = layout.bits;
  return out;
}

Status to_status(const cuda::Outcome& o, std::size_t objects, const Config& config) {
  if (o.out_of_memory)
    return Status::failure(ErrorKind::out_of_memory,
                           out_of_memory_message(objects, nullptr, config) + " (GPU memory; " + o.error + ")");
  return Status::failure(ErrorKind::backend_failure, o.error);
}

class CudaDetector final : public PipelineDetector {
 public:
  explicit CudaDetector(const Config& config) : PipelineDetector(config) {}
  [[nodiscard]] std::string_view name() const override { return "cuda"; }
  [[nodiscard]] const cuda::Times& times() const { return times_; }
  [[nodiscard]] const cuda::SplatTimes& splat_times() const { return splat_times_; }
  void set_chunk_limit(unsigned long long limit) { gpu_.set_chunk_limit(limit); }
  [[nodiscard]] std::uint64_t backend_memory_bytes() const override { return gpu_.bytes(); }

 private:
  // Stage 1 on the GPU; the map's ids (and, for shading, depths and then normals) and the
  // pixel counts come back. Without shading nothing reads the map's depths: they are left as they are.
  Status rasterize(const CameraRig& cam, const Shapes& objects, int threads) override {
    map_.stamp = 0;
    map_.has_counts = false;
    const bool boxes = objects.is_box();
    const float* data = boxes ? reinterpret_cast<const float*>(objects.boxes.data())
                              : reinterpret_cast<const float*>(objects.spheres.data());
    const auto count = static_cast<std::uint32_t>(objects.size());
    map_.counts.resize(count);
    const bool shading = !map_.normal.empty();
    splat_times_ = cuda::SplatTimes{};
    splatted_ = true;
    const cuda::Outcome o = gpu_.splat(to_rig(cam), data, boxes, count, map_.ids.data(),
                                       shading ? map_.depth.data() : nullptr, map_.counts.data(), splat_times_);
    if (!o.ok()) return to_status(o, objects.size(), config_);
    map_.has_counts = true;
    if (shading) {
      parallel_for(static_cast<std::size_t>(map_.height), threads, [&](std::size_t y) {
        for (int x = 0; x < map_.width; ++x) write_normal(cam, objects, map_, x, static_cast<int>(y));
      });
    }
    return {};
  }

  Status broadphase(const Shapes& objects, std::span<const std::uint32_t> pairable, std::span<const std::uint32_t>,
                    std::span<const Filter> filters, std::uint32_t static_from, int bits, int threads,
                    std::vector<Pair>& pairs, FrameStats& stats) override {
    ActiveExtent extent;
    const MortonLayout layout = layout_stage(objects, pairable, bits, config_.layout, threads, extent, stats);
    Stopwatch sw;
    // The objects that take part, packed into pinned memory on the frame's threads: spheres (a
    // box's proxy) and boxes, with their frame indices unless they are all of the frame's objects
    // in order, and the filters.
    const std::size_t n = pairable.size();
    const bool all = n == objects.size();
    const bool boxes = objects.is_box();
    cuda::Staging st;
    const cuda::Outcome staged =
        gpu_.staging(static_cast<std::uint32_t>(n), boxes, !all, static_cast<std::uint32_t>(filters.size()), st);
    if (!staged.ok()) return to_status(staged, objects.size(), config_);
    auto* spheres = reinterpret_cast<Sphere*>(st.spheres);
    auto* packed_boxes = reinterpret_cast<Box*>(st.boxes);
    parallel_for(n, threads, [&](std::size_t k) {
      const std::size_t i = all ? k : pairable[k];
      spheres[k] = objects.proxy(i);
      if (boxes) packed_boxes[k] = objects.boxes[i];
      if (!all) st.ids[k] = pairable[k];
    });
    if (!filters.empty()) {
      auto* packed_filters = reinterpret_cast<Filter*>(st.filters);
      parallel_for(filters.size(), threads, [&](std::size_t k) { packed_filters[k] = filters[k]; });
    }
    cuda::BroadphaseInput in;
    in.n = static_cast<std::uint32_t>(n);
    in.total = static_cast<std::uint32_t>(objects.size());
    in.static_from = static_from;
    in.spheres = st.spheres;
    in.boxes = st.boxes;
    in.ids = st.ids;
    in.filters = st.filters;
    const double host_ms = sw.lap();

    // The pairs, copied out of the pinned download on the frame's threads.
    struct Sink {
      std::vector<Pair>* pairs;
      int threads;
      static void take(void* self, const std::uint32_t* words, std::size_t count) {
        auto* s = static_cast<Sink*>(self);
        s->pairs->resize(count);
        const auto* from = reinterpret_cast<const Pair*>(words);
        Pair* to = s->pairs->data();
        for_chunks(count, ranges_for(count, s->threads),
                   [&](std::size_t b, std::size_t e, std::size_t) { std::copy(from + b, from + e, to + b); });
      }
    } sink{&pairs, threads};
    if (!std::exchange(splatted_, false)) splat_times_ = cuda::SplatTimes{};
    const std::size_t cap = pairs_within_cap(config_.pair_memory_cap);
    const cuda::Outcome o = gpu_.broadphase(in, to_grid(layout, extent.bounds), cap, &Sink::take, &sink, times_);
    if (o.over_limit) return check_pair_cap(o.pairs, config_.pair_memory_cap);
    if (!o.ok()) return to_status(o, objects.size(), config_);
    // GPU times by stage; the packing on the host and the upload count as the codes' stage.
    const cuda::Times& t = times_;
    stats.ms(Stage::codes) = host_ms + t.upload + t.codes;
    stats.ms(Stage::sort) = t.sort;
    stats.ms(Stage::build) = t.build;
    stats.ms(Stage::fit) = t.fit;
    stats.ms(Stage::query) = t.query + t.pair_sort + t.download;
    return {};
  }

  cuda::Gpu gpu_;
  cuda::Times times_;
  cuda::SplatTimes splat_times_;  // zero on frames without a map
  bool splatted_ = false;         // this frame ran rasterize()
};

// The device-resident frame (viscd/cuda.hpp): the arguments checked on the host, the frame
// enqueued by cuda::DeviceFrame.
static_assert(sizeof(CudaReport) == sizeof(cuda::Report) &&
              offsetof(CudaReport, pairs) == offsetof(cuda::Report, pairs) &&
              offsetof(CudaReport, invalid) == offsetof(cuda::Report, invalid) &&
              offsetof(CudaReport, first_invalid) == offsetof(cuda::Report, first_invalid) &&
              offsetof(CudaReport, bits) == offsetof(cuda::Report, bits) &&
              offsetof(CudaReport, objects) == offsetof(cuda::Report, objects));
static_assert(sizeof(ObjectState) == 1);

class CudaBroadphaseImpl final : public CudaBroadphase {
 public:
  explicit CudaBroadphaseImpl(const Config& config)
      : bits_(config.bits == Bits::adaptive ? 32 : static_cast<int>(config.bits)),
        plain_(config.layout == Layout::plain) {}

  Status reserve(std::uint32_t objects, bool boxes) override {
    if (Status s = check_count(objects); !s) return s;
    const cuda::Outcome o = frame_.reserve(objects, boxes, bits_);
    return o.ok() ? Status{} : failure(o, objects);
  }

  Status enqueue(const CudaObjects& objects, const CudaResults& results, CUstream_st* stream) override {
    const std::uint32_t n = objects.count;
    if (Status s = check_count(n); !s) return s;
    if (n > 0 && (objects.spheres == nullptr) == (objects.boxes == nullptr))
      return invalid(objects.spheres
                         ? "CudaObjects: spheres and boxes are both given; give one kind"
                         : "CudaObjects: count is " + std::to_string(n) + " but neither spheres nor boxes is given");
    if (results.report == nullptr)
      return invalid("CudaResults::report is null; the frame needs somewhere to write its count");
    if (results.capacity > 0 && results.pairs == nullptr)
      return invalid("CudaResults::pairs is null with a capacity of " + std::to_string(results.capacity));
    if (objects.static_from != 0xFFFFFFFFu && objects.static_from > n)
      return invalid("CudaObjects::static_from is " + std::to_string(objects.static_from) + ", past count " +
                     std::to_string(n) + " (0xFFFFFFFF makes no object static)");
    struct Field {
      const void* p;
      std::size_t align;
      const char* name;
    };
    const Field fields[] = {{n ? objects.spheres : nullptr, 16, "CudaObjects::spheres"},
                            {n ? objects.boxes : nullptr, 4, "CudaObjects::boxes"},
                            {n ? objects.filters : nullptr, 8, "CudaObjects::filters"},
                            {results.capacity ? results.pairs : nullptr, 8, "CudaResults::pairs"},
                            {results.report, 8, "CudaResults::report"},
                            {n ? results.states : nullptr, 1, "CudaResults::states"}};
    for (const Field& f : fields) {
      if (f.p == nullptr) continue;
      if (reinterpret_cast<std::uintptr_t>(f.p) % f.align != 0)
        return invalid(std::string(f.name) + " is not " + std::to_string(f.align) + "-byte aligned");
      if (const std::string problem = cuda::device_memory_problem(f.p); !problem.empty())
        return invalid(std::string(f.name) + " points to " + problem +
                       "; CudaBroadphase takes device memory (Detector::detect() takes host arrays)");
    }
    cuda::DeviceInput in;
    in.spheres = reinterpret_cast<const float*>(objects.spheres);
    in.boxes = reinterpret_cast<const float*>(objects.boxes);
    in.filters = reinterpret_cast<const std::uint32_t*>(objects.filters);
    in.n = n;
    in.static_from = objects.static_from;
    in.bits = bits_;
    in.plain_layout = plain_;
    cuda::DeviceOutput out;
    out.pairs = reinterpret_cast<std::uint32_t*>(results.pairs);
    out.capacity = results.capacity;
    out.report = reinterpret_cast<cuda::Report*>(results.report);
    out.states = reinterpret_cast<std::uint8_t*>(results.states);
    const cuda::Outcome o = frame_.enqueue(in, out, stream);
    return o.ok() ? Status{} : failure(o, n);
  }

  [[nodiscard]] std::uint64_t memory_bytes() const override { return frame_.bytes(); }

 private:
  static Status invalid(const std::string& what) { return Status::failure(ErrorKind::invalid_input, what); }
  static Status check_count(std::uint32_t n) {
    if (n > 0x7FFFFFFFu)
      return invalid("CudaObjects::count is " + std::to_string(n) + "; a frame takes at most 2^31 - 1 objects");
    return {};
  }
  static Status failure(const cuda::Outcome& o, std::size_t objects) {
    if (o.out_of_memory)
      return Status::failure(ErrorKind::out_of_memory, "CudaBroadphase: " + std::to_string(objects) +
                                                           " objects need more GPU memory than is free (" + o.error +
                                                           ")");
    return Status::failure(ErrorKind::backend_failure, "CudaBroadphase: " + o.error);
  }

  int bits_;
  bool plain_;
  cuda::DeviceFrame frame_;
};

}  // namespace
}  // namespace detail

namespace detail {
const cuda::Times* cuda_times(const Detector& detector) {
  const auto* d = dynamic_cast<const CudaDetector*>(&DetectorAccess::backend(detector));
  return d ? &d->times() : nullptr;
}

const cuda::SplatTimes* cuda_splat_times(const Detector& detector) {
  const auto* d = dynamic_cast<const CudaDetector*>(&DetectorAccess::backend(detector));
  return d ? &d->splat_times() : nullptr;
}

bool set_cuda_chunk_limit(Detector& detector, unsigned long long limit) {
  auto* d = dynamic_cast<CudaDetector*>(&DetectorAccess::backend(detector));
  if (d) d->set_chunk_limit(limit);
  return d != nullptr;
}
}  // namespace detail

Result<std::unique_ptr<CudaBroadphase>> make_cuda_broadphase(const Config& config) {
  using R = Result<std::unique_ptr<CudaBroadphase>>;
  if (auto device = cuda_device(); !device) return R::failure(device.status());
  if (config.bits != Bits::adaptive && config.bits != Bits::b16 && config.bits != Bits::b32 && config.bits != Bits::b64)
    return R::failure(ErrorKind::invalid_input, "Config::bits is " + std::to_string(static_cast<int>(config.bits)) +
                                                    "; expected adaptive, 16, 32 or 64");
  return std::unique_ptr<CudaBroadphase>(std::make_unique<detail::CudaBroadphaseImpl>(config));
}

Result<std::string> cuda_device() {
  std::string description;
  const cuda::Outcome o = cuda::Gpu::probe(description);
  if (!o.ok()) return Result<std::string>::failure(ErrorKind::backend_failure, "no usable CUDA device: " + o.error);
  return description;
}

Result<std::unique_ptr<Detector>> make_cuda_detector(const Config& config) {
  using R = Result<std::unique_ptr<Detector>>;
  if (auto device = cuda_device(); !device) return R::failure(device.status());
  return detail::DetectorAccess::wrap(std::make_unique<detail::CudaDetector>(config));
}

}  // namespace viscd
