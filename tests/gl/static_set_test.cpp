// The static set on the gl backend against the reference backend, frame after frame while the
// set changes (adds, removes, moves, clears): pairs reported as static_index(slot), static
// objects never culled, not in mu, occluding in the map, grey in the image, seen by the queries;
// no moving objects at all; static counts around the work-group sizes; filters; the caller's map.
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <string>

#include "cpu/cpu_detector.hpp"
#include "reference_frames.hpp"

namespace viscd::test {
namespace {

// The shared gl detector keeps its static set between tests: every test starts and ends with it
// empty.
class StaticSetScope {
 public:
  explicit StaticSetScope(Detector& d) : d_(d) { d_.clear_static(); }
  ~StaticSetScope() { d_.clear_static(); }
  StaticSetScope(const StaticSetScope&) = delete;
  StaticSetScope& operator=(const StaticSetScope&) = delete;

 private:
  Detector& d_;
};

FrameInput frame_of(std::span<const Sphere> spheres, std::span<const Box> boxes, const Camera* camera) {
  FrameInput in;
  in.spheres = spheres;
  in.boxes = boxes;
  in.camera = camera;
  return in;
}

// The same change to both detectors; the slots they give must agree.
void add_both(Detector& gl, Detector& ref, const Sphere& s, const Filter& f = {}) {
  auto a = gl.add_static_sphere(s, f), b = ref.add_static_sphere(s, f);
  ASSERT_TRUE(a.ok() && b.ok());
  ASSERT_EQ(a.value(), b.value());
}
void add_both(Detector& gl, Detector& ref, const Box& x, const Filter& f = {}) {
  auto a = gl.add_static_box(x, f), b = ref.add_static_box(x, f);
  ASSERT_TRUE(a.ok() && b.ok());
  ASSERT_EQ(a.value(), b.value());
}

// Frames over a moving cloud while the static set changes between them: pairs, states and stats
// equal the reference's, in both layout modes; in the default mode a change of the static set
// alone makes no frame wait mid-frame.
TEST(GlStaticSet, SpheresWithoutCameraWhileTheSetChanges) {
  for (const bool sync : {true, false}) {
    SCOPED_TRACE(sync ? "sync_layout" : "default mode");
    VISCD_GL_OR_SKIP(gl, Config{}, GlOptions{.sync_layout = sync});
    StaticSetScope scope(gl->detector());
    auto ref = make_reference_detector();
    std::vector<Sphere> moving = random_spheres_by_edge(600, 20.0f, 0.2f, 1.0f, 41);
    const std::vector<Sphere> statics = random_spheres_by_edge(120, 22.0f, 0.3f, 2.0f, 42);
    ASSERT_TRUE(gl->detector().set_static_spheres(statics).ok());
    ASSERT_TRUE(ref->set_static_spheres(statics).ok());
    std::uint64_t waits = 0;
    for (int frame = 0; frame < 8; ++frame) {
      SCOPED_TRACE("frame " + std::to_string(frame));
      if (frame == 1) waits = gl->inspect().mid_frame_waits();
      switch (frame) {
        case 1:  // add three, one far away
          add_both(gl->detector(), *ref, Sphere{0, 0, 0, 3});
          add_both(gl->detector(), *ref, Sphere{5, 5, 5, 0.5f});
          add_both(gl->detector(), *ref, Sphere{500, 0, 0, 1});
          break;
        case 2:  // remove two: their slots free
          ASSERT_TRUE(gl->detector().remove_static(3).ok() && ref->remove_static(3).ok());
          ASSERT_TRUE(gl->detector().remove_static(120).ok() && ref->remove_static(120).ok());
          break;
        case 3:  // moves, and an add that takes the smallest free slot
          for (std::uint32_t k : {0u, 7u, 50u, 119u}) {
            const Sphere s{float(k % 7) - 3, 1, -2, 1.5f};
            ASSERT_TRUE(gl->detector().move_static_sphere(k, s).ok() && ref->move_static_sphere(k, s).ok());
          }
          add_both(gl->detector(), *ref, Sphere{-4, 4, 0, 2});
          break;
        case 5:  // empty, then one again
          gl->detector().clear_static();
          ref->clear_static();
          break;
        case 6:
          add_both(gl->detector(), *ref, Sphere{0, 0, 0, 30});  // overlaps every moving object
          break;
        default:
          break;
      }
      for (Sphere& s : moving) s.x += 0.05f;
      FrameResult a, b;
      ASSERT_TRUE(gl->detect(moving, nullptr, a).ok());
      ASSERT_TRUE(ref->detect(moving, nullptr, b).ok());
      EXPECT_TRUE(a.pairs == b.pairs) << a.pairs.size() << " pairs, reference " << b.pairs.size();
      EXPECT_TRUE(a.state == b.state);
      EXPECT_EQ(a.stats.objects, 600u);
      EXPECT_EQ(a.stats.static_objects, b.stats.static_objects);
      EXPECT_EQ(a.stats.static_objects, gl->detector().static_count());
      EXPECT_EQ(a.stats.active, 600u);
      if (sync) {
        EXPECT_EQ(a.stats.layout, b.stats.layout);
      }
      const bool any_static =
          std::any_of(a.pairs.begin(), a.pairs.end(), [](const Pair& p) { return is_static_index(p.j); });
      EXPECT_EQ(any_static, a.stats.static_objects > 0);
    }
    if (!sync) {
      EXPECT_EQ(gl->inspect().mid_frame_waits(), waits);
    }
  }
}

// Static boxes with a camera: a wall hides part of the moving boxes (and is never culled, nor
// counted in mu), a floor under everything, a static box outside the view; the set changes
// between frames.
TEST(GlStaticSet, BoxesWithACameraOccludeAndStayActive) {
  Config cfg;
  cfg.map_width = 256;
  cfg.map_height = 144;
  cfg.lambda = 15;
  for (const bool sync : {true, false}) {
    SCOPED_TRACE(sync ? "sync_layout" : "default mode");
    VISCD_GL_OR_SKIP(gl, cfg, GlOptions{.sync_layout = sync});
    StaticSetScope scope(gl->detector());
    auto ref = make_reference_detector(cfg);
    std::vector<Box> moving = random_boxes(300, 16.0f, 0.2f, 1.5f, 51);
    const std::vector<Box> statics = {make_box(-20, -9, -20, 20, -8, 20),  // floor
                                      make_box(-2, -6, 8.5f, 6, 6, 9),     // wall in front of part of the cloud
                                      make_box(100, 100, 100, 101, 101, 101)};
    ASSERT_TRUE(gl->detector().set_static_boxes(statics).ok());
    ASSERT_TRUE(ref->set_static_boxes(statics).ok());
    const Camera cam = camera_at(2, 3, 30);
    for (int frame = 0; frame < 5; ++frame) {
      SCOPED_TRACE("frame " + std::to_string(frame));
      if (frame == 1) add_both(gl->detector(), *ref, make_box(-8, -8, -1, -7, 8, 1));  // a post through the cloud
      if (frame == 2) {
        ASSERT_TRUE(gl->detector().remove_static(1).ok() && ref->remove_static(1).ok());  // the wall goes
      }
      if (frame == 3) {
        const Box wall = make_box(-8, -6, 8.5f, 0, 6, 9);  // and comes back elsewhere, in slot 1
        add_both(gl->detector(), *ref, wall);
        ASSERT_TRUE(gl->detector().move_static_box(0, make_box(-20, -8.5f, -20, 20, -7.5f, 20)).ok());
        ASSERT_TRUE(ref->move_static_box(0, make_box(-20, -8.5f, -20, 20, -7.5f, 20)).ok());
      }
      for (Box& b : moving) b.min[1] -= 0.3f, b.max[1] -= 0.3f;  // falling onto the floor
      FrameInput in;
      in.boxes = moving;
      in.camera = &cam;
      FrameResult a, b;
      const MapComparison m = compare_with_reference(*gl, *ref, in, a, b, sync);
      std::printf("[gl] static boxes, frame %d: %zu map pixels differ, worst object by %u\n", frame, m.differing_pixels,
                  m.worst_object);
      EXPECT_LT(a.stats.active, 300u);
      EXPECT_EQ(a.stats.static_objects, gl->detector().static_count());
      // Static ids (above N) are in the map: they are drawn.
      const auto ids = gl->inspect().read_id_map();
      EXPECT_TRUE(std::any_of(ids.begin(), ids.end(), [](std::uint32_t id) { return id > 300; }));
    }
  }
}

// Static spheres among a ring hide some of it; both counter modes count every object drawn.
TEST(GlStaticSet, SpheresWithACamera) {
  Config cfg;
  cfg.map_width = 256;
  cfg.map_height = 144;
  cfg.lambda = 40;
  auto ref = make_reference_detector(cfg);
  Scene scene = Scene::make({.objects = 500, .seed = 7});
  const Camera cam = small_camera(scene, "zoom-out");
  const std::vector<Sphere> statics = random_spheres_by_edge(12, 60.0f, 3.0f, 8.0f, 77);
  ASSERT_TRUE(ref->set_static_spheres(statics).ok());
  for (const GlCounter counter : {GlCounter::ssbo, GlCounter::atomic_uint}) {
    SCOPED_TRACE(counter == GlCounter::ssbo ? "ssbo" : "atomic_uint");
    VISCD_GL_OR_SKIP(gl, cfg, GlOptions{.counter = counter, .sync_layout = true});
    StaticSetScope scope(gl->detector());
    ASSERT_TRUE(gl->detector().set_static_spheres(statics).ok());
    FrameResult a, b;
    const MapComparison m = compare_with_reference(*gl, *ref, frame_of(scene.spheres(), {}, &cam), a, b);
    std::printf("[gl] static spheres: %u of 500 active; %zu map pixels differ, worst object by %u\n", a.stats.active,
                m.differing_pixels, m.worst_object);
    EXPECT_GT(a.stats.active, 0u);
    EXPECT_LT(a.stats.active, 500u);
  }
}

// N = 0: only static objects. No pairs, no states, mu 0; they are still drawn.
TEST(GlStaticSet, NoMovingObjects) {
  Config cfg;
  cfg.map_width = 256;
  cfg.map_height = 144;
  VISCD_GL_OR_SKIP(gl, cfg, GlOptions{.sync_layout = true});
  StaticSetScope scope(gl->detector());
  auto ref = make_reference_detector(cfg);
  const Camera cam = camera_at(0, 2, 20);
  for (const bool boxes : {false, true}) {
    SCOPED_TRACE(boxes ? "boxes" : "spheres");
    if (boxes) {
      const std::vector<Box> b = random_boxes(50, 10.0f, 0.5f, 2.0f, 3);
      ASSERT_TRUE(gl->detector().set_static_boxes(b).ok() && ref->set_static_boxes(b).ok());
    } else {
      const std::vector<Sphere> s = random_spheres_by_edge(50, 10.0f, 0.5f, 2.0f, 3);
      ASSERT_TRUE(gl->detector().set_static_spheres(s).ok() && ref->set_static_spheres(s).ok());
    }
    for (const Camera* camera : {static_cast<const Camera*>(nullptr), &cam}) {
      FrameResult a, b;
      (void)compare_with_reference(*gl, *ref, frame_of({}, {}, camera), a, b);
      EXPECT_TRUE(a.pairs.empty());
      EXPECT_TRUE(a.state.empty());
      EXPECT_EQ(a.stats.objects, 0u);
      EXPECT_EQ(a.stats.static_objects, 50u);
      EXPECT_EQ(a.stats.active, 0u);
      EXPECT_EQ(a.stats.mean_pixels, 0.0);
      if (camera) {
        const auto ids = gl->inspect().read_id_map();
        EXPECT_TRUE(std::any_of(ids.begin(), ids.end(), [](std::uint32_t id) { return id > 0; }));
      }
    }
  }
}

TEST(GlStaticSet, CountsAroundWorkGroupSizes) {
  VISCD_GL_OR_SKIP(gl, Config{}, GlOptions{.sync_layout = true});
  StaticSetScope scope(gl->detector());
  auto ref = make_reference_detector();
  for (std::size_t k : {1u, 255u, 256u, 257u, 1023u, 1025u}) {
    for (std::size_t n : {0u, 1u, 10u, 300u}) {
      SCOPED_TRACE("N = " + std::to_string(n) + ", static " + std::to_string(k));
      const std::vector<Box> statics = random_boxes(k, 2.0f * std::cbrt(float(k + n)), 0.3f, 1.2f, unsigned(k));
      const std::vector<Box> moving = random_boxes(n, 2.0f * std::cbrt(float(k + n)), 0.3f, 1.2f, unsigned(n) + 9);
      ASSERT_TRUE(gl->detector().set_static_boxes(statics).ok() && ref->set_static_boxes(statics).ok());
      FrameResult a, b;
      ASSERT_TRUE(gl->detect(frame_of({}, moving, nullptr), a).ok());
      ASSERT_TRUE(ref->detect(frame_of({}, moving, nullptr), b).ok());
      EXPECT_TRUE(a.pairs == b.pairs) << a.pairs.size() << " pairs, reference " << b.pairs.size();
      EXPECT_TRUE(a.state == b.state);
      EXPECT_EQ(a.stats.layout, b.stats.layout);
    }
  }
}

TEST(GlStaticSet, FiltersOfStaticObjects) {
  Config cfg;
  cfg.map_width = 256;
  cfg.map_height = 144;
  cfg.lambda = 10;
  VISCD_GL_OR_SKIP(gl, cfg, GlOptions{.sync_layout = true});
  StaticSetScope scope(gl->detector());
  auto ref = make_reference_detector(cfg);
  const std::vector<Sphere> moving = random_spheres_by_edge(400, 14.0f, 0.3f, 1.0f, 61);
  const std::vector<Sphere> statics = random_spheres_by_edge(60, 14.0f, 0.5f, 2.0f, 62);
  static constexpr Filter kFilters[] = {{1, 0xFFFFFFFFu}, {2, 1}, {4, 2 | 4}, {8, 0}};
  std::vector<Filter> mf(moving.size()), sf(statics.size());
  for (std::size_t k = 0; k < mf.size(); ++k) mf[k] = kFilters[k % 4];
  for (std::size_t k = 0; k < sf.size(); ++k) sf[k] = kFilters[(k + 1) % 4];
  const Camera cam = camera_at(0, 3, 25);
  for (const bool moving_filters : {false, true}) {
    ASSERT_TRUE(gl->detector().set_static_spheres(statics, sf).ok() && ref->set_static_spheres(statics, sf).ok());
    for (const Camera* camera : {static_cast<const Camera*>(nullptr), &cam}) {
      SCOPED_TRACE(std::string(moving_filters ? "moving filters" : "static filters only") + (camera ? ", camera" : ""));
      FrameInput in = frame_of(moving, {}, camera);
      if (moving_filters) in.filters = mf;
      FrameResult a, b;
      (void)compare_with_reference(*gl, *ref, in, a, b);
      EXPECT_TRUE(std::any_of(a.pairs.begin(), a.pairs.end(), [](const Pair& p) { return is_static_index(p.j); }));
      // Queries with a filter see the static objects' filters.
      const Filter q{2, 1};
      std::vector<std::uint32_t> oa, ob;
      gl->detector().overlap(Sphere{0, 0, 0, 5}, oa, &q);
      ref->overlap(Sphere{0, 0, 0, 5}, ob, &q);
      EXPECT_TRUE(oa == ob);
    }
  }
}

// Queries report static objects as static_index(slot), with the set as it was at the frame even
// after it changes.
TEST(GlStaticSet, QueriesSeeTheFramesStaticSet) {
  for (const bool boxes : {false, true}) {
    SCOPED_TRACE(boxes ? "boxes" : "spheres");
    Config cfg;
    cfg.map_width = 256;
    cfg.map_height = 144;
    cfg.lambda = 30;
    VISCD_GL_OR_SKIP(gl, cfg);
    StaticSetScope scope(gl->detector());
    auto ref = make_reference_detector(cfg);
    const std::vector<Box> mb = random_boxes(200, 12.0f, 0.3f, 1.5f, 71), sb = random_boxes(40, 12.0f, 0.5f, 2.0f, 72);
    const std::vector<Sphere> ms = random_spheres_by_edge(200, 12.0f, 0.3f, 1.0f, 71),
                              ss = random_spheres_by_edge(40, 12.0f, 0.5f, 2.0f, 72);
    if (boxes)
      ASSERT_TRUE(gl->detector().set_static_boxes(sb).ok() && ref->set_static_boxes(sb).ok());
    else
      ASSERT_TRUE(gl->detector().set_static_spheres(ss).ok() && ref->set_static_spheres(ss).ok());
    ASSERT_TRUE(gl->detector().remove_static(5).ok() && ref->remove_static(5).ok());  // a hole in the slots
    const Camera cam = camera_at(0, 2, 22);
    FrameInput in = frame_of({}, {}, &cam);
    if (boxes)
      in.boxes = mb;
    else
      in.spheres = ms;
    FrameResult a, b;
    ASSERT_TRUE(gl->detect(in, a).ok());
    ASSERT_TRUE(ref->detect(in, b).ok());
    ASSERT_TRUE(a.state == b.state);
    for (const bool changed : {false, true}) {
      if (changed) {  // after the frame: the queries still see the frame's set
        gl->detector().clear_static();
        ref->clear_static();
      }
      std::mt19937 rng(5);
      std::uniform_real_distribution<float> u(-7.0f, 7.0f);
      bool saw_static = false;
      for (int q = 0; q < 60; ++q) {
        Ray ray;
        ray.origin[0] = u(rng), ray.origin[1] = u(rng), ray.origin[2] = -20;
        ray.dir[0] = u(rng) * 0.02f, ray.dir[1] = u(rng) * 0.02f, ray.dir[2] = 1;
        std::vector<RayHit> ha, hb;
        gl->detector().ray_cast_all(ray, ha);
        ref->ray_cast_all(ray, hb);
        EXPECT_TRUE(ha == hb);
        for (const RayHit& h : ha) saw_static |= is_static_index(h.index);
        RayHit fa, fb;
        ASSERT_EQ(gl->detector().ray_cast(ray, fa), ref->ray_cast(ray, fb));
        EXPECT_EQ(fa, fb);
        const float p[3] = {u(rng), u(rng), u(rng)};  // a box from the origin to p
        const Box query = make_box(std::min(p[0], 0.f), std::min(p[1], 0.f), std::min(p[2], 0.f), std::max(p[0], 0.f),
                                   std::max(p[1], 0.f), std::max(p[2], 0.f));
        std::vector<std::uint32_t> oa, ob;
        gl->detector().overlap_box(query, oa);
        ref->overlap_box(query, ob);
        EXPECT_TRUE(oa == ob);
      }
      EXPECT_TRUE(saw_static);
    }
  }
}

// Static objects are grey in the image; the rest as the cpu backend shades it.
TEST(GlStaticSet, StaticObjectsAreGrey) {
  Config cfg;
  cfg.map_width = 256;
  cfg.map_height = 144;
  cfg.shade = true;
  cfg.lambda = 20;
  VISCD_GL_OR_SKIP(gl, cfg);
  StaticSetScope scope(gl->detector());
  auto cpu = make_cpu_detector(cfg);
  const std::vector<Box> moving = random_boxes(150, 12.0f, 0.3f, 2.0f, 81);
  const std::vector<Box> statics = {make_box(-20, -9, -20, 20, -8, 20), make_box(-3, -3, -3, 3, 3, 3)};
  ASSERT_TRUE(gl->detector().set_static_boxes(statics).ok() && cpu->set_static_boxes(statics).ok());
  const Camera cam = camera_at(3, 6, 25);
  FrameResult a, c;
  ASSERT_TRUE(gl->detect(frame_of({}, moving, &cam), a).ok());
  ASSERT_TRUE(cpu->detect(frame_of({}, moving, &cam), c).ok());
  const auto ids = gl->inspect().read_id_map();
  const auto& cpu_ids = detail::backend_as<detail::CpuDetector>(*cpu).visibility_map().ids;
  std::size_t grey = 0, worst = 0;
  for (std::size_t i = 0; i < ids.size(); ++i) {
    if (ids[i] > moving.size()) {
      ++grey;
      const std::uint8_t* px = &a.image[4 * i];
      // kStaticColour scaled by the light: blue a little above red and green, which are equal.
      EXPECT_EQ(px[0], px[1]) << "pixel " << i;
      EXPECT_GE(px[2], px[0]) << "pixel " << i;
    }
    if (ids[i] != cpu_ids[i]) continue;
    for (int ch = 0; ch < 4; ++ch)
      worst = std::max<std::size_t>(worst, std::abs(int(a.image[4 * i + ch]) - int(c.image[4 * i + ch])));
  }
  EXPECT_GT(grey, 1000u);
  EXPECT_LE(worst, 1u);
}

// The caller's id map holds the moving objects only (static ones as background): counted,
// culled and paired as the reference does.
TEST(GlStaticSet, WithTheCallersMap) {
  VISCD_GL_OR_SKIP(gl);
  StaticSetScope scope(gl->detector());
  auto ref = make_reference_detector();
  const std::vector<Sphere> moving = random_spheres_by_edge(300, 12.0f, 0.3f, 1.0f, 91);
  const std::vector<Sphere> statics = random_spheres_by_edge(30, 12.0f, 0.5f, 2.0f, 92);
  ASSERT_TRUE(gl->detector().set_static_spheres(statics).ok() && ref->set_static_spheres(statics).ok());
  std::vector<std::uint32_t> ids(160 * 90);
  std::mt19937 rng(4);
  for (std::uint32_t& id : ids) id = rng() % 400 < 300 ? static_cast<std::uint32_t>(rng() % 301) : 0u;
  const Camera cam = camera_at(0, 0, 20);
  FrameResult a, b;
  const FrameInput in = id_map_input(moving, &cam, ids, 160, 90);
  ASSERT_TRUE(gl->detect(in, a).ok());
  ASSERT_TRUE(ref->detect(in, b).ok());
  EXPECT_TRUE(a.pixels == b.pixels);
  EXPECT_TRUE(a.state == b.state);
  EXPECT_TRUE(a.pairs == b.pairs);
  // Map pixels scaled to the screen: gl scales the total, the reference sums scaled counts.
  EXPECT_NEAR(a.stats.mean_pixels, b.stats.mean_pixels, 1e-12 * b.stats.mean_pixels);
  EXPECT_EQ(a.stats.static_objects, 30u);
  // An id naming a static object (above N) is an error, as on every backend.
  ids[17] = 301;
  const Status s = gl->detect(id_map_input(moving, &cam, ids, 160, 90), a);
  ASSERT_FALSE(s.ok());
  EXPECT_FALSE(ref->detect(id_map_input(moving, &cam, ids, 160, 90), b).ok());
}

}  // namespace
}  // namespace viscd::test
