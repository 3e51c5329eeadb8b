#pragma once
/// \file result.hpp
/// `Result<T>`: the value of a fallible operation or a message saying why it failed.
/// No exception crosses the viscd API; broken preconditions are asserts (see assert.hpp).

#include <optional>
#include <string>
#include <utility>

namespace viscd {

/// Either a value of type T or an error message. Check `ok()` before `value()`.
template <class T>
class [[nodiscard]] Result {
 public:
  Result(T value) : value_(std::move(value)) {}  // NOLINT(google-explicit-constructor): ergonomic returns
  /// A failed result carrying `message` (one human-readable sentence, no trailing newline).
  static Result failure(std::string message) {
    Result r;
    r.error_ = std::move(message);
    return r;
  }
  [[nodiscard]] bool ok() const { return value_.has_value(); }
  explicit operator bool() const { return ok(); }
  [[nodiscard]] const T& value() const& { return *value_; }
  [[nodiscard]] T& value() & { return *value_; }
  [[nodiscard]] T&& value() && { return std::move(*value_); }
  /// The error message; empty when ok().
  [[nodiscard]] const std::string& error() const { return error_; }

 private:
  Result() = default;
  std::optional<T> value_;
  std::string error_;
};

/// Success or an error message, for operations that return nothing.
class [[nodiscard]] Status {
 public:
  Status() = default;
  static Status failure(std::string message) {
    Status s;
    s.failed_ = true;
    s.error_ = std::move(message);
    return s;
  }
  [[nodiscard]] bool ok() const { return !failed_; }
  explicit operator bool() const { return ok(); }
  [[nodiscard]] const std::string& error() const { return error_; }

 private:
  bool failed_ = false;
  std::string error_;
};

}  // namespace viscd
