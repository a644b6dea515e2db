// SPDX-License-Identifier: Apache-2.0
// Rounding a double to the float nearest it, for the layers that write
// float32 values (format/, codec/, simplify/; internal, not installed).
#ifndef PSQ_FORMAT_FLOAT_ROUND_H_
#define PSQ_FORMAT_FLOAT_ROUND_H_

namespace psq::detail {

// The float nearest to `d`, widened back to double. GCC 12 at -O2 may drop
// the rounding of (double)(float)d (../shared/toolchain); the empty asm
// keeps the value a float in a register, so the rounding happens.
inline double round_to_float(double d) {
  float f = static_cast<float>(d);
#if (defined(__GNUC__) || defined(__clang__)) && defined(__SSE__)
  __asm__("" : "+x"(f));
#else
  volatile float g = f;
  f = g;
#endif
  return static_cast<double>(f);
}

}  // namespace psq::detail

#endif  // PSQ_FORMAT_FLOAT_ROUND_H_
