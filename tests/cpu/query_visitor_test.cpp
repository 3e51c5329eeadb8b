// Box overlaps, query filters and query visitors on the last frame: the cpu backend's trees (the
// main tree and the tree of the objects the frame's filters left out of it) and the reference
// backend's brute force, against brute-force loops written here over sphere_overlaps_box(),
// spheres_overlap() and ray_hits_sphere() with the filter rule, on random and degenerate scenes.
// The sphere-box test itself is checked by hand-worked cases and against long double.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <initializer_list>
#include <limits>
#include <random>
#include <set>

#include "test_util.hpp"

namespace viscd {
namespace {

using test::AllHits;
using test::describe;
using test::kInf;
using test::make_box;
using test::make_ray;
constexpr float kNan = std::numeric_limits<float>::quiet_NaN();

// ---- the oracles: loops over every object of the frame ----

// What a query sees of the last frame: its spheres, the active objects (null: all) and the
// frame's filters (empty: Filter{} each).
struct Frame {
  std::span<const Sphere> spheres;
  const std::vector<std::uint32_t>* active = nullptr;
  std::span<const Filter> filters;
  [[nodiscard]] bool seen(std::uint32_t k, const Filter* q) const {
    if (active && !std::binary_search(active->begin(), active->end(), k)) return false;
    const Filter f = filters.empty() ? Filter{} : filters[k];
    return q == nullptr || ((q->group & f.mask) != 0 && (f.group & q->mask) != 0);
  }
};

std::vector<RayHit> oracle_hits(const Frame& fr, const Ray& r, const Filter* q) {
  std::vector<RayHit> out;
  for (std::uint32_t k = 0; k < fr.spheres.size(); ++k) {
    float t = 0;
    if (fr.seen(k, q) && ray_hits_sphere(r, fr.spheres[k], t)) out.push_back({k, t});
  }
  std::sort(out.begin(), out.end(),
            [](const RayHit& a, const RayHit& b) { return a.t < b.t || (a.t == b.t && a.index < b.index); });
  return out;
}

std::vector<std::uint32_t> oracle_sphere(const Frame& fr, const Sphere& s, const Filter* q) {
  std::vector<std::uint32_t> out;
  for (std::uint32_t k = 0; k < fr.spheres.size(); ++k)
    if (fr.seen(k, q) && spheres_overlap(s, fr.spheres[k])) out.push_back(k);
  return out;
}

std::vector<std::uint32_t> oracle_box(const Frame& fr, const Box& b, const Filter* q) {
  std::vector<std::uint32_t> out;
  for (std::uint32_t k = 0; k < fr.spheres.size(); ++k)
    if (fr.seen(k, q) && sphere_overlaps_box(fr.spheres[k], b)) out.push_back(k);
  return out;
}

// ---- visitors ----

// The closest hit, ties to the smaller index: clips the ray to each better hit (the smallest
// positive float at t = 0, so that ties at t = 0 are still seen). Checks every call against the
// max t it set.
struct ClosestHit final : RayVisitor {
  bool found = false;
  RayHit best{};
  float max_t = kInf;
  int calls = 0;
  bool over_max = false;
  float on_hit(const RayHit& h) override {
    ++calls;
    over_max |= h.t > max_t;
    if (!found || h.t < best.t || (h.t == best.t && h.index < best.index)) best = h, found = true;
    max_t = std::max(best.t, std::numeric_limits<float>::denorm_min());
    return max_t;
  }
};

// Stops after `limit` hits (0 returned at the limit-th).
struct FirstHits final : RayVisitor {
  std::size_t limit = 1;
  std::vector<RayHit> hits;
  float on_hit(const RayHit& h) override {
    hits.push_back(h);
    return hits.size() >= limit ? 0.0f : kInf;
  }
};

// Ignores (returns -1 for) odd indices, keeps the others; the odd ones must still be offered.
struct IgnoreOdd final : RayVisitor {
  std::vector<RayHit> kept, ignored;
  float on_hit(const RayHit& h) override {
    (h.index % 2 ? ignored : kept).push_back(h);
    return h.index % 2 ? -1.0f : kInf;
  }
};

struct Collect final : OverlapVisitor {
  std::size_t limit = std::numeric_limits<std::size_t>::max();
  std::vector<std::uint32_t> seen;
  bool on_overlap(std::uint32_t index) override {
    seen.push_back(index);
    return seen.size() < limit;
  }
};

std::string describe(const Box& b) {
  char buf[200];
  std::snprintf(buf, sizeof buf, "box [%.9g, %.9g, %.9g] - [%.9g, %.9g, %.9g]", b.min[0], b.min[1], b.min[2], b.max[0],
                b.max[1], b.max[2]);
  return buf;
}

std::string describe(const Filter* q) {
  return q ? "filter {" + std::to_string(q->group) + ", " + std::to_string(q->mask) + "}" : "no filter";
}

// A list of distinct indices, all of them in `want` (ascending).
::testing::AssertionResult distinct_subset(std::vector<std::uint32_t> got, const std::vector<std::uint32_t>& want) {
  std::sort(got.begin(), got.end());
  if (std::adjacent_find(got.begin(), got.end()) != got.end()) return ::testing::AssertionFailure() << "duplicates";
  if (!std::includes(want.begin(), want.end(), got.begin(), got.end()))
    return ::testing::AssertionFailure() << "an index the oracle does not report";
  return ::testing::AssertionSuccess();
}

// Every form of the ray query against the oracle.
void check_ray(Detector& d, const Frame& fr, const Ray& r, const Filter* q, const std::string& what) {
  SCOPED_TRACE(std::string(d.name()) + ": " + what + ": " + describe(r) + ", " + describe(q));
  const std::vector<RayHit> want = oracle_hits(fr, r, q);
  std::vector<RayHit> all;
  d.ray_cast_all(r, all, q);
  ASSERT_EQ(all, want);
  RayHit first{};
  ASSERT_EQ(d.ray_cast(r, first, q), !want.empty());
  if (!want.empty()) {
    ASSERT_EQ(first, want.front());
  }
  AllHits every;
  d.ray_cast(r, every, q);
  std::sort(every.hits.begin(), every.hits.end(),
            [](const RayHit& a, const RayHit& b) { return a.t < b.t || (a.t == b.t && a.index < b.index); });
  ASSERT_EQ(every.hits, want) << "a visitor that keeps every hit";
  ClosestHit closest;
  d.ray_cast(r, closest, q);
  ASSERT_EQ(closest.found, !want.empty()) << "the closest-hit visitor";
  ASSERT_FALSE(closest.over_max) << "a hit beyond the max t the visitor set";
  if (!want.empty()) {
    ASSERT_EQ(closest.best, want.front()) << "the closest-hit visitor";
  }
  for (const std::size_t limit : {std::size_t{1}, std::size_t{3}}) {
    FirstHits stop;
    stop.limit = limit;
    d.ray_cast(r, stop, q);
    ASSERT_EQ(stop.hits.size(), std::min(limit, want.size())) << "a visitor that stops after " << limit;
    for (const RayHit& h : stop.hits) ASSERT_NE(std::find(want.begin(), want.end(), h), want.end());
  }
  IgnoreOdd ignore;
  d.ray_cast(r, ignore, q);
  ASSERT_EQ(ignore.kept.size() + ignore.ignored.size(), want.size()) << "ignored hits keep the max t";
}

// Every form of the sphere and box overlap queries against the oracle.
// The list form against `want`, then a visitor that keeps every object and visitors that stop
// after each of `limits`; list(out) and visit(visitor) run the query.
template <class List, class Visit>
void check_overlap_forms(const std::vector<std::uint32_t>& want, List&& list, Visit&& visit,
                         std::initializer_list<std::size_t> limits) {
  std::vector<std::uint32_t> got;
  list(got);
  ASSERT_EQ(got, want);
  Collect all;
  visit(all);
  std::sort(all.seen.begin(), all.seen.end());
  ASSERT_EQ(all.seen, want) << "a visitor that keeps every object";
  for (const std::size_t limit : limits) {
    Collect some;
    some.limit = limit;
    visit(some);
    ASSERT_EQ(some.seen.size(), std::min(limit, want.size())) << "a visitor that stops after " << limit;
    ASSERT_TRUE(distinct_subset(some.seen, want));
  }
}

void check_sphere(Detector& d, const Frame& fr, const Sphere& s, const Filter* q, const std::string& what) {
  SCOPED_TRACE(std::string(d.name()) + ": " + what + ", " + describe(q));
  check_overlap_forms(
      oracle_sphere(fr, s, q), [&](std::vector<std::uint32_t>& out) { d.overlap(s, out, q); },
      [&](OverlapVisitor& v) { d.overlap(s, v, q); }, {2});
}

void check_box(Detector& d, const Frame& fr, const Box& b, const Filter* q, const std::string& what) {
  SCOPED_TRACE(std::string(d.name()) + ": " + what + ": " + describe(b) + ", " + describe(q));
  check_overlap_forms(
      oracle_box(fr, b, q), [&](std::vector<std::uint32_t>& out) { d.overlap_box(b, out, q); },
      [&](OverlapVisitor& v) { d.overlap_box(b, v, q); }, {1, 5});
}

const Filter kQueryFilters[] = {{1, 0xFFFFFFFFu}, {2, 2}, {4, 1 | 4}, {0x80000000u, 0xFFFFFFFFu}, {0, 0}};

// Queries of every kind at a scene of half extent h, with and without query filters.
void check_scene(Detector& d, const Frame& fr, float h, std::uint64_t seed, const std::string& what) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> u(-1, 1);
  const std::size_t n = fr.spheres.size();
  for (int k = 0; k < 120; ++k) {
    const Filter* q = k % 3 == 0 ? nullptr : &kQueryFilters[static_cast<std::size_t>(k) % std::size(kQueryFilters)];
    // Boxes: ordinary, flat, points, huge, around an object, inside an object.
    const float cx = 1.2f * h * u(rng), cy = 1.2f * h * u(rng), cz = 1.2f * h * u(rng);
    float ex = 0.3f * h * (u(rng) + 1), ey = 0.3f * h * (u(rng) + 1), ez = 0.3f * h * (u(rng) + 1);
    if (k % 7 == 1) ex = 0;                   // flat
    if (k % 7 == 2) ex = ey = ez = 0;         // a point
    if (k % 7 == 3) ex = ey = ez = 1e3f * h;  // everything
    check_box(d, fr, make_box(cx - ex, cy - ey, cz - ez, cx + ex, cy + ey, cz + ez), q, what);
    if (n > 0) {
      const Sphere& t = fr.spheres[rng() % n];
      check_box(d, fr, make_box(t.x - t.r, t.y - t.r, t.z - t.r, t.x + t.r, t.y + t.r, t.z + t.r), q,
                what + ", an object's bounding box");
      const float in = t.r * 0.5f;
      check_box(d, fr, make_box(t.x - in, t.y - in, t.z - in, t.x + in, t.y + in, t.z + in), q,
                what + ", a box inside an object");
      check_box(d, fr, make_box(t.x + t.r, t.y, t.z, t.x + t.r + 1, t.y + 1, t.z + 1), q,
                what + ", a box touching an object");
      check_box(d, fr, make_box(t.x, t.y, t.z, t.x, t.y, t.z), q, what + ", a point box at a centre");
      check_sphere(d, fr, {t.x + t.r, t.y, t.z, 0}, q, what + ", a point on an object's surface");
    }
    check_sphere(d, fr, {cx, cy, cz, k % 5 == 0 ? 0.0f : 0.4f * h * (u(rng) + 1)}, q, what);
    // Rays: from inside and outside, along an axis, with a finite max_t, at an object.
    float dir[3] = {u(rng), u(rng), u(rng)};
    if (k % 4 == 1) dir[0] = dir[1] = 0;
    if (dir[0] == 0 && dir[1] == 0 && dir[2] == 0) dir[2] = 1;
    check_ray(d, fr, make_ray(cx, cy, cz, dir[0], dir[1], dir[2], k % 4 == 3 ? h * (u(rng) + 1) : kInf), q, what);
    if (n > 0) {
      const Sphere& t = fr.spheres[rng() % n];
      check_ray(d, fr, make_ray(-2 * h, -2 * h, -2 * h, t.x + 2 * h, t.y + 2 * h, t.z + 2 * h), q,
                what + ", aimed at an object's centre");
      check_ray(d, fr, make_ray(t.x, t.y, t.z, 0, 0, -1), q, what + ", from an object's centre");
    }
    if (::testing::Test::HasFatalFailure()) return;
  }
}

using test::Factory;
using test::kBackends;

// Runs one frame with `filters` (may be empty) and returns the active set (all, no camera).
void run(Detector& d, std::span<const Sphere> s, std::span<const Filter> filters) {
  FrameInput in;
  in.spheres = s;
  in.filters = filters;
  FrameResult out;
  const Status st = d.detect(in, out);
  ASSERT_TRUE(st.ok()) << st.error();
}

TEST(QueryVisitor, SphereBoxTestHandWorked) {
  const Box unit = make_box(-1, -1, -1, 1, 1, 1);
  EXPECT_TRUE(sphere_overlaps_box({2, 0, 0, 1}, unit)) << "touching a face";
  EXPECT_FALSE(sphere_overlaps_box({2, 0, 0, std::nextafter(1.0f, 0.0f)}, unit)) << "just short of a face";
  EXPECT_TRUE(sphere_overlaps_box({0, 0, 0, 0}, unit)) << "a point inside";
  EXPECT_TRUE(sphere_overlaps_box({1, 1, 1, 0}, unit)) << "a point on a corner";
  EXPECT_FALSE(sphere_overlaps_box({std::nextafter(1.0f, 2.0f), 1, 1, 0}, unit)) << "a point just outside";
  EXPECT_TRUE(sphere_overlaps_box({0, 0, 0, 100}, unit)) << "the box inside the sphere";
  // To a corner: (3, 4, 0) from the point box at the origin is 5 exactly.
  const Box origin = make_box(0, 0, 0, 0, 0, 0);
  EXPECT_TRUE(sphere_overlaps_box({3, 4, 0, 5}, origin));
  EXPECT_FALSE(sphere_overlaps_box({3, 4, 0, std::nextafter(5.0f, 0.0f)}, origin));
  // To an edge: (4, 5, 0.5) is 3 and 4 beyond the box [0, 1]^3 in x and y, within it in z.
  EXPECT_TRUE(sphere_overlaps_box({4, 5, 0.5f, 5}, make_box(0, 0, 0, 1, 1, 1))) << "touching an edge";
  EXPECT_FALSE(sphere_overlaps_box({4, 5, 0.5f, std::nextafter(5.0f, 0.0f)}, make_box(0, 0, 0, 1, 1, 1)));
  // Invalid boxes and spheres overlap nothing.
  for (const Box& b : {make_box(1, 0, 0, 0, 0, 0), make_box(kNan, 0, 0, 1, 1, 1), make_box(0, 0, 0, kInf, 1, 1),
                       make_box(-kInf, 0, 0, 1, 1, 1)})
    EXPECT_FALSE(sphere_overlaps_box({0, 0, 0, 1e9f}, b)) << describe(b);
  EXPECT_FALSE(sphere_overlaps_box({0, 0, 0, -1}, unit));
  EXPECT_FALSE(sphere_overlaps_box({kNan, 0, 0, 1}, unit));
  // Against long double wherever the answer is not within rounding of the surface.
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<float> u(-1, 1);
  int decided = 0;
  for (int k = 0; k < 200000; ++k) {
    const float scale = std::pow(10.0f, 6 * u(rng));
    const Sphere s{scale * u(rng), scale * u(rng), scale * u(rng), scale * (u(rng) + 1)};
    float lo[3], hi[3];
    for (int a = 0; a < 3; ++a) {
      const float p = scale * u(rng), q = k % 3 == 0 ? p : scale * u(rng);
      lo[a] = std::min(p, q), hi[a] = std::max(p, q);
    }
    const Box b = make_box(lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]);
    const long double c[3] = {s.x, s.y, s.z};
    long double d2 = 0;
    for (int a = 0; a < 3; ++a) {
      const long double e = c[a] < lo[a] ? lo[a] - c[a] : c[a] > hi[a] ? c[a] - hi[a] : 0.0L;
      d2 += e * e;
    }
    const long double r2 = static_cast<long double>(s.r) * s.r;
    if (std::fabs(d2 - r2) <= 1e-12L * (d2 + r2)) continue;
    ++decided;
    ASSERT_EQ(sphere_overlaps_box(s, b), d2 < r2) << describe(b) << " r " << s.r;
  }
  EXPECT_GT(decided, 190000);
}

