// SPDX-License-Identifier: Apache-2.0
// codec/src/geometry.h: coded coordinates and their predictions
// (spec/psq-format.md section 7), shared by the encoder and the decoder.
#ifndef PSQ_CODEC_GEOMETRY_H_
#define PSQ_CODEC_GEOMETRY_H_

#include <cmath>
#include <cstdint>
#include <cstring>

#include "float_round.h"

namespace psq {
namespace codec {

// Wrapping arithmetic on coded coordinates (spec 7.3): sums and differences
// are taken modulo 2^64 and read as two's complement.
inline int64_t wrap_add(int64_t a, int64_t b) {
  return static_cast<int64_t>(static_cast<uint64_t>(a) + static_cast<uint64_t>(b));
}
inline int64_t wrap_sub(int64_t a, int64_t b) {
  return static_cast<int64_t>(static_cast<uint64_t>(a) - static_cast<uint64_t>(b));
}
// floor((a + b) / 2) without overflow.
inline int64_t midpoint(int64_t a, int64_t b) { return (a >> 1) + (b >> 1) + (a & b & 1); }

// Spec 7.2: the order-preserving integer of a float's bit pattern.
inline int64_t ordered_from_float(float f) {
  uint32_t b;
  std::memcpy(&b, &f, 4);
  return (b & 0x80000000u) ? -1 - static_cast<int64_t>(b & 0x7fffffffu) : static_cast<int64_t>(b);
}
inline float float_from_ordered(int64_t o) {
  uint32_t b = o >= 0 ? static_cast<uint32_t>(o) : (0x80000000u | static_cast<uint32_t>(-1 - o));
  float f;
  std::memcpy(&f, &b, 4);
  return f;
}
inline int64_t ordered_from_double(double d) {
  uint64_t b;
  std::memcpy(&b, &d, 8);
  return (b >> 63) ? -1 - static_cast<int64_t>(b & 0x7fffffffffffffffull) : static_cast<int64_t>(b);
}
inline double double_from_ordered(int64_t o) {
  uint64_t b = o >= 0 ? static_cast<uint64_t>(o) : (0x8000000000000000ull | static_cast<uint64_t>(-1 - o));
  double d;
  std::memcpy(&d, &b, 8);
  return d;
}

// The float nearest to `d`, widened back to double (format/src/float_round.h
// keeps the rounding that GCC 12 at -O2 would drop).
using detail::round_to_float;

}  // namespace codec
}  // namespace psq

#endif  // PSQ_CODEC_GEOMETRY_H_
