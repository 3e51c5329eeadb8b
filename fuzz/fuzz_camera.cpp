// libFuzzer target: the camera reader, parse_camera, on arbitrary bytes.
//
// Checks (any failure aborts, so libFuzzer keeps the input as a reproducer):
// - parse_camera never crashes, throws, leaks or trips a sanitizer;
// - an accepted camera passes validate_camera, and camera_json() of it reads back to the same
//   camera, field for field;
// - a rejected input has a non-empty message; with VISCD_FUZZ_STRICT_MESSAGES, also one without
//   control characters (bytes < 0x20 and 0x7f).

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include "fuzz_util.hpp"
#include "viscd/detector.hpp"
#include "viscd/io.hpp"

namespace {

[[noreturn]] void fail(const char* what, std::string_view detail = {}) {
  viscd::fuzz::fail("fuzz_camera", what, detail);
}

bool same(const viscd::Camera& a, const viscd::Camera& b) {
  for (int k = 0; k < 3; ++k)
    if (a.eye[k] != b.eye[k] || a.target[k] != b.target[k] || a.up[k] != b.up[k]) return false;
  return a.fov_y_deg == b.fov_y_deg && a.near_plane == b.near_plane && a.far_plane == b.far_plane &&
         a.width == b.width && a.height == b.height;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  const viscd::Result<viscd::Camera> camera = viscd::parse_camera(text, "fuzz.json");
  if (!camera.ok()) {
    if (camera.error().empty()) fail("rejected the input with an empty message");
#ifdef VISCD_FUZZ_STRICT_MESSAGES
    if (viscd::fuzz::has_control_character(camera.error()))
      fail("error message holds a control character", camera.error());
#endif
    return 0;
  }
  if (!camera.error().empty()) fail("accepted the input but has a message", camera.error());
  if (const viscd::Status s = viscd::validate_camera(camera.value()); !s)
    fail("accepted a camera that validate_camera rejects", s.error());
  const std::string json = viscd::camera_json(camera.value());
  const viscd::Result<viscd::Camera> back = viscd::parse_camera(json, "round-trip.json");
  if (!back.ok()) fail("camera_json() of an accepted camera does not read back", back.error());
  if (!same(camera.value(), back.value())) fail("the camera_json() round trip changed the camera", json);
  return 0;
}
