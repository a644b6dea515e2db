// SPDX-License-Identifier: Apache-2.0
// codec/src/symbol_coder.h: the two entropy back-ends of the record
// grammar (spec 13.2). The records read and write their symbols through
// one of these, each symbol with the table of its context (13.5.3); the
// raw block (13.3) is the same for both.
//
//  - static tables with rANS (header flag "rans"): per chunk, one
//    frequency table per context, sent in the chunk; a symbol is a table
//    lookup and a multiplication (13.4);
//  - adaptive models with the range coder (no flag): per context, a
//    bit-tree of adaptive binary models (5.1, 5.5) that starts afresh in
//    every chunk; no table is sent, and the models follow the statistics
//    as they change, which makes the smaller files.
//
// The record encoder and decoder are templates over these, so that the
// grammar is written once.
#ifndef PSQ_CODEC_SYMBOL_CODER_H_
#define PSQ_CODEC_SYMBOL_CODER_H_

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "coding.h"
#include "records.h"
#include "range_coder.h"
#include "rans.h"

namespace psq {
namespace codec {

// The bits of the bit-tree that codes table `table`'s symbols in the
// adaptive back-end: the fewest that hold its alphabet (13.5.3).
inline int adaptive_table_bits(int table) {
  const int size = fast_table_size(table);
  int bits = 1;
  while ((1 << bits) < size) ++bits;
  return bits;
}

// A fresh model for every table (spec 13.2: the adaptive back-end's
// initial state, at every chunk start).
inline void reset_adaptive_models(std::vector<SymbolModel>* models) {
  models->clear();
  models->reserve(kAdaptiveTables);
  for (int t = 0; t < kAdaptiveTables; ++t) models->emplace_back(adaptive_table_bits(t));
  // The residual length tables start from a prior: lengths near 3c/4 in
  // length context c, as the extents make likely (spec 13.2.1).
  std::vector<uint64_t> leaf(128, 0);
  for (int t = kFastTableLength; t < kFastTableDistance; ++t) {
    const int c = (t - kFastTableLength) % kLengthContexts;
    for (int s = 0; s <= kFastLengthEscape; ++s) leaf[s] = length_weight(length_of_symbol(s), c);
    init_tree((*models)[t], leaf);
  }
  // The record classes and B symbols start from their priors (13.2.1).
  for (int ctx = 0; ctx < kFastAContexts; ++ctx) init_class_prior((*models)[kFastTableA + ctx], ctx);
  for (int t = kFastTableB; t < kFastTableB + kFastBContexts; ++t) init_gate_prior((*models)[t], 0);
  for (int t = kFastTables; t < kAdaptiveTables; ++t) init_gate_prior((*models)[t], 1 + (t - kFastTables) / kFastBContexts);
}

class RansSymbolDecoder {
 public:
  static constexpr bool kAdaptive = false;
  RansSymbolDecoder(const uint8_t* data, size_t size, const RansTable* tables) : d_(data, size), tables_(tables) {}
  __attribute__((always_inline)) int decode(int table) { return d_.decode(tables_[table]); }
  bool overran() const { return d_.overran(); }
  bool at_clean_end() const { return d_.at_clean_end(); }

 private:
  RansDecoder d_;
  const RansTable* tables_;
};

class AdaptiveSymbolDecoder {
 public:
  static constexpr bool kAdaptive = true;
  AdaptiveSymbolDecoder(const uint8_t* data, size_t size, SymbolModel* models, bool measure)
      : d_(data, size), size_(size), models_(models), measure_(measure) {}
  int decode(int table) {
    SymbolModel& m = models_[table];
    if (!measure_) return static_cast<int>(d_.decode_symbol(m));
    // Measuring: the symbol's information content, bit by bit of the tree.
    BitModel* tree = m.tree();
    uint32_t node = 1;
    last_bits_ = 0;
    for (int i = 0; i < m.bits(); ++i) {
      const double p0 = tree[node].p0 / 65536.0;
      const int bit = d_.decode_bit(tree[node]);
      last_bits_ -= std::log2(bit ? 1 - p0 : p0);
      node = (node << 1) | static_cast<uint32_t>(bit);
    }
    return static_cast<int>(node - (1u << m.bits()));
  }
  bool overran() const { return d_.overran(); }
  // Spec 5.8: the records use the range coder's bytes exactly.
  bool at_clean_end() const { return !d_.overran() && d_.consumed() == size_; }
  // The information content of the last symbol, when measuring.
  double last_bits() const { return last_bits_; }

 private:
  RangeDecoder d_;
  size_t size_;
  SymbolModel* models_;
  bool measure_;
  double last_bits_ = 0;
};

}  // namespace codec
}  // namespace psq

#endif  // PSQ_CODEC_SYMBOL_CODER_H_
