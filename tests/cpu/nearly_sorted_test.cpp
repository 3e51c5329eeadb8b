// The nearly-sorted sort (cpu/nearly_sorted.hpp) against std::sort: small moves, far movers in
// both directions, runs over several threads, sizes around its reach, and the inputs it gives up on.

#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <vector>

#include "cpu/nearly_sorted.hpp"

namespace viscd {
namespace {

using detail::NearlySortedSort;
using detail::SortEntry;

bool less(const SortEntry& a, const SortEntry& b) { return a.key < b.key || (a.key == b.key && a.id < b.id); }

// Keys 0, 10, 20, ... with ids in order, then perturbed: each key moved by up to `jitter` places'
// worth, and `far` entries given a key from anywhere.
std::vector<SortEntry> nearly(std::size_t n, int jitter, std::size_t far, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> j(-jitter * 10, jitter * 10);
  std::uniform_int_distribution<std::size_t> at(0, n ? n - 1 : 0);
  std::vector<SortEntry> e(n);
  for (std::size_t k = 0; k < n; ++k) {
    const long long key = static_cast<long long>(k) * 10 + (jitter ? j(rng) : 0);
    e[k] = {static_cast<std::uint64_t>(std::max(0ll, key)), static_cast<std::uint32_t>(k),
            static_cast<std::uint32_t>(k)};
  }
  for (std::size_t f = 0; f < far && n; ++f) e[at(rng)].key = static_cast<std::uint64_t>(at(rng)) * 10 + 5;
  return e;
}

// An emit that drops the result (the tests that look at the report only).
const auto ignore_moves = [](std::size_t, const SortEntry&) {};

void expect_sorted_like_std(std::vector<SortEntry> e, int threads, const char* what) {
  std::vector<SortEntry> want = e;
  std::sort(want.begin(), want.end(), less);
  NearlySortedSort s;
  const std::size_t n = e.size();
  // The result comes out through emit(k, entry): each place once.
  std::vector<SortEntry> out(n);
  std::vector<int> emitted(n, 0);
  ASSERT_TRUE(s.sort(e.data(), n, threads, less,
                     [&](std::size_t k, const SortEntry& x) {
                       out[k] = x;
                       ++emitted[k];
                     }))
      << what << ", n = " << n << ", threads " << threads;
  EXPECT_TRUE(s.report().sorted);
  for (std::size_t k = 0; k < n; ++k) {
    ASSERT_EQ(emitted[k], 1) << what << ": place " << k << " of " << n << ", threads " << threads;
    ASSERT_EQ(out[k].key, want[k].key) << what << ": entry " << k << " of " << n << ", threads " << threads;
    ASSERT_EQ(out[k].id, want[k].id) << what << ": entry " << k;
    ASSERT_EQ(out[k].at, want[k].at) << what << ": entry " << k;
  }
}

TEST(NearlySortedSort, EqualsStdSortOnNearlySortedInput) {
  for (int threads : {1, 2, 3, 8}) {
    for (std::size_t n : {0u, 1u, 2u, 31u, 32u, 33u, 65u, 4095u, 4096u, 4097u, 50000u}) {
      expect_sorted_like_std(nearly(n, 0, 0, 1), threads, "sorted already");
      expect_sorted_like_std(nearly(n, 3, 0, 2), threads, "moves within reach");
      expect_sorted_like_std(nearly(n, 3, n / 100 + 1, 3), threads, "a few far movers");
    }
  }
}

TEST(NearlySortedSort, FarMoversBothWaysAndAcrossRuns) {
  // The first entry moved to the end and the last to the front: beyond reach both ways, and in
  // different runs when there are several.
  for (int threads : {1, 2, 8}) {
    std::vector<SortEntry> e = nearly(20000, 1, 0, 4);
    e.front().key = 1u << 30;
    e.back().key = 0;
    expect_sorted_like_std(e, threads, "ends swapped");
    // A block of 40 entries (beyond reach) moved forward by 1000 places.
    std::vector<SortEntry> b = nearly(20000, 0, 0, 5);
    for (std::size_t k = 5000; k < 5040; ++k) b[k].key += 10000;
    expect_sorted_like_std(b, threads, "a block moved forward");
  }
}

TEST(NearlySortedSort, ReportsMovesAndSetAside) {
  std::vector<SortEntry> e = nearly(1000, 0, 0, 6);
  std::swap(e[10].key, e[11].key);  // one shift within reach
  e[500].key = 99999;               // far forward: set aside
  NearlySortedSort s;
  ASSERT_TRUE(s.sort(e.data(), e.size(), 1, less, ignore_moves));
  EXPECT_EQ(s.report().moves, 1u);
  EXPECT_EQ(s.report().far, 1u);
}

TEST(NearlySortedSort, GivesUpWhenTheOrderSaysLittle) {
  // Reversed: nearly everything belongs far back, so more than a quarter is set aside.
  std::vector<SortEntry> e = nearly(10000, 0, 0, 7);
  std::reverse(e.begin(), e.end());
  NearlySortedSort s;
  EXPECT_FALSE(s.sort(e.data(), e.size(), 1, less, ignore_moves));
  EXPECT_FALSE(s.report().sorted);
  // Shuffled, on several runs.
  std::vector<SortEntry> r = nearly(10000, 0, 0, 8);
  std::shuffle(r.begin(), r.end(), std::mt19937(9));
  EXPECT_FALSE(s.sort(r.data(), r.size(), 4, less, ignore_moves));
  // The same object sorts a good input afterwards.
  expect_sorted_like_std(nearly(5000, 2, 10, 10), 4, "after giving up");
}

TEST(NearlySortedSort, ReusesItsBuffers) {
  // As the broadphase uses it: one entries buffer with headroom, refilled every frame; after the
  // first sort nothing grows.
  constexpr std::size_t n = 30000;
  NearlySortedSort s;
  std::vector<SortEntry> entries;
  entries.reserve(n + n / 2);
  std::uint64_t bytes = 0;
  for (int round = 0; round < 4; ++round) {
    const std::vector<SortEntry> input = nearly(n, 2, 100, 12 + static_cast<unsigned>(round));
    entries.assign(input.begin(), input.end());
    ASSERT_TRUE(s.sort(entries.data(), n, 4, less, ignore_moves));
    const std::uint64_t now = s.memory_bytes() + entries.capacity() * sizeof(SortEntry);
    if (round > 0) {
      EXPECT_EQ(now, bytes) << "round " << round;
    }
    bytes = now;
  }
}

}  // namespace
}  // namespace viscd
