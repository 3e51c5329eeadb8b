#pragma once
/// \file result.hpp
/// `Status` and `Result<T>`: success, or an error kind an engine can branch on and a message a
/// person can read. No exception crosses the viscd API; broken preconditions are asserts
/// (see assert.hpp).

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <utility>

namespace viscd {

/// Why an operation failed.
enum class ErrorKind : std::uint8_t {
  none,               ///< not failed
  invalid_input,      ///< the input breaks a rule every backend applies (a NaN, a bad camera, a bad file)
  unsupported_input,  ///< valid input this backend or build does not take (a gl texture on cpu, gl not built)
  pair_cap,           ///< the frame's pairs would exceed Config::pair_memory_cap
  out_of_memory,      ///< memory ran out (the message names the frame's size)
  backend_failure,    ///< the backend itself failed: no OpenGL context, a shader that does not build, a GL error
  io_failure,         ///< a file could not be opened, read or written (the tools' readers and writers)
};

/// Short lowercase name of an error kind ("invalid_input", ...).
[[nodiscard]] constexpr std::string_view error_kind_name(ErrorKind kind) {
  switch (kind) {
    case ErrorKind::none:
      return "none";
    case ErrorKind::invalid_input:
      return "invalid_input";
    case ErrorKind::unsupported_input:
      return "unsupported_input";
    case ErrorKind::pair_cap:
      return "pair_cap";
    case ErrorKind::out_of_memory:
      return "out_of_memory";
    case ErrorKind::backend_failure:
      return "backend_failure";
    case ErrorKind::io_failure:
      return "io_failure";
  }
  return "unknown";
}

/// Success or an error kind with a message, for operations that return nothing.
class [[nodiscard]] Status {
 public:
  Status() = default;
  /// A failure of `kind` (not ErrorKind::none) with `message` (one sentence, no trailing newline).
  static Status failure(ErrorKind kind, std::string message) {
    Status s;
    s.kind_ = kind == ErrorKind::none ? ErrorKind::backend_failure : kind;
    s.error_ = std::move(message);
    return s;
  }
  [[nodiscard]] bool ok() const { return kind_ == ErrorKind::none; }
  explicit operator bool() const { return ok(); }
  /// What kind of failure; ErrorKind::none when ok().
  [[nodiscard]] ErrorKind kind() const { return kind_; }
  /// The message; empty when ok().
  [[nodiscard]] const std::string& error() const { return error_; }

 private:
  ErrorKind kind_ = ErrorKind::none;
  std::string error_;
};

/// Either a value of type T or a failure (kind and message). Check `ok()` before `value()`.
template <class T>
class [[nodiscard]] Result {
 public:
  Result(T value) : value_(std::move(value)) {}  // NOLINT(google-explicit-constructor): ergonomic returns
  /// A failed result: `kind` (not ErrorKind::none) and `message`.
  static Result failure(ErrorKind kind, std::string message) {
    Result r;
    r.status_ = Status::failure(kind, std::move(message));
    return r;
  }
  /// A failed result carrying a failed Status's kind and message.
  static Result failure(const Status& status) { return failure(status.kind(), status.error()); }
  [[nodiscard]] bool ok() const { return value_.has_value(); }
  explicit operator bool() const { return ok(); }
  [[nodiscard]] const T& value() const& { return *value_; }
  [[nodiscard]] T& value() & { return *value_; }
  [[nodiscard]] T&& value() && { return std::move(*value_); }
  /// What kind of failure; ErrorKind::none when ok().
  [[nodiscard]] ErrorKind kind() const { return status_.kind(); }
  /// The error message; empty when ok().
  [[nodiscard]] const std::string& error() const { return status_.error(); }
  /// The failure as a Status (ok() when this holds a value).
  [[nodiscard]] const Status& status() const { return status_; }

 private:
  Result() = default;
  std::optional<T> value_;
  Status status_;
};

}  // namespace viscd
