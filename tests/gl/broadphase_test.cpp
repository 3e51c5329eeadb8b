// Stages 5-8 of the gl backend against the cpu backend's KarrasBroadphase and brute force, on
// identical inputs (same spheres, same active set, same m): codes and sorted order exactly,
// the copied-back tree valid, pairs exactly equal.
#include <algorithm>
#include <numeric>
#include <random>

#include "cpu/brute_force.hpp"
#include "cpu/morton_order.hpp"
#include "gl_test_util.hpp"
#include "karras/karras_lbvh.hpp"

namespace viscd::test {
namespace {

struct Case {
  std::vector<Sphere> spheres;
  std::vector<std::uint32_t> active;
};

Case all_active(std::vector<Sphere> s) {
  Case c{std::move(s), {}};
  c.active.resize(c.spheres.size());
  std::iota(c.active.begin(), c.active.end(), 0u);
  return c;
}

// Runs both broadphases and compares everything observable.
void check(test::GlUnderTest& gl, const Case& c, int bits, Layout layout = Layout::extended) {
  SCOPED_TRACE("n = " + std::to_string(c.active.size()) + ", m = " + std::to_string(bits));
  Config cfg = gl.config();
  cfg.layout = layout;
  gl.set_config(cfg);
  std::vector<Pair> gl_pairs;
  FrameStats gl_stats;
  const Status s = gl.inspect().run_broadphase(c.spheres, c.active, bits, gl_pairs, gl_stats);
  ASSERT_TRUE(s.ok()) << s.error();

  detail::KarrasBroadphase cpu;
  std::vector<Pair> cpu_pairs;
  FrameStats cpu_stats;
  ASSERT_TRUE(cpu.run(c.spheres, c.active, bits, layout, 1, 0, cpu_pairs, cpu_stats).ok());
  EXPECT_EQ(gl_stats.layout, cpu_stats.layout);

  const std::vector<std::uint64_t> codes = gl.inspect().read_sorted_codes();
  const std::vector<std::uint64_t> cpu_codes = cpu.sorted_codes();
  ASSERT_EQ(codes.size(), cpu_codes.size());
  EXPECT_TRUE(codes == cpu_codes) << "sorted Morton codes differ";
  const std::vector<std::uint32_t> ids = gl.inspect().read_sorted_ids();
  EXPECT_TRUE(std::equal(ids.begin(), ids.end(), cpu.sorted_objects().begin(), cpu.sorted_objects().end()))
      << "sorted order differs";

  detail::Lbvh tree;
  std::vector<detail::Aabb> leaf_boxes;
  gl.inspect().read_tree(tree, leaf_boxes);
  EXPECT_EQ(detail::validate_lbvh(tree, leaf_boxes), "");
  // Leaf boxes are conservative_box() bit for bit.
  for (std::size_t p = 0; p < leaf_boxes.size(); ++p) {
    const detail::Aabb& a = leaf_boxes[p];
    const detail::Aabb& b = cpu.leaf_boxes()[p];
    ASSERT_TRUE(a.lo.x == b.lo.x && a.lo.y == b.lo.y && a.lo.z == b.lo.z && a.hi.x == b.hi.x && a.hi.y == b.hi.y &&
                a.hi.z == b.hi.z)
        << "leaf box " << p;
  }
  // The GPU topology equals the CPU one (same keys, same algorithm).
  if (c.active.size() >= 2) {
    for (std::size_t i = 0; i + 1 < c.active.size(); ++i) {
      ASSERT_EQ(tree.nodes[i].child[0], cpu.tree().nodes[i].child[0]) << "node " << i;
      ASSERT_EQ(tree.nodes[i].child[1], cpu.tree().nodes[i].child[1]) << "node " << i;
    }
  }

  std::vector<Pair> brute;
  detail::brute_force_pairs(c.spheres, c.active, brute);
  EXPECT_EQ(gl_pairs.size(), brute.size());
  EXPECT_TRUE(gl_pairs == brute) << "pairs differ from brute force";
  EXPECT_TRUE(gl_pairs == cpu_pairs);
  EXPECT_EQ(gl_stats.pairs, brute.size());
}

TEST(GlBroadphase, SizesAroundWorkGroups) {
  VISCD_GL_OR_SKIP(gl);
  // Work groups of 256; the one-group local sort up to 1024 keys; radix tiles of 1024 keys.
  for (std::size_t n : {0u, 1u, 2u, 3u, 255u, 256u, 257u, 1023u, 1024u, 1025u, 2047u, 2048u, 2049u, 4097u}) {
    const Case c = all_active(random_spheres_by_edge(n, 20.0f, 0.2f, 1.0f, static_cast<unsigned>(n) + 7));
    for (int bits : {16, 32, 64}) check(*gl, c, bits);
  }
}

TEST(GlBroadphase, PairCountsAroundTheLocalSortLimit) {
  VISCD_GL_OR_SKIP(gl);
  // A chain of touching spheres along x gives exactly length - 1 pairs; the pairs are sorted by
  // the one-group sort up to 1024 of them and by the radix passes above. The chain is shuffled
  // so that the traversal finds the pairs out of order.
  for (std::size_t length : {2u, 1024u, 1025u, 1026u, 2050u}) {
    std::vector<Sphere> s(length);
    for (std::size_t k = 0; k < length; ++k) s[k] = {static_cast<float>(k), 0.25f, -0.5f, 0.5f};
    std::mt19937 rng(static_cast<unsigned>(length));
    std::shuffle(s.begin(), s.end(), rng);
    SCOPED_TRACE("chain of " + std::to_string(length));
    check(*gl, all_active(s), 32);
  }
}

TEST(GlBroadphase, PlainLayout) {
  VISCD_GL_OR_SKIP(gl);
  const Case c = all_active(random_spheres_by_edge(700, 30.0f, 0.2f, 1.2f, 3));
  for (int bits : {16, 32, 64}) check(*gl, c, bits, Layout::plain);
}

TEST(GlBroadphase, AllEqualCentresMortonTies) {
  VISCD_GL_OR_SKIP(gl);
  // 300 identical spheres: every key equal, every pair collides (44 850 pairs), ties by index.
  const Case c = all_active(std::vector<Sphere>(300, Sphere{1.5f, -2.0f, 0.25f, 0.5f}));
  for (int bits : {16, 64}) check(*gl, c, bits);
}

TEST(GlBroadphase, TouchingAndPointSpheres) {
  VISCD_GL_OR_SKIP(gl);
  std::vector<Sphere> s;
  for (int k = 0; k < 40; ++k) s.push_back({static_cast<float>(k), 0, 0, 0.5f});  // touching chain
  for (int k = 0; k < 10; ++k) s.push_back({3.0f, 5.0f, 0, 0.0f});                // coincident points
  s.push_back({0, 0, 0, 1000.0f});                                                // huge radius
  check(*gl, all_active(s), 32);
}

TEST(GlBroadphase, SubsetActiveAndRandomScenes) {
  VISCD_GL_OR_SKIP(gl);
  for (SceneKind kind : {SceneKind::ring, SceneKind::box, SceneKind::clusters}) {
    SceneParams p;
    p.kind = kind;
    p.objects = 3000;
    p.seed = 11;
    Scene scene = Scene::make(p);
    scene.step(0.5f);
    Case c{{scene.spheres().begin(), scene.spheres().end()}, {}};
    for (std::uint32_t k = 0; k < c.spheres.size(); ++k)
      if (k % 3 != 1) c.active.push_back(k);
    check(*gl, c, 32);
  }
}

TEST(GlBroadphase, PairBufferOverflowGrowsAndReruns) {
  GlOptions o;
  o.initial_pair_capacity = 64;
  VISCD_GL_OR_SKIP(gl, Config{}, o);
  // Recreate a detector so that the capacity starts small.
  auto fresh = test::GlUnderTest::create(Config{}, GlOptions{.debug = true, .initial_pair_capacity = 64});
  ASSERT_TRUE(fresh.ok()) << fresh.error();
  test::GlUnderTest& d = *fresh.value();
  ASSERT_EQ(d.inspect().pair_capacity(), 64u);
  const Case c = all_active(random_spheres_by_edge(2000, 12.0f, 0.3f, 0.9f, 5));
  std::vector<Pair> brute;
  detail::brute_force_pairs(c.spheres, c.active, brute);
  ASSERT_GT(brute.size(), 64u);
  check(d, c, 32);
  EXPECT_GE(d.inspect().pair_capacity(), brute.size());
}

TEST(GlBroadphase, PairMemoryCapIsAnError) {
  VISCD_GL_OR_SKIP(gl);
  Config cfg;
  cfg.pair_memory_cap = 8 * 10;  // 10 pairs
  gl->set_config(cfg);
  const Case c = all_active(std::vector<Sphere>(20, Sphere{0, 0, 0, 1}));
  std::vector<Pair> pairs;
  FrameStats stats;
  const Status s = gl->inspect().run_broadphase(c.spheres, c.active, 32, pairs, stats);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().find("190 colliding pairs"), std::string::npos) << s.error();
}

}  // namespace
}  // namespace viscd::test
