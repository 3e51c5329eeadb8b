// Output safety: where two names lead to the same file, and the staged folder's exchange.
#include "outputs.hpp"

#include <fcntl.h>
#include <stdlib.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>

#include "viscd/io.hpp"

namespace viscd::app {

Status check_outputs(const std::vector<NamedPath>& inputs, const std::vector<NamedPath>& outputs) {
  namespace fs = std::filesystem;
  std::error_code ec;
  auto same = [&](const fs::path& a, const fs::path& b) {
    if (fs::exists(a, ec) && fs::exists(b, ec)) return fs::equivalent(a, b, ec);
    // A file that does not exist yet: compare where the two names lead.
    const fs::path ca = fs::weakly_canonical(fs::absolute(a, ec), ec);
    const fs::path cb = fs::weakly_canonical(fs::absolute(b, ec), ec);
    return !ca.empty() && ca == cb;
  };
  for (std::size_t k = 0; k < outputs.size(); ++k) {
    const NamedPath& out = outputs[k];
    const std::string shown = printable(out.path.string(), 200);
    if (out.path.empty()) return Status::failure(ErrorKind::invalid_input, out.option + ": expected a file name");
    if (fs::is_directory(out.path, ec))
      return Status::failure(ErrorKind::invalid_input,
                             out.option + " " + shown + ": is a folder, expected a file name");
    for (const NamedPath& in : inputs)
      if (!in.path.empty() && same(in.path, out.path))
        return Status::failure(ErrorKind::invalid_input, out.option + " " + shown + " is the same file as " +
                                                             in.option + " " + printable(in.path.string(), 200) +
                                                             ": refusing to overwrite an input");
    for (std::size_t j = 0; j < k; ++j)
      if (same(outputs[j].path, out.path))
        return Status::failure(ErrorKind::invalid_input,
                               out.option + " and " + outputs[j].option + " name the same file " + shown);
  }
  return {};
}

Status check_folder_output(const NamedPath& folder, const std::vector<NamedPath>& others) {
  namespace fs = std::filesystem;
  std::error_code ec;
  const std::string shown = printable(folder.path.string(), 200);
  if (folder.path.empty()) return Status::failure(ErrorKind::invalid_input, folder.option + ": expected a folder name");
  if (fs::exists(folder.path, ec) && !fs::is_directory(folder.path, ec))
    return Status::failure(ErrorKind::invalid_input, folder.option + " " + shown + ": is a file, expected a folder");
  // Where a name leads (through links, also for names that do not exist yet), without a trailing "/".
  auto where = [&](const fs::path& x) {
    fs::path c = fs::weakly_canonical(fs::absolute(x, ec), ec).lexically_normal();
    if (!c.has_filename() && c != c.root_path()) c = c.parent_path();
    return c;
  };
  const fs::path dir = where(folder.path);
  for (const NamedPath& other : others) {
    if (other.path.empty()) continue;
    const fs::path p = where(other.path);
    if (std::mismatch(dir.begin(), dir.end(), p.begin(), p.end()).first == dir.end())
      return Status::failure(ErrorKind::invalid_input, other.option + " " + printable(other.path.string(), 200) +
                                                           " lies in " + folder.option + " " + shown +
                                                           ", which is replaced as a whole: name a file elsewhere");
  }
  return {};
}

Result<StagedFolder> StagedFolder::create(const std::filesystem::path& dest, const std::string& option,
                                          std::string_view prefix, std::string_view suffix) {
  namespace fs = std::filesystem;
  using R = Result<StagedFolder>;
  std::error_code ec;
  const std::string shown = printable(dest.string(), 200);
  if (fs::exists(dest, ec)) {
    if (!fs::is_directory(dest, ec))
      return R::failure(ErrorKind::invalid_input, option + " " + shown + ": is a file, expected a folder");
    for (const auto& entry : fs::directory_iterator(dest, ec)) {
      const std::string name = entry.path().filename().string();
      if (!entry.is_regular_file(ec) || !name.starts_with(prefix) || !name.ends_with(suffix))
        return R::failure(ErrorKind::invalid_input,
                          option + " " + shown + " holds " + printable(name, 100) + ", which is not a file " +
                              std::string(prefix) + "*" + std::string(suffix) +
                              " of an earlier run: refusing to replace the folder (name a new or empty one)");
    }
    if (ec)
      return R::failure(ErrorKind::io_failure, option + " " + shown + ": cannot list the folder: " + ec.message());
  }
  const fs::path abs = fs::absolute(dest, ec);
  const fs::path parent = abs.parent_path();
  fs::create_directories(parent, ec);
  if (ec)
    return R::failure(ErrorKind::io_failure,
                      option + " " + shown + ": cannot create its parent folder: " + ec.message());
  std::string tmpl = (parent / ("." + abs.filename().string() + ".tmp-XXXXXX")).string();
  if (!::mkdtemp(tmpl.data()))
    return R::failure(ErrorKind::io_failure,
                      option + " " + shown + ": cannot create a folder beside it: " + std::strerror(errno));
  return StagedFolder(abs, tmpl);
}

StagedFolder::StagedFolder(StagedFolder&& o) noexcept
    : dest_(std::move(o.dest_)), staging_(std::move(o.staging_)), done_(o.done_) {
  o.done_ = true;
}

StagedFolder::~StagedFolder() {
  if (done_) return;
  std::error_code ec;
  std::filesystem::remove_all(staging_, ec);
}

Status StagedFolder::commit() {
  namespace fs = std::filesystem;
  std::error_code ec;
  const std::string shown = printable(dest_.string(), 200);
  // The staged files are durable (AtomicFile syncs each); make the folder's entries so too.
  if (const int fd = ::open(staging_.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC); fd >= 0) {
    ::fsync(fd);
    ::close(fd);
  }
  if (fs::exists(dest_, ec)) {
    if (::renameat2(AT_FDCWD, staging_.c_str(), AT_FDCWD, dest_.c_str(), RENAME_EXCHANGE) == 0) {
      fs::remove_all(staging_, ec);  // now the old folder
      done_ = true;
      return {};
    }
    // No exchange on this file system: move the old folder aside, the new one in, the old one out.
    const fs::path old = staging_.string() + ".old";
    if (::rename(dest_.c_str(), old.c_str()) != 0)
      return Status::failure(ErrorKind::io_failure, shown + ": cannot replace the folder: " + std::strerror(errno));
    if (::rename(staging_.c_str(), dest_.c_str()) != 0) {
      const int e = errno;
      (void)::rename(old.c_str(), dest_.c_str());
      return Status::failure(ErrorKind::io_failure, shown + ": cannot replace the folder: " + std::strerror(e));
    }
    fs::remove_all(old, ec);
    done_ = true;
    return {};
  }
  if (::rename(staging_.c_str(), dest_.c_str()) != 0)
    return Status::failure(ErrorKind::io_failure, shown + ": cannot create the folder: " + std::strerror(errno));
  done_ = true;
  return {};
}

}  // namespace viscd::app
