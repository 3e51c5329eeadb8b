#include "gl/gl_detector.hpp"

#include <chrono>
#include <cstdio>
#include <cstring>
#include <new>

#include "core/brute_queries.hpp"
#include "core/frame_rules.hpp"
#include "core/stopwatch.hpp"

namespace viscd {
namespace gl {

Result<std::unique_ptr<GlDetector>> GlDetector::create(const Config& config, const GlOptions& options) {
  using R = Result<std::unique_ptr<GlDetector>>;
  std::unique_ptr<GlDetector> d(new GlDetector(config, options));
  auto ctx = options.use_current_context ? Context::adopt_current() : Context::create(options.debug);
  if (!ctx) return R::failure(ctx.status());
  d->ctx_ = std::move(ctx.value());
  if (Status s = d->init(); !s) return R::failure(s);
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
                            {&pairable_, "pairable.comp"},
                            {&compact_, "compact.comp"},
                            {&dispatch_args_, "dispatch_args.comp"},
                            {&bounds_, "bounds.comp"},
                            {&bounds_fold_, "bounds_fold.comp"},
                            {&morton_, "morton.comp"},
                            {&sort_local_, "sort_local.comp"},
                            {&radix_hist_, "radix_hist.comp"},
                            {&radix_scan_, "radix_scan.comp"},
                            {&radix_scatter_, "radix_scatter.comp"},
                            {&build_, "lbvh_build.comp"},
                            {&fit_, "lbvh_fit.comp"},
                            {&query_, "lbvh_query.comp"},
                            {&state_, "state.comp"},
                            {&shade_, "shade.comp"}};
  for (const Entry& e : computes) {
    auto p = Program::compute(e.name);
    if (!p) return p.status();
    *e.program = std::move(p.value());
  }
  auto imp = Program::graphics("gbuffer_impostor.vert", "gbuffer_impostor.frag");
  if (!imp) return imp.status();
  impostor_ = std::move(imp.value());
  auto mesh = Program::graphics("gbuffer_mesh.vert", "gbuffer_mesh.frag");
  if (!mesh) return mesh.status();
  mesh_ = std::move(mesh.value());
  VISCD_ASSERT(radix_scatter_.local_size() == 256 && radix_hist_.local_size() == 256 && radix_scan_.local_size() == 256,
               "radix sort needs one invocation per 8-bit digit");
  VISCD_ASSERT(scan_local_.local_size() * VISCD_SCAN_PER_THREAD == VISCD_SCAN_BLOCK, "scan block size");

