// `viscd view`: the demo in a window. GLFW opens an OpenGL 3.3 core window, Dear ImGui draws the
// panel, and each frame the chosen detector (cpu, or gl through its own EGL context) steps the
// scene, finds the pairs and shades the image that fills the window.
//
// Contexts: the window's context is GLX (GLFW's default on X11, and what Dear ImGui's OpenGL3
// loader resolves through); the gl backend owns a surfaceless EGL context. libglvnd refuses to
// make one API's context current while the other's is, so every call into the gl detector is
// bracketed by releasing the window's context before and the detector's after (DetectorGuard).
//
// Lifetimes: run_view() checks the options, then opens GLFW, the window and Dear ImGui through
// their owners (view_window.hpp), and only then makes the Viewer, which holds the texture and the
// detector: whatever way run_view() returns, the Viewer goes first (its detector under the
// guard), then ImGui, the window and GLFW.
#include "view_window.hpp"  // first: epoxy's GL header must precede GLFW's and ImGui's

#include <backends/imgui_impl_glfw.h>
#include <backends/imgui_impl_opengl3.h>
#include <imgui.h>
#include <CLI/CLI.hpp>

#include <algorithm>
#include <array>
#include <cfloat>
#include <chrono>
#include <cinttypes>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "commands.hpp"
#include "detector_choice.hpp"
#include "exit_codes.hpp"
#include "options.hpp"
#include "static_objects.hpp"
#include "view_orbit.hpp"
#include "viscd/io.hpp"
#include "viscd/scene.hpp"

namespace viscd::app {
namespace {

using Clock = std::chrono::steady_clock;

struct ViewArgs {
  PipelineOptions pipeline;
  SceneOptions world;
  ObjectOptions objects;
  std::string camera = "zoom-out";
  std::string size = "1280x720";
  int frames = 0;
  std::string screenshot;
  std::string window_screenshot;
};

// What the options start the viewer with, checked before any window opens.
struct ViewStart {
  Config config;  // the pipeline options; the panel edits a copy
  int objects = 0;
  SceneKind kind = SceneKind::ring;
  ShapeKind shape = ShapeKind::sphere;
  std::optional<Camera> file_camera;
  DetectorRequest detector;  // cpu or gl; gl falls back to cpu
};

// Shading colours of stage 9 (viscd::state_colour), for the legend.
ImVec4 rgb(viscd::Rgb8 c) {
  return ImVec4(static_cast<float>(c.r) / 255.0f, static_cast<float>(c.g) / 255.0f, static_cast<float>(c.b) / 255.0f,
                1.0f);
}
const ImVec4 kColliding = rgb(viscd::state_colour(viscd::ObjectState::colliding));
const ImVec4 kFree = rgb(viscd::state_colour(viscd::ObjectState::free));
const ImVec4 kCulled = rgb(viscd::state_colour(viscd::ObjectState::culled));
const ImVec4 kStatic = rgb(viscd::kStaticColour);

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

int no_window(const std::string& what) {
  const char* display = std::getenv("DISPLAY");
  std::string msg = what;
  if (!GlfwLibrary::last_error().empty()) msg += " (" + GlfwLibrary::last_error() + ")";
  msg += display && *display ? std::string(". DISPLAY is '") + display + "'" : std::string(". DISPLAY is not set");
  msg +=
      ": run on a desktop session, or headless under a virtual X server with OpenGL 3.3, e.g.\n"
      "  xvfb-run -a -s \"-screen 0 1280x800x24\" viscd view ...\n"
      "(`viscd run` needs no display)";
  return fail(msg);
}

// The options checked and turned into the viewer's start; every error here exits 1.
// The options' values; a bad one is a usage error (exit 2), as in the other commands. The camera
// file, when one is named, is read afterwards (read_view_camera): a bad file is bad input (exit 1).
Result<ViewStart> check_view_args(const ViewArgs& args, const Config& config) {
  using R = Result<ViewStart>;
  ViewStart start;
  start.config = config;
  if (args.world.objects < 1 || args.world.objects > (1u << 29))
    return R::failure(ErrorKind::invalid_input, "--objects: expected 1 to 536870912");
  start.objects = static_cast<int>(args.world.objects);
  auto params = make_scene_params(args.world);
  if (!params) return R::failure(params.status());
  start.kind = params.value().kind;
  auto shape = parse_shape_kind(args.objects.shape);
  if (!shape) return R::failure(ErrorKind::invalid_input, "--shape: " + shape.error());
  start.shape = shape.value();
  if (args.frames < 0)
    return R::failure(ErrorKind::invalid_input, "--frames: expected 0 (until the window closes) or more");
  auto request = detector_request(args.pipeline);
  if (!request) return R::failure(request.status());
  start.detector = request.value();
  start.detector.fallback = GlFallback::cpu;
  start.detector.tool = "viscd view";
  const std::string& be = args.pipeline.backend;
  if (be != "cpu" && be != "gl")
    return R::failure(ErrorKind::invalid_input,
                      "--backend: viscd view runs cpu or gl, got '" + printable(be) +
                          "' (the reference backend ray-casts every pixel against every object: use viscd pairs)");
  const bool file = args.camera.size() > 5 && args.camera.ends_with(".json");
  if (!file && args.camera != "zoom-out" && args.camera != "zoom-in")
    return R::failure(ErrorKind::invalid_input,
                      "--camera: expected zoom-out, zoom-in or a .json file, got '" + printable(args.camera) + "'");
  return start;
}

// The camera file named by --camera, if any, into `start`.
Status read_view_camera(const ViewArgs& args, ViewStart& start) {
  if (!(args.camera.size() > 5 && args.camera.ends_with(".json"))) return {};
  auto c = read_camera(args.camera);
  if (!c) return c.status();
  start.file_camera = c.value();
  return {};
}

// The viewer's state and frame loop, in a window whose GLFW, context and Dear ImGui outlive it.
class Viewer {
 public:
  Viewer(const ViewArgs& args, ViewStart start, GLFWwindow* window);
  ~Viewer() { destroy_detector(); }
  Viewer(const Viewer&) = delete;
  Viewer& operator=(const Viewer&) = delete;
  /// Runs frames until the window closes or --frames are done; the exit code.
  int run();

