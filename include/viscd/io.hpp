#pragma once
/// \file io.hpp
/// Reading spheres, boxes and cameras, writing pairs, stats and images.
/// Every reader's error names the file (or `source` name), the 1-based line and what was expected.

#include <cstdint>
#include <filesystem>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "viscd/config.hpp"
#include "viscd/frame.hpp"
#include "viscd/result.hpp"
#include "viscd/types.hpp"

namespace viscd {

/// `text` made safe to print inside a message: control characters, DEL and bytes that are not
/// part of valid UTF-8 are escaped (`\n`, `\t`, `\r`, `\xNN`), and text longer than `max_chars`
/// characters is cut with "…". Readers quote every field of the input through this.
[[nodiscard]] std::string printable(std::string_view text, std::size_t max_chars = 40);

/// XYZR text: one sphere per line as four numbers `x y z r` separated by blanks (or commas);
/// `#` starts a comment; blank lines are ignored. An empty file is zero spheres.
[[nodiscard]] Result<std::vector<Sphere>> parse_xyzr(std::string_view text, std::string_view source);
/// CSV with the header `x,y,z,r` (spaces allowed), then one sphere per line. The headers
/// parse_sphere_table() takes are read too: their group, mask and always_active columns are
/// checked and dropped (read them with parse_sphere_table).
[[nodiscard]] Result<std::vector<Sphere>> parse_csv(std::string_view text, std::string_view source);
/// Reads a sphere file: `.csv` is CSV, anything else XYZR.
[[nodiscard]] Result<std::vector<Sphere>> read_spheres(const std::filesystem::path& path);

/// Spheres and, where the file gives them, their collision filters.
struct SphereTable {
  std::vector<Sphere> spheres;
  /// One per sphere when the file has group and mask columns; else empty (no filtering).
  std::vector<Filter> filters;
  /// One per sphere (0 or 1) when the file has an always_active column; else empty
  /// (FrameInput::always_active).
  std::vector<std::uint8_t> always_active;
};
/// CSV with the header `x,y,z,r`, optionally followed by `group,mask` and then by
/// `always_active` (`x,y,z,r,always_active` and `x,y,z,r,group,mask,always_active` too). Group and
/// mask are unsigned 32-bit integers, decimal (`4294967295`) or hexadecimal (`0xFFFFFFFF`);
/// always_active is 0 or 1. Anything else, a value beyond 32 bits or a missing column is an error
/// naming the line and what was expected.
[[nodiscard]] Result<SphereTable> parse_sphere_table(std::string_view text, std::string_view source);
/// Reads a sphere file with its filters: `.csv` as parse_sphere_table, anything else XYZR (no filters).
[[nodiscard]] Result<SphereTable> read_sphere_table(const std::filesystem::path& path);

/// Boxes and, where the file gives them, their collision filters and always_active flags (as
/// SphereTable).
struct BoxTable {
  std::vector<Box> boxes;
  /// One per box when the file has group and mask columns; else empty (no filtering).
  std::vector<Filter> filters;
  /// One per box (0 or 1) when the file has an always_active column; else empty.
  std::vector<std::uint8_t> always_active;
};
/// CSV with the header `minx,miny,minz,maxx,maxy,maxz` (spaces allowed), optionally followed by
/// `group,mask` and then by `always_active`, exactly as parse_sphere_table() reads spheres; then
/// one box per line. Each value is a number as in a sphere file (finite, magnitude at most 1e18),
/// and min <= max on every axis (min = max is a flat box; on every axis, a point). Anything else,
/// a missing column or a header of a sphere file is an error naming the line and what was
/// expected. An empty text is zero boxes.
[[nodiscard]] Result<BoxTable> parse_box_table(std::string_view text, std::string_view source);
/// Reads a box file as parse_box_table, whatever its extension (boxes have no XYZR form).
[[nodiscard]] Result<BoxTable> read_box_table(const std::filesystem::path& path);

/// An object file of either kind.
struct ObjectTable {
  ShapeKind kind = ShapeKind::sphere;
  SphereTable spheres;  ///< the objects when kind is ShapeKind::sphere
  BoxTable boxes;       ///< the objects when kind is ShapeKind::box
  /// The 1-based line that told the kind (the CSV header, or an XYZR file's first sphere); 0 when
  /// the file has no such line (no objects: either kind).
  std::size_t kind_line = 0;
  /// The number of objects.
  [[nodiscard]] std::size_t size() const {
    return kind == ShapeKind::box ? boxes.boxes.size() : spheres.spheres.size();
  }
};
/// Reads spheres or boxes, the kind told by the file: a first line (not blank, not a `#` comment)
/// that starts with `minx` is a box header (read_box_table), anything else a sphere file
/// (read_sphere_table).
[[nodiscard]] Result<ObjectTable> read_object_table(const std::filesystem::path& path);

/// The tools' environment knobs, applied to `config` (the library itself reads no environment):
/// VISCD_SIMD=best|sse2|scalar sets Config::simd, VISCD_KEEP_ORDER=1|0 sets Config::keep_order,
/// VISCD_FOLLOW_CHANGE=1|0 sets Config::follow_change.
/// Unset variables change nothing; any other value is an error naming the variable and value.
[[nodiscard]] Status apply_environment(Config& config);

/// Camera JSON: {"eye":[x,y,z], "target":[x,y,z], "up":[0,1,0], "fov_y_deg":60, "near":0.1,
/// "far":1000, "width":1280, "height":720}. Missing keys take those defaults; unknown keys are errors.
[[nodiscard]] Result<Camera> parse_camera(std::string_view text, std::string_view source);
[[nodiscard]] Result<Camera> read_camera(const std::filesystem::path& path);
/// The camera as JSON, in the format parse_camera reads.
[[nodiscard]] std::string camera_json(const Camera& camera);

/// An output file written whole or not at all. Bytes go to a temporary file in the destination's
/// folder; commit() flushes it to disk and renames it over the destination in one step, so a
/// reader sees the previous file or the new one, never a part. A file destroyed uncommitted
/// (an error, a full disk) removes its temporary and leaves the destination untouched. A
/// destination that is a symbolic link is written where the link points. Move-only.
class AtomicFile {
 public:
  /// Creates the temporary beside `path` (and the parent folders). Fails naming the path and
  /// the system's reason, or when `path` is a folder.
  [[nodiscard]] static Result<AtomicFile> create(const std::filesystem::path& path);
  AtomicFile(AtomicFile&&) noexcept;
  AtomicFile& operator=(AtomicFile&&) noexcept;
  ~AtomicFile();
  /// Appends bytes. After the first failure every later call (and commit) fails with that error.
  [[nodiscard]] Status write(std::string_view bytes);
  /// Makes the bytes durable and renames the temporary onto the destination.
  [[nodiscard]] Status commit();
  /// The destination.
  [[nodiscard]] const std::filesystem::path& path() const;

