// The 16-wide tree over the buckets and the SIMD kernels of stage 8, against scalar oracles: the
// tree's searches against a loop over every leaf box, each instruction set's lane tests against
// overlap_exact() and overlaps(), on random, touching, NaN and empty lanes.
#include <gtest/gtest.h>

#include <cstdio>
#include <limits>
#include <random>
#include <vector>

#include "core/geometry.hpp"
#include "cpu/bucket_broadphase.hpp"
#include "cpu/simd.hpp"
#include "cpu/wide_tree.hpp"
#include "test_util.hpp"

namespace viscd {
namespace {

using detail::Aabb;

std::vector<Aabb> random_boxes(std::size_t n, std::uint64_t seed) {
  std::mt19937 rng(static_cast<std::uint32_t>(seed));
  std::uniform_real_distribution<float> pos(-20.0f, 20.0f), size(0.0f, 3.0f);
  std::vector<Aabb> boxes(n);
  for (Aabb& b : boxes) {
    const float x = pos(rng), y = pos(rng), z = pos(rng);
    b = Aabb{{x, y, z}, {x + size(rng), y + size(rng), z + size(rng)}};
  }
  return boxes;
}

// Runs f once per kernel set this CPU can run, with its name.
template <class F>
void for_each_simd(F&& f) {
  f(detail::SimdScalar{}, "scalar");
#if defined(__SSE2__)
  f(detail::SimdSse2{}, "sse2");
#endif
#if VISCD_HAVE_AVX512
  if (detail::best_simd_level() == detail::SimdLevel::avx512)
    f(detail::SimdAvx512{}, "avx512");
  else
    std::printf("note: this CPU has no AVX-512; its kernels are not run\n");
#endif
}

TEST(WideTree, SearchesEqualALoopOverEveryLeaf) {
  // Leaf counts either side of 16^k, where a level is added or a node is one child short.
  for (std::size_t n : {0u, 1u, 2u, 15u, 16u, 17u, 255u, 256u, 257u, 4095u, 4096u, 4097u}) {
    const std::vector<Aabb> boxes = random_boxes(n, n + 3);
    detail::WideTree tree;
    detail::build_wide_tree(boxes, tree, 2);
    ASSERT_EQ(detail::validate_wide_tree(tree, boxes), "") << "n = " << n;
    for_each_simd([&](auto simd, const char* name) {
      using Simd = decltype(simd);
      const std::size_t step = n > 300 ? 37 : 1;  // every leaf of the small trees, a sample of the large
      for (std::size_t p = 0; p < n; p += step) {
        std::vector<std::uint32_t> after, all, want_after, want_all;
        detail::for_each_wide_overlap_after<Simd>(tree, static_cast<std::uint32_t>(p), boxes[p],
                                                  [&](std::uint32_t q) { after.push_back(q); });
        detail::for_each_wide_overlap<Simd>(tree, boxes[p], [&](std::uint32_t q) { all.push_back(q); });
        for (std::uint32_t q = 0; q < n; ++q)
          if (detail::overlaps(boxes[q], boxes[p])) {
            want_all.push_back(q);
            if (q > p) want_after.push_back(q);
          }
        // Both walks visit leaves in increasing order.
        ASSERT_EQ(after, want_after) << name << ", n = " << n << ", p = " << p;
        ASSERT_EQ(all, want_all) << name << ", n = " << n << ", p = " << p;
      }
    });
  }
}

TEST(WideTree, RebuildsInPlaceAsTheLeafCountChanges) {
  detail::WideTree tree;
  for (std::size_t n : {5000u, 17u, 0u, 300u, 70000u, 1u}) {
    const std::vector<Aabb> boxes = random_boxes(n, 100 + n);
    detail::build_wide_tree(boxes, tree, 2);
    ASSERT_EQ(detail::validate_wide_tree(tree, boxes), "") << "n = " << n;
  }
  // The validator sees a wrong box.
  const std::vector<Aabb> boxes = random_boxes(40, 1);
  detail::build_wide_tree(boxes, tree, 1);
  tree.level[1][0].hi_x[2] += 1.0f;
  EXPECT_NE(detail::validate_wide_tree(tree, boxes), "");
}

struct alignas(64) Lanes {
  float x[16], y[16], z[16], r[16], h[16];
};

TEST(SimdKernels, EveryInstructionSetGivesTheScalarBits) {
  std::mt19937 rng(12);
  std::uniform_real_distribution<float> pos(-3.0f, 3.0f), rad(0.0f, 1.5f);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const std::vector<Sphere> boundary = test::float_boundary_pairs(2000, 5);  // at equality or 1 ulp off
  for (int round = 0; round < 2000; ++round) {
    Lanes ln{};
    for (int l = 0; l < 16; ++l) {
      ln.x[l] = pos(rng), ln.y[l] = pos(rng), ln.z[l] = pos(rng), ln.r[l] = rad(rng);
      ln.h[l] = detail::conservative_half_extent(Sphere{ln.x[l], ln.y[l], ln.z[l], ln.r[l]});
    }
    Sphere p{pos(rng), pos(rng), pos(rng), rad(rng)};
    if (round % 3 == 1) {  // a pair at the float boundary in lane 5
      p = boundary[2 * static_cast<std::size_t>(round)];
      const Sphere& q = boundary[2 * static_cast<std::size_t>(round) + 1];
      ln.x[5] = q.x, ln.y[5] = q.y, ln.z[5] = q.z, ln.r[5] = q.r, ln.h[5] = detail::conservative_half_extent(q);
    }
    // Exactly touching lanes (on a grid of exact floats), and padding lanes.
    if (round % 3 == 0) {
      ln.x[3] = p.x + 1.0f, ln.y[3] = p.y, ln.z[3] = p.z, ln.r[3] = 1.0f - p.r;
      ln.x[9] = ln.y[9] = ln.z[9] = ln.h[9] = nan;
      ln.r[9] = 0;
    }
    const Aabb box = detail::conservative_box(p);
    detail::WideTree tree;  // one node over 16 boxes (some empty) for node_children
    std::vector<Aabb> boxes(static_cast<std::size_t>(1 + round % 16));
    for (Aabb& b : boxes) b = detail::conservative_box(Sphere{pos(rng), pos(rng), pos(rng), rad(rng)});
    detail::build_wide_tree(boxes, tree, 1);
    std::uint32_t want_spheres = 0, want_boxes = 0, want_children = 0;
    for (std::uint32_t l = 0; l < 16; ++l) {
      const Sphere q{ln.x[l], ln.y[l], ln.z[l], ln.r[l]};
      want_spheres |= static_cast<std::uint32_t>(detail::overlap_exact(p, q)) << l;
      const Aabb lane{{q.x - ln.h[l], q.y - ln.h[l], q.z - ln.h[l]}, {q.x + ln.h[l], q.y + ln.h[l], q.z + ln.h[l]}};
      want_boxes |= static_cast<std::uint32_t>(detail::overlaps(lane, box)) << l;
      if (l < boxes.size()) want_children |= static_cast<std::uint32_t>(detail::overlaps(boxes[l], box)) << l;
    }
    for_each_simd([&](auto simd, const char* name) {
      using Simd = decltype(simd);
      ASSERT_EQ(Simd::sphere_lanes(ln, p.x, p.y, p.z, p.r), want_spheres) << name << ", round " << round;
      ASSERT_EQ(Simd::box_lanes(ln, box), want_boxes) << name << ", round " << round;
      ASSERT_EQ(Simd::node_children(tree.level[0][0], box), want_children) << name << ", round " << round;
    });
  }
}

TEST(SimdKernels, LevelCanBeLoweredButNotRaised) {
  EXPECT_EQ(detail::usable_simd_level(detail::SimdLevel::scalar), detail::SimdLevel::scalar);
  EXPECT_EQ(detail::usable_simd_level(detail::SimdLevel::avx512), detail::best_simd_level());
  EXPECT_EQ(detail::simd_level_for(Simd::scalar), detail::SimdLevel::scalar);
  EXPECT_EQ(detail::simd_level_for(Simd::sse2), detail::usable_simd_level(detail::SimdLevel::sse2));
  EXPECT_EQ(detail::simd_level_for(Simd::best), detail::best_simd_level());
}

}  // namespace
}  // namespace viscd
