// The conformance suite's oracle, checks, fixtures and camera scene (see conformance.hpp).
#include <algorithm>
#include <cmath>
#include <cstring>
#include <random>

#include "conformance/conformance.hpp"

namespace viscd::conformance {

std::string bits_name(Bits bits) {
  switch (bits) {
    case Bits::adaptive:
      return "adaptive";
    case Bits::b16:
      return "b16";
    case Bits::b32:
      return "b32";
    case Bits::b64:
      return "b64";
  }
  return "bits" + std::to_string(static_cast<int>(bits));
}

std::string layout_name(Layout layout) { return layout == Layout::plain ? "plain" : "extended"; }

std::string pairs_param_name(const ::testing::TestParamInfo<PairsParam>& info) {
  return bits_name(std::get<1>(info.param)) + "_" + layout_name(std::get<2>(info.param));
}

std::string backend_param_name(const ::testing::TestParamInfo<BackendParam>& info) { return info.param; }

namespace {

// A fresh detector of `backend`. On failure: `skip` says why when the backend cannot run on this
// machine at all (asked only then: it costs a context); otherwise the failure is recorded.
std::unique_ptr<Detector> create(const std::string& backend, const Config& config, std::string& skip) {
  auto d = make_backend(backend, config);
  if (!d) {
    if (auto why = unavailable(backend))
      skip = *why;
    else
      ADD_FAILURE() << "backend " << backend << " is available but cannot be created: " << d.error();
    return nullptr;
  }
  EXPECT_EQ(d.value()->name(), backend);
  return std::move(d.value());
}

}  // namespace

void ConformancePairs::SetUp() {
  std::string skip;
  detector_ = create(backend(), config(), skip);
  if (!skip.empty()) GTEST_SKIP() << skip;
  ASSERT_NE(detector_, nullptr);
}

void ConformanceFrames::SetUp() {
  std::string skip;
  detector_ = create(backend(), Config{}, skip);
  if (!skip.empty()) GTEST_SKIP() << skip;
  ASSERT_NE(detector_, nullptr);
}

void ConformancePairs::check(std::span<const Sphere> spheres, const std::string& what, const Camera* camera) {
  SCOPED_TRACE(backend() + " " + bits_name(std::get<1>(GetParam())) + " " + layout_name(std::get<2>(GetParam())) +
               ": " + what + " (N = " + std::to_string(spheres.size()) + ")");
  const Config& config = detector_->config();
  const Status s = detector_->detect(spheres, camera, frame_);
  ASSERT_TRUE(s.ok()) << s.error();
  check_frame(frame_, spheres, camera, config, expect_frame(spheres, camera, config, true));
}

float pixel_margin(float pixels) { return 6.0f + 0.05f * pixels; }

namespace {

// The reference backend's frame, remembered for the last few inputs: cases check several frames
// of one scene (the ray caster costs O(pixels x N) per frame). The settings that change its
// pixels and pairs are the key; m, the layout and the thresholds a, b do not.
const FrameResult& reference_frame(std::span<const Sphere> spheres, const Camera* camera, const Config& config,
                                   bool& ok) {
  struct Entry {
    std::vector<Sphere> spheres;
    std::optional<Camera> camera;
    bool culling = false;
    float lambda = 0;
    int map_width = 0, map_height = 0;
    FrameResult frame;
  };
  static std::vector<Entry> cache;  // most recent last
  const bool culling = camera && config.culling;
  const float lambda = culling ? config.lambda : 0.0f;
  for (std::size_t k = 0; k < cache.size(); ++k) {
    const Entry& e = cache[k];
    if (e.culling != culling || e.lambda != lambda || e.camera.has_value() != (camera != nullptr) ||
        (camera && *e.camera != *camera) || e.spheres.size() != spheres.size() ||
        (camera && (e.map_width != config.map_width || e.map_height != config.map_height)) ||
        !std::equal(spheres.begin(), spheres.end(), e.spheres.begin(),
                    [](const Sphere& a, const Sphere& b) { return std::memcmp(&a, &b, sizeof(Sphere)) == 0; }))
      continue;
    std::rotate(cache.begin() + static_cast<std::ptrdiff_t>(k), cache.begin() + static_cast<std::ptrdiff_t>(k) + 1,
                cache.end());
    ok = true;
    return cache.back().frame;
  }
  Entry e;
  e.spheres.assign(spheres.begin(), spheres.end());
  if (camera) e.camera = *camera;
  e.culling = culling;
  e.lambda = lambda;
  e.map_width = config.map_width;
  e.map_height = config.map_height;
  const Status s = make_reference_detector(config)->detect(spheres, camera, e.frame);
  EXPECT_TRUE(s.ok()) << "reference: " << s.error();
  ok = s.ok();
  if (!ok) {
    static const FrameResult none;
    return none;
  }
  if (cache.size() == 6) cache.erase(cache.begin());
  cache.push_back(std::move(e));
  return cache.back().frame;
}

}  // namespace

Expected expect_frame(std::span<const Sphere> spheres, const Camera* camera, const Config& config,
                      bool with_reference) {
  Expected e;
  if (camera || with_reference) {
    bool ok = false;
    const FrameResult& ref = reference_frame(spheres, camera, config, ok);
    e.has_reference = ok;
    if (ok) e.reference = ref;
  }
  for (std::uint32_t k = 0; k < spheres.size(); ++k) {
    const bool culled = camera && config.culling && e.has_reference && !(e.reference.pixels[k] >= config.lambda);
    if (!culled) e.active.push_back(k);
  }
  e.pairs = test::oracle_pairs(spheres, &e.active);
  return e;
}

void check_frame(const FrameResult& got, std::span<const Sphere> spheres, const Camera* camera, const Config& config,
                 const Expected& want) {
  const std::size_t n = spheres.size();
  EXPECT_EQ(got.stats.objects, n);
  EXPECT_EQ(got.stats.has_camera, camera != nullptr);
  EXPECT_EQ(got.stats.active, want.active.size());
  EXPECT_TRUE(test::same_pairs(got.pairs, want.pairs)) << "pairs against the brute-force oracle";
  if (want.has_reference) {
    EXPECT_TRUE(test::same_pairs(got.pairs, want.reference.pairs)) << "pairs against the reference backend";
  }
  EXPECT_EQ(got.stats.pairs, got.pairs.size());
  if (!config.contact_events) {
    EXPECT_TRUE(got.began.empty() && got.ended.empty()) << "contact events without Config::contact_events";
  }

  // States: culled outside the active set, colliding iff in a pair, free otherwise.
  ASSERT_EQ(got.state.size(), n);
  std::vector<ObjectState> state(n, ObjectState::culled);
  for (std::uint32_t k : want.active) state[k] = ObjectState::free;
  for (const Pair& p : want.pairs) state[p.i] = state[p.j] = ObjectState::colliding;
  std::size_t wrong = 0, first = n;
  for (std::size_t k = 0; k < n; ++k)
    if (got.state[k] != state[k]) first = std::min(first, k), ++wrong;
  EXPECT_EQ(wrong, 0u) << "object states differ, first at object " << first << ": got "
                       << static_cast<int>(got.state[first]) << ", want " << static_cast<int>(state[first]);

  // Morton width: a fixed one is used as given; adaptive is 32 without a camera (mu undefined).
  if (config.bits != Bits::adaptive) {
    EXPECT_EQ(got.stats.bits, static_cast<int>(config.bits));
  } else if (!camera) {
    EXPECT_EQ(got.stats.bits, 32);
  } else {
    EXPECT_TRUE(got.stats.bits == 16 || got.stats.bits == 32 || got.stats.bits == 64) << got.stats.bits;
  }
  EXPECT_GT(got.stats.layout.total_bits(), 0);

  // Pixels: per object when the frame rendered its map (within the rasterizer margin of the
  // reference's), none otherwise. The map is rendered when a camera is given and something uses
  // it: culling, adaptive bits, shading or Config::report_pixels.
  const bool map_used =
      camera && (config.culling || config.bits == Bits::adaptive || config.shade || config.report_pixels);
  EXPECT_EQ(got.stats.has_pixels, map_used);
  if (!map_used) {
    EXPECT_TRUE(got.pixels.empty());
  } else if (want.has_reference) {
    ASSERT_EQ(got.pixels.size(), n);
    std::size_t off = 0, worst = n;
    float worst_d = 0.0f;
    for (std::size_t k = 0; k < n; ++k) {
      const float d = std::fabs(got.pixels[k] - want.reference.pixels[k]);
      if (d > pixel_margin(want.reference.pixels[k])) ++off;
      if (d > worst_d) worst_d = d, worst = k;
    }
    EXPECT_EQ(off, 0u) << "objects whose pixel count is off the reference's by more than the margin; worst: object "
                       << worst << " by " << worst_d;
  }
  EXPECT_TRUE(got.image.empty());
}

std::vector<Sphere> random_cloud(std::size_t n, std::uint64_t seed, float half_extent, float rmin, float rmax) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> c(-half_extent, half_extent), r(rmin, rmax);
  std::vector<Sphere> s(n);
  for (Sphere& sp : s) sp = {c(rng), c(rng), c(rng), r(rng)};
  return s;
}

