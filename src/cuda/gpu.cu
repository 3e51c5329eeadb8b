// The cuda backend's kernels and their host driver (gpu.hpp). Compiled with -fmad=false and
// IEEE division, square roots and subnormals (nvcc's defaults otherwise), so that every float
// test here is the one the CPU evaluates: core/geometry.hpp's overlap_exact and
// conservative_box, core/visibility.hpp's hit(), hit_box(), sphere_rect() and box_rect(), and
// core/morton.hpp's quantisation, operation for operation.
#include <cub/block/block_reduce.cuh>
#include <cub/device/device_radix_sort.cuh>
#include <cub/device/device_scan.cuh>

#include <cuda_runtime.h>
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <utility>

#include "core/morton_rule.hpp"
#include "cuda/gpu.hpp"

namespace viscd::cuda {
namespace {

constexpr unsigned kLeaf = 0x80000000u;  // core/lbvh.hpp kLeafBit
constexpr int kStack = 128;              // the deepest Karras tree over 64-bit keys is 64 + 32
constexpr int kBlock = 256;

// One internal node: the children's boxes (lo xyz, hi xyz each), the children (kLeaf marks a
// leaf), and the last leaf below each child (the traversal visits only leaves after its own).
struct Node {
  float box[12];
  unsigned child[2];
  unsigned last[2];
};

Outcome failure(cudaError_t e, const char* what) {
  Outcome o;
  o.out_of_memory = e == cudaErrorMemoryAllocation;
  o.error = std::string("CUDA: ") + what + ": " + cudaGetErrorString(e);
  (void)cudaGetLastError();  // clear it
  return o;
}

#define VISCD_CUDA(call)                                          \
  do {                                                            \
    const cudaError_t viscd_e_ = (call);                          \
    if (viscd_e_ != cudaSuccess) return failure(viscd_e_, #call); \
  } while (0)

// Where a growing buffer's memory comes from: the device, or pinned host memory.
struct DeviceMemory {
  static cudaError_t allocate(void** p, std::size_t bytes) { return cudaMalloc(p, bytes); }
  static void release(void* p) { cudaFree(p); }
};
struct PinnedMemory {
  static cudaError_t allocate(void** p, std::size_t bytes) { return cudaHostAlloc(p, bytes, cudaHostAllocDefault); }
  static void release(void* p) { cudaFreeHost(p); }
};

// Memory that only grows (by half again, so that a slowly growing N reallocates rarely; when
// that much is not to be had, exactly what was asked).
template <class Memory>
struct Growing {
  void* ptr = nullptr;
  std::size_t capacity = 0;
  Growing() = default;
  Growing(const Growing&) = delete;
  Growing& operator=(const Growing&) = delete;
  ~Growing() {
    if (ptr) Memory::release(ptr);
  }
  cudaError_t reserve(std::size_t bytes) {
    if (bytes <= capacity) return cudaSuccess;
    std::size_t want = std::max(bytes, capacity + capacity / 2);
    if (ptr) Memory::release(ptr);
    ptr = nullptr;
    capacity = 0;
    if (Memory::allocate(&ptr, want) != cudaSuccess) {
      (void)cudaGetLastError();
      want = bytes;
      const cudaError_t e = Memory::allocate(&ptr, want);
      if (e != cudaSuccess) {
        ptr = nullptr;
        return e;
      }
    }
    capacity = want;
    return cudaSuccess;
  }
  template <class T>
  [[nodiscard]] T* as() const {
    return static_cast<T*>(ptr);
  }
};
using Buffer = Growing<DeviceMemory>;
using PinnedBuffer = Growing<PinnedMemory>;

unsigned blocks(std::uint64_t threads) { return static_cast<unsigned>((threads + kBlock - 1) / kBlock); }

// ---- stage 1-2: the splat ----

__device__ float dot3(float ax, float ay, float az, const float* b) { return ax * b[0] + ay * b[1] + az * b[2]; }

// CameraRig::dir(px, py).
__device__ void ray_dir(const Rig& c, int px, int py, float d[3]) {
  const float nx = (2.0f * (static_cast<float>(px) + 0.5f) / static_cast<float>(c.map_w) - 1.0f) * c.tan_half_x;
  const float ny = (1.0f - 2.0f * (static_cast<float>(py) + 0.5f) / static_cast<float>(c.map_h)) * c.tan_half_y;
  for (int k = 0; k < 3; ++k) d[k] = c.forward[k] + c.right[k] * nx + c.up[k] * ny;
}

// hit(): the nearest visible intersection with a sphere, or -1.
__device__ float hit_sphere(const Rig& c, const float d[3], float4 s) {
  const float ox = c.eye[0] - s.x, oy = c.eye[1] - s.y, oz = c.eye[2] - s.z;
  const float a = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
  const float b = ox * d[0] + oy * d[1] + oz * d[2];
  const float cc = ox * ox + oy * oy + oz * oz - s.w * s.w;
  const float disc = b * b - a * cc;
  if (!(disc >= 0.0f)) return -1.0f;
  const float sq = sqrtf(disc);
  const float t0 = (-b - sq) / a;
  if (t0 >= c.near_plane && t0 <= c.far_plane) return t0;
  const float t1 = (-b + sq) / a;
  if (t1 >= c.near_plane && t1 <= c.far_plane) return t1;
  return -1.0f;
}

// hit_box(): slabs in float.
__device__ float hit_box(const Rig& c, const float d[3], const float* b) {
  float t0 = -INFINITY, t1 = INFINITY;
  for (int k = 0; k < 3; ++k) {
    if (d[k] == 0.0f) {
      if (c.eye[k] < b[k] || c.eye[k] > b[k + 3]) return -1.0f;
      continue;
    }
    float lo = (b[k] - c.eye[k]) / d[k], hi = (b[k + 3] - c.eye[k]) / d[k];
    if (lo > hi) {
      const float t = lo;
      lo = hi;
      hi = t;
    }
    t0 = t0 < lo ? lo : t0;  // std::max(t0, lo)
    t1 = hi < t1 ? hi : t1;  // std::min(t1, hi)
  }
  if (!(t0 <= t1)) return -1.0f;
  if (t0 >= c.near_plane && t0 <= c.far_plane) return t0;
  if (t1 >= c.near_plane && t1 <= c.far_plane) return t1;
  return -1.0f;
}

struct Rect {
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  float near_depth = 0;  // no hit of the sphere is nearer (0: unknown)
};

__device__ int clamp_pixel(double v, int hi) {  // static_cast<int>(std::clamp(v, 0.0, hi))
  const double h = static_cast<double>(hi);
  return static_cast<int>(v < 0.0 ? 0.0 : (h < v ? h : v));
}

__device__ void span_of(float cv, float cz, float r, float tan_half, double& lo, double& hi) {
  const double v = cv, z = cz, rr = r;
  const double q = v * v + z * z - rr * rr;
  const double t = sqrt(q < 0.0 ? 0.0 : q);
  lo = (v * t - rr * z) / (z * t + v * rr) / tan_half;
  hi = (v * t + rr * z) / (z * t - v * rr) / tan_half;
}

// sphere_rect(): every pixel whose ray hit_sphere() can accept lies in the rectangle.
__device__ Rect sphere_rect(const Rig& cam, float sx, float sy, float sz, float sr) {
  const float c0 = sx - cam.eye[0], c1 = sy - cam.eye[1], c2 = sz - cam.eye[2];
  const float cz = dot3(c0, c1, c2, cam.forward), cx = dot3(c0, c1, c2, cam.right), cy = dot3(c0, c1, c2, cam.up);
  const double o2 = static_cast<double>(cz) * cz + static_cast<double>(cx) * cx + static_cast<double>(cy) * cy;
  const double l1 = static_cast<double>(fabsf(cz) + fabsf(cx) + fabsf(cy));
  const double rs = static_cast<double>(sr);
  const float r = static_cast<float>(sqrt(rs * rs + 0x1p-19 * o2) + 1e-4 * (l1 + rs) + 1e-6);
  Rect rect;
  if (cz + r < cam.near_plane || cz - r > cam.far_plane) return rect;
  const float dmin = cz - r;
  if (!(dmin > cam.near_plane * 0.5f)) return Rect{0, 0, cam.map_w, cam.map_h};
  double nx0, nx1, ny0, ny1;
  span_of(cx, cz, r, cam.tan_half_x, nx0, nx1);
  span_of(cy, cz, r, cam.tan_half_y, ny0, ny1);
  rect.x0 = clamp_pixel(floor((nx0 + 1.0) * 0.5 * cam.map_w - 0.5) - 1, cam.map_w);
  rect.x1 = clamp_pixel(ceil((nx1 + 1.0) * 0.5 * cam.map_w - 0.5) + 2, cam.map_w);
  rect.y0 = clamp_pixel(floor((1.0 - ny1) * 0.5 * cam.map_h - 0.5) - 1, cam.map_h);
  rect.y1 = clamp_pixel(ceil((1.0 - ny0) * 0.5 * cam.map_h - 0.5) + 2, cam.map_h);
  rect.near_depth = dmin;  // r includes the slack, so every hit has t >= dmin
  return rect;
}

// box_rect(): the rectangle of the box's bounding sphere.
__device__ Rect box_rect(const Rig& cam, const float* b) {
  const double hx = 0.5 * (double{b[3]} - b[0]), hy = 0.5 * (double{b[4]} - b[1]), hz = 0.5 * (double{b[5]} - b[2]);
  const double cx = 0.5 * (double{b[0]} + b[3]), cy = 0.5 * (double{b[1]} + b[4]), cz = 0.5 * (double{b[2]} + b[5]);
  const double rd = sqrt(hx * hx + hy * hy + hz * hz) + 0x1p-22 * (fabs(cx) + fabs(cy) + fabs(cz));
  return sphere_rect(cam, static_cast<float>(cx), static_cast<float>(cy), static_cast<float>(cz),
                     static_cast<float>(rd * (1.0 + 0x1p-20)));
}

__global__ void clear_map(std::uint64_t n, unsigned long long* map) {
  const std::uint64_t i = blockIdx.x * std::uint64_t{blockDim.x} + threadIdx.x;
  if (i < n) map[i] = ~0ull;
}

constexpr unsigned kChunk = 32;          // pixels of a rectangle a warp of the splat takes
constexpr unsigned kChunksPerBlock = 8;  // warps (chunks) a block
// Longest chunk list (1 GiB); a frame whose rectangles need more is splatted a warp an object.
// Gpu::set_chunk_limit() lowers it (the tests run the fallback with 0).
constexpr unsigned long long kMaxChunks = 1ull << 27;

// The fallback splat: one warp an object, its lanes taking the rectangle's pixels in turn.
__global__ void splat_objects(std::uint32_t count, const float* objects, bool boxes, Rig rig, unsigned long long* map) {
  const std::uint64_t k = (blockIdx.x * std::uint64_t{blockDim.x} + threadIdx.x) / 32;
  const unsigned lane = threadIdx.x & 31u;
  if (k >= count) return;
  const float* b = boxes ? objects + 6 * k : nullptr;
  const float4 s = boxes ? float4{} : reinterpret_cast<const float4*>(objects)[k];
  const Rect r = boxes ? box_rect(rig, b) : sphere_rect(rig, s.x, s.y, s.z, s.w);
  if (r.x0 >= r.x1 || r.y0 >= r.y1) return;
  const std::uint64_t w = static_cast<std::uint64_t>(r.x1 - r.x0);
  const std::uint64_t pixels = w * static_cast<std::uint64_t>(r.y1 - r.y0);
  for (std::uint64_t i = lane; i < pixels; i += 32) {
    const int px = r.x0 + static_cast<int>(i % w), py = r.y0 + static_cast<int>(i / w);
    float d[3];
    ray_dir(rig, px, py, d);
    const float t = boxes ? hit_box(rig, d, b) : hit_sphere(rig, d, s);
    if (t >= 0.0f)
      atomicMin(&map[static_cast<std::uint64_t>(py) * static_cast<std::uint64_t>(rig.map_w) + px],
                (static_cast<unsigned long long>(__float_as_uint(t)) << 32) | (k + 1));
  }
}

// The plan: one thread an object computes its rectangle and cuts it into chunks of kChunk pixels,
// listed as (object, chunk), so that an object covering the screen spreads over the whole GPU and
// one covering a pixel costs one warp. Entries past `capacity` are counted, not written: the
// host reads the count, grows the list and plans again.
__global__ void plan_splat(std::uint32_t count, const float* objects, bool boxes, Rig rig, uint4* rects,
                           unsigned long long* chunk_count, uint2* chunks, unsigned long long capacity) {
  const std::uint32_t k = blockIdx.x * blockDim.x + threadIdx.x;
  if (k >= count) return;
  Rect r;
  if (boxes) {
    r = box_rect(rig, objects + 6 * std::uint64_t{k});
    r.near_depth = 0;  // early rejection for spheres only
  } else {
    const float4 s = reinterpret_cast<const float4*>(objects)[k];
    r = sphere_rect(rig, s.x, s.y, s.z, s.w);
  }
  if (r.x0 >= r.x1 || r.y0 >= r.y1) return;
  const unsigned w = static_cast<unsigned>(r.x1 - r.x0), h = static_cast<unsigned>(r.y1 - r.y0);
  rects[k] = make_uint4(static_cast<unsigned>(r.x0) | (static_cast<unsigned>(r.y0) << 16), w, h,
                        __float_as_uint(r.near_depth));  // map sides < 2^16
  const unsigned n = (w * h + kChunk - 1) / kChunk;
  const unsigned long long base = atomicAdd(chunk_count, static_cast<unsigned long long>(n));
  for (unsigned c = 0; c < n && base + c < capacity; ++c) chunks[base + c] = make_uint2(k, c);
}

// One warp a chunk, one thread a pixel. The nearest hit wins, ties to the smaller id (depth in
// the high word: non-negative floats order as their bits). A pixel already nearer than any hit
// of the sphere is skipped before its ray is cast.
__global__ void splat_chunks(unsigned long long count, const uint2* chunks, const uint4* rects, const float* objects,
                             bool boxes, Rig rig, unsigned long long* map) {
  const unsigned long long entry = blockIdx.x * std::uint64_t{kChunksPerBlock} + threadIdx.x / kChunk;
  if (entry >= count) return;
  const uint2 e = chunks[entry];
  const uint4 r = rects[e.x];  // x0 | y0 << 16, width, height, near depth bits
  const unsigned i = e.y * kChunk + threadIdx.x % kChunk;
  if (i >= r.y * r.z) return;
  const int px = static_cast<int>((r.x & 0xFFFFu) + i % r.y), py = static_cast<int>((r.x >> 16) + i / r.y);
  unsigned long long* cell = &map[static_cast<std::uint64_t>(py) * static_cast<std::uint64_t>(rig.map_w) + px];
  if (static_cast<unsigned>(*cell >> 32) < r.w) return;
  float d[3];
  ray_dir(rig, px, py, d);
  const float t = boxes ? hit_box(rig, d, objects + 6 * std::uint64_t{e.x})
                        : hit_sphere(rig, d, reinterpret_cast<const float4*>(objects)[e.x]);
  if (t >= 0.0f) atomicMin(cell, (static_cast<unsigned long long>(__float_as_uint(t)) << 32) | (e.x + 1ull));
}

// The map's ids (and depths), and the pixels of each object: lanes holding the same id add once.
__global__ void resolve_map(std::uint64_t n, const unsigned long long* map, float far_plane, std::uint32_t* ids,
                            float* depth, std::uint32_t* counts) {
  const std::uint64_t i = blockIdx.x * std::uint64_t{blockDim.x} + threadIdx.x;
  if (i >= n) return;
  const unsigned long long v = map[i];
  const std::uint32_t id = v == ~0ull ? 0u : static_cast<std::uint32_t>(v & 0xFFFFFFFFull);
  ids[i] = id;
  if (depth) depth[i] = id ? __uint_as_float(static_cast<unsigned>(v >> 32)) : far_plane;
  if (id) {
    const unsigned peers = __match_any_sync(__activemask(), id);
    if ((threadIdx.x & 31u) == static_cast<unsigned>(__ffs(peers) - 1)) atomicAdd(&counts[id - 1], __popc(peers));
  }
}

// ---- stages 5-8 ----

// The code of a centre on the grid (core/morton.hpp's MortonEncoder, by the shared rule).
__device__ std::uint64_t code_of(const Grid& g, float x, float y, float z) {
  const float c[3] = {x, y, z};
  std::uint64_t key = 0;
  for (int a = 0; a < 3; ++a) {
    const unsigned q = detail::rule::quantize(c[a], g.lo[a], g.scale[a], g.max_cell[a]);
    for (int b = 0; b < g.axis_bits[a]; ++b)
      if ((q >> b) & 1u) key |= std::uint64_t{1} << g.position[a][b];
  }
  return key;
}

__global__ void morton_codes(std::uint32_t n, const float4* spheres, Grid g, std::uint64_t* keys,
                             std::uint32_t* values) {
  const std::uint32_t k = blockIdx.x * blockDim.x + threadIdx.x;
  if (k >= n) return;
  const float4 s = spheres[k];
  keys[k] = code_of(g, s.x, s.y, s.z);
  values[k] = k;
}

// Karras 2012, as core/lbvh.cpp: equal keys split by position, delta = m + clz32(i ^ j).
__device__ int delta(const std::uint64_t* keys, int n, int bits, int i, int j) {
  if (j < 0 || j >= n) return -1;
  const std::uint64_t a = keys[i], b = keys[j];
  if (a != b) return __clzll(static_cast<long long>(a ^ b)) - (64 - bits);
  return bits + __clz(i ^ j);
}

__global__ void karras_build(int n, int bits, const std::uint64_t* keys, Node* nodes, std::uint32_t* parent,
                             std::uint32_t* arrivals) {
  const int i = static_cast<int>(blockIdx.x * blockDim.x + threadIdx.x);
  if (i >= n - 1) return;
  arrivals[i] = 0;
  const int d = delta(keys, n, bits, i, i + 1) - delta(keys, n, bits, i, i - 1) > 0 ? 1 : -1;
  const int delta_min = delta(keys, n, bits, i, i - d);
  int lmax = 2;
  while (delta(keys, n, bits, i, i + lmax * d) > delta_min) lmax *= 2;
  int l = 0;
  for (int t = lmax / 2; t >= 1; t /= 2)
    if (delta(keys, n, bits, i, i + (l + t) * d) > delta_min) l += t;
  const int j = i + l * d;
  const int delta_node = delta(keys, n, bits, i, j);
  int s = 0, t = l;
  do {
    t = (t + 1) / 2;
    if (delta(keys, n, bits, i, i + (s + t) * d) > delta_node) s += t;
  } while (t > 1);
  const int gamma = i + s * d + min(d, 0);
  const int first = min(i, j), last = max(i, j);
  const unsigned leaf_base = static_cast<unsigned>(n - 1);
  Node& node = nodes[i];
  if (first == gamma) {
    node.child[0] = static_cast<unsigned>(gamma) | kLeaf;
    parent[leaf_base + gamma] = i;
  } else {
    node.child[0] = gamma;
    parent[gamma] = i;
  }
  if (last == gamma + 1) {
    node.child[1] = static_cast<unsigned>(gamma + 1) | kLeaf;
    parent[leaf_base + gamma + 1] = i;
  } else {
    node.child[1] = gamma + 1;
    parent[gamma + 1] = i;
  }
  node.last[0] = gamma;
  node.last[1] = last;
  if (i == 0) parent[0] = 0xFFFFFFFFu;
}

// Leaf boxes (conservative_box() of a sphere, a box itself) and the bottom-up fit: at each node
// the first thread to arrive stops, the second merges both children and climbs. The box is
// written and fenced before the arrival count, and read back past L1 (__ldcg).
__global__ void fit(std::uint32_t n, const float4* spheres, const float* boxes, const std::uint32_t* ids,
                    const std::uint32_t* order, float4* sorted, float* leaf_boxes, std::uint32_t* frame_id, Node* nodes,
                    const std::uint32_t* parent, std::uint32_t* arrivals) {
  const std::uint32_t p = blockIdx.x * blockDim.x + threadIdx.x;
  if (p >= n) return;
  const std::uint32_t g = order[p];
  frame_id[p] = ids ? ids[g] : g;
  const float4 s = spheres[g];
  sorted[p] = s;
  float lo[3], hi[3];
  if (boxes) {
    for (int a = 0; a < 3; ++a) {
      lo[a] = boxes[6 * std::uint64_t{g} + a];
      hi[a] = boxes[6 * std::uint64_t{g} + 3 + a];
    }
  } else {
    const float m = fmaxf(fmaxf(fabsf(s.x), fabsf(s.y)), fabsf(s.z));
    const float r = s.w + (m + s.w) * 1.9073486328125e-06f + 1e-21f;
    lo[0] = s.x - r, lo[1] = s.y - r, lo[2] = s.z - r;
    hi[0] = s.x + r, hi[1] = s.y + r, hi[2] = s.z + r;
  }
  for (int a = 0; a < 3; ++a) {
    leaf_boxes[6 * std::uint64_t{p} + a] = lo[a];
    leaf_boxes[6 * std::uint64_t{p} + 3 + a] = hi[a];
  }
  if (n == 1) return;
  unsigned child = p | kLeaf;
  unsigned node = parent[n - 1 + p];
  for (;;) {
    Node& nd = nodes[node];
    const int side = nd.child[0] == child ? 0 : 6;  // the build's, fixed before this launch
    for (int a = 0; a < 3; ++a) {
      nd.box[side + a] = lo[a];
      nd.box[side + 3 + a] = hi[a];
    }
    __threadfence();
    if (atomicAdd(&arrivals[node], 1u) == 0u) return;  // the sibling's thread merges
    __threadfence();
    const int other = 6 - side;
    for (int a = 0; a < 3; ++a) {  // the sibling's box, read from L2 (__ldcg): L1 may hold none of it
      lo[a] = fminf(lo[a], __ldcg(&nd.box[other + a]));
      hi[a] = fmaxf(hi[a], __ldcg(&nd.box[other + 3 + a]));
    }
    if (node == 0) return;
    child = node;
    node = parent[node];
  }
}

__device__ bool spheres_meet(float4 a, float4 b) {  // overlap_exact(): float, no FMA, touching counts
  const float dx = a.x - b.x, dy = a.y - b.y, dz = a.z - b.z;
  const float s = a.w + b.w;
  return dx * dx + dy * dy + dz * dz <= s * s;
}

__device__ bool boxes_meet(const float* a, const float* b) {  // box_overlap_exact(): closed
  for (int k = 0; k < 3; ++k)
    if (!(a[k] <= b[k + 3] && b[k] <= a[k + 3])) return false;
  return true;
}

// What a traversal pass does with each pair it finds.
enum class Pass {
  append,  // the host frame: a key (i << id_bits) | j at an atomic slot below the capacity
  count,   // the device frame's first pass: counts[p] = pairs of leaf p, the first kKept of them kept in
           // kept[kKept p ...]; both objects' states colliding
  write,   // its second: leaf p's pairs as (i, j) from offsets[p] on, below the capacity: copied from
           // `kept`, or found again by a second traversal for the few leaves with more than kKept
};

// Pairs a leaf keeps from the counting pass (8 bytes each, per object): dense scenes have 0.6
// pairs a leaf on average, so nearly every leaf's second pass is a copy.
constexpr unsigned kKept = 4;

// The traversal's output, by pass.
struct QueryOut {
  std::uint64_t* keys = nullptr;                // append
  unsigned long long* count = nullptr;          // append: every pair counted
  int id_bits = 0;                              // append
  unsigned long long* counts = nullptr;         // count
  std::uint8_t* states = nullptr;               // count; may be null
  uint2* kept = nullptr;                        // count (written), write (read)
  const unsigned long long* offsets = nullptr;  // write
  uint2* pairs = nullptr;                       // write
  std::uint64_t capacity = 0;                   // append, write
};

// One thread a leaf p: the leaves q > p whose boxes meet its own, then the exact test, the static
// rule and the filters. No pass drops a pair: append counts every pair and stores those below the
// capacity (the host grows the buffer and runs it again); count and write find the same pairs in
// the same order, and the caller sees the true total.
template <Pass kPass>
__global__ void query(std::uint32_t n, const float4* __restrict__ sorted, const float* __restrict__ leaf_boxes,
                      const Node* __restrict__ nodes, const std::uint32_t* __restrict__ frame_id,
                      const uint2* __restrict__ filters, std::uint32_t static_from, bool boxes, QueryOut out) {
  const std::uint32_t p = blockIdx.x * blockDim.x + threadIdx.x;
  if (p >= n || n < 2) return;
  const float4 a = sorted[p];
  const float* box = leaf_boxes + 6 * std::uint64_t{p};
  const float lo[3] = {box[0], box[1], box[2]}, hi[3] = {box[3], box[4], box[5]};
  const std::uint32_t ia = frame_id[p];
  unsigned long long found = 0;
  std::uint64_t slot = kPass == Pass::write ? out.offsets[p] : 0;
  if constexpr (kPass == Pass::write) {
    const unsigned long long c = out.counts[p];
    if (c <= kKept) {
      for (unsigned k = 0; k < c && slot + k < out.capacity; ++k)
        out.pairs[slot + k] = out.kept[kKept * std::uint64_t{p} + k];
      return;
    }
  }
  unsigned stack[kStack];
  int sp = 0;
  unsigned node = 0;
  for (;;) {
    unsigned next = 0xFFFFFFFFu;
    const Node& nd = nodes[node];
    for (int c = 0; c < 2; ++c) {
      const float* cb = nd.box + 6 * c;
      if (!(nd.last[c] > p && cb[0] <= hi[0] && lo[0] <= cb[3] && cb[1] <= hi[1] && lo[1] <= cb[4] && cb[2] <= hi[2] &&
            lo[2] <= cb[5]))
        continue;
      const unsigned ch = nd.child[c];
      if (ch & kLeaf) {
        const unsigned q = ch & ~kLeaf;
        if (!(boxes ? boxes_meet(box, leaf_boxes + 6 * std::uint64_t{q}) : spheres_meet(a, sorted[q]))) continue;
        const std::uint32_t ib = frame_id[q];
        if (ia >= static_from && ib >= static_from) continue;
        if (filters) {
          const uint2 fa = filters[ia], fb = filters[ib];
          if ((fa.x & fb.y) == 0u || (fb.x & fa.y) == 0u) continue;
        }
        const std::uint32_t i = min(ia, ib), j = max(ia, ib);
        if constexpr (kPass == Pass::append) {
          const unsigned long long at = atomicAdd(out.count, 1ull);
          if (at < out.capacity) out.keys[at] = (static_cast<std::uint64_t>(i) << out.id_bits) | j;
        } else if constexpr (kPass == Pass::count) {
          if (found < kKept) out.kept[kKept * std::uint64_t{p} + found] = make_uint2(i, j);
          ++found;
          if (out.states) out.states[ib] = 2;  // ObjectState::colliding
        } else {
          if (slot < out.capacity) out.pairs[slot] = make_uint2(i, j);
          ++slot;
        }
      } else if (next == 0xFFFFFFFFu) {
        next = ch;
      } else {
        stack[sp++] = ch;
      }
    }
    if (next != 0xFFFFFFFFu)
      node = next;
    else if (sp > 0)
      node = stack[--sp];
    else
      break;
  }
  if constexpr (kPass == Pass::count) {
    out.counts[p] = found;
    if (found && out.states) out.states[ia] = 2;
  }
}

// Sorted keys (i << id_bits | j) to Pair's memory order (i, j).
__global__ void to_pairs(std::uint64_t n, const std::uint64_t* keys, int id_bits, uint2* out) {
  const std::uint64_t k = blockIdx.x * std::uint64_t{blockDim.x} + threadIdx.x;
  if (k >= n) return;
  const std::uint64_t key = keys[k];
  out[k] = make_uint2(static_cast<unsigned>(key >> id_bits),
                      static_cast<unsigned>(key & ((std::uint64_t{1} << id_bits) - 1)));
}

__global__ void probe_kernel(int* out) { *out = 1; }

int bit_width(std::uint32_t v) { return v ? 32 - __builtin_clz(v) : 0; }

}  // namespace

struct Gpu::Impl {
  // splat
  Buffer map, ids, depth, counts, objects, rects, chunks, chunk_count;
  unsigned long long chunk_capacity = 1u << 16;
  unsigned long long chunk_limit = kMaxChunks;
  // broadphase
  Buffer spheres, boxes, id_map, filters, keys[2], values[2], nodes, parent, arrivals, sorted, leaf_boxes, frame_id,
      pairs[2], pair_count, temp;
  PinnedBuffer staged_spheres, staged_boxes, staged_ids, staged_filters, staged_pairs;
  std::uint64_t pair_capacity = 1 << 16;
  cudaEvent_t ev[10] = {};
  bool events = false;

