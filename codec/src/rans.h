// SPDX-License-Identifier: Apache-2.0
// codec/src/rans.h: static rANS coding, the entropy coder of the rANS
// back-end (spec 13.4, 13.5), and the raw bit stream of both back-ends
// (13.3).
//
// rANS (Duda, "Asymmetric numeral systems", 2013) with 32-bit states kept
// in [2^16, 2^32) and renormalized by 16-bit words, in the style of
// Giesen's rans_word; two states take turns, symbol i using state i mod 2
// (Giesen's interleaving), so that decoding one symbol need not wait for
// the state the symbol before produced. Each context has a frequency table
// of total 2^kRansScaleBits, fixed for a chunk and sent in it
// (RansTable::write), so decoding a symbol is one table lookup, one
// multiplication and a renormalization test: no model update. That is what
// makes the rANS back-end decode several times faster than the adaptive
// one (bench/RESULTS.md has the current figures).
//
// The encoder codes in reverse: it collects a chunk's symbols first, then
// builds the tables from their counts and codes the symbols last to first,
// so that the decoder reads them first to last.
//
// Raw bits (signs and low bits of residuals, explicit slots) go to a
// separate little-endian bit stream (RawWriter, RawReader) instead of
// through the symbol coder: they cost a branchless refill, a shift and a
// mask each to read.
#ifndef PSQ_CODEC_RANS_H_
#define PSQ_CODEC_RANS_H_

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "coding.h"  // ArrayStack
#include "psq/psq_memory.h"  // DefaultInitAllocator

namespace psq {
namespace codec {

// The scale M = 2^8 (spec 13.4.1): a table's slot array takes 256 bytes,
// so that many of a chunk's tables stay in the first-level cache, which
// makes decoding faster, and a table costs few bytes to send
// (bench/HISTORY.md, "Format 9.0").
constexpr int kRansScaleBits = 8;
constexpr uint32_t kRansScale = 1u << kRansScaleBits;
constexpr uint32_t kRansLow = 1u << 16;  // the state's lower bound
// The largest alphabet of a table: symbols are 0..kRansMaxSymbols - 1.
constexpr int kRansMaxSymbols = 127;
// What an absent table decodes (RansTable::set_absent).
constexpr int kRansAbsent = 127;

class RawWriter;
class RawReader;

// A frequency table: for each symbol of an alphabet of size() symbols, a
// frequency (0: the symbol does not occur), summing to kRansScale.
class RansTable {
 public:
  // An empty table, absent (set_absent()): no symbol can be coded with it,
  // and decoding with it yields kRansAbsent. Only what that needs is
  // written (a decoder holds 180 tables, 500 KiB that zeroing would
  // touch per stream; build() and read() set the rest).
  RansTable() { set_absent(); }

  // Frequencies from symbol counts (counts[0..size - 1], any scale, at
  // least one nonzero; size 1..kRansMaxSymbols): proportional, every
  // counted symbol at least 1, and the rounding error given to or taken
  // from the most frequent symbols. Deterministic: the encoder's output
  // depends on it.
  void build(const uint64_t* counts, int size);

  // Writes the table: per symbol, a presence bit and, for a present symbol
  // other than the last present one, its frequency as an Elias gamma code;
  // the last present symbol's frequency is what remains of kRansScale.
  void write(RawWriter& out) const;
  // Reads a table of `size` symbols as write() wrote it. Returns false when
  // the frequencies are not a valid table: no present symbol, a gamma code
  // of more than kRansScaleBits - 1 leading zeros, or explicit frequencies that leave nothing for
  // the last present symbol. The reader's own overrun flag tells whether
  // the bits ran out.
  bool read(RawReader& in, int size);

  // A table that a chunk does not send: decoding with it yields
  // kRansAbsent (outside every alphabet) and leaves the state unchanged
  // (the turn still passes to the other state), so the decoder needs no
  // test for absent tables beyond its range checks.
  void set_absent();

  int size() const { return size_; }
  bool empty() const { return size_ == 0; }
  uint32_t freq(int s) const { return freq_[s]; }
  uint32_t cum(int s) const { return fc_[s] >> 16; }
  // The symbol of a state's low kRansScaleBits bits, and that symbol's
  // frequency (bits 0..15) and cumulative frequency (bits 16..31); an
  // absent table's symbol kRansAbsent has frequency kRansScale at 0.
  uint32_t symbol_at(uint32_t slot) const { return sym_[slot]; }
  uint32_t freq_cum(uint32_t s) const { return fc_[s]; }

 private:
  void finish();  // cumulative frequencies and the decoding arrays from freq_

