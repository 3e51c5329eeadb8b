#include "gl/gl_detector.hpp"

#include <chrono>
#include <cstdio>
#include <cstring>
#include <new>

#include "core/frame_rules.hpp"
#include "core/stopwatch.hpp"

namespace viscd {
namespace gl {

Result<std::unique_ptr<GlDetector>> GlDetector::create(const Config& config, const GlOptions& options) {
  using R = Result<std::unique_ptr<GlDetector>>;
  std::unique_ptr<GlDetector> d(new GlDetector(config, options));
  auto ctx = Context::create(options.debug);
  if (!ctx) return R::failure(ctx.error());
  d->ctx_ = std::move(ctx.value());
  if (Status s = d->init(); !s) return R::failure(s.error());
  return d;
}

GlDetector::~GlDetector() {
  // The GL objects below are deleted by their owners, which need this context current.
  if (ctx_) (void)ctx_->make_current();
}

Status GlDetector::init() {
  struct Entry {
    Program* program;
    const char* name;
  };
  const Entry computes[] = {{&scan_local_, "scan_local.comp"},
                            {&scan_blocks_, "scan_blocks.comp"},
                            {&scan_add_, "scan_add.comp"},
                            {&count_, "count.comp"},
                            {&cull_, "cull.comp"},
                            {&bounds_, "bounds.comp"},
                            {&morton_, "morton.comp"},
                            {&radix_hist_, "radix_hist.comp"},
                            {&radix_scatter_, "radix_scatter.comp"},
                            {&build_, "lbvh_build.comp"},
                            {&fit_, "lbvh_fit.comp"},
                            {&query_, "lbvh_query.comp"},
                            {&state_, "state.comp"},
                            {&shade_, "shade.comp"}};
  for (const Entry& e : computes) {
    auto p = Program::compute(e.name);
    if (!p) return Status::failure(p.error());
    *e.program = std::move(p.value());
  }
  auto imp = Program::graphics("gbuffer_impostor.vert", "gbuffer_impostor.frag");
  if (!imp) return Status::failure(imp.error());
  impostor_ = std::move(imp.value());
  auto mesh = Program::graphics("gbuffer_mesh.vert", "gbuffer_mesh.frag");
  if (!mesh) return Status::failure(mesh.error());
  mesh_ = std::move(mesh.value());
  VISCD_ASSERT(radix_scatter_.local_size() == 256 && radix_hist_.local_size() == 256,
               "radix sort needs one invocation per 8-bit digit");
  VISCD_ASSERT(scan_local_.local_size() * VISCD_SCAN_PER_THREAD == VISCD_SCAN_BLOCK, "scan block size");

  GLuint name = 0;
  glCreateVertexArrays(1, &name);
  empty_vao_ = VertexArray(name);
  glCreateFramebuffers(1, &name);
  empty_fbo_ = Framebuffer(name);
  info_.reserve(sizeof(shader::FrameInfo));
  pair_capacity_ = std::max<std::uint32_t>(1, options_.initial_pair_capacity);
  pairs_.reserve(static_cast<GLsizeiptr>(pair_capacity_) * 8);

  GLint bits = 0;
  glGetQueryiv(GL_TIMESTAMP, GL_QUERY_COUNTER_BITS, &bits);
  timers_ok_ = bits > 0;
  if (timers_ok_) {
    for (auto& frame : timers_)
      for (Query& q : frame) {
        glCreateQueries(GL_TIMESTAMP, 1, &name);
        q = Query(name);
      }
  }
  return gl_errors("initialisation");
}

Status GlDetector::gl_errors(const char* where) {
  std::vector<std::string> errors = ctx_->take_errors();
  GLenum e = glGetError();
  while (e != GL_NO_ERROR) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "glGetError() = 0x%04x", static_cast<unsigned>(e));
    errors.emplace_back(buf);
    e = glGetError();
  }
  if (errors.empty()) return {};
  std::string msg = std::string("OpenGL error during ") + where + ": " + errors.front();
  if (errors.size() > 1) msg += " (and " + std::to_string(errors.size() - 1) + " more)";
  return Status::failure(msg);
}

void GlDetector::upload_spheres(std::span<const Sphere> spheres) {
  spheres_.reserve(static_cast<GLsizeiptr>(spheres.size_bytes()));
  if (!spheres.empty())
    glNamedBufferSubData(spheres_.get(), 0, static_cast<GLsizeiptr>(spheres.size_bytes()), spheres.data());
}

// ---- timers: a GL_TIMESTAMP before and after each stage, read back one frame later ----

