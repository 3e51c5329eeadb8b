// The adapters' outward rounding (src/adapters/adapter_util.hpp) against its definition: the
// largest float <= v and the smallest float >= v, found here with std::nextafter; the lists lent
// per call; the index of an engine's objects against std::unordered_map.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <unordered_map>
#include <vector>

#include "adapter_util.hpp"

namespace viscd::adapter_detail {
namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();

// The definition, slowly: the float nearest v, then one step toward v's far side if it overshot.
float want_down(double v) {
  float f = static_cast<float>(v);
  if (static_cast<double>(f) > v) f = std::nextafter(f, -kInf);
  return f;
}
float want_up(double v) {
  float f = static_cast<float>(v);
  if (static_cast<double>(f) < v) f = std::nextafter(f, kInf);
  return f;
}

void check(double v) {
  const float d = round_down(v), u = round_up(v);
  ASSERT_EQ(std::bit_cast<std::uint32_t>(d), std::bit_cast<std::uint32_t>(want_down(v))) << v;
  ASSERT_EQ(std::bit_cast<std::uint32_t>(u), std::bit_cast<std::uint32_t>(want_up(v))) << v;
  ASSERT_LE(static_cast<double>(d), v);
  ASSERT_GE(static_cast<double>(u), v);
}

TEST(AdapterRounding, EqualsNextafterEverywhere) {
  const double max = std::numeric_limits<float>::max(), tiny = std::numeric_limits<float>::denorm_min();
  for (const double v : {0.0,
                         -0.0,
                         1.0,
                         -1.0,
                         0.1,
                         -0.1,
                         1e-40,
                         -1e-40,
                         tiny,
                         -tiny,
                         tiny / 3,
                         -tiny / 3,
                         max,
                         -max,
                         max * (1 + 1e-12),
                         -max * (1 + 1e-12),
                         1e300,
                         -1e300,
                         1e18,
                         -1e18})
    check(v);
  std::mt19937_64 rng(1);
  std::uniform_real_distribution<double> mantissa(-1.0, 1.0);
  std::uniform_int_distribution<int> exponent(-160, 135);
  for (int k = 0; k < 200000; ++k) check(std::ldexp(mantissa(rng), exponent(rng)));
  // Exact floats stay as they are; infinities stay; NaN stays NaN.
  EXPECT_EQ(round_down(0.5), 0.5f);
  EXPECT_EQ(round_up(-3.0), -3.0f);
  EXPECT_EQ(round_down(std::numeric_limits<double>::infinity()), kInf);
  EXPECT_EQ(round_up(-std::numeric_limits<double>::infinity()), -kInf);
  EXPECT_TRUE(std::isnan(round_down(std::nan(""))));
  EXPECT_TRUE(std::isnan(round_up(std::nan(""))));
  EXPECT_EQ(round_down(1.5f), 1.5f);  // a float in: itself
}

// Random inserts, removals, reassignments and lookups against std::unordered_map: many pools of
// seven keys (they stay in a table of 16 slots, so probe runs wrap around its end and removals
// shift runs back across it; every key is looked up after every step), and pools of 5 000, with
// keys spaced as allocations are (16 bytes) and at random.
TEST(PointerIndex, MatchesUnorderedMap) {
  struct Case {
    std::size_t keys, pools, steps;
  };
  for (const Case c : {Case{7, 200, 2000}, Case{5000, 1, 200000}}) {
    for (const bool spaced : {true, false}) {
      std::mt19937_64 rng(c.keys + spaced);
      for (std::size_t round = 0; round < c.pools; ++round) {
        std::vector<std::uintptr_t> pool(c.keys);
        const std::uintptr_t base = 16 * (rng() >> 20);
        for (std::size_t k = 0; k < c.keys; ++k) pool[k] = spaced ? base + 16 * k : (rng() | 1);
        PointerIndex index;
        std::unordered_map<std::uintptr_t, std::uint32_t> want;
        auto check = [&](std::uintptr_t key) {
          const auto it = want.find(key);
          ASSERT_EQ(index.find(reinterpret_cast<const void*>(key)),
                    it == want.end() ? PointerIndex::kMissing : it->second);
        };
        std::uniform_int_distribution<std::size_t> pick(0, c.keys - 1);
        for (std::size_t step = 0; step < c.steps; ++step) {
          const std::uintptr_t key = pool[pick(rng)];
          const auto* p = reinterpret_cast<const void*>(key);
          const auto value = static_cast<std::uint32_t>(rng() % 1000);
          switch (rng() % 4) {
            case 0:
              ASSERT_EQ(index.insert(p, value), want.emplace(key, value).second);
              break;
            case 1:
              ASSERT_EQ(index.erase(p), want.erase(key) == 1);
              break;
            case 2:
              if (want.count(key)) {
                index.assign(p, value);
                want[key] = value;
              }
              break;
            default:
              break;
          }
          ASSERT_EQ(index.size(), want.size());
          if (c.keys <= 16) {
            for (const std::uintptr_t k : pool) ASSERT_NO_FATAL_FAILURE(check(k));
          } else {
            ASSERT_NO_FATAL_FAILURE(check(key));
          }
        }
        for (const std::uintptr_t k : pool) ASSERT_NO_FATAL_FAILURE(check(k));
        index.clear();
        EXPECT_EQ(index.size(), 0u);
        EXPECT_EQ(index.find(reinterpret_cast<const void*>(pool[0])), PointerIndex::kMissing);
      }
    }
  }
  PointerIndex empty;
  EXPECT_EQ(empty.find(nullptr), PointerIndex::kMissing);
  EXPECT_FALSE(empty.insert(nullptr, 1));
  EXPECT_FALSE(empty.erase(&empty));
}

TEST(VectorPool, LoansAreReusedAndNested) {
  VectorPool<int> pool;
  const int* first = nullptr;
  {
    auto a = pool.take();
    a->assign(100, 7);
    first = a->data();
    {
      auto b = pool.take();  // taken while the first is out: a vector of its own
      b->push_back(1);
      EXPECT_NE(b->data(), first);
    }
  }
  auto c = pool.take();  // given back: empty, its memory kept
  EXPECT_TRUE(c->empty());
  EXPECT_GE(c->capacity(), 1u);
}

}  // namespace
}  // namespace viscd::adapter_detail
