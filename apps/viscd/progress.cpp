// The progress bar: redrawn in place on a terminal, a line per tenth otherwise (logs, pipes).
#include "progress.hpp"

#include <unistd.h>

#include <cstdio>
#include <utility>

namespace viscd::app {

Progress::Progress(std::string label, std::size_t total, bool quiet)
    : label_(std::move(label)), total_(total), tty_(isatty(STDERR_FILENO) != 0), quiet_(quiet) {}

void Progress::update(std::size_t done, const std::string& note) {
  if (quiet_ || total_ == 0) return;
  if (tty_) {
    constexpr int kWidth = 30;
    const int filled = static_cast<int>(kWidth * done / total_);
    std::fprintf(stderr, "\r%s [%s%s] %zu/%zu %s\x1b[K", label_.c_str(), std::string(filled, '#').c_str(),
                 std::string(kWidth - filled, ' ').c_str(), done, total_, note.c_str());
    std::fflush(stderr);
  } else {
    const int decile = static_cast<int>(10 * done / total_);
    if (decile != last_decile_) {
      last_decile_ = decile;
      std::fprintf(stderr, "%s %zu/%zu %s\n", label_.c_str(), done, total_, note.c_str());
    }
  }
}

void Progress::finish() {
  if (!quiet_ && tty_) std::fprintf(stderr, "\n");
}

}  // namespace viscd::app