void GlDetector::stage_begin(Stage s) {
  if (!timers_ok_) return;
  const auto k = static_cast<std::size_t>(s);
  glQueryCounter(timers_[static_cast<std::size_t>(timer_frame_)][2 * k].get(), GL_TIMESTAMP);
}

void GlDetector::stage_end(Stage s) {
  if (!timers_ok_) return;
  const auto k = static_cast<std::size_t>(s);
  glQueryCounter(timers_[static_cast<std::size_t>(timer_frame_)][2 * k + 1].get(), GL_TIMESTAMP);
  timer_used_[static_cast<std::size_t>(timer_frame_)][k] = true;
}

void GlDetector::read_timers(FrameStats& stats) {
  if (!timers_ok_) return;
  // The other slot holds the previous frame's queries: by now the GPU has long finished them
  // (this frame already waited on later work), so reading them does not stall.
  const auto prev = static_cast<std::size_t>(1 - timer_frame_);
  for (std::size_t k = 0; k < kStageCount; ++k) {
    if (!timer_used_[prev][k] || static_cast<Stage>(k) == Stage::layout) continue;
    GLint available = 0;
    glGetQueryObjectiv(timers_[prev][2 * k + 1].get(), GL_QUERY_RESULT_AVAILABLE, &available);
    if (!available) continue;
    GLuint64 t0 = 0, t1 = 0;
    glGetQueryObjectui64v(timers_[prev][2 * k].get(), GL_QUERY_RESULT, &t0);
    glGetQueryObjectui64v(timers_[prev][2 * k + 1].get(), GL_QUERY_RESULT, &t1);
    stats.stage_ms[k] = t1 >= t0 ? static_cast<double>(t1 - t0) * 1e-6 : 0.0;
  }
  timer_used_[prev].fill(false);
  timer_frame_ = 1 - timer_frame_;
}

void GlDetector::wait_for_stage_times(FrameStats& stats) {
  if (!timers_ok_ || !ctx_->make_current()) return;
  // read_timers() has flipped the slots: the frame that just ended is the other slot now.
  // GL_QUERY_RESULT waits for the GPU to reach the query.
  const auto last = static_cast<std::size_t>(1 - timer_frame_);
  for (std::size_t k = 0; k < kStageCount; ++k) {
    if (!timer_used_[last][k] || static_cast<Stage>(k) == Stage::layout) continue;
    GLuint64 t0 = 0, t1 = 0;
    glGetQueryObjectui64v(timers_[last][2 * k].get(), GL_QUERY_RESULT, &t0);
    glGetQueryObjectui64v(timers_[last][2 * k + 1].get(), GL_QUERY_RESULT, &t1);
    stats.stage_ms[k] = t1 >= t0 ? static_cast<double>(t1 - t0) * 1e-6 : 0.0;
  }
}

// ---- the frame ----

Status GlDetector::run_frame(const FrameInput& input, FrameResult& out) {
  if (!input.filters.empty()) return Status::failure("the gl backend does not take filters yet");
  if (!input.id_map.empty()) return Status::failure("the gl backend does not take an id map (FrameInput::id_map) yet");
  if (input.gl_id_texture != 0) return Status::failure("the gl backend does not take an id texture yet");
  try {
    return detect_frame(input.spheres, input.camera, out);
  } catch (const std::bad_alloc&) {
    return Status::failure(detail::out_of_memory_message(input.spheres.size(), input.camera, config_));
  }
}

