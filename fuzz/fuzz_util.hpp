#pragma once
// Helpers shared by the fuzz targets: reporting a failed check.

#include <cstddef>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <string_view>

namespace viscd::fuzz {

/// True when `s` holds a control character: a byte below 0x20, or 0x7f.
inline bool has_control_character(std::string_view s) {
  for (const char c : s)
    if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) return true;
  return false;
}

/// `s` with control characters and bytes >= 0x80 written as \xNN and cut to `limit` bytes, so
/// that it prints safely on a terminal.
inline std::string printable(std::string_view s, std::size_t limit = 300) {
  std::string out;
  for (std::size_t i = 0; i < s.size() && i < limit; ++i) {
    const auto c = static_cast<unsigned char>(s[i]);
    if (c >= 0x20 && c < 0x7f) {
      out += static_cast<char>(c);
    } else {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\x%02x", c);
      out += buf;
    }
  }
  if (s.size() > limit) out += "...";
  return out;
}

/// Prints "<target>: <what>: <detail>" to stderr and aborts: libFuzzer then saves the input as
/// a reproducer and exits non-zero.
[[noreturn]] inline void fail(const char* target, const char* what, std::string_view detail = {}) {
  std::fprintf(stderr, "%s: %s%s%s\n", target, what, detail.empty() ? "" : ": ", printable(detail).c_str());
  std::abort();
}

}  // namespace viscd::fuzz
