// The keep-the-order policy (cpu/keep_order.hpp), step by step.

#include <gtest/gtest.h>

#include <limits>
#include <vector>

#include "cpu/keep_order.hpp"

namespace viscd {
namespace {

using detail::KeepOrderPolicy;
using detail::kStaleness;

const std::vector<std::uint32_t> kAll = {0, 1, 2, 3, 4, 5, 6, 7};
const std::vector<std::uint32_t> kSome = {1, 3, 4, 6};

TEST(KeepOrderPolicy, NothingToKeepBeforeASortedFrame) {
  KeepOrderPolicy p;
  EXPECT_FALSE(p.may_keep(8, kAll, Layout::extended));
}

TEST(KeepOrderPolicy, KeepsTheSameActiveSetAndLayout) {
  KeepOrderPolicy p;
  p.remember_sorted(8, kAll, Layout::extended, 100.0);
  EXPECT_TRUE(p.may_keep(8, kAll, Layout::extended));
  EXPECT_FALSE(p.may_keep(8, kAll, Layout::plain)) << "another layout kind";
  EXPECT_FALSE(p.may_keep(9, std::vector<std::uint32_t>{0, 1, 2, 3, 4, 5, 6, 7, 8}, Layout::extended))
      << "more objects";
  EXPECT_FALSE(p.may_keep(8, kSome, Layout::extended)) << "some culled";
  p.remember_sorted(8, kSome, Layout::extended, 100.0);
  EXPECT_TRUE(p.may_keep(8, kSome, Layout::extended));
  EXPECT_TRUE(p.may_keep(20, kSome, Layout::extended)) << "the same active ids among more objects";
  EXPECT_FALSE(p.may_keep(8, std::vector<std::uint32_t>{1, 3, 4, 7}, Layout::extended)) << "another active set";
  EXPECT_FALSE(p.may_keep(8, kAll, Layout::extended)) << "all active now";
  EXPECT_FALSE(p.may_keep(8, std::vector<std::uint32_t>{3}, Layout::extended)) << "fewer than two";
}

TEST(KeepOrderPolicy, BoxGrowthBeyondStalenessSorts) {
  KeepOrderPolicy p;
  p.remember_sorted(8, kAll, Layout::extended, 160.0);
  EXPECT_TRUE(p.keeps(160.0));
  EXPECT_TRUE(p.keeps(160.0 * (1 + kStaleness)));
  EXPECT_FALSE(p.keeps(160.0 * (1 + kStaleness) + 1e-9));
  // A non-finite box sum (a huge sphere) never keeps.
  p.remember_sorted(8, kAll, Layout::extended, std::numeric_limits<double>::infinity());
  EXPECT_FALSE(p.may_keep(8, kAll, Layout::extended));
}

TEST(KeepOrderPolicy, BucketPairGrowthSortsTheNextFrame) {
  KeepOrderPolicy p;
  p.remember_sorted(8, kAll, Layout::extended, 100.0);
  p.after_search(false, 1600);  // the sorted frame's count
  p.after_search(true, 1700);   // kept frames within 1/16
  EXPECT_TRUE(p.may_keep(8, kAll, Layout::extended));
  p.after_search(true, 1701);  // past 1600 * 17/16 = 1700
  EXPECT_FALSE(p.may_keep(8, kAll, Layout::extended));
  p.remember_sorted(8, kAll, Layout::extended, 100.0);
  EXPECT_TRUE(p.may_keep(8, kAll, Layout::extended));
}

TEST(KeepOrderPolicy, SortNextAndDisabled) {
  KeepOrderPolicy p;
  p.remember_sorted(8, kAll, Layout::extended, 100.0);
  p.sort_next();
  EXPECT_FALSE(p.may_keep(8, kAll, Layout::extended));
  p.remember_sorted(8, kAll, Layout::extended, 100.0);
  p.set_enabled(false);
  EXPECT_FALSE(p.enabled());
  EXPECT_FALSE(p.may_keep(8, kAll, Layout::extended));
}

}  // namespace
}  // namespace viscd
