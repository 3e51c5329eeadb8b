#include <gtest/gtest.h>

#include <algorithm>
#include <numeric>
#include <random>

#include "cpu/radix_sort.hpp"

namespace viscd::detail {
namespace {

template <class K>
void check_against_stable_sort(std::size_t n, int threads, std::uint64_t seed, int distinct_bits) {
  std::mt19937_64 rng(seed);
  std::vector<K> keys(n);
  const std::uint64_t mask = distinct_bits >= 64 ? ~0ull : ((1ull << distinct_bits) - 1);
  for (auto& k : keys) k = static_cast<K>(rng() & mask);
  std::vector<std::uint32_t> values(n);
  std::iota(values.begin(), values.end(), 0u);

  std::vector<std::pair<K, std::uint32_t>> want(n);
  for (std::size_t i = 0; i < n; ++i) want[i] = {keys[i], values[i]};
  std::stable_sort(want.begin(), want.end(), [](auto& a, auto& b) { return a.first < b.first; });

  RadixScratch<K> scratch;
  radix_sort<K>(keys, values, 8 * sizeof(K), threads, scratch);
  for (std::size_t i = 0; i < n; ++i) {
    ASSERT_EQ(keys[i], want[i].first) << "n=" << n << " i=" << i;
    ASSERT_EQ(values[i], want[i].second) << "n=" << n << " i=" << i;
  }
}

class RadixSort : public ::testing::TestWithParam<std::size_t> {};

TEST_P(RadixSort, EqualsStableSortForEveryWidth) {
  const std::size_t n = GetParam();
  for (int threads : {1, 2, 3}) {
    check_against_stable_sort<std::uint16_t>(n, threads, n + 1, 16);
    check_against_stable_sort<std::uint32_t>(n, threads, n + 2, 32);
    check_against_stable_sort<std::uint64_t>(n, threads, n + 3, 64);
    // Many duplicates: stability decides the order of values.
    check_against_stable_sort<std::uint32_t>(n, threads, n + 4, 3);
    check_against_stable_sort<std::uint64_t>(n, threads, n + 5, 0);  // all keys equal
  }
}

INSTANTIATE_TEST_SUITE_P(Sizes, RadixSort,
                         ::testing::Values(0, 1, 2, 3, 255, 256, 257, 4095, 4096, 4097, 65537, 200000));

TEST(RadixSortKeysOnly, SortsWithoutValues) {
  std::vector<std::uint64_t> keys = {5, 1ull << 40, 3, 3, 0, ~0ull};
  RadixScratch<std::uint64_t> s;
  radix_sort<std::uint64_t>(keys, {}, 64, 2, s);
  EXPECT_TRUE(std::is_sorted(keys.begin(), keys.end()));
  EXPECT_EQ(keys.front(), 0u);
  EXPECT_EQ(keys.back(), ~0ull);
}

}  // namespace
}  // namespace viscd::detail
