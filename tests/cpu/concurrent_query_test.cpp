// Queries from many threads at once on one detector between frames (Detector's threading rule):
// the answers equal one thread's, for frames that rebuilt, frames that followed change (whose
// query tree the first query builds), boxes (brute force over lists the first query gathers) and
// filters that leave objects out of the tree (whose tree the first query builds). The TSan
// preset runs this file to find data races.

#include <gtest/gtest.h>

#include <random>
#include <thread>
#include <vector>

#include "test_util.hpp"
#include "viscd/viscd.hpp"

namespace viscd {
namespace {

struct Answers {
  std::vector<std::vector<RayHit>> hits;
  std::vector<RayHit> first;
  std::vector<std::vector<std::uint32_t>> spheres, boxes;
  bool operator==(const Answers&) const = default;
};

// The same queries in the same order, with and without a query filter.
Answers ask(const Detector& d, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> u(-10, 10), dir(-1, 1);
  Answers a;
  const Filter qf{1, 0x3};
  for (int q = 0; q < 60; ++q) {
    const Ray ray = test::make_ray(u(rng), u(rng), u(rng), dir(rng), dir(rng), dir(rng) + 0.01f);
    const Filter* f = q % 2 ? &qf : nullptr;
    a.hits.emplace_back();
    d.ray_cast_all(ray, a.hits.back(), f);
    RayHit h{~0u, -1};
    (void)d.ray_cast(ray, h, f);
    a.first.push_back(h);
    const Sphere s{u(rng), u(rng), u(rng), 1.5f};
    a.spheres.emplace_back();
    d.overlap(s, a.spheres.back(), f);
    a.boxes.emplace_back();
    d.overlap_box(Box{{s.x - 1, s.y - 1, s.z - 1}, {s.x + 1, s.y + 1, s.z + 1}}, a.boxes.back(), f);
  }
  return a;
}

// Four threads ask at once, right after the frame (so that they race to build what the first
// query builds), then one thread asks alone: every answer must be the lone thread's.
void check_side_by_side(Detector& d, const FrameInput& in) {
  FrameResult f;
  ASSERT_TRUE(d.detect(in, f).ok());
  std::vector<Answers> got(4);
  std::vector<std::thread> threads;
  for (std::size_t t = 0; t < got.size(); ++t) threads.emplace_back([&, t] { got[t] = ask(d, 77); });
  for (auto& t : threads) t.join();
  const Answers alone = ask(d, 77);
  for (const Answers& a : got) EXPECT_TRUE(a == alone);
}

TEST(ConcurrentQueries, SpheresRebuiltFollowedAndFiltered) {
  std::vector<Sphere> s = test::random_spheres_by_half_extent(3000, 1, 10);
  const std::vector<Filter> filters = test::random_filters(s.size(), 2);
  auto d = make_cpu_detector();
  for (int frame = 0; frame < 4; ++frame) {
    SCOPED_TRACE(frame);
    s[static_cast<std::size_t>(frame) * 7].x += 0.5f;  // a few move: the later frames are followed
    FrameInput in;
    in.spheres = s;
    if (frame % 2) in.filters = filters;
    check_side_by_side(*d, in);
  }
  FrameResult f;
  ASSERT_TRUE(d->detect(s, nullptr, f).ok());
  EXPECT_TRUE(f.stats.followed_change) << "the followed frames' query tree must be among those tested";
}

TEST(ConcurrentQueries, BoxesAndStaticSet) {
  const std::vector<Sphere> s = test::random_spheres_by_half_extent(2000, 3, 10);
  std::vector<Box> boxes;
  for (const Sphere& x : s) boxes.push_back(Box{{x.x - x.r, x.y - x.r, x.z - x.r}, {x.x + x.r, x.y + x.r, x.z + x.r}});
  auto d = make_cpu_detector();
  ASSERT_TRUE(d->add_static_box(Box{{-3, -3, -3}, {3, 3, 3}}).ok());
  for (int frame = 0; frame < 3; ++frame) {
    SCOPED_TRACE(frame);
    boxes[static_cast<std::size_t>(frame)].min[0] -= 0.25f;
    FrameInput in;
    in.boxes = boxes;
    check_side_by_side(*d, in);
  }
}

}  // namespace
}  // namespace viscd