Status GlDetector::detect_frame(std::span<const Sphere> spheres, const Camera* camera, FrameResult& out) {
  if (Status s = detail::validate_frame(spheres, camera, config_); !s) return s;
  if (spheres.size() >= (1u << 29)) return Status::failure("the gl backend handles at most 2^29 - 1 objects");
  if (!ctx_->make_current()) return Status::failure("OpenGL: cannot make the detector's context current");
  if (Status s = gl_errors("an earlier call"); !s) return s;

  const auto n_all = static_cast<std::uint32_t>(spheres.size());
  FrameStats& stats = out.stats;
  stats = FrameStats{};
  stats.objects = n_all;
  stats.has_camera = camera != nullptr;
  upload_spheres(spheres);
  counts_.reserve(4 * static_cast<GLsizeiptr>(n_all));
  pixels_.reserve(4 * static_cast<GLsizeiptr>(n_all));
  flags_.reserve(4 * static_cast<GLsizeiptr>(n_all));
  scan_out_.reserve(4 * static_cast<GLsizeiptr>(n_all));
  active_.reserve(4 * static_cast<GLsizeiptr>(n_all));
  states_.reserve(4 * static_cast<GLsizeiptr>(n_all));
  partials_.reserve(static_cast<GLsizeiptr>(sizeof(shader::BoundsPartial)) * (n_all / VISCD_WG_SIZE + 1));
  const shader::FrameInfo zero_info{};
  glNamedBufferSubData(info_.get(), 0, sizeof zero_info, &zero_info);

  std::unique_ptr<detail::CameraRig> rig;
  if (camera) {
    const int mw = config_.map_width ? config_.map_width : camera->width;
    const int mh = config_.map_height ? config_.map_height : camera->height;
    rig = std::make_unique<detail::CameraRig>(*camera, mw, mh);
    if (options_.counter == GlCounter::atomic_uint) {
      // Checked before any work so that the error is clean.
      GLint max_frag = 0, max_size = 0;
      glGetIntegerv(GL_MAX_FRAGMENT_ATOMIC_COUNTERS, &max_frag);
      glGetIntegerv(GL_MAX_ATOMIC_COUNTER_BUFFER_SIZE, &max_size);
      const std::uint32_t limit =
          std::min<std::uint32_t>(static_cast<std::uint32_t>(max_frag), static_cast<std::uint32_t>(max_size) / 4);
      if (n_all > limit)
        return Status::failure(
            "atomic_uint counting supports at most " + std::to_string(limit) +
            " objects on this driver (GL_MAX_FRAGMENT_ATOMIC_COUNTERS = " + std::to_string(max_frag) +
            ", GL_MAX_ATOMIC_COUNTER_BUFFER_SIZE = " + std::to_string(max_size) + " bytes); the frame has " +
            std::to_string(n_all) + ": use the ssbo counter mode");
    }
    stage_begin(Stage::visibility);
    ensure_map(mw, mh);
    draw_gbuffer(*rig, n_all);
    stage_end(Stage::visibility);
    stage_begin(Stage::count);
    if (Status s = count_pixels(n_all); !s) return s;
    stage_end(Stage::count);
  }

  // Stage 3: flags, pixels, total; scan; compaction; the active count into FrameInfo.
  stage_begin(Stage::cull);
  counts_.bind_storage(VISCD_BIND_COUNTS);
  pixels_.bind_storage(VISCD_BIND_PIXELS);
  flags_.bind_storage(VISCD_BIND_FLAGS);
  active_.bind_storage(VISCD_BIND_ACTIVE);
  info_.bind_storage(VISCD_BIND_INFO);
  glProgramUniform1ui(cull_.get(), cull_.uniform("u_n"), n_all);
  glProgramUniform1ui(cull_.get(), cull_.uniform("u_phase"), 0);
  glProgramUniform1ui(cull_.get(), cull_.uniform("u_has_counts"), camera ? 1u : 0u);
  glProgramUniform1ui(cull_.get(), cull_.uniform("u_culling"), config_.culling ? 1u : 0u);
  glProgramUniform1d(cull_.get(), cull_.uniform("u_scale"), rig ? rig->pixel_scale : 1.0);
  glProgramUniform1d(cull_.get(), cull_.uniform("u_lambda"), static_cast<double>(config_.lambda));
  cull_.dispatch(n_all);
  glMemoryBarrier(GL_ALL_BARRIER_BITS);
  scan(flags_.get(), scan_out_.get(), n_all);
  // scan() leaves the total (the active count) in block_sums_[blocks]; copy it on the GPU.
  const std::uint32_t blocks = (n_all + VISCD_SCAN_BLOCK - 1) / VISCD_SCAN_BLOCK;
  glCopyNamedBufferSubData(block_sums_.get(), info_.get(), 4 * static_cast<GLintptr>(blocks),
                           offsetof(shader::FrameInfo, active_count), 4);
  flags_.bind_storage(VISCD_BIND_FLAGS);
  scan_out_.bind_storage(VISCD_BIND_SCAN_OUT);
  active_.bind_storage(VISCD_BIND_ACTIVE);
  glProgramUniform1ui(cull_.get(), cull_.uniform("u_phase"), 1);
  cull_.dispatch(n_all);
  glMemoryBarrier(GL_ALL_BARRIER_BITS);
  stage_end(Stage::cull);

  // Stage 4 inputs on the GPU (sized by N, n read on the GPU): this frame's active-centre
  // bounds and diameter sum into FrameInfo. Sync mode reads them back now (its mid-frame
  // wait); the default mode leaves them for the next frame (read with the final readback).
  stage_begin(Stage::layout);
  spheres_.bind_storage(VISCD_BIND_SPHERES);
  active_.bind_storage(VISCD_BIND_ACTIVE);
  partials_.bind_storage(VISCD_BIND_PARTIALS);
  info_.bind_storage(VISCD_BIND_INFO);
  glProgramUniform1ui(bounds_.get(), bounds_.uniform("u_phase"), 0);
  bounds_.dispatch(n_all);
  glMemoryBarrier(GL_ALL_BARRIER_BITS);
  glProgramUniform1ui(bounds_.get(), bounds_.uniform("u_phase"), 1);
  glUseProgram(bounds_.get());
  glDispatchCompute(1, 1, 1);
  glMemoryBarrier(GL_ALL_BARRIER_BITS);
  stage_end(Stage::layout);
  detail::Stopwatch sw;
  // The default mode needs a previous frame of the same N (and camera presence: mu exists only
  // with a camera); otherwise this frame runs as sync_layout.
  const bool use_prev =
      !options_.sync_layout && have_prev_ && prev_objects_ == n_all && prev_camera_ == (camera != nullptr);
  // `layout_info` is the FrameInfo whose active count, bounds and diameter sum choose the layout,
  // `mu` the mean pixels that choose m: this frame's (sync) or the previous frame's (default).
  shader::FrameInfo layout_info{};
  double mu = 0.0;
  std::uint32_t n_bound = n_all;  // dispatch size of stages 5-8 and of the state pass
  if (use_prev) {
    layout_info = prev_info_;  // PREVIOUS frame's n, active-centre bounds and diameter sum
    mu = prev_mean_pixels_;    // PREVIOUS frame's mu (same N, camera in both frames)
  } else {
    glGetNamedBufferSubData(info_.get(), 0, sizeof layout_info, &layout_info);  // the sync mode's wait
    ++mid_frame_waits_;
    n_bound = layout_info.active_count;
    // mu over all N objects, culled ones included (docs/architecture.md, "Contracts"). The cpu
    // backend sums count * scale in double; with scale 1 (map = screen) both sums are exact and
    // equal, otherwise they may differ in the last ulp.
    if (camera) mu = n_all ? static_cast<double>(layout_info.total_pixels) * rig->pixel_scale / n_all : 0.0;
  }
  int bits = 32;  // without a camera mu is undefined; adaptive falls back to 32 (as PipelineDetector)
  if (camera) {
    bits = config_.bits == Bits::adaptive ? detail::bits_for_mean_pixels(mu, config_.a, config_.b)
                                          : static_cast<int>(config_.bits);
  } else if (config_.bits != Bits::adaptive) {
    bits = static_cast<int>(config_.bits);
  }
  detail::Aabb bounds;
  bounds.lo = {layout_info.lo.x, layout_info.lo.y, layout_info.lo.z};
  bounds.hi = {layout_info.hi.x, layout_info.hi.y, layout_info.hi.z};
  const std::uint32_t layout_n = layout_info.active_count;
  const float mean_diameter =
      layout_n ? static_cast<float>(layout_info.diameter_sum.x / static_cast<double>(layout_n)) : 0.f;
  // With the previous frame's bounds a centre may lie outside them: morton.comp clamps it to the
  // border cell, so the codes are valid keys and the pairs stay exact.
  const detail::MortonLayout layout = detail::make_layout(config_.layout, bits, bounds, mean_diameter);
  stats.bits = bits;
  stats.layout = layout.to_string();
  const double layout_ms = sw.lap();

  if (Status s = broadphase(n_bound, n_all, layout, bounds, out.pairs, stats); !s) return s;
  stats.pairs = out.pairs.size();
  // This frame's values, read back by the broadphase's final wait.
  const std::uint32_t n = frame_info_.active_count;
  stats.active = n;
  if (camera)
    stats.mean_pixels = n_all ? static_cast<double>(frame_info_.total_pixels) * rig->pixel_scale / n_all : 0.0;
  // They become the next frame's layout inputs in the default mode.
  have_prev_ = true;
  prev_info_ = frame_info_;
  prev_mean_pixels_ = stats.mean_pixels;
  prev_objects_ = n_all;
  prev_camera_ = camera != nullptr;

  // Object states on the GPU (the shading pass reads them), then read back.
  stage_begin(Stage::query);
  states_.bind_storage(VISCD_BIND_STATE);
  active_.bind_storage(VISCD_BIND_ACTIVE);
  pairs_.bind_storage(VISCD_BIND_PAIRS);
  glProgramUniform1ui(state_.get(), state_.uniform("u_phase"), 0);
  glProgramUniform1ui(state_.get(), state_.uniform("u_n"), n_all);
  state_.dispatch(n_all);
  glMemoryBarrier(GL_ALL_BARRIER_BITS);
  glProgramUniform1ui(state_.get(), state_.uniform("u_phase"), 1);
  info_.bind_storage(VISCD_BIND_INFO);
  state_.dispatch(n_bound);  // phase 1 reads n from FrameInfo
  glMemoryBarrier(GL_ALL_BARRIER_BITS);
  glProgramUniform1ui(state_.get(), state_.uniform("u_phase"), 2);
  glProgramUniform1ui(state_.get(), state_.uniform("u_n"), static_cast<GLuint>(out.pairs.size()));
  state_.dispatch(out.pairs.size());
  glMemoryBarrier(GL_ALL_BARRIER_BITS);
  stage_end(Stage::query);
  {
    std::vector<std::uint32_t> st(n_all);
    if (n_all) glGetNamedBufferSubData(states_.get(), 0, 4 * static_cast<GLsizeiptr>(n_all), st.data());
    out.state.resize(n_all);
    for (std::uint32_t k = 0; k < n_all; ++k) out.state[k] = static_cast<ObjectState>(st[k]);
  }
  if (camera) {
    out.pixels.resize(n_all);
    if (n_all) glGetNamedBufferSubData(pixels_.get(), 0, 4 * static_cast<GLsizeiptr>(n_all), out.pixels.data());
  } else {
    out.pixels.clear();
  }

  if (camera && config_.shade) {
    stage_begin(Stage::shade);
    shade(*rig);
    stage_end(Stage::shade);
    out.image.resize(4 * static_cast<std::size_t>(map_w_) * static_cast<std::size_t>(map_h_));
    glGetNamedBufferSubData(image_.get(), 0, static_cast<GLsizeiptr>(out.image.size()), out.image.data());
    out.image_width = map_w_;
    out.image_height = map_h_;
  } else {
    out.image.clear();
    out.image_width = out.image_height = 0;
  }
  read_timers(stats);
  stats.stage_ms[static_cast<std::size_t>(Stage::layout)] = layout_ms;
  return gl_errors("detect()");
}

}  // namespace gl