 private:
  Config frame_config() const;
  void rebuild_scene();
  Status hand_static_field();
  void reset_camera();
  void destroy_detector();
  void switch_backend(bool gl, bool mesh);
  void handle_input();
  void panel();
  void timings_chart();
  Status frame();
  void upload_image();
  std::string save_screenshot(const std::filesystem::path& path);
  std::string save_window(const std::filesystem::path& path);
  std::filesystem::path next_screenshot_path() const;

  const ViewArgs& args_;
  GLFWwindow* window_;
  int fb_w_ = 1, fb_h_ = 1;

  // Scene and camera.
  SceneKind kind_;
  ShapeKind shape_;
  Scene scene_;
  std::vector<Sphere> field_;  // --static: the static set, made with the scene
  std::vector<Box> cubes_;     // --shape box: the scene's spheres as cubes, each frame
  OrbitCamera orbit_;
  std::optional<Camera> file_camera_;
  bool paused_ = false;

  // The pipeline's settings: the panel's sliders and toggles edit these fields directly. A map
  // width with map_height 0 means a height that follows the window's aspect (frame_config()).
  Config config_;
  Bits fixed_bits_ = Bits::b32;  // the width the bits combo shows, used while adaptive bits are off
  int objects_;

  // Detector.
  DetectorRequest request_;  // the options' gl settings; the panel switches backend and geometry
  bool gl_ = false;
  bool mesh_ = false;
  std::unique_ptr<Detector> detector_;
  std::string backend_message_;

