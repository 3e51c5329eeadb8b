// The gl backend's default mode (GlOptions::sync_layout = false): m, the Morton layout and the
// quantisation bounds come from the previous frame and every pass after culling reads the
// active count on the GPU. Pairs must stay exact in every situation where the previous frame's
// values are stale: moving scenes, objects jumping far outside the previous bounds, N changing,
// culling toggling, zero and one active objects, pair-buffer overflow.
#include <algorithm>

#include "cpu/brute_force.hpp"
#include "gl_test_util.hpp"

namespace viscd::test {
namespace {

Config map_config(bool culling = true, float lambda = 200.0f) {
  Config cfg;
  cfg.lambda = lambda;
  cfg.map_width = 256;
  cfg.map_height = 144;
  cfg.culling = culling;
  return cfg;
}

std::vector<std::uint32_t> active_of(const FrameResult& r) {
  std::vector<std::uint32_t> a;
  for (std::uint32_t k = 0; k < r.state.size(); ++k)
    if (r.state[k] != ObjectState::culled) a.push_back(k);
  return a;
}

// The reference detector's pairs over the gl frame's own active set (the active set itself
// comes from the GPU id map, which may differ from the cpu rasterizer's by a few silhouette
// pixels): run on the active spheres alone, then mapped back to object indices.
std::vector<Pair> reference_pairs(std::span<const Sphere> spheres, const std::vector<std::uint32_t>& active) {
  std::vector<Sphere> sub;
  sub.reserve(active.size());
  for (std::uint32_t k : active) sub.push_back(spheres[k]);
  auto ref = make_reference_detector(Config{.culling = false});
  FrameResult r;
  EXPECT_TRUE(ref->detect(sub, nullptr, r).ok());
  std::vector<Pair> pairs;
  for (const Pair& p : r.pairs) pairs.push_back({active[p.i], active[p.j]});
  std::sort(pairs.begin(), pairs.end(),
            [](const Pair& a, const Pair& b) { return a.i != b.i ? a.i < b.i : a.j < b.j; });
  return pairs;
}

// One frame through gl, checked against the reference (and brute force) over its active set.
void check_frame(test::GlUnderTest& gl, std::span<const Sphere> spheres, const Camera* cam, FrameResult& out,
                 const std::string& what) {
  SCOPED_TRACE(what);
  const Status s = gl.detect(spheres, cam, out);
  ASSERT_TRUE(s.ok()) << s.error();
  const std::vector<std::uint32_t> active = active_of(out);
  ASSERT_EQ(active.size(), out.stats.active);
  if (!cam) {
    ASSERT_EQ(active.size(), spheres.size());
  }
  const std::vector<Pair> ref = reference_pairs(spheres, active);
  EXPECT_EQ(out.pairs.size(), ref.size());
  ASSERT_TRUE(out.pairs == ref) << "pairs differ from the reference";
  std::vector<Pair> brute;
  detail::brute_force_pairs(spheres, active, brute);
  ASSERT_TRUE(out.pairs == brute);
  EXPECT_EQ(out.stats.pairs, ref.size());
  for (const Pair& p : out.pairs) {
    ASSERT_EQ(out.state[p.i], ObjectState::colliding);
    ASSERT_EQ(out.state[p.j], ObjectState::colliding);
  }
}

TEST(GlDefaultMode, MovingRingWithCameraAndCullingEveryFrame) {
  VISCD_GL_OR_SKIP(gl, map_config(true, 4.0f));  // a 256 x 144 screen: small lambda keeps some active
  SceneParams p;
  p.objects = 3000;
  p.seed = 17;
  Scene scene = Scene::make(p);
  const Camera cam = small_camera(scene, "orbit");
  const std::uint64_t waits0 = gl->inspect().mid_frame_waits();
  FrameResult out;
  for (int f = 0; f < 10; ++f) {
    scene.step(1.0f / 60.0f);
    check_frame(*gl, scene.spheres(), &cam, out, "frame " + std::to_string(f));
    if (HasFatalFailure()) return;
    EXPECT_GT(out.stats.active, 0u);
    EXPECT_LT(out.stats.active, 3000u);  // culling did cull
  }
  // At most the first frame waited mid-frame (another test may have left the same N behind).
  EXPECT_LE(gl->inspect().mid_frame_waits() - waits0, 1u);
}

TEST(GlDefaultMode, LayoutIsThePreviousFramesAndReportedAsUsed) {
  VISCD_GL_OR_SKIP(gl);
  const std::vector<Sphere> a = random_spheres_by_edge(1200, 40.0f, 0.2f, 1.0f, 1);
  std::vector<Sphere> b = random_spheres_by_edge(1200, 40.0f, 0.2f, 1.0f, 2);
  for (Sphere& s : b) s.y *= 0.05f;  // flat in y: a different layout
  auto ref = make_reference_detector();
  FrameResult ra, rb, g;
  ASSERT_TRUE(ref->detect(a, nullptr, ra).ok());
  ASSERT_TRUE(ref->detect(b, nullptr, rb).ok());
  ASSERT_NE(ra.stats.layout, rb.stats.layout);
  gl->inspect().set_options(GlOptions{.debug = true, .sync_layout = true});
  check_frame(*gl, a, nullptr, g, "a, sync");
  EXPECT_EQ(g.stats.layout, ra.stats.layout);
  gl->inspect().set_options(GlOptions{.debug = true});
  const std::uint64_t waits = gl->inspect().mid_frame_waits();
  check_frame(*gl, b, nullptr, g, "b after a, default");
  EXPECT_EQ(g.stats.layout, ra.stats.layout) << "the default mode uses the previous frame's layout";
  check_frame(*gl, b, nullptr, g, "b after b, default");
  EXPECT_EQ(g.stats.layout, rb.stats.layout);
  EXPECT_EQ(gl->inspect().mid_frame_waits(), waits) << "the default mode waited mid-frame";
}

TEST(GlDefaultMode, ObjectsJumpFarOutsideThePreviousBounds) {
  VISCD_GL_OR_SKIP(gl);
  std::vector<Sphere> s = random_spheres_by_edge(2500, 20.0f, 0.2f, 1.0f, 4);
  FrameResult out;
  check_frame(*gl, s, nullptr, out, "start");
  for (Sphere& x : s) x.x += 1000.0f;  // every centre clamps to the border cell in x
  check_frame(*gl, s, nullptr, out, "all +1000 in x");
  for (std::size_t k = 0; k < s.size(); k += 2) s[k].x -= 2000.0f;  // half on each side
  check_frame(*gl, s, nullptr, out, "half at -1000, half at +1000");
  for (std::size_t k = 0; k < s.size(); ++k)
    s[k] = {1.5f * static_cast<float>(k), 5e4f, -3e4f, s[k].r};  // a line far away
  check_frame(*gl, s, nullptr, out, "a line far away");
  check_frame(*gl, s, nullptr, out, "same again");
}

TEST(GlDefaultMode, ObjectCountChangesBetweenFrames) {
  VISCD_GL_OR_SKIP(gl, map_config());
  for (bool with_camera : {false, true}) {
    for (std::uint32_t n : {2000u, 3000u, 3000u, 0u, 0u, 1u, 1u, 500u, 500u, 500u}) {
      SceneParams p;
      p.objects = n;
      p.seed = n + 1;
      Scene scene = Scene::make(p);
      scene.step(1.0f / 60.0f);
      Camera cam;  // the default camera: looks at the origin from z = 10
      cam.width = 256;
      cam.height = 144;
      FrameResult out;
      check_frame(*gl, scene.spheres(), with_camera ? &cam : nullptr, out,
                  "N = " + std::to_string(n) + (with_camera ? ", camera" : ""));
      if (HasFatalFailure()) return;
    }
  }
}

TEST(GlDefaultMode, ZeroAndOneActiveOfManyObjects) {
  VISCD_GL_OR_SKIP(gl, map_config());
  Camera cam;  // looks down -z from z = 10
  cam.width = 256;
  cam.height = 144;
  std::vector<Sphere> s = random_spheres_by_edge(3000, 10.0f, 0.05f, 0.3f, 8);  // z in [-5, 5]
  FrameResult out;
  check_frame(*gl, s, &cam, out, "all in front");
  std::vector<Sphere> behind = s;
  for (Sphere& x : behind) x.z += 200.0f;  // behind the camera: no pixels, all culled
  check_frame(*gl, behind, &cam, out, "none active");
  EXPECT_EQ(out.stats.active, 0u);
  check_frame(*gl, behind, &cam, out, "none active again");
  std::vector<Sphere> one = behind;
  one[7] = {0, 0, 0, 2.0f};  // one big sphere at the target
  check_frame(*gl, one, &cam, out, "one active");
  EXPECT_EQ(out.stats.active, 1u);
  check_frame(*gl, one, &cam, out, "one active again");
  one[8] = {0.5f, 0, 0, 2.0f};
  check_frame(*gl, one, &cam, out, "two active");
  EXPECT_EQ(out.stats.active, 2u);
  EXPECT_EQ(out.pairs.size(), 1u);
  check_frame(*gl, s, &cam, out, "all in front again");
}

TEST(GlDefaultMode, ActiveCountJumpsBetweenNoneAndAll) {
  // Every pass after culling is sized on the GPU from the active count: frames whose count
  // jumps from 0 to N (across the local-sort limit and several radix tiles) and back, with
  // counts just around work-group multiples between.
  VISCD_GL_OR_SKIP(gl, map_config());
  Camera cam;  // looks down -z from z = 10
  cam.width = 256;
  cam.height = 144;
  const std::vector<Sphere> front = random_spheres_by_edge(4100, 10.0f, 0.05f, 0.3f, 41);
  std::vector<Sphere> behind = front;
  for (Sphere& x : behind) x.z += 200.0f;  // no pixels: all culled
  FrameResult out;
  const auto with_active = [&](std::size_t count) {
    std::vector<Sphere> s = behind;
    std::copy_n(front.begin(), count, s.begin());
    return s;
  };
  // lambda 0.5: an object is active when it covers a map pixel; those behind the camera never do.
  gl->set_config(map_config(true, 0.5f));
  check_frame(*gl, behind, &cam, out, "none (first frame)");
  EXPECT_EQ(out.stats.active, 0u);
  check_frame(*gl, front, &cam, out, "all in front");
  EXPECT_GT(out.stats.active, 1025u);  // beyond the local sort: radix tiles (some are hidden)
  check_frame(*gl, behind, &cam, out, "none again");
  EXPECT_EQ(out.stats.active, 0u);
  for (std::size_t count : {1u, 257u, 1025u, 2049u, 4100u, 0u}) {
    check_frame(*gl, with_active(count), &cam, out, "the first " + std::to_string(count) + " in front");
    EXPECT_LE(out.stats.active, count);
  }
  // Culling off: the active count is N whatever the camera sees; N chosen around the limits
  // (the default mode needs the same N in consecutive frames, so each runs twice).
  gl->set_config(map_config(false));
  for (std::size_t n : {255u, 256u, 257u, 1024u, 1025u, 2049u}) {
    const std::vector<Sphere> s(front.begin(), front.begin() + static_cast<std::ptrdiff_t>(n));
    check_frame(*gl, s, &cam, out, "no culling, n = " + std::to_string(n));
    check_frame(*gl, s, &cam, out, "no culling again, n = " + std::to_string(n));
    EXPECT_EQ(out.stats.active, n);
  }
}

TEST(GlDefaultMode, CullingTogglesEveryFrame) {
  VISCD_GL_OR_SKIP(gl, map_config());
  SceneParams p;
  p.objects = 3000;
  p.seed = 23;
  Scene scene = Scene::make(p);
  const Camera cam = small_camera(scene, "zoom-in");
  FrameResult out;
  for (int f = 0; f < 6; ++f) {
    const bool culling = f % 2 == 0;
    gl->set_config(map_config(culling));
    scene.step(1.0f / 60.0f);
    check_frame(*gl, scene.spheres(), &cam, out, "frame " + std::to_string(f));
    if (HasFatalFailure()) return;
    if (culling)
      EXPECT_LT(out.stats.active, 3000u);
    else
      EXPECT_EQ(out.stats.active, 3000u);
  }
}

TEST(GlDefaultMode, PairBufferOverflowGrowsAndReruns) {
  VISCD_GL_OR_SKIP(gl);  // skips when there is no context at all
  auto fresh = test::GlUnderTest::create(Config{}, GlOptions{.debug = true, .initial_pair_capacity = 16});
  ASSERT_TRUE(fresh.ok()) << fresh.error();
  test::GlUnderTest& d = *fresh.value();
  FrameResult out;
  const std::vector<Sphere> sparse = random_spheres_by_edge(1500, 2000.0f, 0.1f, 0.2f, 31);
  check_frame(d, sparse, nullptr, out, "sparse (sync: first frame)");
  ASSERT_LE(out.pairs.size(), 16u);
  ASSERT_EQ(d.inspect().pair_capacity(), 16u);
  const std::uint64_t waits = d.inspect().mid_frame_waits();
  const std::vector<Sphere> dense = random_spheres_by_edge(1500, 10.0f, 0.3f, 0.8f, 32);
  check_frame(d, dense, nullptr, out, "dense (default mode, overflows)");
  EXPECT_GT(out.pairs.size(), 16u);
  EXPECT_GE(d.inspect().pair_capacity(), out.pairs.size());
  EXPECT_EQ(d.inspect().mid_frame_waits(), waits);
  check_frame(d, dense, nullptr, out, "dense again");
}

}  // namespace
}  // namespace viscd::test
