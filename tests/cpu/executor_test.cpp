// Executors: the built-in pool runs every task once, from several callers at once; a caller's
// executor (Config::executor) receives the cpu backend's stages and the pairs stay exact.
#include <gtest/gtest.h>

#include <atomic>
#include <stdexcept>
#include <thread>
#include <vector>

#include "cpu/parallel.hpp"
#include "test_util.hpp"
#include "viscd/scene.hpp"
#include "viscd/viscd.hpp"

namespace viscd {
namespace {

using test::oracle_pairs;
using test::random_spheres_by_half_extent;
using test::same_pairs;

TEST(ThreadPool, RunsEveryTaskExactlyOnce) {
  Executor& pool = detail::default_executor();
  EXPECT_GE(pool.concurrency(), 1);
  for (std::uint32_t count : {0u, 1u, 2u, 3u, 64u, 1000u, 100000u}) {
    std::vector<std::atomic<int>> hits(count);
    pool.run(count, [&](std::uint32_t i) { hits[i].fetch_add(1); });
    for (std::uint32_t i = 0; i < count; ++i) ASSERT_EQ(hits[i].load(), 1) << "task " << i << " of " << count;
  }
}

TEST(ThreadPool, SeveralCallersAtOnceAndNestedStages) {
  // Two threads hand stages to the one pool at the same time (the busy pool runs the second
  // caller's stage on that caller), and tasks that start stages of their own run them inline.
  Executor& pool = detail::default_executor();
  std::atomic<long> sum{0};
  auto caller = [&] {
    for (int round = 0; round < 200; ++round)
      pool.run(16, [&](std::uint32_t i) {
        pool.run(4, [&](std::uint32_t j) { sum.fetch_add(static_cast<long>(i * 4 + j)); });
      });
  };
  std::thread a(caller), b(caller);
  a.join();
  b.join();
  EXPECT_EQ(sum.load(), 2L * 200 * (63 * 64 / 2));
}

// A caller's executor: records that it was used and runs the tasks backwards on two threads of
// its own, so that nothing may depend on the built-in pool's order.
class RecordingExecutor final : public Executor {
 public:
  [[nodiscard]] int concurrency() const override { return 3; }
  void run(std::uint32_t count, TaskRef task) override {
    ++stages;
    tasks += count;
    std::thread helper([&] {
      for (std::uint32_t i = count; i-- > 0;)
        if (i % 2 == 1) task(i);
    });
    for (std::uint32_t i = count; i-- > 0;)
      if (i % 2 == 0) task(i);
    helper.join();
  }
  long stages = 0, tasks = 0;
};

TEST(Executor, CallersExecutorRunsTheStagesAndPairsStayExact) {
  RecordingExecutor exec;
  Config c;
  c.executor = &exec;
  auto det = make_cpu_detector(c);
  for (std::size_t n : {0u, 1u, 2u, 5000u, 30000u}) {
    const auto spheres = random_spheres_by_half_extent(n, 40 + n, 60.0f, 0.2f, 1.5f);
    FrameResult f = test::run_frame(*det, spheres);
    EXPECT_TRUE(same_pairs(f.pairs, oracle_pairs(spheres))) << n;
  }
  EXPECT_GT(exec.stages, 0);
  // With a camera too: rasterizer tiles, counts and shading go through it, and give what the
  // detector's own threads give (the cpu backend's maps are checked against the reference's
  // brute-force map elsewhere; here that map would cost 10^9 ray casts).
  Scene scene = Scene::make({.objects = 20000});
  const Camera cam = camera_preset("zoom-out", scene, 320, 180).value();
  const long before = exec.stages;
  c.shade = true;
  det->set_config(c);
  Config own_threads = c;
  own_threads.executor = nullptr;
  auto ref = make_cpu_detector(own_threads);
  const FrameResult f = test::run_frame(*det, scene.spheres(), &cam);
  const FrameResult r = test::run_frame(*ref, scene.spheres(), &cam);
  EXPECT_GT(exec.stages, before);
  EXPECT_EQ(f.pixels, r.pixels);
  EXPECT_TRUE(same_pairs(f.pairs, r.pairs));
  EXPECT_EQ(f.image, r.image);
}

TEST(Executor, SerialExecutorAndOneThreadGiveTheSamePairs) {
  const auto spheres = random_spheres_by_half_extent(40000, 9, 80.0f, 0.2f, 1.5f);
  SerialExecutor serial;
  Config a;
  a.executor = &serial;
  Config b;
  b.threads = 1;
  auto da = make_cpu_detector(a), db = make_cpu_detector(b), dc = make_cpu_detector();
  const FrameResult fa = test::run_frame(*da, spheres), fb = test::run_frame(*db, spheres),
                    fc = test::run_frame(*dc, spheres);
  EXPECT_TRUE(same_pairs(fa.pairs, fb.pairs));
  EXPECT_TRUE(same_pairs(fc.pairs, fb.pairs));
  EXPECT_EQ(fa.stats.layout, fc.stats.layout);
}

// A caller's executor that throws (a job system out of workers, say): no exception leaves
// detect(), the frame fails with the exception's message, queries see nothing, and the next frame
// with a working executor is exact again.
class ThrowingExecutor final : public Executor {
 public:
  [[nodiscard]] int concurrency() const override { return 2; }
  void run(std::uint32_t, TaskRef) override { throw std::runtime_error("no workers left"); }
};

TEST(Executor, AnExecutorThatThrowsFailsTheFrame) {
  const auto spheres = random_spheres_by_half_extent(20000, 4, 40.0f, 0.2f, 1.5f);
  ThrowingExecutor bad;
  Config config;
  config.executor = &bad;
  auto d = make_cpu_detector(config);
  FrameInput in;
  in.spheres = spheres;
  FrameResult r;
  const Status s = d->detect(in, r);
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.kind(), ErrorKind::backend_failure);
  EXPECT_NE(s.error().find("no workers left"), std::string::npos) << s.error();
  RayHit hit;
  EXPECT_FALSE(d->ray_cast(test::make_ray(0, 0, -100, 0, 0, 1), hit));
  config.executor = nullptr;
  d->set_config(config);
  ASSERT_TRUE(d->detect(in, r).ok());
  EXPECT_TRUE(same_pairs(r.pairs, oracle_pairs(spheres)));
}

}  // namespace
}  // namespace viscd
