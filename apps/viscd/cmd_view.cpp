// `viscd view`: the demo in a window. GLFW opens an OpenGL 3.3 core window, Dear ImGui draws the
// panel, and each frame the chosen detector (cpu, or gl through its own EGL context) steps the
// scene, finds the pairs and shades the image that fills the window.
//
// Contexts: the window's context is GLX (GLFW's default on X11, and what Dear ImGui's OpenGL3
// loader resolves through); the gl backend owns a surfaceless EGL context. libglvnd refuses to
// make one API's context current while the other's is, so every call into the gl detector is
// bracketed by releasing the window's context before and the detector's after (DetectorGuard).
#include <epoxy/egl.h>
#include <epoxy/gl.h>
#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>
#include <backends/imgui_impl_glfw.h>
#include <backends/imgui_impl_opengl3.h>
#include <imgui.h>

#include <algorithm>
#include <array>
#include <cfloat>
#include <chrono>
#include <cinttypes>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include "commands.hpp"
#include "exit_codes.hpp"
#include "options.hpp"
#include "view_orbit.hpp"
#include "viscd/gl.hpp"
#include "viscd/io.hpp"

namespace viscd::app {
namespace {

using Clock = std::chrono::steady_clock;

struct ViewArgs {
  PipelineOptions pipeline;
  SceneOptions world;
  std::string camera = "zoom-out";
  std::string size = "1280x720";
  int frames = 0;
  std::string screenshot;
  std::string window_screenshot;
};

// Shading colours of stage 9 (viscd::state_colour), for the legend.
ImVec4 rgb(viscd::Rgb8 c) {
  return ImVec4(static_cast<float>(c.r) / 255.0f, static_cast<float>(c.g) / 255.0f, static_cast<float>(c.b) / 255.0f,
                1.0f);
}
const ImVec4 kColliding = rgb(viscd::state_colour(viscd::ObjectState::colliding));
const ImVec4 kFree = rgb(viscd::state_colour(viscd::ObjectState::free));
const ImVec4 kCulled = rgb(viscd::state_colour(viscd::ObjectState::culled));

// Timing series: simulate (stage 0, timed here) followed by the detector's stages 1-9.
constexpr std::size_t kSeries = kStageCount + 1;
constexpr int kHistory = 120;
const std::array<ImU32, kSeries> kSeriesColour = {
    IM_COL32(160, 160, 160, 255), IM_COL32(31, 119, 180, 255),  IM_COL32(255, 127, 14, 255),
    IM_COL32(44, 160, 44, 255),   IM_COL32(214, 39, 40, 255),   IM_COL32(148, 103, 189, 255),
    IM_COL32(140, 86, 75, 255),   IM_COL32(227, 119, 194, 255), IM_COL32(188, 189, 34, 255),
    IM_COL32(23, 190, 207, 255),  IM_COL32(255, 255, 255, 255)};
static_assert(kSeries == 11, "one colour per timing series");

std::string series_name(std::size_t s) {
  return s == 0 ? "simulate" : std::string(stage_name(static_cast<Stage>(s - 1)));
}

// Layouts are printed with arrows (x(7)→z(6)→y(3)); ImGui's built-in font is ASCII only.
std::string glfw_error_text;
void on_glfw_error(int code, const char* message) {
  glfw_error_text = message ? message : ("GLFW error " + std::to_string(code));
}

int no_window(const std::string& what) {
  const char* display = std::getenv("DISPLAY");
  std::string msg = what;
  if (!glfw_error_text.empty()) msg += " (" + glfw_error_text + ")";
  msg += display && *display ? std::string(". DISPLAY is '") + display + "'" : std::string(". DISPLAY is not set");
  msg +=
      ": run on a desktop session, or headless under a virtual X server with OpenGL 3.3, e.g.\n"
      "  xvfb-run -a -s \"-screen 0 1280x800x24\" viscd view ...\n"
      "(`viscd run` needs no display)";
  return fail(msg);
}

// Releases whatever context the gl detector left current (EGL), then makes the window's current.
void restore_window_context(GLFWwindow* window) {
  if (eglGetCurrentContext() != EGL_NO_CONTEXT)
    eglMakeCurrent(eglGetCurrentDisplay(), EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
  glfwMakeContextCurrent(window);
}

// Brackets a call into a gl detector (create, detect, destroy): window context off before,
// detector context off and window context back after. A no-op for the cpu backend.
class DetectorGuard {
 public:
  DetectorGuard(GLFWwindow* window, bool gl) : window_(window), gl_(gl) {
    if (gl_) glfwMakeContextCurrent(nullptr);
  }
  ~DetectorGuard() {
    if (gl_) restore_window_context(window_);
  }
  DetectorGuard(const DetectorGuard&) = delete;
  DetectorGuard& operator=(const DetectorGuard&) = delete;

 private:
  GLFWwindow* window_;
  bool gl_;
};

class Viewer {
 public:
  explicit Viewer(ViewArgs args) : args_(std::move(args)) {}
  int run();

 private:
  enum class Backend { cpu, gl };

  Status setup();
  Config current_config() const;
  void rebuild_scene();
  void reset_camera();
  Result<std::unique_ptr<Detector>> create_detector(Backend b, bool mesh);
  void destroy_detector();
  void switch_backend(Backend b, bool mesh);
  void handle_input();
  void panel();
  void timings_chart();
  Status frame();
  void upload_image();
  std::string save_screenshot(const std::filesystem::path& path);
  std::string save_window(const std::filesystem::path& path);
  std::filesystem::path next_screenshot_path() const;

  ViewArgs args_;
  GLFWwindow* window_ = nullptr;
  int fb_w_ = 1, fb_h_ = 1;

  // Scene and camera.
  SceneKind kind_ = SceneKind::ring;
  Scene scene_;
  OrbitCamera orbit_;
  Camera file_camera_;
  bool have_file_camera_ = false;
  bool paused_ = false;

  // Pipeline settings (the panel edits these).
  Config base_;  // bits/layout/threads from the options
  int objects_ = 10000;
  float lambda_ = 200, a_ = 100, b_ = 400;
  bool culling_ = true, adaptive_ = true;
  int fixed_bits_index_ = 1;  // 16 / 32 / 64
  int map_width_ = 0;         // 0: the window's framebuffer size
  int map_height_ = 0;        // from --map-size until the slider moves; else by the window's aspect

  // Detector.
  Backend backend_ = Backend::cpu;
  bool mesh_ = false;
  std::unique_ptr<Detector> detector_;
  std::string backend_message_;

  // Frame output.
  FrameResult result_;
  bool have_result_ = false;
  GLuint texture_ = 0;
  int tex_w_ = 0, tex_h_ = 0;
  std::array<std::array<float, kSeries>, kHistory> history_{};
  int history_next_ = 0, history_count_ = 0;
  double frame_ms_smooth_ = 0;
  Clock::time_point last_frame_ = Clock::now();
  bool screenshot_requested_ = false;
  std::string status_line_;
};

Config Viewer::current_config() const {
  Config c = base_;
  c.lambda = lambda_;
  c.pixels_for_32_bits = a_;
  c.pixels_for_64_bits = b_;
  c.culling = culling_;
  c.bits = adaptive_ ? Bits::adaptive
                     : (fixed_bits_index_ == 0   ? Bits::b16
                        : fixed_bits_index_ == 1 ? Bits::b32
                                                 : Bits::b64);
  c.shade = true;
  if (map_width_ > 0) {
    c.map_width = map_width_;
    c.map_height = map_height_ > 0
                       ? map_height_
                       : std::max(1, static_cast<int>(std::lround(static_cast<double>(map_width_) * fb_h_ / fb_w_)));
  } else {
    c.map_width = c.map_height = 0;
  }
  return c;
}

void Viewer::rebuild_scene() {
  scene_ = Scene::make({.kind = kind_, .objects = static_cast<std::uint32_t>(objects_), .seed = args_.world.seed});
  reset_camera();
}

void Viewer::reset_camera() {
  Camera c = file_camera_;
  if (!have_file_camera_) {
    auto preset = camera_preset(args_.camera, scene_, fb_w_, fb_h_);
    c = preset ? preset.value() : camera_preset("zoom-out", scene_, fb_w_, fb_h_).value();
  }
  orbit_.reset(c, scene_.world_radius() + scene_.world_half_height());
}

Result<std::unique_ptr<Detector>> Viewer::create_detector(Backend b, bool mesh) {
  using R = Result<std::unique_ptr<Detector>>;
  if (b == Backend::cpu) return R(make_cpu_detector(current_config()));
  DetectorGuard guard(window_, true);
  GlOptions o = make_gl_options(args_.pipeline).value();        // checked in setup()
  o.geometry = mesh ? GlGeometry::mesh : GlGeometry::impostor;  // the panel's live toggle
  return make_gl_detector(current_config(), o);
}

void Viewer::destroy_detector() {
  DetectorGuard guard(window_, backend_ == Backend::gl && detector_ != nullptr);
  detector_.reset();
}

void Viewer::switch_backend(Backend b, bool mesh) {
  auto d = create_detector(b, mesh);
  if (!d) {
    backend_message_ = "gl backend unavailable: " + d.error();
    std::fprintf(stderr, "viscd view: %s; staying on %s\n", backend_message_.c_str(),
                 backend_ == Backend::gl ? "gl" : "cpu");
    if (!detector_) {  // nothing to stay on: fall back to cpu
      backend_ = Backend::cpu;
      detector_ = make_cpu_detector(current_config());
    }
    return;
  }
  destroy_detector();
  detector_ = std::move(d.value());
  backend_ = b;
  mesh_ = mesh;
  backend_message_.clear();
}

Status Viewer::setup() {
  auto config = make_config(args_.pipeline);
  if (!config) return config.status();
  base_ = config.value();
  lambda_ = base_.lambda, a_ = base_.pixels_for_32_bits, b_ = base_.pixels_for_64_bits;
  culling_ = base_.culling;
  adaptive_ = base_.bits == Bits::adaptive;
  fixed_bits_index_ = base_.bits == Bits::b16 ? 0 : base_.bits == Bits::b64 ? 2 : 1;
  map_width_ = base_.map_width;
  map_height_ = base_.map_height;
  if (args_.world.objects < 1 || args_.world.objects > (1u << 29))
    return Status::failure(ErrorKind::invalid_input, "--objects: expected 1 to 536870912");
  objects_ = static_cast<int>(args_.world.objects);
  auto params = make_scene_params(args_.world);
  if (!params) return params.status();
  kind_ = params.value().kind;
  if (args_.frames < 0)
    return Status::failure(ErrorKind::invalid_input, "--frames: expected 0 (until the window closes) or more");
  if (auto g = make_gl_options(args_.pipeline); !g) return g.status();
  const std::string& be = args_.pipeline.backend;
  if (be != "cpu" && be != "gl")
    return Status::failure(ErrorKind::invalid_input,
                           "--backend: viscd view runs cpu or gl, got '" + be +
                               "' (the reference backend ray-casts every pixel against every object: use viscd pairs)");
  if (args_.camera.size() > 5 && args_.camera.ends_with(".json")) {
    auto c = read_camera(args_.camera);
    if (!c) return c.status();
    file_camera_ = c.value();
    have_file_camera_ = true;
  } else if (args_.camera != "zoom-out" && args_.camera != "zoom-in") {
    return Status::failure(ErrorKind::invalid_input,
                           "--camera: expected zoom-out, zoom-in or a .json file, got '" + args_.camera + "'");
  }
  return {};
}

std::filesystem::path Viewer::next_screenshot_path() const {
  for (int k = 1;; ++k) {
    char name[32];
    std::snprintf(name, sizeof name, "viscd-view-%03d.png", k);
    std::error_code ec;
    if (!std::filesystem::exists(name, ec)) return name;
  }
}

std::string Viewer::save_window(const std::filesystem::path& path) {
  // The back buffer, panel included, read before the swap; GL rows run bottom to top.
  std::vector<std::uint8_t> rgba(4 * static_cast<std::size_t>(fb_w_) * static_cast<std::size_t>(fb_h_));
  glPixelStorei(GL_PACK_ALIGNMENT, 1);
  glReadBuffer(GL_BACK);
  glReadPixels(0, 0, fb_w_, fb_h_, GL_RGBA, GL_UNSIGNED_BYTE, rgba.data());
  const std::size_t row = 4 * static_cast<std::size_t>(fb_w_);
  for (int y = 0; y < fb_h_ / 2; ++y)
    std::swap_ranges(rgba.begin() + static_cast<std::ptrdiff_t>(row * y),
                     rgba.begin() + static_cast<std::ptrdiff_t>(row * (y + 1)),
                     rgba.begin() + static_cast<std::ptrdiff_t>(row * (fb_h_ - 1 - y)));
  for (std::size_t k = 3; k < rgba.size(); k += 4) rgba[k] = 255;
  if (Status s = write_png(path, rgba, fb_w_, fb_h_); !s) return s.error();
  std::printf("viscd view: wrote %s (window, %dx%d)\n", path.c_str(), fb_w_, fb_h_);
  std::fflush(stdout);
  return {};
}

std::string Viewer::save_screenshot(const std::filesystem::path& path) {
  if (!have_result_ || result_.image.empty()) return "no image yet";
  if (Status s = write_png(path, result_.image, result_.image_width, result_.image_height); !s) return s.error();
  std::printf("viscd view: wrote %s (%dx%d)\n", path.c_str(), result_.image_width, result_.image_height);
  std::fflush(stdout);
  return {};
}

void Viewer::handle_input() {
  const ImGuiIO& io = ImGui::GetIO();
  if (!io.WantCaptureMouse) {
    int win_w = 1, win_h = 1;
    glfwGetWindowSize(window_, &win_w, &win_h);
    if (io.MouseDown[0])
      orbit_.orbit(io.MouseDelta.x, io.MouseDelta.y);
    else if (io.MouseDown[1] || io.MouseDown[2])
      orbit_.pan(io.MouseDelta.x, io.MouseDelta.y, win_h);
    if (io.MouseWheel != 0) orbit_.zoom(io.MouseWheel);
  }
  if (!io.WantCaptureKeyboard) {
    if (ImGui::IsKeyPressed(GLFW_KEY_S, false)) screenshot_requested_ = true;
    if (ImGui::IsKeyPressed(GLFW_KEY_SPACE, false)) paused_ = !paused_;
    if (ImGui::IsKeyPressed(GLFW_KEY_R, false)) reset_camera();
    if (ImGui::IsKeyPressed(GLFW_KEY_ESCAPE, false) || ImGui::IsKeyPressed(GLFW_KEY_Q, false))
      glfwSetWindowShouldClose(window_, GLFW_TRUE);
  }
}

void Viewer::timings_chart() {
  ImDrawList* dl = ImGui::GetWindowDrawList();
  const ImVec2 p0 = ImGui::GetCursorScreenPos();
  const ImVec2 size(std::max(ImGui::GetContentRegionAvail().x, 120.0f), 90.0f);
  ImGui::InvisibleButton("##timings", size);
  dl->AddRectFilled(p0, ImVec2(p0.x + size.x, p0.y + size.y), IM_COL32(25, 25, 32, 255));
  float peak = 0.1f;
  for (int k = 0; k < history_count_; ++k) {
    float t = 0;
    for (float v : history_[static_cast<std::size_t>(k)]) t += v;
    peak = std::max(peak, t);
  }
  // Round the scale up to 1, 2 or 5 x 10^k ms so that it does not jitter every frame.
  const float decade = std::pow(10.0f, std::floor(std::log10(peak)));
  const float scale = peak <= decade       ? decade
                      : peak <= 2 * decade ? 2 * decade
                      : peak <= 5 * decade ? 5 * decade
                                           : 10 * decade;
  const float bar = size.x / static_cast<float>(kHistory);
  int hovered = -1;
  for (int k = 0; k < history_count_; ++k) {
    // Oldest on the left, newest at the right edge.
    const int slot = (history_next_ - history_count_ + k + kHistory) % kHistory;
    const float x = p0.x + static_cast<float>(kHistory - history_count_ + k) * bar;
    float y = p0.y + size.y;
    for (std::size_t s = 0; s < kSeries; ++s) {
      const float h = history_[static_cast<std::size_t>(slot)][s] / scale * size.y;
      if (h <= 0) continue;
      dl->AddRectFilled(ImVec2(x, y - h), ImVec2(x + std::max(bar - 1.0f, 1.0f), y), kSeriesColour[s]);
      y -= h;
    }
    if (ImGui::IsItemHovered() && ImGui::GetIO().MousePos.x >= x && ImGui::GetIO().MousePos.x < x + bar) hovered = slot;
  }
  char label[48];
  std::snprintf(label, sizeof label, "%g ms", static_cast<double>(scale));
  dl->AddText(ImVec2(p0.x + 4, p0.y + 2), IM_COL32(220, 220, 220, 255), label);
  if (hovered >= 0) {
    ImGui::BeginTooltip();
    float total = 0;
    for (std::size_t s = 0; s < kSeries; ++s) {
      const float v = history_[static_cast<std::size_t>(hovered)][s];
      total += v;
      ImGui::Text("%-10s %8.3f ms", series_name(s).c_str(), static_cast<double>(v));
    }
    ImGui::Text("%-10s %8.3f ms", "total", static_cast<double>(total));
    ImGui::EndTooltip();
  }

  // Legend with each series' mean over the last 30 frames.
  const int recent = std::min(history_count_, 30);
  if (ImGui::BeginTable("##legend", 2)) {
    for (std::size_t s = 0; s < kSeries; ++s) {
      double sum = 0;
      for (int k = 0; k < recent; ++k)
        sum += history_[static_cast<std::size_t>((history_next_ - 1 - k + 2 * kHistory) % kHistory)][s];
      ImGui::TableNextColumn();
      ImGui::ColorButton(("##c" + std::to_string(s)).c_str(), ImGui::ColorConvertU32ToFloat4(kSeriesColour[s]),
                         ImGuiColorEditFlags_NoTooltip | ImGuiColorEditFlags_NoPicker, ImVec2(10, 10));
      ImGui::SameLine();
      ImGui::Text("%-10s %7.2f", series_name(s).c_str(), recent ? sum / recent : 0.0);
    }
    ImGui::EndTable();
  }
}

void Viewer::panel() {
  ImGui::SetNextWindowPos(ImVec2(10, 10), ImGuiCond_FirstUseEver);
  ImGui::SetNextWindowBgAlpha(0.85f);
  // Auto-sized to its content, but never taller than the window: it scrolls instead.
  ImGui::SetNextWindowSizeConstraints(ImVec2(0, 0),
                                      ImVec2(FLT_MAX, std::max(ImGui::GetIO().DisplaySize.y - 20.0f, 100.0f)));
  ImGui::Begin("viscd", nullptr, ImGuiWindowFlags_AlwaysAutoResize);
  ImGui::PushItemWidth(170);

  if (ImGui::CollapsingHeader("Scene and pipeline", ImGuiTreeNodeFlags_DefaultOpen)) {
    int n = objects_;
    ImGui::SliderInt("objects N", &n, 100, 1000000, "%d", ImGuiSliderFlags_Logarithmic);
    if (n != objects_ && n >= 1) objects_ = n;
    if (ImGui::IsItemDeactivatedAfterEdit()) rebuild_scene();  // rebuild once, on release
    ImGui::SliderFloat("lambda (px)", &lambda_, 0, 5000, "%.0f", ImGuiSliderFlags_Logarithmic);
    if (ImGui::SliderFloat("a (16 below)", &a_, 0, 5000, "%.0f", ImGuiSliderFlags_Logarithmic)) b_ = std::max(a_, b_);
    if (ImGui::SliderFloat("b (64 from)", &b_, 0, 5000, "%.0f", ImGuiSliderFlags_Logarithmic)) a_ = std::min(a_, b_);
    lambda_ = std::max(lambda_, 0.0f);
    if (ImGui::SliderInt("map width", &map_width_, 0, 3840, map_width_ == 0 ? "window" : "%d")) map_height_ = 0;
    map_width_ = std::max(map_width_, 0);
    const Config c = current_config();
    if (map_width_ > 0)
      ImGui::Text("visibility map %dx%d, screen %dx%d", c.map_width, c.map_height, fb_w_, fb_h_);
    else
      ImGui::Text("visibility map = screen, %dx%d", fb_w_, fb_h_);
    ImGui::Checkbox("culling", &culling_);
    ImGui::SameLine();
    ImGui::Checkbox("adaptive bits", &adaptive_);
    if (!adaptive_) {
      ImGui::SameLine();
      ImGui::SetNextItemWidth(70);
      ImGui::Combo("##bits", &fixed_bits_index_,
                   "16\0"
                   "32\0"
                   "64\0");
    }
    ImGui::Checkbox("paused (space)", &paused_);
    ImGui::SameLine();
    if (ImGui::Button("reset camera (R)")) reset_camera();

    ImGui::Text("backend");
    ImGui::SameLine();
    int be = backend_ == Backend::gl ? 1 : 0;
    bool be_changed = ImGui::RadioButton("cpu", &be, 0);
    ImGui::SameLine();
    be_changed |= ImGui::RadioButton("gl", &be, 1);
    int geom = mesh_ ? 1 : 0;
    bool geom_changed = false;
    if (backend_ == Backend::gl) {
      ImGui::SameLine();
      ImGui::TextDisabled("|");
      ImGui::SameLine();
      geom_changed = ImGui::RadioButton("impostor", &geom, 0);
      ImGui::SameLine();
      geom_changed |= ImGui::RadioButton("mesh", &geom, 1);
    }
    if ((be_changed && (be == 1) != (backend_ == Backend::gl)) || (geom_changed && (geom == 1) != mesh_))
      switch_backend(be == 1 ? Backend::gl : Backend::cpu, geom == 1);
    if (!backend_message_.empty()) {
      ImGui::PushTextWrapPos(ImGui::GetCursorPosX() + 320);
      ImGui::TextColored(ImVec4(1, 0.45f, 0.4f, 1), "%s", backend_message_.c_str());
      ImGui::PopTextWrapPos();
    }
  }

  if (ImGui::CollapsingHeader("Frame", ImGuiTreeNodeFlags_DefaultOpen)) {
    const FrameStats& st = result_.stats;
    const double fps = frame_ms_smooth_ > 0 ? 1000.0 / frame_ms_smooth_ : 0.0;
    ImGui::Text("%.1f FPS (%.1f ms per frame), %s backend", fps, frame_ms_smooth_,
                detector_ ? std::string(detector_->name()).c_str() : "-");
    ImGui::Text("active %u / %u (%.1f %%)", st.active, st.objects, st.objects ? 100.0 * st.active / st.objects : 0.0);
    ImGui::Text("mu = %.1f px, m = %d bits %s", st.mean_pixels, st.bits, format_layout(st.layout, true).c_str());
    ImGui::Text("pairs %" PRIu64 ", scene time %.1f s", st.pairs, scene_.time());
  }

  if (ImGui::CollapsingHeader("Stage times (ms)", ImGuiTreeNodeFlags_DefaultOpen)) timings_chart();

  if (ImGui::CollapsingHeader("Colours", ImGuiTreeNodeFlags_DefaultOpen)) {
    const auto swatch = [](const char* id, const ImVec4& c, const char* text) {
      ImGui::ColorButton(id, c, ImGuiColorEditFlags_NoTooltip | ImGuiColorEditFlags_NoPicker, ImVec2(12, 12));
      ImGui::SameLine();
      ImGui::TextUnformatted(text);
    };
    swatch("##red", kColliding, "red: colliding");
    swatch("##blue", kFree, "blue: visible and free");
    swatch("##yellow", kCulled, "yellow: culled (fewer than lambda pixels)");
  }

  if (ImGui::Button("save screenshot (S)")) screenshot_requested_ = true;
  if (!status_line_.empty()) {
    ImGui::SameLine();
    ImGui::TextUnformatted(status_line_.c_str());
  }
  ImGui::TextDisabled("left drag orbit, right/middle drag pan, wheel zoom");
  ImGui::PopItemWidth();
  ImGui::End();
}

Status Viewer::frame() {
  const auto t0 = Clock::now();
  if (!paused_) scene_.step(args_.world.dt);
  const double sim_ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
  const Camera cam = orbit_.camera(fb_w_, fb_h_);
  Status s;
  {
    DetectorGuard guard(window_, backend_ == Backend::gl);
    detector_->set_config(current_config());
    s = detector_->detect(scene_.spheres(), &cam, result_);
  }
  if (!s) {
    have_result_ = false;
    return s;
  }
  have_result_ = true;
  auto& row = history_[static_cast<std::size_t>(history_next_)];
  row[0] = static_cast<float>(sim_ms);
  for (std::size_t k = 0; k < kStageCount; ++k) row[k + 1] = static_cast<float>(result_.stats.stage_ms[k]);
  history_next_ = (history_next_ + 1) % kHistory;
  history_count_ = std::min(history_count_ + 1, kHistory);
  return {};
}

void Viewer::upload_image() {
  if (!have_result_ || result_.image.empty()) return;
  glBindTexture(GL_TEXTURE_2D, texture_);
  glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
  glPixelStorei(GL_UNPACK_ROW_LENGTH, 0);
  if (result_.image_width != tex_w_ || result_.image_height != tex_h_) {
    tex_w_ = result_.image_width;
    tex_h_ = result_.image_height;
    glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA8, tex_w_, tex_h_, 0, GL_RGBA, GL_UNSIGNED_BYTE, result_.image.data());
  } else {
    glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, tex_w_, tex_h_, GL_RGBA, GL_UNSIGNED_BYTE, result_.image.data());
  }
}

int Viewer::run() {
  if (auto config = make_config(args_.pipeline); !config) return usage_fail(config.error());
  auto size = parse_size(args_.size, "--size");
  if (!size) return usage_fail(size.error());
  if (Status s = setup(); !s) return fail(s.error());

  glfwSetErrorCallback(on_glfw_error);
  if (!glfwInit()) return no_window("cannot connect to a display");
  glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 3);
  glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 3);
  glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
  glfwWindowHint(GLFW_OPENGL_FORWARD_COMPAT, GLFW_TRUE);
  window_ = glfwCreateWindow(size.value().first, size.value().second, "viscd view", nullptr, nullptr);
  if (!window_) {
    glfwTerminate();
    return no_window("cannot open an OpenGL 3.3 core window");
  }
  glfwMakeContextCurrent(window_);
  glfwSwapInterval(args_.frames > 0 ? 0 : 1);
  glfwGetFramebufferSize(window_, &fb_w_, &fb_h_);
  fb_w_ = std::max(fb_w_, 1), fb_h_ = std::max(fb_h_, 1);

  IMGUI_CHECKVERSION();
  ImGui::CreateContext();
  ImGui::GetIO().IniFilename = nullptr;  // no imgui.ini in the working folder
  ImGui::StyleColorsDark();
  ImGui_ImplGlfw_InitForOpenGL(window_, true);
  ImGui_ImplOpenGL3_Init("#version 330 core");

  glGenTextures(1, &texture_);
  glBindTexture(GL_TEXTURE_2D, texture_);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);

  rebuild_scene();
  mesh_ = args_.pipeline.geometry == "mesh";
  detector_ = make_cpu_detector(current_config());
  if (args_.pipeline.backend == "gl") switch_backend(Backend::gl, mesh_);
  std::printf("viscd view: %s backend, %d objects (%s scene), window %dx%d%s\n", backend_ == Backend::gl ? "gl" : "cpu",
              objects_, args_.world.kind.c_str(), fb_w_, fb_h_,
              args_.frames > 0 ? (", " + std::to_string(args_.frames) + " frames").c_str() : "");
  std::fflush(stdout);

  int rc = 0;
  int frames_done = 0;
  while (!glfwWindowShouldClose(window_)) {
    glfwPollEvents();
    int w = 0, h = 0;
    glfwGetFramebufferSize(window_, &w, &h);
    if (w <= 0 || h <= 0) {  // minimised
      glfwWaitEventsTimeout(0.1);
      continue;
    }
    fb_w_ = w, fb_h_ = h;

    ImGui_ImplOpenGL3_NewFrame();
    ImGui_ImplGlfw_NewFrame();
    ImGui::NewFrame();
    handle_input();
    panel();

    if (Status s = frame(); !s) {
      if (backend_ == Backend::gl) {
        backend_message_ = "gl backend failed: " + s.error() + "; switched to cpu";
        std::fprintf(stderr, "viscd view: %s\n", backend_message_.c_str());
        destroy_detector();
        backend_ = Backend::cpu;
        detector_ = make_cpu_detector(current_config());
      } else {
        rc = fail("frame " + std::to_string(frames_done) + ": " + s.error());
        break;
      }
    }
    upload_image();
    if (have_result_)
      ImGui::GetBackgroundDrawList()->AddImage(reinterpret_cast<ImTextureID>(static_cast<std::uintptr_t>(texture_)),
                                               ImVec2(0, 0), ImGui::GetIO().DisplaySize);
    if (screenshot_requested_) {
      screenshot_requested_ = false;
      const std::filesystem::path path =
          args_.screenshot.empty() ? next_screenshot_path() : std::filesystem::path(args_.screenshot);
      const std::string err = save_screenshot(path);
      status_line_ = err.empty() ? "wrote " + path.string() : "screenshot failed: " + err;
      if (!err.empty()) std::fprintf(stderr, "viscd view: %s\n", status_line_.c_str());
    }

    ImGui::Render();
    glViewport(0, 0, fb_w_, fb_h_);
    glClearColor(0.07f, 0.07f, 0.09f, 1.0f);
    glClear(GL_COLOR_BUFFER_BIT);
    ImGui_ImplOpenGL3_RenderDrawData(ImGui::GetDrawData());
    const bool last_frame = args_.frames > 0 && have_result_ && frames_done + 1 >= args_.frames;
    if (last_frame && !args_.window_screenshot.empty()) {
      if (std::string err = save_window(args_.window_screenshot); !err.empty()) rc = fail(err);
    }
    glfwSwapBuffers(window_);

    const auto now = Clock::now();
    const double ms = std::chrono::duration<double, std::milli>(now - last_frame_).count();
    last_frame_ = now;
    frame_ms_smooth_ = frame_ms_smooth_ == 0 ? ms : 0.9 * frame_ms_smooth_ + 0.1 * ms;

    if (have_result_) ++frames_done;
    if (args_.frames > 0 && frames_done >= args_.frames) {
      const FrameStats& st = result_.stats;
      std::printf(
          "viscd view: %d frames, last: %u of %u objects active, mu = %.1f px, m = %d bits %s, %" PRIu64 " pairs\n",
          frames_done, st.active, st.objects, st.mean_pixels, st.bits, format_layout(st.layout).c_str(), st.pairs);
      if (!args_.screenshot.empty()) {
        if (std::string err = save_screenshot(args_.screenshot); !err.empty()) rc = fail(err);
      }
      break;
    }
  }

  destroy_detector();
  glDeleteTextures(1, &texture_);
  ImGui_ImplOpenGL3_Shutdown();
  ImGui_ImplGlfw_Shutdown();
  ImGui::DestroyContext();
  glfwDestroyWindow(window_);
  glfwTerminate();
  return rc;
}

}  // namespace

