// SPDX-License-Identifier: Apache-2.0
// Draco (.drc) reader and writer (psq/draco.h), on libdraco's in-core API.
#include "psq/draco.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <exception>
#include <limits>
#include <new>
#include <set>
#include <utility>

#include "draco/attributes/geometry_attribute.h"
#include "draco/attributes/point_attribute.h"
#include "draco/compression/config/compression_shared.h"
#include "draco/compression/decode.h"
#include "draco/compression/expert_encode.h"
#include "draco/core/decoder_buffer.h"
#include "draco/core/encoder_buffer.h"
#include "draco/mesh/mesh.h"
#include "draco/metadata/geometry_metadata.h"
#include "draco/point_cloud/point_cloud.h"

namespace psq {
namespace {

constexpr char kMagic[] = "DRACO";
constexpr size_t kMagicSize = 5;

std::string mib(uint64_t bytes) { return std::to_string((bytes + (1 << 20) - 1) >> 20) + " MiB"; }

// The psq type that holds every value of a Draco component type, or false.
bool scalar_of(draco::DataType dt, ScalarType* t) {
  switch (dt) {
    case draco::DT_INT8: *t = ScalarType::kInt8; return true;
    case draco::DT_UINT8: *t = ScalarType::kUInt8; return true;
    case draco::DT_BOOL: *t = ScalarType::kUInt8; return true;
    case draco::DT_INT16: *t = ScalarType::kInt16; return true;
    case draco::DT_UINT16: *t = ScalarType::kUInt16; return true;
    case draco::DT_INT32: *t = ScalarType::kInt32; return true;
    case draco::DT_UINT32: *t = ScalarType::kUInt32; return true;
    case draco::DT_FLOAT32: *t = ScalarType::kFloat32; return true;
    case draco::DT_FLOAT64: *t = ScalarType::kFloat64; return true;
    default: return false;  // 64-bit integers, invalid
  }
}

draco::DataType draco_of(ScalarType t) {
  switch (t) {
    case ScalarType::kInt8: return draco::DT_INT8;
    case ScalarType::kUInt8: return draco::DT_UINT8;
    case ScalarType::kInt16: return draco::DT_INT16;
    case ScalarType::kUInt16: return draco::DT_UINT16;
    case ScalarType::kInt32: return draco::DT_INT32;
    case ScalarType::kUInt32: return draco::DT_UINT32;
    case ScalarType::kFloat32: return draco::DT_FLOAT32;
    case ScalarType::kFloat64: return draco::DT_FLOAT64;
  }
  return draco::DT_FLOAT64;
}

// Reads component `k` of type `dt` at `p` as a double.
double component(draco::DataType dt, const uint8_t* p, int k) {
  auto get = [&](auto v) {
    std::memcpy(&v, p + k * sizeof(v), sizeof(v));
    return static_cast<double>(v);
  };
  switch (dt) {
    case draco::DT_INT8: return get(int8_t{});
    case draco::DT_UINT8: return get(uint8_t{});
    case draco::DT_BOOL: return get(uint8_t{}) != 0 ? 1.0 : 0.0;
    case draco::DT_INT16: return get(int16_t{});
    case draco::DT_UINT16: return get(uint16_t{});
    case draco::DT_INT32: return get(int32_t{});
    case draco::DT_UINT32: return get(uint32_t{});
    case draco::DT_INT64: return get(int64_t{});
    case draco::DT_UINT64: return get(uint64_t{});
    case draco::DT_FLOAT32: return get(float{});
    case draco::DT_FLOAT64: return get(double{});
    default: return 0;
  }
}

// Writes `v` as component `k` of type `dt` at `p`.
void put_component(draco::DataType dt, uint8_t* p, int k, double v) {
  auto put = [&](auto x) { std::memcpy(p + k * sizeof(x), &x, sizeof(x)); };
  switch (dt) {
    case draco::DT_INT8: put(static_cast<int8_t>(v)); break;
    case draco::DT_UINT8: put(static_cast<uint8_t>(v)); break;
    case draco::DT_INT16: put(static_cast<int16_t>(v)); break;
    case draco::DT_UINT16: put(static_cast<uint16_t>(v)); break;
    case draco::DT_INT32: put(static_cast<int32_t>(v)); break;
    case draco::DT_UINT32: put(static_cast<uint32_t>(v)); break;
    case draco::DT_FLOAT32: put(static_cast<float>(v)); break;
    default: put(v); break;
  }
}

// True when `v` converts to float without overflowing to an infinity (NaN
// and infinities stay what they are).
bool fits_float(double v) { return !(std::fabs(v) > std::numeric_limits<float>::max()) || std::isinf(v); }

// A double for a message: the shortest text that reads back to it.
std::string number_text(double v) {
  char buf[32];
  auto r = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, r.ptr);
}

std::string number_text(float v) {
  char buf[32];
  auto r = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, r.ptr);
}

const char* const kAxisName[3] = {"x", "y", "z"};

// "what: libdraco's message", on one line.
std::string corrupt(const char* what, const draco::Status& s) {
  std::string m = s.error_msg_string();
  for (char& c : m)
    if (c == '\n' || c == '\r') c = ' ';
  return m.empty() ? std::string(what) : std::string(what) + ": " + m;
}

// ---------------------------------------------------------------- pre-check
//
// libdraco sizes its allocations by the counts a file declares, before it
// has read the data those counts describe. The pre-check below reads the
// few header fields that drive those allocations, with its own bounds
// checks, and refuses a file whose counts cannot describe its bytes or
// whose decoding would not fit the memory budget. It follows the Draco
// bitstream as libdraco 1.5.5 reads it (versions 1.0 to 2.2 for meshes, to
// 2.3 for point clouds; the layout of counts changed at 2.0 and 2.2).

constexpr uint8_t kMeshMajor = 2, kMeshMinor = 2;    // newest mesh bitstream of libdraco 1.5.5
constexpr uint8_t kCloudMajor = 2, kCloudMinor = 3;  // newest point cloud bitstream
constexpr uint16_t kMetadataFlag = 0x8000;           // the only flag Draco defines
constexpr size_t kHeaderSize = 11;                   // magic, version, type, method, flags
// Nesting of metadata that the pre-check follows; the writer uses 1 level.
constexpr int kMaxMetadataDepth = 32;

// Bytes libdraco allocates per element while decoding (estimates, rounded
// up from its data structures): per face, the face and the corner table
// (corner -> vertex, opposite corners) plus traversal bookkeeping; per
// attribute connectivity of edgebreaker, another corner table; per vertex of
// the edgebreaker, its corner and hole flags; per point, a float position
// with its quantized copy and prediction buffers.
constexpr uint64_t kFaceBytes = 56;
constexpr uint64_t kAttributeFaceBytes = 28;
constexpr uint64_t kVertexBytes = 16;
constexpr uint64_t kPointBytes = 48;

uint16_t version_of(uint8_t major, uint8_t minor) { return static_cast<uint16_t>((major << 8) | minor); }

