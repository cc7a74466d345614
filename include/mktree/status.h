// Status and Result<T>: how every fallible call in mktree reports failure.
// Exceptions never cross the public API; I/O and parse paths return a Status that names the file
// (and line or page where there is one). Both are [[nodiscard]]: a dropped Status is a bug, so code that
// means to ignore one says so with (void) and a comment why.
//
//   MKTREE_RETURN_IF_ERROR(file.Sync());               // returns the Status unless it is ok
//   MKTREE_ASSIGN_OR_RETURN(auto reader, Open(path));  // reader = the Result's value, or returns its Status
#pragma once

#include <cassert>
#include <optional>
#include <string>
#include <utility>

namespace mktree {

class [[nodiscard]] Status {
 public:
  enum class Code { kOk = 0, kInvalidArgument, kNotFound, kCorruption, kIOError, kUnsupported, kInternal };

  Status() = default;
  // An ok Status has no message: copying one (MKTREE_RETURN_IF_ERROR on a named Status, once per query)
  // copies no string.
  Status(const Status& o) : code_(o.code_) {
    if (o.code_ != Code::kOk) message_ = o.message_;
  }
  Status& operator=(const Status& o) {
    code_ = o.code_;
    if (o.code_ != Code::kOk)
      message_ = o.message_;
    else
      message_.clear();
    return *this;
  }
  Status(Status&&) noexcept = default;
  Status& operator=(Status&&) noexcept = default;
  static Status Ok() { return Status(); }
  static Status InvalidArgument(std::string msg) { return Status(Code::kInvalidArgument, std::move(msg)); }
  static Status NotFound(std::string msg) { return Status(Code::kNotFound, std::move(msg)); }
  static Status Corruption(std::string msg) { return Status(Code::kCorruption, std::move(msg)); }
  static Status IOError(std::string msg) { return Status(Code::kIOError, std::move(msg)); }
  static Status Unsupported(std::string msg) { return Status(Code::kUnsupported, std::move(msg)); }
  static Status Internal(std::string msg) { return Status(Code::kInternal, std::move(msg)); }

  bool ok() const { return code_ == Code::kOk; }
  Code code() const { return code_; }
  const std::string& message() const { return message_; }
  // "corruption: store.mkt: page 12: checksum mismatch"
  std::string ToString() const {
    const char* name = "ok";
    switch (code_) {
      case Code::kOk:
        return "ok";
      case Code::kInvalidArgument:
        name = "invalid argument";
        break;
      case Code::kNotFound:
        name = "not found";
        break;
      case Code::kCorruption:
        name = "corruption";
        break;
      case Code::kIOError:
        name = "I/O error";
        break;
      case Code::kUnsupported:
        name = "unsupported";
        break;
      case Code::kInternal:
        name = "internal error";
        break;
    }
    return std::string(name) + ": " + message_;
  }

 private:
  Status(Code code, std::string msg) : code_(code), message_(std::move(msg)) {}
  Code code_ = Code::kOk;
  std::string message_;
};

// A value or a non-ok Status.
template <typename T>
class [[nodiscard]] Result {
 public:
  Result(T value) : value_(std::move(value)) {}                                  // NOLINT: implicit by design
  Result(Status status) : status_(std::move(status)) { assert(!status_.ok()); }  // NOLINT
  bool ok() const { return status_.ok(); }
  const Status& status() const { return status_; }
  T& value() & { return *value_; }
  const T& value() const& { return *value_; }
  T&& value() && { return std::move(*value_); }
  T* operator->() { return &*value_; }
  const T* operator->() const { return &*value_; }
  T& operator*() & { return *value_; }
  const T& operator*() const& { return *value_; }
  T&& operator*() && { return std::move(*value_); }

 private:
  Status status_;
  std::optional<T> value_;
};

#define MKTREE_RETURN_IF_ERROR(expr) \
  do {                               \
    ::mktree::Status _st = (expr);   \
    if (!_st.ok()) return _st;       \
  } while (0)

// `lhs = value of expr`, or return expr's Status from the enclosing function (which returns a Status or a
// Result). `lhs` may declare (`auto x`, `const Foo& x`) or name an existing variable. It expands to
// several statements: write it as a statement of its own (not an unbraced if's body), one per line.
#define MKTREE_ASSIGN_OR_RETURN(lhs, ...) \
  MKTREE_ASSIGN_OR_RETURN_IMPL_(MKTREE_STATUS_CONCAT_(mktree_result_, __LINE__), lhs, __VA_ARGS__)
#define MKTREE_ASSIGN_OR_RETURN_IMPL_(result, lhs, ...) \
  auto result = (__VA_ARGS__);                          \
  if (!result.ok()) return result.status();             \
  lhs = std::move(result).value()
#define MKTREE_STATUS_CONCAT_(a, b) MKTREE_STATUS_CONCAT_IMPL_(a, b)
#define MKTREE_STATUS_CONCAT_IMPL_(a, b) a##b

}  // namespace mktree