  ~Impl() {
    if (events)
      for (cudaEvent_t e : ev) cudaEventDestroy(e);
  }
  Outcome make_events() {
    if (events) return {};
    for (cudaEvent_t& e : ev) VISCD_CUDA(cudaEventCreate(&e));
    events = true;
    return {};
  }
  float between(int a, int b) const {
    float ms = 0;
    return cudaEventElapsedTime(&ms, ev[a], ev[b]) == cudaSuccess ? ms : 0.0f;
  }
  std::uint64_t bytes() const {
    std::uint64_t b = 0;
    for (const Buffer* x :
         {&map,      &ids,    &depth,      &counts,   &objects,  &rects,     &chunks,     &chunk_count, &spheres,
          &boxes,    &id_map, &filters,    &keys[0],  &keys[1],  &values[0], &values[1],  &nodes,       &parent,
          &arrivals, &sorted, &leaf_boxes, &frame_id, &pairs[0], &pairs[1],  &pair_count, &temp})
      b += x->capacity;
    for (const PinnedBuffer* x : {&staged_spheres, &staged_boxes, &staged_ids, &staged_filters, &staged_pairs})
      b += x->capacity;
    return b;
  }
};

Outcome Gpu::probe(std::string& description) {
  int devices = 0;
  if (const cudaError_t e = cudaGetDeviceCount(&devices); e == cudaErrorInsufficientDriver) {
    Outcome o = failure(e, "cudaGetDeviceCount");
    o.error =
        "no NVIDIA driver on this machine, or one older than the CUDA runtime viscd was built with (" + o.error + ")";
    return o;
  } else if (e != cudaSuccess) {
    return failure(e, "cudaGetDeviceCount");
  }
  if (devices < 1) {
    Outcome o;
    o.error = "CUDA: no device";
    return o;
  }
  cudaDeviceProp prop{};
  VISCD_CUDA(cudaGetDeviceProperties(&prop, 0));
  int* flag = nullptr;
  VISCD_CUDA(cudaMalloc(&flag, sizeof(int)));
  probe_kernel<<<1, 1>>>(flag);
  const cudaError_t launched = cudaGetLastError();
  const cudaError_t done = cudaDeviceSynchronize();
  cudaFree(flag);
  if (launched != cudaSuccess)
    return failure(launched, "a first kernel (is this GPU among the build's architectures?)");
  if (done != cudaSuccess) return failure(done, "a first kernel");
  char buf[256];
  std::snprintf(buf, sizeof buf, "%s, sm_%d%d, %d SMs, %.0f GiB", prop.name, prop.major, prop.minor,
                prop.multiProcessorCount, static_cast<double>(prop.totalGlobalMem) / (1u << 30));
  description = buf;
  return {};
}

Gpu::Gpu() : impl_(std::make_unique<Impl>()) {}
Gpu::~Gpu() = default;
std::uint64_t Gpu::bytes() const { return impl_->bytes(); }
void Gpu::set_chunk_limit(unsigned long long limit) { impl_->chunk_limit = std::min(limit, kMaxChunks); }

Outcome Gpu::splat(const Rig& rig, const float* objects, bool boxes, std::uint32_t count, std::uint32_t* ids,
                   float* depth, std::uint32_t* counts, SplatTimes& times) {
  Impl& m = *impl_;
  if (Outcome o = m.make_events(); !o.ok()) return o;
  const std::uint64_t pixels = static_cast<std::uint64_t>(rig.map_w) * static_cast<std::uint64_t>(rig.map_h);
  const std::size_t object_bytes = (boxes ? 24 : 16) * std::size_t{count};
  VISCD_CUDA(m.map.reserve(8 * pixels));
  VISCD_CUDA(m.ids.reserve(4 * pixels));
  if (depth) VISCD_CUDA(m.depth.reserve(4 * pixels));
  VISCD_CUDA(m.counts.reserve(4 * std::size_t{count} + 4));
  VISCD_CUDA(m.objects.reserve(object_bytes + 16));
  VISCD_CUDA(cudaEventRecord(m.ev[0]));
  if (count) VISCD_CUDA(cudaMemcpy(m.objects.ptr, objects, object_bytes, cudaMemcpyHostToDevice));
  VISCD_CUDA(cudaMemsetAsync(m.counts.ptr, 0, 4 * std::size_t{count} + 4));
  clear_map<<<blocks(pixels), kBlock>>>(pixels, m.map.as<unsigned long long>());
  VISCD_CUDA(cudaEventRecord(m.ev[1]));
  if (count) {
    // The plan, its count read back (grown and planned again when the list was short), the chunks.
    VISCD_CUDA(m.rects.reserve(16 * std::size_t{count}));
    VISCD_CUDA(m.chunk_count.reserve(8));
    unsigned long long chunks = 0;
    for (int attempt = 0; attempt < 2; ++attempt) {
      VISCD_CUDA(m.chunks.reserve(8 * m.chunk_capacity));
      VISCD_CUDA(cudaMemsetAsync(m.chunk_count.ptr, 0, 8));
      plan_splat<<<blocks(count), kBlock>>>(count, m.objects.as<float>(), boxes, rig, m.rects.as<uint4>(),
                                            m.chunk_count.as<unsigned long long>(), m.chunks.as<uint2>(),
                                            m.chunk_capacity);
      VISCD_CUDA(cudaGetLastError());
      VISCD_CUDA(cudaMemcpy(&chunks, m.chunk_count.ptr, 8, cudaMemcpyDeviceToHost));
      if (chunks <= m.chunk_capacity || chunks > m.chunk_limit) break;
      m.chunk_capacity = chunks;
    }
    if (chunks > m.chunk_limit)
      splat_objects<<<blocks(32 * std::uint64_t{count}), kBlock>>>(count, m.objects.as<float>(), boxes, rig,
                                                                   m.map.as<unsigned long long>());
    else if (chunks)
      splat_chunks<<<static_cast<unsigned>((chunks + kChunksPerBlock - 1) / kChunksPerBlock),
                     kChunk * kChunksPerBlock>>>(chunks, m.chunks.as<uint2>(), m.rects.as<uint4>(),
                                                 m.objects.as<float>(), boxes, rig, m.map.as<unsigned long long>());
    VISCD_CUDA(cudaGetLastError());
  }
  VISCD_CUDA(cudaEventRecord(m.ev[2]));
  resolve_map<<<blocks(pixels), kBlock>>>(pixels, m.map.as<unsigned long long>(), rig.far_plane,
                                          m.ids.as<std::uint32_t>(), depth ? m.depth.as<float>() : nullptr,
                                          m.counts.as<std::uint32_t>());
  VISCD_CUDA(cudaGetLastError());
  VISCD_CUDA(cudaEventRecord(m.ev[3]));
  VISCD_CUDA(cudaMemcpy(ids, m.ids.ptr, 4 * pixels, cudaMemcpyDeviceToHost));
  if (depth) VISCD_CUDA(cudaMemcpy(depth, m.depth.ptr, 4 * pixels, cudaMemcpyDeviceToHost));
  if (count) VISCD_CUDA(cudaMemcpy(counts, m.counts.ptr, 4 * std::size_t{count}, cudaMemcpyDeviceToHost));
  VISCD_CUDA(cudaEventRecord(m.ev[4]));
  VISCD_CUDA(cudaEventSynchronize(m.ev[4]));
  times.splat = m.between(0, 2);  // the upload, the clear and the splat
  times.count = m.between(2, 3);
  times.map_download = m.between(3, 4);
  return {};
}

Outcome Gpu::staging(std::uint32_t n, bool boxes, bool ids, std::uint32_t filters, Staging& out) {
  Impl& m = *impl_;
  const std::size_t k = std::max<std::size_t>(n, 1);
  VISCD_CUDA(m.staged_spheres.reserve(16 * k));
  out.spheres = m.staged_spheres.as<float>();
  if (boxes) VISCD_CUDA(m.staged_boxes.reserve(24 * k));
  out.boxes = boxes ? m.staged_boxes.as<float>() : nullptr;
  if (ids) VISCD_CUDA(m.staged_ids.reserve(4 * k));
  out.ids = ids ? m.staged_ids.as<std::uint32_t>() : nullptr;
  if (filters) VISCD_CUDA(m.staged_filters.reserve(8 * std::size_t{filters}));
  out.filters = filters ? m.staged_filters.as<std::uint32_t>() : nullptr;
  return {};
}

Outcome Gpu::broadphase(const BroadphaseInput& in, const Grid& grid, std::uint64_t max_pairs, PairSink sink,
                        void* sink_context, Times& times) {
  Impl& m = *impl_;
  if (Outcome o = m.make_events(); !o.ok()) return o;
  const std::uint32_t n = in.n;
  const bool boxes = in.boxes != nullptr;
  times.upload = times.codes = times.sort = times.build = times.fit = times.query = times.pair_sort = times.download =
      0;
  if (n < 2) {  // no pair; nothing to run
    sink(sink_context, nullptr, 0);
    return {};
  }
  // Buffers (n >= 2).
  VISCD_CUDA(m.spheres.reserve(16 * std::size_t{n}));
  if (boxes) VISCD_CUDA(m.boxes.reserve(24 * std::size_t{n}));
  if (in.ids) VISCD_CUDA(m.id_map.reserve(4 * std::size_t{n}));
  if (in.filters) VISCD_CUDA(m.filters.reserve(8 * std::size_t{in.total}));
  for (int k = 0; k < 2; ++k) {
    VISCD_CUDA(m.keys[k].reserve(8 * std::size_t{n}));
    VISCD_CUDA(m.values[k].reserve(4 * std::size_t{n}));
  }
  VISCD_CUDA(m.nodes.reserve(sizeof(Node) * std::size_t{n}));
  VISCD_CUDA(m.parent.reserve(4 * (2 * std::size_t{n})));
  VISCD_CUDA(m.arrivals.reserve(4 * std::size_t{n}));
  VISCD_CUDA(m.sorted.reserve(16 * std::size_t{n}));
  VISCD_CUDA(m.leaf_boxes.reserve(24 * std::size_t{n}));
  VISCD_CUDA(m.frame_id.reserve(4 * std::size_t{n}));
  VISCD_CUDA(m.pair_count.reserve(8));
  std::size_t sort_temp = 0;
  {
    cub::DoubleBuffer<std::uint64_t> k(m.keys[0].as<std::uint64_t>(), m.keys[1].as<std::uint64_t>());
    cub::DoubleBuffer<std::uint32_t> v(m.values[0].as<std::uint32_t>(), m.values[1].as<std::uint32_t>());
    VISCD_CUDA(cub::DeviceRadixSort::SortPairs(nullptr, sort_temp, k, v, static_cast<int>(n), 0, grid.bits));
  }
  VISCD_CUDA(m.temp.reserve(sort_temp));

  // From Gpu::staging()'s pinned buffers these copies run at the bus's speed; from pageable
  // memory the driver copies through a bounce buffer and they return when done.
  VISCD_CUDA(cudaEventRecord(m.ev[0]));
  VISCD_CUDA(cudaMemcpyAsync(m.spheres.ptr, in.spheres, 16 * std::size_t{n}, cudaMemcpyHostToDevice));
  if (boxes) VISCD_CUDA(cudaMemcpyAsync(m.boxes.ptr, in.boxes, 24 * std::size_t{n}, cudaMemcpyHostToDevice));
  if (in.ids) VISCD_CUDA(cudaMemcpyAsync(m.id_map.ptr, in.ids, 4 * std::size_t{n}, cudaMemcpyHostToDevice));
  if (in.filters)
    VISCD_CUDA(cudaMemcpyAsync(m.filters.ptr, in.filters, 8 * std::size_t{in.total}, cudaMemcpyHostToDevice));
  VISCD_CUDA(cudaEventRecord(m.ev[1]));
  morton_codes<<<blocks(n), kBlock>>>(n, m.spheres.as<float4>(), grid, m.keys[0].as<std::uint64_t>(),
                                      m.values[0].as<std::uint32_t>());
  VISCD_CUDA(cudaGetLastError());
  VISCD_CUDA(cudaEventRecord(m.ev[2]));
  cub::DoubleBuffer<std::uint64_t> keys(m.keys[0].as<std::uint64_t>(), m.keys[1].as<std::uint64_t>());
  cub::DoubleBuffer<std::uint32_t> values(m.values[0].as<std::uint32_t>(), m.values[1].as<std::uint32_t>());
  VISCD_CUDA(cub::DeviceRadixSort::SortPairs(m.temp.ptr, sort_temp, keys, values, static_cast<int>(n), 0, grid.bits));
  VISCD_CUDA(cudaEventRecord(m.ev[3]));
  karras_build<<<blocks(n - 1), kBlock>>>(static_cast<int>(n), grid.bits, keys.Current(), m.nodes.as<Node>(),
                                          m.parent.as<std::uint32_t>(), m.arrivals.as<std::uint32_t>());
  VISCD_CUDA(cudaGetLastError());
  VISCD_CUDA(cudaEventRecord(m.ev[4]));
  fit<<<blocks(n), kBlock>>>(n, m.spheres.as<float4>(), boxes ? m.boxes.as<float>() : nullptr,
                             in.ids ? m.id_map.as<std::uint32_t>() : nullptr, values.Current(), m.sorted.as<float4>(),
                             m.leaf_boxes.as<float>(), m.frame_id.as<std::uint32_t>(), m.nodes.as<Node>(),
                             m.parent.as<std::uint32_t>(), m.arrivals.as<std::uint32_t>());
  VISCD_CUDA(cudaGetLastError());
  VISCD_CUDA(cudaEventRecord(m.ev[5]));
  // The query; with more pairs than the buffer holds, the buffer grows to the count and the
  // query runs again.
  const int id_bits = std::max(1, bit_width(in.total ? in.total - 1 : 0u));
  unsigned long long count = 0;
  for (int attempt = 0;; ++attempt) {
    VISCD_CUDA(m.pairs[0].reserve(8 * m.pair_capacity));
    VISCD_CUDA(cudaMemsetAsync(m.pair_count.ptr, 0, 8));
    QueryOut qo;
    qo.keys = m.pairs[0].as<std::uint64_t>();
    qo.count = m.pair_count.as<unsigned long long>();
    qo.id_bits = id_bits;
    qo.capacity = m.pair_capacity;
    query<Pass::append><<<blocks(n), kBlock>>>(n, m.sorted.as<float4>(), m.leaf_boxes.as<float>(), m.nodes.as<Node>(),
                                               m.frame_id.as<std::uint32_t>(),
                                               in.filters ? m.filters.as<uint2>() : nullptr, in.static_from, boxes, qo);
    VISCD_CUDA(cudaGetLastError());
    VISCD_CUDA(cudaEventRecord(m.ev[6]));
    VISCD_CUDA(cudaMemcpy(&count, m.pair_count.ptr, 8, cudaMemcpyDeviceToHost));
    if (max_pairs && count > max_pairs) {
      Outcome o;
      o.over_limit = true;
      o.pairs = count;
      return o;
    }
    if (count <= m.pair_capacity) break;
    if (attempt > 0) {  // the same input gives the same count: this would be a bug, never a loss
      Outcome o;
      o.error = "the query found " + std::to_string(count) + " pairs after growing its buffer to " +
                std::to_string(m.pair_capacity) + " (an internal error)";
      return o;
    }
    m.pair_capacity = count;
  }
  if (count > 0x7FFFFFFFull) {  // CUB sorts at most 2^31 - 1 items at a time
    Outcome o;
    o.error = "the cuda backend sorts at most 2^31 - 1 pairs a frame; this frame has " + std::to_string(count);
    return o;
  }
  // The pairs sorted as keys of 2 id_bits bits, then to (i, j).
  const int key_bits = 2 * id_bits;
  std::size_t pair_temp = 0;
  VISCD_CUDA(m.pairs[1].reserve(8 * std::max<std::uint64_t>(count, 1)));
  cub::DoubleBuffer<std::uint64_t> pk(m.pairs[0].as<std::uint64_t>(), m.pairs[1].as<std::uint64_t>());
  VISCD_CUDA(cub::DeviceRadixSort::SortKeys(nullptr, pair_temp, pk, static_cast<int>(count), 0, key_bits));
  VISCD_CUDA(m.temp.reserve(pair_temp));
  if (count)
    VISCD_CUDA(cub::DeviceRadixSort::SortKeys(m.temp.ptr, pair_temp, pk, static_cast<int>(count), 0, key_bits));
  uint2* out = reinterpret_cast<uint2*>(pk.Alternate());
  if (count) to_pairs<<<blocks(count), kBlock>>>(count, pk.Current(), id_bits, out);
  VISCD_CUDA(cudaGetLastError());
  VISCD_CUDA(cudaEventRecord(m.ev[7]));
  VISCD_CUDA(m.staged_pairs.reserve(8 * std::max<std::size_t>(count, 1)));
  if (count) VISCD_CUDA(cudaMemcpyAsync(m.staged_pairs.ptr, out, 8 * std::size_t{count}, cudaMemcpyDeviceToHost));
  VISCD_CUDA(cudaEventRecord(m.ev[8]));
  VISCD_CUDA(cudaEventSynchronize(m.ev[8]));
  sink(sink_context, m.staged_pairs.as<std::uint32_t>(), count);
  times.upload = m.between(0, 1);
  times.codes = m.between(1, 2);
  times.sort = m.between(2, 3);
  times.build = m.between(3, 4);
  times.fit = m.between(4, 5);
  times.query = m.between(5, 6);  // with a second attempt: both, and the count read back between them
  times.pair_sort = m.between(6, 7);
  times.download = m.between(7, 8);
  Outcome o;
  o.pairs = count;
  return o;
}

// ---- the device-resident frame ----

namespace {

// One block's share of the objects: the bounds of the valid centres, the sum of their diameters
// (box_proxy()'s for boxes, as the host's extent_of()), and the invalid ones.
struct Partial {
  float lo[3], hi[3];
  double diameters;
  unsigned valid, invalid, first_invalid;
};

struct MergePartial {
  __device__ Partial operator()(const Partial& a, const Partial& b) const {
    Partial r;
    for (int k = 0; k < 3; ++k) {
      r.lo[k] = fminf(a.lo[k], b.lo[k]);
      r.hi[k] = fmaxf(a.hi[k], b.hi[k]);
    }
    r.diameters = a.diameters + b.diameters;
    r.valid = a.valid + b.valid;
    r.invalid = a.invalid + b.invalid;
    r.first_invalid = min(a.first_invalid, b.first_invalid);
    return r;
  }
};

__device__ Partial empty_partial() {
  Partial p;
  for (int k = 0; k < 3; ++k) {
    p.lo[k] = INFINITY;
    p.hi[k] = -INFINITY;
  }
  p.diameters = 0;
  p.valid = p.invalid = 0;
  p.first_invalid = 0xFFFFFFFFu;
  return p;
}

constexpr unsigned kPrepareBlocks = 1024;  // at most; the split depends on n alone, so sums are deterministic

// Each block takes a fixed share of the objects: checks them as validate_spheres() and
// validate_boxes() do (finite, radius >= 0, min <= max), writes a box's proxy (centre, radius) for
// the codes, and reduces its share's bounds, diameters and invalid objects into partial[block].
__global__ void prepare(std::uint32_t n, const float4* spheres, const float* boxes, float4* proxies, Partial* partial) {
  using Reduce = cub::BlockReduce<Partial, kBlock>;
  __shared__ typename Reduce::TempStorage temp;
  Partial mine = empty_partial();
  const std::uint64_t stride = std::uint64_t{gridDim.x} * kBlock;
  for (std::uint64_t k = blockIdx.x * std::uint64_t{kBlock} + threadIdx.x; k < n; k += stride) {
    float4 s;
    bool ok;
    if (boxes) {
      const float* b = boxes + 6 * k;
      ok = true;
      for (int a = 0; a < 3; ++a) ok = ok && isfinite(b[a]) && isfinite(b[a + 3]) && b[a] <= b[a + 3];
      // box_proxy(): the centre and the mean half side.
      s = make_float4((b[0] + b[3]) * 0.5f, (b[1] + b[4]) * 0.5f, (b[2] + b[5]) * 0.5f,
                      ((b[3] - b[0]) + (b[4] - b[1]) + (b[5] - b[2])) / 6.0f);
      proxies[k] = s;
    } else {
      s = spheres[k];
      ok = isfinite(s.x) && isfinite(s.y) && isfinite(s.z) && isfinite(s.w) && s.w >= 0.0f;
    }
    if (!ok) {
      ++mine.invalid;
      mine.first_invalid = min(mine.first_invalid, static_cast<unsigned>(k));
      continue;
    }
    mine.lo[0] = fminf(mine.lo[0], s.x), mine.lo[1] = fminf(mine.lo[1], s.y), mine.lo[2] = fminf(mine.lo[2], s.z);
    mine.hi[0] = fmaxf(mine.hi[0], s.x), mine.hi[1] = fmaxf(mine.hi[1], s.y), mine.hi[2] = fmaxf(mine.hi[2], s.z);
    mine.diameters += 2.0 * static_cast<double>(s.w);
    ++mine.valid;
  }
  const Partial all = Reduce(temp).Reduce(mine, MergePartial{});
  if (threadIdx.x == 0) partial[blockIdx.x] = all;
}

// One block: the partials merged in a fixed order, then the layout (the shared rule, the host's
// make_layout()) and its grid, and the report's header. The pair count is finish()'s.
__global__ void plan_grid(unsigned parts, const Partial* partial, std::uint32_t n, int bits, bool plain, Grid* grid,
                          Report* report) {
  using Reduce = cub::BlockReduce<Partial, kBlock>;
  __shared__ typename Reduce::TempStorage temp;
  Partial mine = empty_partial();
  for (unsigned k = threadIdx.x; k < parts; k += kBlock) mine = MergePartial{}(mine, partial[k]);
  const Partial all = Reduce(temp).Reduce(mine, MergePartial{});
  if (threadIdx.x != 0) return;
  float lo[3], hi[3], extent[3];
  for (int a = 0; a < 3; ++a) {
    lo[a] = all.valid ? all.lo[a] : 0.0f;
    hi[a] = all.valid ? all.hi[a] : 0.0f;
    extent[a] = fmaxf(0.0f, hi[a] - lo[a]);
  }
  const float mean = all.valid ? static_cast<float>(all.diameters / static_cast<double>(all.valid)) : 0.0f;
  const detail::rule::Layout l =
      plain ? detail::rule::plain_layout(bits) : detail::rule::extended_layout(bits, extent, mean);
  Grid g;
  for (int a = 0; a < 3; ++a) {
    detail::rule::axis_grid(l.axis_bits[a], lo[a], hi[a], g.lo[a], g.scale[a], g.max_cell[a]);
    g.axis_bits[a] = l.axis_bits[a];
    for (int b = 0; b < 32; ++b) g.position[a][b] = l.position[a][b];
  }
  g.bits = bits;
  *grid = g;
  report->pairs = 0;
  report->invalid = all.invalid;
  report->first_invalid = all.first_invalid;
  report->bits = static_cast<std::uint32_t>(bits);
  report->objects = n;
}

__global__ void device_codes(std::uint32_t n, const float4* centres, const Grid* grid, std::uint64_t* keys,
                             std::uint32_t* values) {
  const std::uint32_t k = blockIdx.x * blockDim.x + threadIdx.x;
  if (k >= n) return;
  const float4 s = centres[k];
  keys[k] = code_of(*grid, s.x, s.y, s.z);
  values[k] = k;
}

__global__ void fill_states(std::uint32_t n, std::uint8_t* states) {
  const std::uint32_t k = blockIdx.x * blockDim.x + threadIdx.x;
  if (k < n) states[k] = 1;  // ObjectState::free
}

__global__ void finish(std::uint32_t n, const unsigned long long* counts, const unsigned long long* offsets,
                       Report* report) {
  report->pairs = n >= 2 ? offsets[n - 1] + counts[n - 1] : 0ull;
}

unsigned prepare_blocks(std::uint32_t n) {
  return std::max(1u, std::min(kPrepareBlocks, static_cast<unsigned>((std::uint64_t{n} + kBlock - 1) / kBlock)));
}

}  // namespace

struct DeviceFrame::Impl {
  Buffer proxies, partial, grid, keys[2], values[2], nodes, parent, arrivals, sorted, leaf_boxes, frame_id, counts,
      offsets, kept, temp;
  std::size_t sort_temp = 0, scan_temp = 0;
  std::uint32_t sized_n = 0xFFFFFFFFu;  // the frame size the two above were asked for
  int sized_bits = 0;

