#pragma once
// Stage 3 of the gl backend: culling and the compaction into the tree's list. Per object, the
// pixels, the active flag and the first state (free / culled); with filters, the objects that
// can pair with none kept out of the tree; an exclusive scan of the flags and the compaction
// into FrameData::active (ascending, as the cpu backend's list); the active count into
// FrameInfo; and the work-group counts of every later pass written on the GPU from that count
// (FrameData::dispatch). Its own buffers (flags, scan) live only within the stage.

#include <cstdint>

#include "gl/frame_data.hpp"
#include "gl/objects.hpp"
#include "gl/program.hpp"
#include "gl/stage_timers.hpp"
#include "viscd/config.hpp"
#include "viscd/result.hpp"

namespace viscd::gl {

class Culling {
 public:
  /// The part reads `config` (the detector's, which may change between frames) at each frame.
  Culling(FrameData& frame, StageTimers& timers, const Config& config)
      : frame_(frame), timers_(timers), config_(config) {}

  /// Builds the programs. The context must be current.
  [[nodiscard]] Status init();
  /// Sizes the flags and scan buffers for `objects` objects.
  void reserve(std::uint32_t objects);
  /// Stage 3 over `objects` objects, the first `moving` of them the frame's and the rest static
  /// (always active, never counted): reads FrameData::counts and writes FrameData::pixels of the
  /// moving ones when pixels are counted; writes FrameData::states, active, FrameInfo's active
  /// count (static objects included), visible count (moving ones only), pixel total and filter
  /// OR, and DispatchArgs.
  void cull(std::uint32_t objects, std::uint32_t moving);
  /// Writes DispatchArgs from FrameInfo.active_count (one invocation on the GPU).
  void write_dispatch_args();
  /// Bytes held by the part's buffers (Detector::memory_bytes()).
  [[nodiscard]] std::uint64_t buffer_bytes() const;

 private:
  /// Exclusive scan of n uints (three dispatches, reduce-then-scan); leaves the total in
  /// block_sums_[ceil(n / VISCD_SCAN_BLOCK)].
  void scan(GLuint in, GLuint out, std::uint32_t n);

  FrameData& frame_;
  StageTimers& timers_;
  const Config& config_;
  Program scan_local_, scan_blocks_, scan_add_, cull_, pairable_, compact_, dispatch_args_;
  Buffer flags_;       // uint per object: 1 = into the tree (active and, with filters, pairable)
  Buffer scan_out_;    // uint per object: the exclusive scan of flags_, each active object's place
  Buffer block_sums_;  // the scan's per-block sums, then the total
};

}  // namespace viscd::gl
