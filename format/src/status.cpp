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

std::string Status::to_string() const {
  if (ok()) return "ok";
  std::string out;
  if (line_ != kNoPlace) {
    out = "line " + std::to_string(line_) + ": ";
  } else if (offset_ != kNoPlace) {
    out = "byte " + std::to_string(offset_) + ": ";
  }
  out += message_;
  return out;
}

}  // namespace psq