TEST(QueryVisitor, RandomScenesAgainstBruteForce) {
  for (const std::size_t n : {0u, 1u, 2u, 15u, 16u, 17u, 33u, 300u, 5000u}) {
    const float h = 2.0f + std::cbrt(static_cast<float>(n));
    const auto s = test::random_spheres_by_half_extent(n, n + 7, h, 0.05f, 1.0f);
    // Without frame filters, with random ones, and with a third that pair with nothing (the cpu
    // keeps those out of its tree, in a tree of their own).
    const std::vector<Filter> random = test::random_filters(n, n + 1);
    std::vector<Filter> aside(n);
    for (std::size_t k = 0; k < n; k += 3) aside[k] = {2, 0};
    for (std::size_t k = 1; k < n; k += 3) aside[k] = {4, 4 | 1};
    for (const std::vector<Filter>* filters :
         {static_cast<const std::vector<Filter>*>(nullptr), &random, static_cast<const std::vector<Filter>*>(&aside)}) {
      for (Factory make : kBackends) {
        if (n > 1000 && make == make_reference_detector) continue;  // its brute force is the oracle's loop
        auto d = make(Config{});
        const std::span<const Filter> f = filters ? std::span<const Filter>(*filters) : std::span<const Filter>();
        run(*d, s, f);
        const std::string what = "n = " + std::to_string(n) +
                                 (filters == &random ? ", random filters"
                                  : filters          ? ", a third aside"
                                                     : "");
        check_scene(*d, Frame{s, nullptr, f}, h, n + 11, what);
        if (HasFatalFailure()) return;
      }
    }
  }
}

