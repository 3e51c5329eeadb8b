// The gl backend's stage timers (stage_timers.hpp): GL_TIMESTAMP pairs per stage and part, two
// sets in flight, read one frame late.
#include "gl/stage_timers.hpp"

namespace viscd::gl {
namespace {

// Sums a set's intervals per stage into stats.stage_ms; `wait`: block until each is known,
// else skip a stage whose queries are not all available yet.
template <class Queries, class Used>
void sum_intervals(const Queries& queries, const Used& used, std::size_t parts, bool wait, FrameStats& stats) {
  for (std::size_t stage = 0; stage < kStageCount; ++stage) {
    if (static_cast<Stage>(stage) == Stage::layout) continue;  // timed on the host
    double ms = 0;
    bool any = false, ready = true;
    for (std::size_t part = 0; part < parts && ready; ++part) {
      const std::size_t k = stage * parts + part;
      if (!used[k]) continue;
      if (!wait) {
        GLint available = 0;
        glGetQueryObjectiv(queries[2 * k + 1].get(), GL_QUERY_RESULT_AVAILABLE, &available);
        if (!available) ready = false;
        if (!ready) break;
      }
      GLuint64 t0 = 0, t1 = 0;
      glGetQueryObjectui64v(queries[2 * k].get(), GL_QUERY_RESULT, &t0);
      glGetQueryObjectui64v(queries[2 * k + 1].get(), GL_QUERY_RESULT, &t1);
      ms += t1 >= t0 ? static_cast<double>(t1 - t0) * 1e-6 : 0.0;
      any = true;
    }
    // Waiting, the frame's times are complete: a stage it did not run took 0 (not the value
    // the previous frame's times, read one frame late, left there).
    if (wait)
      stats.stage_ms[stage] = any ? ms : 0.0;
    else if (any && ready)
      stats.stage_ms[stage] = ms;
  }
}

}  // namespace

void StageTimers::init() {
  GLint bits = 0;
  glGetQueryiv(GL_TIMESTAMP, GL_QUERY_COUNTER_BITS, &bits);
  ok_ = bits > 0;
  if (!ok_) return;
  for (auto& set : queries_)
    for (Query& q : set) {
      GLuint name = 0;
      glCreateQueries(GL_TIMESTAMP, 1, &name);
      q = Query(name);
    }
}

void StageTimers::begin(Stage s, std::size_t part) {
  if (!ok_) return;
  const std::size_t k = static_cast<std::size_t>(s) * kParts + part;
  glQueryCounter(queries_[static_cast<std::size_t>(frame_)][2 * k].get(), GL_TIMESTAMP);
}

void StageTimers::end(Stage s, std::size_t part) {
  if (!ok_) return;
  const std::size_t k = static_cast<std::size_t>(s) * kParts + part;
  glQueryCounter(queries_[static_cast<std::size_t>(frame_)][2 * k + 1].get(), GL_TIMESTAMP);
  used_[static_cast<std::size_t>(frame_)][k] = true;
}

void StageTimers::read_previous(FrameStats& stats) {
  if (!ok_) return;
  // The other set holds the previous frame's queries: by now the GPU has long finished them
  // (this frame already waited on later work), so reading them does not stall.
  const auto prev = static_cast<std::size_t>(1 - frame_);
  sum_intervals(queries_[prev], used_[prev], kParts, false, stats);
  used_[prev].fill(false);
  frame_ = 1 - frame_;
}

void StageTimers::wait_for_last(FrameStats& stats) {
  if (!ok_) return;
  // read_previous() has swapped the sets: the frame that just ended is the other set now.
  // GL_QUERY_RESULT waits for the GPU to reach the query.
  const auto last = static_cast<std::size_t>(1 - frame_);
  sum_intervals(queries_[last], used_[last], kParts, true, stats);
}

}  // namespace viscd::gl
