// SPDX-License-Identifier: Apache-2.0
// codec/src/properties.cpp: see properties.h and spec/psq-format.md 8.
#include "properties.h"

#define ZSTD_STATIC_LINKING_ONLY  // ZSTD_getCParams
#include <zstd.h>

#include <algorithm>
#include <cstring>

namespace psq {
namespace codec {
namespace {

// The little-endian bytes of `v` as type `t` (v must fit t).
void put_value(ScalarType t, double v, uint8_t* out) {
  uint64_t bits = 0;
  switch (t) {
    case ScalarType::kFloat32: {
      float f = static_cast<float>(v);  // exact: the value is a float
      uint32_t b;
      std::memcpy(&b, &f, 4);
      bits = b;
      break;
    }
    case ScalarType::kFloat64:
      std::memcpy(&bits, &v, 8);
      break;
    default:
      bits = static_cast<uint64_t>(static_cast<int64_t>(v));
  }
  for (int i = 0, n = scalar_size(t); i < n; ++i) out[i] = static_cast<uint8_t>(bits >> (8 * i));
}

double get_value(ScalarType t, const uint8_t* in) {
  uint64_t bits = 0;
  const int n = scalar_size(t);
  for (int i = 0; i < n; ++i) bits |= static_cast<uint64_t>(in[i]) << (8 * i);
  switch (t) {
    case ScalarType::kInt8: return static_cast<int8_t>(bits);
    case ScalarType::kUInt8: return static_cast<uint8_t>(bits);
    case ScalarType::kInt16: return static_cast<int16_t>(bits);
    case ScalarType::kUInt16: return static_cast<uint16_t>(bits);
    case ScalarType::kInt32: return static_cast<int32_t>(bits);
    case ScalarType::kUInt32: return static_cast<uint32_t>(bits);
    case ScalarType::kFloat32: {
      uint32_t b = static_cast<uint32_t>(bits);
      float f;
      std::memcpy(&f, &b, 4);
      return f;
    }
    case ScalarType::kFloat64: {
      double d;
      std::memcpy(&d, &bits, 8);
      return d;
    }
  }
  return 0;
}

}  // namespace

PropertyPacker::PropertyPacker(const std::vector<Property>& vertex, const std::vector<Property>& face)
    : vprops_(vertex), fprops_(face), vcols_(vertex.size()), fcols_(face.size()) {}

bool PropertyPacker::add(const std::vector<Property>& props, std::vector<std::vector<uint8_t>>& cols,
                         const PropertyValues& v, uint64_t* count) {
  size_t at = 0;
  for (size_t i = 0; i < props.size(); ++i) {
    const Property& p = props[i];
    std::vector<uint8_t>& col = cols[i];
    const int s = scalar_size(p.type);
    size_t n = 1;
    if (p.is_list) {
      if (at >= v.size() || !scalar_holds(p.count_type, v[at])) return false;
      n = static_cast<size_t>(v[at]);
      size_t cs = static_cast<size_t>(scalar_size(p.count_type));
      col.resize(col.size() + cs);
      put_value(p.count_type, v[at], col.data() + col.size() - cs);
      raw_size_ += cs;
      ++at;
    }
    if (v.size() - at < n) return false;
    for (size_t k = 0; k < n; ++k, ++at) {
      if (!scalar_holds(p.type, v[at])) return false;
      col.resize(col.size() + s);
      put_value(p.type, v[at], col.data() + col.size() - s);
      raw_size_ += s;
    }
  }
  if (at != v.size()) return false;
  ++*count;
  return true;
}

void PropertyPacker::flush(const std::vector<Property>& props, std::vector<std::vector<uint8_t>>& cols, uint64_t n,
                           std::vector<uint8_t>* raw) {
  for (size_t i = 0; i < props.size(); ++i) {
    std::vector<uint8_t>& col = cols[i];
    const size_t s = static_cast<size_t>(scalar_size(props[i].type));
    if (props[i].is_list || s == 1) {
      raw->insert(raw->end(), col.begin(), col.end());
    } else {
      // Spec 8.1: byte plane j holds byte j of every value, in element order.
      size_t base = raw->size();
      raw->resize(base + col.size());
      uint8_t* out = raw->data() + base;
      for (size_t e = 0; e < n; ++e)
        for (size_t j = 0; j < s; ++j) out[j * n + e] = col[e * s + j];
    }
    col.clear();
  }
}

void PropertyPacker::take(std::vector<uint8_t>* raw) {
  flush(vprops_, vcols_, nv_, raw);
  flush(fprops_, fcols_, nf_, raw);
  nv_ = nf_ = 0;
  raw_size_ = 0;
}

PropertyUnpacker::PropertyUnpacker(const std::vector<Property>& vertex, const std::vector<Property>& face) {
  for (const Property& p : vertex) vcols_.push_back(Column{p, 0, 0});
  for (const Property& p : face) fcols_.push_back(Column{p, 0, 0});
}

bool PropertyUnpacker::layout(std::vector<Column>& cols, uint64_t n, size_t* at) {
  for (Column& c : cols) {
    c.begin = c.cursor = *at;
    const uint64_t s = static_cast<uint64_t>(scalar_size(c.prop.type));
    if (!c.prop.is_list) {
      if ((raw_.size() - *at) / s < n) return false;
      *at += static_cast<size_t>(n * s);
      continue;
    }
    const size_t cs = static_cast<size_t>(scalar_size(c.prop.count_type));
    for (uint64_t e = 0; e < n; ++e) {
      if (raw_.size() - *at < cs) return false;
      double count = get_value(c.prop.count_type, raw_.data() + *at);
      *at += cs;
      if (count < 0 || count > static_cast<double>((raw_.size() - *at) / s)) return false;
      *at += static_cast<size_t>(count) * s;
    }
  }
  return true;
}

bool PropertyUnpacker::load(std::vector<uint8_t>&& raw, uint64_t nv, uint64_t nf) {
  raw_ = std::move(raw);
  nv_ = nv;
  nf_ = nf;
  vi_ = fi_ = 0;
  size_t at = 0;
  if (!layout(vcols_, nv, &at) || !layout(fcols_, nf, &at)) return false;
  return at == raw_.size();
}

void PropertyUnpacker::next(std::vector<Column>& cols, uint64_t n, uint64_t* i, PropertyValues* out) {
  out->clear();
  for (Column& c : cols) {
    const size_t s = static_cast<size_t>(scalar_size(c.prop.type));
    if (!c.prop.is_list) {
      uint8_t b[8];  // spec 8.1: byte j of the value from byte plane j
      for (size_t j = 0; j < s; ++j) b[j] = raw_[c.begin + j * n + *i];
      out->push_back(get_value(c.prop.type, b));
      continue;
    }
    double count = get_value(c.prop.count_type, raw_.data() + c.cursor);
    c.cursor += static_cast<size_t>(scalar_size(c.prop.count_type));
    out->push_back(count);
    for (size_t k = 0; k < static_cast<size_t>(count); ++k, c.cursor += s)
      out->push_back(get_value(c.prop.type, raw_.data() + c.cursor));
  }
  ++*i;
}

void zstd_compress(const std::vector<uint8_t>& raw, int level, std::vector<uint8_t>* out) {
  out->resize(ZSTD_compressBound(raw.size()));
  // The level's parameters for this size, with its match tables capped at
  // 2^17 entries: level 9 on a block of 1 MiB would take a context of 12.5
  // MiB and level 19 (segment states) 17 MiB, for a step in the peak
  // memory of every pipeline that writes .psq; capped, at most 2.3 MiB.
  // Blocks under 128 KiB get the level's own parameters (already smaller).
  constexpr unsigned kMaxTableLog = 17;
  const ZSTD_compressionParameters cp = ZSTD_getCParams(level, raw.size(), 0);
  ZSTD_CCtx* cctx = ZSTD_createCCtx();
  size_t n = 0;  // no frame: the caller's check of the size fails
  if (cctx && !ZSTD_isError(ZSTD_CCtx_setParameter(cctx, ZSTD_c_compressionLevel, level)) &&
      !ZSTD_isError(ZSTD_CCtx_setParameter(cctx, ZSTD_c_hashLog, static_cast<int>(std::min(cp.hashLog, kMaxTableLog)))) &&
      !ZSTD_isError(ZSTD_CCtx_setParameter(cctx, ZSTD_c_chainLog, static_cast<int>(std::min(cp.chainLog, kMaxTableLog)))))
    n = ZSTD_compress2(cctx, out->data(), out->size(), raw.data(), raw.size());
  ZSTD_freeCCtx(cctx);
  out->resize(n == 0 || ZSTD_isError(n) ? 0 : n);
}

bool zstd_decompress(const uint8_t* data, size_t size, size_t raw_size, std::vector<uint8_t>* out) {
  // Exactly one Zstandard frame (spec 8.2; not a skippable or legacy one),
  // declaring its content size.
  if (size < 4 || data[0] != 0x28 || data[1] != 0xb5 || data[2] != 0x2f || data[3] != 0xfd) return false;
  if (ZSTD_findFrameCompressedSize(data, size) != size) return false;
  unsigned long long declared = ZSTD_getFrameContentSize(data, size);
  if (declared != raw_size) return false;
  out->resize(raw_size);
  size_t n = ZSTD_decompress(out->data(), raw_size, data, size);
  return !ZSTD_isError(n) && n == raw_size;
}

}  // namespace codec
}  // namespace psq
