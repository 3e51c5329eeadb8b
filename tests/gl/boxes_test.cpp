// Box frames on the gl backend against the reference and cpu backends: stages 5-8 on box proxies
// and boxes (codes, order, tree, leaf boxes, pairs), whole frames without and with a camera (id
// map, pixels, culling, states, pairs), shading, queries, and the degenerate boxes: points,
// touching faces, edges and corners, flat boxes, one box around everything, the camera inside
// boxes and boxes through the near plane, counts around the work-group sizes.
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <numeric>
#include <set>
#include <string>

#include "cpu/brute_force.hpp"
#include "cpu/cpu_detector.hpp"
#include "karras/karras_lbvh.hpp"
#include "reference_frames.hpp"

namespace viscd::test {
namespace {

FrameInput box_frame(const std::vector<Box>& boxes, const Camera* camera = nullptr) {
  FrameInput in;
  in.boxes = boxes;
  in.camera = camera;
  return in;
}

// Unit cubes on an integer grid, g per side: each touches its face, edge and corner neighbours.
std::vector<Box> touching_grid(int g) {
  std::vector<Box> b;
  for (int x = 0; x < g; ++x)
    for (int y = 0; y < g; ++y)
      for (int z = 0; z < g; ++z) {
        const float lo[3] = {float(x), float(y), float(z)};
        Box box;
        for (int k = 0; k < 3; ++k) box.min[k] = lo[k], box.max[k] = lo[k] + 1;
        b.push_back(box);
      }
  return b;
}

// Every pair of boxes_overlap() among all objects.
std::vector<Pair> brute_box_pairs(const std::vector<Box>& boxes) {
  std::vector<Pair> pairs;
  detail::brute_force_pairs(detail::Shapes(boxes), all_of(boxes.size()), pairs);
  return pairs;
}

// Stages 5-8 over boxes: the codes and the order are the cpu's over the same proxies, the leaf
// boxes are the boxes bit for bit, the tree is valid, the pairs are brute force's.
void check_broadphase(GlUnderTest& gl, const std::vector<Box>& boxes, std::span<const std::uint32_t> active, int bits) {
  SCOPED_TRACE("n = " + std::to_string(active.size()) + ", m = " + std::to_string(bits));
  std::vector<Pair> pairs;
  FrameStats stats;
  const Status s = gl.inspect().run_broadphase(detail::Shapes(boxes), active, bits, pairs, stats);
  ASSERT_TRUE(s.ok()) << s.error();
  std::vector<Sphere> proxies(boxes.size());
  std::transform(boxes.begin(), boxes.end(), proxies.begin(), detail::box_proxy);
  detail::KarrasBroadphase cpu;
  std::vector<Pair> unused;
  FrameStats cpu_stats;
  ASSERT_TRUE(cpu.run(proxies, active, bits, Layout::extended, 1, 0, unused, cpu_stats).ok());
  EXPECT_EQ(stats.layout, cpu_stats.layout);
  EXPECT_TRUE(gl.inspect().read_sorted_codes() == cpu.sorted_codes()) << "sorted Morton codes differ";
  const std::vector<std::uint32_t> ids = gl.inspect().read_sorted_ids();
  ASSERT_TRUE(std::equal(ids.begin(), ids.end(), cpu.sorted_objects().begin(), cpu.sorted_objects().end()))
      << "sorted order differs";
  detail::Lbvh tree;
  std::vector<detail::Aabb> leaf_boxes;
  gl.inspect().read_tree(tree, leaf_boxes);
  EXPECT_EQ(detail::validate_lbvh(tree, leaf_boxes), "");
  for (std::size_t p = 0; p < leaf_boxes.size(); ++p) {
    const Box& b = boxes[ids[p]];
    const detail::Aabb& l = leaf_boxes[p];
    ASSERT_TRUE(l.lo.x == b.min[0] && l.lo.y == b.min[1] && l.lo.z == b.min[2] && l.hi.x == b.max[0] &&
                l.hi.y == b.max[1] && l.hi.z == b.max[2])
        << "leaf box " << p << " is not its box";
  }
  std::vector<Pair> brute;
  detail::brute_force_pairs(detail::Shapes(boxes), active, brute);
  EXPECT_TRUE(pairs == brute) << pairs.size() << " pairs, brute force " << brute.size();
  EXPECT_EQ(stats.pairs, brute.size());
}

TEST(GlBoxes, BroadphaseEqualsCpuOrderAndBruteForce) {
  VISCD_GL_OR_SKIP(gl);
  for (std::size_t n : {0u, 1u, 2u, 3u, 255u, 256u, 257u, 1023u, 1024u, 1025u, 2049u}) {
    const std::vector<Box> b = random_boxes(n, 3.0f * std::cbrt(float(n) + 1), 0.1f, 1.5f, static_cast<unsigned>(n));
    for (int bits : {16, 32, 64}) check_broadphase(*gl, b, all_of(n), bits);
  }
  // A partial active set, every other box.
  const std::vector<Box> b = random_boxes(1500, 12.0f, 0.1f, 2.0f, 5);
  std::vector<std::uint32_t> half;
  for (std::uint32_t k = 0; k < b.size(); k += 2) half.push_back(k);
  check_broadphase(*gl, b, half, 32);
}

TEST(GlBoxes, BroadphaseSkipsPairsOfTwoStaticObjects) {
  VISCD_GL_OR_SKIP(gl);
  const std::vector<Box> b = random_boxes(800, 8.0f, 0.2f, 1.5f, 8);
  for (std::uint32_t from : {0u, 1u, 300u, 799u, 800u}) {
    std::vector<Pair> pairs;
    FrameStats stats;
    ASSERT_TRUE(gl->inspect().run_broadphase(detail::Shapes(b), all_of(b.size()), 32, pairs, stats, from).ok());
    std::vector<Pair> brute;
    detail::brute_force_pairs(detail::Shapes(b), all_of(b.size()), brute, SIZE_MAX, {}, from);
    EXPECT_TRUE(pairs == brute) << "static from " << from;
  }
}

TEST(GlBoxes, DegenerateBoxesPairAsTheReference) {
  VISCD_GL_OR_SKIP(gl, Config{}, GlOptions{.sync_layout = true});
  auto ref = make_reference_detector();
  std::vector<std::pair<std::string, std::vector<Box>>> cases;
  cases.emplace_back("touching faces, edges and corners", touching_grid(6));
  // Point boxes: alone, twice at one place, on a face, on an edge, on a corner, inside.
  cases.emplace_back(
      "points", std::vector<Box>{make_box(0, 0, 0, 1, 1, 1), make_box(5, 5, 5, 5, 5, 5), make_box(5, 5, 5, 5, 5, 5),
                                 make_box(1, 0.5f, 0.5f, 1, 0.5f, 0.5f), make_box(1, 1, 0.5f, 1, 1, 0.5f),
                                 make_box(1, 1, 1, 1, 1, 1), make_box(0.5f, 0.5f, 0.5f, 0.5f, 0.5f, 0.5f),
                                 make_box(1, 1, 1.0000001f, 1, 1, 1.0000001f)});
  // Flat boxes (zero thickness) crossing, and one touching another's face.
  cases.emplace_back(
      "flat", std::vector<Box>{make_box(-1, -1, 0, 1, 1, 0), make_box(0, -1, -1, 0, 1, 1), make_box(2, 2, 2, 3, 3, 2),
                               make_box(2, 2, 2, 3, 3, 3), make_box(-3, 0, 0, -2, 0, 0)});
  // One box around everything, and identical boxes.
  std::vector<Box> spanning = random_boxes(600, 40.0f, 0.1f, 1.0f, 4);
  spanning.push_back(make_box(-1e6f, -1e6f, -1e6f, 1e6f, 1e6f, 1e6f));
  spanning.insert(spanning.end(), 5, make_box(3, 3, 3, 4, 4, 4));
  cases.emplace_back("spanning and identical", spanning);
  // Far from the origin, where a box's float bounds are coarse.
  std::vector<Box> far = random_boxes(400, 2e5f, 1.0f, 3e4f, 6);
  for (Box& b : far)
    for (int k = 0; k < 3; ++k) b.min[k] += 1e15f, b.max[k] += 1e15f;
  cases.emplace_back("near 1e15", far);
  for (const auto& [name, boxes] : cases) {
    SCOPED_TRACE(name);
    FrameResult a, b;
    ASSERT_TRUE(gl->detect(box_frame(boxes), a).ok());
    ASSERT_TRUE(ref->detect(box_frame(boxes), b).ok());
    EXPECT_TRUE(a.pairs == b.pairs) << a.pairs.size() << " pairs, reference " << b.pairs.size();
    EXPECT_TRUE(a.pairs == brute_box_pairs(boxes));
    EXPECT_TRUE(a.state == b.state);
    EXPECT_EQ(a.stats.layout, b.stats.layout);
  }
}

TEST(GlBoxes, CountsAroundWorkGroupSizesWithoutCamera) {
  VISCD_GL_OR_SKIP(gl, Config{}, GlOptions{.sync_layout = true});
  auto ref = make_reference_detector();
  for (std::size_t n : {0u, 1u, 2u, 255u, 256u, 257u, 1023u, 1024u, 1025u, 4097u}) {
    const std::vector<Box> b =
        random_boxes(n, 2.5f * std::cbrt(float(n) + 1), 0.2f, 1.2f, static_cast<unsigned>(n) + 1);
    FrameResult a, r;
    ASSERT_TRUE(gl->detect(box_frame(b), a).ok());
    ASSERT_TRUE(ref->detect(box_frame(b), r).ok());
    EXPECT_TRUE(a.pairs == r.pairs) << "n = " << n;
    EXPECT_TRUE(a.state == r.state) << "n = " << n;
    EXPECT_EQ(a.stats.objects, n);
    EXPECT_EQ(a.stats.layout, r.stats.layout);
  }
}

// Whole frames with a camera, both geometry modes (boxes are cubes in both), both layout modes.
TEST(GlBoxes, FramesWithACameraEqualTheReference) {
  Config cfg;
  cfg.map_width = 256;
  cfg.map_height = 144;
  cfg.lambda = 20;
  auto ref = make_reference_detector(cfg);
  const std::vector<Box> cloud = random_boxes(400, 20.0f, 0.1f, 2.5f, 12);
  // The camera at z = 4 looks down -z, its near plane at z = 3.9: a small box through the near
  // plane (seen from its far side) and one through the eye's plane (half behind the camera).
  std::vector<Box> near_plane = cloud;
  near_plane.push_back(make_box(-0.02f, -0.02f, 3.85f, 0.02f, 0.02f, 3.95f));
  near_plane.push_back(make_box(-1, 1.5f, 3, 1, 2.5f, 6));
  // The camera inside a small box: its inside walls fill the map and hide everything.
  std::vector<Box> inside = cloud;
  inside.push_back(make_box(-0.5f, -0.5f, 3.5f, 0.5f, 0.5f, 4.5f));
  // A big box around the camera and part of the cloud: its far walls hide the rest.
  std::vector<Box> room = cloud;
  room.push_back(make_box(-6, -6, -6, 6, 6, 30));
  // Far away, most boxes below a pixel: the cube's margin must still cover their pixels.
  const Camera outside = camera_at(0, 8, 30), near = camera_at(0, 0, 4), far_cam = camera_at(250, 120, 300);
  struct Case {
    const char* name;
    const std::vector<Box>* boxes;
    const Camera* camera;
  };
  for (const Case& c :
       {Case{"outside", &cloud, &outside}, Case{"near plane", &near_plane, &near}, Case{"inside a box", &inside, &near},
        Case{"room", &room, &near}, Case{"far away", &cloud, &far_cam}}) {
    const FrameInput in = box_frame(*c.boxes, c.camera);
    const ReferenceFrame r = run_reference(*ref, in);
    for (GlGeometry geometry : {GlGeometry::impostor, GlGeometry::mesh, GlGeometry::splat}) {  // boxes: cubes in all
      for (bool sync : {true, false}) {
        SCOPED_TRACE(std::string(c.name) + (geometry == GlGeometry::mesh ? ", mesh" : ", impostor") +
                     (sync ? ", sync" : ", default"));
        VISCD_GL_OR_SKIP(gl, cfg, GlOptions{.geometry = geometry, .sync_layout = sync});
        FrameResult a;
        const MapComparison m = compare_with_reference(*gl, *ref, in, a, r, sync);
        std::printf("[gl] boxes, %s: %u of %zu active, %zu pairs; %zu map pixels differ, worst object by %u\n", c.name,
                    a.stats.active, c.boxes->size(), a.pairs.size(), m.differing_pixels, m.worst_object);
      }
    }
  }
}

TEST(GlBoxes, CullingAroundWorkGroupSizes) {
  Config cfg;
  cfg.map_width = 256;
  cfg.map_height = 144;
  cfg.lambda = 4;
  VISCD_GL_OR_SKIP(gl, cfg, GlOptions{.sync_layout = true});
  auto ref = make_cpu_detector(cfg);  // the cpu backend draws boxes bit for bit as the reference
  const Camera cam = camera_at(0, 10, 40);
  for (std::size_t n : {255u, 256u, 257u, 1023u, 1025u}) {
    SCOPED_TRACE("n = " + std::to_string(n));
    const std::vector<Box> b = random_boxes(n, 25.0f, 0.1f, 1.0f, static_cast<unsigned>(n));
    FrameResult a, r;
    (void)compare_with_reference(*gl, *ref, box_frame(b, &cam), a, r);
  }
}

// The shaded image equals the cpu backend's where the maps agree (within 1 per channel: the
// shading's float operations may round apart), lit faces differ by face.
TEST(GlBoxes, ShadedFacesAsTheCpuBackend) {
  Config cfg;
  cfg.map_width = 256;
  cfg.map_height = 144;
  cfg.shade = true;
  cfg.lambda = 30;
  VISCD_GL_OR_SKIP(gl, cfg);
  auto cpu = make_cpu_detector(cfg);
  const std::vector<Box> b = random_boxes(300, 20.0f, 0.5f, 3.0f, 31);
  const Camera cam = camera_at(10, 14, 30);
  FrameResult a, c;
  ASSERT_TRUE(gl->detect(box_frame(b, &cam), a).ok());
  ASSERT_TRUE(cpu->detect(box_frame(b, &cam), c).ok());
  ASSERT_EQ(a.image.size(), c.image.size());
  const auto ids = gl->inspect().read_id_map();
  const auto& cpu_ids = detail::backend_as<detail::CpuDetector>(*cpu).visibility_map().ids;
  std::size_t compared = 0, worst = 0;
  for (std::size_t i = 0; i < ids.size(); ++i) {
    if (ids[i] != cpu_ids[i]) continue;
    ++compared;
    for (int ch = 0; ch < 4; ++ch)
      worst = std::max<std::size_t>(worst, std::abs(int(a.image[4 * i + ch]) - int(c.image[4 * i + ch])));
  }
  EXPECT_GT(compared, ids.size() * 9 / 10);
  EXPECT_LE(worst, 1u);
  std::set<std::uint32_t> colours;
  for (std::size_t i = 0; i < ids.size(); ++i)
    if (ids[i]) colours.insert(a.image[4 * i] | a.image[4 * i + 1] << 8 | a.image[4 * i + 2] << 16);
  EXPECT_GE(colours.size(), 6u) << "faces of three states in different light";
}

TEST(GlBoxes, QueriesSeeTheActiveBoxes) {
  Config cfg;
  cfg.map_width = 256;
  cfg.map_height = 144;
  cfg.lambda = 30;
  VISCD_GL_OR_SKIP(gl, cfg);
  auto ref = make_reference_detector(cfg);
  const std::vector<Box> b = random_boxes(300, 15.0f, 0.2f, 2.0f, 17);
  const Camera cam = camera_at(0, 5, 25);
  for (const Camera* camera : {static_cast<const Camera*>(nullptr), &cam}) {
    FrameResult a, r;
    ASSERT_TRUE(gl->detect(box_frame(b, camera), a).ok());
    ASSERT_TRUE(ref->detect(box_frame(b, camera), r).ok());
    ASSERT_TRUE(a.state == r.state);
    std::mt19937 rng(3);
    std::uniform_real_distribution<float> u(-8.0f, 8.0f);
    for (int q = 0; q < 40; ++q) {
      Ray ray;
      ray.origin[0] = u(rng), ray.origin[1] = u(rng), ray.origin[2] = 20;
      ray.dir[0] = u(rng) * 0.05f, ray.dir[1] = u(rng) * 0.05f, ray.dir[2] = -1;
      RayHit ha, hr;
      ASSERT_EQ(gl->detector().ray_cast(ray, ha), ref->ray_cast(ray, hr));
      EXPECT_EQ(ha, hr);
      std::vector<RayHit> all_a, all_r;
      gl->detector().ray_cast_all(ray, all_a);
      ref->ray_cast_all(ray, all_r);
      EXPECT_TRUE(all_a == all_r);
      const Sphere s{u(rng), u(rng), u(rng), 1.5f};
      std::vector<std::uint32_t> oa, orr;
      gl->detector().overlap(s, oa);
      ref->overlap(s, orr);
      EXPECT_TRUE(oa == orr);
      const Box qb = make_box(s.x, s.y, s.z, s.x + 2, s.y + 1, s.z + 0.0f);
      gl->detector().overlap_box(qb, oa);
      ref->overlap_box(qb, orr);
      EXPECT_TRUE(oa == orr);
    }
  }
}

}  // namespace
}  // namespace viscd::test
