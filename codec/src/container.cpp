// SPDX-License-Identifier: Apache-2.0
// codec/src/container.cpp: the .psq header (spec/psq-format.md 4.1, 4.2).
#include "container.h"

#include <cmath>
#include <set>

#include "attributes.h"
#include "crc32c.h"

namespace psq {

const uint8_t kPsqMagic[8] = {0x89, 'P', 'S', 'Q', 0x0d, 0x0a, 0x1a, 0x0a};

bool is_psq(const uint8_t* data, size_t size) {
  return size >= 8 && std::memcmp(data, kPsqMagic, 8) == 0;
}

Status VectorWriter::write(const void* data, size_t size) {
  const uint8_t* p = static_cast<const uint8_t*>(data);
  out_->insert(out_->end(), p, p + size);
  return Status();
}

namespace codec {
namespace {

void put_properties(Put& put, const std::vector<Property>& props) {
  put.varint(props.size());
  for (const Property& p : props) {
    put.u8(static_cast<uint8_t>(p.name.size()));
    put.bytes(p.name.data(), p.name.size());
    put.u8(static_cast<uint8_t>(p.type));
    put.u8(p.is_list ? 1 : 0);
    put.u8(p.is_list ? static_cast<uint8_t>(p.count_type) : 0);
  }
}

bool valid_name(const std::string& s) {
  if (s.empty()) return false;
  for (unsigned char c : s)
    if (c <= 0x20 || c >= 0x7f || c == '=') return false;
  return true;
}

Status get_properties(Get& get, uint64_t base, const char* element, std::vector<Property>* props) {
  uint64_t at = base + get.pos();
  const uint64_t n = get.varint();
  if (get.malformed()) return Status(ErrorCode::kBadHeader, "malformed varint", at);
  if (n > kMaxProperties)
    return Status(ErrorCode::kLimit, std::to_string(n) + " " + element + " properties (limit " +
                                         std::to_string(kMaxProperties) + ")", at);
  std::set<std::string> names;
  for (uint64_t i = 0; i < n; ++i) {
    at = base + get.pos();
    Property p;
    p.name = get.str(get.u8());
    uint8_t type = get.u8(), is_list = get.u8(), count_type = get.u8();
    if (get.short_read()) return Status(ErrorCode::kBadHeader, "header payload ends inside a property", at);
    if (!valid_name(p.name))
      return Status(ErrorCode::kBadHeader, std::string(element) + " property name is empty or has a space, '=' or a non-ASCII byte", at);
    if (!names.insert(p.name).second)
      return Status(ErrorCode::kBadHeader, std::string(element) + " property '" + p.name + "' appears twice", at);
    if (type < 1 || type > 8)
      return Status(ErrorCode::kBadHeader, "property '" + p.name + "' has unknown type " + std::to_string(type), at);
    if (is_list > 1 || (is_list == 0 && count_type != 0) || (is_list == 1 && (count_type < 1 || count_type > 6)))
      return Status(ErrorCode::kBadHeader, "property '" + p.name + "' has a bad list flag or count type", at);
    p.type = static_cast<ScalarType>(type);
    p.is_list = is_list == 1;
    p.count_type = is_list ? static_cast<ScalarType>(count_type) : ScalarType::kUInt8;
    props->push_back(p);
  }
  return Status();
}

}  // namespace

std::vector<uint8_t> write_header(const PsqHeader& h) {
  std::vector<uint8_t> payload;
  Put put(&payload);
  put.u8(static_cast<uint8_t>(h.schema.position_type));
  put.u8(static_cast<uint8_t>(h.lossless ? 0 : h.bits));
  for (int i = 0; i < 3; ++i) put.f64(h.lossless ? 0.0 : h.origin[i]);
  put.f64(h.lossless ? 0.0 : h.step);
  put.varint(h.boundary_limit);
  put.varint(h.segment_triangles);
  // Spec 4.2: a count plus one, 0 for unknown (-1).
  put.varint(static_cast<uint64_t>(h.schema.vertex_count) + 1);
  put.varint(static_cast<uint64_t>(h.schema.triangle_count) + 1);
  put_properties(put, h.schema.vertex_properties);
  put_properties(put, h.schema.face_properties);
  // Spec 4.2: the attribute table.
  put.varint(h.attributes.size());
  for (const CodedAttribute& a : h.attributes) {
    put.u8(static_cast<uint8_t>(a.kind));
    put.u8(static_cast<uint8_t>(a.bits));
    put.u8(static_cast<uint8_t>(a.properties.size()));
    for (uint32_t i : a.properties) put.varint(i);
  }
  put.varint(h.schema.comments.size());
  for (const std::string& c : h.schema.comments) {
    put.varint(c.size());
    put.bytes(c.data(), c.size());
  }

  std::vector<uint8_t> out;
  Put head(&out);
  head.bytes(kPsqMagic, 8);
  head.u8(kVersionMajor);
  head.u8(kVersionMinor);
  head.u16(static_cast<uint16_t>((h.lossless ? kFlagLossless : 0) | (h.rotation ? kFlagRotation : 0) |
                                 (h.fast ? kFlagFast : 0)));
  head.varint(payload.size());
  head.bytes(payload.data(), payload.size());
  head.u32(crc32c_update(0, out.data(), out.size()));
  return out;
}

Status parse_header_payload(const uint8_t* p, size_t n, uint64_t base, PsqHeader* h) {
  Get get(p, n);
  auto bad = [&](const std::string& what, size_t at) { return Status(ErrorCode::kBadHeader, what, base + at); };
  uint8_t ptype = get.u8();
  if (ptype != static_cast<uint8_t>(ScalarType::kFloat32) && ptype != static_cast<uint8_t>(ScalarType::kFloat64))
    return bad("position type " + std::to_string(ptype) + " is neither float (7) nor double (8)", 0);
  h->schema = MeshSchema();
  h->schema.position_type = static_cast<ScalarType>(ptype);
  h->bits = get.u8();
  for (int i = 0; i < 3; ++i) h->origin[i] = get.f64();
  h->step = get.f64();
  if (get.short_read()) return bad("header payload too short", get.pos());
  if (h->lossless) {
    if (h->bits != 0 || h->origin[0] != 0 || h->origin[1] != 0 || h->origin[2] != 0 || h->step != 0)
      return bad("a lossless stream must have zero quantization fields", 1);
  } else {
    if (h->bits < 1 || h->bits > 31) return bad("quantization bits " + std::to_string(h->bits) + " not in 1..31", 1);
    for (int i = 0; i < 3; ++i)
      if (!std::isfinite(h->origin[i])) return bad("quantization origin is not finite", 2 + 8 * i);
    if (!std::isfinite(h->step) || !(h->step > 0)) return bad("quantization step is not a positive number", 26);
    // Every grid point must be finite (spec 7.1).
    double far = h->step * static_cast<double>((uint64_t{1} << h->bits) - 1);
    for (int i = 0; i < 3; ++i)
      if (!std::isfinite(h->origin[i] + far) ||
          (h->schema.position_type == ScalarType::kFloat32 &&
           (std::fabs(h->origin[i]) > 3.4e38 || std::fabs(h->origin[i] + far) > 3.4e38)))
        return bad("quantization grid reaches beyond the position type's range", 2);
    h->schema.has_bounds = true;
    for (int i = 0; i < 3; ++i) {
      h->schema.bounds_min[i] = h->origin[i];
      h->schema.bounds_max[i] = h->origin[i] + far;
    }
  }
  size_t at = get.pos();
  const uint64_t limit = get.varint();
  if (get.malformed()) return bad("malformed varint", at);
  if (get.short_read()) return bad("header payload too short", at);
  if (limit < 1 || limit > kMaxBoundaryLimit)
    return Status(ErrorCode::kLimit, "boundary limit " + std::to_string(limit) + " not in 1.." +
                                         std::to_string(kMaxBoundaryLimit), base + at);
  h->boundary_limit = static_cast<uint32_t>(limit);
  at = get.pos();
  h->segment_triangles = get.varint();
  if (get.malformed()) return bad("malformed varint", at);
  if (get.short_read()) return bad("header payload too short", at);
  at = get.pos();
  const uint64_t nv = get.varint();
  const size_t at_t = get.pos();
  const uint64_t nt = get.varint();
  if (get.malformed()) return bad("malformed varint", at);
  if (get.short_read()) return bad("header payload too short", at);
  // Spec 4.2: count + 1, 0 for unknown; at most 2^63 - 1 counted.
  if (nv > uint64_t{INT64_MAX}) return bad("vertex count beyond 2^63 - 2", at);
  if (nt > uint64_t{INT64_MAX}) return bad("triangle count beyond 2^63 - 2", at_t);
  h->schema.vertex_count = static_cast<int64_t>(nv) - 1;
  h->schema.triangle_count = static_cast<int64_t>(nt) - 1;
  PSQ_RETURN_IF_ERROR(get_properties(get, base, "vertex", &h->schema.vertex_properties));
  PSQ_RETURN_IF_ERROR(get_properties(get, base, "face", &h->schema.face_properties));
  for (const Property& pr : h->schema.vertex_properties)
    if (pr.name == "x" || pr.name == "y" || pr.name == "z")
      return bad("vertex property named '" + pr.name + "' clashes with the position", 0);
  at = get.pos();
  // Spec 4.2: the attribute table.
  const uint64_t na = get.varint();
  if (get.malformed()) return bad("malformed varint", at);
  if (na > 5) return bad("attribute table of " + std::to_string(na) + " entries (at most 5)", at);
  h->attributes.clear();
  for (uint64_t i = 0; i < na && !get.short_read(); ++i) {
    CodedAttribute a;
    a.kind = static_cast<CodedAttribute::Kind>(get.u8());
    a.bits = get.u8();
    const uint8_t count = get.u8();
    for (uint8_t j = 0; j < count && !get.short_read() && !get.malformed(); ++j) {
      const uint64_t index = get.varint();
      a.properties.push_back(index > 0xffffffffu ? 0xffffffffu : static_cast<uint32_t>(index));
    }
    if (get.malformed()) return bad("malformed varint", at);
    h->attributes.push_back(std::move(a));
  }
  if (get.short_read()) return bad("header payload too short", at);
  const std::string attr_error = attribute_table_error(h->schema, h->attributes);
  if (!attr_error.empty()) return bad(attr_error, at);
  if (h->rotation != rotation_kept(h->schema, h->attributes))
    return bad("the rotation flag must be set exactly when there are face properties other than corner attributes", 0);
  at = get.pos();
  const uint64_t nc = get.varint();
  for (uint64_t i = 0; i < nc && !get.short_read() && !get.malformed(); ++i) {
    at = get.pos();
    std::string c = get.str(static_cast<size_t>(get.varint()));  // a length past the end: a short read
    if (get.short_read() || get.malformed()) break;
    for (unsigned char ch : c)
      if (ch == '\n' || ch == '\r' || ch == 0) return bad("comment holds a line break or NUL", at);
    h->schema.comments.push_back(std::move(c));
  }
  if (get.malformed()) return bad("malformed varint", at);
  if (get.short_read()) return bad("header payload too short", at);
  if (get.left() != 0) return bad(std::to_string(get.left()) + " unexpected bytes at the end of the header payload", get.pos());
  return Status();
}

}  // namespace codec
}  // namespace psq