Camera scene_camera(float angle_deg) {
  Camera cam;
  const float a = angle_deg * 3.14159265f / 180.0f;
  cam.eye[0] = 16.0f * std::sin(a);
  cam.eye[1] = 2.0f;
  cam.eye[2] = 16.0f * std::cos(a);
  cam.target[0] = cam.target[1] = cam.target[2] = 0.0f;
  cam.fov_y_deg = 60.0f;
  cam.near_plane = 0.1f;
  cam.far_plane = 100.0f;
  cam.width = 128;
  cam.height = 96;
  return cam;
}

namespace {

std::vector<float> reference_pixels(std::span<const Sphere> spheres, const Camera& camera) {
  Config c;
  c.culling = false;
  bool ok = false;
  const FrameResult& f = reference_frame(spheres, &camera, c, ok);
  return ok ? f.pixels : std::vector<float>{};
}

}  // namespace

void clear_lambda_band(std::vector<Sphere>& spheres, const Camera& camera, float lambda) {
  // Shrinking an object can only uncover others, so this converges; a few rounds suffice.
  for (int round = 0; round < 20; ++round) {
    const std::vector<float> px = reference_pixels(spheres, camera);
    if (px.size() != spheres.size()) return;  // failed above
    bool changed = false;
    for (std::size_t k = 0; k < spheres.size(); ++k)
      if (std::fabs(px[k] - lambda) < pixel_margin(lambda)) spheres[k].r = 0.0f, changed = true;
    if (!changed) return;
  }
  ADD_FAILURE() << "objects keep entering the band around lambda = " << lambda;
}