// A bounds-checked little-endian reader over the file's bytes; every read
// fails (returns false) instead of going past the end.
class ByteCursor {
 public:
  ByteCursor(const uint8_t* data, size_t size) : data_(data), size_(size) {}
  size_t pos() const { return pos_; }
  size_t remaining() const { return size_ - pos_; }
  // True once a read failed for want of bytes (not for a malformed value).
  bool ended() const { return ended_; }
  bool skip(uint64_t n) {
    if (n > remaining()) return end();
    pos_ += static_cast<size_t>(n);
    return true;
  }
  bool u8(uint8_t* v) {
    if (remaining() < 1) return end();
    *v = data_[pos_++];
    return true;
  }
  bool u32(uint32_t* v) {
    if (remaining() < 4) return end();
    *v = 0;
    for (int k = 0; k < 4; ++k) *v |= static_cast<uint32_t>(data_[pos_ + k]) << (8 * k);
    pos_ += 4;
    return true;
  }
  bool u16(uint16_t* v) {
    if (remaining() < 2) return end();
    *v = static_cast<uint16_t>(data_[pos_] | (data_[pos_ + 1] << 8));
    pos_ += 2;
    return true;
  }
  // Draco's unsigned LEB128 varint of a 32-bit value: at most 5 bytes. A
  // value over 32 bits is refused (libdraco would truncate it; no encoder
  // writes one), as is a 6th byte.
  bool varint32(uint32_t* v) {
    uint64_t value = 0;
    for (int k = 0; k < 5; ++k) {
      uint8_t b;
      if (!u8(&b)) return false;
      value |= static_cast<uint64_t>(b & 0x7f) << (7 * k);
      if ((b & 0x80) == 0) {
        if (value > std::numeric_limits<uint32_t>::max()) return false;
        *v = static_cast<uint32_t>(value);
        return true;
      }
    }
    return false;
  }

 private:
  bool end() {
    ended_ = true;
    return false;
  }
  const uint8_t* data_;
  size_t size_;
  size_t pos_ = 0;
  bool ended_ = false;
};

// Skips Draco metadata (attribute metadata, then geometry metadata) at `c`.
// Each metadata is: varint entry count, entries (uint8 name length, name,
// varint value size >= 1, value), varint sub-metadata count, then each
// sub-metadata as a uint8-length name and a metadata, depth first.
Status skip_metadata(ByteCursor& c) {
  auto truncated = [&]() {
    return c.ended() ? Status(ErrorCode::kTruncated, "Draco metadata ends early", c.pos())
                     : Status(ErrorCode::kBadValue, "malformed varint in Draco metadata", c.pos());
  };
  // One metadata: its entries, then the count of its children.
  auto body = [&](uint32_t* children) -> Status {
    uint32_t entries;
    if (!c.varint32(&entries)) return truncated();
    // Every entry takes at least 3 bytes, so the count cannot exceed them.
    if (entries > c.remaining() / 3)
      return Status(ErrorCode::kBadValue, "Draco metadata declares " + std::to_string(entries) + " entries in " +
                                              std::to_string(c.remaining()) + " bytes", c.pos());
    for (uint32_t e = 0; e < entries; ++e) {
      uint8_t name_len;
      uint32_t value_size;
      if (!c.u8(&name_len) || !c.skip(name_len) || !c.varint32(&value_size)) return truncated();
      if (value_size == 0) return Status(ErrorCode::kBadValue, "Draco metadata entry without a value", c.pos());
      if (!c.skip(value_size)) return truncated();
    }
    if (!c.varint32(children)) return truncated();
    if (*children > c.remaining() / 3)
      return Status(ErrorCode::kBadValue, "Draco metadata declares " + std::to_string(*children) +
                                              " sub-metadata in " + std::to_string(c.remaining()) + " bytes", c.pos());
    return Status();
  };
  // A whole metadata tree; `pending` holds, per level, the children still
  // to read, so that a deep nesting costs no recursion.
  auto tree = [&]() -> Status {
    std::vector<uint32_t> pending(1);
    PSQ_RETURN_IF_ERROR(body(&pending[0]));
    while (!pending.empty()) {
      if (pending.back() == 0) {
        pending.pop_back();
        continue;
      }
      --pending.back();
      if (pending.size() >= kMaxMetadataDepth)
        return Status(ErrorCode::kUnsupported, "Draco metadata nested deeper than " +
                                                   std::to_string(kMaxMetadataDepth) + " levels", c.pos());
      uint8_t name_len;
      if (!c.u8(&name_len) || !c.skip(name_len)) return truncated();
      uint32_t children;
      PSQ_RETURN_IF_ERROR(body(&children));
      pending.push_back(children);
    }
    return Status();
  };
  uint32_t attribute_metadata;
  if (!c.varint32(&attribute_metadata)) return truncated();
  if (attribute_metadata > c.remaining() / 3)
    return Status(ErrorCode::kBadValue, "Draco metadata declares " + std::to_string(attribute_metadata) +
                                            " attribute metadata in " + std::to_string(c.remaining()) + " bytes",
                  c.pos());
  for (uint32_t a = 0; a < attribute_metadata; ++a) {
    uint32_t unique_id;
    if (!c.varint32(&unique_id)) return truncated();
    PSQ_RETURN_IF_ERROR(tree());
  }
  return tree();
}

}  // namespace