TEST(QueryVisitor, DegenerateScenes) {
  struct Case {
    std::vector<Sphere> spheres;
    float h;
    const char* what;
  };
  std::vector<Case> cases;
  cases.push_back({std::vector<Sphere>(40, Sphere{0, 0, 5, 1}), 6, "identical spheres"});
  std::vector<Sphere> line;  // touching spheres along x: (2k, 0, 0) radius 1
  for (int k = 0; k < 50; ++k) line.push_back({2.0f * static_cast<float>(k), 0, 0, 1});
  cases.push_back({line, 100, "touching spheres in a line"});
  std::vector<Sphere> radii;  // huge, tiny and zero radii together
  std::mt19937_64 rng(17);
  std::uniform_real_distribution<float> u(-1, 1);
  for (int k = 0; k < 400; ++k) {
    const float r = k % 5 == 0 ? 0.0f : k % 5 == 1 ? 1e-30f : std::pow(10.0f, 3 * u(rng));
    radii.push_back({50 * u(rng), 50 * u(rng), 50 * u(rng), r});
  }
  radii.push_back({0, 0, 0, 1e17f});
  cases.push_back({radii, 60, "huge, tiny and zero radii"});
  std::vector<Sphere> far;  // far from the origin: boxes round most
  for (int k = 0; k < 600; ++k) far.push_back({1e6f + 20 * u(rng), -1e6f + 20 * u(rng), 1e6f, 0.5f * (u(rng) + 1)});
  cases.push_back({far, 20, "near 1e6"});
  for (const Case& c : cases) {
    std::vector<Filter> f = test::random_filters(c.spheres.size(), 5);
    for (Factory make : kBackends) {
      auto d = make(Config{});
      run(*d, c.spheres, f);
      const Frame fr{c.spheres, nullptr, f};
      // The scene's queries around its own centre.
      const Sphere& s0 = c.spheres[c.spheres.size() / 2];
      for (int k = 0; k < 60; ++k) {
        const Filter* q = k % 2 ? &kQueryFilters[static_cast<std::size_t>(k) % std::size(kQueryFilters)] : nullptr;
        const float x = s0.x + c.h * u(rng), y = s0.y + c.h * u(rng), z = s0.z + c.h * u(rng);
        const float e = k % 4 == 0 ? 0.0f : c.h * 0.3f * (u(rng) + 1);
        check_box(*d, fr, make_box(x - e, y - e, z - e, x + e, y + e, z + e), q, c.what);
        check_sphere(*d, fr, {x, y, z, e}, q, c.what);
        check_ray(*d, fr, make_ray(x, y, z, u(rng), u(rng), k % 3 == 0 ? 0.0f : u(rng)), q, c.what);
        check_ray(*d, fr, make_ray(s0.x - 3 * c.h, s0.y, s0.z, 1, 0, 0), q, std::string(c.what) + ", along x");
        check_ray(*d, fr, make_ray(s0.x, s0.y, s0.z, 0, 1, 0, 0), q, std::string(c.what) + ", max_t 0 from inside");
        if (HasFatalFailure()) return;
      }
    }
  }
  // The line by hand: a box between spheres 1 and 2 touches both at x = 3 (a point); a closest-hit
  // visitor stops at the first sphere.
  for (Factory make : kBackends) {
    auto d = make(Config{});
    run(*d, line, {});
    std::vector<std::uint32_t> idx;
    d->overlap_box(make_box(3, 0, 0, 3, 0, 0), idx);
    EXPECT_EQ(idx, (std::vector<std::uint32_t>{1, 2})) << d->name();
    d->overlap_box(make_box(3, 1e-3f, 0, 3, 1, 0), idx);  // distance^2 1 + 1e-6 from both centres
    EXPECT_TRUE(idx.empty()) << d->name() << ": just off the contact point";
    ClosestHit closest;
    d->ray_cast(make_ray(-10, 0, 0, 1, 0, 0), closest);
    EXPECT_EQ(closest.best, (RayHit{0, 9.0f})) << d->name();
    // A ray along the line from inside sphere 10 at a contact point with 9: t = 0 for both; the
    // visitor's smallest positive max keeps the tie in reach, so index 9 wins.
    ClosestHit tie;
    d->ray_cast(make_ray(19, 0, 0, 1, 0, 0), tie);
    EXPECT_EQ(tie.best, (RayHit{9, 0.0f})) << d->name();
  }
}

