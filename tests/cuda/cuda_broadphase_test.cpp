// The device-resident broadphase (viscd/cuda.hpp CudaBroadphase): objects, pairs, report and
// states in device memory, enqueued on a stream. Its pairs are checked against the cpu backend's
// detect() and a brute force, as sets (the device order is the tree's) and for determinism; the
// capacity rule (every pair counted, none dropped), graph capture, the degenerate counts and the
// argument errors. On a machine without a usable GPU each test skips, saying why, except the one
// that checks the error.
#include <cuda_runtime.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "test_util.hpp"
#include "viscd/cuda.hpp"
#include "viscd/scene.hpp"
#include "viscd/viscd.hpp"

namespace viscd {
namespace {

#define VISCD_BROADPHASE_OR_SKIP(name, config)                                          \
  auto name##_made = make_cuda_broadphase(config);                                      \
  if (!name##_made) GTEST_SKIP() << "no cuda broadphase here: " << name##_made.error(); \
  CudaBroadphase& name = *name##_made.value()

#define CUDA_OK(call) ASSERT_EQ((call), cudaSuccess) << #call

// Device memory for a test: a typed array that frees itself.
template <class T>
class DeviceArray {
 public:
  explicit DeviceArray(std::size_t n) : n_(n) {
    if (n && cudaMalloc(&p_, n * sizeof(T)) != cudaSuccess) p_ = nullptr;
  }
  explicit DeviceArray(const std::vector<T>& host) : DeviceArray(host.size()) { upload(host); }
  ~DeviceArray() {
    if (p_) cudaFree(p_);
  }
  DeviceArray(const DeviceArray&) = delete;
  DeviceArray& operator=(const DeviceArray&) = delete;
  void upload(const std::vector<T>& host) {
    if (!host.empty()) {
      EXPECT_EQ(cudaMemcpy(p_, host.data(), host.size() * sizeof(T), cudaMemcpyHostToDevice), cudaSuccess);
    }
  }
  [[nodiscard]] std::vector<T> download(std::size_t count) const {
    std::vector<T> out(count);
    if (count) {
      EXPECT_EQ(cudaMemcpy(out.data(), p_, count * sizeof(T), cudaMemcpyDeviceToHost), cudaSuccess);
    }
    return out;
  }
  [[nodiscard]] T* get() const { return p_; }
  [[nodiscard]] std::size_t size() const { return n_; }

 private:
  T* p_ = nullptr;
  std::size_t n_ = 0;
};

// What one frame gave, downloaded.
struct Got {
  CudaReport report;
  std::vector<Pair> pairs;  // as written (the device order), at most the capacity
  std::vector<ObjectState> states;
};

// Runs one frame of host objects through device memory on a stream of its own.
Got run(CudaBroadphase& bp, const std::vector<Sphere>* spheres, const std::vector<Box>* boxes,
        const std::vector<Filter>* filters = nullptr, std::uint32_t static_from = 0xFFFFFFFFu,
        std::uint64_t capacity = std::numeric_limits<std::uint64_t>::max()) {
  const std::size_t n = spheres ? spheres->size() : boxes->size();
  DeviceArray<Sphere> ds(spheres ? *spheres : std::vector<Sphere>{});
  DeviceArray<Box> db(boxes ? *boxes : std::vector<Box>{});
  DeviceArray<Filter> df(filters ? *filters : std::vector<Filter>{});
  if (capacity == std::numeric_limits<std::uint64_t>::max()) capacity = std::max<std::size_t>(n * 64, 16);
  DeviceArray<Pair> dp(capacity);
  DeviceArray<CudaReport> dr(1);
  DeviceArray<ObjectState> dst(n);
  cudaStream_t stream = nullptr;
  EXPECT_EQ(cudaStreamCreate(&stream), cudaSuccess);
  CudaObjects o;
  o.spheres = spheres ? ds.get() : nullptr;
  o.boxes = boxes ? db.get() : nullptr;
  o.count = static_cast<std::uint32_t>(n);
  o.filters = filters ? df.get() : nullptr;
  o.static_from = static_from;
  CudaResults r;
  r.pairs = dp.get();
  r.capacity = capacity;
  r.report = dr.get();
  r.states = dst.get();
  const Status s = bp.enqueue(o, r, stream);
  EXPECT_TRUE(s.ok()) << s.error();
  EXPECT_EQ(cudaStreamSynchronize(stream), cudaSuccess);
  cudaStreamDestroy(stream);
  Got g;
  g.report = dr.download(1)[0];
  g.pairs = dp.download(std::min<std::uint64_t>(g.report.pairs, capacity));
  g.states = dst.download(n);
  return g;
}

std::vector<Pair> sorted(std::vector<Pair> p) {
  std::sort(p.begin(), p.end());
  return p;
}

std::vector<Box> cubes_of(const std::vector<Sphere>& spheres) {
  std::vector<Box> boxes;
  for (const Sphere& s : spheres)
    boxes.push_back(Box{{s.x - s.r, s.y - s.r, s.z - s.r}, {s.x + s.r, s.y + s.r, s.z + s.r}});
  return boxes;
}

TEST(CudaBroadphase, DeviceOrClearError) {
  const auto device = cuda_device();
  const auto made = make_cuda_broadphase();
  ASSERT_EQ(device.ok(), made.ok());
  if (!made) {
    EXPECT_NE(made.error().find("CUDA"), std::string::npos) << made.error();
  }
}

// Dense moving scenes (0.6 pairs an object) around the block size, spheres and boxes, against
// the cpu backend with culling off: the same pairs as a set, the same states, the true count,
// i < j in every pair, and no pair twice.
TEST(CudaBroadphase, DenseScenesMatchCpu) {
  Config c;
  c.bits = Bits::b32;
  c.culling = false;
  VISCD_BROADPHASE_OR_SKIP(bp, c);
  auto cpu = make_cpu_detector(c);
  for (std::uint32_t n : {255u, 256u, 257u, 20000u, 300000u}) {
    Scene scene = Scene::make(SceneParams{.objects = n, .seed = 7, .packing = 0.18f});
    for (int frame = 0; frame < 2; ++frame) {
      SCOPED_TRACE("N = " + std::to_string(n) + ", frame " + std::to_string(frame));
      const std::vector<Sphere> spheres(scene.spheres().begin(), scene.spheres().end());
      const FrameResult want = test::run_frame(*cpu, spheres);
      const Got got = run(bp, &spheres, nullptr);
      EXPECT_EQ(got.report.pairs, want.pairs.size());
      EXPECT_EQ(got.report.invalid, 0u);
      EXPECT_EQ(got.report.objects, n);
      EXPECT_EQ(got.report.bits, 32u);
      for (const Pair& p : got.pairs) ASSERT_LT(p.i, p.j);
      EXPECT_TRUE(test::same_pairs(sorted(got.pairs), want.pairs));
      EXPECT_EQ(got.states, want.state);
      const std::vector<Box> boxes = cubes_of(spheres);
      FrameResult want_boxes;
      FrameInput in;
      in.boxes = boxes;
      ASSERT_TRUE(cpu->detect(in, want_boxes).ok());
      const Got got_boxes = run(bp, nullptr, &boxes);
      EXPECT_EQ(got_boxes.report.pairs, want_boxes.pairs.size());
      EXPECT_TRUE(test::same_pairs(sorted(got_boxes.pairs), want_boxes.pairs));
      EXPECT_EQ(got_boxes.states, want_boxes.state);
      scene.step(1.0f / 60.0f);
    }
  }
}

// Every layout and width gives the same pairs; the same input gives the same array, order included.
TEST(CudaBroadphase, EveryWidthAndLayoutSamePairsDeterministic) {
  const std::vector<Sphere> s = test::random_spheres_by_half_extent(5000, 21, 30.0f);
  const std::vector<Pair> want = test::oracle_pairs(s);
  for (Bits b : {Bits::b16, Bits::b32, Bits::b64, Bits::adaptive})
    for (Layout l : {Layout::extended, Layout::plain}) {
      VISCD_BROADPHASE_OR_SKIP(bp, test::config_bits(b, l));
      const Got a = run(bp, &s, nullptr);
      const Got again = run(bp, &s, nullptr);
      EXPECT_TRUE(test::same_pairs(sorted(a.pairs), want)) << static_cast<int>(b);
      EXPECT_TRUE(test::same_pairs(a.pairs, again.pairs)) << "not deterministic";
      EXPECT_EQ(a.report.bits, b == Bits::adaptive ? 32u : static_cast<unsigned>(b));
    }
}

// Filters and a static tail together, against a brute force written here.
TEST(CudaBroadphase, FiltersAndStaticTail) {
  VISCD_BROADPHASE_OR_SKIP(bp, Config{});
  const std::vector<Sphere> s = test::random_spheres_by_half_extent(3000, 5, 10.0f);
  const std::vector<Filter> f = test::random_filters(s.size(), 3);
  const std::uint32_t static_from = 2000;
  std::vector<Pair> want;
  for (const Pair& p : test::oracle_filtered_pairs(s, f))
    if (p.i < static_from || p.j < static_from) want.push_back(p);
  ASSERT_GT(want.size(), 100u);
  const Got got = run(bp, &s, nullptr, &f, static_from);
  EXPECT_TRUE(test::same_pairs(sorted(got.pairs), want));
  // Boxes through the same rules.
  const std::vector<Box> boxes = cubes_of(s);
  std::vector<Pair> want_boxes;
  for (std::uint32_t i = 0; i < boxes.size(); ++i)
    for (std::uint32_t j = i + 1; j < boxes.size(); ++j) {
      bool meet = true;
      for (int a = 0; a < 3; ++a)
        meet = meet && boxes[i].min[a] <= boxes[j].max[a] && boxes[j].min[a] <= boxes[i].max[a];
      if (meet && (f[i].group & f[j].mask) && (f[j].group & f[i].mask) && (i < static_from || j < static_from))
        want_boxes.push_back({i, j});
    }
  const Got got_boxes = run(bp, nullptr, &boxes, &f, static_from);
  EXPECT_TRUE(test::same_pairs(sorted(got_boxes.pairs), want_boxes));
}

// Every object at one point: n(n-1)/2 pairs. With room for 10 the report still counts them all,
// the 10 written are among them, and every state is colliding; with room for all, all of them.
TEST(CudaBroadphase, ShortCapacityCountsEveryPair) {
  VISCD_BROADPHASE_OR_SKIP(bp, Config{});
  const std::uint32_t n = 3000;
  const std::vector<Sphere> same(n, Sphere{1, 2, 3, 0.5f});
  const Got few = run(bp, &same, nullptr, nullptr, 0xFFFFFFFFu, 10);
  EXPECT_EQ(few.report.pairs, max_pairs_bound(n));
  ASSERT_EQ(few.pairs.size(), 10u);
  for (const Pair& p : few.pairs) EXPECT_LT(p.i, p.j);
  EXPECT_EQ(std::count(few.states.begin(), few.states.end(), ObjectState::colliding), static_cast<long>(n));
  const Got none = run(bp, &same, nullptr, nullptr, 0xFFFFFFFFu, 0);
  EXPECT_EQ(none.report.pairs, max_pairs_bound(n));
  const Got all = run(bp, &same, nullptr, nullptr, 0xFFFFFFFFu, max_pairs_bound(n));
  const std::vector<Pair> got = sorted(all.pairs);
  ASSERT_EQ(got.size(), max_pairs_bound(n));
  std::size_t k = 0;
  for (std::uint32_t i = 0; i < n; ++i)
    for (std::uint32_t j = i + 1; j < n; ++j, ++k) ASSERT_EQ(got[k], (Pair{i, j}));
}

// N = 0, 1, 2 (touching), huge and tiny radii, and invalid objects reported, not paired.
TEST(CudaBroadphase, DegenerateInputs) {
  VISCD_BROADPHASE_OR_SKIP(bp, Config{});
  {
    DeviceArray<CudaReport> dr(1);
    CudaObjects o;  // count 0, no pointers
    CudaResults r;
    r.report = dr.get();
    ASSERT_TRUE(bp.enqueue(o, r, nullptr).ok());
    CUDA_OK(cudaDeviceSynchronize());
    const CudaReport rep = dr.download(1)[0];
    EXPECT_EQ(rep.pairs, 0u);
    EXPECT_EQ(rep.invalid, 0u);
    EXPECT_EQ(rep.objects, 0u);
  }
  const std::vector<Sphere> one = {{0, 0, 0, 1}};
  EXPECT_EQ(run(bp, &one, nullptr).report.pairs, 0u);
  const std::vector<Sphere> touching = {{0, 0, 0, 1}, {2, 0, 0, 1}};
  const Got t = run(bp, &touching, nullptr);
  ASSERT_EQ(t.pairs.size(), 1u);
  EXPECT_EQ(t.pairs[0], (Pair{0, 1}));
  EXPECT_EQ(t.states, (std::vector<ObjectState>{ObjectState::colliding, ObjectState::colliding}));
  const std::vector<Sphere> apart = {{0, 0, 0, 1}, {2.0001f, 0, 0, 1}};
  EXPECT_EQ(run(bp, &apart, nullptr).report.pairs, 0u);
  std::vector<Sphere> mixed = test::random_spheres_by_half_extent(1000, 8, 40.0f);
  mixed[10].r = 1e30f;   // meets everything
  mixed[20].r = 1e-30f;  // meets (almost) nothing
  EXPECT_TRUE(test::same_pairs(sorted(run(bp, &mixed, nullptr).pairs), test::oracle_pairs(mixed)));
  std::vector<Sphere> bad = mixed;
  bad[10].r = 1.0f;
  bad[700].x = std::numeric_limits<float>::quiet_NaN();
  bad[300].r = -1.0f;
  bad[900].z = std::numeric_limits<float>::infinity();
  const Got g = run(bp, &bad, nullptr);
  EXPECT_EQ(g.report.invalid, 3u);
  EXPECT_EQ(g.report.first_invalid, 300u);
  for (const Pair& p : g.pairs)
    for (std::uint32_t k : {300u, 700u}) EXPECT_TRUE(p.i != k && p.j != k);
  std::vector<Box> boxes = cubes_of(mixed);
  std::swap(boxes[5].min[1], boxes[5].max[1]);
  EXPECT_EQ(run(bp, nullptr, &boxes).report.first_invalid, 5u);
}

// The frame captured into a CUDA graph and replayed over new positions equals a direct enqueue;
// a capture that would have to allocate fails and says to reserve first.
TEST(CudaBroadphase, CapturedGraphReplays) {
  VISCD_BROADPHASE_OR_SKIP(bp, Config{});
  const std::uint32_t n = 20000;
  Scene scene = Scene::make(SceneParams{.objects = n, .seed = 3, .packing = 0.18f});
  DeviceArray<Sphere> ds(n);
  DeviceArray<Pair> dp(64 * n);
  DeviceArray<CudaReport> dr(1);
  DeviceArray<ObjectState> dst(n);
  CudaObjects o;
  o.spheres = ds.get();
  o.count = n;
  CudaResults r;
  r.pairs = dp.get();
  r.capacity = dp.size();
  r.report = dr.get();
  r.states = dst.get();
  cudaStream_t stream = nullptr;
  CUDA_OK(cudaStreamCreate(&stream));
  // Too small a reservation: the capture fails with the reason, and ends cleanly.
  ASSERT_TRUE(bp.reserve(100, false).ok());
  CUDA_OK(cudaStreamBeginCapture(stream, cudaStreamCaptureModeThreadLocal));
  const Status refused = bp.enqueue(o, r, stream);
  cudaGraph_t broken = nullptr;
  (void)cudaStreamEndCapture(stream, &broken);
  if (broken) cudaGraphDestroy(broken);
  (void)cudaGetLastError();
  ASSERT_FALSE(refused.ok());
  EXPECT_NE(refused.error().find("reserve()"), std::string::npos) << refused.error();
  // Reserved: captured once, replayed each frame.
  ASSERT_TRUE(bp.reserve(n, false).ok());
  cudaGraph_t graph = nullptr;
  CUDA_OK(cudaStreamBeginCapture(stream, cudaStreamCaptureModeThreadLocal));
  const Status captured = bp.enqueue(o, r, stream);
  CUDA_OK(cudaStreamEndCapture(stream, &graph));
  ASSERT_TRUE(captured.ok()) << captured.error();
  cudaGraphExec_t exec = nullptr;
  CUDA_OK(cudaGraphInstantiate(&exec, graph, 0));
  auto cpu = make_cpu_detector(Config{});
  for (int frame = 0; frame < 3; ++frame) {
    const std::vector<Sphere> spheres(scene.spheres().begin(), scene.spheres().end());
    ds.upload(spheres);
    CUDA_OK(cudaGraphLaunch(exec, stream));
    CUDA_OK(cudaStreamSynchronize(stream));
    const CudaReport rep = dr.download(1)[0];
    const std::vector<Pair> got = dp.download(rep.pairs);
    const Got direct = run(bp, &spheres, nullptr);
    EXPECT_TRUE(test::same_pairs(got, direct.pairs)) << "frame " << frame;
    EXPECT_TRUE(test::same_pairs(sorted(got), test::run_frame(*cpu, spheres).pairs)) << "frame " << frame;
    scene.step(1.0f / 60.0f);
  }
  cudaGraphExecDestroy(exec);
  cudaGraphDestroy(graph);
  cudaStreamDestroy(stream);
}

// Arguments checked on the host, each error naming the field; nothing is enqueued.
TEST(CudaBroadphase, BadArgumentsNameTheField) {
  VISCD_BROADPHASE_OR_SKIP(bp, Config{});
  const std::vector<Sphere> host = {{0, 0, 0, 1}, {1, 0, 0, 1}};
  DeviceArray<Sphere> ds(host);
  DeviceArray<Box> db(2);
  DeviceArray<Pair> dp(4);
  DeviceArray<CudaReport> dr(1);
  CudaObjects o;
  o.spheres = ds.get();
  o.count = 2;
  CudaResults r;
  r.pairs = dp.get();
  r.capacity = 4;
  r.report = dr.get();
  auto error_of = [&](CudaObjects oo, CudaResults rr) {
    const Status s = bp.enqueue(oo, rr, nullptr);
    EXPECT_FALSE(s.ok());
    if (!s.ok()) {
      EXPECT_EQ(s.kind(), ErrorKind::invalid_input) << s.error();
    }
    return s.ok() ? std::string() : s.error();
  };
  CudaObjects host_objects = o;
  host_objects.spheres = host.data();
  EXPECT_NE(error_of(host_objects, r).find("CudaObjects::spheres points to host memory"), std::string::npos);
  CudaObjects both = o;
  both.boxes = db.get();
  EXPECT_NE(error_of(both, r).find("both"), std::string::npos);
  CudaObjects neither = o;
  neither.spheres = nullptr;
  EXPECT_NE(error_of(neither, r).find("neither"), std::string::npos);
  CudaObjects misaligned = o;
  misaligned.spheres = reinterpret_cast<const Sphere*>(reinterpret_cast<const char*>(ds.get()) + 4);
  EXPECT_NE(error_of(misaligned, r).find("aligned"), std::string::npos);
  CudaResults no_report = r;
  no_report.report = nullptr;
  EXPECT_NE(error_of(o, no_report).find("CudaResults::report"), std::string::npos);
  CudaResults no_pairs = r;
  no_pairs.pairs = nullptr;
  EXPECT_NE(error_of(o, no_pairs).find("CudaResults::pairs"), std::string::npos);
  CudaObjects past = o;
  past.static_from = 3;
  EXPECT_NE(error_of(past, r).find("static_from"), std::string::npos);
  // The good call still works after the refusals.
  ASSERT_TRUE(bp.enqueue(o, r, nullptr).ok());
  CUDA_OK(cudaDeviceSynchronize());
  EXPECT_EQ(dr.download(1)[0].pairs, 1u);
}

}  // namespace
}  // namespace viscd
