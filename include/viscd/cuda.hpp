#pragma once
/// \file cuda.hpp
/// The cuda backend (docs/gpu.md): the visibility map as an analytic splat on the GPU (each
/// object's pixels, in chunks of 32 a warp, ray-tested as the CPU rasterizers do, the nearest
/// kept by a 64-bit atomicMin of depth and id), and stages 4-8 on the GPU: Morton codes, CUB radix sort over the key
/// width m, Karras build, bottom-up fit, traversal with a pair buffer that counts, grows and re-runs (never drops a
/// pair), CUB sort of the pairs. Counting, culling, the filters' pre-pass, states and shading run on the host, as in
/// the cpu backend. Spheres and boxes, static sets, filters, always-active objects and the caller's id map, like every
/// backend. That is make_cuda_detector(), a Detector fed from host arrays.
///
/// CudaBroadphase (make_cuda_broadphase()) is the same broadphase for objects that already live on
/// the GPU: device arrays in and out, the frame enqueued on the caller's stream without host
/// synchronisation, capturable in a CUDA graph (docs/gpu.md, "Device-resident frames").
///
/// Built when CMake finds nvcc (VISCD_ENABLE_CUDA, default ON); needs an NVIDIA GPU of compute
/// capability 9.0 (Hopper) at run time, for which the build compiles its code (configure with
/// CMAKE_CUDA_ARCHITECTURES for others).

#include <cstdint>
#include <memory>
#include <string>

#include "viscd/config.hpp"
#include "viscd/detector.hpp"
#include "viscd/result.hpp"
#include "viscd/types.hpp"

struct CUstream_st;  // cudaStream_t is CUstream_st*: pass a cudaStream_t where a CUstream_st* is asked for

namespace viscd {

/// A detector on the first CUDA device. Fails (ErrorKind::unsupported_input) when viscd was
/// built without CUDA, and (ErrorKind::backend_failure) when there is no usable device, saying
/// why: no driver, no device, or a device this build has no code for.
[[nodiscard]] Result<std::unique_ptr<Detector>> make_cuda_detector(const Config& config = {});

/// A frame's objects in device memory (docs/gpu.md, "Device-resident frames"), read by
/// CudaBroadphase::enqueue() while the stream runs. Exactly one of spheres and boxes is given
/// when count > 0.
struct CudaObjects {
  const Sphere* spheres = nullptr;  ///< count spheres, 16-byte aligned (cudaMalloc's alignment)
  const Box* boxes = nullptr;       ///< or count boxes
  std::uint32_t count = 0;          ///< at most 2^31 - 1
  const Filter* filters = nullptr;  ///< optional, count filters (the rule of FrameInput::filters)
  /// Objects from this index on are static: never paired with each other (a level's walls after
  /// its bodies). The default, and any value >= count, makes none static.
  std::uint32_t static_from = 0xFFFFFFFFu;
};

/// What a frame reports, written by the frame into device memory the caller owns.
struct CudaReport {
  /// Every pair the frame found, including those that did not fit the capacity: pairs beyond
  /// it are counted, never silently dropped. When pairs > capacity, grow and run the frame again.
  unsigned long long pairs = 0;
  /// Objects with a NaN or infinite coordinate, a negative radius, or a box with min > max. They
  /// are left out of the frame; a frame with invalid > 0 is the caller's error, as detect()'s
  /// invalid_input would be.
  std::uint32_t invalid = 0;
  std::uint32_t first_invalid = 0xFFFFFFFFu;  ///< the lowest invalid index, or 0xFFFFFFFF
  std::uint32_t bits = 0;                     ///< the Morton code width m used
  std::uint32_t objects = 0;                  ///< count, as the frame read it
};
static_assert(sizeof(CudaReport) == 24);

/// Where a frame writes its results: device memory the caller owns.
struct CudaResults {
  Pair* pairs = nullptr;          ///< room for `capacity` pairs (i < j): deterministic order, see enqueue()
  std::uint64_t capacity = 0;     ///< may be 0: the frame then only counts (and writes states)
  CudaReport* report = nullptr;   ///< required
  ObjectState* states = nullptr;  ///< optional, count entries: colliding, or free (no object is culled)
};

/// The cuda backend's broadphase for engines whose objects live on the GPU (Warp, Newton,
/// PhysX's direct GPU API and the like): objects and results in device memory, the whole frame
/// enqueued on the caller's stream with no host synchronisation, so that it can be captured into
/// a CUDA graph. The pairs are exact (those detect() returns for the same objects with culling
/// off); their order is deterministic (the same objects give the same array) but not sorted:
/// grouped by the tree's leaves, i < j within each pair. No visibility map and no culling: every
/// object takes part. Config::bits (adaptive means 32 here) and Config::layout are honoured.
///
/// Not thread-safe: one frame at a time per object; frames on several streams need one object
/// each. The caller keeps the inputs and outputs alive and unchanged until the stream has run.
class CudaBroadphase {
 public:
  virtual ~CudaBroadphase() = default;
  /// Allocates what frames of up to `objects` objects need, so that enqueue() allocates nothing
  /// (required before capturing a frame into a graph). Waits for the device.
  [[nodiscard]] virtual Status reserve(std::uint32_t objects, bool boxes) = 0;
  /// Enqueues a frame on `stream` (a cudaStream_t; null for the legacy default stream): the
  /// objects' bounds and Morton layout, codes, CUB radix sort, Karras build, fit, a traversal
  /// that counts each leaf's pairs and keeps its first four, a scan, and a pass that writes them
  /// (a copy, or a second traversal for a leaf with more), then the report. Checks the arguments on the host (pointers,
  /// alignment, sizes; invalid_input naming the field) and the objects on the device (CudaReport::invalid). When the
  /// buffers are short it grows them first (which waits for the device), or fails while the stream is capturing.
  [[nodiscard]] virtual Status enqueue(const CudaObjects& objects, const CudaResults& results, CUstream_st* stream) = 0;
  /// Device memory held, in bytes.
  [[nodiscard]] virtual std::uint64_t memory_bytes() const = 0;
};

/// A device-resident broadphase on the first CUDA device; the same errors as make_cuda_detector().
[[nodiscard]] Result<std::unique_ptr<CudaBroadphase>> make_cuda_broadphase(const Config& config = {});

/// The device the cuda backend would run on ("NVIDIA H100 80GB HBM3, sm_90, 132 SMs, 79 GiB"),
/// or why there is none (the same errors as make_cuda_detector()).
[[nodiscard]] Result<std::string> cuda_device();

}  // namespace viscd