  // The temporary storage CUB needs for n objects at `bits` (no device work), asked again only
  // when the size changes: every frame of a steady N skips it.
  Outcome temp_sizes(std::uint32_t n, int bits) {
    if (n == sized_n && bits == sized_bits) return {};
    cub::DoubleBuffer<std::uint64_t> k(nullptr, nullptr);
    cub::DoubleBuffer<std::uint32_t> v(nullptr, nullptr);
    VISCD_CUDA(cub::DeviceRadixSort::SortPairs(nullptr, sort_temp, k, v, static_cast<int>(n), 0, bits));
    VISCD_CUDA(cub::DeviceScan::ExclusiveSum(nullptr, scan_temp, static_cast<unsigned long long*>(nullptr),
                                             static_cast<unsigned long long*>(nullptr), static_cast<int>(n)));
    sized_n = n;
    sized_bits = bits;
    return {};
  }
  // Whether every buffer holds a frame of n objects.
  bool holds(std::uint32_t n, bool boxes) const {
    const std::size_t m = std::max<std::size_t>(n, 2);
    return (!boxes || proxies.capacity >= 16 * m) && keys[0].capacity >= 8 * m && kept.capacity >= 8 * kKept * m &&
           counts.capacity >= 8 * m && temp.capacity >= std::max(sort_temp, scan_temp) && grid.capacity >= sizeof(Grid);
  }
  Outcome reserve(std::uint32_t n, bool boxes, int bits) {
    if (Outcome o = temp_sizes(n, bits); !o.ok()) return o;
    const std::size_t m = std::max<std::size_t>(n, 2);
    if (boxes) VISCD_CUDA(proxies.reserve(16 * m));
    VISCD_CUDA(partial.reserve(sizeof(Partial) * kPrepareBlocks));
    VISCD_CUDA(grid.reserve(sizeof(Grid)));
    for (int k = 0; k < 2; ++k) {
      VISCD_CUDA(keys[k].reserve(8 * m));
      VISCD_CUDA(values[k].reserve(4 * m));
    }
    VISCD_CUDA(nodes.reserve(sizeof(Node) * m));
    VISCD_CUDA(parent.reserve(4 * 2 * m));
    VISCD_CUDA(arrivals.reserve(4 * m));
    VISCD_CUDA(sorted.reserve(16 * m));
    VISCD_CUDA(leaf_boxes.reserve(24 * m));
    VISCD_CUDA(frame_id.reserve(4 * m));
    VISCD_CUDA(counts.reserve(8 * m));
    VISCD_CUDA(offsets.reserve(8 * m));
    VISCD_CUDA(kept.reserve(sizeof(uint2) * kKept * m));
    VISCD_CUDA(temp.reserve(std::max(sort_temp, scan_temp)));
    return {};
  }
};

DeviceFrame::DeviceFrame() : impl_(std::make_unique<Impl>()) {}
DeviceFrame::~DeviceFrame() = default;

std::uint64_t DeviceFrame::bytes() const {
  const Impl& m = *impl_;
  std::uint64_t b = 0;
  for (const Buffer* x :
       {&m.proxies, &m.partial, &m.grid, &m.keys[0], &m.keys[1], &m.values[0], &m.values[1], &m.nodes, &m.parent,
        &m.arrivals, &m.sorted, &m.leaf_boxes, &m.frame_id, &m.counts, &m.offsets, &m.kept, &m.temp})
    b += x->capacity;
  return b;
}

Outcome DeviceFrame::reserve(std::uint32_t n, bool boxes, int bits) { return impl_->reserve(n, boxes, bits); }

Outcome DeviceFrame::enqueue(const DeviceInput& in, const DeviceOutput& out, void* stream_handle) {
  Impl& m = *impl_;
  const auto stream = static_cast<cudaStream_t>(stream_handle);
  const std::uint32_t n = in.n;
  const bool boxes = in.boxes != nullptr;
  cudaStreamCaptureStatus capture = cudaStreamCaptureStatusNone;
  VISCD_CUDA(cudaStreamIsCapturing(stream, &capture));
  if (Outcome o = m.temp_sizes(n, in.bits); !o.ok()) return o;
  if (!m.holds(n, boxes)) {
    if (capture != cudaStreamCaptureStatusNone) {
      Outcome o;
      o.error = "a frame of " + std::to_string(n) +
                " objects needs more device memory than reserve() gave, and allocating is not allowed while the "
                "stream is being captured: call reserve() with at least this many objects before the capture";
      return o;
    }
    if (Outcome o = m.reserve(n, boxes, in.bits); !o.ok()) return o;
  }
  const unsigned parts = prepare_blocks(n);
  const float4* centres = boxes ? m.proxies.as<float4>() : reinterpret_cast<const float4*>(in.spheres);
  prepare<<<parts, kBlock, 0, stream>>>(n, reinterpret_cast<const float4*>(in.spheres), in.boxes,
                                        m.proxies.as<float4>(), m.partial.as<Partial>());
  VISCD_CUDA(cudaGetLastError());
  plan_grid<<<1, kBlock, 0, stream>>>(parts, m.partial.as<Partial>(), n, in.bits, in.plain_layout, m.grid.as<Grid>(),
                                      out.report);
  VISCD_CUDA(cudaGetLastError());
  if (out.states && n) {
    fill_states<<<blocks(n), kBlock, 0, stream>>>(n, out.states);
    VISCD_CUDA(cudaGetLastError());
  }
  if (n < 2) return {};  // plan_grid() reported 0 pairs
  device_codes<<<blocks(n), kBlock, 0, stream>>>(n, centres, m.grid.as<Grid>(), m.keys[0].as<std::uint64_t>(),
                                                 m.values[0].as<std::uint32_t>());
  VISCD_CUDA(cudaGetLastError());
  cub::DoubleBuffer<std::uint64_t> keys(m.keys[0].as<std::uint64_t>(), m.keys[1].as<std::uint64_t>());
  cub::DoubleBuffer<std::uint32_t> values(m.values[0].as<std::uint32_t>(), m.values[1].as<std::uint32_t>());
  std::size_t temp_bytes = m.temp.capacity;
  VISCD_CUDA(
      cub::DeviceRadixSort::SortPairs(m.temp.ptr, temp_bytes, keys, values, static_cast<int>(n), 0, in.bits, stream));
  karras_build<<<blocks(n - 1), kBlock, 0, stream>>>(static_cast<int>(n), in.bits, keys.Current(), m.nodes.as<Node>(),
                                                     m.parent.as<std::uint32_t>(), m.arrivals.as<std::uint32_t>());
  VISCD_CUDA(cudaGetLastError());
  fit<<<blocks(n), kBlock, 0, stream>>>(n, centres, boxes ? in.boxes : nullptr, nullptr, values.Current(),
                                        m.sorted.as<float4>(), m.leaf_boxes.as<float>(), m.frame_id.as<std::uint32_t>(),
                                        m.nodes.as<Node>(), m.parent.as<std::uint32_t>(),
                                        m.arrivals.as<std::uint32_t>());
  VISCD_CUDA(cudaGetLastError());
  const auto* filters = reinterpret_cast<const uint2*>(in.filters);
  QueryOut counting;
  counting.counts = m.counts.as<unsigned long long>();
  counting.states = out.states;
  counting.kept = m.kept.as<uint2>();
  query<Pass::count><<<blocks(n), kBlock, 0, stream>>>(n, m.sorted.as<float4>(), m.leaf_boxes.as<float>(),
                                                       m.nodes.as<Node>(), m.frame_id.as<std::uint32_t>(), filters,
                                                       in.static_from, boxes, counting);
  VISCD_CUDA(cudaGetLastError());
  temp_bytes = m.temp.capacity;
  VISCD_CUDA(cub::DeviceScan::ExclusiveSum(m.temp.ptr, temp_bytes, m.counts.as<unsigned long long>(),
                                           m.offsets.as<unsigned long long>(), static_cast<int>(n), stream));
  if (out.capacity) {
    QueryOut writing;
    writing.offsets = m.offsets.as<unsigned long long>();
    writing.pairs = reinterpret_cast<uint2*>(out.pairs);
    writing.capacity = out.capacity;
    writing.counts = m.counts.as<unsigned long long>();
    writing.kept = m.kept.as<uint2>();
    query<Pass::write><<<blocks(n), kBlock, 0, stream>>>(n, m.sorted.as<float4>(), m.leaf_boxes.as<float>(),
                                                         m.nodes.as<Node>(), m.frame_id.as<std::uint32_t>(), filters,
                                                         in.static_from, boxes, writing);
    VISCD_CUDA(cudaGetLastError());
  }
  finish<<<1, 1, 0, stream>>>(n, m.counts.as<unsigned long long>(), m.offsets.as<unsigned long long>(), out.report);
  VISCD_CUDA(cudaGetLastError());
  return {};
}

std::string device_memory_problem(const void* p) {
  cudaPointerAttributes a{};
  if (const cudaError_t e = cudaPointerGetAttributes(&a, p); e != cudaSuccess) {
    (void)cudaGetLastError();
    return std::string("not a pointer CUDA knows (") + cudaGetErrorString(e) + ")";
  }
  if (a.type == cudaMemoryTypeHost) return "pinned host memory (copy it to the device first)";
  if (a.type != cudaMemoryTypeDevice && a.type != cudaMemoryTypeManaged) return "host memory";
  int current = 0;
  if (cudaGetDevice(&current) == cudaSuccess && a.type == cudaMemoryTypeDevice && a.device != current)
    return "memory of CUDA device " + std::to_string(a.device) + ", not of device " + std::to_string(current) +
           " where the broadphase runs";
  return {};
}

}  // namespace viscd::cuda
