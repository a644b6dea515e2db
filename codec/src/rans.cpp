// SPDX-License-Identifier: Apache-2.0
// codec/src/rans.cpp: see rans.h.
#include "rans.h"

#include "container.h"

#include <algorithm>
#include <cstring>
#include <memory>

namespace psq {
namespace codec {

namespace {

int bit_length(uint32_t v) { return v == 0 ? 0 : 32 - __builtin_clz(v); }

// Elias gamma code of v >= 1, least significant bit first: n = bit length
// of v minus 1 zero bits, a one bit, then the low n bits of v.
void put_gamma(RawWriter& out, uint32_t v) {
  const int n = bit_length(v) - 1;
  out.put(0, n);
  out.put(1, 1);
  out.put(v, n);
}

// Reads a gamma code of at most `max_zeros` leading zeros; 0 when longer.
uint32_t get_gamma(RawReader& in, int max_zeros) {
  int n = 0;
  while (in.get(1) == 0) {
    if (++n > max_zeros) return 0;
  }
  return (1u << n) | in.get(n);
}

}  // namespace

void RawReader::top_up_near_end() {
  // As top_up(), a byte at a time: the bytes past words_ are zeros, and
  // pos_ goes on counting them so that consumed_bits() stays exact.
  while (n_ <= 55) {
    const uint64_t byte = pos_ < words_ ? data_[pos_] : 0;
    acc_ |= byte << n_;
    ++pos_;
    n_ += 8;
  }
}

bool RawReader::at_clean_end() const {
  if (size_ != words_ || overran()) return false;
  const uint64_t total = 8 * static_cast<uint64_t>(words_), used = consumed_bits();
  // The last word must have been reached (no whole word left unread) ...
  if (words_ != 0 && used + 32 <= total) return false;
  // ... and the bits after the last one read must be zeros.
  for (uint64_t b = used; b < total; ++b)
    if (data_[b >> 3] >> (b & 7) & 1) return false;
  return true;
}

void RansTable::build(const uint64_t* counts, int size) {
  size_ = size;
  unsigned __int128 total = 0;
  for (int s = 0; s < size; ++s) total += counts[s];
  int64_t sum = 0;
  for (int s = 0; s < size; ++s) {
    freq_[s] = 0;
    if (counts[s] == 0) continue;
    const uint32_t f = static_cast<uint32_t>((static_cast<unsigned __int128>(counts[s]) * kRansScale) / total);
    freq_[s] = static_cast<uint16_t>(std::max<uint32_t>(f, 1));
    sum += freq_[s];
  }
  // Rounding left kRansScale - sum: a surplus goes to the first most
  // counted symbol; a deficit is taken from the largest frequencies, down
  // to 1 at most.
  int64_t diff = static_cast<int64_t>(kRansScale) - sum;
  if (diff > 0) {
    int top = 0;
    for (int s = 1; s < size; ++s)
      if (counts[s] > counts[top]) top = s;
    freq_[top] = static_cast<uint16_t>(freq_[top] + diff);
  }
  while (diff < 0) {
    int top = 0;
    for (int s = 1; s < size; ++s)
      if (freq_[s] > freq_[top]) top = s;
    const int64_t take = std::min<int64_t>(-diff, freq_[top] - 1);
    freq_[top] = static_cast<uint16_t>(freq_[top] - take);
    diff += take;
  }
  finish();
}

void RansTable::write(RawWriter& out) const {
  int last = -1;
  for (int s = 0; s < size_; ++s) {
    out.put(freq_[s] != 0, 1);
    if (freq_[s] != 0) last = s;
  }
  for (int s = 0; s < last; ++s)
    if (freq_[s] != 0) put_gamma(out, freq_[s]);
}

bool RansTable::read(RawReader& in, int size) {
  size_ = 0;
  int last = -1;
  for (int s = 0; s < size; ++s) {
    freq_[s] = static_cast<uint16_t>(in.get(1));
    if (freq_[s] != 0) last = s;
  }
  if (last < 0) return false;
  uint32_t sum = 0;
  for (int s = 0; s < last; ++s) {
    if (freq_[s] == 0) continue;
    // An explicit frequency is below kRansScale: at most kRansScaleBits - 1
    // leading zeros.
    freq_[s] = static_cast<uint16_t>(get_gamma(in, kRansScaleBits - 1));  // below 2^kRansScaleBits
    if (freq_[s] == 0 || (sum += freq_[s]) >= kRansScale) return false;
  }
  freq_[last] = static_cast<uint16_t>(kRansScale - sum);
  size_ = size;
  finish();
  return true;
}

void RansTable::set_absent() {
  size_ = 0;
  for (uint32_t k = 0; k < kRansScale; ++k) sym_[k] = static_cast<uint8_t>(kRansAbsent);
  fc_[kRansAbsent] = kRansScale;  // the state stays as it is
}

void RansTable::finish() {
  uint32_t cum = 0;
  for (int s = 0; s < size_; ++s) {
    fc_[s] = freq_[s] | cum << 16;
    // The symbol's run of slots, 8 at a time: a store may run up to 7
    // slots into the next run, which that run's stores then overwrite, or
    // into the slack after the last slot. A byte at a time, this loop would
    // be a large part of decoding a small stream (bench/HISTORY.md, "Raw
    // bits without a data-dependent branch, and a stream's fixed costs").
    const uint64_t pattern = 0x0101010101010101ull * static_cast<uint64_t>(s);
    for (uint32_t k = 0; k < freq_[s]; k += 8) std::memcpy(sym_ + cum + k, &pattern, 8);
    cum += freq_[s];
  }
}

void rans_encode(const RansSymbol* symbols, size_t count, const RansTable* tables, size_t ntables,
                 std::vector<uint8_t>* out) {
  // At most one renormalization word per symbol: written through a
  // pointer, without a capacity test per word.
  std::unique_ptr<uint16_t[]> word_buffer(new uint16_t[count + 1]);  // not zeroed
  uint16_t* words = word_buffer.get();
  size_t nwords = 0;
  // The reciprocals of the symbols that occur (the others are not read).
  std::unique_ptr<uint64_t[]> reciprocals(new uint64_t[ntables * kRansMaxSymbols]);  // not zeroed
  for (size_t t = 0; t < ntables; ++t) {
    uint64_t* r = reciprocals.get() + t * kRansMaxSymbols;
    for (int s = 0; s < tables[t].size(); ++s)
      if (tables[t].freq(s) != 0) r[s] = rans_reciprocal(tables[t].freq(s));
  }
  // One symbol into state x. The renormalization keeps the next state
  // below 2^32 (x < 2^(32 - kRansScaleBits) f); its word is stored either way and counted
  // when taken, and the division by f is a multiplication by f's
  // reciprocal: a branch there would be mispredicted, and a division is
  // slow, on each state's chain.
  auto step = [&](uint32_t& x, const RansSymbol& sym) __attribute__((always_inline)) {
    const RansTable& t = tables[sym.table];
    const uint32_t f = t.freq(sym.symbol), c = t.cum(sym.symbol);
    const uint32_t renorm = uint64_t{x} >= uint64_t{f} << (32 - kRansScaleBits);
    words[nwords] = static_cast<uint16_t>(x);
    nwords += renorm;
    x >>= renorm << 4;
    const uint64_t m = reciprocals[size_t{sym.table} * kRansMaxSymbols + sym.symbol];
    const uint32_t q = static_cast<uint32_t>((static_cast<unsigned __int128>(x) * m) >> 42);
    // (q << kRansScaleBits) + (x - q f) + c, the encoding step of rANS.
    x = x + c + q * (kRansScale - f);
  };
  // Symbol i goes through state i mod 2, as the decoder alternates; the
  // two states live in registers (an array indexed by i & 1 put a store
  // and a load on each chain).
  uint32_t x0 = kRansLow, x1 = kRansLow;
  size_t i = count;
  if (i % 2 == 1) {
    --i;
    step(x0, symbols[i]);
  }
  for (; i > 0; i -= 2) {
    step(x1, symbols[i - 1]);
    step(x0, symbols[i - 2]);
  }
  const uint32_t x[2] = {x0, x1};
  const size_t at = out->size();
  out->resize(at + 8 + 2 * nwords);
  uint8_t* o = out->data() + at;
  for (int k = 0; k < 2; ++k)
    for (int b = 0; b < 4; ++b) *o++ = static_cast<uint8_t>(x[k] >> (8 * b));
  for (size_t w = nwords; w-- > 0;) {
    *o++ = static_cast<uint8_t>(words[w]);
    *o++ = static_cast<uint8_t>(words[w] >> 8);
  }
}

RansDecoder::RansDecoder(const uint8_t* data, size_t size) : data_(data), size_(size) {
  if (size < 8) {
    overran_ = true;
    pos_ = size;
    x_ = y_ = kRansLow;
    return;
  }
  x_ = data[0] | uint32_t{data[1]} << 8 | uint32_t{data[2]} << 16 | uint32_t{data[3]} << 24;
  y_ = data[4] | uint32_t{data[5]} << 8 | uint32_t{data[6]} << 16 | uint32_t{data[7]} << 24;
  pos_ = 8;
}

std::vector<uint8_t> RawWriter::finish() {
  const size_t words = (static_cast<size_t>(bits()) + 31) / 32;
  std::vector<uint8_t> out(4 * words);  // zero padding
  std::copy(bytes_.data(), bytes_.data() + pos_, out.begin());
  if (n_ > 0) out[pos_] = static_cast<uint8_t>(acc_);
  pos_ = 0;
  acc_ = 0;
  n_ = 0;
  return out;
}

const char* split_rans_section(const uint8_t* data, size_t size, RansSection* out) {
  uint64_t table_bytes = 0, rans_bytes = 0;
  const int n1 = parse_varint(data, size, &table_bytes);
  if (n1 <= 0) return "malformed table block length";
  const int n2 = parse_varint(data + n1, size - static_cast<size_t>(n1), &rans_bytes);
  if (n2 <= 0) return "malformed rANS block length";
  const size_t at = static_cast<size_t>(n1 + n2);
  if (table_bytes > size - at || rans_bytes > size - at - table_bytes) return "block lengths exceed the section";
  out->tables_at = at;
  out->tables = data + at;
  out->table_bytes = static_cast<size_t>(table_bytes);
  out->rans = out->tables + table_bytes;
  out->rans_bytes = static_cast<size_t>(rans_bytes);
  out->raw = out->rans + rans_bytes;
  out->raw_bytes = size - at - out->table_bytes - out->rans_bytes;
  return nullptr;
}

void put_rans_section(const std::vector<uint8_t>& tables, const std::vector<uint8_t>& rans,
                      const std::vector<uint8_t>& raw, std::vector<uint8_t>* out) {
  Put put(out);
  put.varint(tables.size());
  put.varint(rans.size());
  put.bytes(tables.data(), tables.size());
  put.bytes(rans.data(), rans.size());
  put.bytes(raw.data(), raw.size());
}

}  // namespace codec
}  // namespace psq
