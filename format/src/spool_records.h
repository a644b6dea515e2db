// SPDX-License-Identifier: Apache-2.0
// The records build_sequence() spools its input into (native endianness;
// the files never leave the process): vertex = 3 doubles, uint32 n, n
// doubles; triangle = 3 uint32, uint32 n, n doubles. Shared by the builder
// and the weld pass that rewrites the spools (weld.cpp).
#ifndef PSQ_SRC_SPOOL_RECORDS_H_
#define PSQ_SRC_SPOOL_RECORDS_H_

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

inline Status get_values_at(const SpoolFile& f, uint64_t offset, PropertyValues* values) {
  uint32_t n;
  PSQ_RETURN_IF_ERROR(f.read_at(offset, &n, 4));
  values->resize(n);
  return n == 0 ? Status() : f.read_at(offset + 4, values->data(), 8 * size_t{n});
}

}  // namespace psq::detail

#endif  // PSQ_SRC_SPOOL_RECORDS_H_
