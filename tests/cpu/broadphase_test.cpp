// The cpu backend's pairs against brute force, for every Morton width and layout, over random
// and degenerate sphere sets (none to two spheres, identical centres, touching spheres, a huge
// sphere among tiny ones, collinear centres, large coordinates, subnormal distances, counts
// around powers of two), plus tree validity and pair-memory behaviour.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "core/lbvh.hpp"
#include "cpu/cpu_detector.hpp"
#include "test_util.hpp"

namespace viscd {
namespace {

using test::oracle_pairs;
using test::random_spheres_by_half_extent;
using test::same_pairs;

struct Variant {
  Bits bits;
  Layout layout;
  int threads;
};
const Variant kVariants[] = {{Bits::b16, Layout::extended, 2}, {Bits::b32, Layout::extended, 2},
                             {Bits::b64, Layout::extended, 2}, {Bits::b16, Layout::plain, 1},
                             {Bits::b32, Layout::plain, 2},    {Bits::b64, Layout::plain, 1}};

// Checks every variant against the oracle and the tree's invariants.
void check_exact(const std::vector<Sphere>& spheres, const std::string& what) {
  const std::vector<Pair> want = oracle_pairs(spheres);
  for (const Variant& v : kVariants) {
    Config c = test::config_bits(v.bits, v.layout);
    c.threads = v.threads;
    auto owner = make_cpu_detector(c);
    const auto& det = detail::backend_as<detail::CpuDetector>(*owner);
    FrameResult f = test::run_frame(*owner, spheres);
    ASSERT_TRUE(same_pairs(f.pairs, want))
        << what << ", m=" << static_cast<int>(v.bits) << (v.layout == Layout::plain ? " plain" : " extended");
    EXPECT_EQ(f.stats.pairs, want.size());
    EXPECT_EQ(f.stats.bits, static_cast<int>(v.bits));
    const auto& bp = det.bucket_broadphase();
    ASSERT_EQ(detail::validate_wide_tree(bp.tree(), bp.leaf_boxes()), "") << what;
    // States: colliding iff in a pair; nothing culled without a camera.
    std::vector<char> in_pair(spheres.size(), 0);
    for (const Pair& p : want) in_pair[p.i] = in_pair[p.j] = 1;
    for (std::size_t k = 0; k < spheres.size(); ++k)
      ASSERT_EQ(f.state[k], in_pair[k] ? ObjectState::colliding : ObjectState::free) << what << " object " << k;
  }
}

TEST(CpuBroadphase, RandomScenesManySeeds) {
  for (std::uint64_t seed = 1; seed <= 25; ++seed) {
    const std::size_t n = 50 + seed * 97;
    check_exact(random_spheres_by_half_extent(n, seed, 8.0f + static_cast<float>(seed)),
                "seed " + std::to_string(seed));
  }
}

TEST(CpuBroadphase, EmptyOneTwo) {
  check_exact({}, "N=0");
  check_exact({{1, 2, 3, 1}}, "N=1");
  check_exact({{0, 0, 0, 1}, {1.5f, 0, 0, 1}}, "N=2 overlapping");
  check_exact({{0, 0, 0, 1}, {3, 0, 0, 1}}, "N=2 apart");
}

TEST(CpuBroadphase, AllCentresIdentical) {
  // Every key equal: 2000 spheres at one point give every one of 1 999 000 pairs.
  std::vector<Sphere> s(2000, Sphere{3.25f, -1.5f, 7.0f, 0.5f});
  check_exact(s, "identical centres");
  s.assign(2000, Sphere{0, 0, 0, 0});  // points: distance 0 <= 0
  const std::vector<Pair> want = oracle_pairs(s);
  EXPECT_EQ(want.size(), 1999000u);
  check_exact(s, "identical points");
}

TEST(CpuBroadphase, TouchingOnAGrid) {
  // Radius 0.5 at integer spacing: neighbours along an axis touch exactly (1 <= 1), diagonals don't.
  std::vector<Sphere> s;
  for (int x = 0; x < 12; ++x)
    for (int y = 0; y < 12; ++y)
      for (int z = 0; z < 12; ++z) s.push_back({float(x), float(y), float(z), 0.5f});
  const auto want = oracle_pairs(s);
  EXPECT_EQ(want.size(), 3u * 12 * 12 * 11);  // 3 axes x 144 lines x 11 neighbours
  check_exact(s, "touching grid");
}

TEST(CpuBroadphase, TouchingAtTheFloatBoundary) {
  // Radii chosen so the float test sits exactly at (or one ulp around) equality, at large
  // coordinates where boxes round the most: the tree must never miss what the test accepts.
  check_exact(test::float_boundary_pairs(600, 11), "float boundary");
}

TEST(CpuBroadphase, PairsThatUninflatedBoxesWouldMiss) {
  // Axis-aligned pairs whose float test accepts although the rounded boxes c - r, c + r do not
  // touch (radii of very different scales make s = ri + rj round up). Found by search, so the
  // set is adversarial by construction; geometry.hpp's conservative_box must keep them all.
  std::mt19937 rng(1);
  std::uniform_real_distribution<float> u(0, 1);
  std::vector<Sphere> s;
  auto scale = [&] { return std::ldexp(1.0f + u(rng), static_cast<int>(u(rng) * 30) - 10); };
  while (s.size() < 400) {
    const float cx = scale() * (u(rng) < 0.5f ? -1.f : 1.f), ri = scale(), rj = scale();
    const float y = u(rng) * 100, z = u(rng) * 100;
    float cj = cx + (ri + rj);
    for (int k = 0; k < 3; ++k, cj = std::nextafter(cj, 1e30f)) {
      const Sphere a{cx, y, z, ri}, b{cj, y, z, rj};
      const bool naive_boxes_touch = cj - rj <= cx + ri;
      if (spheres_overlap(a, b) && !naive_boxes_touch) {
        s.push_back(a);
        s.push_back(b);
        break;
      }
    }
  }
  check_exact(s, "adversarial boxes");
  EXPECT_GE(oracle_pairs(s).size(), 200u);
}

TEST(CpuBroadphase, HugeAmongTiny) {
  auto s = random_spheres_by_half_extent(3000, 5, 100.0f, 0.01f, 0.05f);
  s[17] = {0, 0, 0, 40};
  s[1234] = {50, 50, 50, 30};
  s[2999] = {-1e4f, 0, 0, 1e4f};  // swallows half the world
  check_exact(s, "huge among tiny");
}

TEST(CpuBroadphase, AllOnALine) {
  std::vector<Sphere> s;
  for (int k = 0; k < 3000; ++k) s.push_back({0.3f * float(k), 0, 0, 0.2f + 0.001f * float(k % 7)});
  check_exact(s, "line");
}

TEST(CpuBroadphase, CoordinatesNear1e5) {
  auto s = random_spheres_by_half_extent(2500, 9, 30.0f, 0.5f, 2.0f);
  for (auto& sp : s) sp.x += 1e5f, sp.y -= 1e5f, sp.z += 1e5f;
  check_exact(s, "near 1e5");
}

TEST(CpuBroadphase, TinyRadiiAndSubnormalDistances) {
  std::vector<Sphere> s;
  for (int k = 0; k < 500; ++k) {
    const float base = 1e-20f * float(k % 50);
    s.push_back({base, base * 0.5f, 0, 1e-21f * float(k % 7)});
  }
  check_exact(s, "tiny");
}

TEST(CpuBroadphase, CountsAroundPowersOfTwo) {
  for (std::size_t p : {64u, 256u, 1024u, 4096u}) {
    for (std::size_t n : {p - 1, p, p + 1})
      check_exact(random_spheres_by_half_extent(n, n, 6.0f), "N=" + std::to_string(n));
  }
}

TEST(CpuBroadphase, ThreadCountsAgree) {
  const auto s = random_spheres_by_half_extent(20000, 3, 40.0f);
  Config one;
  one.threads = 1;
  Config many;
  many.threads = 4;
  auto a = make_cpu_detector(one), b = make_cpu_detector(many);
  const auto fa = test::run_frame(*a, s), fb = test::run_frame(*b, s);
  EXPECT_TRUE(same_pairs(fa.pairs, fb.pairs));
  EXPECT_TRUE(same_pairs(fa.pairs, oracle_pairs(s)));
}

TEST(CpuBroadphase, PairBuffersGrowAcrossFrames) {
  // Same detector: few pairs, then millions, then few again; every frame exact.
  auto det = make_cpu_detector();
  FrameResult f;
  const auto sparse = random_spheres_by_half_extent(500, 1, 50.0f);
  ASSERT_TRUE(det->detect(sparse, nullptr, f).ok());
  EXPECT_TRUE(same_pairs(f.pairs, oracle_pairs(sparse)));
  const std::vector<Sphere> dense(1500, Sphere{1, 1, 1, 1});
  ASSERT_TRUE(det->detect(dense, nullptr, f).ok());
  EXPECT_EQ(f.pairs.size(), 1500u * 1499 / 2);
  ASSERT_TRUE(det->detect(sparse, nullptr, f).ok());
  EXPECT_TRUE(same_pairs(f.pairs, oracle_pairs(sparse)));
}

TEST(CpuBroadphase, PairMemoryCapIsAnError) {
  const std::vector<Sphere> dense(100, Sphere{0, 0, 0, 1});  // 4950 pairs = 39600 bytes
  Config c;
  c.pair_memory_cap = 39600;
  FrameResult f;
  EXPECT_TRUE(make_cpu_detector(c)->detect(dense, nullptr, f).ok());
  c.pair_memory_cap = 39599;
  for (auto* make : {&make_cpu_detector, &make_reference_detector}) {
    const Status st = (*make)(c)->detect(dense, nullptr, f);
    ASSERT_FALSE(st.ok());
    EXPECT_NE(st.error().find("4950"), std::string::npos) << st.error();
  }
}

TEST(CpuBroadphase, InvalidSpheresAreErrors) {
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  const std::vector<std::pair<Sphere, std::string>> bad = {{{nan, 0, 0, 1}, "x is not a finite"},
                                                           {{0, inf, 0, 1}, "y is not a finite"},
                                                           {{0, 0, 0, -1}, "negative radius"},
                                                           {{0, 0, 2e18f, 1}, "exceeds"},
                                                           {{0, 0, 0, nan}, "r is not a finite"}};
  for (const auto& [sphere, phrase] : bad) {
    std::vector<Sphere> s = random_spheres_by_half_extent(10, 1);
    s[7] = sphere;
    for (const char* backend : {"cpu", "reference"}) {
      FrameResult f;
      const Status st = make_detector(backend).value()->detect(s, nullptr, f);
      ASSERT_FALSE(st.ok()) << backend << " accepted " << phrase;
      EXPECT_NE(st.error().find("sphere 7"), std::string::npos) << st.error();
      EXPECT_NE(st.error().find(phrase), std::string::npos) << st.error();
    }
  }
  // r = 0 (a point) is allowed.
  FrameResult f;
  EXPECT_TRUE(make_cpu_detector()->detect(std::vector<Sphere>{{0, 0, 0, 0}, {0, 0, 0, 0}}, nullptr, f).ok());
  EXPECT_EQ(f.pairs.size(), 1u);
}

TEST(CpuBroadphase, ReferenceBackendMatchesIndependentOracle) {
  const auto s = random_spheres_by_half_extent(1500, 77, 10.0f);
  auto ref = make_reference_detector();
  EXPECT_TRUE(same_pairs(test::run_frame(*ref, s).pairs, oracle_pairs(s)));
}

TEST(Factory, UnknownBackendIsAnError) {
  const auto r = make_detector("vulkan");
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().find("vulkan"), std::string::npos);
}

}  // namespace
}  // namespace viscd
