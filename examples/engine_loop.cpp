// An engine's frame with viscd on the GPU, in the engine's own OpenGL context:
//  - the engine renders its G-buffer (here colour + depth + the id attachment viscd reads), with
//    viscd's GLSL snippets writing object index + 1 into an R32UI texture;
//  - viscd counts that map, culls, and finds the colliding pairs (gl backend, the same context);
//  - contact events tell new contacts from old ones; filters keep bullets off their shooter's
//    team; a ray query asks what the player aims at.
// Headless here (EGL surfaceless, llvmpipe in CI); a windowed engine has its context current.
// Built and run in CI against an installed viscd (tests/install/); docs/embedding.md.
// It checks itself: the pixels viscd reports equal a histogram of the id texture read back.
#include <epoxy/egl.h>
#include <epoxy/gl.h>
#include <viscd/viscd.hpp>

#include <array>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <vector>

namespace {

// The engine's renderer: a G-buffer with colour, depth and viscd's id attachment, and one
// instanced draw of camera-facing sphere billboards.
const char* kVertex = R"(
layout(std430, binding = 0) readonly buffer Spheres { vec4 spheres[]; };
uniform mat4 u_view_proj;
uniform vec3 u_right, u_up;
out vec2 v_corner;
void main() {
  const vec2 corners[4] = vec2[](vec2(-1, -1), vec2(1, -1), vec2(-1, 1), vec2(1, 1));
  const vec4 s = spheres[gl_InstanceID];
  v_corner = corners[gl_VertexID];
  const vec3 p = s.xyz + (u_right * v_corner.x + u_up * v_corner.y) * s.w;
  gl_Position = u_view_proj * vec4(p, 1.0);
  viscd_write_id();  // viscd's snippet: object index + 1 for the id attachment
}
)";
const char* kFragment = R"(
in vec2 v_corner;
layout(location = 0) out vec4 colour;
void main() {
  if (dot(v_corner, v_corner) > 1.0) discard;  // the billboard's disc
  colour = vec4(0.8, 0.8, 0.8, 1.0);
  viscd_output_id();  // viscd's snippet
}
)";

GLuint compile(GLenum stage, const char* prelude, const char* snippet, const char* body) {
  const GLuint s = glCreateShader(stage);
  const char* parts[] = {"#version 450 core\n", prelude, snippet, body};
  glShaderSource(s, 4, parts, nullptr);
  glCompileShader(s);
  GLint ok = 0;
  glGetShaderiv(s, GL_COMPILE_STATUS, &ok);
  if (!ok) {
    char log[2048];
    glGetShaderInfoLog(s, sizeof log, nullptr, log);
    std::fprintf(stderr, "shader: %s\n", log);
  }
  return s;
}

using Mat4 = std::array<float, 16>;  // column-major, as GL

// The view-projection of a viscd::Camera: right-handed look-at, OpenGL clip space.
Mat4 view_proj(const viscd::Camera& c, std::array<float, 3>& right, std::array<float, 3>& up) {
  auto sub = [](const float* a, const float* b) { return std::array<float, 3>{a[0] - b[0], a[1] - b[1], a[2] - b[2]}; };
  auto norm = [](std::array<float, 3> v) {
    const float l = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    return std::array<float, 3>{v[0] / l, v[1] / l, v[2] / l};
  };
  auto cross = [](std::array<float, 3> a, std::array<float, 3> b) {
    return std::array<float, 3>{a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
  };
  auto dot = [](std::array<float, 3> a, const float* b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; };
  const auto f = norm(sub(c.target, c.eye));
  right = norm(cross(f, {c.up[0], c.up[1], c.up[2]}));
  up = cross(right, f);
  const float t = 1.0f / std::tan(c.fov_y_deg * std::numbers::pi_v<float> / 360.0f);
  const float aspect = static_cast<float>(c.width) / static_cast<float>(c.height);
  const float n = c.near_plane, fa = c.far_plane;
  // projection * view, written out.
  const float p00 = t / aspect, p11 = t, p22 = -(fa + n) / (fa - n), p32 = -2 * fa * n / (fa - n);
  Mat4 m{};
  const std::array<float, 3> rows[3] = {right, up, {-f[0], -f[1], -f[2]}};
  const float tr[3] = {-dot(right, c.eye), -dot(up, c.eye), dot(f, c.eye)};
  for (int col = 0; col < 3; ++col) {
    m[col * 4 + 0] = p00 * rows[0][col];
    m[col * 4 + 1] = p11 * rows[1][col];
    m[col * 4 + 2] = p22 * rows[2][col];
    m[col * 4 + 3] = -rows[2][col];
  }
  m[12] = p00 * tr[0];
  m[13] = p11 * tr[1];
  m[14] = p22 * tr[2] + p32;
  m[15] = -tr[2];
  return m;
}

}  // namespace

