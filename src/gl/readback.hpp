#pragma once
// What the gl backend reads back to the host: each frame's pairs, states and pixels, and, for
// the queries (ray_cast, ray_cast_all, overlap), the frame's objects (spheres or boxes, the
// static set's included) and states, read once on the first query after a frame, so that frames
// nobody queries read nothing more (with the frame's filters, when it had any, for queries with a
// filter). The queries then search the active objects by brute force with core's functions.

#include <cstdint>
#include <span>
#include <vector>

#include "core/brute_queries.hpp"
#include "gl/context.hpp"
#include "gl/frame_data.hpp"
#include "gl/objects.hpp"
#include "viscd/frame.hpp"
#include "viscd/types.hpp"

namespace viscd::gl {

class Readback {
 public:
  /// `ctx`: the detector's context, made current by the first query after a frame.
  Readback(FrameData& frame, const Context& ctx) : frame_(frame), ctx_(ctx) {}

  /// The objects and states on the GPU are now those of a frame of `objects` objects, the first
  /// `moving` of them the frame's and the rest the static set's, in `slots` (kept, so that
  /// queries report them as static_index(slot) whatever the set does after the frame); 0 objects
  /// for a stage test, which queries must not see. The query copy is out of date.
  void begin_frame(std::uint32_t objects, std::uint32_t moving, std::span<const std::uint32_t> slots);
  /// The first `count` pairs of `sorted` (uvec2 x = j, y = i) into `pairs` as Pair {i, j}.
  void read_pairs(const Buffer& sorted, std::uint32_t count, std::vector<Pair>& pairs);
  /// FrameData::states into out.state, and with `has_pixels` FrameData::pixels into out.pixels
  /// (cleared without).
  void read_states_and_pixels(std::uint32_t objects, bool has_pixels, FrameResult& out);
  /// The last frame's active objects for the brute-force queries of Backend: their shapes, ids
  /// (static objects as static_index(slot), after the moving ones) and (in frames with filters)
  /// filters, read back on the first call after a frame. The spans stay valid until the next
  /// frame.
  [[nodiscard]] detail::QueryObjects query_objects();

 private:
  /// Reads the last frame's objects, states and filters back once per frame and keeps the
  /// active ones.
  void read_active_objects();

  FrameData& frame_;
  const Context& ctx_;
  std::vector<std::uint32_t> state_words_;  // the states as the GPU holds them, one uint each
  // The last frame's active objects for queries, read back on the first query after it.
  bool query_copy_ready_ = false;
  std::uint32_t query_objects_ = 0, query_moving_ = 0;  // objects of the last frame, and N
  bool query_boxes_ = false;                            // they were boxes
  std::vector<std::uint32_t> static_ids_;               // static_index(slot) of its static objects
  std::vector<Sphere> query_all_, query_active_;
  std::vector<Box> query_all_boxes_, query_active_boxes_;
  std::vector<std::uint32_t> query_ids_;
  std::vector<Filter> query_all_filters_, query_active_filters_;  // empty in frames without filters
};

}  // namespace viscd::gl
