// The cpu backend's bucketed broadphase against brute force, over single frames and over moving
// sequences that exercise the sort from the last frame's order: small motion for many frames,
// teleports, N growing and shrinking, active sets changing, all objects identical, the Morton
// width changing. Also the pair sort and the order the sort produces.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>

#include "cpu/brute_force.hpp"
#include "cpu/bucket_broadphase.hpp"
#include "cpu/simd.hpp"
#include "test_util.hpp"

namespace viscd {
namespace {

using test::all_of;
using test::oracle_pairs;
using test::random_spheres_by_half_extent;
using test::same_pairs;

// One frame through `bp` against brute force, the tree's invariants and the sort's contract:
// codes ascending, ties by object id, each active object once.
void check_frame(detail::BucketBroadphase& bp, const std::vector<Sphere>& s, const std::vector<std::uint32_t>& active,
                 int bits, const std::string& what, int threads = 2) {
  std::vector<Pair> pairs;
  FrameStats stats;
  const Status st = bp.run(s, active, bits, Layout::extended, threads, 0, pairs, stats);
  ASSERT_TRUE(st.ok()) << what << ": " << st.error();
  ASSERT_TRUE(same_pairs(pairs, oracle_pairs(s, &active))) << what;
  ASSERT_EQ(detail::validate_wide_tree(bp.tree(), bp.leaf_boxes()), "") << what;
  // Every bucket box holds its objects' conservative boxes.
  const auto ids = bp.sorted_objects();
  ASSERT_EQ(ids.size(), active.size()) << what;
  for (std::size_t p = 0; p < ids.size(); ++p)
    ASSERT_TRUE(bp.leaf_boxes()[p / detail::kBucket].contains(detail::conservative_box(s[ids[p]]))) << what;
  const std::vector<std::uint64_t> codes = bp.sorted_codes();
  for (std::size_t p = 1; p < ids.size(); ++p)
    ASSERT_TRUE(codes[p - 1] < codes[p] || (codes[p - 1] == codes[p] && ids[p - 1] < ids[p]))
        << what << ": sorted order broken at " << p;
  std::vector<std::uint32_t> sorted_ids(ids.begin(), ids.end());
  std::sort(sorted_ids.begin(), sorted_ids.end());
  ASSERT_EQ(sorted_ids, active) << what << ": not a permutation of the active set";
}

// Runs f(name, level) for each instruction set this CPU has (cpu/simd.hpp).
template <class F>
void for_each_simd_level(F&& f) {
  for (detail::SimdLevel l : {detail::SimdLevel::scalar, detail::SimdLevel::sse2, detail::SimdLevel::avx512})
    if (detail::usable_simd_level(l) == l) f(std::string(detail::simd_name(l)), l);  // else not on this CPU
}

TEST(BucketBroadphase, CountsAroundBucketMultiples) {
  for_each_simd_level([](const std::string& simd, detail::SimdLevel level) {
    // 16^2 and 16^3 buckets are where the tree over the buckets gains a level.
    for (std::size_t n :
         {0u, 1u, 2u, 3u, 15u, 16u, 17u, 31u, 32u, 33u, 47u, 48u, 49u, 255u, 256u, 257u, 4095u, 4096u, 4097u, 65537u}) {
      const auto s = random_spheres_by_half_extent(n, n + 1, 2.0f + 0.1f * std::cbrt(static_cast<float>(n)) * 4.0f);
      for (int bits : {16, 32, 64}) {
        // 65537 objects, 4097 buckets, once: the brute-force oracle is O(n^2).
        if (n > 5000 && (bits != 32 || simd != detail::simd_name(detail::best_simd_level()))) continue;
        detail::BucketBroadphase bp;
        bp.set_simd(level);
        check_frame(bp, s, all_of(n), bits, simd + ", n = " + std::to_string(n) + ", m = " + std::to_string(bits));
      }
    }
  });
}

TEST(BucketBroadphase, DenseAndDegenerateSets) {
  for_each_simd_level([](const std::string& simd, detail::SimdLevel level) {
    SCOPED_TRACE(simd);
    detail::BucketBroadphase bp;
    bp.set_simd(level);
    // Everything overlaps everything: one bucket's all-pairs path and the cross path at once.
    check_frame(bp, std::vector<Sphere>(70, Sphere{1, 2, 3, 0.5f}), all_of(70), 32, "identical");
    check_frame(bp, std::vector<Sphere>(70, Sphere{1, 2, 3, 0}), all_of(70), 16, "identical points");
    // Touching on a line, one radius that covers all, tiny radii.
    std::vector<Sphere> line;
    for (int k = 0; k < 100; ++k) line.push_back({static_cast<float>(k), 0, 0, 0.5f});
    check_frame(bp, line, all_of(line.size()), 32, "touching line");
    auto huge = random_spheres_by_half_extent(300, 9, 50.0f, 0.01f, 0.2f);
    huge[137].r = 1e4f;
    check_frame(bp, huge, all_of(huge.size()), 64, "one huge among tiny");
    check_frame(bp, test::float_boundary_pairs(200, 4), all_of(400), 32, "pairs at the float boundary");
    // A huge sphere in the first group: more later buckets meet that group's box than its
    // candidate list holds (512), so its buckets walk the tree one by one.
    auto many = random_spheres_by_half_extent(12000, 10, 60.0f, 0.01f, 0.3f);
    many[5] = Sphere{-60, -60, -60, 150};
    check_frame(bp, many, all_of(many.size()), 32, "a huge sphere among 12000");
  });
}

TEST(BucketBroadphase, SubsetsOfActiveObjects) {
  const auto s = random_spheres_by_half_extent(2000, 11, 12.0f);
  std::mt19937 rng(3);
  detail::BucketBroadphase bp;
  for (int frame = 0; frame < 12; ++frame) {
    std::vector<std::uint32_t> active;
    const unsigned keep = 1 + rng() % 4;  // 1/keep of the objects, a different subset each frame
    for (std::uint32_t k = 0; k < s.size(); ++k)
      if (rng() % keep == 0) active.push_back(k);
    check_frame(bp, s, active, 32, "subset frame " + std::to_string(frame));
  }
}

// A moving sequence: objects drift a little every frame, so the sort starts from the last order
// (keeping the order is off: every frame sorts; KeepingTheOrder tests the frames that do not).
TEST(BucketBroadphase, MovingSequencesStayExact) {
  auto s = random_spheres_by_half_extent(3000, 5, 14.0f, 0.2f, 0.6f);
  std::mt19937 rng(8);
  std::uniform_real_distribution<float> step(-0.001f, 0.001f), far(-14.0f, 14.0f);
  detail::BucketBroadphase bp;
  bp.set_keep_order(false);
  int reused = 0;
  for (int frame = 0; frame < 40; ++frame) {
    for (Sphere& x : s) x.x += step(rng), x.y += step(rng), x.z += step(rng);
    check_frame(bp, s, all_of(s.size()), 32, "small motion, frame " + std::to_string(frame), 1 + frame % 2);
    reused += bp.sort_report().reused;
  }
  // Frames after the first start from the last order (which is what this test is about); a frame
  // whose shifts exceed the budget sorts from scratch, also exactly.
  EXPECT_GE(reused, 35);

  // Teleports: a few objects jump anywhere; then every object does.
  for (int k = 0; k < 30; ++k) s[rng() % s.size()] = Sphere{far(rng), far(rng), far(rng), 0.4f};
  check_frame(bp, s, all_of(s.size()), 32, "a few teleports");
  // The teleported objects land far from their last place: set aside and merged in.
  EXPECT_TRUE(bp.sort_report().reused);
  EXPECT_GT(bp.sort_report().far, 0u);
  for (Sphere& x : s) x = Sphere{far(rng), far(rng), far(rng), x.r};
  check_frame(bp, s, all_of(s.size()), 32, "everything teleports");
  EXPECT_FALSE(bp.sort_report().reused) << "a shuffled frame should exceed the insertion sort's budget";

  // N grows and shrinks between frames; indices keep their meaning for the objects that stay.
  for (std::size_t n : {3100u, 4000u, 2500u, 10u, 0u, 1u, 3000u}) {
    auto grown = s;
    grown.resize(n, Sphere{0, 0, 0, 0.3f});
    for (std::size_t k = s.size(); k < n; ++k) grown[k] = Sphere{far(rng), far(rng), far(rng), 0.3f};
    check_frame(bp, grown, all_of(n), 32, "N = " + std::to_string(n));
  }

  // All objects identical for a few frames, then apart again.
  std::vector<Sphere> same(500, Sphere{2, 2, 2, 0.1f});
  for (int frame = 0; frame < 3; ++frame) check_frame(bp, same, all_of(same.size()), 32, "identical, moving");
  check_frame(bp, s, all_of(s.size()), 32, "apart again");

  // The Morton width changes: the last order is dropped, the result stays exact.
  for (int bits : {16, 64, 32, 16}) check_frame(bp, s, all_of(s.size()), bits, "m = " + std::to_string(bits));

  // Small motion and a few teleports at 16 and 64 bits (64-bit codes do not pack with the id).
  for (int bits : {16, 64}) {
    for (int frame = 0; frame < 4; ++frame) {
      for (Sphere& x : s) x.x += step(rng), x.y += step(rng), x.z += step(rng);
      if (frame == 2) {
        for (int k = 0; k < 30; ++k) s[rng() % s.size()] = Sphere{far(rng), far(rng), far(rng), 0.4f};
      }
      check_frame(bp, s, all_of(s.size()), bits, "m = " + std::to_string(bits) + ", frame " + std::to_string(frame));
      if (frame > 0) {
        EXPECT_TRUE(bp.sort_report().reused) << "m = " << bits << ", frame " << frame;
      }
    }
  }
}

// The sort from the last order cut into runs (one per thread, here up to 8 on any machine):
// small motion, then teleports (entries set aside and merged across runs), then a shuffle. Two
// spheres that never move fix the extent, so the Morton grid stays put and only what moves moves
// in the order (a changing extent shifts every code).
TEST(BucketBroadphase, SortRunsMergeExactly) {
  for (int threads : {1, 2, 3, 8}) {
    auto s = random_spheres_by_half_extent(6000, 40 + static_cast<std::uint64_t>(threads), 17.0f, 0.2f, 0.6f);
    s[0] = Sphere{-18, -18, -18, 0.3f};
    s[1] = Sphere{18, 18, 18, 0.3f};
    std::mt19937 rng(static_cast<unsigned>(threads));
    std::uniform_real_distribution<float> step(-0.0005f, 0.0005f), far(-17.0f, 17.0f);
    detail::BucketBroadphase bp;
    bp.set_keep_order(false);
    const std::string t = std::to_string(threads) + " threads, ";
    for (int frame = 0; frame < 6; ++frame) {
      for (std::size_t k = 2; k < s.size(); ++k) s[k].x += step(rng), s[k].y += step(rng), s[k].z += step(rng);
      if (frame == 3) {
        for (int k = 0; k < 200; ++k) s[2 + rng() % (s.size() - 2)] = Sphere{far(rng), far(rng), far(rng), 0.4f};
      }
      check_frame(bp, s, all_of(s.size()), 32, t + "frame " + std::to_string(frame), threads);
      if (frame > 0) {
        EXPECT_TRUE(bp.sort_report().reused) << t << "frame " << frame;
      }
      if (frame == 3) {
        EXPECT_GT(bp.sort_report().far, 0u) << t << "teleports should be set aside";
      }
    }
    for (std::size_t k = 2; k < s.size(); ++k) s[k] = Sphere{far(rng), far(rng), far(rng), s[k].r};
    check_frame(bp, s, all_of(s.size()), 32, t + "shuffled", threads);
    EXPECT_FALSE(bp.sort_report().reused) << t << "a shuffled frame should give up";
  }
}

TEST(BucketBroadphase, SortFromScratchGivesTheSameResult) {
  // The same frame through a broadphase that has seen the last frame and one that has not.
  auto s = random_spheres_by_half_extent(5000, 21, 20.0f);
  detail::BucketBroadphase warm, cold;
  warm.set_keep_order(false);
  std::vector<Pair> pw, pc;
  FrameStats fs;
  for (int frame = 0; frame < 5; ++frame) {
    for (Sphere& x : s) x.x += 0.01f;
    cold.reset_order();
    ASSERT_TRUE(warm.run(s, all_of(s.size()), 32, Layout::extended, 2, 0, pw, fs).ok());
    ASSERT_TRUE(cold.run(s, all_of(s.size()), 32, Layout::extended, 2, 0, pc, fs).ok());
    EXPECT_FALSE(cold.sort_report().reused);
    EXPECT_EQ(pw, pc);
    EXPECT_TRUE(std::equal(warm.sorted_objects().begin(), warm.sorted_objects().end(), cold.sorted_objects().begin(),
                           cold.sorted_objects().end()));
    EXPECT_EQ(warm.sorted_codes(), cold.sorted_codes());
  }
}

// Frames that keep the last order (no codes, no sort: the buckets refilled in the last order) give
// the exact pairs, and the order is dropped when it must be: objects moved far (the same frame),
// the bucket-pair count grew (the next frame), the active set, N, the width or the layout changed.
TEST(BucketBroadphase, KeepingTheOrder) {
  auto s = random_spheres_by_half_extent(3000, 15, 14.0f, 0.2f, 0.6f);
  std::mt19937 rng(9);
  std::uniform_real_distribution<float> step(-0.001f, 0.001f), far(-14.0f, 14.0f), speed(-0.02f, 0.02f);
  detail::BucketBroadphase bp;
  auto frame = [&](const std::vector<std::uint32_t>& active, int bits, const std::string& what,
                   Layout layout = Layout::extended, std::span<const Filter> filters = {}) {
    std::vector<Pair> pairs;
    FrameStats stats;
    const Status st = bp.run(s, active, filters, bits, layout, 2, 0, pairs, stats);
    EXPECT_TRUE(st.ok()) << what << ": " << st.error();
    const auto want = filters.empty() ? oracle_pairs(s, &active) : test::oracle_filtered_pairs(s, filters, &active);
    EXPECT_TRUE(same_pairs(pairs, want)) << what;
    EXPECT_EQ(detail::validate_wide_tree(bp.tree(), bp.leaf_boxes()), "") << what;
    const auto ids = bp.sorted_objects();
    for (std::size_t p = 0; p < ids.size(); ++p)
      EXPECT_TRUE(bp.leaf_boxes()[p / detail::kBucket].contains(detail::conservative_box(s[ids[p]]))) << what;
    EXPECT_EQ(stats.order_kept, bp.sort_report().kept) << what;
    return bp.sort_report().kept;
  };
  const auto all = all_of(s.size());

  // Small motion: every frame after the first keeps the order.
  EXPECT_FALSE(frame(all, 32, "first frame"));
  for (int f = 0; f < 20; ++f) {
    for (Sphere& x : s) x.x += step(rng), x.y += step(rng), x.z += step(rng);
    EXPECT_TRUE(frame(all, 32, "small motion " + std::to_string(f))) << f;
  }

  // Steady drift, each object its own way: the buckets spread until a frame sorts again.
  std::vector<detail::Vec3> v(s.size());
  for (detail::Vec3& x : v) x = {speed(rng), speed(rng), speed(rng)};
  int kept = 0, sorted = 0;
  for (int f = 0; f < 60; ++f) {
    for (std::size_t k = 0; k < s.size(); ++k) s[k].x += v[k].x, s[k].y += v[k].y, s[k].z += v[k].z;
    (frame(all, 32, "drift " + std::to_string(f)) ? kept : sorted) += 1;
  }
  EXPECT_GT(kept, 0);
  EXPECT_GT(sorted, 0) << "drifting buckets should make some frame sort";

  // A few teleports: the frame keeps the order with a few buckets stretched across the world (their
  // summed size stays within bounds), but their bucket pairs make the next frame sort.
  EXPECT_TRUE(frame(all, 32, "settle") || frame(all, 32, "settle again"));
  for (int k = 0; k < 10; ++k) s[rng() % s.size()] = Sphere{far(rng), far(rng), far(rng), 0.4f};
  EXPECT_TRUE(frame(all, 32, "a few teleports"));
  EXPECT_FALSE(frame(all, 32, "after the teleports")) << "the stretched buckets should make this frame sort";
  // Everything teleports: the boxes' size jumps, and the same frame sorts.
  EXPECT_TRUE(frame(all, 32, "settled"));
  for (Sphere& x : s) x = Sphere{far(rng), far(rng), far(rng), x.r};
  EXPECT_FALSE(frame(all, 32, "everything teleports"));

  // Filters may change while the order is kept: the pair filter follows them.
  EXPECT_TRUE(frame(all, 32, "no filters"));
  const auto filters = test::random_filters(s.size(), 4);
  EXPECT_TRUE(frame(all, 32, "filters", Layout::extended, filters));
  const auto other = test::random_filters(s.size(), 5);
  EXPECT_TRUE(frame(all, 32, "other filters", Layout::extended, other));

  // What drops the order.
  std::vector<std::uint32_t> half;
  for (std::uint32_t k = 0; k < s.size(); k += 2) half.push_back(k);
  EXPECT_FALSE(frame(half, 32, "half active"));
  EXPECT_TRUE(frame(half, 32, "the same half"));
  half.back() += 1;  // as many, not the same
  EXPECT_FALSE(frame(half, 32, "another half"));
  EXPECT_FALSE(frame(all, 32, "all again"));
  EXPECT_FALSE(frame(all, 64, "m = 64"));
  EXPECT_TRUE(frame(all, 64, "m = 64 again"));
  EXPECT_FALSE(frame(all, 64, "plain layout", Layout::plain));
  EXPECT_TRUE(frame(all, 64, "plain layout again", Layout::plain));
  s.push_back(Sphere{0, 0, 0, 0.3f});
  EXPECT_FALSE(frame(all_of(s.size()), 64, "N + 1", Layout::plain));
  bp.reset_order();
  EXPECT_FALSE(frame(all_of(s.size()), 64, "after reset_order", Layout::plain));
  bp.set_keep_order(false);
  EXPECT_FALSE(frame(all_of(s.size()), 64, "keeping switched off", Layout::plain));
  EXPECT_FALSE(frame(all_of(s.size()), 64, "keeping switched off, again", Layout::plain));
}

TEST(BucketBroadphase, PairCapIsEnforcedWhileSearching) {
  const std::vector<Sphere> s(3000, Sphere{0, 0, 0, 1});  // 4.5 M pairs
  detail::BucketBroadphase bp;
  std::vector<Pair> pairs;
  FrameStats fs;
  const Status st = bp.run(s, all_of(s.size()), 32, Layout::extended, 2, 64 * 1024, pairs, fs);
  ASSERT_FALSE(st.ok());
  EXPECT_NE(st.error().find("pair memory cap"), std::string::npos) << st.error();
  EXPECT_LT(bp.memory_bytes(), std::uint64_t{4} << 20) << "the cap must stop the search before memory is taken";
}

TEST(SortChunkPairs, EqualsAFullSort) {
  std::mt19937 rng(2);
  // Object counts around the 1024-id blocks; pair counts around the parallel threshold; one object
  // with many partners (a block much fuller than the others).
  for (std::uint32_t objects : {1u, 2u, 50u, 1000u, 1023u, 1024u, 1025u, 5000u, 70000u}) {
    std::vector<std::vector<std::uint64_t>> lists(5);
    std::vector<Pair> want;
    const int count = objects > 2000 ? 9000 : 3000;
    for (int k = 0; k < count && objects > 1; ++k) {
      if (k % 7 == 0 && objects > 1025) {  // object 1024 pairs with many
        const auto j = 1025 + static_cast<std::uint32_t>(rng() % (objects - 1025));
        lists[rng() % lists.size()].push_back(std::uint64_t{1024} << 32 | j);
        want.push_back({1024, j});
        continue;
      }
      auto i = static_cast<std::uint32_t>(rng() % objects), j = static_cast<std::uint32_t>(rng() % objects);
      if (i == j) continue;
      if (i > j) std::swap(i, j);
      lists[rng() % lists.size()].push_back(std::uint64_t{i} << 32 | j);
      want.push_back({i, j});
    }
    std::sort(want.begin(), want.end(), [](Pair a, Pair b) { return a.i < b.i || (a.i == b.i && a.j < b.j); });
    std::vector<std::uint32_t> offsets;
    std::vector<Pair> scratch, got;
    for (int threads : {1, 2}) {
      detail::sort_chunk_pairs(lists, objects, offsets, scratch, got, threads);
      EXPECT_TRUE(same_pairs(got, want)) << objects << " objects, " << threads << " threads";
    }
  }
}

TEST(SortChunkPairs, ManyPairsToManyBlocksEqualAFullSort) {
  // Over 2^20 pairs into 196 blocks: the first pass scatters through lines of its own
  // (streaming stores; the partial lines at each block's ends as plain stores). Lists of every
  // size (empty, one pair, a few, most of them), blocks with a handful of pairs next to full
  // ones, and a block of one object with many partners.
  std::mt19937_64 rng(5);
  constexpr std::uint32_t objects = 200000;
  std::vector<std::vector<std::uint64_t>> lists(7);
  std::vector<std::uint64_t> want;
  const auto add = [&](std::size_t list, std::uint32_t i, std::uint32_t j) {
    if (i == j) return;
    if (i > j) std::swap(i, j);
    lists[list].push_back(std::uint64_t{i} << 32 | j);
    want.push_back(std::uint64_t{i} << 32 | j);
  };
  lists[1].push_back(std::uint64_t{3} << 32 | 4);  // a list of one pair
  want.push_back(std::uint64_t{3} << 32 | 4);
  for (int k = 0; k < 13; ++k)
    add(2, static_cast<std::uint32_t>(rng() % objects), static_cast<std::uint32_t>(rng() % objects));
  for (int k = 0; k < 1300000; ++k) {
    const std::uint32_t i = static_cast<std::uint32_t>(rng() % objects);
    // Blocks 40-59 (first indices 40 960-61 439) get only a few pairs each.
    if ((i >> 10) >= 40 && (i >> 10) < 60 && rng() % 512 != 0) continue;
    const std::uint32_t j = k % 97 == 0 ? 150000 : static_cast<std::uint32_t>(rng() % objects);  // one busy partner
    add(3 + static_cast<std::size_t>(rng() % 4), i, j);
  }
  ASSERT_GT(want.size(), std::size_t{1} << 20) << "enough pairs for the scatter through lines";
  std::sort(want.begin(), want.end());
  std::vector<Pair> want_pairs(want.size());
  for (std::size_t k = 0; k < want.size(); ++k) want_pairs[k] = {detail::key_i(want[k]), detail::key_j(want[k])};
  std::vector<std::uint32_t> offsets;
  std::vector<Pair> scratch, got;
  std::vector<std::uint64_t> key_scratch, got_keys;
  for (int threads : {1, 2}) {
    detail::sort_chunk_pairs(lists, objects, offsets, scratch, got, threads);
    EXPECT_TRUE(same_pairs(got, want_pairs)) << threads << " threads";
    detail::sort_chunk_keys(lists, objects, offsets, key_scratch, got_keys, threads);
    EXPECT_EQ(got_keys, want) << threads << " threads";
  }
}

}  // namespace
}  // namespace viscd
