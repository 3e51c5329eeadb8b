#pragma once
// The progress report of long commands (run, bench paper) on stderr.

#include <cstddef>
#include <string>

namespace viscd::app {

/// A progress bar on a terminal (stderr), plain lines every 10 % otherwise.
class Progress {
 public:
  /// `total` steps; `quiet` prints nothing.
  Progress(std::string label, std::size_t total, bool quiet);
  /// `done` of the total steps are done; `note` follows the count.
  void update(std::size_t done, const std::string& note);
  /// Ends the bar's line on a terminal; call before printing anything else.
  void finish();

 private:
  std::string label_;
  std::size_t total_;
  bool tty_, quiet_;
  int last_decile_ = -1;
};

}  // namespace viscd::app
