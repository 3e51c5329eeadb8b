// The cpu backend's static set structure (cpu/static_tree.hpp): main tree, delta tree, objects
// taken out of main in place, and the rebuild once enough changed. Long sequences of adds,
// removes and moves on sets large enough to cross the rebuild threshold, each frame checked
// against the reference backend (brute force) given the same operations; queries too.
#include <gtest/gtest.h>

#include <random>

#include "core/backend.hpp"
#include "cpu/cpu_detector.hpp"
#include "test_util.hpp"
#include "viscd/viscd.hpp"

namespace viscd {
namespace {

Box box_at(float x, float y, float z, float s) { return Box{{x, y, z}, {x + s, y + s, z + s}}; }

template <class Shape>
struct Ops {
  std::mt19937_64 rng;
  std::uniform_real_distribution<float> pos{-40.0f, 40.0f}, size{0.2f, 2.0f};
  explicit Ops(std::uint64_t seed) : rng(seed) {}
  Shape make() {
    if constexpr (std::is_same_v<Shape, Sphere>)
      return Sphere{pos(rng), pos(rng), pos(rng), size(rng)};
    else
      return box_at(pos(rng), pos(rng), pos(rng), size(rng));
  }
};

Result<std::uint32_t> add(Detector& d, const Sphere& s, const Filter& f) { return d.add_static_sphere(s, f); }
Result<std::uint32_t> add(Detector& d, const Box& b, const Filter& f) { return d.add_static_box(b, f); }
Status move(Detector& d, std::uint32_t k, const Sphere& s) { return d.move_static_sphere(k, s); }
Status move(Detector& d, std::uint32_t k, const Box& b) { return d.move_static_box(k, b); }
FrameInput frame_of(std::span<const Sphere> s, std::span<const Filter> f) {
  FrameInput in;
  in.spheres = s;
  in.filters = f;
  return in;
}
FrameInput frame_of(std::span<const Box> b, std::span<const Filter> f) {
  FrameInput in;
  in.boxes = b;
  in.filters = f;
  return in;
}

template <class Shape>
void run(std::uint64_t seed, std::size_t statics, std::size_t changes_per_frame, int frames) {
  auto cpu = make_cpu_detector();
  auto ref = make_reference_detector();
  Ops<Shape> ops(seed);
  std::vector<Shape> initial(statics);
  for (Shape& s : initial) s = ops.make();
  const std::vector<Filter> filters = test::random_filters(statics, seed);
  if constexpr (std::is_same_v<Shape, Sphere>) {
    ASSERT_TRUE(cpu->set_static_spheres(initial, filters).ok());
    ASSERT_TRUE(ref->set_static_spheres(initial, filters).ok());
  } else {
    ASSERT_TRUE(cpu->set_static_boxes(initial, filters).ok());
    ASSERT_TRUE(ref->set_static_boxes(initial, filters).ok());
  }
  std::vector<std::uint32_t> live(statics);
  for (std::uint32_t k = 0; k < statics; ++k) live[k] = k;
  std::vector<Shape> moving(1500);
  FrameResult a, b;
  for (int f = 0; f < frames; ++f) {
    SCOPED_TRACE("frame " + std::to_string(f));
    for (std::size_t c = 0; c < changes_per_frame; ++c) {
      const int what = static_cast<int>(ops.rng() % 3);
      if (what == 0 && !live.empty()) {  // remove
        const std::size_t at = ops.rng() % live.size();
        ASSERT_TRUE(cpu->remove_static(live[at]).ok());
        ASSERT_TRUE(ref->remove_static(live[at]).ok());
        live.erase(live.begin() + static_cast<std::ptrdiff_t>(at));
      } else if (what == 1 && !live.empty()) {  // move
        const Shape s = ops.make();
        const std::uint32_t k = live[ops.rng() % live.size()];
        ASSERT_TRUE(move(*cpu, k, s).ok());
        ASSERT_TRUE(move(*ref, k, s).ok());
      } else {  // add
        const Shape s = ops.make();
        const Filter fl = filters[ops.rng() % filters.size()];
        const auto x = add(*cpu, s, fl), y = add(*ref, s, fl);
        ASSERT_TRUE(x.ok() && y.ok());
        ASSERT_EQ(x.value(), y.value());
        live.push_back(x.value());
      }
    }
    for (Shape& s : moving) s = ops.make();
    const std::vector<Filter> mf = test::random_filters(moving.size(), seed + static_cast<std::uint64_t>(f));
    const std::span<const Filter> use = f % 2 ? std::span<const Filter>(mf) : std::span<const Filter>();
    ASSERT_TRUE(cpu->detect(frame_of(std::span<const Shape>(moving), use), a).ok());
    ASSERT_TRUE(ref->detect(frame_of(std::span<const Shape>(moving), use), b).ok());
    EXPECT_TRUE(test::same_pairs(a.pairs, b.pairs));
    EXPECT_EQ(a.state, b.state);
    EXPECT_EQ(a.stats.static_objects, live.size());
    // Queries see the static trees.
    const Ray ray = test::make_ray(ops.pos(ops.rng), 60, ops.pos(ops.rng), 0.01f, -1, 0.02f, 200);
    std::vector<RayHit> ha, hb;
    cpu->ray_cast_all(ray, ha);
    ref->ray_cast_all(ray, hb);
    EXPECT_EQ(ha, hb);
    const Box q = box_at(ops.pos(ops.rng), ops.pos(ops.rng), ops.pos(ops.rng), 6);
    std::vector<std::uint32_t> oa, ob;
    cpu->overlap_box(q, oa);
    ref->overlap_box(q, ob);
    EXPECT_EQ(oa, ob);
  }
}

// The moving tree meets the static one in two ways (cpu/cross_pairs.hpp): a walk per group of 16
// moving buckets, and where a group meets too many static buckets (few movers in a dense static
// world, as here: a group covers a quarter of it; and the huge object) a walk per moving object.
// Both against brute force.
template <class Shape>
void dense_static_world(std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> pos(-20.0f, 20.0f);
  auto make = [&](float size) {
    if constexpr (std::is_same_v<Shape, Sphere>)
      return Sphere{pos(rng), pos(rng), pos(rng), size};
    else
      return box_at(pos(rng), pos(rng), pos(rng), 2 * size);
  };
  std::vector<Shape> fixed(100000), moving(1024);
  for (Shape& f : fixed) f = make(0.05f);
  for (Shape& m : moving) m = make(0.4f);
  auto cpu = make_cpu_detector();
  auto ref = make_reference_detector();
  for (int round = 0; round < 2; ++round) {
    if (round == 1) {  // one huge object: its bucket meets nearly every static bucket
      if constexpr (std::is_same_v<Shape, Sphere>)
        moving[500] = Sphere{0, 0, 0, 15};
      else
        moving[500] = box_at(-15, -15, -15, 30);
    }
    if constexpr (std::is_same_v<Shape, Sphere>) {
      ASSERT_TRUE(cpu->set_static_spheres(fixed).ok());
      ASSERT_TRUE(ref->set_static_spheres(fixed).ok());
    } else {
      ASSERT_TRUE(cpu->set_static_boxes(fixed).ok());
      ASSERT_TRUE(ref->set_static_boxes(fixed).ok());
    }
    FrameResult a, b;
    ASSERT_TRUE(cpu->detect(frame_of(std::span<const Shape>(moving), {}), a).ok());
    ASSERT_TRUE(ref->detect(frame_of(std::span<const Shape>(moving), {}), b).ok());
    EXPECT_GT(b.pairs.size(), round == 0 ? 100u : 10000u);
    EXPECT_TRUE(test::same_pairs(a.pairs, b.pairs)) << "round " << round;
  }
}

TEST(StaticTree, DenseStaticWorldSpheres) { dense_static_world<Sphere>(7); }
TEST(StaticTree, DenseStaticWorldBoxes) { dense_static_world<Box>(8); }

TEST(StaticTree, SpheresAcrossTheRebuildThreshold) { run<Sphere>(1, 20000, 1500, 6); }
TEST(StaticTree, BoxesAcrossTheRebuildThreshold) { run<Box>(2, 20000, 1500, 6); }
TEST(StaticTree, FewChangesStayInDelta) { run<Sphere>(3, 5000, 7, 8); }
TEST(StaticTree, EverythingRemovedThenRefilled) { run<Box>(4, 300, 400, 6); }

}  // namespace
}  // namespace viscd

