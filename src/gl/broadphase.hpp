#pragma once
// Stages 5-8 of the gl backend: Morton codes, their sort, the Karras hierarchy (build), the
// bottom-up box fit, the traversal with the pair buffer's growth and re-run on overflow, the
// pair sort, and the state pass that marks both objects of every pair colliding. The part owns
// the tree, the key and pair buffers and the frame's one final wait (FrameInfo with the pair
// count). Every pass reads the active count n from FrameInfo on the GPU and is dispatched from
// DispatchArgs, so that the work follows n while the host knows only a bound of it.

#include <cstdint>
#include <vector>

#include "core/geometry.hpp"
#include "core/lbvh.hpp"
#include "core/morton.hpp"
#include "gl/frame_data.hpp"
#include "gl/objects.hpp"
#include "gl/program.hpp"
#include "gl/radix_sort.hpp"
#include "gl/shaders/shared/layout.h"
#include "gl/stage_timers.hpp"
#include "viscd/config.hpp"
#include "viscd/frame.hpp"
#include "viscd/gl.hpp"
#include "viscd/result.hpp"

namespace viscd::gl {

class Broadphase {
 public:
  /// The part reads `config` (the detector's, which may change between frames) at each frame,
  /// and `options` once, in init().
  Broadphase(FrameData& frame, StageTimers& timers, const Config& config, const GlOptions& options)
      : frame_(frame), timers_(timers), config_(config), options_(options), sort_(frame) {}

  /// Builds the programs (the sort's too) and the pair buffer of GlOptions::initial_pair_capacity
  /// pairs. The context must be current.
  [[nodiscard]] Status init();
  /// Stages 5-8 over FrameInfo.active_count active objects (on the GPU) out of `objects`,
  /// dispatched from DispatchArgs; `n_bound` >= that count sizes the buffers. Objects from
  /// `static_from` on are static: no pair of two of them is found. Ends with the frame's one
  /// wait (frame_info() holds this frame's FrameInfo afterwards) and the pair sort. Returns the
  /// pair count, whose pairs (of object indices) lie sorted in pairs(); fails when they exceed
  /// Config::pair_memory_cap. Writes stats.pairs.
  [[nodiscard]] Result<std::uint32_t> run(std::uint32_t n_bound, std::uint32_t objects, std::uint32_t static_from,
                                          const detail::MortonLayout& layout, const detail::Aabb& bounds,
                                          FrameStats& stats);
  /// After run(): the sorted pairs, uvec2 (x = j, y = i) each.
  [[nodiscard]] const Buffer& pairs() const { return pairs_; }
  /// After run(): this frame's FrameInfo as the final wait read it back.
  [[nodiscard]] const shader::FrameInfo& frame_info() const { return frame_info_; }
  /// Stage 8's last part: both objects of each of the first `pairs` pairs become colliding in
  /// FrameData::states (stage 3 wrote free / culled).
  void mark_colliding(std::uint32_t pairs);
  /// Bytes held by the part's buffers, the sort's included (Detector::memory_bytes()).
  [[nodiscard]] std::uint64_t buffer_bytes() const;

  // ---- for tests (test_access.hpp); the caller makes the context current ----

  /// After run(): the sorted codes (widened), the sorted object ids, the tree with its leaf boxes
  /// (a core Lbvh, ready for validate_lbvh).
  [[nodiscard]] std::vector<std::uint64_t> read_sorted_codes();
  [[nodiscard]] std::vector<std::uint32_t> read_sorted_ids();
  void read_tree(detail::Lbvh& bvh, std::vector<detail::Aabb>& leaf_boxes);
  /// Pairs the pair buffer holds now (it grows to a frame's exact count on overflow).
  [[nodiscard]] std::uint32_t pair_capacity() const { return pair_capacity_; }

 private:
  /// Sizes the buffers of stages 5-7 for n active objects.
  void reserve(std::uint32_t n);

  FrameData& frame_;
  StageTimers& timers_;
  const Config& config_;
  const GlOptions& options_;
  RadixSort sort_;
  Program morton_, build_, fit_, query_, state_;
  // Buffers (see shaders/shared/layout.h for their contents).
  Buffer keys_[2], values_[2];                              // codes (uvec2) and object indices, ping-ponged by the sort
  Buffer nodes_, parent_, arrivals_, sorted_, leaf_boxes_;  // the tree and its fit
  Buffer pairs_, pairs_tmp_;                                // found pairs, and the pair sort's second buffer
  int sorted_in_ = 0;                                       // which keys_/values_ holds the last sorted codes
  std::uint32_t last_n_ = 0;                                // active count of the last run
  std::uint32_t pair_capacity_ = 0;
  shader::FrameInfo frame_info_{};  // this frame's, read back once by the final wait
};

}  // namespace viscd::gl
