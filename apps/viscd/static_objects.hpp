#pragma once
// The objects of a frame as the commands take them: the moving objects from --spheres or --boxes,
// the detector's static set from --static (pairs, query) or a generated field (run, view), and
// the numbers the outputs give static objects: static object k is N + k, after the N moving ones.

#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "detector_choice.hpp"
#include "viscd/io.hpp"
#include "viscd/result.hpp"
#include "viscd/viscd.hpp"

namespace viscd::app {

/// The moving objects: the sphere file `spheres` (read_sphere_table) or the box file `boxes`
/// (read_box_table), whichever is not empty (the caller checks that one is given).
[[nodiscard]] Result<ObjectTable> read_moving_objects(const std::string& spheres, const std::string& boxes);

/// The static set's file: spheres or boxes, which must be the moving objects' kind (`moving`, named
/// by `moving_option`: "--spheres", "--boxes"). A file of the other kind is an error naming the
/// file, the line that told its kind and what was expected. An always_active column is read and
/// changes nothing (static objects are never culled). Also refuses N + K objects beyond what the
/// 32-bit indices of the outputs can number (N = `moving_count`).
[[nodiscard]] Result<ObjectTable> read_static_objects(const std::filesystem::path& path, ShapeKind moving,
                                                      std::string_view moving_option, std::size_t moving_count);

/// Points `input` at the table's objects (spheres or boxes), filters and always_active flags.
void set_frame_objects(FrameInput& input, const ObjectTable& objects);

/// Hands the table's objects, with its filters when it has them, to `detector`'s static set
/// (set_static_spheres() or set_static_boxes(): object k of the file takes slot k).
[[nodiscard]] Status set_static_objects(Detector& detector, const ObjectTable& objects);

/// One frame of `input` on the chosen detector, with the static set `fixed` (possibly empty) handed
/// over first; when `--backend auto` chose gl and gl refuses the input, once more on cpu
/// (fall_back_from_auto_gl()). A static set the detector refuses fails with "--static: ...".
[[nodiscard]] Status detect_with_static(DetectorChoice& choice, const DetectorRequest& request, const Config& config,
                                        const ObjectTable& fixed, const FrameInput& input, FrameResult& frame);

/// Hands a generated field (static_field()) to `detector`'s static set, as spheres or as their
/// cubes (cubes_of()) for ShapeKind::box.
[[nodiscard]] Status set_static_field(Detector& detector, std::span<const Sphere> field, ShapeKind shape);

/// The number an output gives a reported index: moving object i is i, static object k
/// (static_index(k)) is n + k, with n the number of moving objects.
[[nodiscard]] constexpr std::uint32_t output_index(std::uint32_t index, std::uint32_t n) {
  return is_static_index(index) ? n + static_slot(index) : index;
}

/// Renumbers pairs in place by output_index(). Sorted pairs stay sorted: a pair's i is moving,
/// n + k lies above every moving index, and static_index(k) ascends with k as n + k does.
void number_pairs(std::span<Pair> pairs, std::uint32_t n);

}  // namespace viscd::app
