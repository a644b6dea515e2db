// SPDX-License-Identifier: Apache-2.0
// codec/src/coding.cpp: the models' initial state of coding.h.
#include "coding.h"

#include <algorithm>
#include <cstdlib>
#include <vector>

#include "records.h"

namespace psq {
namespace codec {

// Sets the nodes of `tree` from the weights of its leaves (spec 8.3).
void init_tree(SymbolModel& tree, const std::vector<uint64_t>& leaf) {
  const int leaves = 1 << tree.bits();
  // Subtree weights, heap-ordered like the tree: node i has children 2i
  // and 2i + 1, leaf j is node leaves + j. At most 65 lengths of at most
  // 2^24: below 2^31, and below 2^47 after the shift by 16.
  std::vector<uint64_t> w(2 * leaves, 0);
  for (int j = 0; j < leaves; ++j) w[leaves + j] = leaf[j];
  for (int i = leaves - 1; i >= 1; --i) w[i] = w[2 * i] + w[2 * i + 1];
  BitModel* node = tree.tree();
  for (int i = 1; i < leaves; ++i) {
    uint64_t p0 = w[i] == 0 ? 32768 : (w[2 * i] << 16) / w[i];
    node[i].p0 = static_cast<uint16_t>(std::min<uint64_t>(std::max<uint64_t>(p0, 32), 65504));
    node[i].n = 2;
  }
}


void init_length_prior(ResidualModel& m, int c) {
  std::vector<uint64_t> length(16, 0), escape(64, 0);
  for (int k = 0; k <= 64; ++k) {
    if (k < static_cast<int>(kLengthEscape)) length[k] = length_weight(k, c);
    else {
      length[kLengthEscape] += length_weight(k, c);
      escape[k - kLengthEscape] = length_weight(k, c);
    }
  }
  init_tree(m.length, length);
  init_tree(m.escape, escape);
}

// Spec 13.2.1: the prior of the record class tables A[ctx] and of the B
// symbol tables by shape context (B[d] is shape context 0, Bs[s][d] the
// others; the degree context d does not change it). Leaf s of a table
// weighs 2^e, e from these rows. The exponents are log2 of each symbol's
// share of its tables' symbols in the 25 shared meshes at 14 bits, so
// that a small chunk does not spend its first records learning that most
// gates add a vertex or close a fan.
namespace {
const uint8_t kClassPrior[kFastAContexts][7] = {
    {16, 12,  0,  6,  5,  1,  0},
    {15,  8,  2, 13, 14,  2,  2},
    {16, 12,  0,  8,  1,  2,  0},
    {16,  7,  7, 12,  6,  0,  6},
    { 0,  0,  0, 15, 12,  0, 15},
    {15,  0,  0, 15,  0,  0,  5},
    {15, 14,  1,  8,  1,  1,  1},
    {16, 12,  5,  9,  6,  6,  7},
    {16, 12,  5,  9,  6,  6,  7},
    {16,  2,  9,  7,  0,  0,  0},
    {16, 12,  5,  9,  6,  6,  7},
    {15,  0,  0, 14,  0,  0,  5},
    {16,  9,  3, 10,  3,  3,  3},
    {16, 12,  5,  9,  6,  6,  7},
    {16, 12,  5,  9,  6,  6,  7},
    {16, 12,  5,  9,  6,  6,  7},
    {16, 12,  5,  9,  6,  6,  7},
    {15,  3,  3, 15,  3,  3,  3},
    {16, 13,  0, 10,  9,  0,  8},
    {16, 12,  5,  9,  6,  6,  7},
    {16,  8,  0,  9,  0,  0,  0},
    {16,  8,  4, 11,  8,  4,  9},
    {16, 12,  5,  9,  6,  6,  7},
    {16,  1,  1, 14,  1,  1,  6},
    {15, 11, 14,  1, 15,  5,  1},
    {12,  6,  2,  2,  6, 16,  2},
    {16, 13,  1,  1,  5,  1,  9}};
const uint8_t kGatePrior[kShapeContexts][kFastBSymbols] = {
    {16, 8, 6, 7, 6, 0, 6, 0, 6, 3, 0, 5, 0, 0, 0, 5, 0, 6, 10, 3, 0, 1, 0, 0, 0, 0, 0, 14, 3, 0, 12, 3, 0, 8},
    {13, 0, 0, 2, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 6, 0, 0, 0, 0, 0, 0, 0, 0, 16, 4, 0, 8, 0, 0, 8},
    {14, 5, 0, 3, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 8, 0, 0, 0, 0, 0, 0, 0, 0, 12, 1, 0, 15, 7, 5, 0},
    {15, 0, 0, 4, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 8, 0, 0, 0, 0, 0, 0, 0, 0, 15, 4, 0, 9, 1, 0, 8},
    {15, 8, 4, 4, 4, 0, 3, 0, 2, 2, 0, 3, 0, 0, 0, 0, 0, 3, 9, 2, 0, 0, 0, 0, 0, 0, 0, 13, 2, 0, 15, 6, 4, 0}};

void init_exponent_prior(SymbolModel& tree, const uint8_t* exponent, int symbols) {
  std::vector<uint64_t> leaf(size_t{1} << tree.bits(), 0);
  for (int s = 0; s < symbols; ++s) leaf[static_cast<size_t>(s)] = uint64_t{1} << exponent[s];
  init_tree(tree, leaf);
}
}  // namespace

void init_class_prior(SymbolModel& tree, int ctx) { init_exponent_prior(tree, kClassPrior[ctx], 7); }

void init_gate_prior(SymbolModel& tree, int shape) { init_exponent_prior(tree, kGatePrior[shape], kFastBSymbols); }

}  // namespace codec
}  // namespace psq
