// The gl backend's Backend (gl_detector.hpp): creation, the frame as its list of stages over
// the parts, the queries, and the factories of viscd/gl.hpp.
#include "gl/gl_detector.hpp"

#include <algorithm>
#include <cstdio>
#include <new>
#include <string>

#include "core/frame_rules.hpp"

namespace viscd {
namespace gl {

GlDetector::GlDetector(const Config& config, const GlOptions& options, std::unique_ptr<Context> ctx)
    : Backend(config),
      options_(options),
      ctx_(std::move(ctx)),
      visibility_(frame_, timers_, config_, options_),
      culling_(frame_, timers_, config_),
      layout_(frame_, timers_, config_, options_),
      broadphase_(frame_, timers_, config_, options_),
      readback_(frame_, *ctx_) {}

Result<std::unique_ptr<GlDetector>> GlDetector::create(const Config& config, const GlOptions& options) {
  using R = Result<std::unique_ptr<GlDetector>>;
  auto ctx = options.use_current_context ? Context::adopt_current() : Context::create(options.debug);
  if (!ctx) return R::failure(ctx.status());
  std::unique_ptr<GlDetector> d(new GlDetector(config, options, std::move(ctx.value())));
  if (Status s = d->init(); !s) return R::failure(s);
  return d;
}

GlDetector::~GlDetector() {
  // The parts' GL objects are deleted by their owners, which need this context current.
  (void)ctx_->make_current();
}

Status GlDetector::init() {
  if (Status s = visibility_.init(); !s) return s;
  if (Status s = culling_.init(); !s) return s;
  if (Status s = layout_.init(); !s) return s;
  if (Status s = broadphase_.init(); !s) return s;
  frame_.info.reserve(sizeof(shader::FrameInfo));
  frame_.dispatch.reserve(sizeof(shader::DispatchArgs));
  GLint groups = 0;
  glGetIntegeri_v(GL_MAX_COMPUTE_WORK_GROUP_COUNT, 0, &groups);
  max_groups_ = static_cast<std::uint32_t>(std::max(groups, 1));
  timers_.init();
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

void GlDetector::wait_for_stage_times(FrameStats& stats) {
  if (!timers_.available() || !ctx_->make_current()) return;
  timers_.wait_for_last(stats);
}

// ---- the frame ----

Status GlDetector::run_frame(const FrameInput& input, FrameResult& out) {
  try {
    return detect_frame(input, out);
  } catch (const std::bad_alloc&) {
    return Status::failure(
        ErrorKind::out_of_memory,
        detail::out_of_memory_message(detail::Shapes::of(input).size() + static_set_.size(), input.camera, config_));
  }
}

detail::QueryObjects GlDetector::query_objects() { return readback_.query_objects(); }

Status GlDetector::detect_frame(const FrameInput& in, FrameResult& out) {
  // Passes over N run one invocation per object (scan blocks of VISCD_SCAN_BLOCK), one
  // dispatch each: the driver's work-group limit bounds N.
  const std::uint64_t max_objects =
      std::min<std::uint64_t>((std::uint64_t{1} << 29) - 1, std::uint64_t{max_groups_} * VISCD_WG_SIZE);
  const std::uint64_t frame_objects = detail::Shapes::of(in).size() + static_set_.size();
  if (frame_objects > max_objects)
    return Status::failure(
        ErrorKind::unsupported_input,
        "the gl backend handles at most " + std::to_string(max_objects) +
            " objects on this driver (GL_MAX_COMPUTE_WORK_GROUP_COUNT = " + std::to_string(max_groups_) +
            " groups of " + std::to_string(VISCD_WG_SIZE) + "); the frame has " + std::to_string(frame_objects) +
            " (its static set included): use the cpu backend");
  if (!ctx_->make_current())
    return Status::failure(ErrorKind::backend_failure, "OpenGL: cannot make the detector's context current");
  if (Status s = gl_errors("an earlier call"); !s) return s;
  const bool has_camera = in.camera != nullptr;
  const bool callers_map = detail::has_callers_map(in);

  begin_frame(in);
  // Every pass runs over all objects, the moving ones and then the static set's; the static
  // ones are drawn, always active and never paired with each other.
  const std::uint32_t total = frame_.objects, n = frame_.moving;
  FrameStats& stats = out.stats;
  stats = FrameStats{};
  stats.objects = n;
  stats.static_objects = total - n;
  stats.has_camera = has_camera;
  stats.has_pixels = frame_.has_pixels;
  readback_.begin_frame(total, n, all_.slots);  // the objects and states on the GPU are this frame's now
  // 1-2: the detector's own map and its counts, or counting on the caller's map.
  if (callers_map) {
    if (Status s = visibility_.count_callers_map(in); !s) return s;
  } else if (frame_.rig) {  // a camera whose map something uses (core's renders_own_map())
    if (Status s = visibility_.render(total); !s) return s;
  }
  // 3: cull, compact, dispatch sizes.
  culling_.cull(total, n);
  // 4: the active centres' bounds on the GPU, m and the layout on the host.
  layout_.measure_extent();
  const LayoutChoice choice = layout_.choose(total, n, frame_.has_pixels, stats);
  // 5-8: codes, sort, build, fit, query, the frame's final wait, pair sort; the pairs back.
  const auto pairs = broadphase_.run(choice.n_bound, total, n, choice.layout, choice.bounds, stats);
  if (!pairs) return pairs.status();
  readback_.read_pairs(broadphase_.pairs(), pairs.value(), out.pairs);
  all_.report(out.pairs);  // static objects as static_index(slot); the order stays sorted
  // What the final wait read: the caller's map's id check, the next frame's layout inputs.
  if (Status s = Visibility::id_check(in, broadphase_.frame_info()); !s) return s;
  layout_.remember(n, frame_.has_pixels, broadphase_.frame_info(), stats);
  // 8, last part: the colliding states; then states and pixels back (the moving objects').
  broadphase_.mark_colliding(pairs.value());
  readback_.read_states_and_pixels(n, frame_.has_pixels, out);
  // 9: shading, the image back.
  visibility_.shade(out);
  // GPU times of the previous frame; `layout` keeps this frame's host time.
  const double layout_ms = stats.ms(Stage::layout);
  timers_.read_previous(stats);
  stats.ms(Stage::layout) = layout_ms;
  return gl_errors("detect()");
}

void GlDetector::begin_frame(const FrameInput& in) {
  // The frame's objects then the static set's, as one array (a view of the input, no copy,
  // without a static set). The static set is uploaded with every frame: the gl backend keeps no
  // structure of its own for it (docs/gl.md).
  all_.build(in, &static_set_);
  const auto n = static_cast<std::uint32_t>(all_.moving);
  const auto total = static_cast<std::uint32_t>(all_.total());
  frame_.upload_objects(all_.objects, n);
  frame_.has_filters = !all_.filters.empty();  // the frame's or the static set's
  if (frame_.has_filters) {
    static_assert(sizeof(Filter) == 8, "Filter must match GLSL uvec2 (group, mask)");
    frame_.filters.reserve(8 * static_cast<GLsizeiptr>(total));
    glNamedBufferSubData(frame_.filters.get(), 0, 8 * static_cast<GLsizeiptr>(total), all_.filters.data());
  }
  frame_.has_always = !in.always_active.empty();
  if (frame_.has_always) {
    // The bytes as they are; the shader reads byte k of word k / 4 (std430 has no byte arrays).
    frame_.always.reserve(4 * ((static_cast<GLsizeiptr>(n) + 3) / 4));
    glNamedBufferSubData(frame_.always.get(), 0, static_cast<GLsizeiptr>(n), in.always_active.data());
  }
  for (Buffer* b : {&frame_.counts, &frame_.pixels, &frame_.active, &frame_.states})
    b->reserve(4 * static_cast<GLsizeiptr>(total));
  culling_.reserve(total);
  layout_.reserve(total);
  shader::FrameInfo zero_info{};
  zero_info.id_check.y = 0xFFFFFFFFu;  // atomicMin's start: no bad pixel
  glNamedBufferSubData(frame_.info.get(), 0, sizeof zero_info, &zero_info);
  const bool callers_map = detail::has_callers_map(in);
  frame_.has_pixels = detail::counts_pixels(in, config_);
  frame_.rig.reset();
  if (callers_map) {
    frame_.pixel_scale = detail::map_pixel_scale(in.camera, in.id_map_width, in.id_map_height);
  } else if (detail::renders_own_map(in, config_)) {
    const detail::MapSize map = detail::map_size(config_, *in.camera);
    frame_.rig.emplace(*in.camera, map.width, map.height);
    frame_.pixel_scale = frame_.rig->pixel_scale;
  } else {
    frame_.pixel_scale = 1.0;
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
  return frame_.buffer_bytes() + visibility_.memory_bytes() + culling_.buffer_bytes() + layout_.buffer_bytes() +
         broadphase_.buffer_bytes();
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
