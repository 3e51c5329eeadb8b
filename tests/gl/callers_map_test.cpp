// The caller's visibility map on the gl backend: as an R32UI texture of the detector's context
// (FrameInput::gl_id_texture) or of the caller's own context (GlOptions::use_current_context),
// counted exactly as a histogram of the map written in the test, culled and paired as the
// reference backend does from the same map given as an array; and the errors.
#include <epoxy/egl.h>

#include <thread>

#include "cpu/brute_force.hpp"
#include "gl_test_util.hpp"
#include "test_util.hpp"

namespace viscd::test {
namespace {

// A map of w x h ids over n objects: horizontal bands of sizes that differ per object, some
// background, deterministic.
std::vector<std::uint32_t> banded_map(int w, int h, std::uint32_t n) {
  std::vector<std::uint32_t> ids(static_cast<std::size_t>(w) * static_cast<std::size_t>(h), 0);
  std::mt19937 rng(7);
  for (std::size_t k = 0; k < ids.size(); ++k) {
    const auto r = static_cast<std::uint32_t>(rng() % (n + n / 3 + 1));
    ids[k] = r <= n ? r : 0;  // 0: background
  }
  return ids;
}

// A texture of the current context holding `ids` (rows in memory order).
GLuint make_id_texture(const std::vector<std::uint32_t>& ids, int w, int h, GLenum format = GL_R32UI) {
  GLuint t = 0;
  glCreateTextures(GL_TEXTURE_2D, 1, &t);
  glTextureStorage2D(t, 1, format, w, h);
  if (format == GL_R32UI) {
    glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
    glTextureSubImage2D(t, 0, 0, 0, w, h, GL_RED_INTEGER, GL_UNSIGNED_INT, ids.data());
  }
  return t;
}

FrameInput texture_input(std::span<const Sphere> s, const Camera* cam, GLuint tex, int w, int h) {
  FrameInput in = test::id_map_input(s, cam, {}, w, h);
  in.gl_id_texture = tex;
  return in;
}

// Frames from the texture and from the same map as an array (reference backend) agree: pixels,
// states, pairs, m.
void expect_same_as_reference(test::GlUnderTest& gl, GLuint tex, const std::vector<std::uint32_t>& ids, int w, int h,
                              const std::vector<Sphere>& spheres, const Camera* cam, const Config& cfg) {
  const FrameInput in = texture_input(spheres, cam, tex, w, h);
  FrameResult a;
  const Status s = gl.detect(in, a);
  ASSERT_TRUE(s.ok()) << s.error();
  const FrameInput ref_in = id_map_input(spheres, cam, ids, w, h);
  auto ref = make_reference_detector(cfg);
  FrameResult b;
  ASSERT_TRUE(ref->detect(ref_in, b).ok());
  // The counts themselves: a histogram written here.
  std::vector<std::uint32_t> hist(spheres.size() + 1, 0);
  for (std::uint32_t id : ids) ++hist[id];
  const double scale =
      cam ? static_cast<double>(cam->width) * cam->height / (static_cast<double>(w) * static_cast<double>(h)) : 1.0;
  ASSERT_EQ(a.pixels.size(), spheres.size());
  for (std::size_t k = 0; k < spheres.size(); ++k)
    ASSERT_EQ(a.pixels[k], static_cast<float>(hist[k + 1] * scale)) << "object " << k;
  EXPECT_TRUE(a.pixels == b.pixels);
  EXPECT_TRUE(a.state == b.state);
  EXPECT_TRUE(a.pairs == b.pairs);
  EXPECT_EQ(a.stats.active, b.stats.active);
  EXPECT_EQ(a.stats.bits, b.stats.bits);
  EXPECT_TRUE(a.stats.has_pixels);
}

TEST(GlCallersMap, TextureOfTheDetectorsContext) {
  Config cfg;
  cfg.lambda = 40;
  GlOptions sync;
  sync.sync_layout = true;  // m from this frame's mu, as the reference (the default mode takes the previous frame's)
  VISCD_GL_OR_SKIP(gl, cfg, sync);
  const std::vector<Sphere> s = random_spheres_by_edge(300, 12.0f, 0.2f, 1.0f, 5);
  FrameResult warm;
  ASSERT_TRUE(gl->detect(s, nullptr, warm).ok());  // the detector's context is current now
  for (const auto& [w, h] : std::vector<std::pair<int, int>>{{160, 90}, {333, 177}, {1, 1}}) {
    SCOPED_TRACE(std::to_string(w) + "x" + std::to_string(h));
    const std::vector<std::uint32_t> ids = banded_map(w, h, 300);
    const GLuint tex = make_id_texture(ids, w, h);
    Camera cam;
    cam.width = 640;
    cam.height = 360;
    expect_same_as_reference(*gl, tex, ids, w, h, s, nullptr, cfg);  // counts in map pixels
    expect_same_as_reference(*gl, tex, ids, w, h, s, &cam, cfg);     // scaled to the screen
    glDeleteTextures(1, &tex);
  }
}

// lambda applies to the count as reported (a float): on a 39 x 51 map of a 1 x 1 screen an object
// covering the whole map has 1989 x (1 / 1989) screen pixels, a double just below 1 that rounds to
// the float 1, so with lambda = 1 it is active; one map pixel fewer culls it. As a texture and as
// an array.
TEST(GlCallersMap, LambdaReadsTheReportedCount) {
  Config cfg;
  cfg.lambda = 1;
  VISCD_GL_OR_SKIP(gl, cfg);
  const std::vector<Sphere> s = {{0, 0, 0, 1}, {0.5f, 0, 0, 1}, {5, 0, 0, 1}};
  Camera cam;
  cam.width = 1, cam.height = 1;
  FrameResult warm;
  ASSERT_TRUE(gl->detect(s, nullptr, warm).ok());  // the detector's context is current now
  for (const bool whole : {true, false}) {
    std::vector<std::uint32_t> ids(39 * 51, 1);
    if (!whole) ids[0] = 3;
    const GLuint tex = make_id_texture(ids, 39, 51);
    for (const bool texture : {true, false}) {
      SCOPED_TRACE(std::string(whole ? "the whole map" : "all but one pixel") + (texture ? ", texture" : ", array"));
      FrameResult r;
      const Status st =
          gl->detect(texture ? texture_input(s, &cam, tex, 39, 51) : id_map_input(s, &cam, ids, 39, 51), r);
      ASSERT_TRUE(st.ok()) << st.error();
      ASSERT_EQ(r.pixels.size(), 3u);
      if (whole) {
        EXPECT_EQ(r.pixels[0], 1.0f);
        EXPECT_EQ(r.stats.active, 1u);
        EXPECT_EQ(r.state[0], ObjectState::free);
      } else {
        EXPECT_LT(r.pixels[0], 1.0f);
        EXPECT_EQ(r.stats.active, 0u);
        EXPECT_EQ(r.state[0], ObjectState::culled);
      }
      EXPECT_EQ(r.state[1], ObjectState::culled);
      EXPECT_TRUE(r.pairs.empty());
    }
    glDeleteTextures(1, &tex);
  }
}

TEST(GlCallersMap, TextureErrors) {
  VISCD_GL_OR_SKIP(gl);
  const std::vector<Sphere> s = random_spheres_by_edge(50, 5.0f, 0.2f, 0.5f, 6);
  FrameResult out;
  ASSERT_TRUE(gl->detect(s, nullptr, out).ok());
  const auto run = [&](GLuint tex, int w, int h) { return gl->detect(texture_input(s, nullptr, tex, w, h), out); };
  std::vector<std::uint32_t> ids = banded_map(40, 30, 50);
  // Not a texture.
  Status st = run(987654u, 40, 30);
  ASSERT_FALSE(st.ok());
  EXPECT_NE(st.error().find("is not a texture"), std::string::npos) << st.error();
  // Another size than the one given.
  const GLuint tex = make_id_texture(ids, 40, 30);
  st = run(tex, 30, 40);
  ASSERT_FALSE(st.ok());
  EXPECT_NE(st.error().find("is 40x30 texels, but id_map_width x id_map_height is 30x40"), std::string::npos)
      << st.error();
  // Another format.
  const GLuint wrong = make_id_texture(ids, 40, 30, GL_R32F);
  st = run(wrong, 40, 30);
  ASSERT_FALSE(st.ok());
  EXPECT_NE(st.error().find("expected an R32UI texture"), std::string::npos) << st.error();
  // Ids above N: texel (7, 2) first, and two more.
  ids[2 * 40 + 7] = 51;
  ids[2 * 40 + 9] = 1000;
  ids[29 * 40 + 0] = 52;
  const GLuint bad = make_id_texture(ids, 40, 30);
  st = run(bad, 40, 30);
  ASSERT_FALSE(st.ok());
  EXPECT_NE(st.error().find("texel (7, 2) and 2 more hold ids above the frame's 50 objects"), std::string::npos)
      << st.error();
  // The same map as an array names the first bad pixel too.
  st = gl->detect(id_map_input(s, nullptr, ids, 40, 30), out);
  ASSERT_FALSE(st.ok());
  EXPECT_NE(st.error().find("pixel (7, 2) holds id 51"), std::string::npos) << st.error();
  // And the detector goes on: a good frame after the errors.
  ids[2 * 40 + 7] = ids[2 * 40 + 9] = ids[29 * 40 + 0] = 1;
  expect_same_as_reference(*gl, tex, banded_map(40, 30, 50), 40, 30, s, nullptr, Config{});
  GLuint names[3] = {tex, wrong, bad};
  glDeleteTextures(3, names);
}

// An EGL surfaceless context of the test's own: the engine's, as far as the detector knows.
struct CallersContext {
  EGLDisplay display = EGL_NO_DISPLAY;
  EGLContext context = EGL_NO_CONTEXT;
  CallersContext() {
    display = eglGetPlatformDisplayEXT(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr);
    if (display == EGL_NO_DISPLAY || !eglInitialize(display, nullptr, nullptr) || !eglBindAPI(EGL_OPENGL_API)) return;
    const EGLint attribs[] = {
        EGL_CONTEXT_MAJOR_VERSION,           4,       EGL_CONTEXT_MINOR_VERSION, 5, EGL_CONTEXT_OPENGL_PROFILE_MASK,
        EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT, EGL_NONE};
    context = eglCreateContext(display, EGL_NO_CONFIG_KHR, EGL_NO_CONTEXT, attribs);
  }
  ~CallersContext() {
    if (context != EGL_NO_CONTEXT) {
      eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
      eglDestroyContext(display, context);
    }
  }
  bool make_current() const { return eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, context) == EGL_TRUE; }
};

TEST(GlCallersMap, TheCallersOwnContext) {
  VISCD_GL_OR_SKIP(shared);  // skips when there is no OpenGL 4.5 at all
  (void)shared;
  CallersContext engine;
  ASSERT_NE(engine.context, EGL_NO_CONTEXT);
  ASSERT_TRUE(engine.make_current());
  GlOptions o;
  o.use_current_context = true;
  Config cfg;
  cfg.lambda = 30;
  auto made = test::GlUnderTest::create(cfg, o);
  ASSERT_TRUE(made.ok()) << made.error();
  test::GlUnderTest& gl = *made.value();
  // The engine's texture, in the engine's context, read by the detector directly.
  const std::vector<Sphere> s = random_spheres_by_edge(500, 10.0f, 0.2f, 0.8f, 9);
  const std::vector<std::uint32_t> ids = banded_map(200, 120, 500);
  const GLuint tex = make_id_texture(ids, 200, 120);
  expect_same_as_reference(gl, tex, ids, 200, 120, s, nullptr, cfg);
  EXPECT_EQ(eglGetCurrentContext(), engine.context) << "the detector switched contexts";
  // Its own frames (no caller's map) work in the engine's context too.
  FrameResult a, b;
  ASSERT_TRUE(gl.detect(s, nullptr, a).ok());
  ASSERT_TRUE(make_reference_detector(cfg)->detect(s, nullptr, b).ok());
  EXPECT_TRUE(a.pairs == b.pairs);
  glDeleteTextures(1, &tex);
  made.value().reset();  // destroyed while the engine's context is current, as documented
  // Without a current context there is nothing to adopt.
  std::string error;
  std::thread([&] {
    auto none = test::GlUnderTest::create(cfg, o);
    error = none.ok() ? "" : none.error();
  }).join();
  EXPECT_NE(error.find("no OpenGL context is current"), std::string::npos) << error;
}

}  // namespace
}  // namespace viscd::test
