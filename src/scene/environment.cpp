// The tools' environment knobs (viscd/io.hpp): the library reads no environment, so the command
// line tool and the benchmarks map these onto Config themselves.

#include <cstdlib>
#include <string>
#include <string_view>

#include "viscd/io.hpp"

namespace viscd {
namespace {

// A variable that is 1 or 0, into `field` when set; any other value is an error naming it.
Status bool_variable(const char* name, bool& field) {
  const char* v = std::getenv(name);
  if (v == nullptr) return {};
  const std::string_view s(v);
  if (s != "1" && s != "0")
    return Status::failure(ErrorKind::invalid_input, std::string(name) + "=" + printable(s) + ": expected 1 or 0");
  field = s == "1";
  return {};
}

}  // namespace

Status apply_environment(Config& config) {
  if (const char* v = std::getenv("VISCD_SIMD")) {
    const std::string_view s(v);
    if (s == "best" || s == "avx512")
      config.simd = Simd::best;
    else if (s == "sse2")
      config.simd = Simd::sse2;
    else if (s == "scalar")
      config.simd = Simd::scalar;
    else
      return Status::failure(ErrorKind::invalid_input,
                             "VISCD_SIMD=" + printable(s) + ": expected best, sse2 or scalar");
  }
  if (Status st = bool_variable("VISCD_KEEP_ORDER", config.keep_order); !st) return st;
  if (Status st = bool_variable("VISCD_FOLLOW_CHANGE", config.follow_change); !st) return st;
  return {};
}

}  // namespace viscd
