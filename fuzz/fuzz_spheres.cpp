// libFuzzer target: the sphere readers, parse_xyzr, parse_csv and parse_sphere_table, on arbitrary
// bytes.
//
// Checks (any failure aborts, so libFuzzer keeps the input as a reproducer):
// - neither reader crashes, leaks or trips a sanitizer;
// - an accepted file holds only valid spheres: finite, |x|, |y|, |z|, r <= kMaxCoordinate, r >= 0;
// - accepted spheres round-trip: written as CSV with 9 significant digits (as write_spheres_csv
//   does) and read back by parse_csv, they come back equal;
// - parse_sphere_table accepts what parse_csv accepts, with the same spheres, and gives either no
//   filters or one per sphere;
// - a rejected file has a non-empty message; with VISCD_FUZZ_STRICT_MESSAGES, also one without
//   control characters (bytes < 0x20 and 0x7f), so that messages print safely on a terminal.

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <string>
#include <string_view>
#include <vector>

#include "fuzz_util.hpp"
#include "viscd/io.hpp"

namespace {

using viscd::Sphere;
using SpheresResult = viscd::Result<std::vector<Sphere>>;

[[noreturn]] void fail(const char* what, std::string_view detail = {}) {
  viscd::fuzz::fail("fuzz_spheres", what, detail);
}

bool valid(const Sphere& s) {
  for (const float v : {s.x, s.y, s.z, s.r})
    if (!std::isfinite(v) || std::fabs(v) > viscd::kMaxCoordinate) return false;
  return s.r >= 0;
}

void check(const SpheresResult& result) {
  if (!result.ok()) {
    if (result.error().empty()) fail("rejected the input with an empty message");
#ifdef VISCD_FUZZ_STRICT_MESSAGES
    if (viscd::fuzz::has_control_character(result.error()))
      fail("error message holds a control character", result.error());
#endif
    return;
  }
  if (!result.error().empty()) fail("accepted the input but has a message", result.error());
  const std::vector<Sphere>& spheres = result.value();
  std::string csv = "x,y,z,r\n";
  for (const Sphere& s : spheres) {
    char line[160];
    std::snprintf(line, sizeof line, "%.9g,%.9g,%.9g,%.9g\n", static_cast<double>(s.x), static_cast<double>(s.y),
                  static_cast<double>(s.z), static_cast<double>(s.r));
    if (!valid(s)) fail("accepted an invalid sphere", line);
    csv += line;
  }
  const SpheresResult back = viscd::parse_csv(csv, "round-trip.csv");
  if (!back.ok()) fail("accepted spheres written as CSV do not read back", back.error());
  if (back.value().size() != spheres.size()) fail("the CSV round trip changed the sphere count", csv);
  for (std::size_t k = 0; k < spheres.size(); ++k) {
    const Sphere &a = spheres[k], &b = back.value()[k];
    if (a.x != b.x || a.y != b.y || a.z != b.z || a.r != b.r) fail("the CSV round trip changed a sphere", csv);
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  check(viscd::parse_xyzr(text, "fuzz.xyzr"));
  const SpheresResult csv = viscd::parse_csv(text, "fuzz.csv");
  check(csv);
  const viscd::Result<viscd::SphereTable> table = viscd::parse_sphere_table(text, "fuzz.csv");
  if (table.ok() != csv.ok()) fail("parse_sphere_table and parse_csv disagree on accepting the input");
  if (table.ok()) {
    const auto& t = table.value();
    if (!t.filters.empty() && t.filters.size() != t.spheres.size()) fail("filters are neither none nor one per sphere");
    if (t.spheres.size() != csv.value().size()) fail("parse_sphere_table and parse_csv read different spheres");
  } else if (table.error() != csv.error()) {
    fail("parse_sphere_table and parse_csv give different messages", table.error());
  }
  return 0;
}
