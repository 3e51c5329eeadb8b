#include "viscd/io.hpp"

#include "viscd/detector.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <nlohmann/json.hpp>

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
  return printable(source, 200) + ":" + std::to_string(line) + ": ";
}

// The system's reason for the last failed call, e.g. "No such file or directory".
std::string reason(int error) { return std::strerror(error); }

// A UTF-8 byte-order mark at the start of a file carries no data.
std::string_view skip_bom(std::string_view text) { return text.starts_with("\xEF\xBB\xBF") ? text.substr(3) : text; }

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

// Parses one number field named `name` (x, minx, ...): finite, within kMaxCoordinate. On error
// returns the message (without location).
std::string parse_number(std::string_view field, std::string_view name, float& v) {
  std::string_view t = field;
  if (!t.empty() && t[0] == '+') t.remove_prefix(1);
  auto [ptr, ec] = std::from_chars(t.data(), t.data() + t.size(), v);
  if (ec == std::errc::result_out_of_range) {
    // Underflow (e.g. 1e-46) rounds to zero like any other decimal; overflow is an error.
    double d = 0;
    const auto [dptr, dec] = std::from_chars(t.data(), t.data() + t.size(), d);
    if (dec != std::errc() || dptr != t.data() + t.size() || std::fabs(d) >= 1.0)
      return std::string(name) + " = '" + printable(field) + "' is out of float range";
    v = static_cast<float>(d);
    ptr = dptr;
    ec = std::errc();
  }
  if (ec != std::errc() || ptr != t.data() + t.size() || t.empty())
    return std::string(name) + ": expected a number, found '" + printable(field) + "'";
  if (!std::isfinite(v))
    return std::string(name) + " = " + printable(field) + " is not finite (NaN and infinity are not allowed)";
  if (std::fabs(v) > kMaxCoordinate)
    return std::string(name) + " = " + printable(field) + " exceeds the supported magnitude 1e18";
  return {};
}

// Parses the four fields of a sphere; on error returns the message (without location).
std::string parse_sphere(std::span<const std::string_view> f, Sphere& s) {
  if (f.size() != 4)
    return "expected 4 numbers `x y z r`, found " + std::to_string(f.size()) + " field" + (f.size() == 1 ? "" : "s");
  float v[4];
  static constexpr std::string_view kName[4] = {"x", "y", "z", "r"};
  for (std::size_t c = 0; c < 4; ++c)
    if (std::string e = parse_number(f[c], kName[c], v[c]); !e.empty()) return e;
  if (v[3] < 0) return "r = " + printable(f[3]) + " is negative (a radius must be >= 0)";
  s = Sphere{v[0], v[1], v[2], v[3]};
  return {};
}

// Parses the six fields of a box; on error returns the message (without location).
std::string parse_box(std::span<const std::string_view> f, Box& b) {
  if (f.size() != 6)
    return "expected 6 numbers `minx,miny,minz,maxx,maxy,maxz`, found " + std::to_string(f.size()) + " field" +
           (f.size() == 1 ? "" : "s");
  float v[6];
  static constexpr std::string_view kName[6] = {"minx", "miny", "minz", "maxx", "maxy", "maxz"};
  for (std::size_t c = 0; c < 6; ++c)
    if (std::string e = parse_number(f[c], kName[c], v[c]); !e.empty()) return e;
  for (std::size_t k = 0; k < 3; ++k)
    if (v[k] > v[k + 3])
      return std::string(kName[k]) + " = " + printable(f[k]) + " exceeds " + std::string(kName[k + 3]) + " = " +
             printable(f[k + 3]) + " (a box needs min <= max on every axis)";
  b = Box{{v[0], v[1], v[2]}, {v[3], v[4], v[5]}};
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
  using R = Result<std::string>;
  const std::string name = printable(path.string(), 200);
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return R::failure(ErrorKind::io_failure, name + ": cannot open for reading: " + reason(errno));
  struct stat st {};
  if (::fstat(fd, &st) == 0 && S_ISDIR(st.st_mode)) {
    ::close(fd);
    return R::failure(ErrorKind::invalid_input, name + ": is a folder, expected a file");
  }
  std::string text;
  if (S_ISREG(st.st_mode) && st.st_size > 0) text.reserve(static_cast<std::size_t>(st.st_size));
  char buf[1 << 16];
  for (;;) {
    const ssize_t got = ::read(fd, buf, sizeof buf);
    if (got == 0) break;
    if (got < 0) {
      if (errno == EINTR) continue;
      const int e = errno;
      ::close(fd);
      return R::failure(ErrorKind::io_failure, name + ": read error: " + reason(e));
    }
    text.append(buf, static_cast<std::size_t>(got));
  }
  ::close(fd);
  return text;
}

}  // namespace

