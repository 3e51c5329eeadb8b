#pragma once
// The tools' input files that viscd/io.hpp does not read as such: the caller's raw id map
// (`pairs --id-map`) and a camera file that may not be given (`--camera`).

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "viscd/result.hpp"
#include "viscd/types.hpp"

namespace viscd::app {

/// Reads a camera JSON file, or nothing when `path` is empty (the option was not given).
[[nodiscard]] Result<std::optional<Camera>> read_optional_camera(const std::string& path);
/// Reads a raw id map: width x height little-endian uint32 ids, row-major from the top-left. A
/// file of another size than width * height * 4 bytes is an error naming both sizes.
[[nodiscard]] Result<std::vector<std::uint32_t>> read_id_map(const std::filesystem::path& path, int width, int height);

}  // namespace viscd::app
