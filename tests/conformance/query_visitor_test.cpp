// Conformance, the queries an engine drives: box overlaps, query filters against the frame's
// filters, and visitors that stop early or shorten the ray, on every backend, against
// brute-force loops written here (over sphere_overlaps_box(), spheres_overlap() and
// ray_hits_sphere(), with the filter rule) over the oracle's active set, with and without
// culling. A closest-hit visitor must find what ray_cast finds.
#include <algorithm>
#include <limits>
#include <random>

#include "conformance/conformance.hpp"

namespace viscd::conformance {
namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();
using test::AllHits;

// The frame as the queries see it: spheres, the active objects (ascending) and filters.
struct Seen {
  std::span<const Sphere> spheres;
  const std::vector<std::uint32_t>& active;
  std::span<const Filter> filters;
  [[nodiscard]] bool passes(std::uint32_t k, const Filter* q) const {
    const Filter f = filters.empty() ? Filter{} : filters[k];
    return q == nullptr || ((q->group & f.mask) != 0 && (f.group & q->mask) != 0);
  }
};

bool by_t_then_index(const RayHit& a, const RayHit& b) { return a.t < b.t || (a.t == b.t && a.index < b.index); }

// Clips the ray to the best hit so far (the smallest positive float at t = 0: ties stay in reach).
struct ClosestHit final : RayVisitor {
  bool found = false;
  RayHit best{};
  float on_hit(const RayHit& h) override {
    if (!found || by_t_then_index(h, best)) best = h, found = true;
    return std::max(best.t, std::numeric_limits<float>::denorm_min());
  }
};

struct StopAfter final : RayVisitor, OverlapVisitor {
  std::size_t limit = 1;
  std::vector<std::uint32_t> seen;
  float on_hit(const RayHit& h) override {
    seen.push_back(h.index);
    return seen.size() >= limit ? 0.0f : kInf;
  }
  bool on_overlap(std::uint32_t index) override {
    seen.push_back(index);
    return seen.size() < limit;
  }
};

// Distinct, and all among `want` (ascending).
bool distinct_subset(std::vector<std::uint32_t> got, const std::vector<std::uint32_t>& want) {
  std::sort(got.begin(), got.end());
  return std::adjacent_find(got.begin(), got.end()) == got.end() &&
         std::includes(want.begin(), want.end(), got.begin(), got.end());
}

void check_queries(Detector& d, const Seen& fr, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> u(-1, 1);
  static constexpr Filter kFilters[] = {{1, 0xFFFFFFFFu}, {2, 2}, {4, 1 | 4}, {0, 0}};
  std::vector<std::uint32_t> got;
  std::vector<RayHit> hits;
  for (int k = 0; k < 80; ++k) {
    SCOPED_TRACE("query " + std::to_string(k));
    const Filter* q = k % 3 == 0 ? nullptr : &kFilters[static_cast<std::size_t>(k) % std::size(kFilters)];
    // A box: ordinary, a point, flat, or around an object.
    const float x = 12 * u(rng), y = 12 * u(rng), z = 12 * u(rng);
    float e[3] = {3 * (u(rng) + 1), 3 * (u(rng) + 1), 3 * (u(rng) + 1)};
    if (k % 5 == 1) e[0] = e[1] = e[2] = 0;
    if (k % 5 == 2) e[1] = 0;
    Box b{{x - e[0], y - e[1], z - e[2]}, {x + e[0], y + e[1], z + e[2]}};
    if (k % 5 == 3 && !fr.active.empty()) {
      const Sphere& t = fr.spheres[fr.active[rng() % fr.active.size()]];
      b = Box{{t.x + t.r, t.y - 1, t.z - 1}, {t.x + t.r + 1, t.y + 1, t.z + 1}};  // touching it
    }
    std::vector<std::uint32_t> want;
    for (const std::uint32_t a : fr.active)
      if (fr.passes(a, q) && sphere_overlaps_box(fr.spheres[a], b)) want.push_back(a);
    d.overlap_box(b, got, q);
    ASSERT_EQ(got, want) << "overlap_box";
    StopAfter all;
    all.limit = std::numeric_limits<std::size_t>::max();
    d.overlap_box(b, all, q);
    std::sort(all.seen.begin(), all.seen.end());
    ASSERT_EQ(all.seen, want) << "overlap_box, a visitor that keeps all";
    StopAfter two;
    two.limit = 2;
    d.overlap_box(b, two, q);
    ASSERT_EQ(two.seen.size(), std::min<std::size_t>(2, want.size())) << "overlap_box, stopped after 2";
    ASSERT_TRUE(distinct_subset(two.seen, want));
    // A sphere with the same filter.
    const Sphere s{x, y, z, k % 4 == 0 ? 0.0f : e[0]};
    want.clear();
    for (const std::uint32_t a : fr.active)
      if (fr.passes(a, q) && spheres_overlap(s, fr.spheres[a])) want.push_back(a);
    d.overlap(s, got, q);
    ASSERT_EQ(got, want) << "overlap";
    StopAfter one;
    d.overlap(s, one, q);
    ASSERT_EQ(one.seen.size(), std::min<std::size_t>(1, want.size())) << "overlap, stopped after 1";
    ASSERT_TRUE(distinct_subset(one.seen, want));
    // A ray from the box's centre, or from far away at an object.
    Ray r{{x, y, z}, {u(rng), u(rng), k % 4 == 1 ? 0.0f : u(rng)}, k % 3 == 2 ? 10 * (u(rng) + 1) : kInf};
    if (k % 4 == 2 && !fr.active.empty()) {
      const Sphere& t = fr.spheres[fr.active[rng() % fr.active.size()]];
      r = Ray{{-30, -30, -30}, {t.x + 30, t.y + 30, t.z + 30}, kInf};
    }
    std::vector<RayHit> want_hits;
    for (const std::uint32_t a : fr.active) {
      float t = 0;
      if (fr.passes(a, q) && ray_hits_sphere(r, fr.spheres[a], t)) want_hits.push_back({a, t});
    }
    std::sort(want_hits.begin(), want_hits.end(), by_t_then_index);
    d.ray_cast_all(r, hits, q);
    ASSERT_EQ(hits, want_hits) << "ray_cast_all";
    RayHit h{};
    ASSERT_EQ(d.ray_cast(r, h, q), !want_hits.empty()) << "ray_cast";
    if (!want_hits.empty()) {
      ASSERT_EQ(h, want_hits.front()) << "ray_cast";
    }
    AllHits every;
    d.ray_cast(r, every, q);
    std::sort(every.hits.begin(), every.hits.end(), by_t_then_index);
    ASSERT_EQ(every.hits, want_hits) << "a ray visitor that keeps all";
    ClosestHit closest;
    d.ray_cast(r, closest, q);
    ASSERT_EQ(closest.found, !want_hits.empty()) << "the closest-hit visitor";
    if (closest.found) {
      ASSERT_EQ(closest.best, h) << "the closest-hit visitor finds what ray_cast finds";
    }
    StopAfter first;
    d.ray_cast(r, first, q);
    ASSERT_EQ(first.seen.size(), std::min<std::size_t>(1, want_hits.size())) << "a ray visitor that stops at once";
  }
}

TEST_P(ConformanceFrames, QueryFiltersBoxesAndVisitors) {
  CameraScene scene = camera_scene(300, 43, 20.0f);
  std::vector<Filter> filters = test::random_filters(scene.spheres.size(), 4);
  for (std::size_t k = 0; k < filters.size(); k += 3) filters[k] = {2, 0};  // pair with nothing
  Config c;
  c.lambda = scene.lambda;
  detector_->set_config(c);
  for (const bool with_filters : {false, true}) {
    for (const Camera* camera : {static_cast<const Camera*>(nullptr), static_cast<const Camera*>(&scene.camera)}) {
      SCOPED_TRACE(std::string(camera ? "with culling" : "without a camera") +
                   (with_filters ? ", frame filters" : ", no frame filters"));
      FrameInput in;
      in.spheres = scene.spheres;
      in.camera = camera;
      if (with_filters) in.filters = filters;
      FrameResult f;
      const Status st = detector_->detect(in, f);
      ASSERT_TRUE(st.ok()) << st.error();
      const Expected want = expect_frame(scene.spheres, camera, c, false);
      if (camera) {
        ASSERT_LT(want.active.size(), scene.spheres.size());
      }
      const std::span<const Filter> fs = with_filters ? std::span<const Filter>(filters) : std::span<const Filter>();
      check_queries(*detector_, Seen{scene.spheres, want.active, fs}, with_filters ? 5 : 6);
      if (HasFatalFailure()) return;
    }
  }
}

TEST_P(ConformanceFrames, QueriesOnTinyAndDegenerateFrames) {
  // N = 0, 1, 2, identical spheres, nested spheres, and a point: every query form agrees with
  // brute force, rays starting inside included.
  const std::vector<std::vector<Sphere>> frames = {
      {},
      {{0, 0, 0, 1}},
      {{0, 0, 0, 1}, {2, 0, 0, 1}},
      std::vector<Sphere>(20, Sphere{1, 1, 1, 2}),
      {{0, 0, 0, 8}, {0, 0, 0, 4}, {0, 0, 0, 0}, {1, 0, 0, 0.5f}, {0, 9, 0, 1e-20f}, {0, -3, 0, 1e6f}},
  };
  for (std::size_t k = 0; k < frames.size(); ++k) {
    SCOPED_TRACE("frame " + std::to_string(k));
    const std::vector<Sphere>& s = frames[k];
    std::vector<Filter> f = test::random_filters(s.size(), k);
    FrameInput in;
    in.spheres = s;
    in.filters = f;
    FrameResult out;
    const Status st = detector_->detect(in, out);
    ASSERT_TRUE(st.ok()) << st.error();
    std::vector<std::uint32_t> active(s.size());
    for (std::uint32_t a = 0; a < s.size(); ++a) active[a] = a;
    check_queries(*detector_, Seen{s, active, f}, 100 + k);
    if (HasFatalFailure()) return;
  }
}

}  // namespace
}  // namespace viscd::conformance
