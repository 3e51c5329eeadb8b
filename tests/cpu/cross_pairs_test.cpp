// The pairs of one bucket tree's objects with another's (cpu/cross_pairs.hpp), by each of its
// walks (per group of buckets, per bucket, per object) and each instruction set this CPU has,
// against every pair of the two sets by the exact tests. Degenerate sets: one or two objects,
// counts around the bucket and group sizes, all centres equal, touching spheres, one huge object
// (every group and bucket walk gives up), tiny radii, and objects taken out of the other tree.
// With only some of the moving objects searching (the lanes cross_pairs() is given), the pairs of
// those alone.

#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "core/geometry.hpp"
#include "cpu/bucket_broadphase.hpp"
#include "cpu/cross_pairs.hpp"
#include "cpu/simd.hpp"

namespace viscd {
namespace {

using detail::BucketBroadphase;
using detail::CrossWalk;
using detail::SimdLevel;

struct Sets {
  std::vector<Sphere> a, b;           // a: the moving tree's objects, b: the other tree's
  std::vector<std::uint32_t> erased;  // objects of b taken out of its tree
  std::vector<std::uint8_t> search;   // per object of a, whether it searches; empty: all of them
};

// A tree over `s` (or over the boxes of `s` as box lanes).
void build(BucketBroadphase& t, const std::vector<Sphere>& s, std::vector<Box>& boxes, std::vector<Sphere>& proxies,
           bool as_boxes) {
  std::vector<std::uint32_t> ids(s.size());
  for (std::uint32_t k = 0; k < ids.size(); ++k) ids[k] = k;
  FrameStats stats;
  if (!as_boxes) {
    t.build(s, ids, 32, Layout::extended, 2, stats);
    return;
  }
  boxes.clear();
  proxies.clear();
  for (const Sphere& o : s) {
    boxes.push_back(Box{{o.x - o.r, o.y - o.r, o.z - o.r}, {o.x + o.r, o.y + o.r, o.z + o.r}});
    proxies.push_back(detail::box_proxy(boxes.back()));
  }
  BucketBroadphase::Extras extras;
  extras.boxes = boxes;
  t.build(proxies, ids, 32, Layout::extended, 2, stats, extras);
}

// Every pair (i in a, j in b, j not erased) by the exact test the trees use.
std::vector<std::pair<std::uint32_t, std::uint32_t>> every_pair(const Sets& s, bool as_boxes) {
  std::vector<std::uint8_t> gone(s.b.size(), 0);
  for (const std::uint32_t k : s.erased) gone[k] = 1;
  auto box_of = [](const Sphere& o) {
    return Box{{o.x - o.r, o.y - o.r, o.z - o.r}, {o.x + o.r, o.y + o.r, o.z + o.r}};
  };
  std::vector<std::pair<std::uint32_t, std::uint32_t>> out;
  for (std::uint32_t i = 0; i < s.a.size(); ++i)
    for (std::uint32_t j = 0; j < s.b.size(); ++j) {
      if (!s.search.empty() && s.search[i] == 0) continue;
      if (gone[j]) continue;
      const bool hit = as_boxes ? boxes_overlap(box_of(s.a[i]), box_of(s.b[j])) : spheres_overlap(s.a[i], s.b[j]);
      if (hit) out.emplace_back(i, j);
    }
  return out;
}

void check(const Sets& sets, const std::string& what) {
  for (const bool as_boxes : {false, true}) {
    BucketBroadphase ta, tb;
    std::vector<Box> boxes_a, boxes_b;
    std::vector<Sphere> prox_a, prox_b;
    build(ta, sets.a, boxes_a, prox_a, as_boxes);
    build(tb, sets.b, boxes_b, prox_b, as_boxes);
    tb.index_positions();
    for (const std::uint32_t k : sets.erased) tb.erase(k);
    const auto expected = every_pair(sets, as_boxes);
    // The searching lanes per bucket of ta, from its sorted order.
    std::vector<std::uint16_t> lanes;
    if (!sets.search.empty()) {
      lanes.assign(detail::buckets_for(sets.a.size()), 0);
      for (std::size_t p = 0; p < ta.sorted_objects().size(); ++p)
        if (sets.search[ta.sorted_objects()[p]] != 0)
          lanes[p / detail::kBucket] |= static_cast<std::uint16_t>(1u << (p % detail::kBucket));
    }
    const std::uint16_t* const search = sets.search.empty() ? nullptr : lanes.data();
    const std::size_t groups = (detail::buckets_for(sets.a.size()) + detail::kWide - 1) / detail::kWide;
    for (const SimdLevel level : {SimdLevel::scalar, SimdLevel::sse2, SimdLevel::avx512}) {
      if (detail::usable_simd_level(level) != level) continue;  // not on this CPU
      for (int w = 0; w < 4; ++w) {
        const CrossWalk walk{(w & 1) != 0, (w & 2) != 0};
        SCOPED_TRACE(what + (as_boxes ? ", boxes" : ", spheres") + ", " + detail::simd_name(level) + ", group walk " +
                     std::to_string(walk.group) + ", bucket walk " + std::to_string(walk.bucket));
        std::vector<std::pair<std::uint32_t, std::uint32_t>> got;
        auto emit = [&](std::size_t p, std::size_t q) {
          got.emplace_back(ta.sorted_objects()[p], tb.sorted_objects()[q]);
        };
        std::size_t fetched = 0;
        auto fetch = [&](std::size_t q) { fetched += q < tb.sorted_objects().size() ? 1 : 1000000; };
        for (std::size_t g = 0; g < groups; ++g)
          if (as_boxes)
            detail::cross_pairs_at<detail::BoxTests>(level, ta, tb, g, walk, search, emit, fetch);
          else
            detail::cross_pairs_at<detail::SphereTests>(level, ta, tb, g, walk, search, emit, fetch);
        EXPECT_LT(fetched, 1000000u) << "fetch() of a position past the tree";
        std::sort(got.begin(), got.end());
        ASSERT_EQ(std::adjacent_find(got.begin(), got.end()), got.end()) << "a pair reported twice";
        EXPECT_EQ(got, expected);
      }
    }
  }
}

std::vector<Sphere> random_spheres(std::size_t n, float extent, float r_lo, float r_hi, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> pos(-extent, extent), rad(r_lo, r_hi);
  std::vector<Sphere> s(n);
  for (Sphere& o : s) o = Sphere{pos(rng), pos(rng), pos(rng) * 0.1f, rad(rng)};
  return s;
}

TEST(CrossPairs, EveryWalkFindsEveryPair) {
  // Moving sets from as dense as the other to a hundredth of it, so that group walks succeed and
  // give up, and bucket walks meet few buckets and many.
  for (const std::size_t na : {1u, 2u, 15u, 16u, 17u, 255u, 256u, 257u, 600u, 3000u}) {
    Sets s;
    s.a = random_spheres(na, 40, 0.2f, 1.5f, na);
    s.b = random_spheres(3000, 40, 0.2f, 1.5f, na + 100);
    check(s, "moving " + std::to_string(na));
  }
}

TEST(CrossPairs, OnlySearchingLanesFindPairs) {
  // From one searching object in 50 (buckets with one or two: each walks alone) to half of them
  // (buckets walk as one), and none.
  for (const std::size_t na : {17u, 600u, 3000u})
    for (const int one_in : {50, 8, 3, 2, 1000000}) {
      Sets s;
      s.a = random_spheres(na, 40, 0.2f, 1.5f, na + 7);
      s.b = random_spheres(3000, 40, 0.2f, 1.5f, na + 200);
      std::mt19937_64 rng(static_cast<std::uint64_t>(na * 31 + static_cast<std::size_t>(one_in)));
      s.search.resize(na);
      for (std::uint8_t& f : s.search) f = (rng() % static_cast<std::uint64_t>(one_in)) == 0 ? 1 : 0;
      if (one_in == 1000000) std::fill(s.search.begin(), s.search.end(), std::uint8_t{0});
      check(s, "moving " + std::to_string(na) + ", one in " + std::to_string(one_in) + " searching");
    }
}

TEST(CrossPairs, DegenerateSets) {
  {
    Sets s;  // every centre the same: every pair meets
    s.a.assign(40, Sphere{1, 2, 3, 0.5f});
    s.b.assign(300, Sphere{1, 2, 3, 0.25f});
    check(s, "equal centres");
  }
  {
    Sets s;  // touching spheres on a line: distance exactly the sum of the radii
    for (int k = 0; k < 64; ++k) s.a.push_back(Sphere{static_cast<float>(2 * k), 0, 0, 0.5f});
    for (int k = 0; k < 64; ++k) s.b.push_back(Sphere{static_cast<float>(2 * k + 1), 0, 0, 0.5f});
    check(s, "touching");
  }
  {
    Sets s;  // one huge moving object among small ones: every group and bucket walk gives up
    s.a = random_spheres(100, 40, 0.1f, 0.3f, 5);
    s.a[37] = Sphere{0, 0, 0, 30};
    s.b = random_spheres(2000, 40, 0.1f, 0.3f, 6);
    check(s, "huge");
  }
  {
    Sets s;  // tiny radii, close together
    s.a = random_spheres(500, 0.01f, 1e-6f, 1e-4f, 7);
    s.b = random_spheres(500, 0.01f, 1e-6f, 1e-4f, 8);
    check(s, "tiny");
  }
  {
    Sets s;  // a third of the other tree taken out
    s.a = random_spheres(400, 20, 0.2f, 1.5f, 9);
    s.b = random_spheres(2000, 20, 0.2f, 1.5f, 10);
    for (std::uint32_t k = 0; k < 2000; k += 3) s.erased.push_back(k);
    check(s, "erased");
  }
}

TEST(CrossPairs, WalkChoiceFollowsTheCounts) {
  EXPECT_TRUE(detail::cross_walk_for(100, 100).group);
  EXPECT_TRUE(detail::cross_walk_for(100, 400).group);
  EXPECT_FALSE(detail::cross_walk_for(100, 401).group);
  EXPECT_TRUE(detail::cross_walk_for(100, 2500).bucket);
  EXPECT_FALSE(detail::cross_walk_for(100, 2501).bucket);
}

}  // namespace
}  // namespace viscd