Status check_draco_header(const uint8_t* data, size_t size, uint64_t memory_budget, DracoHeaderInfo* info) {
  DracoHeaderInfo local;
  DracoHeaderInfo& h = info != nullptr ? *info : local;
  h = DracoHeaderInfo();
  ByteCursor c(data, size);
  if (!looks_like_draco(data, size)) return Status(ErrorCode::kUnknownFormat, "not a Draco file (no DRACO magic)", 0);
  if (size < kHeaderSize)
    return Status(ErrorCode::kTruncated, "Draco header ends after " + std::to_string(size) + " of " +
                                             std::to_string(kHeaderSize) + " bytes", size);
  c.skip(kMagicSize);
  uint8_t type = 0, method = 0;
  uint16_t flags = 0;
  c.u8(&h.version_major), c.u8(&h.version_minor), c.u8(&type), c.u8(&method), c.u16(&flags);
  if (type > 1) return Status(ErrorCode::kBadHeader, "unknown Draco geometry type " + std::to_string(type), 7);
  h.mesh = type == 1;
  const std::string what = h.mesh ? "mesh" : "point cloud";
  const uint8_t max_major = h.mesh ? kMeshMajor : kCloudMajor;
  const uint8_t max_minor = h.mesh ? kMeshMinor : kCloudMinor;
  const uint16_t version = version_of(h.version_major, h.version_minor);
  if (h.version_major < 1 || version > version_of(max_major, max_minor)) {
    return Status(ErrorCode::kUnsupported, "Draco " + what + " bitstream version " + std::to_string(h.version_major) +
                                               "." + std::to_string(h.version_minor) + " (libdraco reads 1.0 to " +
                                               std::to_string(max_major) + "." + std::to_string(max_minor) + ")",
                  5);
  }
  if (method > 1)
    return Status(ErrorCode::kBadHeader, "unknown Draco " + what + " encoding method " + std::to_string(method), 8);
  h.method = method;
  if ((flags & ~kMetadataFlag) != 0)
    return Status(ErrorCode::kBadHeader, "unknown Draco header flags 0x" + [&] {
      char buf[8];
      std::snprintf(buf, sizeof buf, "%04x", flags);
      return std::string(buf);
    }(), 9);
  if ((flags & kMetadataFlag) && version >= version_of(1, 3)) PSQ_RETURN_IF_ERROR(skip_metadata(c));

  size_t counts_at = c.pos();  // where the counts start, for the messages
  auto truncated = [&]() {
    return c.ended() ? Status(ErrorCode::kTruncated, "Draco " + what + " ends inside its element counts", c.pos())
                     : Status(ErrorCode::kBadValue, "malformed varint in the Draco " + what + "'s counts", c.pos());
  };
  // A 32-bit count: a varint from `varint_from` on, a raw uint32 before.
  auto count = [&](uint16_t varint_from, uint32_t* v) {
    return version >= varint_from ? c.varint32(v) : c.u32(v);
  };
  uint64_t estimate = size;  // the file itself is held while decoding
  if (!h.mesh) {
    // Sequential and k-d tree point clouds alike: an int32 point count.
    uint32_t points;
    if (!c.u32(&points)) return truncated();
    if (points > static_cast<uint32_t>(std::numeric_limits<int32_t>::max()))
      return Status(ErrorCode::kBadValue, "Draco point cloud declares a negative number of points", counts_at);
    h.points = points;
    estimate += h.points * kPointBytes;
  } else if (method == 0) {
    // Sequential mesh: face and point counts, then how indices are stored.
    uint32_t faces, points;
    if (!count(version_of(2, 2), &faces) || !count(version_of(2, 2), &points)) return truncated();
    uint8_t index_method;
    if (!c.u8(&index_method)) return truncated();
    h.faces = faces;
    h.points = points;
    if (h.faces > 0xffffffffu / 3)
      return Status(ErrorCode::kBadValue, "Draco mesh declares " + std::to_string(faces) + " faces (at most " +
                                              std::to_string(0xffffffffu / 3) + ")", counts_at);
    if (index_method != 0) {
      // Raw indices: 1, 2 or 4 bytes each by the point count, or a varint
      // of at least one byte; all of them must be in the file.
      uint64_t width = points < 256 ? 1 : points < (1u << 16) ? 2 : 4;
      if (points >= (1u << 16) && points < (1u << 21) && version >= version_of(2, 2)) width = 1;
      if (h.faces * 3 * width > c.remaining()) {
        return Status(ErrorCode::kBadValue, "Draco mesh declares " + std::to_string(faces) +
                                                " faces, but their indices need " +
                                                std::to_string(h.faces * 3 * width) + " bytes and " +
                                                std::to_string(c.remaining()) + " remain", counts_at);
      }
    }
    // The faces, plus the entropy-decoded index buffer or the raw indices.
    estimate += h.faces * (12 + 12) + h.points * kPointBytes;
  } else {
    // Edgebreaker: the traversal kind, then (older versions: new vertices)
    // encoded vertices, faces, attribute connectivities, symbols, splits.
    uint8_t traversal;
    if (!c.u8(&traversal)) return truncated();
    if (traversal > 2)
      return Status(ErrorCode::kBadHeader, "unknown Draco edgebreaker traversal " + std::to_string(traversal),
                    c.pos() - 1);
    counts_at = c.pos();
    uint32_t new_vertices = 0, vertices, faces, symbols, splits;
    uint8_t attribute_data;
    if (version < version_of(2, 2) && !count(version_of(2, 0), &new_vertices)) return truncated();
    if (!count(version_of(2, 0), &vertices) || !count(version_of(2, 0), &faces)) return truncated();
    if (!c.u8(&attribute_data) || !count(version_of(2, 0), &symbols) || !count(version_of(2, 0), &splits))
      return truncated();
    h.faces = faces;
    // Every encoded vertex is a corner of some face (the edgebreaker keeps
    // no isolated points), so the vertices are bounded by the corners; the
    // split symbols add temporary vertices, merged again while decoding.
    const uint64_t corners = h.faces * 3;
    const uint64_t all_vertices = uint64_t{vertices} + new_vertices + splits;
    if (h.faces > std::numeric_limits<uint32_t>::max() / 3)
      return Status(ErrorCode::kBadValue, "Draco mesh declares " + std::to_string(faces) + " faces (at most " +
                                              std::to_string(std::numeric_limits<uint32_t>::max() / 3) + ")",
                    counts_at);
    if (symbols > faces || splits > symbols || uint64_t{vertices} + new_vertices > corners) {
      return Status(ErrorCode::kBadValue, "Draco mesh declares inconsistent counts: " + std::to_string(faces) +
                                              " faces, " + std::to_string(all_vertices) + " vertices, " +
                                              std::to_string(symbols) + " symbols, " + std::to_string(splits) +
                                              " split symbols", counts_at);
    }
    // The standard traversal spends at least one bit per symbol.
    if (traversal == 0 && symbols / 8 > c.remaining()) {
      return Status(ErrorCode::kBadValue, "Draco mesh declares " + std::to_string(symbols) +
                                              " edgebreaker symbols, more than the " + std::to_string(c.remaining()) +
                                              " bytes left can hold", counts_at);
    }
    h.points = all_vertices;
    estimate += h.faces * (kFaceBytes + kAttributeFaceBytes * attribute_data) + all_vertices * kVertexBytes +
                all_vertices * kPointBytes;
  }
  h.estimated_bytes = estimate;
  if (estimate > memory_budget) {
    return Status(ErrorCode::kLimit, "Draco is read in memory: the declared " +
                                         (h.mesh ? std::to_string(h.faces) + " faces and " : std::string()) +
                                         std::to_string(h.points) + " points need about " + mib(estimate) +
                                         ", over the memory budget of " + mib(memory_budget) + " (--memory)",
                  counts_at);
  }
  return Status();
}

namespace {

bool valid_property_name(const std::string& s) {
  if (s.empty() || s.size() > 64) return false;
  for (unsigned char c : s)
    if (c <= ' ' || c >= 127) return false;
  return s != "x" && s != "y" && s != "z";
}

}  // namespace

bool looks_like_draco(const uint8_t* data, size_t size) {
  return size >= kMagicSize && std::memcmp(data, kMagic, kMagicSize) == 0;
}

// ------------------------------------------------------------------ reader

struct DracoReader::Impl {
  struct Column {
    const draco::PointAttribute* att = nullptr;
    int components = 0;
    int corner = -1;  // welded (below): 0 normals, 1 texture coordinates per corner, else -1
  };
  MeshSchema schema;
  SourceReport report;
  std::string name;
  std::unique_ptr<draco::PointCloud> cloud;
  const draco::Mesh* mesh = nullptr;  // cloud, when it has faces
  const draco::PointAttribute* position = nullptr;
  std::vector<Column> columns;
  uint32_t num_points = 0;
  uint32_t num_faces = 0;
  uint32_t next_vertex = 0;
  uint32_t next_face = 0;
  bool ended = false;
  Status error;
  // Welded: a vertex per position value, which Draco's points map to (a
  // mesh with texture seams or creases has several points at one position,
  // 8.5 of spec/psq-format.md), normals and texture coordinates that
  // differ between them per corner; else a vertex per point.
  bool welded = false;
  uint32_t num_vertices = 0;
  std::vector<uint32_t> vertex_of;  // by point
  std::vector<uint32_t> point_of;   // by vertex: a point at it

