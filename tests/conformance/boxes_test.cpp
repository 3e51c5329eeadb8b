// Conformance, boxes (FrameInput::boxes): every backend, every Morton width and layout, against a
// brute force over the boxes written out here (min_i <= max_j && min_j <= max_i on each axis):
// none to two boxes, touching faces, edges and corners, points, planks far longer than wide,
// boxes inside boxes, one box spanning all, counts around work-group sizes, large coordinates;
// culling with a camera against the reference backend's pixels; queries on boxes; filters and
// hostile boxes.
#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

#include "conformance/conformance.hpp"

namespace viscd::conformance {
namespace {

// The box test, written out independently of the library.
bool oracle_overlap(const Box& a, const Box& b) {
  for (int k = 0; k < 3; ++k)
    if (!(a.min[k] <= b.max[k] && b.min[k] <= a.max[k])) return false;
  return true;
}

std::vector<Pair> oracle_box_pairs(std::span<const Box> b, const std::vector<std::uint32_t>* active = nullptr,
                                   std::span<const Filter> filters = {}) {
  std::vector<std::uint32_t> all;
  if (!active) {
    for (std::uint32_t k = 0; k < b.size(); ++k) all.push_back(k);
    active = &all;
  }
  std::vector<Pair> out;
  for (std::size_t x = 0; x < active->size(); ++x)
    for (std::size_t y = x + 1; y < active->size(); ++y) {
      const std::uint32_t i = (*active)[x], j = (*active)[y];
      if (!oracle_overlap(b[i], b[j])) continue;
      if (!filters.empty() && !((filters[i].group & filters[j].mask) && (filters[j].group & filters[i].mask))) continue;
      out.push_back({i, j});
    }
  return out;
}

Box cube(float x, float y, float z, float half) {
  return Box{{x - half, y - half, z - half}, {x + half, y + half, z + half}};
}

std::vector<Box> random_boxes(std::size_t n, std::uint64_t seed, float half_extent, float smin = 0.1f,
                              float smax = 2.0f) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> c(-half_extent, half_extent), s(smin, smax);
  std::vector<Box> out(n);
  for (Box& b : out)
    for (int k = 0; k < 3; ++k) {
      b.min[k] = c(rng);
      b.max[k] = b.min[k] + s(rng);
    }
  return out;
}

// One frame of boxes on `d`, checked against the oracle: pairs, states, stats.
void check_boxes(Detector& d, FrameResult& frame, std::span<const Box> boxes, const std::string& what) {
  SCOPED_TRACE(std::string(d.name()) + ": " + what + " (N = " + std::to_string(boxes.size()) + ")");
  FrameInput in;
  in.boxes = boxes;
  const Status s = d.detect(in, frame);
  ASSERT_TRUE(s.ok()) << s.error();
  const std::vector<Pair> want = oracle_box_pairs(boxes);
  EXPECT_TRUE(test::same_pairs(frame.pairs, want));
  ASSERT_EQ(frame.state.size(), boxes.size());
  std::vector<ObjectState> state(boxes.size(), ObjectState::free);
  for (const Pair& p : want) state[p.i] = state[p.j] = ObjectState::colliding;
  EXPECT_EQ(frame.state, state);
  EXPECT_EQ(frame.stats.objects, boxes.size());
  EXPECT_EQ(frame.stats.active, boxes.size());
  EXPECT_EQ(frame.stats.pairs, want.size());
  EXPECT_TRUE(frame.pixels.empty());
}

TEST_P(ConformancePairs, BoxesNoneOneTwo) {
  check_boxes(*detector_, frame_, {}, "N = 0");
  check_boxes(*detector_, frame_, std::vector<Box>{cube(1, 2, 3, 1)}, "N = 1");
  check_boxes(*detector_, frame_, std::vector<Box>{cube(0, 0, 0, 0)}, "N = 1, a point");
  check_boxes(*detector_, frame_, std::vector<Box>{cube(0, 0, 0, 1), cube(3, 0, 0, 1)}, "N = 2 apart");
  check_boxes(*detector_, frame_, std::vector<Box>{cube(0, 0, 0, 1), cube(2, 0, 0, 1)}, "N = 2 touching faces");
  check_boxes(*detector_, frame_, std::vector<Box>{cube(0, 0, 0, 1), cube(2, 2, 0, 1)}, "N = 2 touching edges");
  check_boxes(*detector_, frame_, std::vector<Box>{cube(0, 0, 0, 1), cube(2, 2, 2, 1)}, "N = 2 touching corners");
  check_boxes(*detector_, frame_,
              std::vector<Box>{Box{{0, 0, 0}, {1, 1, 1}}, Box{{std::nextafter(1.0f, 2.0f), 0, 0}, {2, 1, 1}}},
              "N = 2 one ulp apart");
  check_boxes(*detector_, frame_, std::vector<Box>{cube(0, 0, 0, 1), cube(1.5f, 0.5f, -0.5f, 1)}, "N = 2 overlapping");
  check_boxes(*detector_, frame_, std::vector<Box>{cube(5, -2, 1, 1), cube(5, -2, 1, 1)}, "N = 2 identical");
  check_boxes(*detector_, frame_, std::vector<Box>{cube(0, 0, 0, 0), cube(0, 0, 0, 0)}, "N = 2 points at one place");
  check_boxes(*detector_, frame_, std::vector<Box>{cube(0, 0, 0, 0), cube(0, 0, 1, 0)}, "N = 2 points apart");
  check_boxes(*detector_, frame_, std::vector<Box>{cube(0, 0, 0, 3), cube(0.5f, 0.5f, 0, 0.1f)},
              "N = 2 one inside the other");
  check_boxes(*detector_, frame_, std::vector<Box>{cube(0, 0, 0, 1), Box{{1, -0.5f, -0.5f}, {1, 0.5f, 0.5f}}},
              "a flat box on a face");
}

TEST_P(ConformancePairs, BoxesTouchingGridOfCubes) {
  // Unit cubes at integer spacing: each touches its 26 neighbours (faces, edges, corners).
  std::vector<Box> b;
  for (int x = 0; x < 8; ++x)
    for (int y = 0; y < 8; ++y)
      for (int z = 0; z < 8; ++z)
        b.push_back(Box{{float(x), float(y), float(z)}, {float(x + 1), float(y + 1), float(z + 1)}});
  check_boxes(*detector_, frame_, b, "touching cubes");
  // Along each axis 8 cells give 7 touching steps; a neighbour is a step of -1, 0 or 1 on each axis.
  const std::uint64_t per_axis_same = 8, per_axis_step = 7;
  const std::uint64_t all =
      (per_axis_same + 2 * per_axis_step) * (per_axis_same + 2 * per_axis_step) * (per_axis_same + 2 * per_axis_step);
  const std::uint64_t self = 8 * 8 * 8;
  EXPECT_EQ(frame_.pairs.size(), (all - self) / 2);
  // Shrunk by a little: no cube touches another.
  for (Box& x : b)
    for (int k = 0; k < 3; ++k) x.min[k] += 0.001f, x.max[k] -= 0.001f;
  check_boxes(*detector_, frame_, b, "cubes a little apart");
  EXPECT_TRUE(frame_.pairs.empty());
}

TEST_P(ConformancePairs, BoxesPlanksPointsNestedAndOneSpanningAll) {
  std::vector<Box> b = random_boxes(700, 3, 50.0f, 0.05f, 1.0f);
  // Planks: long in one axis, thin in the others, crossing the cloud.
  for (int k = 0; k < 30; ++k) {
    Box& p = b[static_cast<std::size_t>(k)];
    const int axis = k % 3;
    for (int a = 0; a < 3; ++a) {
      const float c = -40.0f + 80.0f * float(k) / 30.0f;
      p.min[a] = a == axis ? -50.0f : c;
      p.max[a] = a == axis ? 50.0f : c + 0.01f;
    }
  }
  for (int k = 30; k < 60; ++k) b[static_cast<std::size_t>(k)] = cube(float(k) - 45.0f, 0, 0, 0);  // points
  for (int k = 60; k < 70; ++k) b[static_cast<std::size_t>(k)] = cube(0, 0, 0, float(k - 59));     // nested
  check_boxes(*detector_, frame_, b, "planks, points, nested");
  b[400] = Box{{-1e4f, -1e4f, -1e4f}, {1e4f, 1e4f, 1e4f}};  // spans all
  check_boxes(*detector_, frame_, b, "one box spanning all");
  b.assign(300, cube(3, -1, 2, 0.5f));
  check_boxes(*detector_, frame_, b, "300 identical boxes");
  EXPECT_EQ(frame_.pairs.size(), 300u * 299 / 2);
}

TEST_P(ConformancePairs, BoxesCountsAroundWorkGroupSizes) {
  for (std::size_t n : {15, 16, 17, 255, 256, 257, 1023, 1024, 1025})
    check_boxes(*detector_, frame_, random_boxes(n, n, 12.0f), "random boxes, N = " + std::to_string(n));
}

TEST_P(ConformancePairs, BoxesLargeCoordinates) {
  std::vector<Box> b = random_boxes(200, 9, 1e17f, 1e14f, 1e16f);
  b.push_back(
      Box{{-kMaxCoordinate, -kMaxCoordinate, -kMaxCoordinate}, {kMaxCoordinate, kMaxCoordinate, kMaxCoordinate}});
  b.push_back(Box{{kMaxCoordinate, kMaxCoordinate, kMaxCoordinate}, {kMaxCoordinate, kMaxCoordinate, kMaxCoordinate}});
  check_boxes(*detector_, frame_, b, "coordinates up to 1e18");
}

TEST_P(ConformancePairs, BoxesFramesInARowMoving) {
  std::vector<Box> b = random_boxes(2000, 21, 30.0f);
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<float> step(-0.3f, 0.3f);
  for (int f = 0; f < 6; ++f) {
    check_boxes(*detector_, frame_, b, "moving boxes, frame " + std::to_string(f));
    for (Box& x : b)
      for (int k = 0; k < 3; ++k) {
        const float d = step(rng);
        x.min[k] += d, x.max[k] += d;
      }
  }
}

// ---- frame cases that do not depend on the Morton width ----

TEST_P(ConformanceFrames, BoxesWithFiltersAndEvents) {
  const std::vector<Box> b = random_boxes(600, 4, 10.0f);
  const std::vector<Filter> f = test::random_filters(b.size(), 8);
  Config c = detector_->config();
  c.contact_events = true;
  detector_->set_config(c);
  FrameInput in;
  in.boxes = b;
  in.filters = f;
  FrameResult got;
  ASSERT_TRUE(detector_->detect(in, got).ok());
  EXPECT_TRUE(test::same_pairs(got.pairs, oracle_box_pairs(b, nullptr, f)));
  EXPECT_EQ(got.began, got.pairs);
  // Moved: began and ended against the oracle's set differences.
  std::vector<Box> moved = b;
  for (std::size_t k = 0; k < moved.size(); k += 2)
    for (int a = 0; a < 3; ++a) moved[k].min[a] += 0.7f, moved[k].max[a] += 0.7f;
  in.boxes = moved;
  const std::vector<Pair> before = got.pairs;
  ASSERT_TRUE(detector_->detect(in, got).ok());
  const std::vector<Pair> now = oracle_box_pairs(moved, nullptr, f);
  EXPECT_TRUE(test::same_pairs(got.pairs, now));
  std::vector<Pair> began, ended;
  test::oracle_events(before, now, began, ended);
  EXPECT_EQ(got.began, began);
  EXPECT_EQ(got.ended, ended);
}

TEST_P(ConformanceFrames, BoxesCulledByTheCamera) {
  // Big boxes in front of the camera, some behind it, some off screen, some hidden behind a wall:
  // every object is clearly visible (hundreds of pixels) or not at all, so lambda = 1 culls the
  // same set on every rasterizer.
  std::vector<Box> b;
  for (int k = 0; k < 6; ++k) b.push_back(cube(-5.0f + 2.0f * float(k), 0, 0, 0.8f));  // visible row
  b.push_back(cube(0, 0, 30, 1));                                                      // behind the eye
  b.push_back(cube(200, 0, 0, 1));                                                     // off screen
  b.push_back(Box{{-12, -12, -8.2f}, {12, 12, -8}});                                   // wall behind the row
  b.push_back(cube(0, 0, -10, 1));                                                     // hidden behind the wall
  b.push_back(cube(-3.0f, 0.0f, 0.0f, 0.5f));                                          // inside a visible one? overlaps
  const Camera cam = scene_camera();
  Config c;
  c.lambda = 1.0f;
  c.report_pixels = true;
  detector_->set_config(c);
  auto ref = make_backend("reference", c);
  ASSERT_TRUE(ref.ok());
  FrameInput in;
  in.boxes = b;
  in.camera = &cam;
  FrameResult want, got;
  ASSERT_TRUE(ref.value()->detect(in, want).ok());
  const Status s = detector_->detect(in, got);
  ASSERT_TRUE(s.ok()) << s.error();
  ASSERT_EQ(got.state.size(), b.size());
  std::vector<std::uint32_t> active;
  for (std::uint32_t k = 0; k < b.size(); ++k) {
    const bool visible = want.pixels[k] >= 1.0f;
    if (visible) active.push_back(k);
    EXPECT_EQ(got.state[k] != ObjectState::culled, visible) << "object " << k << " pixels " << want.pixels[k];
    EXPECT_NEAR(got.pixels[k], want.pixels[k], pixel_margin(want.pixels[k])) << "object " << k;
  }
  EXPECT_EQ(want.state[6], ObjectState::culled) << "behind the eye";
  EXPECT_EQ(want.state[7], ObjectState::culled) << "off screen";
  EXPECT_EQ(want.state[9], ObjectState::culled) << "hidden behind the wall";
  EXPECT_NE(want.state[8], ObjectState::culled) << "the wall";
  EXPECT_TRUE(test::same_pairs(got.pairs, oracle_box_pairs(b, &active)));
  EXPECT_TRUE(test::same_pairs(got.pairs, want.pairs));
}

TEST_P(ConformanceFrames, QueriesOnBoxes) {
  const std::vector<Box> b = random_boxes(500, 12, 10.0f);
  FrameInput in;
  in.boxes = b;
  FrameResult got;
  ASSERT_TRUE(detector_->detect(in, got).ok());
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<float> u(-12.0f, 12.0f);
  for (int q = 0; q < 40; ++q) {
    const Ray ray = test::make_ray(u(rng), u(rng), u(rng), u(rng), u(rng), u(rng), q % 2 ? 100.0f : 0.5f);
    std::vector<RayHit> want;
    for (std::uint32_t k = 0; k < b.size(); ++k) {
      float t = 0;
      if (ray_hits_box(ray, b[k], t)) want.push_back({k, t});
    }
    std::sort(want.begin(), want.end(),
              [](const RayHit& x, const RayHit& y) { return x.t < y.t || (x.t == y.t && x.index < y.index); });
    std::vector<RayHit> hits;
    detector_->ray_cast_all(ray, hits);
    EXPECT_EQ(hits, want) << "ray " << q;
    RayHit first;
    EXPECT_EQ(detector_->ray_cast(ray, first), !want.empty());
    if (!want.empty()) EXPECT_EQ(first, want.front());
    const Sphere qs{u(rng), u(rng), u(rng), 1.5f};
    const Box qb = cube(u(rng), u(rng), u(rng), 1.5f);
    std::vector<std::uint32_t> want_s, want_b, got_s, got_b;
    for (std::uint32_t k = 0; k < b.size(); ++k) {
      if (sphere_overlaps_box(qs, b[k])) want_s.push_back(k);
      if (oracle_overlap(qb, b[k])) want_b.push_back(k);
    }
    detector_->overlap(qs, got_s);
    detector_->overlap_box(qb, got_b);
    EXPECT_EQ(got_s, want_s) << "query sphere " << q;
    EXPECT_EQ(got_b, want_b) << "query box " << q;
  }
}

TEST_P(ConformanceFrames, HostileBoxes) {
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  auto refused = [&](Box bad, const std::string& what, const std::string& in_message) {
    std::vector<Box> b = random_boxes(20, 1, 5.0f);
    b[7] = bad;
    FrameInput in;
    in.boxes = b;
    FrameResult out;
    const Status s = detector_->detect(in, out);
    EXPECT_EQ(s.kind(), ErrorKind::invalid_input) << what;
    EXPECT_NE(s.error().find("box 7"), std::string::npos) << what << ": " << s.error();
    EXPECT_NE(s.error().find(in_message), std::string::npos) << what << ": " << s.error();
  };
  refused(Box{{0, 0, 0}, {1, -1, 1}}, "min > max", "miny");
  refused(Box{{nan, 0, 0}, {1, 1, 1}}, "NaN", "minx is not a finite number");
  refused(Box{{0, 0, 0}, {1, 1, inf}}, "infinity", "maxz is not a finite number");
  refused(Box{{0, 0, -2e18f}, {1, 1, 1}}, "beyond the bound", "exceeds the supported 1e18");
  // Spheres and boxes in one frame.
  const std::vector<Sphere> s{{0, 0, 0, 1}};
  const std::vector<Box> b{cube(0, 0, 0, 1)};
  FrameInput in;
  in.spheres = s;
  in.boxes = b;
  FrameResult out;
  const Status both = detector_->detect(in, out);
  EXPECT_EQ(both.kind(), ErrorKind::invalid_input);
  EXPECT_NE(both.error().find("spheres or boxes"), std::string::npos) << both.error();
  // Filters of the wrong count name boxes.
  const std::vector<Filter> f(3);
  in.spheres = {};
  in.filters = f;
  const Status count = detector_->detect(in, out);
  EXPECT_EQ(count.kind(), ErrorKind::invalid_input);
  EXPECT_NE(count.error().find("3 filters for 1 boxes"), std::string::npos) << count.error();
}

}  // namespace
}  // namespace viscd::conformance
