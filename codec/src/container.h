// SPDX-License-Identifier: Apache-2.0
// codec/src/container.h: the framing of a .psq stream (spec/psq-format.md
// section 4): little-endian field helpers, the header, the chunk and end
// record layouts and the limits a decoder enforces.
#ifndef PSQ_CODEC_CONTAINER_H_
#define PSQ_CODEC_CONTAINER_H_

#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "psq/psq_codec.h"
#include "psq/status.h"

namespace psq {
namespace codec {

// The version pair written, and the only major version read (spec 11).
constexpr int kVersionMajor = 1;
constexpr int kVersionMinor = 0;
constexpr uint16_t kFlagLossless = 1u << 0;
constexpr uint16_t kFlagRotation = 1u << 1;
constexpr uint16_t kFlagFast = 1u << 2;
constexpr uint16_t kKnownFlags = kFlagLossless | kFlagRotation | kFlagFast;

constexpr size_t kFixedHeaderBytes = 12;    // magic, version, flags (the payload length follows)
constexpr uint32_t kMaxHeaderPayload = 1u << 20;
constexpr uint32_t kMaxProperties = 1024;   // per element
constexpr uint32_t kMaxBoundaryLimit = 1u << 28;

constexpr uint8_t kChunkTag = 0x43;         // 'C'
constexpr uint8_t kEndTag = 0x45;           // 'E'
constexpr uint8_t kSegmentTag = 0x53;       // 'S': a segment record (spec 4.6)
constexpr uint8_t kIndexTag = 0x49;         // 'I': the segment index (spec 4.7)
constexpr uint32_t kMaxStateBytes = 1u << 26;  // a segment record's compressed state block
constexpr uint32_t kMaxStateRaw = 1u << 28;    // and its size after decompression
constexpr size_t kMaxVarintBytes = 10;      // a 64-bit value in 7-bit groups (spec 3.1)
constexpr uint32_t kMaxChunkRecords = 1u << 24;
constexpr uint32_t kMaxRecordBytes = 1u << 26;     // coded records of one chunk
constexpr uint32_t kMaxPropertyBytes = 1u << 26;   // compressed properties of one chunk
constexpr uint32_t kMaxPropertyRaw = 1u << 28;     // their decompressed size
constexpr size_t kChunkPropertyTarget = 4u << 20;  // the encoder closes a chunk at this much

// Appends little-endian fields.
class Put {
 public:
  explicit Put(std::vector<uint8_t>* out) : out_(out) {}
  void u8(uint8_t v) { out_->push_back(v); }
  void u16(uint16_t v) { for (int i = 0; i < 2; ++i) out_->push_back(static_cast<uint8_t>(v >> (8 * i))); }
  void u32(uint32_t v) { for (int i = 0; i < 4; ++i) out_->push_back(static_cast<uint8_t>(v >> (8 * i))); }
  void u64(uint64_t v) { for (int i = 0; i < 8; ++i) out_->push_back(static_cast<uint8_t>(v >> (8 * i))); }
  // Spec 3.1: 7 bits per byte, least significant group first, the high bit
  // set on every byte but the last.
  void varint(uint64_t v) {
    while (v >= 0x80) {
      out_->push_back(static_cast<uint8_t>(v | 0x80));
      v >>= 7;
    }
    out_->push_back(static_cast<uint8_t>(v));
  }
  void f64(double d) {
    uint64_t v;
    std::memcpy(&v, &d, 8);
    u64(v);
  }
  void bytes(const void* p, size_t n) {
    const uint8_t* b = static_cast<const uint8_t*>(p);
    out_->insert(out_->end(), b, b + n);
  }

 private:
  std::vector<uint8_t>* out_;
};

// Parses a varint (spec 3.1) from the n bytes at p. Returns the number of
// bytes it takes, 0 when the n bytes end inside it, or -1 when it is
// malformed: longer than 10 bytes, above 2^64 - 1, or not in its shortest
// form (a last byte of 0 after another byte).
inline int parse_varint(const uint8_t* p, size_t n, uint64_t* v) {
  uint64_t x = 0;
  for (size_t i = 0; i < n && i < kMaxVarintBytes; ++i) {
    const uint64_t g = p[i] & 0x7f;
    if (i == 9 && g > 1) return -1;
    x |= g << (7 * i);
    if (!(p[i] & 0x80)) {
      if (i > 0 && p[i] == 0) return -1;
      *v = x;
      return static_cast<int>(i + 1);
    }
  }
  return n >= kMaxVarintBytes ? -1 : 0;
}

// Reads little-endian fields from a byte span; reading past the end sets
// `short_` and yields zeros.
class Get {
 public:
  Get(const uint8_t* p, size_t n) : p_(p), n_(n) {}
  uint64_t uint(int bytes) {
    if (n_ - pos_ < static_cast<size_t>(bytes) || pos_ > n_) {
      short_ = true;
      pos_ = n_;
      return 0;
    }
    uint64_t v = 0;
    for (int i = 0; i < bytes; ++i) v |= static_cast<uint64_t>(p_[pos_ + i]) << (8 * i);
    pos_ += bytes;
    return v;
  }
  uint8_t u8() { return static_cast<uint8_t>(uint(1)); }
  uint16_t u16() { return static_cast<uint16_t>(uint(2)); }
  uint32_t u32() { return static_cast<uint32_t>(uint(4)); }
  uint64_t u64() { return uint(8); }
  // A varint (spec 3.1); a malformed one sets `malformed_`, a cut one
  // `short_`, and both yield 0.
  uint64_t varint() {
    uint64_t v = 0;
    const int k = pos_ <= n_ ? parse_varint(p_ + pos_, n_ - pos_, &v) : 0;
    if (k <= 0) {
      if (k < 0) malformed_ = true;
      else short_ = true;
      pos_ = n_;
      return 0;
    }
    pos_ += static_cast<size_t>(k);
    return v;
  }
  double f64() {
    uint64_t v = u64();
    double d;
    std::memcpy(&d, &v, 8);
    return d;
  }
  std::string str(size_t n) {
    if (n_ - pos_ < n) {
      short_ = true;
      pos_ = n_;
      return std::string();
    }
    std::string s(reinterpret_cast<const char*>(p_ + pos_), n);
    pos_ += n;
    return s;
  }
  size_t pos() const { return pos_; }
  size_t left() const { return n_ - pos_; }
  bool short_read() const { return short_; }
  bool malformed() const { return malformed_; }

 private:
  const uint8_t* p_;
  size_t n_;
  size_t pos_ = 0;
  bool short_ = false;
  bool malformed_ = false;
};

// The whole header (spec 4.2), magic to checksum.
std::vector<uint8_t> write_header(const PsqHeader& h);

// Parses the header payload (the bytes after the fixed 16, without the
// checksum) into `h` (whose version and flags are already set). `base` is
// the payload's offset in the stream, for error places.
Status parse_header_payload(const uint8_t* p, size_t n, uint64_t base, PsqHeader* h);

}  // namespace codec
}  // namespace psq

#endif  // PSQ_CODEC_CONTAINER_H_