  // Whether the points can be welded by their position values: a mesh
  // whose position values are each some points', and whose attributes
  // other than one normal and one texture coordinate are the same at every
  // point of a position. Sets vertex_of, point_of and the columns' corner.
  bool weld(const std::vector<int>& column_kind);
  // The bytes of value `point` of `att`, or null when the file's mapping or
  // buffer does not hold them.
  static const uint8_t* value_at(const draco::PointAttribute* att, uint32_t point) {
    if (!att->is_mapping_identity() && point >= att->indices_map_size()) return nullptr;
    draco::AttributeValueIndex avi = att->mapped_index(draco::PointIndex(point));
    if (avi.value() >= att->size()) return nullptr;
    const draco::DataBuffer* b = att->buffer();
    if (b == nullptr) return nullptr;
    const int64_t len = static_cast<int64_t>(draco::DataTypeLength(att->data_type())) * att->num_components();
    const int64_t pos = att->byte_offset() + att->byte_stride() * static_cast<int64_t>(avi.value());
    if (pos < 0 || len <= 0 || pos + len > static_cast<int64_t>(b->data_size())) return nullptr;
    return b->data() + pos;
  }
};

bool DracoReader::Impl::weld(const std::vector<int>& column_kind) {
  if (mesh == nullptr || position->is_mapping_identity() || position->indices_map_size() < num_points) return false;
  const uint32_t nv = static_cast<uint32_t>(position->size());
  if (nv == 0 || nv >= num_points) return false;
  vertex_of.assign(num_points, 0);
  point_of.assign(nv, UINT32_MAX);
  for (uint32_t p = 0; p < num_points; ++p) {
    const uint32_t v = position->mapped_index(draco::PointIndex(p)).value();
    if (v >= nv) return false;
    vertex_of[p] = v;
    if (point_of[v] == UINT32_MAX) point_of[v] = p;
  }
  for (uint32_t v = 0; v < nv; ++v)
    if (point_of[v] == UINT32_MAX) return false;
  for (size_t c = 0; c < columns.size(); ++c) {
    const Column& col = columns[c];
    const size_t len = static_cast<size_t>(draco::DataTypeLength(col.att->data_type())) * col.components;
    bool same = true;
    for (uint32_t p = 0; p < num_points && same; ++p) {
      const uint8_t* a = value_at(col.att, p);
      const uint8_t* b = value_at(col.att, point_of[vertex_of[p]]);
      if (a == nullptr || b == nullptr) return false;
      same = std::memcmp(a, b, len) == 0;
    }
    if (same) continue;
    if (column_kind[c] < 0) return false;  // only normals and texture coordinates go per corner
    columns[c].corner = column_kind[c];
  }
  num_vertices = nv;
  return true;
}

DracoReader::DracoReader() : impl_(std::make_unique<Impl>()) {}
DracoReader::~DracoReader() = default;

