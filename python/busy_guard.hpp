#pragma once
/// \file busy_guard.hpp
/// One call at a time on a Python-side detector: the GIL is released while a call runs, so a
/// second thread could enter; the guard makes that call raise RuntimeError instead. The flag is
/// read and set with the GIL held (the guard is made before the GIL is released and ends after it
/// is taken back).
#include <stdexcept>

namespace viscd::python {

class BusyGuard {
 public:
  /// Raises RuntimeError(`message`) when `busy` is set; else sets it until the guard ends.
  BusyGuard(bool& busy, const char* message) : busy_(busy) {
    if (busy_) throw std::runtime_error(message);
    busy_ = true;
  }
  ~BusyGuard() { busy_ = false; }
  BusyGuard(const BusyGuard&) = delete;
  BusyGuard& operator=(const BusyGuard&) = delete;

 private:
  bool& busy_;
};

}  // namespace viscd::python