void add_view_command(CLI::App& app, int& rc) {
  auto args = std::make_shared<ViewArgs>();
  CLI::App* cmd =
      app.add_subcommand("view",
                         "The demo in a window (GLFW + Dear ImGui): the paper's scene moving, shaded red (colliding),\n"
                         "blue (visible and free) and yellow (culled), with sliders for N, lambda, a, b and the\n"
                         "visibility-map size, toggles for culling and adaptive bits, the cpu or gl backend, and live\n"
                         "per-stage timings. Mouse: left drag orbits, right or middle drag pans, wheel zooms.\n"
                         "Keys: S screenshot, Space pause, R reset camera, Esc quit. Needs a display (or xvfb-run).");
  add_scene_options(*cmd, args->world);
  cmd->add_option("--camera", args->camera, "start view: zoom-out | zoom-in | FILE.json")->capture_default_str();
  cmd->add_option("--size", args->size, "window WxH")->capture_default_str();
  cmd->add_option("--frames", args->frames,
                  "run this many frames, write --screenshot (if given) and exit; 0 = until closed")
      ->capture_default_str();
  cmd->add_option("--screenshot", args->screenshot,
                  "PNG written after --frames, and by S / the button (default viscd-view-NNN.png)");
  cmd->add_option("--window-screenshot", args->window_screenshot,
                  "with --frames: also write the whole window, panel included, as PNG");
  add_pipeline_options(*cmd, args->pipeline, false);
  cmd->get_option("--backend")
      ->description("cpu | gl (switchable in the panel; gl falls back to cpu if it cannot start)");
  cmd->callback([args, &rc] { rc = Viewer(*args).run(); });
}

}  // namespace viscd::app
