// libFuzzer target: one frame of the cpu backend against the reference backend and against an
// independent brute force, on up to 64 spheres (and optionally a camera) decoded from the input.
//
// Checks (any failure aborts with a short message on stderr):
// - cpu and reference succeed or fail together, never without a message, and (without a pair
//   cap) with the same message; invalid spheres (non-finite, r < 0, a magnitude beyond
//   kMaxCoordinate) always fail; valid spheres without a camera fail exactly when their pairs
//   exceed Config::pair_memory_cap;
// - on success both report the same pairs, object states, pixel counts, shaded image and stats
//   (objects, active, pairs, mu, Morton width, layout), and the pairs are sorted, unique, have
//   i < j < N and equal an O(N^2) loop of spheres_overlap over the active objects: all of them
//   without a camera or with culling off, else those with at least lambda pixels. A state is
//   culled for an inactive object, colliding for one in a pair, free otherwise;
// - the cpu detector first runs another frame (the second half of the spheres, another Morton
//   width) into the same FrameResult, so reuse of buffers between frames is covered too.
//
// With VISCD_FUZZ_VERBOSE set in the environment, every input prints what it decodes to (config,
// camera, spheres as hex floats) and the reference's result.
//
// Input format, read front to back; reads past the end give zero bytes, so every input decodes:
//   flags     bits 0-1 Morton width (adaptive, 16, 32, 64); bit 2 plain layout; bit 3 culling
//             off; bit 4 a camera follows the scene byte; bit 5 two threads; bit 6 shade; bit 7 a
//             tuning byte follows
//   [tuning]  bits 0-2 lambda (kLambda); bits 3-4 thresholds a, b (kThresholds); bits 5-6 map
//             size: the screen's, 1 x 1, 8 x 6, or two bytes follow, each taken % 64 (one zero
//             is invalid); bit 7 a byte c follows and pair_memory_cap = 4 c
//   scene     bits 0-2 world unit u (kUnit); bits 3-4 offset o (kOffset); bits 5-7 encoding
//   [camera]  see read_camera()
//   spheres   until the input ends, at most kMaxSpheres, in the scene's encoding:
//             0-3 grid, 4 bytes x y z r: a coordinate is o + (b % 16 - 8) u, nudged by bits 4-5
//               (none, one ulp up, one ulp down, + u/2) and + u/4 when bits 6-7 are 3;
//               r = kRadius[b % 8] u, nudged by bits 3-4 alike; bits 5-7 = 7 give r = 0 and
//               6 the smallest denormal. Touching and barely missing spheres are common.
//             4 raw, 16 bytes: four floats as they are (NaN, infinities, denormals, huge)
//             5 raw but valid, 16 bytes: non-finite -> 0, scaled by 2^-64 until within
//               kMaxCoordinate, r = |r|
//             6 mixed: per sphere a selector byte, then the sphere raw (0), raw but valid (1)
//               or grid (else)
//             7 fine grid, 4 bytes: a coordinate is o + (b - 128) u / 16, r = b u / 16

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "fuzz_util.hpp"
#include "viscd/detector.hpp"

namespace {

using viscd::Camera;
using viscd::Config;
using viscd::FrameResult;
using viscd::ObjectState;
using viscd::Pair;
using viscd::Sphere;

constexpr std::size_t kMaxSpheres = 64;
constexpr int kMaxScreen = 64;  // camera width and height are 1..64: the reference casts a ray per pixel

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
constexpr float kLambda[8] = {200.0f, 0.0f, 1.0f, 0.5f, 20.0f, 1e9f, -1.0f, kNaN};
constexpr float kThresholds[4][2] = {{100.0f, 400.0f}, {0.0f, 0.0f}, {1.0f, 2.0f}, {1e9f, 1e10f}};
// 0x1p-100 underflows the squares of the overlap test; 1e-41 is denormal; 1.5e17 * 7 > kMaxCoordinate.
constexpr float kUnit[8] = {1.0f, 0.25f, 1e-3f, 0x1p-100f, 1e-41f, 1e6f, 1e15f, 1.5e17f};
// 2^24: the ulp there is 2, so u/2 and u/4 steps round.
constexpr float kOffset[4] = {0.0f, 1000.5f, 0x1p24f, -3e12f};
constexpr float kRadius[8] = {0.0f, 0.5f, 1.0f, 1.5f, 2.0f, 0.25f, 3.0f, 8.0f};
constexpr float kNear[8] = {0.1f, 0.01f, 1.0f, 1e-6f, 0.0f, 10.0f, 0.5f, 100.0f};
constexpr float kFar[8] = {1e4f, 10.0f, 1e6f, 2.0f, 1.0f, 1.0000001f, 1e30f, 0.5f};

[[noreturn]] void fail(const char* what) { viscd::fuzz::fail("fuzz_detect", what); }
[[noreturn]] void fail(const char* what, const std::string& detail) { viscd::fuzz::fail("fuzz_detect", what, detail); }

// Reads the input front to back; past the end every byte is zero.
class Bytes {
 public:
  Bytes(const std::uint8_t* data, std::size_t size) : data_(data), size_(size) {}
  [[nodiscard]] bool empty() const { return pos_ >= size_; }
  std::uint8_t u8() { return pos_ < size_ ? data_[pos_++] : 0; }
  float i8() { return static_cast<float>(static_cast<std::int8_t>(u8())); }
  float f32() {
    std::uint8_t b[4] = {u8(), u8(), u8(), u8()};
    float f;
    std::memcpy(&f, b, sizeof f);
    return f;
  }

