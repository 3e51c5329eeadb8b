#include "viscd/io.hpp"

#include "viscd/detector.hpp"

#include <charconv>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wconversion"
#pragma GCC diagnostic ignored "-Wsign-conversion"
#pragma GCC diagnostic ignored "-Wmissing-field-initializers"
#define STB_IMAGE_WRITE_IMPLEMENTATION
#define STB_IMAGE_WRITE_STATIC
#include <stb/stb_image_write.h>
#pragma GCC diagnostic pop

namespace viscd {
namespace {

using SpheresResult = Result<std::vector<Sphere>>;

std::string where(std::string_view source, std::size_t line) {
  return std::string(source) + ":" + std::to_string(line) + ": ";
}

std::string_view trim(std::string_view s) {
  const auto b = s.find_first_not_of(" \t\r");
  if (b == std::string_view::npos) return {};
  const auto e = s.find_last_not_of(" \t\r");
  return s.substr(b, e - b + 1);
}

// Splits on `seps`, skipping empty fields when `collapse` (blanks), keeping them otherwise (CSV).
std::vector<std::string_view> split(std::string_view s, std::string_view seps, bool collapse) {
  std::vector<std::string_view> out;
  std::size_t start = 0;
  for (std::size_t i = 0; i <= s.size(); ++i) {
    if (i == s.size() || seps.find(s[i]) != std::string_view::npos) {
      std::string_view f = trim(s.substr(start, i - start));
      if (!collapse || !f.empty()) out.push_back(f);
      start = i + 1;
    }
  }
  return out;
}

// Parses the four fields of a sphere; on error returns the message (without location).
std::string parse_sphere(const std::vector<std::string_view>& f, Sphere& s) {
  if (f.size() != 4)
    return "expected 4 numbers `x y z r`, found " + std::to_string(f.size()) + " field" + (f.size() == 1 ? "" : "s");
  float v[4];
  static constexpr const char* kName[4] = {"x", "y", "z", "r"};
  for (int c = 0; c < 4; ++c) {
    std::string_view t = f[c];
    if (!t.empty() && t[0] == '+') t.remove_prefix(1);
    auto [ptr, ec] = std::from_chars(t.data(), t.data() + t.size(), v[c]);
    if (ec == std::errc::result_out_of_range) {
      // Underflow (e.g. 1e-46) rounds to zero like any other decimal; overflow is an error.
      double d = 0;
      const auto [dptr, dec] = std::from_chars(t.data(), t.data() + t.size(), d);
      if (dec != std::errc() || dptr != t.data() + t.size() || std::fabs(d) >= 1.0)
        return std::string(kName[c]) + " = '" + std::string(f[c]) + "' is out of float range";
      v[c] = static_cast<float>(d);
      ptr = dptr;
      ec = std::errc();
    }
    if (ec != std::errc() || ptr != t.data() + t.size() || t.empty())
      return std::string(kName[c]) + ": expected a number, found '" + std::string(f[c]) + "'";
    if (!std::isfinite(v[c]))
      return std::string(kName[c]) + " = " + std::string(f[c]) + " is not finite (NaN and infinity are not allowed)";
    if (std::fabs(v[c]) > kMaxCoordinate)
      return std::string(kName[c]) + " = " + std::string(f[c]) + " exceeds the supported magnitude 1e18";
  }
  if (v[3] < 0) return "r = " + std::string(f[3]) + " is negative (a radius must be >= 0)";
  s = Sphere{v[0], v[1], v[2], v[3]};
  return {};
}

template <class F>
void for_each_line(std::string_view text, F&& f) {
  std::size_t line = 1, start = 0;
  while (start < text.size()) {
    std::size_t end = text.find('\n', start);
    if (end == std::string_view::npos) end = text.size();
    if (!f(text.substr(start, end - start), line)) return;
    start = end + 1;
    ++line;
  }
}

Result<std::string> slurp(const std::filesystem::path& path) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec))
    return Result<std::string>::failure(path.string() + ": is a folder, expected a file");
  std::ifstream in(path, std::ios::binary);
  if (!in) return Result<std::string>::failure(path.string() + ": cannot open for reading");
  std::ostringstream ss;
  ss << in.rdbuf();
  if (in.bad()) return Result<std::string>::failure(path.string() + ": read error");
  return ss.str();
}

}  // namespace

