// The tools' environment knobs (viscd/io.hpp): the library reads no environment, so the command
// line tool and the benchmarks map these onto Config themselves.

#include <cstdlib>
#include <string>
#include <string_view>

#include "viscd/io.hpp"

namespace viscd {

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
  if (const char* v = std::getenv("VISCD_KEEP_ORDER")) {
    const std::string_view s(v);
    if (s == "1")
      config.keep_order = true;
    else if (s == "0")
      config.keep_order = false;
    else
      return Status::failure(ErrorKind::invalid_input, "VISCD_KEEP_ORDER=" + printable(s) + ": expected 1 or 0");
  }
  if (const char* v = std::getenv("VISCD_FOLLOW_CHANGE")) {
    const std::string_view s(v);
    if (s == "1")
      config.follow_change = true;
    else if (s == "0")
      config.follow_change = false;
    else
      return Status::failure(ErrorKind::invalid_input, "VISCD_FOLLOW_CHANGE=" + printable(s) + ": expected 1 or 0");
  }
  return {};
}

}  // namespace viscd
