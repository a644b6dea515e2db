// SPDX-License-Identifier: Apache-2.0
// The records build_sequence() spools its input into (native endianness;
// the files never leave the process): vertex = 3 doubles, uint32 n, n
// doubles; triangle = 3 uint32, uint32 n, n doubles. Shared by the builder
// and the weld pass that rewrites the spools (weld.cpp).
#ifndef PSQ_SRC_SPOOL_RECORDS_H_
#define PSQ_SRC_SPOOL_RECORDS_H_

#include <cstring>

#include "psq/indexed_mesh.h"
#include "psq/io.h"

namespace psq::detail {

inline Status put_values(SpoolFile& f, const PropertyValues& values) {
  uint32_t n = static_cast<uint32_t>(values.size());
  PSQ_RETURN_IF_ERROR(f.write(&n, 4));
  return values.empty() ? Status() : f.write(values.data(), 8 * values.size());
}

inline Status get_values(InputStream& in, PropertyValues* values) {
  uint32_t n;
  PSQ_RETURN_IF_ERROR(in.read_exact(&n, 4));
  values->resize(n);
  return n == 0 ? Status() : in.read_exact(values->data(), 8 * size_t{n});
}

// A whole record: its head (a vertex's 24 bytes of position, a triangle's
// 12 of indices), the count and the values, with one call for the head and
// count (a record without values, the common case, costs one call).
constexpr size_t kMaxRecordHead = 24;
inline Status put_record(SpoolFile& f, const void* head, size_t head_bytes, const PropertyValues& values) {
  uint8_t buf[kMaxRecordHead + 4];
  const uint32_t n = static_cast<uint32_t>(values.size());
  std::memcpy(buf, head, head_bytes);
  std::memcpy(buf + head_bytes, &n, 4);
  PSQ_RETURN_IF_ERROR(f.write(buf, head_bytes + 4));
  return values.empty() ? Status() : f.write(values.data(), 8 * values.size());
}

inline Status get_record(InputStream& in, void* head, size_t head_bytes, PropertyValues* values) {
  uint8_t buf[kMaxRecordHead + 4];
  PSQ_RETURN_IF_ERROR(in.read_exact(buf, head_bytes + 4));
  uint32_t n;
  std::memcpy(head, buf, head_bytes);
  std::memcpy(&n, buf + head_bytes, 4);
  values->resize(n);
  return n == 0 ? Status() : in.read_exact(values->data(), 8 * size_t{n});
}

inline Status get_values_at(const SpoolFile& f, uint64_t offset, PropertyValues* values) {
  uint32_t n;
  PSQ_RETURN_IF_ERROR(f.read_at(offset, &n, 4));
  values->resize(n);
  return n == 0 ? Status() : f.read_at(offset + 4, values->data(), 8 * size_t{n});
}

}  // namespace psq::detail

#endif  // PSQ_SRC_SPOOL_RECORDS_H_
