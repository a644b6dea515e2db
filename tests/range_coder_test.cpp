// SPDX-License-Identifier: Apache-2.0
// The range coder: exact round trips of bits, symbols and raw bits;
// compression close to the entropy; safe decoding of truncated
// and corrupt streams.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "range_coder.h"

namespace psq {
namespace {

struct Op {
  int kind;  // 0 bit, 1 symbol, 2 raw
  uint32_t value;
  int bits;
};

std::vector<Op> random_ops(uint32_t seed, size_t n) {
  std::mt19937 rng(seed);
  std::vector<Op> ops;
  for (size_t i = 0; i < n; ++i) {
    Op op{static_cast<int>(rng() % 3), 0, 0};
    switch (op.kind) {
      case 0: op.value = (rng() % 10) < 2 ? 1 : 0; break;
      case 1: op.value = rng() % 37 < 30 ? rng() % 4 : rng() % 256; break;
      case 2: op.bits = static_cast<int>(rng() % 33); op.value = op.bits == 32 ? rng() : rng() & ((1u << op.bits) - 1); break;
    }
    ops.push_back(op);
  }
  return ops;
}

std::vector<uint8_t> encode(const std::vector<Op>& ops) {
  std::vector<uint8_t> bytes;
  RangeEncoder enc(&bytes);
  BitModel bit;
  SymbolModel sym(8);
  for (const Op& op : ops) {
    switch (op.kind) {
      case 0: enc.encode_bit(bit, static_cast<int>(op.value)); break;
      case 1: enc.encode_symbol(sym, op.value); break;
      case 2: enc.encode_raw(op.value, op.bits); break;
    }
  }
  enc.finish();
  return bytes;
}

// Decodes `ops`' shapes from `bytes`; returns how many values matched.
size_t decode_matches(const std::vector<Op>& ops, const std::vector<uint8_t>& bytes, bool* overran) {
  RangeDecoder dec(bytes.data(), bytes.size());
  BitModel bit;
  SymbolModel sym(8);
  size_t matched = 0;
  for (const Op& op : ops) {
    uint32_t v = 0;
    switch (op.kind) {
      case 0: v = static_cast<uint32_t>(dec.decode_bit(bit)); break;
      case 1: v = dec.decode_symbol(sym); break;
      case 2: v = dec.decode_raw(op.bits); break;
    }
    if (v == op.value) ++matched;
  }
  *overran = dec.overran();
  return matched;
}

TEST(RangeCoder, RoundTripsEveryKindOfValue) {
  for (uint32_t seed = 1; seed <= 5; ++seed) {
    std::vector<Op> ops = random_ops(seed, 20000);
    std::vector<uint8_t> bytes = encode(ops);
    bool overran = true;
    EXPECT_EQ(decode_matches(ops, bytes, &overran), ops.size()) << "seed " << seed;
    EXPECT_FALSE(overran);
  }
}

// decode_raw_short() is decode_raw() for 1 to 16 bits: the same values,
// position and overrun, on valid streams and on garbage.
TEST(RangeCoder, ShortRawDecodesAsRaw) {
  std::mt19937 rng(11);
  for (int round = 0; round < 40; ++round) {
    std::vector<uint8_t> bytes;
    if (round % 2 == 0) {
      bytes = encode(random_ops(100 + round, 2000));
    } else {
      bytes.resize(rng() % 300);
      for (uint8_t& b : bytes) b = static_cast<uint8_t>(rng());
    }
    RangeDecoder a(bytes.data(), bytes.size()), b(bytes.data(), bytes.size());
    BitModel ma, mb;
    for (int i = 0; i < 3000; ++i) {
      if (rng() % 3 == 0) {
        ASSERT_EQ(a.decode_bit(ma), b.decode_bit(mb));
      } else {
        const int bits = 1 + static_cast<int>(rng() % 16);
        ASSERT_EQ(a.decode_raw(bits), b.decode_raw_short(bits)) << "round " << round << " op " << i;
      }
      ASSERT_EQ(a.overran(), b.overran());
      ASSERT_EQ(a.consumed(), b.consumed());
    }
  }
}

TEST(RangeCoder, SkewedBitsCostCloseToTheirEntropy) {
  std::mt19937 rng(3);
  const double p1 = 0.05;
  const size_t n = 200000;
  std::vector<uint8_t> bytes;
  RangeEncoder enc(&bytes);
  BitModel m;
  size_t ones = 0;
  for (size_t i = 0; i < n; ++i) {
    int b = std::uniform_real_distribution<double>(0, 1)(rng) < p1 ? 1 : 0;
    ones += static_cast<size_t>(b);
    enc.encode_bit(m, b);
  }
  enc.finish();
  double p = static_cast<double>(ones) / n;
  double entropy_bits = n * -(p * std::log2(p) + (1 - p) * std::log2(1 - p));
  double coded_bits = 8.0 * static_cast<double>(bytes.size());
  EXPECT_LT(coded_bits, entropy_bits * 1.06) << coded_bits << " vs entropy " << entropy_bits;
}

TEST(RangeCoder, TruncatedAndCorruptStreamsDecodeSafely) {
  std::vector<Op> ops = random_ops(9, 3000);
  std::vector<uint8_t> bytes = encode(ops);
  // Every prefix: decoding never reads outside the span, and a prefix that
  // lacks bytes the values need is reported (the last flushed bytes may not
  // be needed, so the cut leaves them out of the claim).
  for (size_t cut = 0; cut + 5 < bytes.size(); cut += 7) {
    std::vector<uint8_t> prefix(bytes.begin(), bytes.begin() + static_cast<std::ptrdiff_t>(cut));
    bool overran = false;
    decode_matches(ops, prefix, &overran);
    EXPECT_TRUE(overran) << "prefix " << cut << " of " << bytes.size();
  }
  std::mt19937 rng(4);
  for (int i = 0; i < 200; ++i) {
    std::vector<uint8_t> bad = bytes;
    bad[rng() % bad.size()] ^= static_cast<uint8_t>(1u << (rng() % 8));
    bool overran = false;
    decode_matches(ops, bad, &overran);  // must not crash; values are garbage
  }
  // An empty input decodes as overrun at once.
  RangeDecoder empty(nullptr, 0);
  EXPECT_TRUE(empty.overran());
}

TEST(RangeCoder, DeterministicBytes) {
  std::vector<Op> ops = random_ops(11, 5000);
  EXPECT_EQ(encode(ops), encode(ops));
}

}  // namespace
}  // namespace psq