TEST(QueryVisitor, ShorteningTheRayPrunesTheCpuWalk) {
  // 4000 spheres in a row along x: a ray along the row hits them all. A visitor that clips the
  // ray to each hit walks the tree nearest first and sees only a handful; one that stops at once
  // sees exactly one.
  std::vector<Sphere> row;
  for (int k = 0; k < 4000; ++k) row.push_back({static_cast<float>(k), 0, 0, 0.25f});
  auto d = make_cpu_detector(Config{});
  run(*d, row, {});
  const Ray r = make_ray(-5, 0, 0, 1, 0, 0);
  ClosestHit closest;
  d->ray_cast(r, closest);
  EXPECT_EQ(closest.best, (RayHit{0, 4.75f}));
  EXPECT_LE(closest.calls, 32) << "the walk did not prune by the shortened ray";
  FirstHits stop;
  d->ray_cast(r, stop);
  EXPECT_EQ(stop.hits.size(), 1u);
  AllHits all;
  d->ray_cast(r, all);
  EXPECT_EQ(all.hits.size(), row.size());
  // A visitor that clips the ray to t = 100 (x = 95) on its first hit sees no hit beyond it.
  struct ClipAt100 final : RayVisitor {
    std::vector<RayHit> hits;
    float on_hit(const RayHit& h) override {
      hits.push_back(h);
      return 100;
    }
  } clip;
  d->ray_cast(r, clip);
  ASSERT_FALSE(clip.hits.empty());
  for (std::size_t k = 1; k < clip.hits.size(); ++k) EXPECT_LE(clip.hits[k].t, 100.0f) << "after the clip";
  EXPECT_GE(clip.hits.size(), 96u) << "every hit up to the final max t (x = 95: spheres 0 to 95)";
  EXPECT_LE(clip.hits.size(), 96u + 1u) << "at most the first hit beyond it";
  // The same through the overlap visitor: a box over the whole row, stopped at the first.
  Collect one;
  one.limit = 1;
  d->overlap_box(make_box(-1, -1, -1, 5000, 1, 1), one);
  EXPECT_EQ(one.seen.size(), 1u);
}

