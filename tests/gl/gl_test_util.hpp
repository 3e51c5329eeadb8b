#pragma once
// Shared helpers of the gl backend tests: one debug-context detector per process (context and
// program creation on llvmpipe cost about a second), skipped with a logged reason when no
// OpenGL 4.5 context can be created.

#include <gtest/gtest.h>

#include <cstdio>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "core/backend.hpp"
#include "gl/gl_detector.hpp"
#include "gl/test_access.hpp"
#include "viscd/scene.hpp"
#include "viscd/viscd.hpp"

namespace viscd::test {

/// A gl detector as the tests drive it: the public Detector for frames and queries, and a
/// gl::GlInspector on its backend for the stage access that only tests use.
class GlUnderTest {
 public:
  explicit GlUnderTest(std::unique_ptr<Detector> d)
      : detector_(std::move(d)), inspector_(detail::backend_as<gl::GlDetector>(*detector_)) {}
  [[nodiscard]] static Result<std::unique_ptr<GlUnderTest>> create(const Config& config, const GlOptions& options) {
    auto d = make_gl_detector(config, options);
    if (!d) return Result<std::unique_ptr<GlUnderTest>>::failure(d.status());
    return std::make_unique<GlUnderTest>(std::move(d.value()));
  }
  Detector& detector() { return *detector_; }
  /// The backend's parts: run_broadphase, read_sorted_codes, read_tree, count_id_map, ...
  gl::GlInspector& inspect() { return inspector_; }
  [[nodiscard]] const gl::GlInspector& inspect() const { return inspector_; }

  [[nodiscard]] Status detect(const FrameInput& in, FrameResult& out) { return detector_->detect(in, out); }
  [[nodiscard]] Status detect(std::span<const Sphere> s, const Camera* c, FrameResult& out) {
    return detector_->detect(s, c, out);
  }
  void wait_for_stage_times(FrameStats& stats) { detector_->wait_for_stage_times(stats); }
  [[nodiscard]] const Config& config() const { return detector_->config(); }
  void set_config(const Config& c) { detector_->set_config(c); }

 private:
  std::unique_ptr<Detector> detector_;
  gl::GlInspector inspector_;
};

struct GlHolder {
  std::unique_ptr<GlUnderTest> detector;
  std::string error;
};

inline GlHolder& gl_holder() {
  static GlHolder h = [] {
    GlHolder g;
    GlOptions o;
    o.debug = true;  // every GL error makes the call fail with the driver's message
    auto d = GlUnderTest::create(Config{}, o);
    if (d) {
      g.detector = std::move(d.value());
      std::fprintf(stderr, "[gl] device: %s\n", g.detector->inspect().device().c_str());
    } else {
      g.error = d.error();
    }
    return g;
  }();
  return h;
}

/// The shared detector with `config` and `options` (debug always on), or nullptr after
/// GTEST_SKIP-worthy failure (the caller skips).
inline GlUnderTest* gl_detector(const Config& config = {}, GlOptions options = {}) {
  GlHolder& h = gl_holder();
  if (!h.detector) return nullptr;
  options.debug = true;
  h.detector->set_config(config);
  h.detector->inspect().set_options(options);
  return h.detector.get();
}

#define VISCD_GL_OR_SKIP(var, ...)                                           \
  ::viscd::test::GlUnderTest* var = ::viscd::test::gl_detector(__VA_ARGS__); \
  if (!var) GTEST_SKIP() << "no OpenGL 4.5 context: " << ::viscd::test::gl_holder().error

/// A preset camera over a small 256 x 144 screen, which keeps llvmpipe frames fast.
inline Camera small_camera(const Scene& scene, const char* preset) {
  auto c = camera_preset(preset, scene, 256, 144);
  EXPECT_TRUE(c.ok());
  return c.value();
}

/// n spheres with centres uniform in a cube of edge `edge` centred at the origin, i.e. in
/// [-edge/2, edge/2]^3, and radii uniform in [rmin, rmax] (std::mt19937 seeded with `seed`).
/// test_util.hpp's random_spheres_by_half_extent takes half the edge instead.
inline std::vector<Sphere> random_spheres_by_edge(std::size_t n, float edge, float rmin, float rmax, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> pos(-edge / 2, edge / 2), rad(rmin, rmax);
  std::vector<Sphere> s(n);
  for (Sphere& x : s) x = {pos(rng), pos(rng), pos(rng), rad(rng)};
  return s;
}

}  // namespace viscd::test