Status DracoReader::open(InputStream* in, uint64_t memory_budget) {
  Impl& m = *impl_;
  m.name = in->name();
  if (in->size() >= 0 && static_cast<uint64_t>(in->size()) > memory_budget) {
    return Status(ErrorCode::kLimit, "Draco is read in memory: the file (" + mib(in->size()) +
                                         ") exceeds the memory budget of " + mib(memory_budget) + " (--memory)");
  }
  std::vector<char> bytes;
  for (;;) {
    size_t avail = 0;
    PSQ_RETURN_IF_ERROR(in->fill(size_t{1} << 20, &avail));
    if (avail == 0) break;
    if (bytes.size() + avail > memory_budget) {
      return Status(ErrorCode::kLimit, "Draco is read in memory: the input exceeds the memory budget of " +
                                           mib(memory_budget) + " (--memory)");
    }
    bytes.insert(bytes.end(), in->cursor(), in->cursor() + avail);
    in->advance(avail);
  }
  // libdraco allocates what the file's counts ask for before it reads the
  // data they describe: the counts are checked first (see draco.h).
  DracoHeaderInfo header;
  PSQ_RETURN_IF_ERROR(check_draco_header(reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size(),
                                         memory_budget, &header));

  draco::DecoderBuffer buffer;
  buffer.Init(bytes.data(), bytes.size());
  // Where libdraco stopped: its buffer always points into `bytes` (the
  // edgebreaker re-initialises it further on, never elsewhere).
  auto stopped_at = [&]() -> uint64_t {
    const char* head = buffer.data_head();
    if (head < bytes.data() || head > bytes.data() + bytes.size()) return 0;
    return static_cast<uint64_t>(head - bytes.data());
  };
  draco::Decoder decoder;
  try {
    if (header.mesh) {
      auto decoded = decoder.DecodeMeshFromBuffer(&buffer);
      if (!decoded.ok() || !decoded.value())
        return Status(ErrorCode::kBadValue, corrupt("corrupt Draco mesh", decoded.status()), stopped_at());
      std::unique_ptr<draco::Mesh> mesh = std::move(decoded).value();
      m.mesh = mesh.get();
      m.num_faces = mesh->num_faces();
      m.cloud = std::move(mesh);
    } else {
      auto decoded = decoder.DecodePointCloudFromBuffer(&buffer);
      if (!decoded.ok() || !decoded.value())
        return Status(ErrorCode::kBadValue, corrupt("corrupt Draco point cloud", decoded.status()), stopped_at());
      m.cloud = std::move(decoded).value();
    }
  } catch (const std::bad_alloc&) {
    return Status(ErrorCode::kLimit, "out of memory decoding the Draco data (corrupt counts, or a mesh too large)",
                  stopped_at());
  } catch (const std::exception& e) {
    return Status(ErrorCode::kBadValue, std::string("corrupt Draco data: ") + e.what(), stopped_at());
  }
  m.num_points = m.cloud->num_points();

  // What the decoded geometry takes, against the budget.
  uint64_t used = bytes.size() + uint64_t{12} * m.num_faces;
  for (int32_t a = 0; a < m.cloud->num_attributes(); ++a) {
    const draco::PointAttribute* att = m.cloud->attribute(a);
    if (att == nullptr) continue;
    if (att->buffer()) used += att->buffer()->data_size();
    used += uint64_t{4} * att->indices_map_size();
  }
  if (used > memory_budget) {
    return Status(ErrorCode::kLimit, "Draco is read in memory: the decoded mesh takes " + mib(used) +
                                         ", over the memory budget of " + mib(memory_budget) + " (--memory)");
  }

  // Attributes to properties.
  std::set<std::string> names;
  bool have_normal = false, have_color = false, have_uv = false;
  std::vector<int> column_kind;  // 0 the normal, 1 the texture coordinate, else -1
  std::vector<size_t> column_first;  // its first vertex property
  auto add = [&](const std::string& n, ScalarType t) {
    Property p;
    p.name = n;
    p.type = t;
    m.schema.vertex_properties.push_back(p);
    names.insert(n);
  };
  for (int32_t a = 0; a < m.cloud->num_attributes(); ++a) {
    const draco::PointAttribute* att = m.cloud->attribute(a);
    if (att == nullptr || att->num_components() == 0) continue;
    const int nc = att->num_components();
    ScalarType t;
    if (!scalar_of(att->data_type(), &t)) {
      if (att->data_type() == draco::DT_INT64 || att->data_type() == draco::DT_UINT64) {
        t = ScalarType::kFloat64;
        m.report.notes.push_back("Draco attribute " + std::to_string(a) + " has 64-bit integers: read as double");
      } else {
        m.report.notes.push_back("Draco attribute " + std::to_string(a) + " has an unknown data type: skipped");
        continue;
      }
    }
    const auto at = att->attribute_type();
    if (at == draco::GeometryAttribute::POSITION && m.position == nullptr && nc <= 3) {
      m.position = att;
      m.schema.position_type = (t == ScalarType::kFloat64 || t == ScalarType::kInt32 || t == ScalarType::kUInt32)
                                   ? ScalarType::kFloat64
                                   : ScalarType::kFloat32;
      continue;
    }
    Impl::Column col{att, nc};
    column_first.push_back(m.schema.vertex_properties.size());
    column_kind.push_back(-1);
    if (at == draco::GeometryAttribute::NORMAL && !have_normal && nc == 3 &&
        !names.count("nx") && !names.count("ny") && !names.count("nz")) {
      have_normal = true;
      column_kind.back() = 0;
      add("nx", t), add("ny", t), add("nz", t);
    } else if (at == draco::GeometryAttribute::COLOR && !have_color && (nc == 3 || nc == 4) &&
               !names.count("red") && !names.count("green") && !names.count("blue") && !names.count("alpha")) {
      have_color = true;
      add("red", t), add("green", t), add("blue", t);
      if (nc == 4) add("alpha", t);
    } else if (at == draco::GeometryAttribute::TEX_COORD && !have_uv && nc == 2 && !names.count("u") &&
               !names.count("v")) {
      have_uv = true;
      column_kind.back() = 1;
      add("u", t), add("v", t);
    } else {
      std::string meta;
      const draco::AttributeMetadata* md = m.cloud->GetAttributeMetadataByAttributeId(a);
      if (nc == 1 && md != nullptr && md->GetEntryString("name", &meta) && valid_property_name(meta) &&
          !names.count(meta)) {
        add(meta, t);
      } else {
        for (int k = 0; k < nc; ++k) {
          std::string n = "attr" + std::to_string(a) + "_" + std::to_string(k);
          while (names.count(n)) n += "_";
          add(n, t);
        }
      }
    }
    m.columns.push_back(col);
  }
  if (m.position == nullptr) return Status(ErrorCode::kBadValue, "Draco geometry without a position attribute");
  m.welded = m.weld(column_kind);
  m.schema.vertex_count = m.num_points;
  if (m.welded) {
    // The corner columns' vertex properties become face lists.
    for (size_t c = m.columns.size(); c-- > 0;) {
      if (m.columns[c].corner < 0) continue;
      const Property p = m.schema.vertex_properties[column_first[c]];
      m.schema.vertex_properties.erase(m.schema.vertex_properties.begin() + static_cast<std::ptrdiff_t>(column_first[c]),
                                       m.schema.vertex_properties.begin() +
                                           static_cast<std::ptrdiff_t>(column_first[c] + m.columns[c].components));
      Property list;
      list.name = m.columns[c].corner == 0 ? "corner_normals" : "corner_uv";
      list.type = p.type == ScalarType::kFloat64 ? ScalarType::kFloat64 : ScalarType::kFloat32;
      list.is_list = true;
      list.count_type = ScalarType::kUInt8;
      m.schema.face_properties.insert(m.schema.face_properties.begin(), list);
    }
    if (m.schema.face_properties.size() == 2 && m.schema.face_properties[0].name == "corner_uv")
      std::swap(m.schema.face_properties[0], m.schema.face_properties[1]);
    m.schema.vertex_count = m.num_vertices;
    m.report.notes.push_back(std::to_string(m.num_points) + " Draco points welded into " +
                             std::to_string(m.num_vertices) + " vertices by position, " +
                             (m.schema.face_properties.empty() ? std::string("their attributes the same")
                                                               : "the attributes that differ kept per corner"));
  }
  m.schema.triangle_count = m.num_faces;
  if (m.mesh == nullptr) m.report.notes.push_back("Draco point cloud: vertices only");
  return Status();
}

const MeshSchema& DracoReader::schema() const { return impl_->schema; }
const SourceReport& DracoReader::report() const { return impl_->report; }

Status DracoReader::next(MeshItem* item) {
  Impl& m = *impl_;
  if (!m.error.ok()) return m.error;
  item->values.clear();
  if (m.next_vertex < (m.welded ? m.num_vertices : m.num_points)) {
    const uint32_t i = m.welded ? m.point_of[m.next_vertex] : m.next_vertex;
    const uint8_t* p = Impl::value_at(m.position, i);
    if (p == nullptr) return m.error = Status(ErrorCode::kBadValue, "corrupt Draco data: point " + std::to_string(i) + " has no position");
    const int nc = m.position->num_components();
    for (int k = 0; k < 3; ++k) {
      item->position[k] = k < nc ? component(m.position->data_type(), p, k) : 0.0;
      if (!std::isfinite(item->position[k]))
        return m.error = Status(ErrorCode::kBadValue, "Draco point " + std::to_string(i) + " has a non-finite position");
    }
    for (const Impl::Column& c : m.columns) {
      if (c.corner >= 0) continue;
      const uint8_t* q = Impl::value_at(c.att, i);
      if (q == nullptr)
        return m.error = Status(ErrorCode::kBadValue, "corrupt Draco data: point " + std::to_string(i) + " has no attribute value");
      for (int k = 0; k < c.components; ++k) item->values.push_back(component(c.att->data_type(), q, k));
    }
    item->kind = MeshItem::Kind::kVertex;
    ++m.next_vertex;
    return Status();
  }
  if (m.mesh != nullptr && m.next_face < m.num_faces) {
    const draco::Mesh::Face& f = m.mesh->face(draco::FaceIndex(m.next_face));
    for (int k = 0; k < 3; ++k) {
      if (f[k].value() >= m.num_points)
        return m.error = Status(ErrorCode::kBadIndex, "corrupt Draco data: face " + std::to_string(m.next_face) +
                                                          " refers to point " + std::to_string(f[k].value()) + " of " +
                                                          std::to_string(m.num_points));
      item->index[k] = m.welded ? m.vertex_of[f[k].value()] : f[k].value();
    }
    // The corner lists, normals first, each corner's values in turn.
    for (int kind = 0; kind < 2 && m.welded; ++kind)
      for (const Impl::Column& c : m.columns) {
        if (c.corner != kind) continue;
        item->values.push_back(3.0 * c.components);
        for (int k = 0; k < 3; ++k) {
          const uint8_t* q = Impl::value_at(c.att, f[k].value());
          if (q == nullptr)
            return m.error = Status(ErrorCode::kBadValue, "corrupt Draco data: point " + std::to_string(f[k].value()) +
                                                              " has no attribute value");
          for (int d = 0; d < c.components; ++d) item->values.push_back(component(c.att->data_type(), q, d));
        }
      }
    item->kind = MeshItem::Kind::kTriangle;
    ++m.next_face;
    return Status();
  }
  item->kind = MeshItem::Kind::kEnd;
  return Status();
}

