#pragma once
// The gl backend: every stage of the frame (docs/architecture.md) runs in OpenGL 4.5 compute
// shaders (and one instanced draw for the visibility map). GlDetector is the Backend and the
// frame's list of stages; each stage's programs and buffers belong to a part of its own:
//   Visibility     (visibility.*)      stages 1, 2 and 9: G-buffer, pixel counts, shading
//   Culling        (cull.*)            stage 3: cull, filters, compaction, dispatch sizes
//   LayoutChooser  (layout_chooser.*)  stage 4: bounds on the GPU, m and the layout on the host
//   Broadphase     (broadphase.*)      stages 5-8: codes, sort (RadixSort, radix_sort.*), build,
//                                      fit, query, pair sort, states
//   Readback       (readback.*)        pairs, states, pixels, and the queries' copy
//   StageTimers    (stage_timers.*)    GPU times per stage, read a frame late
// and the data they pass between them is a FrameData (frame_data.hpp). Tests reach the parts
// through GlInspector (test_access.hpp).
//
// Two modes (GlOptions::sync_layout, docs/gl.md):
//   default (sync_layout = false): no host wait between the start of the frame and its final
//      readback. m and the Morton layout are chosen on the host (core/morton.hpp, as the cpu
//      backend) from the PREVIOUS frame's FrameInfo (active count, active-centre bounds,
//      diameter sum, pixel total), which the host read with that frame's pair count. Every
//      pass after culling is sized by this frame's active count n through indirect dispatch
//      (DispatchArgs, written on the GPU from FrameInfo), and reads n from FrameInfo. The
//      first frame, and a frame whose N, or whether it counts pixels (a camera or the caller's
//      map), differs from the previous frame's, run as sync_layout.
//   sync_layout = true: one wait after stage 4's bounds passes for this frame's FrameInfo; m and
//      the layout are then exactly the cpu backend's (bit-identical codes).
// In both modes the frame ends with one wait, for FrameInfo (the pair count: grow the pair
// buffer and re-run on overflow; n and the values the next frame uses), then the results the
// caller asked for (pairs, states, pixels, image) are read back.
// The decisions that do not depend on where a stage runs (map size, m, the Morton layout and
// grid, culling, shading) are core's (src/core), shared with the cpu backend.

#include <cstdint>
#include <memory>
#include <string_view>
#include <vector>

#include "core/backend.hpp"
#include "core/with_static.hpp"
#include "gl/broadphase.hpp"
#include "gl/context.hpp"
#include "gl/cull.hpp"
#include "gl/frame_data.hpp"
#include "gl/layout_chooser.hpp"
#include "gl/readback.hpp"
#include "gl/stage_timers.hpp"
#include "gl/visibility.hpp"
#include "viscd/gl.hpp"

namespace viscd::gl {

class GlDetector final : public detail::Backend {
 public:
  /// A detector with its own EGL context, or the caller's (GlOptions::use_current_context), and
  /// every program built. Fails with the step's message.
  [[nodiscard]] static Result<std::unique_ptr<GlDetector>> create(const Config& config, const GlOptions& options);
  /// Makes the context current, so that the parts can delete their GL objects.
  ~GlDetector() override;

  [[nodiscard]] std::string_view name() const override { return "gl"; }
  [[nodiscard]] std::uint64_t memory_bytes() const override;
  void wait_for_stage_times(FrameStats& stats) override;

 protected:
  /// The frame: any input detect() accepts, boxes, the static set, filters and the caller's id
  /// map (an array, or FrameInput::gl_id_texture) included.
  [[nodiscard]] Status run_frame(const FrameInput& input, FrameResult& out) override;
  // Queries: the frame's objects, states and filters stay on the GPU; the first query after a
  // frame reads them back once (Readback; no host copy in frames nobody queries), then Backend's
  // brute force searches the active ones and the static set's.
  [[nodiscard]] bool answers_queries() const override { return true; }
  [[nodiscard]] detail::QueryObjects query_objects() override;

 private:
  friend class GlInspector;  // test access to the parts (test_access.hpp)

  GlDetector(const Config& config, const GlOptions& options, std::unique_ptr<Context> ctx);
  [[nodiscard]] Status init();
  /// The context's debug errors and glGetError()'s since the last call, as a failure naming
  /// `where`; success when there are none.
  [[nodiscard]] Status gl_errors(const char* where);
  /// run_frame() without the bad_alloc guard: the stages in order.
  [[nodiscard]] Status detect_frame(const FrameInput& in, FrameResult& out);
  /// Uploads the objects, the static set's after the frame's (and filters), sizes the per-object
  /// buffers, zeroes FrameInfo, sets up the camera and the map's pixel scale (FrameData).
  void begin_frame(const FrameInput& in);

  GlOptions options_;
  std::unique_ptr<Context> ctx_;
  // Work groups per dispatch (x), read once: passes over objects are one-dimensional, so it
  // bounds N.
  std::uint32_t max_groups_ = 65535;
  // Declared after ctx_, every GL object below is deleted before the context is released, and
  // ~GlDetector has made it current. The parts hold config_, options_, timers_ and frame_ by
  // reference: declared after them, they are destroyed first.
  StageTimers timers_;
  detail::WithStatic all_;  // this frame's objects with the static set's, on the host
  FrameData frame_;
  Visibility visibility_;
  Culling culling_;
  LayoutChooser layout_;
  Broadphase broadphase_;
  Readback readback_;
};

}  // namespace viscd::gl
