#pragma once
// Stage 4 of the gl backend: the Morton width m and layout. The GPU measures the active centres'
// bounds and diameter sum into FrameInfo; the host chooses m and the layout with core's rules
// (core/morton.hpp, as the cpu backend) from this frame's FrameInfo (a mid-frame wait:
// GlOptions::sync_layout, a first frame, or a change of N or of whether pixels are counted) or
// from the previous frame's, which the final wait of that frame read anyway (the default mode:
// no wait).
// This part keeps those previous-frame values and counts the mid-frame waits.

#include <cstdint>

#include "core/geometry.hpp"
#include "core/morton.hpp"
#include "gl/frame_data.hpp"
#include "gl/objects.hpp"
#include "gl/program.hpp"
#include "gl/shaders/shared/layout.h"
#include "gl/stage_timers.hpp"
#include "viscd/config.hpp"
#include "viscd/frame.hpp"
#include "viscd/gl.hpp"
#include "viscd/result.hpp"

namespace viscd::gl {

/// What stage 4 chose for stages 5-8.
struct LayoutChoice {
  detail::MortonLayout layout;
  detail::Aabb bounds;        ///< the quantisation bounds (active centres)
  std::uint32_t n_bound = 0;  ///< sizes the buffers of stages 5-8: n when known, else N
};

class LayoutChooser {
 public:
  /// The part reads `config` and `options` (the detector's, which may change between frames) at
  /// each frame.
  LayoutChooser(FrameData& frame, StageTimers& timers, const Config& config, const GlOptions& options)
      : frame_(frame), timers_(timers), config_(config), options_(options) {}

  /// Builds the programs. The context must be current.
  [[nodiscard]] Status init();
  /// Sizes the bounds partials for `objects` objects.
  void reserve(std::uint32_t objects);
  /// Stage 4's inputs on the GPU, dispatched from DispatchArgs: the bounds of the active centres
  /// and their diameter sum into FrameInfo.
  void measure_extent();
  /// Stage 4 on the host: m and the layout for a frame of `objects` objects, the first `moving`
  /// of them the frame's (mu is theirs) and the rest static; writes stats.bits, stats.layout and
  /// stats.ms(Stage::layout) (host time, the mid-frame wait included).
  [[nodiscard]] LayoutChoice choose(std::uint32_t objects, std::uint32_t moving, bool has_pixels, FrameStats& stats);
  /// After the broadphase's final wait read `info` (this frame's FrameInfo): this frame's pair
  /// count, active count and mu (over its `moving` objects) into stats, and kept as the next
  /// frame's layout inputs.
  void remember(std::uint32_t moving, bool has_pixels, const shader::FrameInfo& info, FrameStats& stats);
  /// Frames so far that waited mid-frame for their own FrameInfo (sync_layout, a first frame,
  /// or a change of N or of whether pixels are counted); default-mode frames do not count.
  [[nodiscard]] std::uint64_t mid_frame_waits() const { return mid_frame_waits_; }
  /// Bytes held by the part's buffers (Detector::memory_bytes()).
  [[nodiscard]] std::uint64_t buffer_bytes() const { return static_cast<std::uint64_t>(partials_.size()); }

 private:
  FrameData& frame_;
  StageTimers& timers_;
  const Config& config_;
  const GlOptions& options_;
  Program bounds_, bounds_fold_;
  Buffer partials_;  // shader::BoundsPartial per work group of bounds.comp
  // The previous frame's values, the default mode's source of m, the layout and the bounds.
  bool have_prev_ = false;
  shader::FrameInfo prev_info_{};  // its active count, active-centre bounds, diameter sum
  double prev_mean_pixels_ = 0.0;  // its mu
  std::uint32_t prev_moving_ = 0;  // its N
  bool prev_pixels_ = false;       // it counted pixels (a camera or the caller's map)
  std::uint64_t mid_frame_waits_ = 0;
};

}  // namespace viscd::gl
