#pragma once
// The one way anchormap reports a recoverable failure (docs/ARCHITECTURE.md, "Errors"):
//   - a call that can fail because of its input returns Status (nothing else to return)
//     or Result<T> (a value, or the Status that says why there is none);
//   - a failure carries an ErrorCode (why, counted by RejectCounter) and a one-line
//     message for a person;
//   - exceptions are for bugs only (a violated precondition the caller could have
//     checked); third-party exceptions are caught where the call is made and become a
//     Status; mains catch what is left and exit non-zero with the message.

#include <cassert>
#include <optional>
#include <string>
#include <utility>

#include "common/util/error_code.h"

namespace anchormap {

class [[nodiscard]] Status {
 public:
  Status() = default;  // ok
  static Status Ok() { return Status(); }
  static Status Error(ErrorCode code, std::string message) {
    return Status(code, std::move(message));
  }
  // A bad argument, option or file content: the common case of a configuration error.
  static Status Error(std::string message) {
    return Status(ErrorCode::kInvalidArgument, std::move(message));
  }

  bool ok() const { return !failed_; }
  ErrorCode code() const { return code_; }  // meaningful when !ok()
  const std::string& message() const { return message_; }
  // "not_finite: x is NaN", or "ok".
  std::string ToString() const;

 private:
  Status(ErrorCode code, std::string message)
      : failed_(true), code_(code), message_(std::move(message)) {}
  bool failed_ = false;
  ErrorCode code_ = ErrorCode::kInvalidArgument;
  std::string message_;
};

// A value, or the Status that says why there is none. Reading value() of a failed
// Result is a bug (asserted).
template <typename T>
class [[nodiscard]] Result {
 public:
  Result(T value) : value_(std::move(value)) {}       // NOLINT: implicit, like std::optional
  Result(Status error) : status_(std::move(error)) {  // NOLINT
    assert(!status_.ok() && "a Result without a value needs a failed Status");
    if (status_.ok()) status_ = Status::Error(ErrorCode::kInvalidArgument, "no value");
  }

  bool ok() const { return value_.has_value(); }
  const Status& status() const { return status_; }

  const T& value() const& {
    assert(ok());
    return *value_;
  }
  T& value() & {
    assert(ok());
    return *value_;
  }
  T&& value() && {
    assert(ok());
    return std::move(*value_);
  }
  const T& operator*() const& { return value(); }
  T& operator*() & { return value(); }
  const T* operator->() const { return &value(); }
  T* operator->() { return &value(); }

 private:
  std::optional<T> value_;
  Status status_;
};

}  // namespace anchormap
