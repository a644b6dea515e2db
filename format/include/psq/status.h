// SPDX-License-Identifier: Apache-2.0
// psq/status.h: error reporting for every psq library.
//
// The libraries never print, exit or abort on bad input. Every fallible call
// returns a Status: a stable numeric code (never renumbered; new codes are
// appended), a one-line message and, where known, the place in the input the
// error refers to (a byte offset for binary data, a line for text).
#ifndef PSQ_STATUS_H_
#define PSQ_STATUS_H_

#include <cstdint>
#include <string>
#include <utility>

namespace psq {

// Stable error codes. The numbers are part of the API (tools and bindings may
// switch on them); they never change meaning.
enum class ErrorCode : uint16_t {
  kOk = 0,
  kIo = 1,             // the operating system refused a read, write or open
  kTruncated = 2,      // the input ended before a structure was complete
  kBadHeader = 3,      // a header is missing, malformed or inconsistent
  kBadValue = 4,       // a value is malformed or not allowed (NaN position...)
  kBadIndex = 5,       // a vertex index is negative or out of range
  kUnsupported = 6,    // valid input that psq does not handle
  kLimit = 7,          // a size or count exceeds a documented limit
  kUnknownFormat = 8,  // the content matches no format psq reads
  kUsage = 9,          // the caller passed invalid arguments
  kInternal = 10,      // a psq bug: an invariant did not hold
  kBadSequence = 11,   // events that do not form a valid processing sequence
  kChecksum = 12,      // stored data does not match its checksum
};

// Returns the stable name of a code, e.g. "truncated". Never null.
const char* error_name(ErrorCode code);

class Status {
 public:
  static constexpr uint64_t kNoPlace = ~uint64_t{0};

  Status() noexcept = default;  // success

  // An error; `offset` is a byte offset into the input, `line` a 1-based line
  // number of a text input. Either may be kNoPlace. kOk makes a success (the
  // message and places are dropped).
  Status(ErrorCode code, std::string message, uint64_t offset = kNoPlace, uint64_t line = kNoPlace)
      : rep_(code == ErrorCode::kOk ? nullptr : new Rep{code, std::move(message), offset, line}) {}

  // A success is one null pointer, so that the hot paths that return one
  // per triangle pay a store and a test, not a string's construction and
  // destruction.
  Status(const Status& o) : rep_(o.rep_ ? new Rep(*o.rep_) : nullptr) {}
  Status(Status&& o) noexcept : rep_(o.rep_) { o.rep_ = nullptr; }
  Status& operator=(const Status& o) {
    if (this != &o) {
      Rep* copy = o.rep_ ? new Rep(*o.rep_) : nullptr;
      delete rep_;
      rep_ = copy;
    }
    return *this;
  }
  Status& operator=(Status&& o) noexcept {
    if (this != &o) {
      delete rep_;
      rep_ = o.rep_;
      o.rep_ = nullptr;
    }
    return *this;
  }
  ~Status() { delete rep_; }

  bool ok() const { return rep_ == nullptr; }
  ErrorCode code() const { return rep_ ? rep_->code : ErrorCode::kOk; }
  // Empty for a success.
  const std::string& message() const;
  uint64_t offset() const { return rep_ ? rep_->offset : kNoPlace; }
  uint64_t line() const { return rep_ ? rep_->line : kNoPlace; }

  // "line 12: message", "byte 4096: message" or "message"; one line.
  std::string to_string() const;

 private:
  struct Rep {
    ErrorCode code;
    std::string message;
    uint64_t offset;
    uint64_t line;
  };
  Rep* rep_ = nullptr;
};

// Returns from the enclosing function if `expr` yields an error Status.
#define PSQ_RETURN_IF_ERROR(expr)            \
  do {                                       \
    ::psq::Status psq_status_ = (expr);      \
    if (!psq_status_.ok()) return psq_status_; \
  } while (0)

}  // namespace psq

#endif  // PSQ_STATUS_H_
