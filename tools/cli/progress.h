// SPDX-License-Identifier: Apache-2.0
// Progress on long runs: a line on stderr, rewritten in
// place at most ten times a second, when stderr is a terminal and -q was
// not given; then a one-line summary, or nothing (clear()). Nothing at all
// otherwise.
//
// The line gives the triangles so far, their rate over the last few
// seconds (RateMeter), the share done when it is known (of the input's
// bytes while it is read; of the triangles read, when a spooled input is
// written after it was read) and then the time left at the recent rate.
#ifndef PSQ_CLI_PROGRESS_H_
#define PSQ_CLI_PROGRESS_H_

#include <chrono>
#include <cstdint>
#include <string>

#include "psq/indexed_mesh.h"
#include "psq/io.h"
#include "psq/sequence.h"

namespace psq::cli {

// A rate over the last few seconds, from observations at irregular times:
// what was done divided by the time it took, where each part counts with
// weight exp(-age / time constant). At first that is the average since the
// start; a few time constants after the speed changed, only the new speed
// counts (an average since the start would still mix the two). The same
// for the fraction done, whose rate gives the time left.
class RateMeter {
 public:
  static constexpr double kTimeConstant = 2.0;  // seconds

  explicit RateMeter(double time_constant = kTimeConstant) : tau_(time_constant) {}
  // Starts over at time `t` (seconds) with `count` done and `fraction`
  // done (negative: unknown); the rate is unknown until the next update.
  void reset(double t, double count, double fraction);
  // An observation at time `t` (an earlier or equal time is ignored).
  void update(double t, double count, double fraction);
  // Count per second; negative while unknown.
  double rate() const;
  // Seconds until the fraction reaches 1 at the recent rate of the
  // fraction; negative when unknown (no fraction, or no progress in it).
  double seconds_left() const;

 private:
  double tau_;
  double t_ = 0, count_ = 0, fraction_ = -1;
  double done_ = 0, fraction_done_ = 0, time_ = 0;  // weighted sums
};

// "12 s", "3 min 05 s", "2 h 07 min".
std::string format_duration(double seconds);

// The text of a progress line: "psq: " then, when `fraction` is known (0 to
// 1), the percentage and `what` ("of input", "written"), the count of
// triangles, the rate when known (not negative), the time left when known
// (not negative), and the bytes read when `bytes_read` is not negative
// (input of unknown size).
std::string progress_line(double count, double rate, double fraction, const char* what, double seconds_left,
                          int64_t bytes_read);

class Progress {
 public:
  // `input` is read by the run (its offset and, for a file, its size give
  // the percentage); `enabled` is false for -q. The line shows only when
  // stderr is a terminal.
  Progress(const InputStream* input, bool enabled);
  ~Progress();
  bool active() const { return active_; }
  // Counts one triangle; now and then redraws the line.
  void triangle() {
    if (++triangles_ % 4096 == 0 && active_) draw(false);
  }
  // Counts one triangle written (after the input was read, the percentage
  // becomes that of the triangles read that were written).
  void written() {
    if (++written_ % 4096 == 0 && active_) draw(false);
  }
  // Clears the line and prints "psq: IN -> OUT: SUMMARY, N s".
  void finish(const std::string& in, const std::string& out, const std::string& summary);
  // Clears the line, printing nothing (for a command whose report follows).
  void clear();
  double seconds() const;

 private:
  enum class Phase { kNone, kReading, kWriting, kUnknown };
  void draw(bool force);

  const InputStream* input_;
  bool active_;
  bool drawn_ = false;
  uint64_t triangles_ = 0;
  uint64_t written_ = 0;
  Phase phase_ = Phase::kNone;
  RateMeter meter_;
  std::chrono::steady_clock::time_point start_, last_;
};

// Passes a sequence on and counts its triangles as written for a Progress.
class ProgressSequenceSink : public SequenceSink {
 public:
  ProgressSequenceSink(SequenceSink* out, Progress* progress) : out_(out), progress_(progress) {}
  Status begin(const MeshSchema& s) override { return out_->begin(s); }
  Status vertex(const SequenceVertex& v) override { return out_->vertex(v); }
  Status triangle(const SequenceTriangle& t) override {
    progress_->written();
    return out_->triangle(t);
  }
  Status finalize(uint32_t i) override { return out_->finalize(i); }
  Status finish() override { return out_->finish(); }

 private:
  SequenceSink* out_;
  Progress* progress_;
};

// Passes a source on and counts its triangles for a Progress.
class ProgressSource : public MeshSource {
 public:
  ProgressSource(MeshSource* in, Progress* progress) : in_(in), progress_(progress) {}
  const MeshSchema& schema() const override { return in_->schema(); }
  const SourceReport& report() const override { return in_->report(); }
  Status next(MeshItem* item) override {
    Status s = in_->next(item);
    if (s.ok() && item->kind == MeshItem::Kind::kTriangle) progress_->triangle();
    return s;
  }

 private:
  MeshSource* in_;
  Progress* progress_;
};

}  // namespace psq::cli

#endif  // PSQ_CLI_PROGRESS_H_