std::string printable(std::string_view text, std::size_t max_chars) {
  std::string out;
  std::size_t chars = 0;
  static constexpr char kHex[] = "0123456789ABCDEF";
  for (std::size_t i = 0; i < text.size();) {
    if (chars == max_chars) {
      out += "\xE2\x80\xA6";  // …
      break;
    }
    const auto c = static_cast<unsigned char>(text[i]);
    // Length of a valid UTF-8 sequence starting here (0: not valid).
    std::size_t len = 0;
    if (c >= 0x20 && c < 0x7F) {
      len = 1;
    } else if (c >= 0xC2 && c <= 0xF4) {
      const std::size_t want = c < 0xE0 ? 2 : c < 0xF0 ? 3 : 4;
      len = want;
      for (std::size_t k = 1; k < want; ++k)
        if (i + k >= text.size() || (static_cast<unsigned char>(text[i + k]) & 0xC0) != 0x80) len = 0;
      if (len) {  // no overlong forms, surrogates or code points beyond U+10FFFF
        const auto c1 = static_cast<unsigned char>(text[i + 1]);
        if ((c == 0xE0 && c1 < 0xA0) || (c == 0xED && c1 >= 0xA0) || (c == 0xF0 && c1 < 0x90) ||
            (c == 0xF4 && c1 >= 0x90))
          len = 0;
      }
    }
    if (len) {
      out.append(text.substr(i, len));
      i += len;
    } else {
      switch (c) {
        case '\n':
          out += "\\n";
          break;
        case '\r':
          out += "\\r";
          break;
        case '\t':
          out += "\\t";
          break;
        default:
          out += "\\x";
          out += kHex[c >> 4];
          out += kHex[c & 15];
      }
      ++i;
    }
    ++chars;
  }
  return out;
}

SpheresResult parse_xyzr(std::string_view text, std::string_view source) {
  text = skip_bom(text);
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
  if (!error.empty()) return SpheresResult::failure(ErrorKind::invalid_input, error);
  return out;
}