CameraScene camera_scene(std::size_t n, std::uint64_t seed, float angle_deg) {
  // Nine in ten spheres in a cube around the target, one in ten behind the eye; half small,
  // half large. None reaches within one unit of the eye: how a rasterizer clips a sphere around
  // the eye at the near plane is its own business, not what culling is about.
  CameraScene scene;
  scene.camera = scene_camera(angle_deg);
  const Camera& cam = scene.camera;
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> c(-12.0f, 12.0f), behind(-4.0f, 4.0f), small(0.1f, 0.4f), large(0.8f, 1.8f);
  while (scene.spheres.size() < n) {
    const float r = scene.spheres.size() % 2 ? large(rng) : small(rng);
    Sphere sp{c(rng), c(rng), c(rng), r};
    if (scene.spheres.size() % 10 == 9)
      sp = {1.5f * cam.eye[0] + behind(rng), cam.eye[1] + behind(rng), 1.5f * cam.eye[2] + behind(rng), r};
    const float dx = sp.x - cam.eye[0], dy = sp.y - cam.eye[1], dz = sp.z - cam.eye[2];
    if (std::sqrt(dx * dx + dy * dy + dz * dz) > sp.r + 1.0f) scene.spheres.push_back(sp);
  }
  // lambda: keep about the largest 40% of the visible objects.
  std::vector<float> visible;
  for (float px : reference_pixels(scene.spheres, cam))
    if (px > 0) visible.push_back(px);
  if (visible.empty()) {
    ADD_FAILURE() << "the camera sees nothing";
    return scene;
  }
  std::sort(visible.begin(), visible.end());
  scene.lambda = std::max(20.0f, std::round(visible[visible.size() * 6 / 10]) + 0.5f);
  clear_lambda_band(scene.spheres, cam, scene.lambda);
  return scene;
}

}  // namespace viscd::conformance