  GLuint name = 0;
  glCreateVertexArrays(1, &name);
  empty_vao_ = VertexArray(name);
  glCreateFramebuffers(1, &name);
  empty_fbo_ = Framebuffer(name);
  glCreateSamplers(1, &name);
  nearest_ = Sampler(name);
  glSamplerParameteri(name, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
  glSamplerParameteri(name, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
  info_.reserve(sizeof(shader::FrameInfo));
  dispatch_.reserve(sizeof(shader::DispatchArgs));
  GLint groups = 0;
  glGetIntegeri_v(GL_MAX_COMPUTE_WORK_GROUP_COUNT, 0, &groups);
  max_groups_ = static_cast<std::uint32_t>(std::max(groups, 1));
  glGetIntegerv(GL_MAX_FRAGMENT_ATOMIC_COUNTERS, &max_fragment_counters_);
  glGetIntegerv(GL_MAX_ATOMIC_COUNTER_BUFFER_SIZE, &max_counter_buffer_bytes_);
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
  return Status::failure(ErrorKind::backend_failure, msg);
}

void GlDetector::upload_spheres(std::span<const Sphere> spheres) {
  spheres_.reserve(static_cast<GLsizeiptr>(spheres.size_bytes()));
  if (!spheres.empty())
    glNamedBufferSubData(spheres_.get(), 0, static_cast<GLsizeiptr>(spheres.size_bytes()), spheres.data());
}

// ---- timers: a GL_TIMESTAMP before and after each stage, read back one frame later ----

void GlDetector::stage_begin(Stage s, std::size_t part) {
  if (!timers_ok_) return;
  const std::size_t k = static_cast<std::size_t>(s) * kTimerParts + part;
  glQueryCounter(timers_[static_cast<std::size_t>(timer_frame_)][2 * k].get(), GL_TIMESTAMP);
}

void GlDetector::stage_end(Stage s, std::size_t part) {
  if (!timers_ok_) return;
  const std::size_t k = static_cast<std::size_t>(s) * kTimerParts + part;
  glQueryCounter(timers_[static_cast<std::size_t>(timer_frame_)][2 * k + 1].get(), GL_TIMESTAMP);
  timer_used_[static_cast<std::size_t>(timer_frame_)][k] = true;
}

namespace {

// Sums a slot's intervals per stage into stats.stage_ms; `wait`: block until each is known,
// else skip a stage whose queries are not all available yet.
template <class Timers, class Used>
void sum_intervals(const Timers& timers, Used& used, std::size_t parts, bool wait, FrameStats& stats) {
  for (std::size_t stage = 0; stage < kStageCount; ++stage) {
    if (static_cast<Stage>(stage) == Stage::layout) continue;  // timed on the host
    double ms = 0;
    bool any = false, ready = true;
    for (std::size_t part = 0; part < parts && ready; ++part) {
      const std::size_t k = stage * parts + part;
      if (!used[k]) continue;
      if (!wait) {
        GLint available = 0;
        glGetQueryObjectiv(timers[2 * k + 1].get(), GL_QUERY_RESULT_AVAILABLE, &available);
        if (!available) ready = false;
        if (!ready) break;
      }
      GLuint64 t0 = 0, t1 = 0;
      glGetQueryObjectui64v(timers[2 * k].get(), GL_QUERY_RESULT, &t0);
      glGetQueryObjectui64v(timers[2 * k + 1].get(), GL_QUERY_RESULT, &t1);
      ms += t1 >= t0 ? static_cast<double>(t1 - t0) * 1e-6 : 0.0;
      any = true;
    }
    if (any && ready) stats.stage_ms[stage] = ms;
  }
}

}  // namespace

void GlDetector::read_timers(FrameStats& stats) {
  if (!timers_ok_) return;
  // The other slot holds the previous frame's queries: by now the GPU has long finished them
  // (this frame already waited on later work), so reading them does not stall.
  const auto prev = static_cast<std::size_t>(1 - timer_frame_);
  sum_intervals(timers_[prev], timer_used_[prev], kTimerParts, false, stats);
  timer_used_[prev].fill(false);
  timer_frame_ = 1 - timer_frame_;
}

void GlDetector::wait_for_stage_times(FrameStats& stats) {
  if (!timers_ok_ || !ctx_->make_current()) return;
  // read_timers() has flipped the slots: the frame that just ended is the other slot now.
  // GL_QUERY_RESULT waits for the GPU to reach the query.
  const auto last = static_cast<std::size_t>(1 - timer_frame_);
  sum_intervals(timers_[last], timer_used_[last], kTimerParts, true, stats);
}

// ---- the frame ----

Status GlDetector::run_frame(const FrameInput& input, FrameResult& out) {
  try {
    return detect_frame(input, out);
  } catch (const std::bad_alloc&) {
    return Status::failure(ErrorKind::out_of_memory,
                           detail::out_of_memory_message(input.spheres.size(), input.camera, config_));
  }
}

bool GlDetector::query_ray(const Ray& ray, RayHit& hit) {
  read_active_spheres();
  return detail::brute_ray(query_active_, query_ids_, ray, hit);
}

void GlDetector::query_ray_all(const Ray& ray, std::vector<RayHit>& hits) {
  read_active_spheres();
  detail::brute_ray_all(query_active_, query_ids_, ray, hits);
}

void GlDetector::query_overlap(const Sphere& sphere, std::vector<std::uint32_t>& indices) {
  read_active_spheres();
  detail::brute_overlap(query_active_, query_ids_, sphere, indices);
}

void GlDetector::read_active_spheres() {
  if (query_copy_ready_) return;
  query_copy_ready_ = true;
  const std::uint32_t n = query_objects_;
  query_all_.resize(n);
  state_words_.resize(n);
  query_active_.clear();
  query_ids_.clear();
  if (n == 0 || !ctx_->make_current()) return;
  glGetNamedBufferSubData(spheres_.get(), 0, 16 * static_cast<GLsizeiptr>(n), query_all_.data());
  glGetNamedBufferSubData(states_.get(), 0, 4 * static_cast<GLsizeiptr>(n), state_words_.data());
  for (std::uint32_t k = 0; k < n; ++k) {
    if (state_words_[k] == VISCD_STATE_CULLED) continue;
    query_active_.push_back(query_all_[k]);
    query_ids_.push_back(k);
  }
}

Status GlDetector::detect_frame(const FrameInput& in, FrameResult& out) {
  // Passes over N run one invocation per object (scan blocks of VISCD_SCAN_BLOCK), one
  // dispatch each: the driver's work-group limit bounds N.
  const std::uint64_t max_objects =
      std::min<std::uint64_t>((std::uint64_t{1} << 29) - 1, std::uint64_t{max_groups_} * VISCD_WG_SIZE);
  if (in.spheres.size() > max_objects)
    return Status::failure(ErrorKind::unsupported_input,
                           "the gl backend handles at most " + std::to_string(max_objects) +
                               " objects on this driver (GL_MAX_COMPUTE_WORK_GROUP_COUNT = " +
                               std::to_string(max_groups_) + " groups of " + std::to_string(VISCD_WG_SIZE) +
                               "); the frame has " + std::to_string(in.spheres.size()) + ": use the cpu backend");
  if (!ctx_->make_current())
    return Status::failure(ErrorKind::backend_failure, "OpenGL: cannot make the detector's context current");
  if (Status s = gl_errors("an earlier call"); !s) return s;
  const auto n_all = static_cast<std::uint32_t>(in.spheres.size());
  const bool has_camera = in.camera != nullptr;
  const bool callers_map = !in.id_map.empty() || in.gl_id_texture != 0;
  FrameStats& stats = out.stats;
  stats = FrameStats{};
  stats.objects = n_all;
  stats.has_camera = has_camera;

  begin_frame(in);
  stats.has_pixels = has_pixels_;
  query_copy_ready_ = false;  // the spheres and states on the GPU are this frame's now
  query_objects_ = n_all;
  if (callers_map) {
    if (Status s = count_callers_map(in); !s) return s;
  } else if (has_camera) {
    if (Status s = render_visibility(n_all); !s) return s;
  }
  cull(n_all);
  measure_extent();
  const LayoutChoice choice = choose_layout(n_all, has_pixels_, stats);
  if (Status s = broadphase(choice.n_bound, n_all, choice.layout, choice.bounds, out.pairs, stats); !s) return s;
  if (Status s = id_check(in); !s) return s;
  remember_frame(n_all, has_pixels_, stats);
  mark_colliding(static_cast<std::uint32_t>(out.pairs.size()));
  read_states_and_pixels(n_all, has_pixels_, out);
  shade(out);
  const double layout_ms = stats.ms(Stage::layout);
  read_timers(stats);
  stats.ms(Stage::layout) = layout_ms;
  return gl_errors("detect()");
}

void GlDetector::begin_frame(const FrameInput& in) {
  const auto n = static_cast<GLsizeiptr>(in.spheres.size());
  upload_spheres(in.spheres);
  has_filters_ = !in.filters.empty();
  if (has_filters_) {
    static_assert(sizeof(Filter) == 8, "Filter must match GLSL uvec2 (group, mask)");
    filters_.reserve(8 * n);
    glNamedBufferSubData(filters_.get(), 0, 8 * n, in.filters.data());
  }
  for (Buffer* b : {&counts_, &pixels_, &flags_, &scan_out_, &active_, &states_}) b->reserve(4 * n);
  partials_.reserve(static_cast<GLsizeiptr>(sizeof(shader::BoundsPartial)) * (n / VISCD_WG_SIZE + 1));
  shader::FrameInfo zero_info{};
  zero_info.id_check.y = 0xFFFFFFFFu;  // atomicMin's start: no bad pixel
  glNamedBufferSubData(info_.get(), 0, sizeof zero_info, &zero_info);
  const bool callers_map = !in.id_map.empty() || in.gl_id_texture != 0;
  has_pixels_ = callers_map || in.camera;
  rig_.reset();
  if (callers_map) {
    pixel_scale_ = detail::map_pixel_scale(in.camera, in.id_map_width, in.id_map_height);
  } else if (in.camera) {
    const detail::MapSize map = detail::map_size(config_, *in.camera);
    rig_.emplace(*in.camera, map.width, map.height);
    pixel_scale_ = rig_->pixel_scale;
  } else {
    pixel_scale_ = 1.0;
  }
}

void GlDetector::cull(std::uint32_t objects) {
  stage_begin(Stage::cull);
  counts_.bind_storage(VISCD_BIND_COUNTS);
  pixels_.bind_storage(VISCD_BIND_PIXELS);
  flags_.bind_storage(VISCD_BIND_FLAGS);
  states_.bind_storage(VISCD_BIND_STATE);
  info_.bind_storage(VISCD_BIND_INFO);
  if (has_filters_) filters_.bind_storage(VISCD_BIND_FILTERS);
  const GLuint p = cull_.get();
  glProgramUniform1ui(p, cull_.uniform("u_n"), objects);
  glProgramUniform1ui(p, cull_.uniform("u_has_counts"), has_pixels_ ? 1u : 0u);
  glProgramUniform1ui(p, cull_.uniform("u_culling"), config_.culling ? 1u : 0u);
  glProgramUniform1ui(p, cull_.uniform("u_has_filters"), has_filters_ ? 1u : 0u);
  glProgramUniform1d(p, cull_.uniform("u_scale"), pixel_scale_);
  glProgramUniform1d(p, cull_.uniform("u_lambda"), static_cast<double>(config_.lambda));
  cull_.dispatch(objects);
  glMemoryBarrier(GL_ALL_BARRIER_BITS);
  if (has_filters_) {
    glProgramUniform1ui(pairable_.get(), pairable_.uniform("u_n"), objects);
    pairable_.dispatch(objects);
    glMemoryBarrier(GL_ALL_BARRIER_BITS);
  }
  scan(flags_.get(), scan_out_.get(), objects);
  // scan() leaves the total (the active count) in block_sums_[blocks]; copy it on the GPU.
  const std::uint32_t blocks = (objects + VISCD_SCAN_BLOCK - 1) / VISCD_SCAN_BLOCK;
  glCopyNamedBufferSubData(block_sums_.get(), info_.get(), 4 * static_cast<GLintptr>(blocks),
                           offsetof(shader::FrameInfo, active_count), 4);
  flags_.bind_storage(VISCD_BIND_FLAGS);
  scan_out_.bind_storage(VISCD_BIND_SCAN_OUT);
  active_.bind_storage(VISCD_BIND_ACTIVE);
  glProgramUniform1ui(compact_.get(), compact_.uniform("u_n"), objects);
  compact_.dispatch(objects);
  glMemoryBarrier(GL_ALL_BARRIER_BITS);
  write_dispatch_args();
  stage_end(Stage::cull);
}

void GlDetector::measure_extent() {
  stage_begin(Stage::layout);
  spheres_.bind_storage(VISCD_BIND_SPHERES);
  active_.bind_storage(VISCD_BIND_ACTIVE);
  partials_.bind_storage(VISCD_BIND_PARTIALS);
  info_.bind_storage(VISCD_BIND_INFO);
  dispatch_indirect(bounds_, offsetof(shader::DispatchArgs, per_object));
  glMemoryBarrier(GL_ALL_BARRIER_BITS);
  glUseProgram(bounds_fold_.get());
  glDispatchCompute(1, 1, 1);
  glMemoryBarrier(GL_ALL_BARRIER_BITS);
  stage_end(Stage::layout);
}

GlDetector::LayoutChoice GlDetector::choose_layout(std::uint32_t objects, bool has_pixels, FrameStats& stats) {
  detail::Stopwatch sw;
  // The default mode needs a previous frame of the same N (and pixel counts in both or neither:
  // mu exists only with them); otherwise this frame runs as sync_layout.
  const bool use_prev = !options_.sync_layout && have_prev_ && prev_objects_ == objects && prev_pixels_ == has_pixels;
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
    glGetNamedBufferSubData(info_.get(), 0, sizeof info, &info);  // the sync mode's wait
    ++mid_frame_waits_;
    choice.n_bound = info.active_count;
    // mu over all N objects, culled ones included (docs/architecture.md, "Contracts"). The cpu
    // backend sums count * scale in double; with scale 1 (map = screen) both sums are exact and
    // equal, otherwise they may differ in the last ulp.
    if (has_pixels) mu = objects ? static_cast<double>(info.total_pixels) * pixel_scale_ / objects : 0.0;
  }
  const int bits = detail::choose_bits(config_, has_pixels, mu);
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

void GlDetector::remember_frame(std::uint32_t objects, bool has_pixels, FrameStats& stats) {
  // This frame's values, read back by the broadphase's final wait.
  stats.pairs = frame_info_.pair_count;
  stats.active = frame_info_.visible_count;
  if (has_pixels)
    stats.mean_pixels = objects ? static_cast<double>(frame_info_.total_pixels) * pixel_scale_ / objects : 0.0;
  // They become the next frame's layout inputs in the default mode.
  have_prev_ = true;
  prev_info_ = frame_info_;
  prev_mean_pixels_ = stats.mean_pixels;
  prev_objects_ = objects;
  prev_pixels_ = has_pixels;
}

Status GlDetector::id_check(const FrameInput& in) const {
  const std::uint32_t bad = frame_info_.id_check.x;
  if (bad == 0) return {};
  if (!in.id_map.empty()) return detail::id_map_error(in.id_map, in.id_map_width, in.spheres.size());
  const std::uint32_t first = frame_info_.id_check.y;
  const auto w = static_cast<std::uint32_t>(in.id_map_width);
  return Status::failure(ErrorKind::invalid_input, "FrameInput::gl_id_texture: texel (" + std::to_string(first % w) +
                                                       ", " + std::to_string(first / w) + ") and " +
                                                       std::to_string(bad - 1) + " more hold ids above the frame's " +
                                                       std::to_string(in.spheres.size()) +
                                                       " objects (an id is an object index + 1, 0 is background)");
}

void GlDetector::mark_colliding(std::uint32_t pairs) {
  stage_begin(Stage::query, 2);  // stage 8's third part: the states
  pairs_.bind_storage(VISCD_BIND_PAIRS);
  states_.bind_storage(VISCD_BIND_STATE);
  glProgramUniform1ui(state_.get(), state_.uniform("u_pairs"), pairs);
  state_.dispatch(pairs);
  glMemoryBarrier(GL_ALL_BARRIER_BITS);
  stage_end(Stage::query, 2);
}

void GlDetector::read_states_and_pixels(std::uint32_t objects, bool has_pixels, FrameResult& out) {
  state_words_.resize(objects);
  if (objects) glGetNamedBufferSubData(states_.get(), 0, 4 * static_cast<GLsizeiptr>(objects), state_words_.data());
  out.state.resize(objects);
  for (std::uint32_t k = 0; k < objects; ++k) out.state[k] = static_cast<ObjectState>(state_words_[k]);
  if (has_pixels) {
    out.pixels.resize(objects);
    if (objects) glGetNamedBufferSubData(pixels_.get(), 0, 4 * static_cast<GLsizeiptr>(objects), out.pixels.data());
  } else {
    out.pixels.clear();
  }
}

}  // namespace gl

Result<std::unique_ptr<Detector>> make_gl_detector(const Config& config, const GlOptions& options) {
  auto d = gl::GlDetector::create(config, options);
  if (!d) return Result<std::unique_ptr<Detector>>::failure(d.status());
  return detail::DetectorAccess::wrap(std::move(d.value()));
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
       {&spheres_, &counts_,   &pixels_,  &flags_,   &scan_out_,  &block_sums_, &active_,     &info_,    &partials_,
        &hist_,    &dispatch_, &nodes_,   &parent_,  &arrivals_,  &sorted_,     &leaf_boxes_, &pairs_,   &pairs_tmp_,
        &states_,  &image_,    &keys_[0], &keys_[1], &values_[0], &values_[1],  &mesh_vbo_,   &mesh_ibo_})
    b += static_cast<std::uint64_t>(buf->size());
  // G-buffer: R32UI ids, R32F depth, RGBA32F normals, 32-bit float z-buffer.
  b += static_cast<std::uint64_t>(map_w_) * static_cast<std::uint64_t>(map_h_) * (4 + 4 + 16 + 4);
  return b;
}

Result<unsigned> make_gl_id_texture(int width, int height) {
  using R = Result<unsigned>;
  if (Status s = validate_map_size(width, height); !s) return R::failure(s);
  if (width < 1 || height < 1)
    return R::failure(ErrorKind::invalid_input, "an id texture of " + std::to_string(width) + "x" +
                                                    std::to_string(height) + " texels: both sides must be at least 1");
  if (!glGetString(GL_VERSION) || epoxy_gl_version() < 45)
    return R::failure(ErrorKind::backend_failure,
                      "make_gl_id_texture: no OpenGL 4.5 context is current on this thread");
  GLuint t = 0;
  glCreateTextures(GL_TEXTURE_2D, 1, &t);
  glTextureStorage2D(t, 1, GL_R32UI, width, height);
  glTextureParameteri(t, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
  glTextureParameteri(t, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
  if (const GLenum e = glGetError(); e != GL_NO_ERROR) {
    glDeleteTextures(1, &t);
    return R::failure(ErrorKind::backend_failure, "make_gl_id_texture: OpenGL error " + std::to_string(e));
  }
  return t;
}

Result<std::string> gl_device() {
  auto ctx = gl::Context::create(false);
  if (!ctx) return Result<std::string>::failure(ctx.status());
  return ctx.value()->description();
}

}  // namespace viscd
