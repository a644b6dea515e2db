// SPDX-License-Identifier: Apache-2.0
// psq/memory_budget.h: one memory budget for a pipeline, split among its
// stages by the code that builds the pipeline.
//
// `--memory SIZE` makes one MemoryBudget. Whoever composes the pipeline
// (a command of the CLI, build_sequence() for its sort and converter)
// draws each stage's share from it and hands the stage the bytes, so that
// the shares are decided in one place and add up to the budget, instead of
// each stage taking a fraction of its own. A stage that runs only in one
// phase gives its share back when the phase ends, for the next phase's
// stages to draw.
//
// What a share means is the stage's to say (its header): the external
// sort's buffers, the converter's lookahead, a filter's structures (which
// fail with kLimit beyond it), Draco's in-core mesh.
#ifndef PSQ_MEMORY_BUDGET_H_
#define PSQ_MEMORY_BUDGET_H_

#include <algorithm>
#include <cstdint>

namespace psq {

class MemoryBudget {
 public:
  explicit MemoryBudget(uint64_t total) : total_(total) {}

  uint64_t total() const { return total_; }
  // Bytes not drawn.
  uint64_t left() const { return total_ - drawn_; }
  // Draws `parts` / `whole` of the total (whole > 0), or what is left if
  // that is less, and returns the bytes drawn.
  uint64_t draw(uint64_t parts, uint64_t whole) {
    const uint64_t share =
        whole == 0 ? 0 : static_cast<uint64_t>(static_cast<unsigned __int128>(total_) * parts / whole);
    return draw_bytes(share);
  }
  // Draws `bytes`, or what is left if that is less.
  uint64_t draw_bytes(uint64_t bytes) {
    const uint64_t share = std::min(bytes, left());
    drawn_ += share;
    return share;
  }
  // Draws everything that is left.
  uint64_t draw_rest() { return draw_bytes(left()); }
  // Returns `bytes` drawn earlier (a stage whose phase ended).
  void give_back(uint64_t bytes) { drawn_ -= std::min(bytes, drawn_); }

 private:
  uint64_t total_;
  uint64_t drawn_ = 0;
};

}  // namespace psq

#endif  // PSQ_MEMORY_BUDGET_H_