 private:
  const std::uint8_t* data_;
  std::size_t size_;
  std::size_t pos_ = 0;
};

struct Scene {
  float unit = 1, offset = 0;
  int encoding = 0;
};

float nudge(float v, unsigned how, float unit) {
  switch (how & 3u) {
    case 1:
      return std::nextafter(v, std::numeric_limits<float>::infinity());
    case 2:
      return std::nextafter(v, -std::numeric_limits<float>::infinity());
    case 3:
      return v + unit * 0.5f;
    default:
      return v;
  }
}

float grid_coordinate(std::uint8_t b, const Scene& sc) {
  float v = sc.offset + static_cast<float>((b & 15) - 8) * sc.unit;
  v = nudge(v, b >> 4, sc.unit);
  if ((b >> 6) == 3) v += sc.unit * 0.25f;
  return v;
}

Sphere grid_sphere(Bytes& in, const Scene& sc) {
  Sphere s;
  s.x = grid_coordinate(in.u8(), sc);
  s.y = grid_coordinate(in.u8(), sc);
  s.z = grid_coordinate(in.u8(), sc);
  const std::uint8_t b = in.u8();
  s.r = nudge(kRadius[b & 7] * sc.unit, b >> 3, sc.unit);
  if ((b >> 5) == 7) s.r = 0.0f;
  if ((b >> 5) == 6) s.r = std::numeric_limits<float>::denorm_min();
  return s;
}

Sphere fine_grid_sphere(Bytes& in, const Scene& sc) {
  const float step = sc.unit / 16.0f;
  Sphere s;
  s.x = sc.offset + static_cast<float>(in.u8() - 128) * step;
  s.y = sc.offset + static_cast<float>(in.u8() - 128) * step;
  s.z = sc.offset + static_cast<float>(in.u8() - 128) * step;
  s.r = static_cast<float>(in.u8()) * step;
  return s;
}

Sphere raw_sphere(Bytes& in, bool make_valid) {
  Sphere s{in.f32(), in.f32(), in.f32(), in.f32()};
  if (make_valid) {
    for (float* v : {&s.x, &s.y, &s.z, &s.r}) {
      if (!std::isfinite(*v)) *v = 0.0f;
      while (std::fabs(*v) > viscd::kMaxCoordinate) *v *= 0x1p-64f;
    }
    s.r = std::fabs(s.r);
  }
  return s;
}

// Camera: a mode byte; bit 0 raw: 12 floats (eye, target, up, fov_y_deg, near, far), then
// width and height bytes. Otherwise bytes ex ey ez tx ty tz (eye = o + int8 u / 4, target =
// o + int8 u / 16), up (% 4: +y, +z, +x, -y), fov (0.5 + 0.7 b degrees), near (kNear[b % 8] u),
// far (near kFar[b % 8]), width, height (each 1 + b % 64).
Camera read_camera(Bytes& in, const Scene& sc) {
  Camera c;
  if (in.u8() & 1) {
    for (float* v : {&c.eye[0], &c.eye[1], &c.eye[2], &c.target[0], &c.target[1], &c.target[2], &c.up[0], &c.up[1],
                     &c.up[2], &c.fov_y_deg, &c.near_plane, &c.far_plane})
      *v = in.f32();
  } else {
    for (float& v : c.eye) v = sc.offset + in.i8() * sc.unit * 0.25f;
    for (float& v : c.target) v = sc.offset + in.i8() * sc.unit * 0.0625f;
    static constexpr float kUp[4][3] = {{0, 1, 0}, {0, 0, 1}, {1, 0, 0}, {0, -1, 0}};
    const std::uint8_t up = in.u8();
    for (int k = 0; k < 3; ++k) c.up[k] = kUp[up & 3][k];
    c.fov_y_deg = 0.5f + 0.7f * static_cast<float>(in.u8());
    c.near_plane = kNear[in.u8() & 7] * sc.unit;
    c.far_plane = c.near_plane * kFar[in.u8() & 7];
  }
  c.width = 1 + in.u8() % kMaxScreen;
  c.height = 1 + in.u8() % kMaxScreen;
  return c;
}

struct Input {
  std::vector<Sphere> spheres;
  std::optional<Camera> camera;
  Config config;
};

Input decode(Bytes& in) {
  Input input;
  Config& c = input.config;
  const std::uint8_t flags = in.u8();
  static constexpr viscd::Bits kBits[4] = {viscd::Bits::adaptive, viscd::Bits::b16, viscd::Bits::b32, viscd::Bits::b64};
  c.bits = kBits[flags & 3];
  c.layout = (flags & 4) ? viscd::Layout::plain : viscd::Layout::extended;
  c.culling = !(flags & 8);
  c.threads = (flags & 32) ? 2 : 1;
  c.shade = (flags & 64) != 0;
  if (flags & 128) {
    const std::uint8_t tuning = in.u8();
    c.lambda = kLambda[tuning & 7];
    c.pixels_for_32_bits = kThresholds[(tuning >> 3) & 3][0];
    c.pixels_for_64_bits = kThresholds[(tuning >> 3) & 3][1];
    switch ((tuning >> 5) & 3) {
      case 1:
        c.map_width = c.map_height = 1;
        break;
      case 2:
        c.map_width = 8, c.map_height = 6;
        break;
      case 3:
        c.map_width = in.u8() % 64;
        c.map_height = in.u8() % 64;
        break;
      default:
        break;
    }
    if (tuning & 128) c.pair_memory_cap = 4u * in.u8();
  }
  const std::uint8_t scene = in.u8();
  const Scene sc{kUnit[scene & 7], kOffset[(scene >> 3) & 3], scene >> 5};
  if (flags & 16) input.camera = read_camera(in, sc);
  while (!in.empty() && input.spheres.size() < kMaxSpheres) {
    int encoding = sc.encoding;
    if (encoding == 6) {
      const std::uint8_t selector = in.u8();
      encoding = selector == 0 ? 4 : selector == 1 ? 5 : 0;
    }
    switch (encoding) {
      case 4:
        input.spheres.push_back(raw_sphere(in, false));
        break;
      case 5:
        input.spheres.push_back(raw_sphere(in, true));
        break;
      case 7:
        input.spheres.push_back(fine_grid_sphere(in, sc));
        break;
      default:
        input.spheres.push_back(grid_sphere(in, sc));
        break;
    }
  }
  return input;
}

bool valid(const Sphere& s) {
  for (const float v : {s.x, s.y, s.z, s.r})
    if (!std::isfinite(v) || std::fabs(v) > viscd::kMaxCoordinate) return false;
  return s.r >= 0;
}

// Every overlapping pair among `active` (ascending), in sorted order.
std::vector<Pair> brute_force(std::span<const Sphere> spheres, std::span<const std::uint32_t> active) {
  std::vector<Pair> pairs;
  for (std::size_t a = 0; a < active.size(); ++a)
    for (std::size_t b = a + 1; b < active.size(); ++b)
      if (viscd::spheres_overlap(spheres[active[a]], spheres[active[b]])) pairs.push_back({active[a], active[b]});
  return pairs;
}

std::string pair_text(const Pair& p) { return "(" + std::to_string(p.i) + ", " + std::to_string(p.j) + ")"; }

// The first difference of two pair lists, for the report.
std::string pair_difference(const std::vector<Pair>& got, const std::vector<Pair>& want) {
  std::string s = std::to_string(got.size()) + " pairs, expected " + std::to_string(want.size());
  for (std::size_t k = 0; k < got.size() || k < want.size(); ++k) {
    if (k < got.size() && k < want.size() && got[k] == want[k]) continue;
    s += "; first difference at " + std::to_string(k) + ": " + (k < got.size() ? pair_text(got[k]) : "none") + " vs " +
         (k < want.size() ? pair_text(want[k]) : "none");
    break;
  }
  return s;
}

void check_frame(const Input& in, const FrameResult& cpu, const FrameResult& ref) {
  const std::size_t n = in.spheres.size();
  const Config& c = in.config;
  const bool has_camera = in.camera.has_value();
  // A camera's map is rendered and counted only when something uses it (the library's rule).
  const bool map_used = has_camera && (c.culling || c.bits == viscd::Bits::adaptive || c.shade || c.report_pixels);

  // Stats and sizes.
  for (const FrameResult* f : {&cpu, &ref}) {
    if (f->stats.objects != n) fail("stats.objects is not N");
    if (f->stats.has_camera != has_camera) fail("stats.has_camera is wrong");
    if (f->state.size() != n) fail("state does not have N entries");
    if (f->pixels.size() != (map_used ? n : 0)) fail("pixels has the wrong size");
    if (f->stats.has_pixels != map_used) fail("stats.has_pixels is wrong");
    if (f->stats.pairs != f->pairs.size()) fail("stats.pairs differs from the pair count");
  }
  for (std::size_t k = 0; k < cpu.pixels.size(); ++k)
    if (cpu.pixels[k] != ref.pixels[k])
      fail("cpu and reference pixel counts differ", "object " + std::to_string(k) + ": " +
                                                        std::to_string(cpu.pixels[k]) + " vs " +
                                                        std::to_string(ref.pixels[k]));
  if (cpu.stats.active != ref.stats.active) fail("cpu and reference active counts differ");
  if (cpu.stats.mean_pixels != ref.stats.mean_pixels) fail("cpu and reference mu differ");
  if (cpu.stats.bits != ref.stats.bits) fail("cpu and reference Morton widths differ");
  if (cpu.stats.layout != ref.stats.layout)
    fail("cpu and reference layouts differ",
         format_layout(cpu.stats.layout) + " vs " + format_layout(ref.stats.layout));
  if (c.bits != viscd::Bits::adaptive && cpu.stats.bits != static_cast<int>(c.bits))
    fail("a fixed Morton width was not used");
  if (has_camera && c.shade) {
    if (cpu.image_width != ref.image_width || cpu.image_height != ref.image_height || cpu.image != ref.image)
      fail("cpu and reference shaded images differ");
  } else if (!cpu.image.empty() || !ref.image.empty()) {
    fail("an image was produced without a camera or shading");
  }

  // The active set, from the documented rule.
  std::vector<std::uint32_t> active;
  for (std::uint32_t k = 0; k < n; ++k)
    if (!has_camera || !c.culling || static_cast<double>(ref.pixels[k]) >= static_cast<double>(c.lambda))
      active.push_back(k);
  if (ref.stats.active != active.size())
    fail("stats.active differs from the objects with at least lambda pixels",
         std::to_string(ref.stats.active) + " vs " + std::to_string(active.size()));

  // Pairs: well formed, equal between backends, equal to brute force.
  for (const FrameResult* f : {&cpu, &ref})
    for (std::size_t k = 0; k < f->pairs.size(); ++k) {
      const Pair& p = f->pairs[k];
      if (!(p.i < p.j && p.j < n)) fail("a pair is not (i < j < N)", pair_text(p));
      if (k > 0 && !(f->pairs[k - 1] < p)) fail("pairs are not sorted and unique", pair_text(p));
    }
  const std::vector<Pair> want = brute_force(in.spheres, active);
  if (cpu.pairs != ref.pairs) fail("cpu pairs differ from the reference's", pair_difference(cpu.pairs, ref.pairs));
  if (ref.pairs != want) fail("pairs differ from brute force", pair_difference(ref.pairs, want));
  if (c.pair_memory_cap != 0 && want.size() * sizeof(Pair) > c.pair_memory_cap)
    fail("a frame over the pair memory cap succeeded");

  // States.
  std::vector<ObjectState> state(n, ObjectState::culled);
  for (const std::uint32_t k : active) state[k] = ObjectState::free;
  for (const Pair& p : want) state[p.i] = state[p.j] = ObjectState::colliding;
  if (cpu.state != ref.state) fail("cpu and reference object states differ");
  if (ref.state != state) fail("object states do not follow from the active set and the pairs");
}

// The decoded input and the reference's result, for VISCD_FUZZ_VERBOSE (floats as C hex literals).
void print(const Input& in, const viscd::Status& status, const FrameResult& ref) {
  const Config& c = in.config;
  std::fprintf(stderr,
               "fuzz_detect: config bits %d layout %s culling %d threads %d shade %d lambda %a a %a b %a map %dx%d "
               "pair_memory_cap %zu\n",
               static_cast<int>(c.bits), c.layout == viscd::Layout::plain ? "plain" : "extended", c.culling ? 1 : 0,
               c.threads, c.shade ? 1 : 0, static_cast<double>(c.lambda), static_cast<double>(c.pixels_for_32_bits),
               static_cast<double>(c.pixels_for_64_bits), c.map_width, c.map_height, c.pair_memory_cap);
  if (in.camera) {
    const Camera& k = *in.camera;
    std::fprintf(stderr,
                 "fuzz_detect: camera eye {%a, %a, %a} target {%a, %a, %a} up {%a, %a, %a} fov %a near %a far %a "
                 "%dx%d\n",
                 static_cast<double>(k.eye[0]), static_cast<double>(k.eye[1]), static_cast<double>(k.eye[2]),
                 static_cast<double>(k.target[0]), static_cast<double>(k.target[1]), static_cast<double>(k.target[2]),
                 static_cast<double>(k.up[0]), static_cast<double>(k.up[1]), static_cast<double>(k.up[2]),
                 static_cast<double>(k.fov_y_deg), static_cast<double>(k.near_plane), static_cast<double>(k.far_plane),
                 k.width, k.height);
  }
  for (std::size_t k = 0; k < in.spheres.size(); ++k) {
    const Sphere& s = in.spheres[k];
    std::fprintf(stderr, "fuzz_detect: sphere %zu {%a, %a, %a, %a}\n", k, static_cast<double>(s.x),
                 static_cast<double>(s.y), static_cast<double>(s.z), static_cast<double>(s.r));
  }
  std::fprintf(stderr, "fuzz_detect: N = %zu, %s: active %u, pairs %zu, bits %d, %s\n", in.spheres.size(),
               status.ok() ? "ok" : status.error().c_str(), ref.stats.active, ref.pairs.size(), ref.stats.bits,
               format_layout(ref.stats.layout).c_str());
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  Bytes bytes(data, size);
  const Input in = decode(bytes);
  const Camera* camera = in.camera ? &*in.camera : nullptr;
  const std::span<const Sphere> spheres(in.spheres);

  // A different frame first, so that the real one reuses the detector's and the result's buffers.
  Config warm = in.config;
  warm.bits = in.config.bits == viscd::Bits::b64 ? viscd::Bits::b16 : viscd::Bits::b64;
  const auto cpu_detector = viscd::make_cpu_detector(warm);
  FrameResult cpu;
  (void)cpu_detector->detect(spheres.subspan(spheres.size() / 2), camera, cpu);
  cpu_detector->set_config(in.config);
  const viscd::Status cpu_status = cpu_detector->detect(spheres, camera, cpu);

  FrameResult ref;
  const viscd::Status ref_status = viscd::make_reference_detector(in.config)->detect(spheres, camera, ref);

  static const bool verbose = std::getenv("VISCD_FUZZ_VERBOSE") != nullptr;
  if (verbose) print(in, ref_status, ref);
  if (cpu_status.ok() != ref_status.ok())
    fail(cpu_status.ok() ? "cpu succeeds, reference fails" : "reference succeeds, cpu fails",
         cpu_status.ok() ? ref_status.error() : cpu_status.error());
  bool all_valid = true;
  for (const Sphere& s : in.spheres) all_valid = all_valid && valid(s);
  if (!cpu_status.ok()) {
    if (cpu_status.error().empty() || ref_status.error().empty()) fail("a failure without a message");
    // Over the pair cap a backend may stop counting early ("at least N pairs"); other failures
    // come from the same input checks and read the same.
    if (in.config.pair_memory_cap == 0 && cpu_status.error() != ref_status.error())
      fail("cpu and reference fail with different messages", cpu_status.error() + " | " + ref_status.error());
    if (!camera && all_valid) {
      // Only the pair cap can fail this frame.
      std::vector<std::uint32_t> all(in.spheres.size());
      for (std::uint32_t k = 0; k < all.size(); ++k) all[k] = k;
      const std::size_t pairs = brute_force(spheres, all).size();
      if (in.config.pair_memory_cap == 0 || pairs * sizeof(Pair) <= in.config.pair_memory_cap)
        fail("valid spheres without a camera failed", cpu_status.error());
    }
    return 0;
  }
  if (!all_valid) fail("a frame with an invalid sphere succeeded");
  check_frame(in, cpu, ref);
  return 0;
}