TEST(QueryVisitor, InvalidQueriesCallNothing) {
  const std::vector<Sphere> s = {{0, 0, 0, 1}, {0, 0, 5, 1}};
  struct Never final : RayVisitor, OverlapVisitor {
    int calls = 0;
    float on_hit(const RayHit&) override { return static_cast<float>(++calls); }
    bool on_overlap(std::uint32_t) override { return ++calls > 0; }
  };
  for (Factory make : kBackends) {
    auto d = make(Config{});
    Never never;
    std::vector<std::uint32_t> idx{7};
    d->ray_cast(make_ray(0, 0, -5, 0, 0, 1), never);
    d->overlap_box(make_box(-9, -9, -9, 9, 9, 9), never);
    d->overlap_box(make_box(-9, -9, -9, 9, 9, 9), idx);
    EXPECT_TRUE(idx.empty());
    EXPECT_EQ(never.calls, 0) << d->name() << ": before any frame";
    run(*d, s, {});
    for (const Ray& r :
         {make_ray(0, 0, 0, 0, 0, 0), make_ray(0, 0, 0, 0, 0, 1, -1.0f), make_ray(0, 0, 0, 0, 0, 1, kNan),
          make_ray(kNan, 0, 0, 0, 0, 1), make_ray(0, 0, 0, kInf, 0, 1)})
      d->ray_cast(r, never);
    for (const Box& b : {make_box(1, 0, 0, 0, 0, 0), make_box(kNan, 0, 0, 1, 1, 1), make_box(0, 0, 0, kInf, 1, 1),
                         make_box(-kInf, -kInf, -kInf, kInf, kInf, kInf)}) {
      d->overlap_box(b, never);
      idx.push_back(3);
      d->overlap_box(b, idx);
      EXPECT_TRUE(idx.empty()) << d->name() << ": " << describe(b);
    }
    for (const Sphere& q : {Sphere{0, 0, 0, -1}, Sphere{kNan, 0, 0, 1}, Sphere{0, 0, 0, kInf}}) d->overlap(q, never);
    EXPECT_EQ(never.calls, 0) << d->name();
    // A filter that matches no object: nothing, and the same queries without it find both.
    const Filter none{0, 0};
    d->overlap_box(make_box(-9, -9, -9, 9, 9, 9), idx, &none);
    EXPECT_TRUE(idx.empty());
    d->overlap_box(make_box(-9, -9, -9, 9, 9, 9), idx);
    EXPECT_EQ(idx, (std::vector<std::uint32_t>{0, 1}));
    RayHit h{};
    EXPECT_FALSE(d->ray_cast(make_ray(0, 0, -5, 0, 0, 1), h, &none));
    EXPECT_TRUE(d->ray_cast(make_ray(0, 0, -5, 0, 0, 1), h));
    // A failed frame: queries see nothing until the next good one.
    FrameResult out;
    const std::vector<Sphere> bad = {{0, 0, 0, -1}};
    ASSERT_FALSE(d->detect(bad, nullptr, out).ok());
    d->overlap_box(make_box(-9, -9, -9, 9, 9, 9), never);
    d->ray_cast(make_ray(0, 0, -5, 0, 0, 1), never);
    EXPECT_EQ(never.calls, 0) << d->name() << ": after a failed frame";
  }
}