namespace {

// A group or mask field: an unsigned 32-bit integer, decimal or 0x hex. Returns the message on error.
std::string parse_filter_field(std::string_view field, const char* name, std::uint32_t& v) {
  std::string_view t = field;
  int base = 10;
  if (t.size() > 2 && t[0] == '0' && (t[1] == 'x' || t[1] == 'X')) {
    t.remove_prefix(2);
    base = 16;
  }
  std::uint64_t wide = 0;
  const auto [ptr, ec] = std::from_chars(t.data(), t.data() + t.size(), wide, base);
  if (t.empty() || ptr != t.data() + t.size() || (ec != std::errc() && ec != std::errc::result_out_of_range))
    return std::string(name) + ": expected an unsigned 32-bit integer (decimal, or hexadecimal as 0x...), found '" +
           printable(field) + "'";
  if (ec == std::errc::result_out_of_range || wide > 0xFFFFFFFFu)
    return std::string(name) + " = " + printable(field) + " does not fit in 32 bits (at most 4294967295 = 0xFFFFFFFF)";
  v = static_cast<std::uint32_t>(wide);
  return {};
}

// An object CSV's columns: the shape's own (x,y,z,r or minx,...,maxz), then optionally group,mask,
// then optionally always_active. `other` names the other kind's first column and the kind, so
// that a file of the other kind is called that in the header's error.
struct ObjectColumns {
  std::span<const std::string_view> shape;
  std::string_view other_first;  // "minx" for a sphere file, "x" for a box file
  std::string_view other_file;   // "a box file, where spheres were expected"
};

constexpr std::string_view kSphereColumns[] = {"x", "y", "z", "r"};
constexpr std::string_view kBoxColumns[] = {"minx", "miny", "minz", "maxx", "maxy", "maxz"};
const ObjectColumns kSphereFile{kSphereColumns, "minx", "a box file, where spheres were expected"};
const ObjectColumns kBoxFile{kBoxColumns, "x", "a sphere file, where boxes were expected"};

// Reads an object CSV into shapes, filters and always_active flags; `parse` reads a shape's own
// fields (and gives the count message when there are no other columns). Returns the error with
// its location, or nothing.
template <class Shape, class Parse>
std::string parse_object_csv(std::string_view text, std::string_view source, const ObjectColumns& cols, Parse parse,
                             std::vector<Shape>& shapes, std::vector<Filter>& filters,
                             std::vector<std::uint8_t>& always_active) {
  text = skip_bom(text);
  std::string error;
  bool header = false, with_filters = false, with_always = false;
  const std::size_t own = cols.shape.size();
  std::size_t columns = own;
  std::string shape_header;
  for (const std::string_view name : cols.shape) shape_header += (shape_header.empty() ? "" : ",") + std::string(name);
  std::string header_text = shape_header;
  for_each_line(text, [&](std::string_view line, std::size_t no) {
    if (trim(line).empty()) return true;
    const auto fields = split(line, ",", false);
    if (!header) {
      // The shape's columns, then optionally group,mask, then optionally always_active.
      const bool shape = fields.size() >= own && std::equal(cols.shape.begin(), cols.shape.end(), fields.begin());
      std::size_t at = own;
      with_filters = shape && fields.size() >= own + 2 && fields[own] == "group" && fields[own + 1] == "mask";
      if (with_filters) at = own + 2;
      with_always = shape && fields.size() == at + 1 && fields[at] == "always_active";
      if (with_always) ++at;
      if (!shape || fields.size() != at) {
        error = where(source, no) + "expected the header `" + shape_header + "` or `" + shape_header +
                ",group,mask`, either optionally followed by `,always_active`, found '" + printable(trim(line)) + "'";
        if (!fields.empty() && fields[0] == cols.other_first) error += ": " + std::string(cols.other_file);
        return false;
      }
      columns = at;
      header_text = shape_header + (with_filters ? ",group,mask" : "") + (with_always ? ",always_active" : "");
      header = true;
      return true;
    }
    Shape s;
    Filter f;
    std::uint8_t always = 0;
    std::string e;
    if (columns == own)
      e = parse(fields, s);  // its own message for a wrong count: "expected 4 numbers"
    else if (fields.size() != columns)
      e = "expected " + std::to_string(columns) + " fields `" + header_text + "`, found " +
          std::to_string(fields.size());
    else
      e = parse(std::span<const std::string_view>(fields).first(own), s);
    if (e.empty() && with_filters) e = parse_filter_field(fields[own], "group", f.group);
    if (e.empty() && with_filters) e = parse_filter_field(fields[own + 1], "mask", f.mask);
    if (e.empty() && with_always) {
      const std::string_view v = trim(fields[columns - 1]);
      if (v == "0" || v == "1")
        always = v == "1" ? 1 : 0;
      else
        e = "always_active: expected 0 or 1, found '" + printable(fields[columns - 1]) + "'";
    }
    if (!e.empty()) {
      error = where(source, no) + e;
      return false;
    }
    shapes.push_back(s);
    if (with_filters) filters.push_back(f);
    if (with_always) always_active.push_back(always);
    return true;
  });
  return error;
}

// The first field of the first line that is neither blank nor a comment (an XYZR `#`): a CSV's
// header or an XYZR file's first sphere, with its 1-based line; line 0 when there is none.
std::pair<std::string_view, std::size_t> first_field(std::string_view text) {
  std::pair<std::string_view, std::size_t> found{{}, 0};
  for_each_line(skip_bom(text), [&](std::string_view line, std::size_t no) {
    if (trim(line).empty() || trim(line).starts_with('#')) return true;
    found = {split(line, ",", false).front(), no};
    return false;
  });
  return found;
}

}  // namespace

