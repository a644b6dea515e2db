// SPDX-License-Identifier: Apache-2.0
// codec/src/coding.cpp: the models' initial state and the cost table of
// coding.h.
#include "coding.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <vector>

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
  const int mu = 3 * c / 4;
  auto weight = [mu](int k) { return uint64_t{1} << (24 - std::min(24, std::abs(k - mu))); };
  std::vector<uint64_t> length(16, 0), escape(64, 0);
  for (int k = 0; k <= 64; ++k) {
    if (k < static_cast<int>(kLengthEscape)) length[k] = weight(k);
    else {
      length[kLengthEscape] += weight(k);
      escape[k - kLengthEscape] = weight(k);
    }
  }
  init_tree(m.length, length);
  init_tree(m.escape, escape);
}

namespace {
struct CostTable {
  double v[4097];
  CostTable() {
    v[0] = 12;
    for (int i = 1; i <= 4096; ++i) v[i] = -std::log2(i / 4096.0);
  }
};
const CostTable& cost_table() {
  static const CostTable kTable;
  return kTable;
}
}  // namespace

double bit_cost(uint32_t p12) { return cost_table().v[p12 > 4096 ? 4096 : p12]; }


}  // namespace codec
}  // namespace psq
