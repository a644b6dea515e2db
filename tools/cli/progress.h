// Progress on long runs: a line on stderr, rewritten in place at
// most ten times a second, when stderr is a terminal and -q was not given;
// then a one-line summary. Nothing at all otherwise.
#ifndef PSQ_CLI_PROGRESS_H_
#define PSQ_CLI_PROGRESS_H_

#include <chrono>
#include <cstdint>
#include <string>

#include "psq/indexed_mesh.h"
#include "psq/io.h"
#include "psq/sequence.h"

namespace psq::cli {

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
  double seconds() const;

 private:
  void draw(bool force);

  const InputStream* input_;
  bool active_;
  bool drawn_ = false;
  uint64_t triangles_ = 0;
  uint64_t written_ = 0;
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