Result<SphereTable> parse_sphere_table(std::string_view text, std::string_view source) {
  SphereTable out;
  if (std::string e =
          parse_object_csv(text, source, kSphereFile, parse_sphere, out.spheres, out.filters, out.always_active);
      !e.empty())
    return Result<SphereTable>::failure(ErrorKind::invalid_input, e);
  return out;
}

Result<BoxTable> parse_box_table(std::string_view text, std::string_view source) {
  BoxTable out;
  if (std::string e = parse_object_csv(text, source, kBoxFile, parse_box, out.boxes, out.filters, out.always_active);
      !e.empty())
    return Result<BoxTable>::failure(ErrorKind::invalid_input, e);
  return out;
}

SpheresResult parse_csv(std::string_view text, std::string_view source) {
  auto table = parse_sphere_table(text, source);
  if (!table) return SpheresResult::failure(table.status());
  return std::move(table.value().spheres);
}

SpheresResult read_spheres(const std::filesystem::path& path) {
  auto text = slurp(path);
  if (!text) return SpheresResult::failure(text.status());
  if (path.extension() == ".csv") return parse_csv(text.value(), path.string());
  return parse_xyzr(text.value(), path.string());
}

namespace {
// A sphere file's text by its name: `.csv` as parse_sphere_table, anything else XYZR (no filters).
Result<SphereTable> read_sphere_table_text(std::string_view text, const std::filesystem::path& path) {
  if (path.extension() == ".csv") return parse_sphere_table(text, path.string());
  auto spheres = parse_xyzr(text, path.string());
  if (!spheres) return Result<SphereTable>::failure(spheres.status());
  return SphereTable{std::move(spheres.value()), {}, {}};
}
}  // namespace

Result<SphereTable> read_sphere_table(const std::filesystem::path& path) {
  auto text = slurp(path);
  if (!text) return Result<SphereTable>::failure(text.status());
  return read_sphere_table_text(text.value(), path);
}

Result<BoxTable> read_box_table(const std::filesystem::path& path) {
  auto text = slurp(path);
  if (!text) return Result<BoxTable>::failure(text.status());
  return parse_box_table(text.value(), path.string());
}

Result<ObjectTable> read_object_table(const std::filesystem::path& path) {
  using R = Result<ObjectTable>;
  auto text = slurp(path);
  if (!text) return R::failure(text.status());
  ObjectTable out;
  const auto [first, line] = first_field(text.value());
  out.kind_line = line;
  if (first == kBoxColumns[0]) {  // a box header, whatever the extension: boxes have no XYZR form
    auto boxes = parse_box_table(text.value(), path.string());
    if (!boxes) return R::failure(boxes.status());
    out.kind = ShapeKind::box;
    out.boxes = std::move(boxes.value());
    return out;
  }
  auto spheres = read_sphere_table_text(text.value(), path);
  if (!spheres) return R::failure(spheres.status());
  out.spheres = std::move(spheres.value());
  return out;
}

