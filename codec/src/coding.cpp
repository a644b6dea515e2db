// codec/src/coding.cpp: the cost table of coding.h.
#include "coding.h"

#include <cmath>

namespace psq {
namespace codec {

double bit_cost(uint32_t p12) {
  struct Table {
    double v[4097];
    Table() {
      v[0] = 12;
      for (int i = 1; i <= 4096; ++i) v[i] = -std::log2(i / 4096.0);
    }
  };
  static const Table kTable;
  return kTable.v[p12 > 4096 ? 4096 : p12];
}

}  // namespace codec
}  // namespace psq
