#pragma once
// The cuda backend's device side (gpu.cu), behind an interface of plain types so that the host
// code (cuda_detector.cpp) is compiled by the C++ compiler and only gpu.cu by nvcc.
//
//   splat()       stage 1-2: every object's pixels (its conservative rectangle, planned into chunks
//                 of 32 a warp) ray-tested as the CPU rasterizers do, the nearest kept by a 64-bit atomicMin of (depth,
//                 id); then the ids, optionally the depths, and the pixel counts per object back.
//   broadphase()  stages 5-8 over n objects: Morton codes, CUB radix sort over the key width m,
//                 Karras build, bottom-up fit, traversal with a pair buffer that counts, grows
//                 and re-runs, CUB sort of the pairs; the sorted pairs back.
//   DeviceFrame   the device-resident frame (viscd/cuda.hpp CudaBroadphase): objects, pairs and
//                 the report in device memory, every step enqueued on the caller's stream, no
//                 host synchronisation: bounds and layout planned on the GPU, a counting
//                 traversal that keeps each leaf's first pairs, a scan and a writing pass,
//                 instead of a growing buffer and a pair sort.

#include <cstdint>
#include <memory>
#include <string>

namespace viscd::cuda {

/// core/visibility.hpp's CameraRig, as floats and ints.
struct Rig {
  float eye[3], forward[3], right[3], up[3];
  float tan_half_x, tan_half_y, near_plane, far_plane;
  int map_w, map_h;
};

/// core/morton.hpp's MortonGrid and MortonLayout: cell q = (v - lo) * scale in double, clamped
/// to [0, max_cell]; bit b of axis a goes to code bit position[a][b].
struct Grid {
  double lo[3], scale[3], max_cell[3];
  int axis_bits[3];
  signed char position[3][32];
  int bits;  ///< m: 16, 32 or 64
};

/// A broadphase's input, on the host. Object k of the n is spheres[k] (a box's proxy sphere for
/// boxes) and, for boxes, boxes[k]; its index in the frame is ids[k] (k itself when ids is null).
/// filters (group, mask per frame index, `total` of them) may be null. Frame indices from
/// static_from on are static: never paired with each other.
struct BroadphaseInput {
  const float* spheres = nullptr;  ///< 4 floats an object: x, y, z, r
  const float* boxes = nullptr;    ///< 6 floats an object: min xyz, max xyz; null for spheres
  const std::uint32_t* ids = nullptr;
  const std::uint32_t* filters = nullptr;
  std::uint32_t n = 0, total = 0, static_from = 0xFFFFFFFFu;
};

/// GPU time of each part of the broadphase, milliseconds (CUDA events).
struct Times {
  float upload = 0, codes = 0, sort = 0, build = 0, fit = 0, query = 0, pair_sort = 0, download = 0;
};

/// GPU time of each part of the splat, milliseconds (CUDA events).
struct SplatTimes {
  float splat = 0, count = 0, map_download = 0;
};

/// What a call came to: ok, or an error (out of memory told apart), or more pairs than allowed.
struct Outcome {
  std::string error;  ///< empty: ok
  bool out_of_memory = false;
  bool over_limit = false;  ///< broadphase(): more than max_pairs pairs (`pairs` holds the count)
  std::uint64_t pairs = 0;
  [[nodiscard]] bool ok() const { return error.empty() && !over_limit; }
};

/// Pinned host memory for a broadphase's input (Gpu::staging()): the host packs the frame here and
/// the upload runs at the bus's speed rather than through the driver's pageable bounce buffer.
struct Staging {
  float* spheres = nullptr;          ///< 4 floats an object
  float* boxes = nullptr;            ///< 6 floats an object, when asked for
  std::uint32_t* ids = nullptr;      ///< an object's frame index, when asked for
  std::uint32_t* filters = nullptr;  ///< 2 words a frame index, when asked for
};

/// Receives the sorted pairs: `count` pairs of (i, j), 2 count words in pinned host memory that
/// stays valid until the next broadphase().
using PairSink = void (*)(void* context, const std::uint32_t* pairs, std::size_t count);

class Gpu {
 public:
  /// The device ("NVIDIA H100 80GB HBM3, sm_90, 132 SMs, 79 GiB"), or an error saying why there
  /// is none (no driver, no device, a device this build has no code for).
  static Outcome probe(std::string& description);

  Gpu();
  ~Gpu();
  Gpu(const Gpu&) = delete;
  Gpu& operator=(const Gpu&) = delete;

  /// Draws `count` objects (4 floats a sphere, or 6 a box) into a rig.map_w x rig.map_h map:
  /// ids (object index + 1, 0 = background) and, when `depth` is not null, view depths (far plane
  /// on the background); counts[k] = pixels of object k (count entries).
  Outcome splat(const Rig& rig, const float* objects, bool boxes, std::uint32_t count, std::uint32_t* ids, float* depth,
                std::uint32_t* counts, SplatTimes& times);

  /// The longest chunk list the splat plans before it falls back to a warp an object (a test
  /// hook: 0 forces the fallback). At most 2^27.
  void set_chunk_limit(unsigned long long limit);

  /// Pinned host buffers for n objects (and `filters` filters), grown as needed and kept.
  Outcome staging(std::uint32_t n, bool boxes, bool ids, std::uint32_t filters, Staging& out);

  /// Every overlapping pair of the input (frame indices i < j; sorted), given to `sink`.
  Outcome broadphase(const BroadphaseInput& in, const Grid& grid, std::uint64_t max_pairs, PairSink sink,
                     void* sink_context, Times& times);

  /// Device and pinned host memory held (bytes).
  [[nodiscard]] std::uint64_t bytes() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// viscd::CudaReport's layout (viscd/cuda.hpp; cuda_detector.cpp asserts that they agree).
struct Report {
  unsigned long long pairs;
  std::uint32_t invalid, first_invalid, bits, objects;
};

/// A device-resident frame's input: device pointers.
struct DeviceInput {
  const float* spheres = nullptr;          ///< 4 floats an object, 16-byte aligned; or
  const float* boxes = nullptr;            ///< 6 floats an object
  const std::uint32_t* filters = nullptr;  ///< group, mask an object; may be null
  std::uint32_t n = 0, static_from = 0xFFFFFFFFu;
  int bits = 32;
  bool plain_layout = false;
};

/// A device-resident frame's output: device pointers.
struct DeviceOutput {
  std::uint32_t* pairs = nullptr;  ///< 2 words a pair, `capacity` pairs
  std::uint64_t capacity = 0;
  Report* report = nullptr;
  std::uint8_t* states = nullptr;  ///< ObjectState an object; may be null
};

class DeviceFrame {
 public:
  DeviceFrame();
  ~DeviceFrame();
  DeviceFrame(const DeviceFrame&) = delete;
  DeviceFrame& operator=(const DeviceFrame&) = delete;

  /// Allocates what a frame of n objects needs, so that enqueue() allocates nothing.
  Outcome reserve(std::uint32_t n, bool boxes, int bits);
  /// Enqueues the frame on `stream` (a cudaStream_t; null: the legacy default stream). Grows
  /// its buffers first when they are short, unless the stream is capturing (then an error).
  Outcome enqueue(const DeviceInput& in, const DeviceOutput& out, void* stream);
  [[nodiscard]] std::uint64_t bytes() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Empty when p points to memory the device can read (device or managed), else what it is.
std::string device_memory_problem(const void* p);

}  // namespace viscd::cuda
