// SPDX-License-Identifier: Apache-2.0
// The fast profile's static rANS coder and raw bit stream (codec/src/rans.h).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <utility>
#include <vector>

#include "rans.h"

namespace psq {
namespace codec {
namespace {

void rans_encode(const std::vector<RansSymbol>& symbols, const RansTable* tables, std::vector<uint8_t>* out) {
  size_t ntables = 0;
  for (const RansSymbol& s : symbols) ntables = std::max<size_t>(ntables, s.table + size_t{1});
  codec::rans_encode(symbols.data(), symbols.size(), tables, ntables, out);
}

TEST(RawBits, RoundTripsEveryWidth) {
  std::mt19937 rng(1);
  RawWriter w;
  std::vector<std::pair<uint32_t, int>> items;
  for (int i = 0; i < 5000; ++i) {
    const int bits = static_cast<int>(rng() % 33);
    const uint32_t v = bits == 32 ? static_cast<uint32_t>(rng()) : static_cast<uint32_t>(rng()) & ((1u << bits) - 1);
    items.push_back({v, bits});
    w.put(v, bits);
  }
  const uint64_t written = w.bits();
  std::vector<uint8_t> bytes = w.finish();
  EXPECT_EQ(bytes.size(), (written + 31) / 32 * 4);
  RawReader r(bytes.data(), bytes.size());
  for (const auto& [v, bits] : items) ASSERT_EQ(r.get(bits), v);
  EXPECT_TRUE(r.at_clean_end());
  EXPECT_FALSE(r.overran());
}

TEST(RawBits, PutKeepsOnlyTheLowBits) {
  RawWriter w;
  w.put(0xffffffffu, 3);
  w.put(0, 29);
  std::vector<uint8_t> bytes = w.finish();
  ASSERT_EQ(bytes.size(), 4u);
  EXPECT_EQ(bytes[0], 7);
  EXPECT_EQ(bytes[1] | bytes[2] | bytes[3], 0);
}

TEST(RawBits, ReadingPastTheEndSetsOverrun) {
  const uint8_t data[6] = {0xff, 0xff, 0xff, 0xff, 0xab, 0xcd};
  RawReader r(data, sizeof data);
  EXPECT_EQ(r.get(32), 0xffffffffu);
  EXPECT_FALSE(r.overran());
  EXPECT_EQ(r.get(8), 0u);  // the 2 trailing bytes are not a whole word
  EXPECT_TRUE(r.overran());
  EXPECT_FALSE(r.at_clean_end());
}

TEST(RawBits, NonzeroPaddingIsNotACleanEnd) {
  const uint8_t data[4] = {0x01, 0x00, 0x00, 0x80};
  RawReader r(data, sizeof data);
  EXPECT_EQ(r.get(1), 1u);
  EXPECT_FALSE(r.at_clean_end());
}

// The reader fills its accumulator 8 bytes at a time away from the end
// and a byte at a time near it: against a reader of one bit at a time, on
// streams of every length up to 40 bytes (whole words or not), read in
// random widths until well past the end.
TEST(RawBits, MatchesABitAtATimeReaderUpToAndPastTheEnd) {
  std::mt19937 rng(3);
  for (size_t size = 0; size <= 40; ++size) {
    for (int trial = 0; trial < 20; ++trial) {
      std::vector<uint8_t> data(size);
      for (auto& b : data) b = static_cast<uint8_t>(rng());
      const uint64_t whole = 8 * static_cast<uint64_t>(size & ~size_t{3});
      RawReader r(data.data(), data.size());
      uint64_t at = 0;
      while (at < whole + 100) {
        const int bits = static_cast<int>(rng() % 33);
        uint32_t expect = 0;
        for (int i = 0; i < bits; ++i) {
          const uint64_t b = at + static_cast<uint64_t>(i);
          if (b < whole && (data[b >> 3] >> (b & 7) & 1)) expect |= 1u << i;
        }
        ASSERT_EQ(r.get(bits), expect) << "size " << size << " at bit " << at;
        at += static_cast<uint64_t>(bits);
        ASSERT_EQ(r.consumed_bits(), at);
        ASSERT_EQ(r.overran(), at > whole);
      }
    }
  }
}

TEST(RawBits, AWordLeftUnreadIsNotACleanEnd) {
  const uint8_t data[8] = {0x01, 0, 0, 0, 0, 0, 0, 0};
  RawReader r(data, sizeof data);
  EXPECT_EQ(r.get(1), 1u);
  EXPECT_FALSE(r.at_clean_end());  // the second word is unread
  EXPECT_EQ(r.get(31), 0u);
  EXPECT_FALSE(r.at_clean_end());
  EXPECT_EQ(r.get(1), 0u);
  EXPECT_TRUE(r.at_clean_end());
  const uint8_t empty[1] = {0};
  EXPECT_TRUE(RawReader(empty, 0).at_clean_end());
  EXPECT_FALSE(RawReader(empty, 1).at_clean_end());  // not a whole word
}

TEST(RansTable, BuildSumsToTheScaleAndKeepsEveryCountedSymbol) {
  std::mt19937_64 rng(2);
  for (int trial = 0; trial < 200; ++trial) {
    const int size = 1 + static_cast<int>(rng() % kRansMaxSymbols);
    std::vector<uint64_t> counts(size);
    bool any = false;
    for (auto& c : counts) {
      const int kind = static_cast<int>(rng() % 4);
      c = kind == 0 ? 0 : kind == 1 ? 1 : kind == 2 ? rng() % 1000 : rng() % (uint64_t{1} << 40);
      any |= c != 0;
    }
    if (!any) counts[0] = 5;
    RansTable t;
    t.build(counts.data(), size);
    uint32_t sum = 0;
    for (int s = 0; s < size; ++s) {
      EXPECT_EQ(t.freq(s) == 0, counts[s] == 0) << "trial " << trial << " symbol " << s;
      EXPECT_EQ(t.cum(s), sum);
      sum += t.freq(s);
    }
    EXPECT_EQ(sum, kRansScale);
  }
}

TEST(RansTable, WriteReadRoundTrips) {
  std::mt19937_64 rng(3);
  for (int trial = 0; trial < 200; ++trial) {
    const int size = 1 + static_cast<int>(rng() % kRansMaxSymbols);
    std::vector<uint64_t> counts(size, 0);
    const int used = 1 + static_cast<int>(rng() % size);
    for (int i = 0; i < used; ++i) counts[rng() % size] += 1 + rng() % 10000;
    RansTable t;
    t.build(counts.data(), size);
    RawWriter w;
    t.write(w);
    w.put(0x5a, 8);  // what follows the table must still be in place
    std::vector<uint8_t> bytes = w.finish();
    RawReader r(bytes.data(), bytes.size());
    RansTable u;
    ASSERT_TRUE(u.read(r, size));
    for (int s = 0; s < size; ++s) ASSERT_EQ(u.freq(s), t.freq(s));
    for (uint32_t k = 0; k < kRansScale; ++k) ASSERT_EQ(u.symbol_at(k), t.symbol_at(k));
    for (int s = 0; s < size; ++s) ASSERT_EQ(u.freq_cum(s), t.freq_cum(s));
    EXPECT_EQ(r.get(8), 0x5au);
    EXPECT_FALSE(r.overran());
  }
}

TEST(RansTable, ReadRejectsInvalidTables) {
  {  // no present symbol
    RawWriter w;
    w.put(0, 5);
    std::vector<uint8_t> b = w.finish();
    RawReader r(b.data(), b.size());
    RansTable t;
    EXPECT_FALSE(t.read(r, 5));
  }
  {  // explicit frequencies reaching the scale: nothing left for the last symbol
    RawWriter w;
    w.put(0b111, 3);
    // Two explicit halves of the scale (valid gamma codes) leave nothing.
    for (uint32_t f : {kRansScale / 2, kRansScale / 2}) {
      const int n = 31 - __builtin_clz(f);
      w.put(0, n);
      w.put(1, 1);
      w.put(f, n);
    }
    std::vector<uint8_t> b = w.finish();
    RawReader r(b.data(), b.size());
    RansTable t;
    EXPECT_FALSE(t.read(r, 3));
  }
  {  // a gamma code that is too long (and zero bits past the end)
    RawWriter w;
    w.put(0b11, 2);
    std::vector<uint8_t> b = w.finish();
    RawReader r(b.data(), b.size());
    RansTable t;
    EXPECT_FALSE(t.read(r, 2));
  }
}

// Spec 13.5.1 (format 9.0, M = 2^8): an explicit frequency is a gamma code
// of at most 7 leading zeros, so below 2^8; a code with an eighth zero
// makes the table invalid, even when the bits that follow are there.
TEST(RansTable, GammaCodesStopAtSevenLeadingZeros) {
  static_assert(kRansScaleBits == 8, "the spec's limits below are those of M = 2^8");
  auto table_with_leading_zeros = [](int zeros) {
    RawWriter w;
    w.put(0b11, 2);  // symbols 0 and 1 present; symbol 0's frequency is explicit
    w.put(0, zeros);
    w.put(1, 1);
    w.put(0, zeros);  // the frequency 2^zeros
    w.put(0xffffffffu, 32);  // more bits, so that the end of the data is not what fails
    std::vector<uint8_t> b = w.finish();
    RawReader r(b.data(), b.size());
    RansTable t;
    const bool ok = t.read(r, 2);
    return std::make_pair(ok, ok ? t.freq(0) : 0u);
  };
  // 2^6 and 2^7: valid, and the last symbol takes the rest of 256.
  EXPECT_EQ(table_with_leading_zeros(6), std::make_pair(true, 64u));
  EXPECT_EQ(table_with_leading_zeros(7), std::make_pair(true, 128u));
  // Eight zeros would code 2^8 or more: invalid.
  EXPECT_FALSE(table_with_leading_zeros(8).first);
}

TEST(RansTable, AbsentTableDecodesTheAbsentSymbolAndKeepsTheState) {
  std::vector<uint64_t> counts = {3, 1};
  RansTable present;
  present.build(counts.data(), 2);
  RansTable absent;  // a new table is absent
  EXPECT_TRUE(absent.empty());
  std::vector<RansSymbol> syms = {{0, 0}, {0, 1}, {0, 0}};
  std::vector<uint8_t> bytes;
  rans_encode(syms, &present, &bytes);
  RansDecoder d(bytes.data(), bytes.size());
  EXPECT_EQ(d.decode(present), 0);
  // Each decode passes the turn to the other of the two states; an absent
  // table changes neither state, so two absent decodes give the turn back.
  EXPECT_EQ(d.decode(absent), kRansAbsent);
  EXPECT_EQ(d.decode(absent), kRansAbsent);
  EXPECT_EQ(d.decode(present), 1);
  EXPECT_EQ(d.decode(present), 0);
  EXPECT_TRUE(d.at_clean_end());
  // set_absent() on a table that was read or built makes it absent again.
  present.set_absent();
  EXPECT_TRUE(present.empty());
  EXPECT_EQ(present.symbol_at(0), static_cast<uint32_t>(kRansAbsent));
}

// A table's decoding array gives every slot the symbol whose run of
// cumulative frequencies holds it (the runs are filled 8 slots at a
// store, overlapping the next run), for tables of runs of every length.
TEST(RansTable, EverySlotDecodesToTheSymbolOfItsRun) {
  std::mt19937_64 rng(4);
  for (int trial = 0; trial < 300; ++trial) {
    const int size = 1 + static_cast<int>(rng() % kRansMaxSymbols);
    std::vector<uint64_t> counts(size);
    for (auto& c : counts) c = rng() % 3 == 0 ? 0 : 1 + rng() % (trial % 2 ? 20 : 5000);
    counts[rng() % size] += 1;
    RansTable t;
    t.build(counts.data(), size);
    for (int s = 0; s < size; ++s)
      for (uint32_t k = 0; k < t.freq(s); ++k)
        ASSERT_EQ(t.symbol_at(t.cum(s) + k), static_cast<uint32_t>(s)) << "trial " << trial << " symbol " << s;
  }
}

// The encoder divides a state by a frequency as a multiplication by the
// frequency's reciprocal and a shift by 42: exact for every frequency and
// every 32-bit state (checked at the ends of the range, around multiples
// of the frequency, and at random).
TEST(RansTable, ReciprocalDividesExactly) {
  std::mt19937_64 rng(5);
  for (uint32_t f = 1; f <= kRansScale; ++f) {
    const uint64_t m = rans_reciprocal(f);
    auto check = [&](uint32_t x) {
      ASSERT_EQ(static_cast<uint32_t>((static_cast<unsigned __int128>(x) * m) >> 42), x / f) << x << " / " << f;
    };
    for (uint32_t x : {0u, 1u, f - 1, f, f + 1, 0xffffffffu, 0xfffffffeu, (0xffffffffu / f) * f, (0xffffffffu / f) * f - 1})
      check(x);
    for (int k = 0; k < 2000; ++k) {
      const uint32_t q = static_cast<uint32_t>(rng() % (uint64_t{0xffffffffu} / f + 1));
      check(q * f);
      if (q * f > 0) check(q * f - 1);
      check(static_cast<uint32_t>(rng()));
    }
  }
}

// Symbols from a few skewed distributions, coded and decoded back; the
// coded size is close to the symbols' empirical entropy under the tables.
TEST(Rans, RoundTripsAndCodesNearTheEntropy) {
  std::mt19937_64 rng(4);
  const int kTables = 6;
  const int sizes[kTables] = {1, 2, 5, 20, 62, 127};
  std::vector<RansSymbol> syms;
  std::vector<std::vector<uint64_t>> counts(kTables);
  for (int t = 0; t < kTables; ++t) counts[t].assign(sizes[t], 0);
  for (int i = 0; i < 200000; ++i) {
    const int t = static_cast<int>(rng() % kTables);
    // Geometric-like: small symbols are frequent.
    int s = 0;
    while (s + 1 < sizes[t] && rng() % 3 != 0) ++s;
    syms.push_back({static_cast<uint16_t>(t), static_cast<uint8_t>(s)});
    ++counts[t][s];
  }
  std::vector<RansTable> tables(kTables);
  for (int t = 0; t < kTables; ++t) tables[t].build(counts[t].data(), sizes[t]);
  std::vector<uint8_t> bytes;
  rans_encode(syms, tables.data(), &bytes);
  double entropy_bits = 0;
  for (const RansSymbol& s : syms) entropy_bits -= std::log2(tables[s.table].freq(s.symbol) / double(kRansScale));
  EXPECT_LT(bytes.size(), entropy_bits / 8 * 1.002 + 16);
  EXPECT_GT(bytes.size(), entropy_bits / 8 * 0.998 - 16);
  RansDecoder d(bytes.data(), bytes.size());
  for (size_t i = 0; i < syms.size(); ++i) ASSERT_EQ(d.decode(tables[syms[i].table]), syms[i].symbol) << i;
  EXPECT_TRUE(d.at_clean_end());
}

TEST(Rans, TruncatedAndCorruptStreamsDecodeSafely) {
  std::mt19937_64 rng(5);
  std::vector<uint64_t> counts(20);
  for (auto& c : counts) c = 1 + rng() % 100;
  RansTable t;
  t.build(counts.data(), 20);
  std::vector<RansSymbol> syms;
  for (int i = 0; i < 5000; ++i) syms.push_back({0, static_cast<uint8_t>(rng() % 20)});
  std::vector<uint8_t> bytes;
  rans_encode(syms, &t, &bytes);
  for (size_t cut : {size_t{0}, size_t{3}, bytes.size() / 2, bytes.size() - 1}) {
    RansDecoder d(bytes.data(), cut);
    for (size_t i = 0; i < syms.size(); ++i) {
      const int s = d.decode(t);
      ASSERT_GE(s, 0);
      ASSERT_LT(s, 20);
    }
    EXPECT_TRUE(d.overran()) << cut;
    EXPECT_FALSE(d.at_clean_end());
  }
  std::vector<uint8_t> garbage(4000);
  for (auto& b : garbage) b = static_cast<uint8_t>(rng());
  RansDecoder g(garbage.data(), garbage.size());
  for (size_t i = 0; i < syms.size(); ++i) ASSERT_LT(g.decode(t), 20);
  // A flipped bit is caught at the end: the state does not come back to
  // its start value, or bytes are left over or missing.
  std::vector<uint8_t> flipped = bytes;
  flipped[flipped.size() / 3] ^= 0x10;
  RansDecoder f(flipped.data(), flipped.size());
  bool same = true;
  for (size_t i = 0; i < syms.size(); ++i) same &= f.decode(t) == syms[i].symbol;
  EXPECT_FALSE(same && f.at_clean_end());
}

}  // namespace
}  // namespace codec
}  // namespace psq