Result<std::unique_ptr<Detector>> make_gl_detector(const Config& config, const GlOptions& options) {
  auto d = gl::GlDetector::create(config, options);
  if (!d) return Result<std::unique_ptr<Detector>>::failure(d.error());
  return std::unique_ptr<Detector>(std::move(d.value()));
}

std::uint64_t gl::GlDetector::memory_bytes() const {
  if (!ctx_->make_current()) return 0;
  if (epoxy_has_gl_extension("GL_NVX_gpu_memory_info")) {
    // The paper's Fig. 8 measure: total minus currently available video memory (KiB).
    GLint total = 0, available = 0;
    glGetIntegerv(0x9048 /* GL_GPU_MEMORY_INFO_TOTAL_AVAILABLE_MEMORY_NVX */, &total);
    glGetIntegerv(0x9049 /* GL_GPU_MEMORY_INFO_CURRENT_AVAILABLE_VIDMEM_NVX */, &available);
    return static_cast<std::uint64_t>(total - available) * 1024u;
  }
  std::uint64_t b = 0;
  for (const Buffer* buf :
       {&spheres_, &counts_,    &pixels_,  &flags_,   &scan_out_,  &block_sums_, &active_,     &info_,    &partials_,
        &hist_,    &hist_scan_, &nodes_,   &parent_,  &arrivals_,  &sorted_,     &leaf_boxes_, &pairs_,   &pairs_tmp_,
        &states_,  &image_,     &keys_[0], &keys_[1], &values_[0], &values_[1],  &mesh_vbo_,   &mesh_ibo_})
    b += static_cast<std::uint64_t>(buf->size());
  // G-buffer: R32UI ids, R32F depth, RGBA32F normals, 32-bit float z-buffer.
  b += static_cast<std::uint64_t>(map_w_) * static_cast<std::uint64_t>(map_h_) * (4 + 4 + 16 + 4);
  return b;
}

Result<std::string> gl_device() {
  auto ctx = gl::Context::create(false);
  if (!ctx) return Result<std::string>::failure(ctx.error());
  return ctx.value()->description();
}

}  // namespace viscd
