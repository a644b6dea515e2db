// SPDX-License-Identifier: Apache-2.0
// codec/src/range_coder.h: the adaptive binary range coder of the .psq codec.
//
// A range coder (Martin 1979; the carry handling with a cached byte as in
// Subbotin's and LZMA's coders) that codes binary decisions with adaptive
// probabilities, symbols of up to 16 bits as a binary tree of such decisions,
// and raw bits at probability one half (coding.h codes signed integers with
// them as a bit length followed by the bits below the leading one, after the
// integer coder of LASzip, Isenburg 2013).
//
// Probabilities are 16-bit (1/65536 units, kept within [32, 65504]) and
// adapt after each decision by 1/2^s of the error, where s grows from 2 to 6
// with the number of updates the model has seen (fast learning, then stable
// estimates; spec 5.1). The encoder appends to a byte vector; the decoder
// reads a byte span and never reads outside it: past the end it reads zero
// bytes and remembers that it overran, which the caller turns into an error
// (overran()). Decoding is therefore safe on untrusted input; what a corrupt
// stream decodes to is garbage that the caller's checks must reject.
//
// The exact arithmetic is normative: spec/psq-format.md, section 5.
#ifndef PSQ_CODEC_RANGE_CODER_H_
#define PSQ_CODEC_RANGE_CODER_H_

#include <cstddef>
#include <cstdint>
#include <vector>

namespace psq {

// An adaptive binary probability (spec 5.1).
struct BitModel {
  uint16_t p0 = 32768;  // the chance of a 0, in 1/65536 units
  uint16_t n = 0;       // updates so far, counted up to 30: sets the adaptation rate
};
// One update of a model with n updates so far (n <= 30): the adaptation
// shift, 2, 3, 4, 5, then 6 from n = 30 on (spec 5.1 counts on to 255; the
// shift is the same from 30 on), and the count after the update,
// min(n + 1, 30). One lookup instead of a lookup and a saturating
// increment, on every decision.
struct AdaptStep {
  uint8_t shift;
  uint8_t next;
};
inline AdaptStep adapt_step(uint16_t n) {
  static const AdaptStep kStep[31] = {
      {2, 1}, {2, 2}, {3, 3}, {3, 4}, {3, 5}, {3, 6}, {4, 7}, {4, 8},
      {4, 9}, {4, 10}, {4, 11}, {4, 12}, {4, 13}, {4, 14}, {5, 15}, {5, 16},
      {5, 17}, {5, 18}, {5, 19}, {5, 20}, {5, 21}, {5, 22}, {5, 23}, {5, 24},
      {5, 25}, {5, 26}, {5, 27}, {5, 28}, {5, 29}, {5, 30}, {6, 30}};
  return kStep[n];
}

// An adaptive model for symbols of `bits` bits (1..16): a binary tree of
// BitModels, most significant bit first.
class SymbolModel {
 public:
  explicit SymbolModel(int bits = 8);
  int bits() const { return bits_; }
  BitModel* tree() { return tree_.data(); }
  const BitModel* tree() const { return tree_.data(); }

 private:
  int bits_;
  std::vector<BitModel> tree_;  // node 1 is the root; 2^bits entries
};

class RangeEncoder {
 public:
  // Appends the coded bytes to `out`, which must outlive the encoder.
  explicit RangeEncoder(std::vector<uint8_t>* out);

  // Inline: the encoder's innermost operation (spec 5.7).
  void encode_bit(BitModel& m, int bit) {
    const uint32_t bound = (range_ >> 16) * m.p0;
    const AdaptStep step = adapt_step(m.n);
    const int sh = step.shift;
    m.n = step.next;
    if (bit == 0) {
      range_ = bound;
      m.p0 = static_cast<uint16_t>(m.p0 + ((65536u - 32 - m.p0) >> sh));
    } else {
      low_ += bound;
      range_ -= bound;
      m.p0 = static_cast<uint16_t>(m.p0 - ((m.p0 - 32) >> sh));
    }
    while (range_ < (1u << 24)) {
      range_ <<= 8;
      shift_low();
    }
  }
  void encode_symbol(SymbolModel& m, uint32_t symbol);  // symbol < 2^bits
  void encode_raw(uint32_t value, int bits);           // bits 0..32
  // Flushes the final state (5 bytes). The encoder must not be used after.
  void finish();

 private:
  void shift_low();

  std::vector<uint8_t>* out_;
  uint64_t low_ = 0;
  uint32_t range_ = 0xffffffffu;
  uint8_t cache_ = 0;
  uint64_t cache_size_ = 1;
};

class RangeDecoder {
 public:
  // Decodes from `size` bytes at `data`, which must outlive the decoder.
  RangeDecoder(const uint8_t* data, size_t size);

  // Inline: the decoder's innermost operation (spec/psq-format.md 5).
  int decode_bit(BitModel& m) {
    const uint32_t bound = (range_ >> 16) * m.p0;
    const AdaptStep step = adapt_step(m.n);
    const int sh = step.shift;
    m.n = step.next;
    int bit;
    if (code_ < bound) {
      range_ = bound;
      m.p0 = static_cast<uint16_t>(m.p0 + ((65536u - 32 - m.p0) >> sh));
      bit = 0;
    } else {
      code_ -= bound;
      range_ -= bound;
      m.p0 = static_cast<uint16_t>(m.p0 - ((m.p0 - 32) >> sh));
      bit = 1;
    }
    if (range_ < (1u << 24)) normalize();
    return bit;
  }
  uint32_t decode_symbol(SymbolModel& m);
  uint32_t decode_raw(int bits);
  // decode_raw() for 1 to 16 bits, inline: one step, which decode_raw()
  // repeats for longer values.
  uint32_t decode_raw_short(int bits) {
    range_ >>= bits;
    uint32_t part = code_ / range_;
    if (part >> bits) {  // only a corrupt stream puts code beyond the range
      overran_ = true;
      part = (1u << bits) - 1;
    }
    code_ -= part * range_;
    if (range_ < (1u << 24)) normalize();
    return part;
  }

  // True when decoding needed bytes past the end of the input: the stream
  // was truncated or corrupt.
  bool overran() const { return overran_; }
  // Bytes consumed so far (at most the input size).
  size_t consumed() const { return pos_; }

 private:
  uint8_t next_byte() {
    if (pos_ < size_) return data_[pos_++];
    overran_ = true;
    return 0;
  }
  void normalize() {
    while (range_ < (1u << 24)) {
      range_ <<= 8;
      code_ = (code_ << 8) | next_byte();
    }
  }

  const uint8_t* data_;
  size_t size_;
  size_t pos_ = 0;
  bool overran_ = false;
  uint32_t range_ = 0xffffffffu;
  uint32_t code_ = 0;
};

}  // namespace psq

#endif  // PSQ_CODEC_RANGE_CODER_H_
