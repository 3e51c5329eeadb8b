// Stages 1, 2 and 9 of the gl backend (visibility.hpp): the G-buffer pass, pixel counting (also
// on the caller's map), deferred shading.
#include "gl/visibility.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <string>

#include "core/frame_rules.hpp"
#include "core/visibility.hpp"
#include "viscd/assert.hpp"

namespace viscd::gl {
namespace {

Texture make_texture(GLenum format, int w, int h) {
  GLuint t = 0;
  glCreateTextures(GL_TEXTURE_2D, 1, &t);
  glTextureStorage2D(t, 1, format, w, h);
  glTextureParameteri(t, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
  glTextureParameteri(t, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
  return Texture(t);
}

// Work groups of a 2D pass over the map (VISCD_TILE_SIDE pixels a side).
void dispatch_over_map(GLuint program, int w, int h) {
  const auto groups = [](int pixels) { return static_cast<GLuint>((pixels + VISCD_TILE_SIDE - 1) / VISCD_TILE_SIDE); };
  if (w <= 0 || h <= 0) return;
  glUseProgram(program);
  glDispatchCompute(groups(w), groups(h), 1);
}

}  // namespace

Status Visibility::init() {
  if (Status s = build_compute_programs({{&count_, "count.comp"},
                                         {&shade_, "shade.comp"},
                                         {&splat_plan_, "splat_plan.comp"},
                                         {&splat_, "splat.comp"},
                                         {&splat_resolve_, "splat_resolve.comp"}});
      !s)
    return s;
  auto imp = Program::graphics("gbuffer_impostor.vert", "gbuffer_impostor.frag");
  if (!imp) return imp.status();
  impostor_ = std::move(imp.value());
  auto mesh = Program::graphics("gbuffer_mesh.vert", "gbuffer_mesh.frag");
  if (!mesh) return mesh.status();
  mesh_ = std::move(mesh.value());
  auto box = Program::graphics("gbuffer_box.vert", "gbuffer_box.frag");
  if (!box) return box.status();
  box_ = std::move(box.value());
  GLuint name = 0;
  glCreateVertexArrays(1, &name);
  empty_vao_ = VertexArray(name);
  glCreateFramebuffers(1, &name);
  empty_fbo_ = Framebuffer(name);
  glCreateSamplers(1, &name);
  nearest_ = Sampler(name);
  glSamplerParameteri(name, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
  glSamplerParameteri(name, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
  glGetIntegerv(GL_MAX_FRAGMENT_ATOMIC_COUNTERS, &max_fragment_counters_);
  glGetIntegerv(GL_MAX_ATOMIC_COUNTER_BUFFER_SIZE, &max_counter_buffer_bytes_);
  return {};
}

void Visibility::set_camera_uniforms(const Program& prog) const {
  const detail::CameraRig& rig = *frame_.rig;
  const GLuint p = prog.get();
  glProgramUniform3f(p, prog.uniform("u_eye"), rig.eye.x, rig.eye.y, rig.eye.z);
  glProgramUniform3f(p, prog.uniform("u_forward"), rig.forward.x, rig.forward.y, rig.forward.z);
  glProgramUniform3f(p, prog.uniform("u_right"), rig.right.x, rig.right.y, rig.right.z);
  glProgramUniform3f(p, prog.uniform("u_up"), rig.up.x, rig.up.y, rig.up.z);
  glProgramUniform2f(p, prog.uniform("u_tan_half"), rig.tan_half_x, rig.tan_half_y);
  glProgramUniform2f(p, prog.uniform("u_near_far"), rig.near_plane, rig.far_plane);
  if (prog.has_uniform("u_map")) glProgramUniform2i(p, prog.uniform("u_map"), rig.map_w, rig.map_h);  // not the mesh
}

Status Visibility::render(std::uint32_t objects) {
  if (options_.counter == GlCounter::atomic_uint) {
    // Checked before any work so that the error is clean.
    const std::uint32_t limit = std::min<std::uint32_t>(static_cast<std::uint32_t>(max_fragment_counters_),
                                                        static_cast<std::uint32_t>(max_counter_buffer_bytes_) / 4);
    if (objects > limit)
      return Status::failure(
          ErrorKind::unsupported_input,
          "atomic_uint counting supports at most " + std::to_string(limit) +
              " objects on this driver (GL_MAX_FRAGMENT_ATOMIC_COUNTERS = " + std::to_string(max_fragment_counters_) +
              ", GL_MAX_ATOMIC_COUNTER_BUFFER_SIZE = " + std::to_string(max_counter_buffer_bytes_) +
              " bytes); the frame has " + std::to_string(objects) + ": use the ssbo counter mode");
  }
  timers_.begin(Stage::visibility);
  ensure_map(frame_.rig->map_w, frame_.rig->map_h);
  draw_gbuffer(objects);
  timers_.end(Stage::visibility);
  timers_.begin(Stage::count);
  if (Status s = count_pixels(ids_tex_.get(), map_w_, map_h_, objects, options_.counter); !s) return s;
  timers_.end(Stage::count);
  return {};
}

Status Visibility::count_callers_map(const FrameInput& in) {
  const int w = in.id_map_width, h = in.id_map_height;
  // The frame's moving objects: static ones are not in the caller's map (their pixels are 0).
  const auto objects = static_cast<std::uint32_t>(detail::Shapes::of(in).size());
  GLuint ids = in.gl_id_texture;
  if (ids == 0) {
    // The caller's array as a texture of our own. Its row 0 is the top; counting does not care.
    ensure_map(w, h);
    glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
    glPixelStorei(GL_UNPACK_ROW_LENGTH, 0);
    glTextureSubImage2D(ids_tex_.get(), 0, 0, 0, w, h, GL_RED_INTEGER, GL_UNSIGNED_INT, in.id_map.data());
    ids = ids_tex_.get();
  } else {
    if (glIsTexture(ids) != GL_TRUE)
      return Status::failure(ErrorKind::invalid_input,
                             "FrameInput::gl_id_texture = " + std::to_string(ids) +
                                 " is not a texture of the detector's OpenGL context (GlOptions::use_current_context "
                                 "makes the detector use the caller's)");
    GLint tw = 0, th = 0, format = 0;
    glGetTextureLevelParameteriv(ids, 0, GL_TEXTURE_WIDTH, &tw);
    glGetTextureLevelParameteriv(ids, 0, GL_TEXTURE_HEIGHT, &th);
    glGetTextureLevelParameteriv(ids, 0, GL_TEXTURE_INTERNAL_FORMAT, &format);
    if (format != GL_R32UI) {
      char hex[16];
      std::snprintf(hex, sizeof hex, "0x%04x", static_cast<unsigned>(format));
      return Status::failure(ErrorKind::invalid_input,
                             "FrameInput::gl_id_texture = " + std::to_string(ids) +
                                 ": expected an R32UI texture (object index + 1 per texel); its internal format is " +
                                 hex);
    }
    if (tw != w || th != h)
      return Status::failure(ErrorKind::invalid_input, "FrameInput::gl_id_texture = " + std::to_string(ids) + " is " +
                                                           std::to_string(tw) + "x" + std::to_string(th) +
                                                           " texels, but id_map_width x id_map_height is " +
                                                           std::to_string(w) + "x" + std::to_string(h));
  }
  timers_.begin(Stage::count);
  // Always the ssbo counter: it checks every id against N, which a caller's map needs.
  const Status s = count_pixels(ids, w, h, objects, GlCounter::ssbo);
  timers_.end(Stage::count);
  return s;
}

Status Visibility::id_check(const FrameInput& in, const shader::FrameInfo& info) {
  const std::uint32_t bad = info.id_check.x;
  if (bad == 0) return {};
  const std::size_t n = detail::Shapes::of(in).size();
  if (!in.id_map.empty()) return detail::id_map_error(in.id_map, in.id_map_width, n);
  const std::uint32_t first = info.id_check.y;
  const auto w = static_cast<std::uint32_t>(in.id_map_width);
  return Status::failure(ErrorKind::invalid_input, "FrameInput::gl_id_texture: texel (" + std::to_string(first % w) +
                                                       ", " + std::to_string(first / w) + ") and " +
                                                       std::to_string(bad - 1) + " more hold ids above the frame's " +
                                                       std::to_string(n) +
                                                       " objects (an id is an object index + 1, 0 is background)");
}

// The G-buffer: ids (R32UI), view depth (R32F), normal (RGBA32F) and a D32F depth buffer.
void Visibility::ensure_map(int w, int h) {
  if (w == map_w_ && h == map_h_ && gbuffer_) return;
  map_w_ = w;
  map_h_ = h;
  ids_tex_ = make_texture(GL_R32UI, w, h);
  depth_tex_ = make_texture(GL_R32F, w, h);
  normal_tex_ = make_texture(GL_RGBA32F, w, h);
  zbuffer_ = make_texture(GL_DEPTH_COMPONENT32F, w, h);
  GLuint f = 0;
  glCreateFramebuffers(1, &f);
  gbuffer_ = Framebuffer(f);
  glNamedFramebufferTexture(f, GL_COLOR_ATTACHMENT0, ids_tex_.get(), 0);
  glNamedFramebufferTexture(f, GL_COLOR_ATTACHMENT1, depth_tex_.get(), 0);
  glNamedFramebufferTexture(f, GL_COLOR_ATTACHMENT2, normal_tex_.get(), 0);
  glNamedFramebufferTexture(f, GL_DEPTH_ATTACHMENT, zbuffer_.get(), 0);
  const GLenum draw[] = {GL_COLOR_ATTACHMENT0, GL_COLOR_ATTACHMENT1, GL_COLOR_ATTACHMENT2};
  glNamedFramebufferDrawBuffers(f, 3, draw);
  VISCD_ASSERT(glCheckNamedFramebufferStatus(f, GL_FRAMEBUFFER) == GL_FRAMEBUFFER_COMPLETE, "G-buffer incomplete");
  // The attachment-less framebuffer of the atomic_uint counting pass.
  glNamedFramebufferParameteri(empty_fbo_.get(), GL_FRAMEBUFFER_DEFAULT_WIDTH, w);
  glNamedFramebufferParameteri(empty_fbo_.get(), GL_FRAMEBUFFER_DEFAULT_HEIGHT, h);
}

// A UV sphere of 16 stacks x 32 slices (960 triangles), vertices on the unit sphere.
void Visibility::make_mesh() {
  constexpr int kStacks = 16, kSlices = 32;
  std::vector<float> v;
  std::vector<GLuint> idx;
  for (int i = 0; i <= kStacks; ++i) {
    const double phi = std::numbers::pi * i / kStacks;
    for (int j = 0; j <= kSlices; ++j) {
      const double th = 2 * std::numbers::pi * j / kSlices;
      v.push_back(static_cast<float>(std::sin(phi) * std::cos(th)));
      v.push_back(static_cast<float>(std::cos(phi)));
      v.push_back(static_cast<float>(std::sin(phi) * std::sin(th)));
    }
  }
  for (int i = 0; i < kStacks; ++i)
    for (int j = 0; j < kSlices; ++j) {
      const GLuint a = static_cast<GLuint>(i * (kSlices + 1) + j), b = a + kSlices + 1;
      if (i != 0) idx.insert(idx.end(), {a, b, a + 1});
      if (i != kStacks - 1) idx.insert(idx.end(), {a + 1, b, b + 1});
    }
  mesh_indices_ = static_cast<GLsizei>(idx.size());
  mesh_vbo_.reserve(static_cast<GLsizeiptr>(v.size() * sizeof(float)));
  mesh_ibo_.reserve(static_cast<GLsizeiptr>(idx.size() * sizeof(GLuint)));
  glNamedBufferSubData(mesh_vbo_.get(), 0, static_cast<GLsizeiptr>(v.size() * sizeof(float)), v.data());
  glNamedBufferSubData(mesh_ibo_.get(), 0, static_cast<GLsizeiptr>(idx.size() * sizeof(GLuint)), idx.data());
  GLuint vao = 0;
  glCreateVertexArrays(1, &vao);
  mesh_vao_ = VertexArray(vao);
  glVertexArrayVertexBuffer(vao, 0, mesh_vbo_.get(), 0, 3 * sizeof(float));
  glVertexArrayElementBuffer(vao, mesh_ibo_.get());
  glEnableVertexArrayAttrib(vao, 0);
  glVertexArrayAttribFormat(vao, 0, 3, GL_FLOAT, GL_FALSE, 0);
  glVertexArrayAttribBinding(vao, 0, 0);
}

// Stage 1: instanced draw of every object (the static ones after the moving ones, so that they
// occlude), ids ascending; depth test LESS keeps the nearest hit and, on equal depth, the first
// drawn (smaller id), GL's primitive order guarantee.
void Visibility::splat_gbuffer(std::uint32_t n) {
  const auto pixels = static_cast<GLsizeiptr>(map_w_) * static_cast<GLsizeiptr>(map_h_);
  splat_depth_.reserve(4 * pixels);
  splat_ids_.reserve(4 * pixels);
  const GLuint none = 0xFFFFFFFFu;
  glClearNamedBufferSubData(splat_depth_.get(), GL_R32UI, 0, 4 * pixels, GL_RED_INTEGER, GL_UNSIGNED_INT, &none);
  glClearNamedBufferSubData(splat_ids_.get(), GL_R32UI, 0, 4 * pixels, GL_RED_INTEGER, GL_UNSIGNED_INT, &none);
  frame_.spheres.bind_storage(VISCD_BIND_SPHERES);
  splat_depth_.bind_storage(VISCD_BIND_SPLAT_DEPTH);
  splat_ids_.bind_storage(VISCD_BIND_SPLAT_IDS);
  if (n > 0) {
    // Plan: each sphere's rectangle, cut into chunks; the host reads how many (this mode's one
    // wait of its own) and, when the list was too short, grows it and plans again.
    splat_rects_.reserve(16 * static_cast<GLsizeiptr>(n));
    splat_rects_.bind_storage(VISCD_BIND_SPLAT_RECTS);
    splat_count_.reserve(4);
    splat_count_.bind_storage(VISCD_BIND_SPLAT_COUNT);
    set_camera_uniforms(splat_plan_);
    glProgramUniform1ui(splat_plan_.get(), splat_plan_.uniform("u_objects"), n);
    const GLuint groups = (n + VISCD_WG_SIZE - 1) / VISCD_WG_SIZE;
    const GLuint gx = std::min<GLuint>(groups, 65535u), gy = (groups + gx - 1) / gx;
    GLuint chunks = 0;
    for (int attempt = 0; attempt < 2; ++attempt) {
      splat_chunks_.reserve(8 * static_cast<GLsizeiptr>(std::max(splat_capacity_, 1u)));
      splat_chunks_.bind_storage(VISCD_BIND_SPLAT_CHUNKS);
      const GLuint zero = 0;
      glClearNamedBufferSubData(splat_count_.get(), GL_R32UI, 0, 4, GL_RED_INTEGER, GL_UNSIGNED_INT, &zero);
      glProgramUniform1ui(splat_plan_.get(), splat_plan_.uniform("u_capacity"), splat_capacity_);
      glUseProgram(splat_plan_.get());
      glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT | GL_BUFFER_UPDATE_BARRIER_BIT);
      glDispatchCompute(gx, gy, 1);
      glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT | GL_SHADER_STORAGE_BARRIER_BIT);
      glGetNamedBufferSubData(splat_count_.get(), 0, 4, &chunks);
      if (chunks <= splat_capacity_) break;
      splat_capacity_ = chunks;  // the exact count: the second plan writes every chunk
    }
    if (chunks > 0) {
      // One work group per chunk, on a 2D grid: GL promises 65 535 groups per dimension.
      const GLuint cx = std::min<GLuint>(chunks, 65535u), cy = (chunks + cx - 1) / cx;
      set_camera_uniforms(splat_);
      glProgramUniform1ui(splat_.get(), splat_.uniform("u_chunks"), chunks);
      glUseProgram(splat_.get());
      for (GLuint pass = 0; pass < 2; ++pass) {
        glProgramUniform1ui(splat_.get(), splat_.uniform("u_pass"), pass);
        glDispatchCompute(cx, cy, 1);
        glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
      }
    }
  }
  glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT | GL_BUFFER_UPDATE_BARRIER_BIT);
  set_camera_uniforms(splat_resolve_);
  glBindImageTexture(0, ids_tex_.get(), 0, GL_FALSE, 0, GL_WRITE_ONLY, GL_R32UI);
  glBindImageTexture(1, depth_tex_.get(), 0, GL_FALSE, 0, GL_WRITE_ONLY, GL_R32F);
  glBindImageTexture(2, normal_tex_.get(), 0, GL_FALSE, 0, GL_WRITE_ONLY, GL_RGBA32F);
  glUseProgram(splat_resolve_.get());
  glDispatchCompute((static_cast<GLuint>(map_w_) + VISCD_TILE_SIDE - 1) / VISCD_TILE_SIDE,
                    (static_cast<GLuint>(map_h_) + VISCD_TILE_SIDE - 1) / VISCD_TILE_SIDE, 1);
  glMemoryBarrier(GL_ALL_BARRIER_BITS);
}

void Visibility::draw_gbuffer(std::uint32_t n) {
  if (options_.geometry == GlGeometry::splat && !frame_.has_boxes) {
    splat_gbuffer(n);
    return;
  }
  const detail::CameraRig& rig = *frame_.rig;
  const GLuint zero_id[4] = {0, 0, 0, 0};
  const float far_depth[4] = {rig.far_plane, 0, 0, 0};
  const float zero[4] = {0, 0, 0, 0};
  const float one = 1.0f;
  glClearNamedFramebufferuiv(gbuffer_.get(), GL_COLOR, 0, zero_id);
  glClearNamedFramebufferfv(gbuffer_.get(), GL_COLOR, 1, far_depth);
  glClearNamedFramebufferfv(gbuffer_.get(), GL_COLOR, 2, zero);
  glClearNamedFramebufferfv(gbuffer_.get(), GL_DEPTH, 0, &one);
  if (n == 0) return;
  glBindFramebuffer(GL_FRAMEBUFFER, gbuffer_.get());
  glViewport(0, 0, map_w_, map_h_);
  glEnable(GL_DEPTH_TEST);
  glDepthFunc(GL_LESS);
  glDisable(GL_CULL_FACE);  // a camera inside a sphere sees its back faces (CameraRig hit())
  frame_.spheres.bind_storage(VISCD_BIND_SPHERES);
  if (frame_.has_boxes) {
    // Boxes are cubes in both geometry modes. The cube may reach behind the near plane (its
    // fragments ray-cast the box and keep the far side, as for spheres) and beyond the far
    // plane: depth clamping keeps such parts from being clipped away; gl_FragDepth is the hit's.
    frame_.boxes.bind_storage(VISCD_BIND_BOXES);
    set_camera_uniforms(box_);
    glEnable(GL_DEPTH_CLAMP);
    glUseProgram(box_.get());
    glBindVertexArray(empty_vao_.get());
    glDrawArraysInstanced(GL_TRIANGLES, 0, 36, static_cast<GLsizei>(n));
    glDisable(GL_DEPTH_CLAMP);
  } else if (options_.geometry == GlGeometry::mesh) {
    if (!mesh_vao_) make_mesh();
    set_camera_uniforms(mesh_);
    glUseProgram(mesh_.get());
    glBindVertexArray(mesh_vao_.get());
    glDrawElementsInstanced(GL_TRIANGLES, mesh_indices_, GL_UNSIGNED_INT, nullptr, static_cast<GLsizei>(n));
  } else {
    set_camera_uniforms(impostor_);
    glUseProgram(impostor_.get());
    glBindVertexArray(empty_vao_.get());
    glDrawArraysInstanced(GL_TRIANGLE_STRIP, 0, 4, static_cast<GLsizei>(n));
  }
  glDisable(GL_DEPTH_TEST);
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  glMemoryBarrier(GL_ALL_BARRIER_BITS);
}

// Stage 2 from an id texture into FrameData::counts[0..n).
Status Visibility::count_pixels(GLuint ids, int w, int h, std::uint32_t n, GlCounter mode) {
  frame_.counts.reserve(4 * static_cast<GLsizeiptr>(n));
  const GLuint zero = 0;
  glClearNamedBufferSubData(frame_.counts.get(), GL_R32UI, 0, frame_.counts.size(), GL_RED_INTEGER, GL_UNSIGNED_INT,
                            &zero);
  glMemoryBarrier(GL_ALL_BARRIER_BITS);
  glBindTextureUnit(VISCD_UNIT_IDS, ids);
  glBindSampler(VISCD_UNIT_IDS, nearest_.get());
  if (mode == GlCounter::atomic_uint) {
    if (n == 0) return {};
    if (!count_atomic_ || count_atomic_n_ != n) {
      auto p = Program::graphics("fullscreen.vert", "count_atomic.frag",
                                 "#define VISCD_AC_COUNT " + std::to_string(n) + "\n");
      if (!p) return p.status();
      count_atomic_ = std::move(p.value());
      count_atomic_n_ = n;
    }
    // The counts buffer is the atomic counter buffer: no copy afterwards.
    glBindBufferRange(GL_ATOMIC_COUNTER_BUFFER, VISCD_BIND_ATOMIC_COUNTERS, frame_.counts.get(), 0,
                      4 * static_cast<GLsizeiptr>(n));
    glBindFramebuffer(GL_FRAMEBUFFER, empty_fbo_.get());
    glViewport(0, 0, w, h);
    glUseProgram(count_atomic_.get());
    glBindVertexArray(empty_vao_.get());
    glDrawArrays(GL_TRIANGLES, 0, 3);
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
  } else {
    frame_.counts.bind_storage(VISCD_BIND_COUNTS);
    frame_.info.bind_storage(VISCD_BIND_INFO);
    glProgramUniform2i(count_.get(), count_.uniform("u_map"), w, h);
    glProgramUniform1ui(count_.get(), count_.uniform("u_n"), n);
    dispatch_over_map(count_.get(), w, h);
  }
  glBindSampler(VISCD_UNIT_IDS, 0);
  glMemoryBarrier(GL_ALL_BARRIER_BITS);
  return {};
}

// Stage 9: the shared shading model and state colours (core/visibility.hpp, viscd/types.hpp),
// as the cpu backend's shade().
void Visibility::shade(FrameResult& out) {
  if (!frame_.rig || !config_.shade) {
    out.image.clear();
    out.image_width = out.image_height = 0;
    return;
  }
  timers_.begin(Stage::shade);
  const std::size_t pixels = static_cast<std::size_t>(map_w_) * static_cast<std::size_t>(map_h_);
  image_.reserve(4 * static_cast<GLsizeiptr>(pixels));
  const detail::ShadingModel& model = detail::shading_model();
  const GLuint p = shade_.get();
  glProgramUniform2i(p, shade_.uniform("u_map"), map_w_, map_h_);
  glProgramUniform3f(p, shade_.uniform("u_light"), model.light.x, model.light.y, model.light.z);
  glProgramUniform3f(p, shade_.uniform("u_terms"), model.ambient, model.diffuse, model.rim);
  glProgramUniform3f(p, shade_.uniform("u_view"), -frame_.rig->forward.x, -frame_.rig->forward.y,
                     -frame_.rig->forward.z);
  float colours[15];
  const Rgb8 c[5] = {state_colour(ObjectState::colliding), state_colour(ObjectState::free),
                     state_colour(ObjectState::culled), kBackgroundColour, kStaticColour};
  for (int k = 0; k < 5; ++k) {
    colours[3 * k] = c[k].r;
    colours[3 * k + 1] = c[k].g;
    colours[3 * k + 2] = c[k].b;
  }
  glProgramUniform3fv(p, shade_.uniform("u_colour"), 5, colours);
  glProgramUniform1ui(p, shade_.uniform("u_moving"), frame_.moving);
  glBindTextureUnit(VISCD_UNIT_IDS, ids_tex_.get());
  glBindTextureUnit(VISCD_UNIT_NORMAL, normal_tex_.get());
  frame_.states.bind_storage(VISCD_BIND_STATE);
  image_.bind_storage(VISCD_BIND_IMAGE);
  dispatch_over_map(p, map_w_, map_h_);
  glMemoryBarrier(GL_ALL_BARRIER_BITS);
  timers_.end(Stage::shade);
  out.image.resize(4 * pixels);
  glGetNamedBufferSubData(image_.get(), 0, static_cast<GLsizeiptr>(out.image.size()), out.image.data());
  out.image_width = map_w_;
  out.image_height = map_h_;
}

std::uint64_t Visibility::memory_bytes() const {
  std::uint64_t b = 0;
  for (const Buffer* buf :
       {&image_, &mesh_vbo_, &mesh_ibo_, &splat_depth_, &splat_ids_, &splat_rects_, &splat_chunks_, &splat_count_})
    b += static_cast<std::uint64_t>(buf->size());
  // G-buffer: R32UI ids, R32F depth, RGBA32F normals, 32-bit float z-buffer.
  b += static_cast<std::uint64_t>(map_w_) * static_cast<std::uint64_t>(map_h_) * (4 + 4 + 16 + 4);
  return b;
}

std::vector<std::uint32_t> Visibility::read_id_map() {
  const std::size_t w = static_cast<std::size_t>(map_w_), h = static_cast<std::size_t>(map_h_);
  std::vector<std::uint32_t> bottom_up(w * h), ids(w * h);
  if (!ids_tex_ || ids.empty()) return ids;
  glGetTextureImage(ids_tex_.get(), 0, GL_RED_INTEGER, GL_UNSIGNED_INT, static_cast<GLsizei>(4 * w * h),
                    bottom_up.data());
  for (std::size_t y = 0; y < h; ++y) std::copy_n(&bottom_up[(h - 1 - y) * w], w, &ids[y * w]);
  return ids;
}

Result<std::vector<std::uint32_t>> Visibility::count_id_map(std::span<const std::uint32_t> ids, int width, int height,
                                                            std::uint32_t objects) {
  using R = Result<std::vector<std::uint32_t>>;
  VISCD_ASSERT(ids.size() == static_cast<std::size_t>(width) * static_cast<std::size_t>(height), "id map size");
  ensure_map(width, height);
  const std::size_t w = static_cast<std::size_t>(width), h = static_cast<std::size_t>(height);
  std::vector<std::uint32_t> bottom_up(w * h);
  for (std::size_t y = 0; y < h; ++y) std::copy_n(&ids[(h - 1 - y) * w], w, &bottom_up[y * w]);
  glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
  glTextureSubImage2D(ids_tex_.get(), 0, 0, 0, width, height, GL_RED_INTEGER, GL_UNSIGNED_INT, bottom_up.data());
  glMemoryBarrier(GL_ALL_BARRIER_BITS);
  if (Status s = count_pixels(ids_tex_.get(), width, height, objects, options_.counter); !s) return R::failure(s);
  std::vector<std::uint32_t> counts(objects);
  if (objects) glGetNamedBufferSubData(frame_.counts.get(), 0, 4 * static_cast<GLsizeiptr>(objects), counts.data());
  return counts;
}

}  // namespace viscd::gl
