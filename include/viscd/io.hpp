#pragma once
/// \file io.hpp
/// Reading spheres and cameras, writing pairs, stats and images.
/// Every reader's error names the file (or `source` name), the 1-based line and what was expected.

#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "viscd/frame.hpp"
#include "viscd/result.hpp"
#include "viscd/types.hpp"

namespace viscd {

/// XYZR text: one sphere per line as four numbers `x y z r` separated by blanks (or commas);
/// `#` starts a comment; blank lines are ignored. An empty file is zero spheres.
[[nodiscard]] Result<std::vector<Sphere>> parse_xyzr(std::string_view text, std::string_view source);
/// CSV with the header `x,y,z,r` (spaces allowed), then one sphere per line.
[[nodiscard]] Result<std::vector<Sphere>> parse_csv(std::string_view text, std::string_view source);
/// Reads a sphere file: `.csv` is CSV, anything else XYZR.
[[nodiscard]] Result<std::vector<Sphere>> read_spheres(const std::filesystem::path& path);

/// Camera JSON: {"eye":[x,y,z], "target":[x,y,z], "up":[0,1,0], "fov_y_deg":60, "near":0.1,
/// "far":1000, "width":1280, "height":720}. Missing keys take those defaults; unknown keys are errors.
[[nodiscard]] Result<Camera> parse_camera(std::string_view text, std::string_view source);
[[nodiscard]] Result<Camera> read_camera(const std::filesystem::path& path);
/// The camera as JSON, in the format parse_camera reads.
[[nodiscard]] std::string camera_json(const Camera& camera);

/// Writes spheres as CSV with header `x,y,z,r` (round-trips exactly: 9 significant digits).
[[nodiscard]] Status write_spheres_csv(const std::filesystem::path& path, std::span<const Sphere> spheres);
/// Writes pairs as CSV with header `i,j`, one pair per line, in the given (sorted) order.
[[nodiscard]] Status write_pairs_csv(const std::filesystem::path& path, std::span<const Pair> pairs);
/// Frame stats as a JSON object (N, active, mu, m, layout, pairs, per-stage ms).
[[nodiscard]] std::string stats_json(const FrameStats& stats, std::string_view backend);
/// Writes text to a file, creating parent folders.
[[nodiscard]] Status write_text(const std::filesystem::path& path, std::string_view text);
/// Writes an RGBA8 image (rows top to bottom) as PNG.
[[nodiscard]] Status write_png(const std::filesystem::path& path, std::span<const std::uint8_t> rgba, int width,
                               int height);
/// FNV-1a 64 hash of the pairs in order: equal pair lists give equal hashes on every machine.
[[nodiscard]] std::uint64_t pairs_hash(std::span<const Pair> pairs);

}  // namespace viscd
