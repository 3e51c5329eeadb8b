// Collision filters (group/mask) in the cpu broadphase, the filters' pre-pass and the cpu and
// reference backends, against brute force with the filter rule written out in the tests
// (test::oracle_filtered_pairs) and hand-worked cases.
#include <gtest/gtest.h>

#include <numeric>
#include <random>

#include "cpu/bucket_broadphase.hpp"
#include "cpu/pipeline.hpp"
#include "test_util.hpp"

namespace viscd {
namespace {

using test::all_of;
using test::oracle_filtered_pairs;
using test::random_filters;
using test::random_spheres_by_half_extent;
using test::same_pairs;

FrameResult run_filtered(Detector& d, std::span<const Sphere> s, std::span<const Filter> f,
                         const Camera* cam = nullptr) {
  FrameInput in;
  in.spheres = s;
  in.filters = f;
  in.camera = cam;
  FrameResult out;
  const Status st = d.detect(in, out);
  EXPECT_TRUE(st.ok()) << d.name() << ": " << st.error();
  return out;
}

// The frame of both CPU-side backends against the oracle over every object (no camera): pairs,
// and states (every object active: free or colliding).
void check_both(std::span<const Sphere> s, std::span<const Filter> f, const std::string& what) {
  const std::vector<Pair> want = oracle_filtered_pairs(s, f);
  for (auto make : {make_cpu_detector, make_reference_detector}) {
    auto d = make(Config{});
    const FrameResult got = run_filtered(*d, s, f);
    EXPECT_TRUE(same_pairs(got.pairs, want)) << d->name() << ": " << what;
    ASSERT_EQ(got.state.size(), s.size());
    std::vector<ObjectState> state(s.size(), ObjectState::free);
    for (const Pair& p : want) state[p.i] = state[p.j] = ObjectState::colliding;
    EXPECT_EQ(got.state, state) << d->name() << ": " << what;
    EXPECT_EQ(got.stats.active, s.size()) << d->name() << ": filtered objects stay active";
  }
}

TEST(FilterRule, HandWorked) {
  EXPECT_TRUE(pair_passes_filter({1, 0xFFFFFFFFu}, {1, 0xFFFFFFFFu}));
  EXPECT_FALSE(pair_passes_filter({0, 0xFFFFFFFFu}, {1, 0xFFFFFFFFu})) << "group 0 belongs to nothing";
  EXPECT_FALSE(pair_passes_filter({1, 0}, {1, 0xFFFFFFFFu})) << "mask 0 accepts nothing";
  EXPECT_FALSE(pair_passes_filter({1, 2}, {2, 2})) << "b's mask does not accept a's group";
  EXPECT_TRUE(pair_passes_filter({1, 2}, {2, 1}));
  EXPECT_TRUE(pair_passes_filter({3, 4}, {4, 2}));
}

TEST(FilterPrepass, SplitsByWhatTheActiveSetCanPair) {
  const std::vector<Filter> f = {{1, 2}, {2, 1}, {4, 8}, {8, 4}, {16, 0}, {4, 1}};
  std::vector<std::uint32_t> pairable_buffer, unpaired_buffer;
  std::vector<std::uint32_t> pairable, unpaired;
  auto split = [&](const std::vector<std::uint32_t>& active, std::span<const Filter> filters) {
    const detail::FilterSplit s = detail::split_by_filters(active, filters, pairable_buffer, unpaired_buffer);
    pairable.assign(s.pairable.begin(), s.pairable.end());
    unpaired.assign(s.unpaired.begin(), s.unpaired.end());
  };
  // Active {0, 1, 2, 4}: G = 1 | 2 | 4 | 16 = 23, M = 2 | 1 | 8 | 0 = 11.
  // 0: mask 2 & G, group 1 & M: can. 1: mask 1 & G, group 2 & M: can. 2: mask 8 & G = 0: cannot.
  // 4: mask 0: cannot.
  split({0, 1, 2, 4}, f);
  EXPECT_EQ(pairable, (std::vector<std::uint32_t>{0, 1}));
  EXPECT_EQ(unpaired, (std::vector<std::uint32_t>{2, 4}));
  // Active {0, ..., 4}: G = 31, M = 15. Now 2 (mask 8, group 4) and 3 (mask 4, group 8) can.
  split({0, 1, 2, 3, 4}, f);
  EXPECT_EQ(pairable, (std::vector<std::uint32_t>{0, 1, 2, 3}));
  EXPECT_EQ(unpaired, (std::vector<std::uint32_t>{4}));
  // Active {2, 5}: G = 4, M = 9. 2: mask 8 & 4 = 0: cannot. 5: mask 1 & 4 = 0: cannot.
  split({2, 5}, f);
  EXPECT_TRUE(pairable.empty());
  EXPECT_EQ(unpaired, (std::vector<std::uint32_t>{2, 5}));
  // A necessary condition only: these three pass it (G = M = 7), yet no two accept each other;
  // the broadphase's own test per pair decides.
  const std::vector<Filter> ring = {{1, 2}, {2, 4}, {4, 1}};
  split({0, 1, 2}, ring);
  EXPECT_EQ(pairable, (std::vector<std::uint32_t>{0, 1, 2}));
  EXPECT_TRUE(unpaired.empty());
  check_both(std::vector<Sphere>(3, Sphere{0, 0, 0, 1}), ring, "three that pass the pre-pass and pair with none");
  split({}, f);
  EXPECT_TRUE(pairable.empty() && unpaired.empty());
}

TEST(FilterBroadphase, RandomFiltersAroundBucketMultiples) {
  for (std::size_t n : {0u, 1u, 2u, 15u, 16u, 17u, 31u, 32u, 33u, 255u, 256u, 257u, 3000u}) {
    const auto s = random_spheres_by_half_extent(n, n + 7, 2.0f + 0.05f * static_cast<float>(n));
    const auto f = random_filters(n, n + 3);
    for (int bits : {16, 32, 64}) {
      detail::BucketBroadphase bp;
      std::vector<Pair> pairs;
      FrameStats stats;
      ASSERT_TRUE(bp.run(s, all_of(n), f, bits, Layout::extended, 2, 0, pairs, stats).ok());
      EXPECT_TRUE(same_pairs(pairs, oracle_filtered_pairs(s, f))) << "n = " << n << ", m = " << bits;
    }
  }
}

TEST(FilterBroadphase, FiltersChangeFromFrameToFrame) {
  // One broadphase, frames alternating with and without filters and with other filters: no
  // filter of an earlier frame may leak into a later one.
  detail::BucketBroadphase bp;
  auto s = random_spheres_by_half_extent(2000, 5, 9.0f);
  for (int frame = 0; frame < 8; ++frame) {
    for (Sphere& x : s) x.x += 0.05f;
    std::vector<Pair> pairs;
    FrameStats stats;
    if (frame % 3 == 2) {
      ASSERT_TRUE(bp.run(s, all_of(s.size()), 32, Layout::extended, 2, 0, pairs, stats).ok());
      EXPECT_TRUE(same_pairs(pairs, test::oracle_pairs(s))) << "frame " << frame << " without filters";
    } else {
      const auto f = random_filters(s.size(), static_cast<std::uint64_t>(frame));
      ASSERT_TRUE(bp.run(s, all_of(s.size()), f, 32, Layout::extended, 2, 0, pairs, stats).ok());
      EXPECT_TRUE(same_pairs(pairs, oracle_filtered_pairs(s, f))) << "frame " << frame;
    }
  }
}

TEST(FilterDetector, DegenerateCases) {
  const Filter all{};
  check_both({}, {}, "N = 0");
  check_both(std::vector<Sphere>{{0, 0, 0, 1}}, std::vector<Filter>{all}, "N = 1");
  const std::vector<Sphere> two = {{0, 0, 0, 1}, {2, 0, 0, 1}};  // touching exactly
  check_both(two, std::vector<Filter>{all, all}, "N = 2 touching, default filters");
  check_both(two, std::vector<Filter>{{0, ~0u}, all}, "N = 2, group 0");
  check_both(two, std::vector<Filter>{{1, 0}, all}, "N = 2, mask 0");
  check_both(two, std::vector<Filter>{{1, 2}, {2, 2}}, "N = 2, one-sided masks");
  check_both(two, std::vector<Filter>{{1, 2}, {2, 1}}, "N = 2, each accepts the other");
  // Identical centres: every pair overlaps, the filters alone decide.
  const std::vector<Sphere> same(300, Sphere{1, 2, 3, 0.5f});
  check_both(same, random_filters(same.size(), 9), "300 identical spheres, random filters");
  std::vector<Filter> alternate(same.size());
  for (std::size_t k = 0; k < alternate.size(); ++k) alternate[k] = {k % 2 ? 2u : 1u, k % 2 ? 2u : 1u};
  check_both(same, alternate, "identical spheres, two groups that collide only among themselves");
  // Everything filtered out.
  const auto cloud = random_spheres_by_half_extent(500, 3, 4.0f);
  check_both(cloud, std::vector<Filter>(cloud.size(), Filter{0, ~0u}), "every group 0");
  check_both(cloud, std::vector<Filter>(cloud.size(), Filter{1, 0}), "every mask 0");
  check_both(cloud, std::vector<Filter>(cloud.size(), Filter{}), "every filter default");
  // Touching grid with groups by column.
  std::vector<Sphere> grid;
  std::vector<Filter> by_column;
  for (int x = 0; x < 12; ++x)
    for (int y = 0; y < 12; ++y) {
      grid.push_back({float(x), float(y), 0, 0.5f});
      by_column.push_back({1u << (x % 3), x % 3 == 0 ? ~0u : 1u});
    }
  check_both(grid, by_column, "touching grid, groups by column");
}

TEST(FilterDetector, HalfTheObjectsCollideWithNothing) {
  // The case the pre-pass is for: half in a group no mask accepts and with mask 0.
  const auto s = random_spheres_by_half_extent(20000, 17, 40.0f, 0.2f, 0.8f);
  std::vector<Filter> f(s.size());
  for (std::size_t k = 0; k < f.size(); k += 2) f[k] = {2, 0};
  for (std::size_t k = 1; k < f.size(); k += 2) f[k] = {1, 1};
  check_both(s, f, "half in group 2 with mask 0");
}

TEST(FilterDetector, WithCulling) {
  // With a camera, the filters apply among the objects culling leaves: cpu against the oracle
  // over the reference backend's active set.
  const auto s = random_spheres_by_half_extent(600, 21, 6.0f, 0.2f, 1.2f);
  const auto f = random_filters(s.size(), 4);
  Camera cam;
  cam.eye[2] = 14;
  cam.width = 160;
  cam.height = 120;
  Config c;
  c.lambda = 30;
  auto ref = make_reference_detector(c), cpu = make_cpu_detector(c);
  const FrameResult fr = run_filtered(*ref, s, f, &cam), fc = run_filtered(*cpu, s, f, &cam);
  std::vector<std::uint32_t> active;
  for (std::uint32_t k = 0; k < s.size(); ++k)
    if (fr.state[k] != ObjectState::culled) active.push_back(k);
  ASSERT_GT(active.size(), 10u);
  ASSERT_LT(active.size(), s.size());
  const auto want = oracle_filtered_pairs(s, f, &active);
  EXPECT_TRUE(same_pairs(fr.pairs, want)) << "reference";
  EXPECT_TRUE(same_pairs(fc.pairs, want)) << "cpu";
  EXPECT_EQ(fc.state, fr.state);
}

TEST(FilterDetector, ContactEventsFollowTheFilters) {
  // Frames whose filters change: a pair the filters drop ends, one they let through again begins,
  // against std::set_difference of the oracle's filtered pair sets.
  std::vector<Sphere> s = random_spheres_by_half_extent(700, 44, 6.0f, 0.2f, 1.0f);
  for (auto make : {make_cpu_detector, make_reference_detector}) {
    Config c;
    c.contact_events = true;
    auto d = make(c);
    std::vector<Pair> before;
    for (int frame = 0; frame < 8; ++frame) {
      std::vector<Filter> f = random_filters(s.size(), static_cast<std::uint64_t>(frame % 3));
      if (frame == 5) f.clear();  // no filters: every overlapping pair
      for (Sphere& x : s) x.y += 0.05f;
      FrameInput in;
      in.spheres = s;
      in.filters = f;
      FrameResult out;
      ASSERT_TRUE(d->detect(in, out).ok());
      const std::vector<Pair> now = f.empty() ? test::oracle_pairs(s) : oracle_filtered_pairs(s, f);
      ASSERT_TRUE(same_pairs(out.pairs, now)) << d->name() << ", frame " << frame;
      std::vector<Pair> began, ended;
      test::oracle_events(before, now, began, ended);
      EXPECT_TRUE(same_pairs(out.began, began)) << d->name() << ", frame " << frame;
      EXPECT_TRUE(same_pairs(out.ended, ended)) << d->name() << ", frame " << frame;
      if (frame > 0) {
        EXPECT_FALSE(began.empty() && ended.empty()) << "the filters changed the pairs";
      }
      before = now;
    }
  }
}

TEST(FilterDetector, FilterCountMustMatch) {
  const auto s = random_spheres_by_half_extent(10, 1, 3.0f);
  for (auto make : {make_cpu_detector, make_reference_detector}) {
    auto d = make(Config{});
    FrameInput in;
    in.spheres = s;
    const std::vector<Filter> nine(9);
    in.filters = nine;
    FrameResult out;
    const Status st = d->detect(in, out);
    ASSERT_FALSE(st.ok()) << d->name();
    EXPECT_NE(st.error().find("9 filters for 10 spheres"), std::string::npos) << st.error();
  }
}

}  // namespace
}  // namespace viscd