Result<Camera> parse_camera(std::string_view text, std::string_view source) {
  using nlohmann::json;
  text = skip_bom(text);
  json j;
  try {
    j = json::parse(text);
  } catch (const json::exception& e) {
    // nlohmann's message reads "[json.exception.parse_error.101] parse error at line 3, column 7:
    // syntax error while parsing value - invalid literal; last read: '1e4x'". Keep what follows
    // the prefix and the position, and give the position our way: file:line:column.
    std::string at;
    if (const auto* pe = dynamic_cast<const json::parse_error*>(&e)) {
      std::size_t line = 1, column = 1;
      const std::size_t byte = std::min<std::size_t>(pe->byte, text.size());
      for (std::size_t i = 0; i + 1 < byte; ++i) {
        if (text[i] == '\n') {
          ++line;
          column = 1;
        } else {
          ++column;
        }
      }
      at = ":" + std::to_string(line) + ":" + std::to_string(column);
    }
    std::string what = e.what();
    if (const auto bracket = what.find("] "); what.starts_with("[json.exception") && bracket != std::string::npos)
      what.erase(0, bracket + 2);
    if (what.starts_with("parse error")) {
      const auto colon = what.find(": ");
      if (colon != std::string::npos) what.erase(0, colon + 2);
    }
    return Result<Camera>::failure(ErrorKind::invalid_input,
                                   printable(source, 200) + at + ": invalid JSON: " + printable(what, 200));
  }
  auto fail = [&](const std::string& m) {
    return Result<Camera>::failure(ErrorKind::invalid_input, printable(source, 200) + ": " + m);
  };
  if (!j.is_object()) return fail("expected a JSON object {\"eye\": [x,y,z], ...}");
  Camera c;
  for (auto it = j.begin(); it != j.end(); ++it) {
    const std::string key = printable(it.key());
    const json& v = it.value();
    // A JSON number as float: finite, and within what the camera accepts.
    auto to_float = [&](const json& x, float& dst) -> bool {
      // Compared as float, as the spheres' bound is: 1e18 itself rounds to the float 1e18f.
      const double d = x.get<double>();
      if (!(std::fabs(d) <= 1e30)) return false;
      dst = static_cast<float>(d);
      return std::fabs(dst) <= kMaxCoordinate;
    };
    auto vec3 = [&](float* dst) -> std::string {
      if (!v.is_array() || v.size() != 3 || !v[0].is_number() || !v[1].is_number() || !v[2].is_number())
        return "\"" + key + "\": expected an array of 3 numbers [x, y, z]";
      for (std::size_t k = 0; k < 3; ++k)
        if (!to_float(v[k], dst[k]))
          return "\"" + key + "\": " + printable(v[k].dump()) + " is beyond the supported magnitude 1e18";
      return {};
    };
    auto number = [&](float& dst) -> std::string {
      if (!v.is_number()) return "\"" + key + "\": expected a number";
      if (!to_float(v, dst))
        return "\"" + key + "\": " + printable(v.dump()) + " is beyond the supported magnitude 1e18";
      return {};
    };
    auto integer = [&](int& dst) -> std::string {
      // is_number_integer covers unsigned values too; one beyond INT64_MAX reads as negative.
      const bool in_range = v.is_number_integer() && v.get<std::int64_t>() >= 1 && v.get<std::int64_t>() <= 65536;
      if (!in_range) return "\"" + key + "\": expected an integer number of pixels in 1..65536";
      dst = static_cast<int>(v.get<std::int64_t>());
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
  if (!text) return Result<Camera>::failure(text.status());
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

// ---- AtomicFile ----

struct AtomicFile::State {
  std::filesystem::path path;       // the destination
  std::filesystem::path temporary;  // beside it, same file system, so rename is atomic
  int fd = -1;
  std::string error;  // the first failure
  bool committed = false;
};

AtomicFile::AtomicFile(std::unique_ptr<State> state) : state_(std::move(state)) {}
AtomicFile::AtomicFile(AtomicFile&&) noexcept = default;
AtomicFile& AtomicFile::operator=(AtomicFile&&) noexcept = default;

AtomicFile::~AtomicFile() {
  if (!state_) return;
  if (state_->fd >= 0) ::close(state_->fd);
  if (!state_->committed) ::unlink(state_->temporary.c_str());
}

const std::filesystem::path& AtomicFile::path() const { return state_->path; }

Result<AtomicFile> AtomicFile::create(const std::filesystem::path& path) {
  namespace fs = std::filesystem;
  using R = Result<AtomicFile>;
  const std::string name = printable(path.string(), 200);
  std::error_code ec;
  fs::path dest = path;
  if (fs::is_symlink(dest, ec)) {  // write where the link points, as an ordinary open would
    const fs::path target = fs::weakly_canonical(dest, ec);
    if (!ec) dest = target;
  }
  if (fs::is_directory(dest, ec))
    return R::failure(ErrorKind::invalid_input, name + ": is a folder, expected a file name");
  if (dest.filename().empty()) return R::failure(ErrorKind::invalid_input, name + ": expected a file name");
  const fs::path dir = dest.has_parent_path() ? dest.parent_path() : fs::path(".");
  fs::create_directories(dir, ec);
  if (ec) return R::failure(ErrorKind::io_failure, name + ": cannot create its folder: " + ec.message());
  std::string tmpl = (dir / ("." + dest.filename().string() + ".tmp-XXXXXX")).string();
  const int fd = ::mkostemp(tmpl.data(), O_CLOEXEC);
  if (fd < 0) return R::failure(ErrorKind::io_failure, name + ": cannot open for writing: " + reason(errno));
  // mkostemp creates the file private (0600); give it the mode an ordinary new file would get.
  const mode_t mask = ::umask(0);
  ::umask(mask);
  if (::fchmod(fd, 0666 & ~mask) != 0) {
    const int e = errno;
    ::close(fd);
    ::unlink(tmpl.c_str());
    return R::failure(ErrorKind::io_failure, name + ": cannot set the file mode: " + reason(e));
  }
  auto state = std::make_unique<State>();
  state->path = dest;
  state->temporary = tmpl;
  state->fd = fd;
  return AtomicFile(std::move(state));
}

Status AtomicFile::write(std::string_view bytes) {
  State& st = *state_;
  if (!st.error.empty()) return Status::failure(ErrorKind::io_failure, st.error);
  while (!bytes.empty()) {
    const ssize_t put = ::write(st.fd, bytes.data(), bytes.size());
    if (put < 0) {
      if (errno == EINTR) continue;
      st.error = printable(st.path.string(), 200) + ": write failed: " + reason(errno);
      return Status::failure(ErrorKind::io_failure, st.error);
    }
    bytes.remove_prefix(static_cast<std::size_t>(put));
  }
  return {};
}

Status AtomicFile::commit() {
  State& st = *state_;
  if (!st.error.empty()) return Status::failure(ErrorKind::io_failure, st.error);
  if (st.committed) return {};
  const std::string name = printable(st.path.string(), 200);
  const bool synced = ::fsync(st.fd) == 0 || errno == EINVAL;  // EINVAL: a file system without fsync
  const int sync_errno = errno;
  const bool closed = ::close(st.fd) == 0;
  const int close_errno = errno;
  st.fd = -1;
  if (!synced) st.error = name + ": write failed: " + reason(sync_errno);
  if (synced && !closed) st.error = name + ": write failed: " + reason(close_errno);
  if (st.error.empty() && ::rename(st.temporary.c_str(), st.path.c_str()) != 0)
    st.error = name + ": cannot replace the file: " + reason(errno);
  if (!st.error.empty()) return Status::failure(ErrorKind::io_failure, st.error);
  st.committed = true;
  return {};
}

namespace {
// Creates the AtomicFile, lets `fill` write it, commits it: every path-taking writer below.
template <class F>
Status write_whole(const std::filesystem::path& path, F&& fill) {
  auto f = AtomicFile::create(path);
  if (!f) return f.status();
  if (Status s = fill(f.value()); !s) return s;
  return f.value().commit();
}
}  // namespace

Status write_text(const std::filesystem::path& path, std::string_view text) {
  return write_whole(path, [&](AtomicFile& f) { return f.write(text); });
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

Status write_boxes_csv(const std::filesystem::path& path, std::span<const Box> boxes) {
  std::string s = "minx,miny,minz,maxx,maxy,maxz\n";
  char buf[192];
  for (const Box& b : boxes) {
    std::snprintf(buf, sizeof buf, "%.9g,%.9g,%.9g,%.9g,%.9g,%.9g\n", static_cast<double>(b.min[0]),
                  static_cast<double>(b.min[1]), static_cast<double>(b.min[2]), static_cast<double>(b.max[0]),
                  static_cast<double>(b.max[1]), static_cast<double>(b.max[2]));
    s += buf;
  }
  return write_text(path, s);
}

Status write_pairs_csv(AtomicFile& out, std::span<const Pair> pairs) {
  // Streamed in blocks of about 1 MiB: a billion pairs need no gigabytes of text in memory.
  constexpr std::size_t kBlock = 1 << 20;
  std::string s = "i,j\n";
  s.reserve(kBlock + 32);
  char buf[32];
  for (const Pair& p : pairs) {
    auto* end = std::to_chars(buf, buf + 12, p.i).ptr;
    *end++ = ',';
    end = std::to_chars(end, buf + 30, p.j).ptr;
    *end++ = '\n';
    s.append(buf, end);
    if (s.size() >= kBlock) {
      if (Status st = out.write(s); !st) return st;
      s.clear();
    }
  }
  return out.write(s);
}

Status write_pairs_csv(const std::filesystem::path& path, std::span<const Pair> pairs) {
  return write_whole(path, [&](AtomicFile& f) { return write_pairs_csv(f, pairs); });
}

std::string stats_json(const FrameStats& st, std::string_view backend) {
  nlohmann::ordered_json j;
  j["backend"] = backend;
  j["objects"] = st.objects;
  j["static_objects"] = st.static_objects;
  j["active"] = st.active;
  j["mean_pixels"] =
      st.has_pixels || st.has_camera ? nlohmann::ordered_json(st.mean_pixels) : nlohmann::ordered_json(nullptr);
  j["bits"] = st.bits;
  j["layout"] = format_layout(st.layout);
  j["pairs"] = st.pairs;
  nlohmann::ordered_json ms;
  for (std::size_t s = 0; s < kStageCount; ++s) ms[std::string(stage_name(static_cast<Stage>(s)))] = st.stage_ms[s];
  j["stage_ms"] = ms;
  j["total_ms"] = st.total_ms();
  return j.dump(2) + "\n";
}

Status write_png(AtomicFile& out, std::span<const std::uint8_t> rgba, int width, int height) {
  if (width < 1 || height < 1 || rgba.size() != static_cast<std::size_t>(width) * height * 4)
    return Status::failure(ErrorKind::invalid_input,
                           printable(out.path().string(), 200) + ": image size does not match its pixels");
  struct Sink {
    AtomicFile* file;
    Status status;
  } sink{&out, {}};
  auto put = [](void* context, void* data, int size) {
    auto* k = static_cast<Sink*>(context);
    if (k->status.ok()) k->status = k->file->write({static_cast<const char*>(data), static_cast<std::size_t>(size)});
  };
  if (!stbi_write_png_to_func(put, &sink, width, height, 4, rgba.data(), width * 4))
    return Status::failure(ErrorKind::io_failure, printable(out.path().string(), 200) + ": cannot encode the PNG");
  return sink.status;
}

Status write_png(const std::filesystem::path& path, std::span<const std::uint8_t> rgba, int width, int height) {
  return write_whole(path, [&](AtomicFile& f) { return write_png(f, rgba, width, height); });
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