int main() {
  // ---- the engine's context (a windowed engine has one already) ----
  EGLDisplay display = eglGetPlatformDisplayEXT(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr);
  if (display == EGL_NO_DISPLAY || !eglInitialize(display, nullptr, nullptr) || !eglBindAPI(EGL_OPENGL_API)) {
    std::fprintf(stderr, "no EGL display\n");
    return 1;
  }
  const EGLint attribs[] = {
      EGL_CONTEXT_MAJOR_VERSION,           4,       EGL_CONTEXT_MINOR_VERSION, 5, EGL_CONTEXT_OPENGL_PROFILE_MASK,
      EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT, EGL_NONE};
  EGLContext context = eglCreateContext(display, EGL_NO_CONFIG_KHR, EGL_NO_CONTEXT, attribs);
  if (context == EGL_NO_CONTEXT || !eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, context)) {
    std::fprintf(stderr, "no OpenGL 4.5 context\n");
    return 1;
  }

  // ---- the world: 4 000 objects on a ring, team A (even) and team B (odd); a few bullets ----
  constexpr int kObjects = 4000, kWidth = 640, kHeight = 360;
  constexpr std::uint32_t kTeamA = 1, kTeamB = 2, kBulletsOfA = 4;
  std::vector<viscd::Sphere> spheres(kObjects);
  std::vector<viscd::Filter> filters(kObjects);
  for (int k = 0; k < kObjects; ++k) {
    if (k % 50 == 0) {
      filters[k] = {kBulletsOfA, kTeamB};  // team A's bullets hit team B only
    } else {
      const std::uint32_t team = k % 2 ? kTeamB : kTeamA;
      filters[k] = {team, kTeamA | kTeamB | (team == kTeamB ? kBulletsOfA : 0u)};
    }
  }
  auto place = [&](float time) {
    for (int k = 0; k < kObjects; ++k) {
      const float a = 2 * std::numbers::pi_v<float> * static_cast<float>(k) / kObjects + time * (0.1f + 0.0001f * k);
      const float rho = 40.0f + 12.0f * std::sin(0.37f * static_cast<float>(k));
      spheres[k] = {rho * std::cos(a), 0.8f * std::sin(0.11f * static_cast<float>(k)), rho * std::sin(a),
                    0.35f + 0.25f * std::sin(1.7f * static_cast<float>(k))};
    }
  };

  // ---- the G-buffer: colour, depth, and viscd's id attachment ----
  auto ids = viscd::make_gl_id_texture(kWidth, kHeight);
  if (!ids) {
    std::fprintf(stderr, "%s\n", ids.error().c_str());
    return 1;
  }
  GLuint colour = 0, depth = 0, fbo = 0, ssbo = 0, vao = 0;
  glCreateTextures(GL_TEXTURE_2D, 1, &colour);
  glTextureStorage2D(colour, 1, GL_RGBA8, kWidth, kHeight);
  glCreateRenderbuffers(1, &depth);
  glNamedRenderbufferStorage(depth, GL_DEPTH_COMPONENT32F, kWidth, kHeight);
  glCreateFramebuffers(1, &fbo);
  glNamedFramebufferTexture(fbo, GL_COLOR_ATTACHMENT0, colour, 0);
  glNamedFramebufferTexture(fbo, GL_COLOR_ATTACHMENT1, ids.value(), 0);
  glNamedFramebufferRenderbuffer(fbo, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, depth);
  const GLenum draw_buffers[] = {GL_COLOR_ATTACHMENT0, GL_COLOR_ATTACHMENT1};
  glNamedFramebufferDrawBuffers(fbo, 2, draw_buffers);
  glCreateBuffers(1, &ssbo);
  glNamedBufferData(ssbo, sizeof(viscd::Sphere) * kObjects, nullptr, GL_DYNAMIC_DRAW);
  glCreateVertexArrays(1, &vao);
  const GLuint program = glCreateProgram();
  const GLuint vs = compile(GL_VERTEX_SHADER, "", viscd::kGlIdVertexGlsl, kVertex);
  const GLuint fs = compile(GL_FRAGMENT_SHADER, "#define VISCD_ID_LOCATION 1\n", viscd::kGlIdFragmentGlsl, kFragment);
  glAttachShader(program, vs);
  glAttachShader(program, fs);
  glLinkProgram(program);
  GLint linked = 0;
  glGetProgramiv(program, GL_LINK_STATUS, &linked);
  if (!linked) {
    std::fprintf(stderr, "the G-buffer program does not link\n");
    return 1;
  }

  // ---- viscd in the same context ----
  viscd::Config config;
  config.lambda = 20;            // cull objects covering fewer than 20 screen pixels
  config.contact_events = true;  // FrameResult::began / ended
  viscd::GlOptions options;
  options.use_current_context = true;  // read the engine's id texture
  auto made = viscd::make_gl_detector(config, options);
  if (!made) {
    std::fprintf(stderr, "%s\n", made.error().c_str());
    return 1;
  }
  viscd::Detector& detector = *made.value();
  viscd::FrameResult frame;  // reused: no allocation per frame once warmed up
  std::vector<std::uint32_t> readback(static_cast<std::size_t>(kWidth) * kHeight);
  std::vector<viscd::RayHit> hits;

  for (int tick = 0; tick <= 60; ++tick) {
    place(0.05f * static_cast<float>(tick));
    viscd::Camera camera;
    camera.eye[0] = 0, camera.eye[1] = 30, camera.eye[2] = 75;
    camera.target[0] = 0, camera.target[1] = 0, camera.target[2] = 20;
    camera.width = kWidth, camera.height = kHeight;
    camera.far_plane = 400;

    // The engine's G-buffer pass.
    std::array<float, 3> right{}, up{};
    const Mat4 vp = view_proj(camera, right, up);
    glNamedBufferSubData(ssbo, 0, sizeof(viscd::Sphere) * kObjects, spheres.data());
    const GLuint zero[4] = {0, 0, 0, 0};
    const float black[4] = {0, 0, 0, 1}, far_depth = 1.0f;
    glClearNamedFramebufferfv(fbo, GL_COLOR, 0, black);
    glClearNamedFramebufferuiv(fbo, GL_COLOR, 1, zero);  // viscd's ids: 0 = background
    glClearNamedFramebufferfv(fbo, GL_DEPTH, 0, &far_depth);
    glBindFramebuffer(GL_FRAMEBUFFER, fbo);
    glViewport(0, 0, kWidth, kHeight);
    glEnable(GL_DEPTH_TEST);
    glUseProgram(program);
    glProgramUniformMatrix4fv(program, glGetUniformLocation(program, "u_view_proj"), 1, GL_FALSE, vp.data());
    glProgramUniform3fv(program, glGetUniformLocation(program, "u_right"), 1, right.data());
    glProgramUniform3fv(program, glGetUniformLocation(program, "u_up"), 1, up.data());
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, ssbo);
    glBindVertexArray(vao);
    glDrawArraysInstanced(GL_TRIANGLE_STRIP, 0, 4, kObjects);  // instance k = object k
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
    glMemoryBarrier(GL_ALL_BARRIER_BITS);

    // viscd: counts the engine's map, culls, finds the pairs the filters allow.
    viscd::FrameInput input;
    input.spheres = spheres;
    input.camera = &camera;  // the map is the screen: counts are screen pixels
    input.filters = filters;
    input.gl_id_texture = ids.value();
    input.id_map_width = kWidth;
    input.id_map_height = kHeight;
    if (viscd::Status s = detector.detect(input, frame); !s) {
      std::fprintf(stderr, "collision detection failed: %s\n", s.error().c_str());
      return 1;
    }
    for (const viscd::Pair& p : frame.began) (void)p;  // start a contact sound, spawn sparks ...
    for (const viscd::Pair& p : frame.ended) (void)p;  // ... and stop them

    // What does the player aim at? Here, along the line to object 1000 (queries see the last
    // frame's active objects: the first hit may be another one in front, or none if culled).
    viscd::Ray aim;
    const float target[3] = {spheres[1000].x, spheres[1000].y, spheres[1000].z};
    for (int a = 0; a < 3; ++a) aim.origin[a] = camera.eye[a], aim.dir[a] = target[a] - camera.eye[a];
    viscd::RayHit hit;
    const bool aimed = detector.ray_cast(aim, hit);
    detector.ray_cast_all(aim, hits);

    if (tick % 20 == 0) {
      // The engine's own check: viscd's pixel counts are a histogram of the id texture.
      glGetTextureImage(ids.value(), 0, GL_RED_INTEGER, GL_UNSIGNED_INT,
                        static_cast<GLsizei>(readback.size() * sizeof(std::uint32_t)), readback.data());
      std::vector<std::uint32_t> histogram(kObjects + 1, 0);
      for (std::uint32_t id : readback) ++histogram[id];
      for (int k = 0; k < kObjects; ++k)
        if (frame.pixels[k] != static_cast<float>(histogram[k + 1])) {
          std::fprintf(stderr, "object %d: viscd counted %g pixels, the map holds %u\n", k, frame.pixels[k],
                       histogram[k + 1]);
          return 1;
        }
      for (const viscd::Pair& p : frame.pairs)
        if (!viscd::pair_passes_filter(filters[p.i], filters[p.j])) {
          std::fprintf(stderr, "pair (%u, %u) passed its filters\n", p.i, p.j);
          return 1;
        }
      std::printf(
          "tick %3d: %u of %u objects visible enough, %llu pairs (%zu began, %zu ended), aim: %s%u at t = %.2f "
          "(%zu hits)\n",
          tick, frame.stats.active, frame.stats.objects, static_cast<unsigned long long>(frame.stats.pairs),
          frame.began.size(), frame.ended.size(), aimed ? "object " : "nothing ", aimed ? hit.index : 0,
          aimed ? hit.t : 0.0f, hits.size());
    }
  }
  made.value().reset();  // destroyed while the engine's context is current
  GLuint textures[2] = {colour, ids.value()};
  glDeleteTextures(2, textures);
  eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
  eglDestroyContext(display, context);
  return 0;
}