  int size_ = 0;
  // Frequencies (at most kRansScale); the cumulative ones live in fc_. A
  // chunk's 180 tables are built anew for every decoder, so their size is
  // pages touched per stream: 1 KiB each.
  uint16_t freq_[kRansMaxSymbols];
  // Decoding: a byte per slot (256 bytes, a quarter of a table of whole
  // entries, so that a chunk's tables stay in the cache) and the
  // frequencies beside it.
  uint32_t fc_[kRansAbsent + 1];
  uint8_t sym_[kRansScale + 8];  // 8 bytes of slack for finish()'s stores
};

// A symbol to code: its table (an index into the caller's tables) and value.
struct RansSymbol {
  uint16_t table;
  uint8_t symbol;
};

// Codes `symbols` with `tables` (each symbol's table must give it a nonzero
// frequency), symbol i with state i mod 2, and appends the bytes to `out`:
// the final states of symbols 0 and 1 as 4 bytes each, then the
// renormalization words, all little-endian, in the order the decoder reads
// them.
// `ntables`: how many tables there are (every symbol's table is below it).
void rans_encode(const RansSymbol* symbols, size_t count, const RansTable* tables, size_t ntables,
                 std::vector<uint8_t>* out);

// A section of three blocks (spec 13.2.2 for records, 8.3 for
// attributes): the sizes of the table block and of the rANS block as
// varints, then the table block, the rANS block and the raw block, which
// takes the rest.
struct RansSection {
  const uint8_t* tables;
  size_t table_bytes;
  const uint8_t* rans;
  size_t rans_bytes;
  const uint8_t* raw;
  size_t raw_bytes;
  size_t tables_at;  // the table block's offset in the section
};
// Splits the `size` bytes at `data`; nullptr, or what is wrong with them.
const char* split_rans_section(const uint8_t* data, size_t size, RansSection* out);
// Appends a section of these blocks to `out`.
void put_rans_section(const std::vector<uint8_t>& tables, const std::vector<uint8_t>& rans,
                      const std::vector<uint8_t>& raw, std::vector<uint8_t>* out);

// The encoder's reciprocal of a frequency f in 1..kRansScale:
// ceil(2^42 / f), so that x / f = (x * rans_reciprocal(f)) >> 42 for every
// 32-bit x (Granlund and Montgomery, "Division by invariant integers using
// multiplication", 1994, theorem 4.2: m f lies in [2^42, 2^42 + f), within [2^42, 2^42 + 2^10)).
inline uint64_t rans_reciprocal(uint32_t f) { return ((uint64_t{1} << 42) + f - 1) / f; }

// The symbols of the chunk an encoder has open, in order.
using RansSymbols = ArrayStack<RansSymbol, 4096>;

class RansDecoder {
 public:
  // Decodes from `size` bytes at `data`, which must outlive the decoder.
  RansDecoder(const uint8_t* data, size_t size);

  // The next symbol, coded with table `t` (built, read or absent).
  // Symbols alternate between two states, so that the decoding of one
  // does not wait for the state that the one before produced.
  __attribute__((always_inline)) int decode(const RansTable& t) {
    uint32_t x = x_;
    const uint32_t slot = x & (kRansScale - 1);
    const uint32_t s = t.symbol_at(slot);
    const uint32_t fc = t.freq_cum(s);
    x = (fc & 0xffffu) * (x >> kRansScaleBits) + slot - (fc >> 16);
    if (x < kRansLow) x = x << 16 | next_word();
    x_ = y_;
    y_ = x;
    return static_cast<int>(s);
  }

  // True when decoding needed bytes past the end: truncated or corrupt.
  bool overran() const { return overran_; }
  // True when every byte was read and the state is back where the encoder
  // started (2^16): the end of a correctly decoded stream.
  bool at_clean_end() const { return !overran_ && pos_ == size_ && x_ == kRansLow && y_ == kRansLow; }

 private:
  uint32_t next_word() {
    if (size_ - pos_ >= 2) {
      const uint32_t w = data_[pos_] | uint32_t{data_[pos_ + 1]} << 8;
      pos_ += 2;
      return w;
    }
    overran_ = true;
    pos_ = size_;
    return 0;
  }

