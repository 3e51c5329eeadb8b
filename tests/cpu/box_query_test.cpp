// Queries on frames of boxes: the cpu backend walks its trees (box lanes, the boxes themselves in
// the leaves, no conservative margin around them) for rays and overlaps. Checked here against a
// brute-force loop over the public predicates (ray_hits_box, sphere_overlaps_box, boxes_overlap)
// on scenes where a missed margin would show: touching unit cubes far from the origin, rays that
// run along faces and edges or start on them, query boxes and spheres that only touch. Objects
// left out of the tree by their filters, a static set of boxes and followed frames are covered.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include "cpu/simd.hpp"
#include "cpu/wide_tree.hpp"
#include "test_util.hpp"
#include "viscd/detector.hpp"

namespace viscd {
namespace {

// What brute force sees: every active object with the index a query reports and its filter.
struct Known {
  std::uint32_t index;
  Box box;
  Filter filter;
};

bool hit_order(const RayHit& a, const RayHit& b) { return a.t < b.t || (a.t == b.t && a.index < b.index); }

using test::describe;

bool passes(const Filter* q, const Filter& f) { return q == nullptr || pair_passes_filter(*q, f); }

void check_ray(const Detector& d, const std::vector<Known>& all, const Ray& r, const Filter* filter,
               const std::string& what) {
  std::vector<RayHit> want;
  for (const Known& k : all) {
    float t = 0;
    if (passes(filter, k.filter) && ray_hits_box(r, k.box, t)) want.push_back({k.index, t});
  }
  std::sort(want.begin(), want.end(), hit_order);
  std::vector<RayHit> got;
  d.ray_cast_all(r, got, filter);
  ASSERT_EQ(got, want) << what << ": " << describe(r);
  RayHit first{};
  ASSERT_EQ(d.ray_cast(r, first, filter), !want.empty()) << what << ": " << describe(r);
  if (!want.empty()) {
    ASSERT_EQ(first, want.front()) << what << ": " << describe(r);
  }
}

void check_overlaps(const Detector& d, const std::vector<Known>& all, const Sphere& s, const Box& b,
                    const Filter* filter, const std::string& what) {
  std::vector<std::uint32_t> want_s, want_b, got_s, got_b;
  for (const Known& k : all) {
    if (!passes(filter, k.filter)) continue;
    if (sphere_overlaps_box(s, k.box)) want_s.push_back(k.index);
    if (boxes_overlap(b, k.box)) want_b.push_back(k.index);
  }
  std::sort(want_s.begin(), want_s.end());
  std::sort(want_b.begin(), want_b.end());
  d.overlap(s, got_s, filter);
  d.overlap_box(b, got_b, filter);
  ASSERT_EQ(got_s, want_s) << what << ": sphere (" << s.x << ", " << s.y << ", " << s.z << ", " << s.r << ")";
  ASSERT_EQ(got_b, want_b) << what << ": box at (" << b.min[0] << ", " << b.min[1] << ", " << b.min[2] << ")";
}

Box cube_at(float x, float y, float z, float side) { return Box{{x, y, z}, {x + side, y + side, z + side}}; }

// 20 x 20 x 4 unit cubes that touch their neighbours, with their corner at `o`.
std::vector<Box> touching_cubes(float o) {
  std::vector<Box> b;
  for (int k = 0; k < 4; ++k)
    for (int j = 0; j < 20; ++j)
      for (int i = 0; i < 20; ++i)
        b.push_back(cube_at(o + static_cast<float>(i), o + static_cast<float>(j), o + static_cast<float>(k), 1.0f));
  return b;
}

// Rays and overlaps that run along the faces of the cubes or only touch them.
void check_grazing(const Detector& d, const std::vector<Known>& all, float o, const std::string& what) {
  const auto f = [o](int v) { return o + static_cast<float>(v); };
  const float inf = std::numeric_limits<float>::infinity();
  for (int a = 0; a <= 20; a += 5)
    for (int c = 0; c <= 4; ++c) {
      // Along x on the edge where four cubes meet, from outside and from inside the grid.
      check_ray(d, all, test::make_ray(f(-2), f(a), f(c), 1, 0, 0), nullptr, what + ", edge ray");
      check_ray(d, all, test::make_ray(f(3), f(a), f(c), -1, 0, 0, 2.0f), nullptr, what + ", edge ray back");
      // Along z on a face (x on a grid line, y halfway), and down from above onto a corner.
      check_ray(d, all, test::make_ray(f(a), f(c) + 0.5f, f(9), 0, 0, -1, inf), nullptr, what + ", face ray");
      check_ray(d, all, test::make_ray(f(a), f(c), f(6), 0, 0, -1, 2.0f), nullptr, what + ", ray onto a corner");
      // Diagonal through the corners; a ray that stops exactly at a face (max_t) and one of length 0.
      check_ray(d, all, test::make_ray(f(a) - 1, f(c) - 1, f(-1), 1, 1, 1), nullptr, what + ", diagonal");
      check_ray(d, all, test::make_ray(f(a) + 0.5f, f(c) + 0.5f, f(7), 0, 0, -1, 3.0f), nullptr,
                what + ", ray ending on a face");
      check_ray(d, all, test::make_ray(f(a), f(c), f(2), 0.3f, -0.7f, 0.1f, 0.0f), nullptr, what + ", max_t 0");
      // From the world's origin through a corner (t = 1 there), and on by a little or not at all:
      // the slab test's roundings at the corner are not covered by a margin of the origin's size.
      for (const int z : {0, 4}) {
        check_ray(d, all, test::make_ray(0, 0, 0, f(a), f(c), f(z), 1.0f), nullptr, what + ", ray to a corner");
        check_ray(d, all, test::make_ray(0, 0, 0, f(a), f(c), f(z), 1.5f), nullptr, what + ", ray past a corner");
      }
      // A point box and a zero-radius sphere at a corner; a cube that touches a face.
      const Box point{{f(a), f(c), f(2)}, {f(a), f(c), f(2)}};
      check_overlaps(d, all, Sphere{f(a), f(c), f(4), 0.0f}, point, nullptr, what + ", corner");
      check_overlaps(d, all, Sphere{f(a) + 0.5f, f(c) + 0.5f, f(4) + 0.5f, 0.5f}, cube_at(f(a), f(c), f(4), 1.0f),
                     nullptr, what + ", touching the top face");
    }
}

TEST(BoxQueries, TouchingCubesNearAndFarFromTheOrigin) {
  for (const float o : {0.0f, 1.0e4f, -3.0e5f})
    for (const Simd simd : {Simd::best, Simd::sse2}) {
      const std::vector<Box> boxes = touching_cubes(o);
      std::vector<Known> all;
      for (std::uint32_t k = 0; k < boxes.size(); ++k) all.push_back({k, boxes[k], Filter{}});
      Config config;
      config.simd = simd;
      auto d = make_detector("cpu", config).value();
      FrameInput in;
      in.boxes = boxes;
      FrameResult r;
      ASSERT_TRUE(d->detect(in, r).ok());
      ASSERT_FALSE(r.stats.followed_change);
      check_grazing(*d, all, o, "rebuilt, offset " + std::to_string(o));
      // The same boxes again: a followed frame, whose queries build their tree on demand.
      ASSERT_TRUE(d->detect(in, r).ok());
      ASSERT_TRUE(r.stats.followed_change);
      check_grazing(*d, all, o, "followed, offset " + std::to_string(o));
    }
}

TEST(BoxQueries, FiltersUnpairedObjectsAndAStaticSet) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> pos(-30.0f, 30.0f), side(0.0f, 3.0f);
  auto random_box = [&] {
    const float x = pos(rng), y = pos(rng), z = pos(rng);
    return Box{{x, y, z}, {x + side(rng), y + side(rng), z + side(rng)}};
  };
  std::vector<Box> moving(3000), fixed(2000);
  std::vector<Filter> filters(moving.size()), fixed_filters(fixed.size());
  for (std::size_t k = 0; k < moving.size(); ++k) {
    moving[k] = random_box();
    // Every seventh pairs with nothing (mask 0): left out of the frame's tree, found by queries.
    filters[k] = k % 7 == 0 ? Filter{2, 0} : Filter{1u << (k % 3), 0xFFFFFFFFu};
  }
  for (std::size_t k = 0; k < fixed.size(); ++k) {
    fixed[k] = random_box();
    fixed_filters[k] = Filter{1u << (k % 4), 0xFFFFFFFFu};
  }
  auto d = make_detector("cpu").value();
  ASSERT_TRUE(d->set_static_boxes(fixed, fixed_filters).ok());
  ASSERT_TRUE(d->remove_static(5).ok());  // taken out of the static tree in place
  std::vector<Known> all;
  for (std::uint32_t k = 0; k < moving.size(); ++k) all.push_back({k, moving[k], filters[k]});
  for (std::uint32_t k = 0; k < fixed.size(); ++k)
    if (k != 5) all.push_back({static_index(k), fixed[k], fixed_filters[k]});
  FrameInput in;
  in.boxes = moving;
  in.filters = filters;
  FrameResult r;
  for (int frame = 0; frame < 2; ++frame) {  // rebuilt, then followed
    ASSERT_TRUE(d->detect(in, r).ok());
    ASSERT_EQ(r.stats.followed_change, frame == 1);
    const std::string what = frame == 0 ? "rebuilt" : "followed";
    const Filter only_group_2{1, 2}, group_1{1, 1};
    std::uniform_real_distribution<float> dir(-1.0f, 1.0f), len(0.0f, 80.0f);
    for (int q = 0; q < 60; ++q) {
      const Filter* filter = q % 3 == 0 ? nullptr : q % 3 == 1 ? &only_group_2 : &group_1;
      check_ray(*d, all, test::make_ray(pos(rng), pos(rng), pos(rng), dir(rng), dir(rng), dir(rng), len(rng)), filter,
                what);
      check_overlaps(*d, all, Sphere{pos(rng), pos(rng), pos(rng), side(rng)}, random_box(), filter, what);
    }
  }
}

// The rays' node test with AVX-512 gives what the SSE2 one gives, mask and entry points, on
// children that are boxes, points, empty (+inf, -inf) and NaN, for rays along and across the axes.
TEST(BoxQueries, RayChildrenAvx512MatchesSse2) {
#if VISCD_HAVE_AVX512
  if (detail::best_simd_level() != detail::SimdLevel::avx512) GTEST_SKIP() << "this CPU has no AVX-512F";
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(-20.0f, 20.0f), side(0.0f, 6.0f);
  const float inf = std::numeric_limits<float>::infinity(), nan = std::numeric_limits<float>::quiet_NaN();
  for (int round = 0; round < 2000; ++round) {
    detail::WideNode node;
    for (std::uint32_t l = 0; l < detail::kWide; ++l) {
      const float x = u(rng), y = u(rng), z = u(rng);
      const float s = l % 5 == 0 ? 0.0f : side(rng);
      node.set_child(l, detail::Aabb{{x, y, z}, {x + s, y + s, z + s}});
      if (l == 3) node.set_child(l, detail::Aabb{});  // empty
      if (l == 7 && round % 2) node.lo_y[l] = node.hi_y[l] = nan;
    }
    Ray r = test::make_ray(u(rng), u(rng), u(rng), u(rng), u(rng), u(rng));
    if (round % 4 == 1) r.dir[round % 3] = 0;  // flat along one axis
    if (round % 4 == 2) r.dir[0] = r.dir[1] = 0;
    const detail::RaySetup q(r, round % 3 == 0 ? 1e-3 : 0.0);
    const double t_hi = round % 5 == 0 ? static_cast<double>(inf) : 0.5 + round % 7;
    double t_sse[16], t_avx[16];
    const std::uint32_t m_sse = detail::ray_children(q, node, t_hi, t_sse);
    const std::uint32_t m_avx = detail::ray_children_avx512(q, node, t_hi, t_avx);
    ASSERT_EQ(m_sse, m_avx) << "round " << round;
    for (std::uint32_t l = 0; l < 16; ++l)
      if (m_sse >> l & 1) {
        ASSERT_EQ(t_sse[l], t_avx[l]) << "round " << round << ", lane " << l;
      }
  }
#else
  GTEST_SKIP() << "built without AVX-512 kernels";
#endif
}

}  // namespace
}  // namespace viscd