  // Frame output.
  FrameResult result_;
  bool have_result_ = false;
  GlTexture texture_;
  int tex_w_ = 0, tex_h_ = 0;
  std::array<std::array<float, kSeries>, kHistory> history_{};
  int history_next_ = 0, history_count_ = 0;
  double frame_ms_smooth_ = 0;
  Clock::time_point last_frame_ = Clock::now();
  bool screenshot_requested_ = false;
  std::string status_line_;
};

Viewer::Viewer(const ViewArgs& args, ViewStart start, GLFWwindow* window)
    : args_(args),
      window_(window),
      kind_(start.kind),
      shape_(start.shape),
      file_camera_(start.file_camera),
      config_(start.config),
      objects_(start.objects),
      request_(std::move(start.detector)) {
  config_.shade = true;  // the window shows the shaded image
  if (config_.bits != Bits::adaptive) fixed_bits_ = config_.bits;
  mesh_ = request_.gl.geometry == GlGeometry::mesh;
  glfwGetFramebufferSize(window_, &fb_w_, &fb_h_);
  fb_w_ = std::max(fb_w_, 1), fb_h_ = std::max(fb_h_, 1);
  rebuild_scene();
}

Config Viewer::frame_config() const {
  Config c = config_;
  if (c.map_width > 0) {
    if (c.map_height <= 0)
      c.map_height = std::max(1, static_cast<int>(std::lround(static_cast<double>(c.map_width) * fb_h_ / fb_w_)));
  } else {
    c.map_width = c.map_height = 0;
  }
  return c;
}

void Viewer::rebuild_scene() {
  scene_ = Scene::make({.kind = kind_, .objects = static_cast<std::uint32_t>(objects_), .seed = args_.world.seed});
  // The world grows with N: so does the field on its ground (none before the first detector).
  field_ = static_field(scene_, args_.objects.static_count);
  if (detector_)
    if (Status s = hand_static_field(); !s) std::fprintf(stderr, "viscd view: --static: %s\n", s.error().c_str());
  reset_camera();
}

// The static field to the detector: once per detector and per scene.
Status Viewer::hand_static_field() {
  DetectorGuard guard(window_, gl_);
  return set_static_field(*detector_, field_, shape_);
}

void Viewer::reset_camera() {
  Camera c;
  if (file_camera_) {
    c = *file_camera_;
  } else {
    auto preset = camera_preset(args_.camera, scene_, fb_w_, fb_h_);
    c = preset ? preset.value() : camera_preset("zoom-out", scene_, fb_w_, fb_h_).value();
  }
  orbit_.reset(c, scene_.world_radius() + scene_.world_half_height());
}

void Viewer::destroy_detector() {
  DetectorGuard guard(window_, gl_ && detector_ != nullptr);
  detector_.reset();
}

// The panel's backend or geometry choice; a gl backend that cannot start leaves the current
// detector running and says why.
void Viewer::switch_backend(bool gl, bool mesh) {
  DetectorRequest request = request_;
  request.backend = gl ? "gl" : "cpu";
  request.gl.geometry = mesh ? GlGeometry::mesh : GlGeometry::impostor;
  request.fallback = GlFallback::none;
  request.quiet = true;
  Result<DetectorChoice> chosen = [&] {
    DetectorGuard guard(window_, gl);
    return make_tool_detector(request, frame_config());
  }();
  if (!chosen) {
    backend_message_ = gl_unavailable(chosen.error());
    std::fprintf(stderr, "viscd view: %s; staying on %s\n", backend_message_.c_str(), gl_ ? "gl" : "cpu");
    return;
  }
  destroy_detector();
  detector_ = std::move(chosen.value().detector);
  gl_ = gl;
  mesh_ = mesh;
  backend_message_.clear();
  if (Status s = hand_static_field(); !s) backend_message_ = "--static: " + s.error();
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
    float& a = config_.pixels_for_32_bits;
    float& b = config_.pixels_for_64_bits;
    ImGui::SliderFloat("lambda (px)", &config_.lambda, 0, 5000, "%.0f", ImGuiSliderFlags_Logarithmic);
    if (ImGui::SliderFloat("a (16 below)", &a, 0, 5000, "%.0f", ImGuiSliderFlags_Logarithmic)) b = std::max(a, b);
    if (ImGui::SliderFloat("b (64 from)", &b, 0, 5000, "%.0f", ImGuiSliderFlags_Logarithmic)) a = std::min(a, b);
    config_.lambda = std::max(config_.lambda, 0.0f);
    int& map_width = config_.map_width;
    if (ImGui::SliderInt("map width", &map_width, 0, 3840, map_width == 0 ? "window" : "%d"))
      config_.map_height = 0;  // from now on the height follows the window's aspect
    map_width = std::max(map_width, 0);
    const Config c = frame_config();
    if (map_width > 0)
      ImGui::Text("visibility map %dx%d, screen %dx%d", c.map_width, c.map_height, fb_w_, fb_h_);
    else
      ImGui::Text("visibility map = screen, %dx%d", fb_w_, fb_h_);
    ImGui::Checkbox("culling", &config_.culling);
    ImGui::SameLine();
    bool adaptive = config_.bits == Bits::adaptive;
    if (ImGui::Checkbox("adaptive bits", &adaptive)) config_.bits = adaptive ? Bits::adaptive : fixed_bits_;
    if (!adaptive) {
      ImGui::SameLine();
      ImGui::SetNextItemWidth(70);
      constexpr std::array<Bits, 3> kFixed = {Bits::b16, Bits::b32, Bits::b64};
      int index = static_cast<int>(std::find(kFixed.begin(), kFixed.end(), fixed_bits_) - kFixed.begin());
      if (ImGui::Combo("##bits", &index,
                       "16\0"
                       "32\0"
                       "64\0"))
        config_.bits = fixed_bits_ = kFixed[static_cast<std::size_t>(index)];
    }
    ImGui::Checkbox("paused (space)", &paused_);
    ImGui::SameLine();
    if (ImGui::Button("reset camera (R)")) reset_camera();

    ImGui::Text("backend");
    ImGui::SameLine();
    int be = gl_ ? 1 : 0;
    bool be_changed = ImGui::RadioButton("cpu", &be, 0);
    ImGui::SameLine();
    be_changed |= ImGui::RadioButton("gl", &be, 1);
    int geom = mesh_ ? 1 : 0;
    bool geom_changed = false;
    if (gl_) {
      ImGui::SameLine();
      ImGui::TextDisabled("|");
      ImGui::SameLine();
      geom_changed = ImGui::RadioButton("impostor", &geom, 0);
      ImGui::SameLine();
      geom_changed |= ImGui::RadioButton("mesh", &geom, 1);
    }
    if ((be_changed && (be == 1) != gl_) || (geom_changed && (geom == 1) != mesh_)) switch_backend(be == 1, geom == 1);
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
    ImGui::Text("active %u / %u %s (%.1f %%)", st.active, st.objects, shape_ == ShapeKind::box ? "boxes" : "spheres",
                st.objects ? 100.0 * st.active / st.objects : 0.0);
    if (!field_.empty()) ImGui::Text("static %u (never culled)", st.static_objects);
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
    if (!field_.empty()) swatch("##grey", kStatic, "grey: static (never culled)");
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
  FrameInput input;
  if (shape_ == ShapeKind::box) {
    cubes_of(scene_.spheres(), cubes_);
    input.boxes = cubes_;
  } else {
    input.spheres = scene_.spheres();
  }
  const double sim_ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
  const Camera cam = orbit_.camera(fb_w_, fb_h_);
  input.camera = &cam;
  Status s;
  {
    DetectorGuard guard(window_, gl_);
    detector_->set_config(frame_config());
    s = detector_->detect(input, result_);
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
  glBindTexture(GL_TEXTURE_2D, texture_.id());
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
  {
    // The detector the options ask for; gl that cannot start falls back to cpu with a message.
    Result<DetectorChoice> chosen = [&] {
      DetectorGuard guard(window_, request_.backend == "gl");
      return make_tool_detector(request_, frame_config());
    }();
    if (!chosen) return fail(chosen.error());
    detector_ = std::move(chosen.value().detector);
    gl_ = chosen.value().backend == "gl";
    if (chosen.value().fell_back) backend_message_ = chosen.value().why;
    if (Status s = hand_static_field(); !s) return fail("--static: " + s.error());
  }
  std::printf("viscd view: %s backend, %d %s (%s scene)%s, window %dx%d%s\n", gl_ ? "gl" : "cpu", objects_,
              shape_ == ShapeKind::box ? "boxes" : "objects", args_.world.kind.c_str(),
              field_.empty() ? "" : (" + " + std::to_string(field_.size()) + " static").c_str(), fb_w_, fb_h_,
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
      if (gl_) {
        // A gl backend that fails mid-run: the window goes on with cpu rather than closing.
        backend_message_ = "gl backend failed: " + s.error() + "; switched to cpu";
        std::fprintf(stderr, "viscd view: %s\n", backend_message_.c_str());
        destroy_detector();
        gl_ = false;
        detector_ = make_cpu_detector(frame_config());
        if (Status hs = hand_static_field(); !hs) {
          rc = fail("--static: " + hs.error());
          break;
        }
      } else {
        rc = fail("frame " + std::to_string(frames_done) + ": " + s.error());
        break;
      }
    }
    upload_image();
    if (have_result_)
      ImGui::GetBackgroundDrawList()->AddImage(
          reinterpret_cast<ImTextureID>(static_cast<std::uintptr_t>(texture_.id())), ImVec2(0, 0),
          ImGui::GetIO().DisplaySize);
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
      std::printf("viscd view: %d frames, last: %u of %u objects active%s, mu = %.1f px, m = %d bits %s, %" PRIu64
                  " pairs\n",
                  frames_done, st.active, st.objects,
                  field_.empty() ? "" : (", " + std::to_string(st.static_objects) + " static").c_str(), st.mean_pixels,
                  st.bits, format_layout(st.layout).c_str(), st.pairs);
      if (!args_.screenshot.empty()) {
        if (std::string err = save_screenshot(args_.screenshot); !err.empty()) rc = fail(err);
      }
      break;
    }
  }
  return rc;
}

int run_view(const ViewArgs& args) {
  auto config = make_config(args.pipeline);
  if (!config) return usage_fail(config.error());
  auto size = parse_size(args.size, "--size");
  if (!size) return usage_fail(size.error());
  auto start = check_view_args(args, config.value());
  if (!start) return usage_fail(start.error());
  if (Status s = read_view_camera(args, start.value()); !s) return fail(s.error());

  // Declared in the order they start; destroyed in the reverse one on every return.
  const GlfwLibrary glfw;
  if (!glfw.ok()) return no_window("cannot connect to a display");
  const GlfwWindow window(size.value().first, size.value().second, "viscd view");
  if (!window.get()) return no_window("cannot open an OpenGL 3.3 core window");
  glfwSwapInterval(args.frames > 0 ? 0 : 1);
  const ImGuiLayer imgui(window.get());
  if (!imgui.ok()) return fail("cannot start Dear ImGui's GLFW or OpenGL 3 backend in the window");
  Viewer viewer(args, std::move(start.value()), window.get());
  return viewer.run();
}

}  // namespace

void add_view_command(CLI::App& app, int& rc) {
  auto args = std::make_shared<ViewArgs>();
  CLI::App* cmd = app.add_subcommand(
      "view",
      "The demo in a window (GLFW + Dear ImGui): the paper's scene moving (as spheres, or boxes\n"
      "with --shape box; on a static field with --static K), shaded red (colliding), blue\n"
      "(visible and free), yellow (culled) and grey (static), with sliders for N, lambda, a, b\n"
      "and the visibility-map size, toggles for culling and adaptive bits, the cpu or gl backend,\n"
      "and live per-stage timings. Mouse: left drag orbits, right or middle drag pans, wheel zooms.\n"
      "Keys: S screenshot, Space pause, R reset camera, Esc quit. Needs a display (or xvfb-run).");
  add_scene_options(*cmd, args->world);
  add_object_options(*cmd, args->objects, "; the field follows the world as the N slider rebuilds it");
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
  cmd->callback([args, &rc] { rc = run_view(*args); });
}

}  // namespace viscd::app
