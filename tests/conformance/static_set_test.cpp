// Conformance, the static set (Detector::set_static_spheres and the rest): every backend against
// an oracle kept here, a map from slot to object: pairs among the moving objects plus each active
// moving object with each static object it overlaps, as {i, static_index(k)}, never two static
// objects; through sequences of adds, removes and moves; with filters, events, queries, a camera
// (static objects never culled, not in mu, occluding), N = 0, spheres and boxes, and the errors.
#include <algorithm>
#include <cmath>
#include <map>
#include <random>

#include "conformance/conformance.hpp"

namespace viscd::conformance {
namespace {

bool passes(const Filter& a, const Filter& b) { return (a.group & b.mask) != 0 && (b.group & a.mask) != 0; }

bool boxes_meet(const Box& a, const Box& b) {
  for (int k = 0; k < 3; ++k)
    if (!(a.min[k] <= b.max[k] && b.min[k] <= a.max[k])) return false;
  return true;
}

// The static set as the oracle sees it: slot -> object and filter.
template <class Shape>
struct Model {
  std::map<std::uint32_t, std::pair<Shape, Filter>> objects;
};

bool meet(const Sphere& a, const Sphere& b) { return spheres_overlap(a, b); }
bool meet(const Box& a, const Box& b) { return boxes_meet(a, b); }

// The frame's pairs by brute force: moving pairs, then moving x static, sorted.
template <class Shape>
std::vector<Pair> oracle(std::span<const Shape> moving, const Model<Shape>& st, std::span<const Filter> filters = {}) {
  std::vector<Pair> out;
  auto filter_of = [&](std::size_t k) { return filters.empty() ? Filter{} : filters[k]; };
  for (std::uint32_t i = 0; i < moving.size(); ++i) {
    for (std::uint32_t j = i + 1; j < moving.size(); ++j)
      if (meet(moving[i], moving[j]) && passes(filter_of(i), filter_of(j))) out.push_back({i, j});
    for (const auto& [slot, o] : st.objects)
      if (meet(moving[i], o.first) && passes(filter_of(i), o.second)) out.push_back({i, static_index(slot)});
  }
  std::sort(out.begin(), out.end());
  return out;
}

std::vector<Sphere> cloud(std::size_t n, std::uint64_t seed, float half, float rmin, float rmax) {
  return random_cloud(n, seed, half, rmin, rmax);
}

std::vector<Box> box_cloud(std::size_t n, std::uint64_t seed, float half, float smin, float smax) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> c(-half, half), s(smin, smax);
  std::vector<Box> out(n);
  for (Box& b : out)
    for (int k = 0; k < 3; ++k) b.min[k] = c(rng), b.max[k] = b.min[k] + s(rng);
  return out;
}

Status add(Detector& d, const Sphere& s, const Filter& f, std::uint32_t& slot) {
  auto r = d.add_static_sphere(s, f);
  if (r) slot = r.value();
  return r.status();
}
Status add(Detector& d, const Box& b, const Filter& f, std::uint32_t& slot) {
  auto r = d.add_static_box(b, f);
  if (r) slot = r.value();
  return r.status();
}
Status move(Detector& d, std::uint32_t k, const Sphere& s) { return d.move_static_sphere(k, s); }
Status move(Detector& d, std::uint32_t k, const Box& b) { return d.move_static_box(k, b); }

FrameInput input_of(std::span<const Sphere> s) {
  FrameInput in;
  in.spheres = s;
  return in;
}
FrameInput input_of(std::span<const Box> b) {
  FrameInput in;
  in.boxes = b;
  return in;
}

// Frames through a sequence of adds, removes and moves of static objects, each checked against the
// oracle, on one detector (so whatever it keeps between frames is tested too).
template <class Shape>
void run_sequence(Detector& d, const std::vector<Shape>& moving_start, const std::vector<Shape>& statics,
                  std::uint64_t seed) {
  std::vector<Shape> moving = moving_start;
  Model<Shape> model;
  std::mt19937_64 rng(seed);
  const std::vector<Filter> fl = test::random_filters(statics.size(), seed + 1);
  std::size_t next = 0;
  // Half the static objects at once, the rest added piecemeal.
  for (; next < statics.size() / 2; ++next) {
    std::uint32_t slot = 0;
    ASSERT_TRUE(add(d, statics[next], fl[next], slot).ok());
    EXPECT_EQ(slot, next) << "an empty set's adds take slots 0, 1, ...";
    model.objects[slot] = {statics[next], fl[next]};
  }
  FrameResult got;
  for (int frame = 0; frame < 8; ++frame) {
    SCOPED_TRACE(std::string(d.name()) + " frame " + std::to_string(frame) + ", " +
                 std::to_string(model.objects.size()) + " static objects");
    // Remove a few, move a few, add a few.
    std::vector<std::uint32_t> slots;
    for (const auto& [slot, o] : model.objects) slots.push_back(slot);
    std::shuffle(slots.begin(), slots.end(), rng);
    for (std::size_t r = 0; r < std::min<std::size_t>(5, slots.size()); ++r) {
      ASSERT_TRUE(d.remove_static(slots[r]).ok());
      model.objects.erase(slots[r]);
    }
    for (std::size_t m = 5; m < std::min<std::size_t>(15, slots.size()); ++m) {
      const Shape& to = statics[(slots[m] * 7 + static_cast<std::size_t>(frame)) % statics.size()];
      ASSERT_TRUE(move(d, slots[m], to).ok());
      model.objects[slots[m]].first = to;
    }
    for (int a = 0; a < 12 && next < statics.size(); ++a, ++next) {
      std::uint32_t slot = 0;
      ASSERT_TRUE(add(d, statics[next], fl[next], slot).ok());
      // The smallest free slot.
      std::uint32_t want = 0;
      while (model.objects.count(want)) ++want;
      EXPECT_EQ(slot, want);
      model.objects[slot] = {statics[next], fl[next]};
    }
    ASSERT_EQ(d.static_count(), model.objects.size());
    FrameInput in = input_of(std::span<const Shape>(moving));
    const Status s = d.detect(in, got);
    ASSERT_TRUE(s.ok()) << s.error();
    const std::vector<Pair> want = oracle(std::span<const Shape>(moving), model);
    EXPECT_TRUE(test::same_pairs(got.pairs, want));
    EXPECT_EQ(got.stats.objects, moving.size());
    EXPECT_EQ(got.stats.static_objects, model.objects.size());
    ASSERT_EQ(got.state.size(), moving.size());
    std::vector<ObjectState> state(moving.size(), ObjectState::free);
    for (const Pair& p : want) state[p.i] = ObjectState::colliding;
    for (const Pair& p : want)
      if (!is_static_index(p.j)) state[p.j] = ObjectState::colliding;
    EXPECT_EQ(got.state, state);
    // The moving objects move too.
    std::shuffle(moving.begin(), moving.end(), rng);
  }
}

TEST_P(ConformanceFrames, StaticSpheresThroughAddsRemovesAndMoves) {
  run_sequence(*detector_, cloud(400, 1, 20.0f, 0.2f, 1.0f), cloud(300, 2, 20.0f, 0.5f, 2.0f), 3);
}

TEST_P(ConformanceFrames, StaticBoxesThroughAddsRemovesAndMoves) {
  run_sequence(*detector_, box_cloud(400, 4, 20.0f, 0.2f, 2.0f), box_cloud(300, 5, 20.0f, 0.5f, 4.0f), 6);
}

TEST_P(ConformanceFrames, StaticSetReplacedWithFilters) {
  const std::vector<Sphere> moving = cloud(500, 7, 15.0f, 0.2f, 1.0f);
  const std::vector<Sphere> statics = cloud(800, 8, 15.0f, 0.1f, 1.5f);
  const std::vector<Filter> mf = test::random_filters(moving.size(), 9), sf = test::random_filters(statics.size(), 10);
  ASSERT_TRUE(detector_->set_static_spheres(statics, sf).ok());
  Model<Sphere> model;
  for (std::uint32_t k = 0; k < statics.size(); ++k) model.objects[k] = {statics[k], sf[k]};
  FrameInput in;
  in.spheres = moving;
  in.filters = mf;
  FrameResult got;
  ASSERT_TRUE(detector_->detect(in, got).ok());
  EXPECT_TRUE(test::same_pairs(got.pairs, oracle<Sphere>(moving, model, mf)));
  // Overlapping static objects never pair, even with no moving object at all.
  const std::vector<Sphere> none;
  ASSERT_TRUE(detector_->detect(none, nullptr, got).ok());
  EXPECT_TRUE(got.pairs.empty());
  EXPECT_EQ(got.stats.static_objects, statics.size());
  detector_->clear_static();
  EXPECT_EQ(detector_->static_count(), 0u);
  ASSERT_TRUE(detector_->detect(moving, nullptr, got).ok());
  EXPECT_TRUE(test::same_pairs(got.pairs, test::oracle_pairs(moving)));
}

TEST_P(ConformanceFrames, StaticPairsInEventsAndQueries) {
  Config c = detector_->config();
  c.contact_events = true;
  detector_->set_config(c);
  const std::vector<Box> wall{Box{{-10, -1, -10}, {10, 0, 10}}, Box{{20, 0, 0}, {21, 5, 1}}};
  ASSERT_TRUE(detector_->set_static_boxes(wall).ok());
  std::vector<Box> bodies{Box{{0, 0, 0}, {1, 1, 1}}, Box{{0, 3, 0}, {1, 4, 1}}};  // one resting on the floor
  FrameInput in;
  in.boxes = bodies;
  FrameResult got;
  ASSERT_TRUE(detector_->detect(in, got).ok());
  EXPECT_EQ(got.pairs, (std::vector<Pair>{{0, static_index(0)}}));
  EXPECT_EQ(got.began, got.pairs);
  bodies[1] = Box{{0, -0.5f, 2}, {1, 0.5f, 3}};  // falls into the floor
  bodies[0] = Box{{0, 0.5f, 0}, {1, 1.5f, 1}};   // bounces off it
  ASSERT_TRUE(detector_->detect(in, got).ok());
  EXPECT_EQ(got.pairs, (std::vector<Pair>{{1, static_index(0)}}));
  EXPECT_EQ(got.began, (std::vector<Pair>{{1, static_index(0)}}));
  EXPECT_EQ(got.ended, (std::vector<Pair>{{0, static_index(0)}}));
  // Queries see static objects under their static index.
  RayHit hit;
  ASSERT_TRUE(detector_->ray_cast(test::make_ray(20.5f, 10, 0.5f, 0, -1, 0), hit));
  EXPECT_EQ(hit.index, static_index(1));
  EXPECT_EQ(hit.t, 5.0f);
  std::vector<std::uint32_t> found;
  detector_->overlap_box(Box{{0.2f, -0.2f, 2.2f}, {0.3f, 0.1f, 2.3f}}, found);
  EXPECT_EQ(found, (std::vector<std::uint32_t>{1, static_index(0)}));
  // Moving the wall out of the way ends the pair.
  ASSERT_TRUE(detector_->move_static_box(0, Box{{-10, -20, -10}, {10, -19, 10}}).ok());
  ASSERT_TRUE(detector_->detect(in, got).ok());
  EXPECT_TRUE(got.pairs.empty());
  EXPECT_EQ(got.ended, (std::vector<Pair>{{1, static_index(0)}}));
}

TEST_P(ConformanceFrames, StaticObjectsOccludeAndAreNeverCulled) {
  // A row of spheres, and behind it a second row hidden by a static wall; a static object off
  // screen. The hidden row is culled, the static ones are not, and mu counts the moving objects.
  std::vector<Sphere> moving;
  for (int k = 0; k < 5; ++k) moving.push_back({-4.0f + 2.0f * float(k), 0, 0, 0.8f});
  for (int k = 0; k < 5; ++k) moving.push_back({-4.0f + 2.0f * float(k), 0, -12, 0.8f});
  const std::vector<Sphere> statics{{0, 0, -8, 6}, {300, 0, 0, 1}};  // the wall (a big sphere), off screen
  ASSERT_TRUE(detector_->set_static_spheres(statics).ok());
  moving.push_back({300, 0, 1.5f, 1});  // off screen, touching the off-screen static object
  const Camera cam = scene_camera();
  Config c;
  c.lambda = 1.0f;
  detector_->set_config(c);
  FrameResult got;
  const Status s = detector_->detect(moving, &cam, got);
  ASSERT_TRUE(s.ok()) << s.error();
  ASSERT_EQ(got.pixels.size(), moving.size());
  for (int k = 0; k < 5; ++k) {
    EXPECT_GT(got.pixels[static_cast<std::size_t>(k)], 30.0f) << "front row " << k;
    EXPECT_EQ(got.pixels[static_cast<std::size_t>(5 + k)], 0.0f) << "hidden row " << k;
    EXPECT_EQ(got.state[static_cast<std::size_t>(5 + k)], ObjectState::culled);
  }
  EXPECT_EQ(got.state[10], ObjectState::culled);
  // mu over the 11 moving objects only.
  double sum = 0;
  for (float p : got.pixels) sum += p;
  EXPECT_NEAR(got.stats.mean_pixels, sum / 11.0, 1e-6 * sum);
  // The culled object pairs with nothing; the active front row pairs with nothing either.
  EXPECT_TRUE(got.pairs.empty());
  // Always-active: the off-screen object now pairs with the static one it touches.
  std::vector<std::uint8_t> flags(moving.size(), 0);
  flags[10] = 1;
  FrameInput in;
  in.spheres = moving;
  in.camera = &cam;
  in.always_active = flags;
  ASSERT_TRUE(detector_->detect(in, got).ok());
  EXPECT_EQ(got.pairs, (std::vector<Pair>{{10, static_index(1)}}));
}

TEST_P(ConformanceFrames, StaticSetErrors) {
  ASSERT_TRUE(detector_->add_static_sphere({0, 0, 0, 1}).ok());
  // A box into a sphere set; a frame of boxes against it.
  const auto wrong = detector_->add_static_box(Box{{0, 0, 0}, {1, 1, 1}});
  EXPECT_EQ(wrong.kind(), ErrorKind::invalid_input);
  EXPECT_NE(wrong.error().find("holds spheres"), std::string::npos) << wrong.error();
  const std::vector<Box> b{Box{{0, 0, 0}, {1, 1, 1}}};
  FrameInput in;
  in.boxes = b;
  FrameResult out;
  const Status kind = detector_->detect(in, out);
  EXPECT_EQ(kind.kind(), ErrorKind::invalid_input);
  EXPECT_NE(kind.error().find("static set holds spheres"), std::string::npos) << kind.error();
  // Unknown slots, bad shapes: refused, nothing changed.
  EXPECT_EQ(detector_->remove_static(5).kind(), ErrorKind::invalid_input);
  EXPECT_EQ(detector_->move_static_sphere(1, {0, 0, 0, 1}).kind(), ErrorKind::invalid_input);
  const Status nan = detector_->move_static_sphere(0, {std::nanf(""), 0, 0, 1});
  EXPECT_EQ(nan.kind(), ErrorKind::invalid_input);
  EXPECT_EQ(nan.error(), "static sphere: x is not a finite number");
  const auto negative = detector_->add_static_sphere({0, 0, 0, -1});
  EXPECT_EQ(negative.kind(), ErrorKind::invalid_input);
  EXPECT_EQ(negative.error(), "static sphere: negative radius " + std::to_string(-1.0f));
  const std::vector<Sphere> two{{0, 0, 0, 1}, {1, 0, 0, 1}};
  const std::vector<Filter> one(1);
  EXPECT_EQ(detector_->set_static_spheres(two, one).kind(), ErrorKind::invalid_input);
  EXPECT_EQ(detector_->static_count(), 1u);
  // Removed and empty: the set takes boxes again.
  ASSERT_TRUE(detector_->remove_static(0).ok());
  ASSERT_TRUE(detector_->add_static_box(Box{{0, 0, 0}, {1, 1, 1}}).ok());
  EXPECT_EQ(detector_->static_kind(), ShapeKind::box);
  const Status flipped = detector_->move_static_box(0, Box{{0, 2, 0}, {1, 1, 1}});
  EXPECT_EQ(flipped.error(), "static box: miny = " + std::to_string(2.0f) + " exceeds maxy = " + std::to_string(1.0f));
  ASSERT_TRUE(detector_->detect(in, out).ok());
  EXPECT_EQ(out.pairs, (std::vector<Pair>{{0, static_index(0)}}));
}

}  // namespace
}  // namespace viscd::conformance
