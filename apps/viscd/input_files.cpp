// Reading the id map and the optional camera.
#include "input_files.hpp"

#include <cerrno>
#include <cstring>
#include <fstream>

#include "viscd/io.hpp"

namespace viscd::app {

Result<std::optional<Camera>> read_optional_camera(const std::string& path) {
  using R = Result<std::optional<Camera>>;
  if (path.empty()) return std::optional<Camera>{};
  auto c = read_camera(path);
  if (!c) return R::failure(c.status());
  return std::optional<Camera>(c.value());
}

Result<std::vector<std::uint32_t>> read_id_map(const std::filesystem::path& path, int width, int height) {
  using R = Result<std::vector<std::uint32_t>>;
  const std::string name = printable(path.string(), 200);
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec))
    return R::failure(ErrorKind::invalid_input, name + ": is a folder, expected a file");
  std::ifstream in(path, std::ios::binary);
  if (!in) return R::failure(ErrorKind::io_failure, name + ": cannot open for reading: " + std::strerror(errno));
  in.seekg(0, std::ios::end);
  const auto size = static_cast<std::uint64_t>(in.tellg());
  const std::uint64_t want = static_cast<std::uint64_t>(width) * static_cast<std::uint64_t>(height) * 4;
  if (size != want)
    return R::failure(ErrorKind::invalid_input, name + ": " + std::to_string(size) + " bytes, but a " +
                                                    std::to_string(width) + "x" + std::to_string(height) +
                                                    " id map of 32-bit ids has " + std::to_string(want) + " bytes");
  in.seekg(0);
  std::vector<unsigned char> bytes(static_cast<std::size_t>(size));
  if (!in.read(reinterpret_cast<char*>(bytes.data()), static_cast<std::streamsize>(size)))
    return R::failure(ErrorKind::io_failure, name + ": read error: " + std::strerror(errno));
  std::vector<std::uint32_t> ids(bytes.size() / 4);
  for (std::size_t k = 0; k < ids.size(); ++k)  // little-endian whatever the host
    ids[k] = std::uint32_t{bytes[4 * k]} | std::uint32_t{bytes[4 * k + 1]} << 8 |
             std::uint32_t{bytes[4 * k + 2]} << 16 | std::uint32_t{bytes[4 * k + 3]} << 24;
  return ids;
}

}  // namespace viscd::app
