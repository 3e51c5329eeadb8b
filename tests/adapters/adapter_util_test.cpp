// The adapters' outward rounding (src/adapters/adapter_util.hpp) against its definition: the
// largest float <= v and the smallest float >= v, found here with std::nextafter; and the lists
// lent per call.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
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
