// SPDX-License-Identifier: Apache-2.0
#include "psq/status.h"

namespace psq {

const char* error_name(ErrorCode code) {
  switch (code) {
    case ErrorCode::kOk: return "ok";
    case ErrorCode::kIo: return "io";
    case ErrorCode::kTruncated: return "truncated";
    case ErrorCode::kBadHeader: return "bad_header";
    case ErrorCode::kBadValue: return "bad_value";
    case ErrorCode::kBadIndex: return "bad_index";
    case ErrorCode::kUnsupported: return "unsupported";
    case ErrorCode::kLimit: return "limit";
    case ErrorCode::kUnknownFormat: return "unknown_format";
    case ErrorCode::kUsage: return "usage";
    case ErrorCode::kInternal: return "internal";
    case ErrorCode::kBadSequence: return "bad_sequence";
    case ErrorCode::kChecksum: return "checksum";
  }
  return "unknown";
}

const std::string& Status::message() const {
  static const std::string kEmpty;
  return rep_ ? rep_->message : kEmpty;
}

std::string Status::to_string() const {
  if (ok()) return "ok";
  std::string out;
  if (rep_->line != kNoPlace) {
    out = "line " + std::to_string(rep_->line) + ": ";
  } else if (rep_->offset != kNoPlace) {
    out = "byte " + std::to_string(rep_->offset) + ": ";
  }
  out += rep_->message;
  return out;
}

}  // namespace psq
