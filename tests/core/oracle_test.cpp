// The tests' own oracle (test_util.hpp's oracle_pairs(), a sweep along x) against the plainest
// brute force, on the inputs where a sweep could go wrong: pairs at the float boundary, tiny and
// huge radii, identical centres, NaN, Inf and negative radii, and an active subset out of order.
#include <gtest/gtest.h>

#include <limits>
#include <vector>

#include "test_util.hpp"

namespace viscd {
namespace {

std::vector<Pair> every_pair(const std::vector<Sphere>& s, const std::vector<std::uint32_t>& active) {
  std::vector<Pair> out;
  for (std::size_t a = 0; a < active.size(); ++a)
    for (std::size_t b = a + 1; b < active.size(); ++b)
      if (spheres_overlap(s[active[a]], s[active[b]])) out.push_back({active[a], active[b]});
  return out;
}

void expect_same(const std::vector<Sphere>& s, const char* what) {
  std::vector<std::uint32_t> all(s.size());
  for (std::uint32_t k = 0; k < s.size(); ++k) all[k] = k;
  const std::vector<Pair> want = every_pair(s, all), got = test::oracle_pairs(s);
  ASSERT_EQ(got.size(), want.size()) << what;
  for (std::size_t k = 0; k < want.size(); ++k)
    ASSERT_TRUE(got[k].i == want[k].i && got[k].j == want[k].j) << what << ": pair " << k;
  // A subset, out of order: the pairs come in the order of brute force over that list.
  std::vector<std::uint32_t> some;
  for (std::uint32_t k = 0; k < s.size(); k += 2) some.insert(some.begin(), k);
  const std::vector<Pair> want_some = every_pair(s, some), got_some = test::oracle_pairs(s, &some);
  ASSERT_EQ(got_some.size(), want_some.size()) << what << " (subset)";
  for (std::size_t k = 0; k < want_some.size(); ++k)
    ASSERT_TRUE(got_some[k].i == want_some[k].i && got_some[k].j == want_some[k].j) << what << " (subset)";
}

TEST(Oracle, SweepEqualsEveryPair) {
  expect_same({}, "none");
  expect_same({{0, 0, 0, 1}}, "one");
  expect_same({{0, 0, 0, 1}, {2, 0, 0, 1}}, "two touching");
  expect_same(test::float_boundary_pairs(300, 7), "float boundary");
  expect_same(std::vector<Sphere>(50, Sphere{3, -2, 1, 0.25f}), "identical");
  expect_same(std::vector<Sphere>(50, Sphere{3, -2, 1, 0}), "identical points");
  auto mixed = test::random_spheres_by_half_extent(600, 3, 20.0f, 0.0f, 1.5f);
  mixed[1] = {0, 0, 0, 1e4f};                                     // one huge
  mixed[2] = {1e-30f, 0, 0, 1e-30f};                              // tiny, squares underflow
  mixed[3] = {2e-30f, 0, 0, 0};                                   // tiny
  mixed[4] = {0, 0, 0, std::numeric_limits<float>::quiet_NaN()};  // NaN radius
  mixed[5] = {std::numeric_limits<float>::infinity(), 0, 0, 1};   // Inf centre
  mixed[6] = {5, 5, 5, -3};                                       // negative radius
  mixed[7] = {4, 5, 5, -3};                                       // and its partner
  mixed[8] = {1e19f, 0, 0, 1e19f};                                // squares overflow
  mixed[9] = {-1e20f, 0, 0, 2e19f};                               // far off, overflowing too
  expect_same(mixed, "mixed");
}

}  // namespace
}  // namespace viscd
