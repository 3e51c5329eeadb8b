// Available memory from /proc and the cgroup, and byte sizes as text.
#include "memory.hpp"

#include <sys/resource.h>

#include <charconv>
#include <cstdio>
#include <cstdlib>
#include <fstream>

#include "viscd/io.hpp"

namespace viscd::app {

std::uint64_t available_memory_bytes() {
  std::uint64_t best = 0;
  auto consider = [&](std::uint64_t v) {
    if (v > 0 && (best == 0 || v < best)) best = v;
  };
  {
    std::ifstream meminfo("/proc/meminfo");
    std::string key;
    std::uint64_t kib = 0;
    std::string unit;
    while (meminfo >> key >> kib >> unit)
      if (key == "MemAvailable:") consider(kib * 1024);
  }
  rlimit as{};
  if (getrlimit(RLIMIT_AS, &as) == 0 && as.rlim_cur != RLIM_INFINITY) {
    // The limit counts the address space already mapped too.
    std::ifstream status("/proc/self/status");
    std::uint64_t used_kib = 0;
    std::string line;
    while (std::getline(status, line))
      if (line.rfind("VmSize:", 0) == 0) used_kib = std::strtoull(line.c_str() + 7, nullptr, 10);
    const std::uint64_t limit = as.rlim_cur, used = used_kib * 1024;
    consider(limit > used ? limit - used : 1);
  }
  {
    std::ifstream max_file("/sys/fs/cgroup/memory.max"), current_file("/sys/fs/cgroup/memory.current");
    std::string max_text;
    std::uint64_t current = 0;
    if (max_file >> max_text && max_text != "max" && current_file >> current) {
      const std::uint64_t max = std::strtoull(max_text.c_str(), nullptr, 10);
      if (max > 0) consider(max > current ? max - current : 1);
    }
  }
  return best;
}

std::uint64_t default_pair_memory_cap() {
  static const std::uint64_t cap = available_memory_bytes() / 8;
  return cap;
}

Result<std::uint64_t> parse_bytes(std::string_view text, std::string_view option) {
  using R = Result<std::uint64_t>;
  if (text == "auto") return default_pair_memory_cap();
  double v = 0;
  const auto [p, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
  std::string_view unit = text.substr(static_cast<std::size_t>(p - text.data()));
  if (unit.ends_with("iB") || unit.ends_with("ib")) unit.remove_suffix(2);
  if (unit.size() == 2 && (unit[1] == 'B' || unit[1] == 'b')) unit.remove_suffix(1);
  double scale = 0;
  if (unit.empty() || unit == "B" || unit == "b")
    scale = 1;
  else if (unit == "K" || unit == "k")
    scale = 1024.0;
  else if (unit == "M" || unit == "m")
    scale = 1024.0 * 1024;
  else if (unit == "G" || unit == "g")
    scale = 1024.0 * 1024 * 1024;
  else if (unit == "T" || unit == "t")
    scale = 1024.0 * 1024 * 1024 * 1024;
  const double bytes = v * scale;
  if (ec != std::errc() || p == text.data() || scale == 0 || !(bytes >= 0) || bytes > 9.0e18)
    return R::failure(
        ErrorKind::invalid_input,
        std::string(option) + ": expected a size such as 512M, 4G or 0 (no cap), got '" + printable(text) + "'");
  return static_cast<std::uint64_t>(bytes);
}

std::string format_bytes(std::uint64_t bytes) {
  char buf[32];
  const char* units[] = {"bytes", "KiB", "MiB", "GiB", "TiB"};
  double v = static_cast<double>(bytes);
  int u = 0;
  while (v >= 1024 && u < 4) v /= 1024, ++u;
  std::snprintf(buf, sizeof buf, u == 0 ? "%.0f %s" : "%.1f %s", v, units[u]);
  return buf;
}

}  // namespace viscd::app
