// The caller's visibility map (FrameInput::id_map): counting (count_ids) against a histogram
// written here, hand-worked maps, a detector's own map given back as the caller's (the same
// pixels, culling, m and pairs), and the errors.
#include <gtest/gtest.h>

#include <random>

#include "cpu/pipeline.hpp"
#include "cpu/visibility.hpp"
#include "test_util.hpp"
#include "viscd/scene.hpp"

namespace viscd {
namespace {

using test::same_pairs;

// Runs of random ids in [0, max_id], lengths 1 to max_run.
std::vector<std::uint32_t> random_map(std::size_t pixels, std::uint32_t max_id, std::uint32_t max_run,
                                      std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::vector<std::uint32_t> ids;
  while (ids.size() < pixels) {
    const auto id = static_cast<std::uint32_t>(rng() % (std::uint64_t{max_id} + 1));
    const std::size_t run = 1 + rng() % max_run;
    for (std::size_t k = 0; k < run && ids.size() < pixels; ++k) ids.push_back(id);
  }
  return ids;
}

std::vector<std::uint32_t> histogram(const std::vector<std::uint32_t>& ids, std::size_t objects) {
  std::vector<std::uint32_t> h(objects + 2, 0);
  for (std::uint32_t id : ids) ++h[id > objects ? objects + 1 : id];
  return h;
}

TEST(CountIds, AgainstAHistogram) {
  std::vector<std::uint32_t> hist;
  detail::CountScratch scratch;
  for (std::size_t pixels : {0u, 1u, 3u, 4u, 5u, 7u, 8u, 9u, 4095u, 4096u, 4097u, 100003u, 921600u}) {
    for (std::uint32_t max_run : {1u, 3u, 4u, 5u, 64u, 5000u}) {
      // Few objects for the pixels (in parallel, a histogram per range of rows) and many (serial).
      for (std::size_t objects : {1u, 7u, 1000u, 300000u}) {
        const auto ids = random_map(pixels, static_cast<std::uint32_t>(objects), max_run, pixels + max_run);
        for (int threads : {1, 2, 5})
          for (const detail::SimdLevel simd : {detail::SimdLevel::scalar, detail::SimdLevel::avx512}) {
            ASSERT_TRUE(detail::count_ids(ids, objects, threads, hist, scratch, simd));
            ASSERT_EQ(hist, histogram(ids, objects))
                << pixels << " pixels, runs up to " << max_run << ", " << objects << " objects, " << threads
                << " threads, " << detail::simd_name(simd);
          }
      }
    }
  }
}

// Object counts around the histogram's segments (one histogram per range of pixels up to
// CountScratch::kSegment slots, segments of ids beyond), ids bunched at the top and bottom of the
// range, maps of background only and of one object only, and one run across every block.
TEST(CountIds, AroundTheSegments) {
  std::vector<std::uint32_t> hist;
  detail::CountScratch scratch;
  constexpr std::size_t kSeg = detail::CountScratch::kSegment;
  for (std::size_t objects : {kSeg - 3, kSeg - 2, kSeg - 1, kSeg, 2 * kSeg - 2, 2 * kSeg + 5, 5 * kSeg + 1}) {
    std::mt19937_64 rng(objects);
    std::vector<std::vector<std::uint32_t>> maps;
    std::vector<std::uint32_t> ids;
    for (std::size_t k = 0; k < 70000; ++k) {  // ids near both ends and at segment edges
      const std::uint64_t pick = rng() % 6;
      const std::uint64_t edge = (rng() % (objects / kSeg + 1)) * kSeg;
      const std::uint64_t id = pick == 0   ? objects - rng() % 3
                               : pick == 1 ? rng() % 3
                               : pick == 2 ? std::min<std::uint64_t>(objects, edge + rng() % 2)
                               : pick == 3 ? (edge == 0 ? 0 : edge - 1)
                                           : rng() % (objects + 1);
      const std::size_t run = 1 + rng() % 7;
      for (std::size_t r = 0; r < run; ++r) ids.push_back(static_cast<std::uint32_t>(id));
    }
    maps.push_back(ids);
    maps.emplace_back(100003, 0u);                                   // background only
    maps.emplace_back(100003, static_cast<std::uint32_t>(objects));  // the last object only
    maps.emplace_back(2048 * 3 + 17, 1u);                            // one run across blocks
    for (const auto& map : maps)
      for (int threads : {1, 2, 3})
        for (const detail::SimdLevel simd : {detail::SimdLevel::scalar, detail::SimdLevel::avx512}) {
          ASSERT_TRUE(detail::count_ids(map, objects, threads, hist, scratch, simd));
          ASSERT_EQ(hist, histogram(map, objects)) << objects << " objects, " << map.size() << " pixels, " << threads
                                                   << " threads, " << detail::simd_name(simd);
        }
  }
}

// The buffers are kept between calls: a call on a smaller map (one range of pixels), on an empty
// one, and on fewer or more objects leaves nothing of the one before in the counts.
TEST(CountIds, BuffersKeptBetweenCallsLeaveNothingBehind) {
  std::vector<std::uint32_t> hist;
  detail::CountScratch scratch;
  const std::size_t many = 3 * detail::CountScratch::kSegment + 11;
  const std::vector<std::pair<std::size_t, std::size_t>> calls = {
      {200003, many}, {0, many}, {100, many}, {200003, many}, {5000, 1000}, {0, 1000}, {7, 3}, {300000, many}};
  for (int threads : {1, 2, 3}) {
    std::uint64_t seed = 1;
    for (const auto& [pixels, objects] : calls) {
      const auto ids = random_map(pixels, static_cast<std::uint32_t>(objects), 9, seed++);
      ASSERT_TRUE(detail::count_ids(ids, objects, threads, hist, scratch));
      ASSERT_EQ(hist, histogram(ids, objects))
          << pixels << " pixels, " << objects << " objects, " << threads << " threads";
    }
  }
}

// Stage 3 on threads (cull_in_parallel) against the serial rule (cull_and_choose_bits): the same
// pixels, active set, mu and bits for sizes around the parallel threshold, with and without flags
// and culling, and scaled counts.
TEST(CullInParallel, EqualsTheSerialRule) {
  detail::CullScratch scratch;
  for (std::size_t n : {0u, 1u, 4095u, 4096u, 4097u, 100003u}) {
    std::mt19937_64 rng(n);
    std::vector<std::uint32_t> counts(n);
    std::vector<std::uint8_t> flags(n);
    for (std::size_t k = 0; k < n; ++k) {
      counts[k] = static_cast<std::uint32_t>(rng() % 3 == 0 ? rng() % 1000 : 0);
      flags[k] = rng() % 50 == 0;
    }
    for (const bool culling : {true, false})
      for (const bool with_flags : {false, true})
        for (const double scale : {1.0, 2.25, 0.3})
          for (int threads : {1, 2, 3}) {
            Config c;
            c.culling = culling;
            const std::span<const std::uint8_t> always =
                with_flags ? std::span<const std::uint8_t>(flags) : std::span<const std::uint8_t>();
            std::vector<float> pa, pb;
            std::vector<std::uint32_t> aa{7, 7}, ab;
            FrameStats sa, sb;
            const int ba = detail::cull_and_choose_bits(counts, scale, c, always, pa, aa, sa);
            const int bb = detail::cull_in_parallel(counts, scale, c, always, threads, pb, ab, scratch, sb);
            const std::string what = std::to_string(n) + " objects, culling " + (culling ? "on" : "off") +
                                     (with_flags ? ", flags" : "") + ", scale " + std::to_string(scale) + ", " +
                                     std::to_string(threads) + " threads";
            ASSERT_EQ(pa, pb) << what;
            ASSERT_EQ(aa, ab) << what;
            EXPECT_EQ(ba, bb) << what;
            EXPECT_EQ(sa.mean_pixels, sb.mean_pixels) << what;
            EXPECT_EQ(sa.active, sb.active) << what;
            // The oracle: the rule written out here.
            std::vector<std::uint32_t> want;
            double sum = 0;
            for (std::size_t k = 0; k < n; ++k) {
              sum += counts[k];
              // The count as FrameResult::pixels reports it (a float) against lambda.
              if (!culling || static_cast<float>(counts[k] * scale) >= c.lambda || (with_flags && flags[k]))
                want.push_back(static_cast<std::uint32_t>(k));
            }
            ASSERT_EQ(ab, want) << what;
            EXPECT_DOUBLE_EQ(sb.mean_pixels, n ? sum * scale / static_cast<double>(n) : 0.0) << what;
          }
  }
}

TEST(CountIds, IdsBeyondTheObjectsAreCountedApart) {
  std::vector<std::uint32_t> hist;
  detail::CountScratch scratch;
  for (std::size_t pixels : {1u, 6u, 5000u, 200000u}) {
    for (std::uint32_t objects : {10u, 100000u}) {
      for (std::size_t at : {std::size_t{0}, pixels / 2, pixels - 1}) {
        auto ids = random_map(pixels, objects, 9, at + 1);
        ids[at] = objects + 1;  // ids 0..objects are fine
        for (int threads : {1, 2}) {
          EXPECT_FALSE(detail::count_ids(ids, objects, threads, hist, scratch))
              << pixels << " pixels, " << objects << " objects, bad id at " << at;
          EXPECT_EQ(hist, histogram(ids, objects));
        }
        ids[at] = 0xFFFFFFFFu;
        EXPECT_FALSE(detail::count_ids(ids, objects, 2, hist, scratch));
        EXPECT_EQ(hist[objects + 1], 1u);
      }
    }
  }
}

FrameResult detect_map(Detector& d, std::span<const Sphere> s, std::span<const std::uint32_t> map, int w, int h,
                       const Camera* cam = nullptr, Status* status = nullptr) {
  FrameResult out;
  const Status st = d.detect(test::id_map_input(s, cam, map, w, h), out);
  if (status)
    *status = st;
  else
    EXPECT_TRUE(st.ok()) << d.name() << ": " << st.error();
  return out;
}

using test::Factory;
using test::kBackends;

TEST(IdMap, HandWorked) {
  // 4 x 3 map of 3 objects: object 0 (id 1) 4 pixels, object 1 (id 2) 2, object 2 (id 3) 3.
  const std::vector<std::uint32_t> map = {1, 1, 0, 2,  //
                                          1, 1, 0, 2,  //
                                          0, 3, 3, 3};
  // Every sphere overlaps every other.
  const std::vector<Sphere> s = {{0, 0, 0, 1}, {1, 0, 0, 1}, {0, 1, 0, 1}};
  for (Factory make : kBackends) {
    Config c;
    c.lambda = 3;
    auto d = make(c);
    // No camera: counts are map pixels. Object 1 (2 < 3 pixels) is culled.
    FrameResult f = detect_map(*d, s, map, 4, 3);
    EXPECT_EQ(f.pixels, (std::vector<float>{4, 2, 3})) << d->name();
    EXPECT_EQ(f.stats.active, 2u);
    EXPECT_TRUE(f.stats.has_pixels);
    EXPECT_FALSE(f.stats.has_camera);
    EXPECT_DOUBLE_EQ(f.stats.mean_pixels, 3.0);
    EXPECT_EQ(f.stats.bits, 16) << "mu = 3 < a = 100";
    EXPECT_EQ(f.pairs, (std::vector<Pair>{{0, 2}}));
    EXPECT_EQ(f.state, (std::vector<ObjectState>{ObjectState::colliding, ObjectState::culled, ObjectState::colliding}));
    // A camera of 8 x 6 pixels: 4 screen pixels per map pixel. lambda 10: object 1 (8) culled.
    Camera cam;
    cam.width = 8, cam.height = 6;
    c.lambda = 10;
    d->set_config(c);
    f = detect_map(*d, s, map, 4, 3, &cam);
    EXPECT_EQ(f.pixels, (std::vector<float>{16, 8, 12})) << d->name();
    EXPECT_TRUE(f.stats.has_camera);
    EXPECT_DOUBLE_EQ(f.stats.mean_pixels, 12.0);
    EXPECT_EQ(f.pairs, (std::vector<Pair>{{0, 2}}));
    // lambda 8: all active; culling off: all active whatever lambda.
    c.lambda = 8;
    d->set_config(c);
    EXPECT_EQ(detect_map(*d, s, map, 4, 3, &cam).pairs, (std::vector<Pair>{{0, 1}, {0, 2}, {1, 2}}));
    c.lambda = 1000;
    c.culling = false;
    d->set_config(c);
    f = detect_map(*d, s, map, 4, 3);
    EXPECT_EQ(f.pairs.size(), 3u);
    EXPECT_EQ(f.pixels, (std::vector<float>{4, 2, 3})) << "pixels are reported with culling off too";
    // Adaptive m from mu: a = 1, b = 2 puts mu = 3 at 64 bits.
    c.culling = true;
    c.lambda = 0;
    c.pixels_for_32_bits = 1, c.pixels_for_64_bits = 2;
    d->set_config(c);
    EXPECT_EQ(detect_map(*d, s, map, 4, 3).stats.bits, 64);
  }
}

// A detector's own frame, then its map given back as the caller's: the same frame.
void check_own_map_given_back(const std::vector<Sphere>& s, const Camera& cam, Config c, const std::string& what) {
  for (Factory make : kBackends) {
    auto d = make(c);
    const FrameResult own = test::run_frame(*d, s, &cam);
    const detail::VisibilityMap& map = detail::backend_as<detail::PipelineDetector>(*d).visibility_map();
    const std::vector<std::uint32_t> ids(map.ids.begin(), map.ids.end());
    const int w = map.width, h = map.height;
    auto fresh = make(c);  // another detector: no state of the first frame
    const FrameResult given = detect_map(*fresh, s, ids, w, h, &cam);
    EXPECT_EQ(given.pixels, own.pixels) << d->name() << ": " << what;
    EXPECT_EQ(given.state, own.state) << d->name() << ": " << what;
    EXPECT_EQ(given.stats.active, own.stats.active) << d->name() << ": " << what;
    EXPECT_EQ(given.stats.mean_pixels, own.stats.mean_pixels) << d->name() << ": " << what;
    EXPECT_EQ(given.stats.bits, own.stats.bits) << d->name() << ": " << what;
    EXPECT_EQ(given.stats.layout, own.stats.layout) << d->name() << ": " << what;
    EXPECT_TRUE(same_pairs(given.pairs, own.pairs)) << d->name() << ": " << what;
    EXPECT_TRUE(given.image.empty());
  }
}

TEST(IdMap, OwnMapGivenBack) {
  Scene scene = Scene::make({.objects = 3000});
  const Camera cam = camera_preset("zoom-in", scene, 200, 120).value();
  Config c;
  c.lambda = 20;
  check_own_map_given_back(std::vector<Sphere>(scene.spheres().begin(), scene.spheres().end()), cam, c,
                           "zoom-in, map = screen");
  c.map_width = 100, c.map_height = 50;  // a smaller map: counts scaled by 200 * 120 / (100 * 50)
  check_own_map_given_back(std::vector<Sphere>(scene.spheres().begin(), scene.spheres().end()), cam, c,
                           "zoom-in, 100x50 map of a 200x120 screen");
}

// lambda applies to the count as reported: on a 39 x 51 map of a 1 x 1 screen an object that
// covers the whole map has 1989 x (1 / 1989) screen pixels, a double just below 1 that rounds to
// the float 1. With lambda = 1 it is active, as pixels[0] >= lambda tells the caller (a frame
// that compared the double culled it while reporting 1 pixel).
TEST(IdMap, LambdaReadsTheReportedCount) {
  ASSERT_LT(1989.0 * (1.0 / 1989.0), 1.0) << "the premise: the double product lies below 1";
  const std::vector<Sphere> s = {{0, 0, 0, 1}, {0.5f, 0, 0, 1}, {5, 0, 0, 1}};
  std::vector<std::uint32_t> map(39 * 51, 1);
  map[0] = 3;  // object 2: 1 map pixel, 1 / 1989 screen pixels
  Camera cam;
  cam.width = 1, cam.height = 1;
  Config c;
  c.lambda = 1;
  for (Factory make : kBackends) {
    auto d = make(c);
    const FrameResult r = detect_map(*d, s, map, 39, 51, &cam);
    ASSERT_EQ(r.pixels.size(), 3u) << d->name();
    EXPECT_LT(r.pixels[0], 1.0f) << d->name();
    EXPECT_GT(r.pixels[0], 0.99f) << d->name();
    EXPECT_EQ(r.pixels[1], 0.0f) << d->name();
    EXPECT_EQ(r.state, (std::vector<ObjectState>{ObjectState::culled, ObjectState::culled, ObjectState::culled}))
        << d->name() << ": 1988 map pixels are below 1 screen pixel";
    map[0] = 1;  // now object 0 covers the whole map
    const FrameResult whole = detect_map(*d, s, map, 39, 51, &cam);
    map[0] = 3;
    EXPECT_EQ(whole.pixels[0], 1.0f) << d->name();
    EXPECT_EQ(whole.stats.active, 1u) << d->name();
    EXPECT_EQ(whole.state, (std::vector<ObjectState>{ObjectState::free, ObjectState::culled, ObjectState::culled}))
        << d->name();
    EXPECT_TRUE(whole.pairs.empty()) << d->name() << ": object 1 is culled";
  }
}

TEST(IdMap, Errors) {
  const std::vector<Sphere> s = {{0, 0, 0, 1}, {1, 0, 0, 1}, {0, 1, 0, 1}};
  const std::vector<std::uint32_t> map = {1, 1, 0, 2, 1, 1, 0, 4, 0, 3, 3, 3};  // id 4 at (3, 1)
  for (Factory make : kBackends) {
    auto d = make(Config{});
    Status st;
    detect_map(*d, s, map, 4, 3, nullptr, &st);
    ASSERT_FALSE(st.ok()) << d->name();
    EXPECT_NE(st.error().find("(3, 1)"), std::string::npos) << st.error();
    EXPECT_NE(st.error().find("id 4"), std::string::npos) << st.error();
    EXPECT_NE(st.error().find("3 objects"), std::string::npos) << st.error();
    // Sizes.
    detect_map(*d, s, map, 4, 4, nullptr, &st);
    ASSERT_FALSE(st.ok());
    EXPECT_NE(st.error().find("holds 12 ids, but 4x4 needs 16"), std::string::npos) << st.error();
    detect_map(*d, s, map, 12, 0, nullptr, &st);
    EXPECT_FALSE(st.ok());
    detect_map(*d, s, map, -4, -3, nullptr, &st);
    EXPECT_FALSE(st.ok());
    const std::vector<std::uint32_t> line(20000, 0);
    detect_map(*d, s, line, 20000, 1, nullptr, &st);
    ASSERT_FALSE(st.ok()) << "a side beyond kMaxMapSide";
    EXPECT_NE(st.error().find("too large"), std::string::npos) << st.error();
    // Shading needs the detector's own map; a gl texture is the gl backend's.
    Config shade;
    shade.shade = true;
    d->set_config(shade);
    const std::vector<std::uint32_t> good = {1, 1, 0, 2, 1, 1, 0, 2, 0, 3, 3, 3};
    Camera cam;
    detect_map(*d, s, good, 4, 3, &cam, &st);
    ASSERT_FALSE(st.ok());
    EXPECT_NE(st.error().find("Config::shade"), std::string::npos) << st.error();
    d->set_config(Config{});
    FrameInput in;
    in.spheres = s;
    in.gl_id_texture = 5;
    in.id_map_width = 4, in.id_map_height = 3;
    FrameResult out;
    st = d->detect(in, out);
    ASSERT_FALSE(st.ok());
    EXPECT_NE(st.error().find("gl_id_texture"), std::string::npos) << st.error();
    EXPECT_EQ(st.kind(), ErrorKind::unsupported_input) << st.error();
    in.id_map = good;
    st = d->detect(in, out);
    ASSERT_FALSE(st.ok());
    EXPECT_NE(st.error().find("both"), std::string::npos) << st.error();
    // And the detector goes on.
    const FrameResult f = detect_map(*d, s, good, 4, 3);
    EXPECT_EQ(f.pixels, (std::vector<float>{4, 2, 3}));
  }
}

TEST(IdMap, MapSizeOfConfigIsNotUsed) {
  // Config::map_width x map_height (even an invalid one) gives way to the id map's size.
  const std::vector<Sphere> s = {{0, 0, 0, 1}, {1, 0, 0, 1}};
  const std::vector<std::uint32_t> map = {1, 2, 2, 0};
  Config c;
  c.map_width = 7, c.map_height = 0;
  c.lambda = 0;
  Camera cam;
  cam.width = 4, cam.height = 4;  // 16 screen pixels over 4 map pixels
  for (Factory make : kBackends) {
    auto d = make(c);
    EXPECT_EQ(detect_map(*d, s, map, 2, 2, &cam).pixels, (std::vector<float>{4, 8})) << d->name();
  }
}

}  // namespace
}  // namespace viscd
