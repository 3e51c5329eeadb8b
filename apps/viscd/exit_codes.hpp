#pragma once
// The tool's exit codes, and the two ways a command reports an error and ends with one.

#include <string>

namespace viscd::app {

/// Exit codes of the tool (docs/usage.md).
inline constexpr int kExitOk = 0;
inline constexpr int kExitFailed = 1;        ///< bad input file, or a run that failed
inline constexpr int kExitUsage = 2;         ///< unknown option, bad option value
inline constexpr int kExitHashMismatch = 3;  ///< --validate-hash differs

/// Prints "viscd: error: <msg>" to stderr and returns kExitFailed.
int fail(const std::string& message);
/// Prints "viscd: error: <msg>" to stderr and returns kExitUsage (a bad option or value).
int usage_fail(const std::string& message);

}  // namespace viscd::app
