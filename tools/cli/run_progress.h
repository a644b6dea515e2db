// SPDX-License-Identifier: Apache-2.0
// The progress line (progress.h) of a run of tools/src/ops: its
// RunObserver counts on a Progress.
#ifndef PSQ_CLI_RUN_PROGRESS_H_
#define PSQ_CLI_RUN_PROGRESS_H_

#include "pipeline.h"
#include "progress.h"

namespace psq::cli {

class RunProgress : public detail::RunObserver {
 public:
  explicit RunProgress(Progress* progress) : progress_(progress) {}
  void triangle_read() override { progress_->triangle(); }
  void triangle_written() override { progress_->written(); }

 private:
  Progress* progress_;
};

}  // namespace psq::cli

#endif  // PSQ_CLI_RUN_PROGRESS_H_