namespace viscd {
namespace {

// The cpu map with a static set (the static layer kept between frames and merged with the moving
// objects' map) equals the reference's single pass over both, bit for bit, as the camera, the
// set and the moving objects change; pixels, states and pairs follow.
template <class Shape>
void same_maps(std::uint64_t seed) {
  Config c;
  c.lambda = 4;
  c.shade = true;
  c.map_width = 96;
  c.map_height = 64;
  auto cpu = make_cpu_detector(c);
  auto ref = make_reference_detector(c);
  Ops<Shape> ops(seed);
  ops.pos = std::uniform_real_distribution<float>(-12.0f, 12.0f);
  std::vector<Shape> statics(300), moving(200);
  for (Shape& s : statics) s = ops.make();
  if constexpr (std::is_same_v<Shape, Sphere>) {
    ASSERT_TRUE(cpu->set_static_spheres(statics).ok() && ref->set_static_spheres(statics).ok());
  } else {
    ASSERT_TRUE(cpu->set_static_boxes(statics).ok() && ref->set_static_boxes(statics).ok());
  }
  Camera cam;
  cam.eye[2] = 40;
  FrameResult a, b;
  for (int f = 0; f < 6; ++f) {
    SCOPED_TRACE("frame " + std::to_string(f));
    for (Shape& s : moving) s = ops.make();
    if (f == 2) cam.eye[0] = 7;  // the camera moves: the layer is drawn again
    if (f == 4) {                // the set changes: again
      ASSERT_TRUE(cpu->remove_static(3).ok() && ref->remove_static(3).ok());
      ASSERT_TRUE(move(*cpu, 5, moving[0]).ok() && move(*ref, 5, moving[0]).ok());
    }
    FrameInput in = frame_of(std::span<const Shape>(moving), {});
    in.camera = &cam;
    ASSERT_TRUE(cpu->detect(in, a).ok());
    ASSERT_TRUE(ref->detect(in, b).ok());
    const auto& ma = detail::backend_as<detail::PipelineDetector>(*cpu).visibility_map();
    const auto& mb = detail::backend_as<detail::PipelineDetector>(*ref).visibility_map();
    ASSERT_EQ(ma.ids.size(), mb.ids.size());
    std::size_t static_pixels = 0;
    for (std::size_t i = 0; i < ma.ids.size(); ++i) {
      ASSERT_EQ(ma.ids[i], mb.ids[i]) << "pixel " << i;
      ASSERT_EQ(ma.depth[i], mb.depth[i]) << "pixel " << i;
      static_pixels += ma.ids[i] > moving.size();
    }
    EXPECT_GT(static_pixels, 100u);
    EXPECT_EQ(a.pixels, b.pixels);
    EXPECT_EQ(a.state, b.state);
    EXPECT_EQ(a.image, b.image);
    EXPECT_TRUE(test::same_pairs(a.pairs, b.pairs));
  }
}

TEST(StaticLayer, SpheresMapEqualsTheReference) { same_maps<Sphere>(5); }
TEST(StaticLayer, BoxesMapEqualsTheReference) { same_maps<Box>(6); }

// Without an image the cpu backend draws the moving spheres over the static layer's depth (its
// occluder) instead of merging the two maps: the pixel counts must still be those of the
// reference's single pass over both, at every SIMD level, with moving spheres that sit exactly
// on static ones (a tie at every pixel, which goes to the moving sphere), half inside them, and
// in front of and behind them, while the camera and the set change.
void counts_over_the_layer(Simd simd, std::uint64_t seed) {
  Config c;
  c.lambda = 4;
  c.simd = simd;
  c.map_width = 160;  // five tiles and a part one across
  c.map_height = 100;
  auto cpu = make_cpu_detector(c);
  auto ref = make_reference_detector(c);
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> u(-12.0f, 12.0f), r(0.3f, 2.0f);
  std::vector<Sphere> statics(300), moving(240);
  for (Sphere& s : statics) s = {u(rng), u(rng), u(rng) * 0.5f, r(rng)};
  ASSERT_TRUE(cpu->set_static_spheres(statics).ok() && ref->set_static_spheres(statics).ok());
  Camera cam;
  cam.eye[2] = 40;
  FrameResult a, b;
  for (int f = 0; f < 6; ++f) {
    SCOPED_TRACE("frame " + std::to_string(f));
    for (std::size_t k = 0; k < moving.size(); ++k) {
      const Sphere& st = statics[(k * 7 + static_cast<std::size_t>(f)) % statics.size()];
      switch (k % 4) {
        case 0:  // exactly on a static sphere: equal depth at every pixel
          moving[k] = st;
          break;
        case 1:  // half inside one
          moving[k] = {st.x + st.r * 0.5f, st.y, st.z, st.r * 0.8f};
          break;
        case 2:  // just behind one, and larger: its rim shows
          moving[k] = {st.x, st.y, st.z - st.r, st.r * 1.3f};
          break;
        default:
          moving[k] = {u(rng), u(rng), u(rng) * 0.5f, r(rng)};
      }
    }
    if (f == 2) cam.eye[0] = 7;  // the camera moves: the layer is drawn again
    if (f == 4) {                // the set changes: again
      ASSERT_TRUE(cpu->remove_static(3).ok() && ref->remove_static(3).ok());
      ASSERT_TRUE(cpu->move_static_sphere(5, moving[3]).ok() && ref->move_static_sphere(5, moving[3]).ok());
    }
    FrameInput in;
    in.spheres = moving;
    in.camera = &cam;
    ASSERT_TRUE(cpu->detect(in, a).ok());
    ASSERT_TRUE(ref->detect(in, b).ok());
    EXPECT_EQ(a.pixels, b.pixels);
    EXPECT_EQ(a.state, b.state);
    EXPECT_TRUE(test::same_pairs(a.pairs, b.pairs));
    std::size_t hidden = 0;
    for (const float p : b.pixels) hidden += p == 0.0f;
    EXPECT_GT(hidden, 0u) << "some moving sphere should be hidden entirely";
  }
}

TEST(StaticLayer, CountsOverTheLayerEqualTheReference) {
  counts_over_the_layer(Simd::best, 9);
  counts_over_the_layer(Simd::sse2, 9);
}

}  // namespace
}  // namespace viscd

