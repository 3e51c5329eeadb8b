// Stage 4 of the gl backend (layout_chooser.hpp): the bounds passes on the GPU, the choice of m
// and the layout on the host, and the previous frame's values of the default mode.
#include "gl/layout_chooser.hpp"

#include <cstddef>

#include "core/stopwatch.hpp"

namespace viscd::gl {

Status LayoutChooser::init() {
  return build_compute_programs({{&bounds_, "bounds.comp"}, {&bounds_fold_, "bounds_fold.comp"}});
}

void LayoutChooser::reserve(std::uint32_t objects) {
  partials_.reserve(static_cast<GLsizeiptr>(sizeof(shader::BoundsPartial)) * (objects / VISCD_WG_SIZE + 1));
}

void LayoutChooser::measure_extent() {
  // The stage's timestamps bracket these passes, but StageTimers reports `layout` from the host
  // (choose()), so their GPU time is not in FrameStats.
  timers_.begin(Stage::layout);
  frame_.spheres.bind_storage(VISCD_BIND_SPHERES);
  frame_.active.bind_storage(VISCD_BIND_ACTIVE);
  partials_.bind_storage(VISCD_BIND_PARTIALS);
  frame_.info.bind_storage(VISCD_BIND_INFO);
  frame_.dispatch_indirect(bounds_, offsetof(shader::DispatchArgs, per_object));
  glMemoryBarrier(GL_ALL_BARRIER_BITS);
  glUseProgram(bounds_fold_.get());
  glDispatchCompute(1, 1, 1);
  glMemoryBarrier(GL_ALL_BARRIER_BITS);
  timers_.end(Stage::layout);
}

LayoutChoice LayoutChooser::choose(std::uint32_t objects, std::uint32_t moving, bool has_pixels, FrameStats& stats) {
  detail::Stopwatch sw;
  // The default mode needs a previous frame of the same N (and pixel counts in both or neither:
  // mu exists only with them); otherwise this frame runs as sync_layout. A change of the static
  // set alone does not force a wait: the previous bounds are a frame late for static objects as
  // they are for moving ones, which costs the tree some quality, never a pair.
  const bool use_prev = !options_.sync_layout && have_prev_ && prev_moving_ == moving && prev_pixels_ == has_pixels;
  // `info` is the FrameInfo whose active count, bounds and diameter sum choose the layout, `mu`
  // the mean pixels that choose m: the previous frame's (default) or this frame's (sync).
  shader::FrameInfo info{};
  double mu = 0.0;
  LayoutChoice choice;
  choice.n_bound = objects;
  if (use_prev) {
    info = prev_info_;
    mu = prev_mean_pixels_;
  } else {
    glGetNamedBufferSubData(frame_.info.get(), 0, sizeof info, &info);  // the sync mode's wait
    ++mid_frame_waits_;
    choice.n_bound = info.active_count;
    // mu over all N moving objects, culled ones included (docs/architecture.md, "Contracts");
    // static objects are not counted. The exact pixel total times the scale over N, as the cpu
    // backend computes it (finish_cull()): the same mu.
    if (has_pixels) mu = moving ? static_cast<double>(info.total_pixels) * frame_.pixel_scale / moving : 0.0;
  }
  // The active moving objects (this frame's, or the previous frame's in the default mode) raise
  // m from 16 to 32 past detail::kMostObjectsFor16Bits, as on the cpu.
  const int bits = detail::choose_bits(config_, has_pixels, mu, info.visible_count);
  choice.bounds.lo = {info.lo.x, info.lo.y, info.lo.z};
  choice.bounds.hi = {info.hi.x, info.hi.y, info.hi.z};
  const std::uint32_t n = info.active_count;
  const float mean_diameter = n ? static_cast<float>(info.diameter_sum.x / static_cast<double>(n)) : 0.f;
  // With the previous frame's bounds a centre may lie outside them: morton.comp clamps it to the
  // border cell, so the codes are valid keys and the pairs stay exact.
  choice.layout = detail::make_layout(config_.layout, bits, choice.bounds, mean_diameter);
  stats.bits = bits;
  stats.layout = choice.layout.info();
  stats.ms(Stage::layout) = sw.lap();
  return choice;
}

void LayoutChooser::remember(std::uint32_t moving, bool has_pixels, const shader::FrameInfo& info, FrameStats& stats) {
  stats.pairs = info.pair_count;
  stats.active = info.visible_count;
  if (has_pixels)
    stats.mean_pixels = moving ? static_cast<double>(info.total_pixels) * frame_.pixel_scale / moving : 0.0;
  // They become the next frame's layout inputs in the default mode.
  have_prev_ = true;
  prev_info_ = info;
  prev_mean_pixels_ = stats.mean_pixels;
  prev_moving_ = moving;
  prev_pixels_ = has_pixels;
}

}  // namespace viscd::gl
