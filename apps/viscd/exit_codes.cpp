// The tool's error messages on stderr, each ending a command with its exit code.
#include "exit_codes.hpp"

#include <cstdio>

namespace viscd::app {

int fail(const std::string& message) {
  std::fprintf(stderr, "viscd: error: %s\n", message.c_str());
  return kExitFailed;
}

int usage_fail(const std::string& message) {
  std::fprintf(stderr, "viscd: error: %s\n", message.c_str());
  return kExitUsage;
}

}  // namespace viscd::app