// ------------------------------------------------------------------ writer

struct DracoWriter::Impl {
  // One Draco attribute made of vertex properties.
  struct Group {
    draco::GeometryAttribute::Type type = draco::GeometryAttribute::GENERIC;
    draco::DataType data_type = draco::DT_FLOAT32;
    bool normalized = false;
    std::vector<int> props;  // indices into the schema's vertex properties
    std::string name;        // GENERIC: the property's name
  };
  OutputFile* out = nullptr;
  DracoWriteOptions options;
  MeshSchema schema;
  std::vector<Group> groups;
  std::vector<int> kept;          // schema property index -> slot in `values`, or -1
  size_t slots = 0;               // kept values per vertex
  std::vector<double> positions;  // 3 per vertex
  std::vector<double> values;     // `slots` per vertex
  std::vector<uint32_t> indices;  // 3 per triangle
  // Normals and texture coordinates per corner (the face lists
  // corner_normals and corner_uv of psq's OBJ reader and codec, spec 8.5):
  // Draco keeps them as attributes of points, one point per distinct
  // vertex and corner values, its positions mapped to the vertices.
  struct CornerList {
    int property = -1;  // index of the face property, or -1
    int arity = 0;      // values a corner: 3 or 2
  };
  CornerList corner[2];          // normals, texture coordinates
  int corner_slots = 0;          // values a corner, both lists
  std::vector<double> corners;   // corner_slots per corner, 3 corners per triangle
  uint64_t vertex_cost = 0;       // bytes per vertex, buffered and in Draco
  uint64_t used = 0;
  std::vector<std::string> dropped;
  std::vector<std::string> notes;

  // Positions Draco stores as floats: each must fit a float; quantized,
  // the range Draco computes in float must be finite, and a double
  // position's rounding to float must stay within half of Draco's
  // quantization step, or the output would not hold the positions at the
  // precision asked for. Errors: kBadValue, kLimit (naming the vertex).
  Status check_float_positions(uint32_t nv) const {
    float lo[3], hi[3];
    for (uint32_t i = 0; i < nv; ++i) {
      for (int k = 0; k < 3; ++k) {
        const double v = positions[3 * size_t{i} + k];
        if (!fits_float(v))
          return Status(ErrorCode::kBadValue, "vertex " + std::to_string(i) + ": " + kAxisName[k] + " = " +
                                                  number_text(v) +
                                                  " is beyond float range (Draco stores float positions)");
        const float f = static_cast<float>(v);
        lo[k] = i == 0 ? f : std::min(lo[k], f);
        hi[k] = i == 0 ? f : std::max(hi[k], f);
      }
    }
    if (options.lossless) return Status();
    // Draco's quantization (AttributeQuantizationTransform): the largest
    // per-axis range, in float, 1 when it is 0.
    float range = 0;
    for (int k = 0; k < 3; ++k) {
      const float e = hi[k] - lo[k];
      if (!std::isfinite(e))
        return Status(ErrorCode::kLimit, std::string("positions span ") + number_text(lo[k]) + " to " +
                                             number_text(hi[k]) + " on " + kAxisName[k] +
                                             ": the range overflows Draco's float quantization (write .psq, or "
                                             "Draco lossless)");
      range = std::max(range, e);
    }
    if (range == 0) range = 1;
    if (schema.position_type != ScalarType::kFloat64) return Status();
    const double half_step = 0.5 * static_cast<double>(range) / static_cast<double>((uint64_t{1} << options.bits) - 1);
    for (uint32_t i = 0; i < nv; ++i) {
      for (int k = 0; k < 3; ++k) {
        const double v = positions[3 * size_t{i} + k];
        volatile float f = static_cast<float>(v);  // volatile: the GCC 12 rounding trap (toolchain/README)
        const double stored = f;
        if (std::fabs(stored - v) > half_step)
          return Status(ErrorCode::kLimit, "vertex " + std::to_string(i) + ": " + kAxisName[k] + " = " +
                                               number_text(v) + " becomes " + number_text(stored) +
                                               " as a float, more than half a quantization step (" +
                                               number_text(2 * half_step) +
                                               ") away (Draco stores float positions; Draco lossless keeps "
                                               "doubles)");
      }
    }
    return Status();
  }

  Status charge(uint64_t bytes) {
    used += bytes;
    if (used > options.memory_budget) {
      return Status(ErrorCode::kLimit, "Draco is written in memory: the mesh exceeds the memory budget of " +
                                           mib(options.memory_budget) + " (--memory)");
    }
    return Status();
  }
};

DracoWriter::DracoWriter(OutputFile* out, DracoWriteOptions options) : impl_(std::make_unique<Impl>()) {
  impl_->out = out;
  impl_->options = options;
}
DracoWriter::~DracoWriter() = default;

const std::vector<std::string>& DracoWriter::dropped() const { return impl_->dropped; }
const std::vector<std::string>& DracoWriter::notes() const { return impl_->notes; }

