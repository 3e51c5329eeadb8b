#pragma once
// The conformance suite: one set of cases, run for every backend. Each case computes its own
// answer here, independently of the library's broadphase: a brute-force loop over the active set
// with viscd::spheres_overlap (test_util.hpp's oracle_pairs). With a camera and culling, the
// active set is the reference backend's pixel counts against lambda, and every backend's pairs
// are also compared with the reference backend's.
//
// A backend joins by one VISCD_CONFORMANCE_BACKEND(name) line in backends.cpp (guarded by its
// build flag) and its name in conformance_backends in tests/CMakeLists.txt (one ctest each);
// make_backend() creates it by name through viscd::make_detector.

#include <gtest/gtest.h>

#include <cstdint>
#include <memory>
#include <optional>
#include <ostream>
#include <span>
#include <string>
#include <tuple>
#include <vector>

#include "test_util.hpp"
#include "viscd/viscd.hpp"

namespace viscd {

// Test parameters print by name in GoogleTest's messages.
inline void PrintTo(Bits bits, std::ostream* os) {
  *os << (bits == Bits::adaptive ? std::string("adaptive") : "b" + std::to_string(static_cast<int>(bits)));
}
inline void PrintTo(Layout layout, std::ostream* os) { *os << (layout == Layout::plain ? "plain" : "extended"); }

}  // namespace viscd

namespace viscd::conformance {

/// Why `backend` cannot run on this machine (the gl backend without an OpenGL 4.5 context), or
/// nothing when it can. Asked when creating a backend fails: its cases then skip with this
/// reason; a backend that is available but fails to initialise fails them.
[[nodiscard]] std::optional<std::string> unavailable(const std::string& backend);

/// Creates a backend by name with the settings the suite tests it in (gl: a debug context with
/// synchronous debug output, so that every GL error makes detect() fail with the driver's message).
[[nodiscard]] Result<std::unique_ptr<Detector>> make_backend(const std::string& backend, const Config& config);

/// The oracle's view of one frame.
struct Expected {
  std::vector<std::uint32_t> active;  ///< ascending
  std::vector<Pair> pairs;            ///< brute force over `active`
  FrameResult reference;              ///< the reference backend's frame (empty when not run)
  bool has_reference = false;
};

/// Pixels a backend's count may differ from the reference's for the same object (different
/// rasterizers of the same ray model differ at silhouette edges).
[[nodiscard]] float pixel_margin(float pixels);

/// The expected frame: without a camera (or with culling off) every object is active; with a
/// camera and culling on, the objects whose reference pixel count is >= config.lambda. The pairs
/// are the brute force over that set. The reference backend runs whenever a camera is given or
/// `with_reference` is set.
[[nodiscard]] Expected expect_frame(std::span<const Sphere> spheres, const Camera* camera, const Config& config,
                                    bool with_reference);

/// Checks a backend's frame against the expectation: pairs (vs the oracle and, when it ran, the
/// reference backend), per-object states, pixels, stats.
void check_frame(const FrameResult& got, std::span<const Sphere> spheres, const Camera* camera, const Config& config,
                 const Expected& want);

/// A backend name as a test parameter.
using BackendParam = std::string;
/// A backend, a Morton width and a layout.
using PairsParam = std::tuple<std::string, Bits, Layout>;

[[nodiscard]] std::string bits_name(Bits bits);
[[nodiscard]] std::string layout_name(Layout layout);
[[nodiscard]] std::string pairs_param_name(const ::testing::TestParamInfo<PairsParam>& info);
[[nodiscard]] std::string backend_param_name(const ::testing::TestParamInfo<BackendParam>& info);

/// Fixture of the cases that hold for every Morton width and layout: a fresh detector of the
/// backend with Config{.bits, .layout}.
class ConformancePairs : public ::testing::TestWithParam<PairsParam> {
 protected:
  void SetUp() override;
  [[nodiscard]] const std::string& backend() const { return std::get<0>(GetParam()); }
  [[nodiscard]] Config config() const { return test::config_bits(std::get<1>(GetParam()), std::get<2>(GetParam())); }
  /// One frame on the fixture's detector (reusing `frame_`), checked against expect_frame().
  void check(std::span<const Sphere> spheres, const std::string& what, const Camera* camera = nullptr);
  std::unique_ptr<Detector> detector_;
  FrameResult frame_;
};

/// Fixture of the cases that do not depend on the Morton width: a fresh detector with Config{}.
class ConformanceFrames : public ::testing::TestWithParam<BackendParam> {
 protected:
  void SetUp() override;
  [[nodiscard]] const std::string& backend() const { return GetParam(); }
  std::unique_ptr<Detector> detector_;
};

/// n spheres with centres uniform in [-half_extent, half_extent]^3 and radii uniform in
/// [rmin, rmax], deterministic in `seed`.
[[nodiscard]] std::vector<Sphere> random_cloud(std::size_t n, std::uint64_t seed, float half_extent, float rmin = 0.1f,
                                               float rmax = 1.0f);

/// A small screen (128 x 96) looking at the origin from 16 units away, `angle_deg` about y.
[[nodiscard]] Camera scene_camera(float angle_deg = 0.0f);

/// A random cloud seen by scene_camera(angle_deg), and a culling threshold for it. Some objects
/// are off screen, behind the eye or hidden (0 pixels), some visible below lambda, some above.
/// No object's reference pixel count lies within pixel_margin(lambda) of lambda, so every
/// backend's rasterizer puts each object on the reference's side of it.
struct CameraScene {
  std::vector<Sphere> spheres;
  Camera camera;
  float lambda = 0.0f;
};
[[nodiscard]] CameraScene camera_scene(std::size_t n, std::uint64_t seed, float angle_deg = 0.0f);
/// After the spheres moved: shrinks to points (r = 0, no pixels) the objects whose reference
/// count came within pixel_margin(lambda) of lambda, until none does. N stays the same.
void clear_lambda_band(std::vector<Sphere>& spheres, const Camera& camera, float lambda);

}  // namespace viscd::conformance

/// Runs the whole conformance suite on one backend, by its make_detector name (unquoted).
#define VISCD_CONFORMANCE_BACKEND(backend)                                                                           \
  INSTANTIATE_TEST_SUITE_P(backend, ConformancePairs,                                                                \
                           ::testing::Combine(::testing::Values(std::string(#backend)),                              \
                                              ::testing::Values(::viscd::Bits::adaptive, ::viscd::Bits::b16,         \
                                                                ::viscd::Bits::b32, ::viscd::Bits::b64),             \
                                              ::testing::Values(::viscd::Layout::extended, ::viscd::Layout::plain)), \
                           ::viscd::conformance::pairs_param_name);                                                  \
  INSTANTIATE_TEST_SUITE_P(backend, ConformanceFrames, ::testing::Values(std::string(#backend)),                     \
                           ::viscd::conformance::backend_param_name)
