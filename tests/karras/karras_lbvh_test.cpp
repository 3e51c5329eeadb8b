#include <gtest/gtest.h>

#include <algorithm>
#include <random>

#include "karras/karras_lbvh.hpp"

namespace viscd::detail {
namespace {

template <class K>
void build_and_check(std::vector<K> keys, int threads, int* depth_out = nullptr) {
  std::sort(keys.begin(), keys.end());
  Lbvh bvh;
  build_lbvh<K>(keys, bvh, threads);
  std::vector<Aabb> boxes(keys.size());
  std::mt19937 rng(static_cast<unsigned>(keys.size()));
  std::uniform_real_distribution<float> u(-50, 50);
  for (auto& b : boxes) {
    const float x = u(rng), y = u(rng), z = u(rng);
    b = Aabb{{x, y, z}, {x + 1, y + 2, z + 3}};
  }
  fit_lbvh(boxes, bvh, threads);
  ASSERT_EQ(validate_lbvh(bvh, boxes), "") << "n=" << keys.size();
  const int depth = lbvh_depth(bvh);
  EXPECT_LE(depth, 8 * static_cast<int>(sizeof(K)) + 32);
  if (depth_out) *depth_out = depth;

  // Traversal: for each leaf p, the leaves q > p it reports are exactly the overlapping boxes.
  const std::size_t n = keys.size();
  const std::size_t step = std::max<std::size_t>(1, n / 200);
  for (std::size_t p = 0; p < n; p += step) {
    std::vector<std::uint32_t> got, want;
    for_each_overlap_after(bvh, static_cast<std::uint32_t>(p), boxes[p], [&](std::uint32_t q) { got.push_back(q); });
    for (std::size_t q = p + 1; q < n; ++q)
      if (overlaps(boxes[p], boxes[q])) want.push_back(static_cast<std::uint32_t>(q));
    std::sort(got.begin(), got.end());
    ASSERT_EQ(got, want) << "leaf " << p << " of " << n;
  }
}

TEST(Lbvh, RandomKeysAllWidths) {
  for (std::size_t n : {0, 1, 2, 3, 7, 64, 255, 256, 257, 1000, 5000}) {
    std::mt19937_64 rng(n);
    std::vector<std::uint16_t> k16(n);
    std::vector<std::uint32_t> k32(n);
    std::vector<std::uint64_t> k64(n);
    for (std::size_t i = 0; i < n; ++i) {
      k64[i] = rng();
      k32[i] = static_cast<std::uint32_t>(k64[i]);
      k16[i] = static_cast<std::uint16_t>(k64[i]);
    }
    for (int threads : {1, 2}) {
      build_and_check(k16, threads);
      build_and_check(k32, threads);
      build_and_check(k64, threads);
    }
  }
}

TEST(Lbvh, AllKeysEqualSplitsByIndex) {
  // Every key equal: the tree is built on the index bits alone, depth ~ log2(n).
  int depth = 0;
  build_and_check(std::vector<std::uint16_t>(10000, 0x1234), 2, &depth);
  EXPECT_LE(depth, 16 + 32);
  EXPECT_GE(depth, 14);  // ceil(log2 10000)
  build_and_check(std::vector<std::uint64_t>(4097, ~0ull), 2);
}

TEST(Lbvh, FewDistinctKeysManyDuplicates) {
  std::vector<std::uint32_t> keys;
  for (int k = 0; k < 3000; ++k) keys.push_back(static_cast<std::uint32_t>(k % 5) << 28);
  build_and_check(keys, 2);
}

TEST(Lbvh, ValidateDetectsCorruption) {
  std::vector<std::uint32_t> keys = {1, 2, 3, 4, 5, 6, 7, 8};
  Lbvh bvh;
  build_lbvh<std::uint32_t>(keys, bvh, 1);
  std::vector<Aabb> boxes(8, Aabb{{0, 0, 0}, {1, 1, 1}});
  boxes[5] = Aabb{{4, 4, 4}, {5, 5, 5}};
  fit_lbvh(boxes, bvh, 1);
  ASSERT_EQ(validate_lbvh(bvh, boxes), "");
  Lbvh broken = bvh;
  broken.nodes[0].box[1].hi.x = 0.5f;  // no longer contains its subtree
  EXPECT_NE(validate_lbvh(broken, boxes), "");
  broken = bvh;
  std::swap(broken.nodes[0].child[0], broken.nodes[0].child[1]);  // links and ranges disagree
  EXPECT_NE(validate_lbvh(broken, boxes), "");
  broken = bvh;
  broken.leaf_parent[3] = 6;
  EXPECT_NE(validate_lbvh(broken, boxes), "");
}

}  // namespace
}  // namespace viscd::detail

namespace viscd::detail {
namespace {

TEST(Lbvh, TraversalDeeperThanItsStackDropsNothing) {
  // A hand-built tree (not a Karras tree) deeper than the traversal stack: chain nodes
  // C_0..C_{k-1} descend through child[0] and each has a pair node P_i (two leaves) as child[1],
  // which the traversal must push. With k = 200 > kStackDepth the overflow path runs; every
  // box overlaps, so the search from the root must report every leaf.
  const std::uint32_t k = 200, n = 2 * (k + 1);
  Lbvh bvh;
  bvh.leaves = n;
  bvh.nodes.resize(n - 1);
  const Aabb unit{{0, 0, 0}, {1, 1, 1}};
  for (std::uint32_t j = 0; j <= k; ++j) {  // pair nodes k..2k hold leaves 2j, 2j + 1
    BvhNode& pn = bvh.nodes[k + j];
    pn.box[0] = pn.box[1] = unit;
    pn.child[0] = (2 * j) | kLeafBit, pn.child[1] = (2 * j + 1) | kLeafBit;
    pn.last[0] = 2 * j, pn.last[1] = 2 * j + 1;
  }
  for (std::uint32_t i = 0; i < k; ++i) {
    BvhNode& cn = bvh.nodes[i];
    cn.box[0] = cn.box[1] = unit;
    cn.child[0] = i + 1 < k ? i + 1 : 2 * k;  // deeper chain, or the last pair node
    cn.last[0] = n - 1;
    cn.child[1] = k + i;
    cn.last[1] = 2 * i + 1;
  }
  std::vector<std::uint32_t> got;
  for_each_overlap_in_subtree(bvh, 0, unit, [&](std::uint32_t q) { got.push_back(q); });
  std::sort(got.begin(), got.end());
  ASSERT_EQ(got.size(), n);
  for (std::uint32_t q = 0; q < n; ++q) EXPECT_EQ(got[q], q);
}

}  // namespace
}  // namespace viscd::detail