  const uint8_t* data_;
  size_t size_;
  size_t pos_ = 0;
  uint32_t x_ = 0;  // the state of the next symbol
  uint32_t y_ = 0;  // the state of the symbol after it
  bool overran_ = false;
};

// Raw bits, least significant first, in 32-bit little-endian words (which
// is the same as bytes, least significant bit first, padded to a multiple
// of 4 bytes).
class RawWriter {
 public:
  // Appends the low `bits` bits of `value` (bits 0..32).
  __attribute__((always_inline)) void put(uint32_t value, int bits) {
    // n_ < 8 and bits <= 32: the accumulator never overflows, and the
    // 64-bit mask needs no case for 0 or 32 bits. The whole bytes go out
    // without a test of how many there are: 8 bytes are stored and the
    // position moves by the whole ones (Giesen's branchless bit writer;
    // the later stores overwrite the rest). A flush on a test of the bits
    // held would be a data-dependent branch in the encoder's loop.
    acc_ |= (static_cast<uint64_t>(value) & ((uint64_t{1} << bits) - 1)) << n_;
    n_ += bits;
    if (__builtin_expect(pos_ + 8 > bytes_.size(), 0)) grow();
    uint64_t w = acc_;
#if __BYTE_ORDER__ == __ORDER_BIG_ENDIAN__
    w = __builtin_bswap64(w);
#endif
    __builtin_memcpy(bytes_.data() + pos_, &w, 8);
    pos_ += static_cast<size_t>(n_ >> 3);
    acc_ >>= n_ & ~7;
    n_ &= 7;
  }
  // Bits written so far.
  uint64_t bits() const { return 8 * static_cast<uint64_t>(pos_) + static_cast<uint64_t>(n_); }
  // Pads the last word with zero bits, returns the bytes and starts over.
  std::vector<uint8_t> finish();

 private:
  // Room for 8 more bytes at pos_, growing geometrically.
  __attribute__((noinline)) void grow() { bytes_.resize(2 * bytes_.size() + 4096); }
  // Grown without zeroing: finish() returns only the bytes written.
  std::vector<uint8_t, DefaultInitAllocator<uint8_t>> bytes_;
  size_t pos_ = 0;  // whole bytes written
  uint64_t acc_ = 0;
  int n_ = 0;       // bits in acc_ not yet counted in pos_, 0..7
};

class RawReader {
 public:
  // Reads from `size` bytes at `data` (a multiple of 4 for a stream that
  // RawWriter wrote), which must outlive the reader. Only whole words are
  // read: the bytes after the last multiple of 4 never are.
  RawReader(const uint8_t* data, size_t size) : data_(data), size_(size), words_(size & ~size_t{3}) {}

  // The next `bits` bits (0..32). Past the last whole word it returns zero
  // bits, and overran() becomes true.
  __attribute__((always_inline)) uint32_t get(int bits) {
    top_up();
    const uint32_t v = static_cast<uint32_t>(acc_ & ((uint64_t{1} << bits) - 1));
    acc_ >>= bits;
    n_ -= bits;
    return v;
  }
  // The next `bits` bits (0..56) as one value, with one refill: the raw
  // bits of several fields that follow each other, split by the caller.
  __attribute__((always_inline)) uint64_t get_wide(int bits) {
    top_up();
    const uint64_t v = acc_ & ((uint64_t{1} << bits) - 1);
    acc_ >>= bits;
    n_ -= bits;
    return v;
  }
  // True when more bits were read than the whole words hold.
  bool overran() const { return consumed_bits() > 8 * static_cast<uint64_t>(words_); }
  // Bits read so far.
  uint64_t consumed_bits() const { return 8 * static_cast<uint64_t>(pos_) - static_cast<uint64_t>(n_); }
  // True when the stream is whole words, the last of them was reached
  // (none is left unread) and the bits after the last read are zero (the
  // writer's padding).
  bool at_clean_end() const;

 private:
  // Fills the accumulator to 56 to 63 bits without a test on how many it
  // holds: 8 bytes are loaded at the first byte not yet in it, and the
  // position moves by the whole bytes that fit (Giesen's branchless
  // bit-reader refill, "Reading bits in far too many ways", 2018). The bits
  // above n_ that a load leaves are the stream's next bits, so the next
  // load's OR over them changes nothing. A refill that depended on n_
  // would be a data-dependent branch in the decoder's loop, often
  // mispredicted.
  __attribute__((always_inline)) void top_up() {
    if (__builtin_expect(pos_ + 8 <= words_, 1)) {
      uint64_t w;
      __builtin_memcpy(&w, data_ + pos_, 8);
#if __BYTE_ORDER__ == __ORDER_BIG_ENDIAN__
      w = __builtin_bswap64(w);
#endif
      acc_ |= w << n_;
      pos_ += static_cast<size_t>((63 - n_) >> 3);
      n_ |= 56;
    } else {
      top_up_near_end();
    }
  }
  // top_up() within 8 bytes of the end: bytes past the last whole word
  // read as zeros.
  void top_up_near_end();

  const uint8_t* data_;
  size_t size_;
  size_t words_;     // the bytes of whole words
  size_t pos_ = 0;   // the first byte not in the accumulator (may pass words_)
  uint64_t acc_ = 0;
  int n_ = 0;        // valid bits in acc_, 0..63
};

}  // namespace codec
}  // namespace psq

#endif  // PSQ_CODEC_RANS_H_
