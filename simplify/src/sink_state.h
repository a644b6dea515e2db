// SPDX-License-Identifier: Apache-2.0
// The event-order rules of a SequenceSink (psq/sequence.h) that every
// filter of simplify/ enforces the same way: the first error is sticky,
// begin() comes once, the other events only between begin() and finish(),
// and finish() once.
#ifndef PSQ_SIMPLIFY_SINK_STATE_H_
#define PSQ_SIMPLIFY_SINK_STATE_H_

#include <cmath>
#include <string>
#include <utility>

#include "psq/sequence.h"
#include "psq/status.h"

namespace psq::detail {

class SinkState {
 public:
  // Before begin(): the sticky error, or kUsage the second time.
  Status begin() {
    if (!error_.ok()) return error_;
    if (begun_) return fail(Status(ErrorCode::kUsage, "begin() called twice"));
    begun_ = true;
    return Status();
  }
  // Before vertex(), triangle() and finalize(); `what` names the event.
  Status event(const char* what) {
    if (!error_.ok()) return error_;
    if (!begun_ || finished_) return fail(Status(ErrorCode::kUsage, std::string(what) + " outside begin()..finish()"));
    return Status();
  }
  // Before finish(): as event(), and no event may follow.
  Status finish() {
    Status s = event("finish()");
    finished_ = true;
    return s;
  }
  // Keeps the first error; returns it (or `s` while there is none).
  Status fail(Status s) {
    if (error_.ok()) error_ = std::move(s);
    return error_;
  }

 private:
  Status error_;
  bool begun_ = false, finished_ = false;
};

// kBadValue for a vertex whose position is not finite.
inline Status check_finite(const SequenceVertex& v) {
  for (double c : v.position)
    if (!std::isfinite(c))
      return Status(ErrorCode::kBadValue, "vertex " + std::to_string(v.index) + ": position is not finite");
  return Status();
}

}  // namespace psq::detail

#endif  // PSQ_SIMPLIFY_SINK_STATE_H_
