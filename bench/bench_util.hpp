#pragma once
// Small helpers shared by the benchmark executables: a wall clock, order statistics, CSV output.

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <initializer_list>
#include <string>
#include <vector>

#include "viscd/config.hpp"
#include "viscd/io.hpp"

namespace viscd::bench {

/// Config{} with the tools' environment knobs applied (VISCD_SIMD, VISCD_KEEP_ORDER; viscd/io.hpp);
/// a bad value ends the benchmark with the message.
[[nodiscard]] inline Config bench_config() {
  Config c;
  if (Status s = apply_environment(c); !s) {
    std::fprintf(stderr, "%s\n", s.error().c_str());
    std::exit(2);
  }
  return c;
}

using Clock = std::chrono::steady_clock;

/// Milliseconds from `start` to now.
[[nodiscard]] inline double ms_since(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

/// Median (mean of the two middle values for an even count); 0 for no samples.
[[nodiscard]] inline double median(std::vector<double> v) {
  if (v.empty()) return 0;
  const std::size_t h = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(h), v.end());
  const double upper = v[h];
  if (v.size() % 2 == 1) return upper;
  const double lower = *std::max_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(h));
  return 0.5 * (lower + upper);
}

/// Arithmetic mean; 0 for no samples.
[[nodiscard]] inline double mean(const std::vector<double>& v) {
  if (v.empty()) return 0;
  double sum = 0;
  for (const double x : v) sum += x;
  return sum / static_cast<double>(v.size());
}

/// Smallest sample; 0 for no samples.
[[nodiscard]] inline double minimum(const std::vector<double>& v) {
  return v.empty() ? 0 : *std::min_element(v.begin(), v.end());
}

/// A CSV file written row by row; does nothing when opened with an empty path.
class CsvWriter {
 public:
  /// Opens `path` (truncating) and writes the header; `ok()` tells whether it could.
  CsvWriter(const std::string& path, std::initializer_list<const char*> header) {
    if (path.empty()) return;
    file_.open(path);
    row(std::vector<std::string>(header.begin(), header.end()));
  }
  [[nodiscard]] bool ok() const { return !file_.is_open() || file_.good(); }
  /// Cells holding a comma, a quote or a line break are quoted (RFC 4180: quotes doubled).
  void row(const std::vector<std::string>& cells) {
    if (!file_.is_open()) return;
    for (std::size_t c = 0; c < cells.size(); ++c) {
      const std::string& v = cells[c];
      file_ << (c ? "," : "");
      if (v.find_first_of(",\"\r\n") == std::string::npos) {
        file_ << v;
        continue;
      }
      file_ << '"';
      for (const char ch : v) file_ << (ch == '"' ? "\"\"" : std::string(1, ch));
      file_ << '"';
    }
    file_ << '\n';
    file_.flush();
  }

 private:
  std::ofstream file_;
};

/// printf-style formatting into a std::string.
template <class... Args>
[[nodiscard]] std::string format(const char* fmt, Args... args) {
  const int n = std::snprintf(nullptr, 0, fmt, args...);
  std::string s(static_cast<std::size_t>(std::max(n, 0)), '\0');
  std::snprintf(s.data(), s.size() + 1, fmt, args...);
  return s;
}

}  // namespace viscd::bench
