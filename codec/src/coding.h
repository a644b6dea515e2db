// SPDX-License-Identifier: Apache-2.0
// codec/src/coding.h: what the encoder and the decoder share so that both
// use the same contexts: the prediction kinds and choices (spec/psq-format.md
// 7.3), the length and degree contexts of the records (13.7.3, 13.8.1),
// and the residual models of the attribute section's adaptive back-end
// (5.6, 8.3) with the helpers that code with them and the range coder.
#ifndef PSQ_CODEC_CODING_H_
#define PSQ_CODEC_CODING_H_

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <vector>

#include "psq/psq_memory.h"  // DefaultInitAllocator
#include "range_coder.h"

namespace psq {
namespace codec {

// The degree context of a gate record's B symbol (spec 13.7.3): the
// triangles around the gate's endpoints, 0..5+ each.
constexpr int kDegreeCap = 5;

// Residual contexts (spec 7.4): prediction kind x axis. An add's new
// vertex is predicted across the gate (kind 0) or, when the encoder chose
// so, across the open edge before or after the gate (kind 2), or by the
// mean of the gate's and such a neighbour's parallelograms (kind 3; spec
// 7.3); other new vertices have kind 1.
constexpr int kPredParallelogram = 0;
constexpr int kPredOther = 1;
constexpr int kPredNeighbour = 2;
constexpr int kPredMean = 3;
constexpr int kPredKinds = 4;
// What predicts an add's new vertex (spec 7.3): the parallelogram across
// the gate, across the open edge before it (its `prev` link) or after it
// (`next`), or the mean of the gate's and the one before or after.
constexpr int kChoiceGate = 0;
constexpr int kChoiceBefore = 1;
constexpr int kChoiceAfter = 2;
constexpr int kChoiceMeanBefore = 3;
constexpr int kChoiceMeanAfter = 4;
constexpr int kChoices = 5;
// The neighbour a choice uses: kChoiceGate (none), kChoiceBefore or kChoiceAfter.
constexpr int choice_side(int ch) { return ch <= kChoiceAfter ? ch : ch - 2; }
// The edge whose triangle is the choice's predicting triangle (its extents
// give the length contexts): the neighbour for one parallelogram, the gate
// for the gate's and for a mean.
constexpr int predicting_side(int ch) { return ch <= kChoiceAfter ? ch : kChoiceGate; }
// The prediction kind (residual models) of a choice.
constexpr int prediction_kind(int ch) {
  return ch == kChoiceGate ? kPredParallelogram : ch >= kChoiceMeanBefore ? kPredMean : kPredNeighbour;
}

// Signed 64-bit residual (spec 5.6): the bit length 0..64 as min(k, 15) in
// a 4-bit tree and, from 15 on, k - 15 in a 6-bit escape tree; the bit
// below the leading one (adaptive, by length); then the sign and the bits
// below as one raw value (the sign of a prediction's error is a fair coin:
// an adaptive model of it only added its learning cost).
constexpr uint32_t kLengthEscape = 15;
struct ResidualModel {
  SymbolModel length{4};
  SymbolModel escape{6};
  BitModel second[65];
};

// Length contexts 0..11 of a residual (spec 13.8.1 for positions,
// fast_length_context(); 8.3 for attributes).
constexpr int kLengthContexts = 12;
// The bit length of v (0 for 0), without a branch: a test for zero would
// be a branch on data, which the fast encoder's search mispredicts.
inline int bit_length64(uint64_t v) { return (63 - __builtin_clzll(v | 1)) + (v != 0 ? 1 : 0); }
// bit_length64() for v below 2^63, in two instructions: 2v + 1 has
// one bit more than v, and 1 for v = 0.
inline int bit_length63(uint64_t v) { return 63 - __builtin_clzll(2 * v + 1); }
// |a - b| for coordinates, the difference taken modulo 2^64 and its two's
// complement magnitude.
inline uint64_t coord_distance(int64_t a, int64_t b) {
  const uint64_t d = static_cast<uint64_t>(a) - static_cast<uint64_t>(b);
  const uint64_t sign = 0 - (d >> 63);  // all ones when d reads negative; branch-free
  return (d ^ sign) - sign;
}
// The bit length of a triangle's extent along `axis`: of the largest
// coordinate distance between two of its corners a, b, c.
inline int triangle_extent(const int64_t* a, const int64_t* b, const int64_t* c, int axis) {
  // When the largest minus the smallest is below 2^63, every pair's
  // difference is its distance and none is larger; otherwise some
  // difference wraps, and the pairs decide.
  const int64_t x = a[axis], y = b[axis], z = c[axis];
  // Conditional moves, not branches: the comparisons are data.
  const int64_t hi_xy = x > y ? x : y, lo_xy = x > y ? y : x;
  const int64_t hi = hi_xy > z ? hi_xy : z, lo = lo_xy < z ? lo_xy : z;
  const uint64_t spread = static_cast<uint64_t>(hi) - static_cast<uint64_t>(lo);
  if (static_cast<int64_t>(spread) >= 0) return bit_length63(spread);
  return bit_length64(std::max(coord_distance(x, y), std::max(coord_distance(x, z), coord_distance(y, z))));
}

// The prior weight of residual length k in length context c (spec 8.3,
// 13.2.1): 2^(24 - min(24, |k - mu|)), with mu = floor(3c / 4).
inline uint64_t length_weight(int k, int c) { return uint64_t{1} << (24 - std::min(24, std::abs(k - 3 * c / 4))); }
// Spec 8.3: the initial state of the length and escape trees of an
// attribute residual model with length context `c`. Each length k
// <= 64 gets the weight length_weight(k, c); leaf 15 of the length tree weighs all lengths from 15 on, leaf e of the
// escape tree the length 15 + e (0 above 64); each node's p0 is the share
// of its 0-subtree in its weight, and its count n starts at 2. The typical
// length grows with the context (about 3c/4 on the shared meshes);
// starting there instead of at one half saves the models' learning, which
// weighs most on a small mesh.
void init_length_prior(ResidualModel& m, int c);
// Spec 13.2.1: the adaptive back-end's initial state of the record class
// table A[ctx] and of a B symbol table of shape context `shape` (0 to 4).
void init_class_prior(SymbolModel& tree, int ctx);
void init_gate_prior(SymbolModel& tree, int shape);
// Sets the nodes of bit-tree `tree` to the distribution of its leaves'
// weights `leaf` (one per leaf; each node's p0 the share of its
// 0-subtree, clamped to 32..65504, its count n 2).
void init_tree(SymbolModel& tree, const std::vector<uint64_t>& leaf);

// The degree context of a gate record's B symbol: the triangles already
// around the gate's endpoints p and q (spec 13.7.3).
inline int third_context(uint32_t degree_p, uint32_t degree_q) {
  return static_cast<int>(std::min<uint32_t>(degree_p, kDegreeCap) * (kDegreeCap + 1) +
                          std::min<uint32_t>(degree_q, kDegreeCap));
}

// Bits of an explicit edge slot when `capacity` slots were ever handed out
// (spec 6.1.1, 13.7.2 step 4): enough for capacity - 1.
inline int slot_bits(uint32_t capacity) { return capacity <= 1 ? 0 : 32 - __builtin_clz(capacity - 1); }

// Cost categories: what `psq info` splits the record bytes into (not part
// of the format).
enum Cost { kCostConnectivity = 0, kCostGeometry = 1, kCostCount = 2 };

// Forces the inlining of the coders' per-decision helpers, which GCC
// otherwise leaves as calls in the encoder's large functions.
#if defined(__GNUC__)
#define PSQ_INLINE inline __attribute__((always_inline))
#define PSQ_LAMBDA_INLINE __attribute__((always_inline))
#define PSQ_NOINLINE __attribute__((noinline))
#else
#define PSQ_INLINE inline
#define PSQ_LAMBDA_INLINE
#define PSQ_NOINLINE
#endif

// A stack of T in a plain array and a count: its push stays inline in the
// encoder's and the decoder's loops, where std::vector's push_back would be
// a call. It grows to the capacity reserved, else to twice its size plus
// kMinGrow, without zeroing: every element is written before it is read.
template <class T, size_t kMinGrow>
class ArrayStack {
 public:
  bool empty() const { return n_ == 0; }
  size_t size() const { return n_; }
  const T* data() const { return v_.data(); }
  const T* begin() const { return v_.data(); }
  const T* end() const { return v_.data() + n_; }
  void clear() { n_ = 0; }
  // Room for n elements without moving them (address space only).
  void reserve(size_t n) { v_.reserve(n); }
  __attribute__((always_inline)) T pop() { return v_[--n_]; }
  __attribute__((always_inline)) void push(T x) {
    if (n_ == v_.size()) grow();
    v_[n_++] = x;
  }

