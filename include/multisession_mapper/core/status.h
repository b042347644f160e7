// Error reporting for the core library: functions that can fail on bad input return a Status
// (or a StatusOr<T>) with a message that names the problem, instead of throwing or logging.
// The ROS layer turns a failed Status into a ROS_ERROR; the tools print it and exit non-zero.
#pragma once

#include <optional>
#include <string>
#include <utility>

namespace multisession_mapper {
namespace core {

class Status {
 public:
  /// The success value.
  static Status Ok() { return Status(); }
  /// A failure with a message that says what is wrong and where (file, field, value).
  static Status Error(std::string message) { return Status(std::move(message)); }

  Status() = default;
  bool ok() const { return !message_.has_value(); }
  /// Empty for a success.
  const std::string& message() const {
    static const std::string kEmpty;
    return message_ ? *message_ : kEmpty;
  }
  explicit operator bool() const { return ok(); }

 private:
  explicit Status(std::string message) : message_(std::move(message)) {}
  std::optional<std::string> message_;
};

/// A value or the Status that explains why there is none.
template <typename T>
class StatusOr {
 public:
  StatusOr(T value) : value_(std::move(value)), status_(Status::Ok()) {}  // NOLINT: like absl
  StatusOr(Status status) : status_(std::move(status)) {}  // NOLINT(runtime/explicit)

  bool ok() const { return value_.has_value(); }
  /// Ok when a value is held.
  const Status& status() const { return status_; }
  const T& value() const& { return *value_; }
  T& value() & { return *value_; }
  T&& value() && { return std::move(*value_); }

 private:
  std::optional<T> value_;
  Status status_ = Status::Error("no value");
};

}  // namespace core
}  // namespace multisession_mapper