Status DracoWriter::begin(const MeshSchema& schema) {
  Impl& m = *impl_;
  if (!m.options.lossless && (m.options.bits < 1 || m.options.bits > 30))
    return Status(ErrorCode::kUsage, "Draco quantizes positions to 1..30 bits, not " + std::to_string(m.options.bits));
  m.schema = schema;
  const auto& props = schema.vertex_properties;
  auto find = [&](const char* n) -> int {
    for (size_t i = 0; i < props.size(); ++i)
      if (props[i].name == n && !props[i].is_list) return static_cast<int>(i);
    return -1;
  };
  std::vector<bool> used(props.size(), false);
  // Corner lists take the place of the vertex attribute of their kind
  // (whose properties then stay, as generic attributes).
  const auto& fprops = schema.face_properties;
  for (size_t i = 0; i < fprops.size(); ++i) {
    const bool real = fprops[i].is_list &&
                      (fprops[i].type == ScalarType::kFloat32 || fprops[i].type == ScalarType::kFloat64);
    const int c = fprops[i].name == "corner_normals" ? 0 : fprops[i].name == "corner_uv" ? 1 : -1;
    if (!real || c < 0 || m.corner[c].property >= 0) continue;
    m.corner[c] = {static_cast<int>(i), c == 0 ? 3 : 2};
    m.corner_slots += m.corner[c].arity;
  }
  int nx = find("nx"), ny = find("ny"), nz = find("nz");
  if (m.corner[0].property < 0 && nx >= 0 && ny >= 0 && nz >= 0) {
    Impl::Group g;
    g.type = draco::GeometryAttribute::NORMAL;
    g.props = {nx, ny, nz};
    m.groups.push_back(g);
  }
  int r = find("red"), gr = find("green"), b = find("blue"), al = find("alpha");
  auto is_uchar = [&](int i) { return i >= 0 && props[i].type == ScalarType::kUInt8; };
  if (!(is_uchar(r) && is_uchar(gr) && is_uchar(b))) r = find("r"), gr = find("g"), b = find("b"), al = find("a");
  if (is_uchar(r) && is_uchar(gr) && is_uchar(b)) {
    Impl::Group g;
    g.type = draco::GeometryAttribute::COLOR;
    g.data_type = draco::DT_UINT8;
    g.normalized = true;
    g.props = {r, gr, b};
    if (is_uchar(al)) g.props.push_back(al);
    m.groups.push_back(g);
  }
  // Texture coordinates by any of the names psq's codec knows (spec 8.3).
  int u = -1, v = -1;
  for (auto [un, vn] : {std::pair<const char*, const char*>{"u", "v"}, {"s", "t"}, {"texture_u", "texture_v"},
                        {"texture_s", "texture_t"}})
    if (u < 0 || v < 0) u = find(un), v = find(vn);
  if (m.corner[1].property < 0 && u >= 0 && v >= 0) {
    Impl::Group g;
    g.type = draco::GeometryAttribute::TEX_COORD;
    g.props = {u, v};
    m.groups.push_back(g);
  }
  for (const Impl::Group& g : m.groups)
    for (int i : g.props) used[i] = true;
  for (size_t i = 0; i < props.size(); ++i) {
    if (used[i]) continue;
    if (props[i].is_list) {
      m.dropped.push_back(props[i].name);
      continue;
    }
    Impl::Group g;
    g.type = draco::GeometryAttribute::GENERIC;
    g.data_type = draco_of(props[i].type);
    g.props = {static_cast<int>(i)};
    g.name = props[i].name;
    m.groups.push_back(g);
  }
  for (size_t i = 0; i < fprops.size(); ++i)
    if (static_cast<int>(i) != m.corner[0].property && static_cast<int>(i) != m.corner[1].property)
      m.dropped.push_back(fprops[i].name);
  m.kept.assign(props.size(), -1);
  uint64_t draco_bytes = 12;  // position
  for (const Impl::Group& g : m.groups) {
    for (int i : g.props) m.kept[i] = static_cast<int>(m.slots++);
    draco_bytes += static_cast<uint64_t>(draco::DataTypeLength(g.data_type)) * g.props.size();
  }
  m.vertex_cost = 24 + 8 * m.slots + draco_bytes;
  return Status();
}

Status DracoWriter::vertex(const double position[3], const PropertyValues& values) {
  Impl& m = *impl_;
  if (m.positions.size() / 3 >= static_cast<size_t>(std::numeric_limits<int32_t>::max()))
    return Status(ErrorCode::kLimit, "Draco holds at most 2^31 - 1 points");
  PSQ_RETURN_IF_ERROR(m.charge(m.vertex_cost));
  m.positions.insert(m.positions.end(), position, position + 3);
  // Scalar values of kept properties, skipping lists.
  const auto& props = m.schema.vertex_properties;
  size_t at = 0;
  const size_t base = m.values.size();
  m.values.resize(base + m.slots, 0.0);
  for (size_t i = 0; i < props.size() && at < values.size(); ++i) {
    if (props[i].is_list) {
      at += 1 + static_cast<size_t>(values[at]);
      continue;
    }
    if (m.kept[i] >= 0) m.values[base + m.kept[i]] = values[at];
    ++at;
  }
  return Status();
}

Status DracoWriter::triangle(const uint32_t index[3], const PropertyValues& values) {
  Impl& m = *impl_;
  // Buffered, Draco's face, its corner table (roughly); corner values
  // buffered and in Draco's points.
  PSQ_RETURN_IF_ERROR(m.charge(12 + 12 + 12 + uint64_t{3} * 12 * static_cast<uint64_t>(m.corner_slots)));
  m.indices.insert(m.indices.end(), index, index + 3);
  if (m.corner_slots == 0) return Status();
  const size_t base = m.corners.size();
  m.corners.resize(base + 3 * static_cast<size_t>(m.corner_slots));
  const auto& fprops = m.schema.face_properties;
  size_t at = 0;
  for (size_t i = 0; i < fprops.size() && at < values.size(); ++i) {
    const size_t n = fprops[i].is_list ? static_cast<size_t>(values[at]) : 0;
    for (int c = 0, offset = 0; c < 2; offset += m.corner[c].arity, ++c) {
      if (m.corner[c].property != static_cast<int>(i)) continue;
      const int arity = m.corner[c].arity;
      if (n != static_cast<size_t>(3 * arity) || values.size() - at < 1 + n)
        return Status(ErrorCode::kBadValue, "triangle " + std::to_string(m.indices.size() / 3 - 1) + ": " +
                                                fprops[i].name + " holds " + std::to_string(n) + " values, not " +
                                                std::to_string(3 * arity));
      for (int k = 0; k < 3; ++k)
        for (int d = 0; d < arity; ++d)
          m.corners[base + static_cast<size_t>(k * m.corner_slots + offset + d)] = values[at + 1 + k * arity + d];
    }
    at += fprops[i].is_list ? 1 + n : 1;
  }
  return Status();
}

