#pragma once
// The gl backend's stage timers: a GL_TIMESTAMP query before and after each GPU stage, in two
// sets so that one frame's queries are read while the next frame records into the other. Reading
// one frame late means that reading never waits for the GPU (FrameStats::stage_ms of frame f
// holds frame f-1's GPU times); wait_for_last() is the exception, for callers who want the
// frame that just ended.

#include <array>
#include <cstddef>

#include "gl/objects.hpp"
#include "viscd/frame.hpp"

namespace viscd::gl {

class StageTimers {
 public:
  /// Intervals per stage. A stage's GPU time is the sum of its parts, so that a stage split by a
  /// host wait (stage 8: traversal | wait for the pair count | pair sort | states) counts GPU
  /// work only.
  static constexpr std::size_t kParts = 3;

  /// Creates the queries when the driver's GL_TIMESTAMP has bits (GL_QUERY_COUNTER_BITS > 0);
  /// without them every call below does nothing. The context must be current.
  void init();
  /// Whether the driver has timestamps (init() created the queries).
  [[nodiscard]] bool available() const { return ok_; }
  /// Timestamps at the start and the end of one part of stage `s` in this frame's set.
  void begin(Stage s, std::size_t part = 0);
  void end(Stage s, std::size_t part = 0);
  /// At the end of a frame: the previous frame's times into stats.stage_ms (a stage whose
  /// queries are not all available yet is left as it is; `layout` is left alone, it is timed on
  /// the host), then this frame's set becomes the previous one.
  void read_previous(FrameStats& stats);
  /// After read_previous(): the times of the frame that just ended, waiting for the GPU to reach
  /// its queries (Detector::wait_for_stage_times).
  void wait_for_last(FrameStats& stats);

 private:
  // Two sets (frames) of a begin and an end query per stage and part, and which parts a frame used.
  std::array<std::array<Query, 2 * kStageCount * kParts>, 2> queries_;
  std::array<std::array<bool, kStageCount * kParts>, 2> used_{};
  int frame_ = 0;  // the set this frame records into
  bool ok_ = false;
};

}  // namespace viscd::gl
