// SPDX-License-Identifier: Apache-2.0
// The adaptive binary range coder (range_coder.h). A range coder in
// the style of Martin (1979), with 32-bit range, bottom renormalisation by
// bytes and carry propagation through a cached byte and a run of 0xff bytes
// (the scheme of Subbotin's and LZMA's coders); 16-bit adaptive bit models
// whose update rate slows as they learn (adapt_step).
#include "range_coder.h"

namespace psq {
namespace {

constexpr uint32_t kTop = 1u << 24;

}  // namespace

SymbolModel::SymbolModel(int bits) : bits_(bits < 1 ? 1 : bits > 16 ? 16 : bits), tree_(size_t{1} << bits_) {}

// ------------------------------------------------------------------ encoder

RangeEncoder::RangeEncoder(std::vector<uint8_t>* out) : out_(out) {}

void RangeEncoder::shift_low() {
  // The top byte of low is final unless a carry may still reach it: hold it
  // (and any 0xff bytes after it) until the carry is known.
  if (static_cast<uint32_t>(low_) < 0xff000000u || (low_ >> 32) != 0) {
    uint8_t carry = static_cast<uint8_t>(low_ >> 32);
    uint8_t byte = cache_;
    do {
      out_->push_back(static_cast<uint8_t>(byte + carry));
      byte = 0xff;
    } while (--cache_size_ != 0);
    cache_ = static_cast<uint8_t>(low_ >> 24);
  }
  ++cache_size_;
  low_ = (low_ & 0x00ffffffu) << 8;
}

void RangeEncoder::encode_symbol(SymbolModel& m, uint32_t symbol) {
  BitModel* tree = m.tree();
  uint32_t node = 1;
  for (int i = m.bits() - 1; i >= 0; --i) {
    int bit = static_cast<int>((symbol >> i) & 1u);
    encode_bit(tree[node], bit);
    node = (node << 1) | static_cast<uint32_t>(bit);
  }
}

void RangeEncoder::encode_raw(uint32_t value, int bits) {
  // Up to 16 bits at a time: the range keeps at least 2^24 before, so at
  // least 2^8 after dividing it into 2^16 equal parts.
  while (bits > 0) {
    int n = bits > 16 ? 16 : bits;
    bits -= n;
    uint32_t part = (value >> bits) & ((1u << n) - 1);
    range_ >>= n;
    low_ += static_cast<uint64_t>(part) * range_;
    while (range_ < kTop) {
      range_ <<= 8;
      shift_low();
    }
  }
}

void RangeEncoder::finish() {
  for (int i = 0; i < 5; ++i) shift_low();
}

// ------------------------------------------------------------------ decoder

RangeDecoder::RangeDecoder(const uint8_t* data, size_t size) : data_(data), size_(size) {
  // The encoder's first byte is the initial (empty) cache; the next four
  // fill the code register.
  for (int i = 0; i < 5; ++i) code_ = (code_ << 8) | next_byte();
}

uint32_t RangeDecoder::decode_symbol(SymbolModel& m) {
  BitModel* tree = m.tree();
  uint32_t node = 1;
  for (int i = 0; i < m.bits(); ++i) node = (node << 1) | static_cast<uint32_t>(decode_bit(tree[node]));
  return node - (1u << m.bits());
}

uint32_t RangeDecoder::decode_raw(int bits) {
  uint32_t value = 0;
  while (bits > 0) {
    int n = bits > 16 ? 16 : bits;
    bits -= n;
    value = (value << n) | decode_raw_short(n);
  }
  return value;
}

}  // namespace psq