 private:
  struct State;
  explicit AtomicFile(std::unique_ptr<State> state);
  std::unique_ptr<State> state_;
};

/// Writes spheres as CSV with header `x,y,z,r` (round-trips exactly: 9 significant digits).
[[nodiscard]] Status write_spheres_csv(const std::filesystem::path& path, std::span<const Sphere> spheres);
/// Writes boxes as CSV with header `minx,miny,minz,maxx,maxy,maxz` (round-trips exactly: 9
/// significant digits).
[[nodiscard]] Status write_boxes_csv(const std::filesystem::path& path, std::span<const Box> boxes);
/// Writes pairs as CSV with header `i,j`, one pair per line, in the given (sorted) order. The
/// text is streamed in blocks: memory use does not grow with the number of pairs.
[[nodiscard]] Status write_pairs_csv(const std::filesystem::path& path, std::span<const Pair> pairs);
[[nodiscard]] Status write_pairs_csv(AtomicFile& out, std::span<const Pair> pairs);
/// Frame stats as a JSON object (N, the static set's size, active, mu (null unless has_pixels or
/// has_camera), m, layout, pairs, per-stage ms).
[[nodiscard]] std::string stats_json(const FrameStats& stats, std::string_view backend);
/// Writes text to a file, creating parent folders; whole or not at all (AtomicFile).
[[nodiscard]] Status write_text(const std::filesystem::path& path, std::string_view text);
/// Writes an RGBA8 image (rows top to bottom) as PNG; whole or not at all.
[[nodiscard]] Status write_png(const std::filesystem::path& path, std::span<const std::uint8_t> rgba, int width,
                               int height);
[[nodiscard]] Status write_png(AtomicFile& out, std::span<const std::uint8_t> rgba, int width, int height);
/// FNV-1a 64 hash of the pairs in order: equal pair lists give equal hashes on every machine.
[[nodiscard]] std::uint64_t pairs_hash(std::span<const Pair> pairs);

}  // namespace viscd
