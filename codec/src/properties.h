// SPDX-License-Identifier: Apache-2.0
// codec/src/properties.h: the property section of a .psq chunk
// (spec/psq-format.md section 8): the values of the chunk's new vertices and
// of its triangles, one column per property, scalar columns split into byte
// planes, the whole compressed with zstd.
#ifndef PSQ_CODEC_PROPERTIES_H_
#define PSQ_CODEC_PROPERTIES_H_

#include <cstdint>
#include <vector>

#include "psq/indexed_mesh.h"
#include "psq/status.h"

namespace psq {
namespace codec {

class PropertyPacker {
 public:
  PropertyPacker(const std::vector<Property>& vertex, const std::vector<Property>& face);
  bool empty() const { return vprops_.empty() && fprops_.empty(); }
  // Adds one element's values. Returns false when a value does not fit its
  // declared type or the flattening does not match the schema.
  bool add_vertex(const PropertyValues& v) {
    if (vprops_.empty() && v.empty()) return ++nv_, true;  // the common case, inline
    return add(vprops_, vcols_, v, &nv_);
  }
  bool add_face(const PropertyValues& v) {
    if (fprops_.empty() && v.empty()) return ++nf_, true;
    return add(fprops_, fcols_, v, &nf_);
  }
  size_t raw_size() const { return raw_size_; }
  // Appends the section's raw bytes (spec 8.1) and starts a new chunk.
  void take(std::vector<uint8_t>* raw);

 private:
  bool add(const std::vector<Property>& props, std::vector<std::vector<uint8_t>>& cols, const PropertyValues& v,
           uint64_t* count);
  void flush(const std::vector<Property>& props, std::vector<std::vector<uint8_t>>& cols, uint64_t n,
             std::vector<uint8_t>* raw);

  std::vector<Property> vprops_, fprops_;
  std::vector<std::vector<uint8_t>> vcols_, fcols_;
  uint64_t nv_ = 0, nf_ = 0;
  size_t raw_size_ = 0;
};

class PropertyUnpacker {
 public:
  PropertyUnpacker(const std::vector<Property>& vertex, const std::vector<Property>& face);
  // Takes a chunk's raw section for `nv` vertices and `nf` faces; false when
  // its size or a list count does not match (a corrupt stream).
  bool load(std::vector<uint8_t>&& raw, uint64_t nv, uint64_t nf);
  // True when the schema has neither vertex nor face properties.
  bool empty() const { return vcols_.empty() && fcols_.empty(); }
  // The next vertex's or face's values, in order.
  // Without columns (no properties) nothing is read: the common case costs
  // no call.
  void next_vertex(PropertyValues* out) {
    if (vcols_.empty()) return out->clear();
    next(vcols_, nv_, &vi_, out);
  }
  void next_face(PropertyValues* out) {
    if (fcols_.empty()) return out->clear();
    next(fcols_, nf_, &fi_, out);
  }

 private:
  struct Column {
    Property prop;
    size_t begin = 0;   // offset in raw_
    size_t cursor = 0;  // lists: offset of the next element
  };
  bool layout(std::vector<Column>& cols, uint64_t n, size_t* at);
  void next(std::vector<Column>& cols, uint64_t n, uint64_t* i, PropertyValues* out);

  std::vector<Column> vcols_, fcols_;
  std::vector<uint8_t> raw_;
  uint64_t nv_ = 0, nf_ = 0, vi_ = 0, fi_ = 0;
};

// zstd around the section. compress() never fails; decompress() returns
// false unless the frame decodes to exactly `raw_size` bytes.
void zstd_compress(const std::vector<uint8_t>& raw, int level, std::vector<uint8_t>* out);
bool zstd_decompress(const uint8_t* data, size_t size, size_t raw_size, std::vector<uint8_t>* out);

}  // namespace codec
}  // namespace psq

#endif  // PSQ_CODEC_PROPERTIES_H_
