#pragma once
// Memory: how much this process may still use (for the default --max-pair-memory), and byte
// sizes as the options take and the messages print them.

#include <cstdint>
#include <string>
#include <string_view>

#include "viscd/result.hpp"

namespace viscd::app {

/// Memory this process may still use, in bytes: the least of the system's available memory
/// (MemAvailable), the address-space limit and the cgroup's limit. 0 when none can be read.
[[nodiscard]] std::uint64_t available_memory_bytes();
/// The default pair memory cap: 1/8 of available_memory_bytes() (a frame's pair buffers take
/// several times the pairs' own 8 bytes), or 0 (no cap) when that is unknown. Measured once.
[[nodiscard]] std::uint64_t default_pair_memory_cap();
/// Parses a byte size: "0", "1048576", "512K", "64M", "1.5G", "2T" (binary units); "auto" is
/// default_pair_memory_cap(). The error names `option`.
[[nodiscard]] Result<std::uint64_t> parse_bytes(std::string_view text, std::string_view option);
/// "1.5 GiB".
[[nodiscard]] std::string format_bytes(std::uint64_t bytes);

}  // namespace viscd::app