 private:
  __attribute__((noinline)) void grow() { v_.resize(std::max(v_.capacity(), 2 * v_.size() + kMinGrow)); }
  std::vector<T, DefaultInitAllocator<T>> v_;
  size_t n_ = 0;
};

class Encoder {
 public:
  explicit Encoder(RangeEncoder* rc) : rc_(rc) {}
  PSQ_INLINE void bit(BitModel& m, int b) { rc_->encode_bit(m, b); }
  // A symbol of a model of kBits bits (kBits must be m.bits(); a template
  // parameter, so that the tree's walk unrolls; spec 5.5).
  template <int kBits>
  PSQ_INLINE void symbol(SymbolModel& m, uint32_t s) {
    BitModel* tree = m.tree();
    uint32_t node = 1;
    for (int i = kBits - 1; i >= 0; --i) {
      int b = static_cast<int>((s >> i) & 1u);
      bit(tree[node], b);
      node = (node << 1) | static_cast<uint32_t>(b);
    }
  }
  void raw(uint64_t v, int bits) {
    if (bits > 32) {
      rc_->encode_raw(static_cast<uint32_t>(v >> 32), bits - 32);
      bits = 32;
    }
    rc_->encode_raw(static_cast<uint32_t>(v), bits);
  }
  // Returns the bit length it coded.
  int residual(ResidualModel& m, int64_t r) {
    uint64_t mag = r < 0 ? 0 - static_cast<uint64_t>(r) : static_cast<uint64_t>(r);
    int k = mag == 0 ? 0 : 64 - __builtin_clzll(mag);
    if (k < static_cast<int>(kLengthEscape)) {
      symbol<4>(m.length, static_cast<uint32_t>(k));
    } else {
      symbol<4>(m.length, kLengthEscape);
      symbol<6>(m.escape, static_cast<uint32_t>(k) - kLengthEscape);
    }
    if (k == 0) return 0;
    if (k >= 2) bit(m.second[k], static_cast<int>((mag >> (k - 2)) & 1));
    // One raw value: the sign above the k - 2 bits below the second bit
    // (none for k = 1).
    const int low_bits = k >= 2 ? k - 2 : 0;
    const uint64_t low = mag & ((uint64_t{1} << low_bits) - 1);
    raw((static_cast<uint64_t>(r < 0) << low_bits) | low, low_bits + 1);
    return k;
  }

