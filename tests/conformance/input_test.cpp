// Conformance, the rest of FrameInput and the queries:
// - filters (every Morton width and layout): pairs against brute force with the filter rule
//   written in test_util.hpp, over the active set;
// - the caller's id map: hand-worked counts, culling and pairs;
// - ray and overlap queries on the last frame against brute-force loops over ray_hits_sphere and
//   spheres_overlap, with and without culling.
// Every backend takes every input.
#include <random>

#include "conformance/conformance.hpp"

namespace viscd::conformance {
namespace {

TEST_P(ConformancePairs, Filters) {
  const Camera cam = scene_camera(15.0f);
  const std::vector<Sphere> cloud = random_cloud(700, 31, 8.0f, 0.2f, 1.0f);
  struct Case {
    std::vector<Sphere> spheres;
    std::vector<Filter> filters;
    const char* what;
  };
  std::vector<Case> cases;
  cases.push_back({cloud, test::random_filters(cloud.size(), 1), "random filters"});
  std::vector<Filter> half(cloud.size());
  for (std::size_t k = 0; k < half.size(); k += 2) half[k] = {2, 0};
  cases.push_back({cloud, half, "half collide with nothing"});
  cases.push_back({cloud, std::vector<Filter>(cloud.size(), Filter{0, ~0u}), "all group 0"});
  cases.push_back({std::vector<Sphere>(64, Sphere{1, 1, 1, 1}), test::random_filters(64, 2), "identical centres"});
  cases.push_back({{}, {}, "N = 0"});
  cases.push_back({{{0, 0, 0, 1}, {2, 0, 0, 1}}, {{1, 2}, {2, 1}}, "N = 2 touching, accepting each other"});
  cases.push_back({{{0, 0, 0, 1}, {2, 0, 0, 1}}, {{1, 2}, {2, 2}}, "N = 2 touching, one-sided"});
  for (const Case& c : cases) {
    for (const Camera* camera : {static_cast<const Camera*>(nullptr), &cam}) {
      SCOPED_TRACE(std::string(c.what) + (camera ? ", with a camera" : ""));
      FrameInput in;
      in.spheres = c.spheres;
      in.filters = c.filters;
      in.camera = camera;
      Config cfg = config();
      cfg.lambda = 40;
      detector_->set_config(cfg);
      const Status st = detector_->detect(in, frame_);
      ASSERT_TRUE(st.ok()) << st.error();
      // The active set as without filters (filters never cull), the pairs filtered.
      Expected want = expect_frame(c.spheres, camera, cfg, true);
      want.pairs = test::oracle_filtered_pairs(c.spheres, c.filters, &want.active);
      want.has_reference = false;  // the reference's pairs above are unfiltered
      check_frame(frame_, c.spheres, camera, cfg, want);
    }
  }
}

TEST_P(ConformanceFrames, CallersIdMap) {
  const std::vector<std::uint32_t> map = {1, 1, 0, 2,  //
                                          1, 1, 0, 2,  //
                                          0, 3, 3, 3};
  const std::vector<Sphere> s = {{0, 0, 0, 1}, {1, 0, 0, 1}, {0, 1, 0, 1}};
  Camera cam;
  cam.width = 8, cam.height = 6;  // 4 screen pixels per map pixel
  Config c;
  c.lambda = 10;
  detector_->set_config(c);
  FrameInput in;
  in.spheres = s;
  in.camera = &cam;
  in.id_map = map;
  in.id_map_width = 4, in.id_map_height = 3;
  FrameResult f;
  const Status st = detector_->detect(in, f);
  ASSERT_TRUE(st.ok()) << st.error();
  EXPECT_EQ(f.pixels, (std::vector<float>{16, 8, 12}));
  EXPECT_EQ(f.pairs, (std::vector<Pair>{{0, 2}}));
  EXPECT_EQ(f.state, (std::vector<ObjectState>{ObjectState::colliding, ObjectState::culled, ObjectState::colliding}));
  EXPECT_DOUBLE_EQ(f.stats.mean_pixels, 12.0);
  // An id beyond N is an error naming the pixel.
  std::vector<std::uint32_t> bad = map;
  bad[6] = 9;
  in.id_map = bad;
  const Status e = detector_->detect(in, f);
  ASSERT_FALSE(e.ok());
  EXPECT_NE(e.error().find("(2, 1)"), std::string::npos) << e.error();
}

// Rays at the scene: random, axis-aligned, from inside objects, aimed and grazing.
std::vector<Ray> some_rays(std::span<const Sphere> s, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> u(-1, 1);
  std::vector<Ray> rays;
  for (int k = 0; k < 150; ++k) {
    Ray r;
    for (int c = 0; c < 3; ++c) r.origin[c] = 14 * u(rng), r.dir[c] = u(rng);
    if (k % 5 == 0) r.dir[k % 3] = 0, r.dir[(k + 1) % 3] = 0, r.dir[(k + 2) % 3] = 1;
    if (k % 7 == 0) r.max_t = 10 * (u(rng) + 1);
    rays.push_back(r);
  }
  for (std::size_t k = 0; k < s.size() && k < 60; ++k) {
    const Sphere& t = s[rng() % s.size()];
    Ray from{{t.x, t.y, t.z}, {u(rng), u(rng), 1}};
    rays.push_back(from);
    Ray graze{{t.x - 20, t.y + t.r, t.z}, {1, 0, 0}};
    rays.push_back(graze);
  }
  return rays;
}

TEST_P(ConformanceFrames, Queries) {
  CameraScene scene = camera_scene(300, 41, 30.0f);
  Config c;
  c.lambda = scene.lambda;
  detector_->set_config(c);
  for (const Camera* camera : {static_cast<const Camera*>(nullptr), static_cast<const Camera*>(&scene.camera)}) {
    SCOPED_TRACE(camera ? "with culling" : "without a camera");
    FrameResult f;
    const Status st = detector_->detect(scene.spheres, camera, f);
    ASSERT_TRUE(st.ok()) << st.error();
    const Expected want = expect_frame(scene.spheres, camera, c, camera != nullptr);
    check_frame(f, scene.spheres, camera, c, want);
    if (camera) {
      ASSERT_LT(want.active.size(), scene.spheres.size());
    }
    std::vector<RayHit> all;
    for (const Ray& r : some_rays(scene.spheres, 5)) {
      const std::vector<RayHit> hits = test::oracle_hits(scene.spheres, r, &want.active);
      detector_->ray_cast_all(r, all);
      ASSERT_EQ(all, hits);
      RayHit h{};
      ASSERT_EQ(detector_->ray_cast(r, h), !hits.empty());
      if (!hits.empty()) {
        ASSERT_EQ(h, hits.front());
      }
    }
    std::mt19937_64 rng(9);
    std::uniform_real_distribution<float> u(-1, 1);
    std::vector<std::uint32_t> idx;
    for (int k = 0; k < 100; ++k) {
      const Sphere q{12 * u(rng), 12 * u(rng), 12 * u(rng), k % 4 == 0 ? 0.0f : 3 * (u(rng) + 1)};
      detector_->overlap(q, idx);
      ASSERT_EQ(idx, test::oracle_overlap(scene.spheres, q, &want.active));
    }
  }
}

}  // namespace
}  // namespace viscd::conformance
