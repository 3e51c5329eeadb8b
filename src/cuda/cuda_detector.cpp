// The cuda backend (viscd/cuda.hpp, docs/gpu.md): the CPU pipeline's frame (pipeline.hpp) with
// stage 1 (and the counting of stage 2) and stages 4-8 on the GPU (gpu.hpp).
#include <algorithm>
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
  [[nodiscard]] std::uint64_t backend_memory_bytes() const override {
    return gpu_.bytes() + bytes_of(spheres_) + bytes_of(boxes_);
  }

 private:
  // Stage 1 on the GPU; the map's ids (and, for shading, depths and then normals) and the
  // pixel counts come back. A failure is kept for broadphase(), the next step that can report it.
  void rasterize(const CameraRig& cam, const Shapes& objects, int threads) override {
    map_.stamp = 0;
    map_.has_counts = false;
    const bool boxes = objects.is_box();
    const float* data = boxes ? reinterpret_cast<const float*>(objects.boxes.data())
                              : reinterpret_cast<const float*>(objects.spheres.data());
    const auto count = static_cast<std::uint32_t>(objects.size());
    map_.counts.resize(count);
    const bool shading = !map_.normal.empty();
    times_ = cuda::Times{};
    splatted_ = true;
    const cuda::Outcome o = gpu_.splat(to_rig(cam), data, boxes, count, map_.ids.data(),
                                       shading ? map_.depth.data() : nullptr, map_.counts.data(), times_);
    if (!o.ok()) {
      // An empty map and no counts, so that the pipeline's next stages run harmlessly up to
      // broadphase(), which reports the error.
      splat_error_ = o;
      std::fill(map_.ids.begin(), map_.ids.end(), 0u);
      std::fill(map_.counts.begin(), map_.counts.end(), 0u);
      map_.has_counts = true;
      return;
    }
    map_.has_counts = true;
    if (shading) {
      parallel_for(static_cast<std::size_t>(map_.height), threads, [&](std::size_t y) {
        for (int x = 0; x < map_.width; ++x) write_normal(cam, objects, map_, x, static_cast<int>(y));
      });
    } else {
      // No depths came back: the map holds ids only (nothing reads its depths without shading).
      std::fill(map_.depth.begin(), map_.depth.end(), cam.far_plane);
    }
  }

  Status broadphase(const Shapes& objects, std::span<const std::uint32_t> pairable, std::span<const std::uint32_t>,
                    std::span<const Filter> filters, std::uint32_t static_from, int bits, int threads,
                    std::vector<Pair>& pairs, FrameStats& stats) override {
    if (!splat_error_.ok()) {
      const cuda::Outcome o = std::exchange(splat_error_, cuda::Outcome{});
      return to_status(o, objects.size(), config_);
    }
    ActiveExtent extent;
    const MortonLayout layout = layout_stage(objects, pairable, bits, config_.layout, threads, extent, stats);
    Stopwatch sw;
    // The objects that take part, packed: spheres (a box's proxy) and boxes, with their frame
    // indices unless they are all of the frame's objects in order.
    const std::size_t n = pairable.size();
    const bool all = n == objects.size();
    cuda::BroadphaseInput in;
    in.n = static_cast<std::uint32_t>(n);
    in.total = static_cast<std::uint32_t>(objects.size());
    in.static_from = static_from;
    in.filters = filters.empty() ? nullptr : reinterpret_cast<const std::uint32_t*>(filters.data());
    if (objects.is_box()) {
      spheres_.resize(n);
      boxes_.resize(n);
      parallel_for(n, threads, [&](std::size_t k) {
        const std::size_t i = all ? k : pairable[k];
        spheres_[k] = objects.proxy(i);
        boxes_[k] = objects.boxes[i];
      });
      in.spheres = reinterpret_cast<const float*>(spheres_.data());
      in.boxes = reinterpret_cast<const float*>(boxes_.data());
    } else if (all) {
      in.spheres = reinterpret_cast<const float*>(objects.spheres.data());
    } else {
      spheres_.resize(n);
      parallel_for(n, threads, [&](std::size_t k) { spheres_[k] = objects.spheres[pairable[k]]; });
      in.spheres = reinterpret_cast<const float*>(spheres_.data());
    }
    if (!all) in.ids = pairable.data();
    const double host_ms = sw.lap();

    struct Sink {
      std::vector<Pair>* pairs;
      static std::uint32_t* give(void* self, std::size_t count) {
        auto* s = static_cast<Sink*>(self);
        s->pairs->resize(count);
        return reinterpret_cast<std::uint32_t*>(s->pairs->data());
      }
    } sink{&pairs};
    if (!std::exchange(splatted_, false)) times_ = cuda::Times{};
    cuda::Times t;
    t.splat = times_.splat;
    t.count = times_.count;
    t.map_download = times_.map_download;
    const std::size_t cap = pairs_within_cap(config_.pair_memory_cap);
    const cuda::Outcome o = gpu_.broadphase(in, to_grid(layout, extent.bounds), cap, &Sink::give, &sink, t);
    times_ = t;
    if (o.over_limit) return check_pair_cap(o.pairs, config_.pair_memory_cap);
    if (!o.ok()) return to_status(o, objects.size(), config_);
    // GPU times by stage; the packing on the host and the upload count as the codes' stage.
    stats.ms(Stage::codes) = host_ms + t.upload + t.codes;
    stats.ms(Stage::sort) = t.sort;
    stats.ms(Stage::build) = t.build;
    stats.ms(Stage::fit) = t.fit;
    stats.ms(Stage::query) = t.query + t.pair_sort + t.download;
    return {};
  }

  cuda::Gpu gpu_;
  cuda::Times times_;
  bool splatted_ = false;  // this frame ran rasterize()
  cuda::Outcome splat_error_;
  std::vector<Sphere> spheres_;
  std::vector<Box> boxes_;
};

}  // namespace
}  // namespace detail

namespace detail {
const cuda::Times* cuda_times(const Detector& detector) {
  const auto* d = dynamic_cast<const CudaDetector*>(&DetectorAccess::backend(detector));
  return d ? &d->times() : nullptr;
}
}  // namespace detail

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