Status DracoWriter::finish() {
  Impl& m = *impl_;
  const uint32_t nv = static_cast<uint32_t>(m.positions.size() / 3);
  const uint32_t nt = static_cast<uint32_t>(m.indices.size() / 3);
  if (nv == 0) return Status(ErrorCode::kUnsupported, "Draco cannot hold a mesh without vertices");
  for (uint32_t i : m.indices)
    if (i >= nv) return Status(ErrorCode::kBadIndex, "triangle refers to vertex " + std::to_string(i) + " of " + std::to_string(nv));
  if (nt > 0) {
    // What edgebreaker will not keep, for the user.
    std::vector<bool> referenced(nv, false);
    uint64_t degenerate = 0;
    for (uint32_t f = 0; f < nt; ++f) {
      const uint32_t* t = &m.indices[3 * size_t{f}];
      if (t[0] == t[1] || t[1] == t[2] || t[2] == t[0]) {
        ++degenerate;
        continue;
      }
      for (int k = 0; k < 3; ++k) referenced[t[k]] = true;
    }
    const uint64_t unreferenced = static_cast<uint64_t>(std::count(referenced.begin(), referenced.end(), false));
    if (unreferenced)
      m.notes.push_back(std::to_string(unreferenced) + " unreferenced vertex(es) dropped: Draco meshes keep only vertices of triangles");
    if (degenerate)
      m.notes.push_back(std::to_string(degenerate) + " degenerate triangle(s) dropped by Draco");
  }

  const bool double_positions = m.options.lossless && m.schema.position_type == ScalarType::kFloat64;
  if (!double_positions) PSQ_RETURN_IF_ERROR(m.check_float_positions(nv));

  // With corner values: a point per distinct vertex and corner values,
  // found among its vertex's points so far (a vertex has few).
  const int cs = m.corner_slots;
  std::vector<uint32_t> point_vertex, corner_point;
  std::vector<double> point_values;
  if (cs > 0) {
    std::vector<uint32_t> first(nv, UINT32_MAX), next;
    corner_point.resize(m.indices.size());
    for (size_t c = 0; c < m.indices.size(); ++c) {
      const uint32_t v = m.indices[c];
      const double* x = &m.corners[c * static_cast<size_t>(cs)];
      uint32_t p = first[v];
      while (p != UINT32_MAX && !std::equal(x, x + cs, &point_values[size_t{p} * static_cast<size_t>(cs)])) p = next[p];
      if (p == UINT32_MAX) {
        if (point_vertex.size() >= static_cast<size_t>(std::numeric_limits<int32_t>::max()))
          return Status(ErrorCode::kLimit, "Draco holds at most 2^31 - 1 points");
        p = static_cast<uint32_t>(point_vertex.size());
        point_vertex.push_back(v);
        point_values.insert(point_values.end(), x, x + cs);
        next.push_back(first[v]);
        first[v] = p;
      }
      corner_point[c] = p;
    }
    std::vector<double>().swap(m.corners);
  }
  const uint32_t np = cs > 0 ? static_cast<uint32_t>(point_vertex.size()) : nv;

  draco::Mesh mesh;
  mesh.set_num_points(np);
  // An attribute of nv values, one a vertex: the points map to their
  // vertices' (the positions, welded, and every vertex property).
  auto add_attribute = [&](draco::GeometryAttribute::Type type, draco::DataType dt, int nc, bool normalized) {
    draco::GeometryAttribute ga;
    ga.Init(type, nullptr, static_cast<uint8_t>(nc), dt, normalized, int64_t{draco::DataTypeLength(dt)} * nc, 0);
    if (cs == 0) return mesh.AddAttribute(ga, true, nv);
    const int id = mesh.AddAttribute(ga, false, nv);
    draco::PointAttribute* att = mesh.attribute(id);
    att->SetExplicitMapping(np);
    for (uint32_t p = 0; p < np; ++p)
      att->SetPointMapEntry(draco::PointIndex(p), draco::AttributeValueIndex(point_vertex[p]));
    return id;
  };
  const draco::DataType pos_type = double_positions ? draco::DT_FLOAT64 : draco::DT_FLOAT32;
  const int pos_id = add_attribute(draco::GeometryAttribute::POSITION, pos_type, 3, false);
  {
    draco::PointAttribute* att = mesh.attribute(pos_id);
    uint8_t buf[24];
    for (uint32_t i = 0; i < nv; ++i) {
      for (int k = 0; k < 3; ++k) put_component(pos_type, buf, k, m.positions[3 * size_t{i} + k]);
      att->SetAttributeValue(draco::AttributeValueIndex(i), buf);
    }
  }
  std::vector<double>().swap(m.positions);
  std::vector<std::pair<int, const Impl::Group*>> ids;
  for (const Impl::Group& g : m.groups) {
    const int nc = static_cast<int>(g.props.size());
    const int id = add_attribute(g.type, g.data_type, nc, g.normalized);
    draco::PointAttribute* att = mesh.attribute(id);
    std::vector<uint8_t> buf(static_cast<size_t>(draco::DataTypeLength(g.data_type)) * nc);
    for (uint32_t i = 0; i < nv; ++i) {
      for (int k = 0; k < nc; ++k) {
        const double v = m.values[size_t{i} * m.slots + m.kept[g.props[k]]];
        if (g.data_type == draco::DT_FLOAT32 && !fits_float(v))
          return Status(ErrorCode::kBadValue, "vertex " + std::to_string(i) + ": " +
                                                  m.schema.vertex_properties[g.props[k]].name + " = " +
                                                  number_text(v) + " is beyond float range (Draco stores a float)");
        put_component(g.data_type, buf.data(), k, v);
      }
      att->SetAttributeValue(draco::AttributeValueIndex(i), buf.data());
    }
    if (g.type == draco::GeometryAttribute::GENERIC) {
      auto md = std::make_unique<draco::AttributeMetadata>();
      md->AddEntryString("name", g.name);
      mesh.AddAttributeMetadata(id, std::move(md));
    }
    ids.emplace_back(id, &g);
  }
  std::vector<double>().swap(m.values);
  // The corner attributes: a value a point.
  std::vector<std::pair<int, draco::GeometryAttribute::Type>> corner_ids;
  for (int c = 0, offset = 0; c < 2; offset += m.corner[c].arity, ++c) {
    if (m.corner[c].property < 0) continue;
    const int nc = m.corner[c].arity;
    draco::GeometryAttribute ga;
    const auto type = c == 0 ? draco::GeometryAttribute::NORMAL : draco::GeometryAttribute::TEX_COORD;
    ga.Init(type, nullptr, static_cast<uint8_t>(nc), draco::DT_FLOAT32, false, int64_t{4} * nc, 0);
    const int id = mesh.AddAttribute(ga, true, np);
    draco::PointAttribute* att = mesh.attribute(id);
    float buf[3];
    for (uint32_t p = 0; p < np; ++p) {
      for (int k = 0; k < nc; ++k) {
        const double v = point_values[size_t{p} * static_cast<size_t>(cs) + static_cast<size_t>(offset + k)];
        if (!fits_float(v))
          return Status(ErrorCode::kBadValue, m.schema.face_properties[m.corner[c].property].name + " value " +
                                                  number_text(v) + " is beyond float range (Draco stores a float)");
        buf[k] = static_cast<float>(v);
      }
      att->SetAttributeValue(draco::AttributeValueIndex(p), buf);
    }
    corner_ids.emplace_back(id, type);
  }
  mesh.SetNumFaces(nt);
  for (uint32_t f = 0; f < nt; ++f) {
    draco::Mesh::Face face;
    for (int k = 0; k < 3; ++k)
      face[k] = draco::PointIndex(cs > 0 ? corner_point[3 * size_t{f} + k] : m.indices[3 * size_t{f} + k]);
    mesh.SetFace(draco::FaceIndex(f), face);
  }
  std::vector<uint32_t>().swap(m.indices);

  const draco::PointCloud& geometry = mesh;
  std::unique_ptr<draco::ExpertEncoder> encoder =
      nt > 0 ? std::make_unique<draco::ExpertEncoder>(mesh) : std::make_unique<draco::ExpertEncoder>(geometry);
  encoder->SetSpeedOptions(3, 3);
  if (nt > 0) {
    encoder->SetEncodingMethod(draco::MESH_EDGEBREAKER_ENCODING);
  } else {
    encoder->SetEncodingMethod(draco::POINT_CLOUD_SEQUENTIAL_ENCODING);
  }
  if (!m.options.lossless) {
    encoder->SetAttributeQuantization(pos_id, m.options.bits);
    std::vector<std::pair<int, draco::GeometryAttribute::Type>> all = corner_ids;
    for (const auto& [id, g] : ids) all.emplace_back(id, g->type);
    for (const auto& [id, type] : all) {
      if (type == draco::GeometryAttribute::NORMAL) encoder->SetAttributeQuantization(id, 10);
      if (type == draco::GeometryAttribute::TEX_COORD) encoder->SetAttributeQuantization(id, 12);
    }
  }
  draco::EncoderBuffer buffer;
  draco::Status s;
  try {
    s = encoder->EncodeToBuffer(&buffer);
  } catch (const std::bad_alloc&) {
    return Status(ErrorCode::kLimit, "out of memory encoding the Draco mesh");
  }
  if (!s.ok()) return Status(ErrorCode::kInternal, "Draco refused to encode the mesh: " + s.error_msg_string());
  return m.out->write(buffer.data(), buffer.size());
}

}  // namespace psq