 private:
  RangeEncoder* rc_;
};

// Encoder's counterpart.
class Decoder {
 public:
  explicit Decoder(RangeDecoder* rc) : rc_(rc) {}
  PSQ_INLINE int bit(BitModel& m) { return rc_->decode_bit(m); }
  // A symbol of a model of kBits bits (kBits must be m.bits(); a template
  // parameter, so that the tree's walk unrolls; spec 5.5).
  template <int kBits>
  uint32_t symbol(SymbolModel& m) {
    BitModel* tree = m.tree();
    uint32_t node = 1;
    for (int i = 0; i < kBits; ++i) node = (node << 1) | static_cast<uint32_t>(bit(tree[node]));
    return node - (1u << kBits);
  }
  uint64_t raw(int bits) {
    if (bits >= 1 && bits <= 16) return rc_->decode_raw_short(bits);
    uint64_t v = 0;
    if (bits > 32) {
      v = static_cast<uint64_t>(rc_->decode_raw(bits - 32)) << 32;
      bits = 32;
    }
    return v | rc_->decode_raw(bits);
  }
  // Returns false on a length above 64 (a corrupt stream); sets *length.
  bool residual(ResidualModel& m, int64_t* r, int* length) {
    uint32_t k = symbol<4>(m.length);
    if (k == kLengthEscape) k += symbol<6>(m.escape);
    *length = static_cast<int>(k);
    if (k == 0) {
      *r = 0;
      return true;
    }
    if (k > 64) return false;
    uint64_t mag = uint64_t{1} << (k - 1);
    if (k >= 2) mag |= static_cast<uint64_t>(bit(m.second[k])) << (k - 2);
    const int low_bits = k >= 2 ? static_cast<int>(k) - 2 : 0;
    const uint64_t v = raw(low_bits + 1);
    const int negative = static_cast<int>(v >> low_bits);
    mag |= v & ((uint64_t{1} << low_bits) - 1);
    *r = negative ? static_cast<int64_t>(0 - mag) : static_cast<int64_t>(mag);
    if (!negative && static_cast<int64_t>(mag) < 0) return false;  // 2^63 is not a positive int64
    return true;
  }
  bool overran() const { return rc_->overran(); }

 private:
  RangeDecoder* rc_;
};

}  // namespace codec
}  // namespace psq

#endif  // PSQ_CODEC_CODING_H_