TEST(QueryVisitor, FrameFiltersFollowTheFrames) {
  // The frame's filters decide what a filtered query sees, frame by frame: a frame without
  // filters gives every object Filter{} again; a moving scene changes N and the unpaired set.
  std::mt19937_64 rng(8);
  std::uniform_real_distribution<float> u(-1, 1);
  std::vector<Sphere> s = test::random_spheres_by_half_extent(1200, 4, 8.0f);
  for (Factory make : kBackends) {
    auto d = make(Config{});
    for (int frame = 0; frame < 6; ++frame) {
      for (Sphere& x : s) x.x += 0.3f * u(rng);
      if (frame == 2) s.resize(500);
      if (frame == 4) {
        const auto more = test::random_spheres_by_half_extent(900, 99, 8.0f);
        s.insert(s.end(), more.begin(), more.end());
      }
      std::vector<Filter> f;
      if (frame % 2) {
        f = test::random_filters(s.size(), static_cast<std::uint64_t>(frame));
        for (std::size_t k = 0; k < f.size(); k += 4) f[k] = {8, 0};  // pairs with nothing
      }
      run(*d, s, f);
      check_scene(*d, Frame{s, nullptr, f}, 8.0f, static_cast<std::uint64_t>(frame) + 40,
                  "frame " + std::to_string(frame));
      if (HasFatalFailure()) return;
    }
  }
}

TEST(QueryVisitor, CulledObjectsStayInvisibleToFilteredQueries) {
  const auto s = test::random_spheres_by_half_extent(800, 12, 6.0f, 0.2f, 1.2f);
  std::vector<Filter> f = test::random_filters(s.size(), 3);
  for (std::size_t k = 0; k < f.size(); k += 3) f[k] = {2, 0};
  Camera cam;
  cam.eye[2] = 14;
  cam.width = 160, cam.height = 120;
  Config c;
  c.lambda = 30;
  for (Factory make : kBackends) {
    auto d = make(c);
    FrameInput in;
    in.spheres = s;
    in.filters = f;
    in.camera = &cam;
    FrameResult out;
    ASSERT_TRUE(d->detect(in, out).ok());
    std::vector<std::uint32_t> active;
    for (std::uint32_t k = 0; k < s.size(); ++k)
      if (out.state[k] != ObjectState::culled) active.push_back(k);
    ASSERT_LT(active.size(), s.size());
    check_scene(*d, Frame{s, &active, f}, 6.0f, 77, "culling and filters");
  }
}

}  // namespace
}  // namespace viscd