namespace viscd {
namespace {

// The pair cap counts the pairs with static objects too: a frame whose moving pairs fit but whose
// static pairs do not fails with pair_cap, on cpu (its own search) and reference alike.
TEST(StaticTree, PairCapCountsStaticPairs) {
  std::vector<Sphere> moving(40, Sphere{0, 0, 0, 1});                                           // 780 moving pairs
  for (std::size_t k = 0; k < moving.size(); ++k) moving[k].x = static_cast<float>(k) * 10.0f;  // now none
  std::vector<Sphere> statics;
  for (std::size_t k = 0; k < moving.size(); ++k)
    for (int s = 0; s < 25; ++s) statics.push_back({moving[k].x, 0.5f, 0, 1});  // 25 per moving object
  for (const char* name : {"cpu", "reference"}) {
    SCOPED_TRACE(name);
    Config c;
    c.pair_memory_cap = 8 * 999;  // 999 pairs; the frame has 1000
    auto d = make_detector(name, c);
    ASSERT_TRUE(d.ok());
    ASSERT_TRUE(d.value()->set_static_spheres(statics).ok());
    FrameResult out;
    const Status s = d.value()->detect(moving, nullptr, out);
    EXPECT_EQ(s.kind(), ErrorKind::pair_cap) << s.error();
    c.pair_memory_cap = 8 * 1000;
    d.value()->set_config(c);
    ASSERT_TRUE(d.value()->detect(moving, nullptr, out).ok());
    EXPECT_EQ(out.pairs.size(), 1000u);
  }
}

}  // namespace
}  // namespace viscd