SpheresResult parse_xyzr(std::string_view text, std::string_view source) {
  std::vector<Sphere> out;
  std::string error;
  for_each_line(text, [&](std::string_view line, std::size_t no) {
    const auto hash = line.find('#');
    if (hash != std::string_view::npos) line = line.substr(0, hash);
    if (trim(line).empty()) return true;
    Sphere s;
    if (std::string e = parse_sphere(split(line, " \t,", true), s); !e.empty()) {
      error = where(source, no) + e;
      return false;
    }
    out.push_back(s);
    return true;
  });
  if (!error.empty()) return SpheresResult::failure(error);
  return out;
}

SpheresResult parse_csv(std::string_view text, std::string_view source) {
  std::vector<Sphere> out;
  std::string error;
  bool header = false;
  for_each_line(text, [&](std::string_view line, std::size_t no) {
    if (trim(line).empty()) return true;
    const auto fields = split(line, ",", false);
    if (!header) {
      if (fields.size() != 4 || fields[0] != "x" || fields[1] != "y" || fields[2] != "z" || fields[3] != "r") {
        error = where(source, no) + "expected the header `x,y,z,r`, found '" + std::string(trim(line)) + "'";
        return false;
      }
      header = true;
      return true;
    }
    Sphere s;
    if (std::string e = parse_sphere(fields, s); !e.empty()) {
      error = where(source, no) + e;
      return false;
    }
    out.push_back(s);
    return true;
  });
  if (!error.empty()) return SpheresResult::failure(error);
  return out;
}

SpheresResult read_spheres(const std::filesystem::path& path) {
  auto text = slurp(path);
  if (!text) return SpheresResult::failure(text.error());
  if (path.extension() == ".csv") return parse_csv(text.value(), path.string());
  return parse_xyzr(text.value(), path.string());
}

Result<Camera> parse_camera(std::string_view text, std::string_view source) {
  using nlohmann::json;
  json j;
  try {
    j = json::parse(text);
  } catch (const json::parse_error& e) {
    // Turn the byte offset into a line number.
    std::size_t line = 1;
    for (std::size_t i = 0; i < std::min<std::size_t>(e.byte, text.size()); ++i) line += text[i] == '\n';
    std::string what = e.what();
    const auto colon = what.rfind(": ");
    return Result<Camera>::failure(where(source, line) +
                                   "invalid JSON: " + (colon == std::string::npos ? what : what.substr(colon + 2)));
  }
  auto fail = [&](const std::string& m) { return Result<Camera>::failure(std::string(source) + ": " + m); };
  if (!j.is_object()) return fail("expected a JSON object {\"eye\": [x,y,z], ...}");
  Camera c;
  for (auto it = j.begin(); it != j.end(); ++it) {
    const std::string& key = it.key();
    const json& v = it.value();
    auto vec3 = [&](float* dst) -> std::string {
      if (!v.is_array() || v.size() != 3 || !v[0].is_number() || !v[1].is_number() || !v[2].is_number())
        return "\"" + key + "\": expected an array of 3 numbers [x, y, z]";
      for (int k = 0; k < 3; ++k) dst[k] = v[k].get<float>();
      return {};
    };
    auto number = [&](float& dst) -> std::string {
      if (!v.is_number()) return "\"" + key + "\": expected a number";
      dst = v.get<float>();
      return {};
    };
    auto integer = [&](int& dst) -> std::string {
      if (!v.is_number_integer() || v.get<long long>() < 1 || v.get<long long>() > 65536)
        return "\"" + key + "\": expected an integer number of pixels in 1..65536";
      dst = v.get<int>();
      return {};
    };
    std::string e;
    if (key == "eye")
      e = vec3(c.eye);
    else if (key == "target")
      e = vec3(c.target);
    else if (key == "up")
      e = vec3(c.up);
    else if (key == "fov_y_deg")
      e = number(c.fov_y_deg);
    else if (key == "near")
      e = number(c.near_plane);
    else if (key == "far")
      e = number(c.far_plane);
    else if (key == "width")
      e = integer(c.width);
    else if (key == "height")
      e = integer(c.height);
    else
      e = "unknown key \"" + key + "\" (expected eye, target, up, fov_y_deg, near, far, width, height)";
    if (!e.empty()) return fail(e);
  }
  if (Status s = validate_camera(c); !s) return fail(s.error().substr(s.error().find(": ") + 2));
  return c;
}

