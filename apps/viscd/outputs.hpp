#pragma once
// Output safety: refusing, before anything is read or written, an output that names an input or
// another output, and a folder output (--pairs-dir) written whole or not at all (StagedFolder).
// Single output files are written whole by viscd::AtomicFile (viscd/io.hpp).

#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "viscd/result.hpp"

namespace viscd::app {

/// A file the command reads or writes, with the option that names it (for messages).
struct NamedPath {
  std::string option;
  std::filesystem::path path;
};
/// Refuses, before anything is read or written: an output that is the same file as an input
/// (also through links), two outputs naming the same file, and an output that is a folder.
[[nodiscard]] Status check_outputs(const std::vector<NamedPath>& inputs, const std::vector<NamedPath>& outputs);

/// Refuses, before anything is read or written, a folder output that will be replaced as a whole
/// (`--pairs-dir`) when any other input or output names it or lies inside it.
[[nodiscard]] Status check_folder_output(const NamedPath& folder, const std::vector<NamedPath>& others);

/// A folder written whole or not at all: files go into a hidden folder beside the destination,
/// and commit() puts it in the destination's place in one step (exchanged with an existing
/// folder, which is then removed), so a reader sees the old folder or the new one. A destination
/// that exists must be a folder holding only files whose names start with `prefix` and end with
/// `suffix` (an earlier run's): anything else is refused rather than deleted. Destroyed
/// uncommitted, it removes what it wrote. Move-only.
class StagedFolder {
 public:
  [[nodiscard]] static Result<StagedFolder> create(const std::filesystem::path& dest, const std::string& option,
                                                   std::string_view prefix, std::string_view suffix);
  StagedFolder(StagedFolder&& o) noexcept;
  StagedFolder& operator=(StagedFolder&&) = delete;
  StagedFolder(const StagedFolder&) = delete;
  ~StagedFolder();
  /// Where a file of the folder is written until commit().
  [[nodiscard]] std::filesystem::path file(std::string_view name) const { return staging_ / name; }
  [[nodiscard]] Status commit();

 private:
  StagedFolder(std::filesystem::path dest, std::filesystem::path staging)
      : dest_(std::move(dest)), staging_(std::move(staging)) {}
  std::filesystem::path dest_, staging_;
  bool done_ = false;
};

}  // namespace viscd::app
