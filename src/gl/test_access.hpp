#pragma once
// For tests only: GlInspector reaches into a GlDetector's parts for what no engine calls: a
// broadphase over a given active set, the sorted codes and ids, the tree, the pair capacity, the
// mid-frame wait count, the id map, counting a given map, changing GlOptions on a live detector,
// the device string. It is a friend of GlDetector, so that the backend's own interface stays the
// Backend's. Each call that uses GL makes the detector's context current first, as a frame does.

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "core/geometry.hpp"
#include "core/lbvh.hpp"
#include "core/shapes.hpp"
#include "gl/gl_detector.hpp"
#include "viscd/frame.hpp"
#include "viscd/gl.hpp"
#include "viscd/result.hpp"
#include "viscd/types.hpp"

namespace viscd::gl {

class GlInspector {
 public:
  /// Inspects `detector`, which must outlive the inspector.
  explicit GlInspector(GlDetector& detector) : d_(&detector) {}

  /// Replaces the detector's GlOptions; the next frame uses them (initial_pair_capacity and
  /// use_current_context apply only at creation).
  void set_options(const GlOptions& options);
  /// "llvmpipe (LLVM 15.0.6, 256 bits) | 4.5 (Core Profile) Mesa 22.3.6"
  [[nodiscard]] const std::string& device() const;
  /// Frames so far that waited mid-frame for their own FrameInfo (LayoutChooser::mid_frame_waits).
  [[nodiscard]] std::uint64_t mid_frame_waits() const;
  /// Pairs the pair buffer holds now (Broadphase).
  [[nodiscard]] std::uint32_t pair_capacity() const;

  /// Stages 5-8 alone over a given active set (ascending) of `objects` (spheres, or boxes with
  /// their box_proxy() for stages 4-6), with the layout and bounds computed on the host as the
  /// cpu backend does them: writes the sorted pairs (of object indices) and
  /// stats.bits/layout/active/objects/pairs. Objects from `static_from` on are treated as
  /// static: never paired with each other. Queries see no objects afterwards.
  [[nodiscard]] Status run_broadphase(const detail::Shapes& objects, std::span<const std::uint32_t> active, int bits,
                                      std::vector<Pair>& pairs, FrameStats& stats,
                                      std::uint32_t static_from = 0xFFFFFFFFu);
  /// After a frame or run_broadphase(): sorted codes (widened), sorted object ids, the tree with
  /// its leaf boxes (a core Lbvh, ready for validate_lbvh).
  [[nodiscard]] std::vector<std::uint64_t> read_sorted_codes();
  [[nodiscard]] std::vector<std::uint32_t> read_sorted_ids();
  void read_tree(detail::Lbvh& bvh, std::vector<detail::Aabb>& leaf_boxes);
  /// After a frame with a camera: the id map, rows top to bottom (object index + 1, 0 = none).
  [[nodiscard]] std::vector<std::uint32_t> read_id_map();
  /// Stage 2 alone on a given id map (rows top to bottom) of `objects` objects, in the current
  /// counter mode; the counts per object.
  [[nodiscard]] Result<std::vector<std::uint32_t>> count_id_map(std::span<const std::uint32_t> ids, int width,
                                                                int height, std::uint32_t objects);

 private:
  GlDetector* d_;
};

}  // namespace viscd::gl