Result<Camera> read_camera(const std::filesystem::path& path) {
  auto text = slurp(path);
  if (!text) return Result<Camera>::failure(text.error());
  return parse_camera(text.value(), path.string());
}

std::string camera_json(const Camera& c) {
  nlohmann::json j = {{"eye", {c.eye[0], c.eye[1], c.eye[2]}},
                      {"target", {c.target[0], c.target[1], c.target[2]}},
                      {"up", {c.up[0], c.up[1], c.up[2]}},
                      {"fov_y_deg", c.fov_y_deg},
                      {"near", c.near_plane},
                      {"far", c.far_plane},
                      {"width", c.width},
                      {"height", c.height}};
  return j.dump(2) + "\n";
}

Status write_text(const std::filesystem::path& path, std::string_view text) {
  std::error_code ec;
  if (path.has_parent_path()) std::filesystem::create_directories(path.parent_path(), ec);
  std::ofstream out(path, std::ios::binary);
  if (!out) return Status::failure(path.string() + ": cannot open for writing");
  out.write(text.data(), static_cast<std::streamsize>(text.size()));
  out.close();
  if (!out) return Status::failure(path.string() + ": write failed");
  return {};
}

Status write_spheres_csv(const std::filesystem::path& path, std::span<const Sphere> spheres) {
  std::string s = "x,y,z,r\n";
  char buf[128];
  for (const Sphere& sp : spheres) {
    std::snprintf(buf, sizeof buf, "%.9g,%.9g,%.9g,%.9g\n", static_cast<double>(sp.x), static_cast<double>(sp.y),
                  static_cast<double>(sp.z), static_cast<double>(sp.r));
    s += buf;
  }
  return write_text(path, s);
}

Status write_pairs_csv(const std::filesystem::path& path, std::span<const Pair> pairs) {
  std::string s = "i,j\n";
  s.reserve(s.size() + pairs.size() * 14);
  char buf[32];
  for (const Pair& p : pairs) {
    auto* end = std::to_chars(buf, buf + 12, p.i).ptr;
    *end++ = ',';
    end = std::to_chars(end, buf + 30, p.j).ptr;
    *end++ = '\n';
    s.append(buf, end);
  }
  return write_text(path, s);
}

std::string stats_json(const FrameStats& st, std::string_view backend) {
  nlohmann::ordered_json j;
  j["backend"] = backend;
  j["objects"] = st.objects;
  j["active"] = st.active;
  j["mean_pixels"] = st.has_camera ? nlohmann::ordered_json(st.mean_pixels) : nlohmann::ordered_json(nullptr);
  j["bits"] = st.bits;
  j["layout"] = st.layout;
  j["pairs"] = st.pairs;
  nlohmann::ordered_json ms;
  for (std::size_t s = 0; s < kStageCount; ++s) ms[std::string(stage_name(static_cast<Stage>(s)))] = st.stage_ms[s];
  j["stage_ms"] = ms;
  j["total_ms"] = st.total_ms();
  return j.dump(2) + "\n";
}

Status write_png(const std::filesystem::path& path, std::span<const std::uint8_t> rgba, int width, int height) {
  if (width < 1 || height < 1 || rgba.size() != static_cast<std::size_t>(width) * height * 4)
    return Status::failure(path.string() + ": image size does not match its pixels");
  std::error_code ec;
  if (path.has_parent_path()) std::filesystem::create_directories(path.parent_path(), ec);
  if (!stbi_write_png(path.string().c_str(), width, height, 4, rgba.data(), width * 4))
    return Status::failure(path.string() + ": cannot write PNG");
  return {};
}

std::uint64_t pairs_hash(std::span<const Pair> pairs) {
  std::uint64_t h = 0xcbf29ce484222325ull;
  for (const Pair& p : pairs) {
    for (std::uint32_t v : {p.i, p.j})
      for (int b = 0; b < 4; ++b) {
        h ^= (v >> (8 * b)) & 0xFF;
        h *= 0x100000001b3ull;
      }
  }
  return h;
}

}  // namespace viscd
