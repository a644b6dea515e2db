// SPDX-License-Identifier: Apache-2.0
// Streaming PLY writer (psq/ply.h). PLY puts element counts in its header,
// so when the source cannot promise them up front the elements are spooled to
// unlinked temporary files and copied after the header at finish().
#include <sys/mman.h>
#include <unistd.h>

#include <algorithm>
#include <mutex>
#include <vector>
#include <charconv>
#include <cmath>
#include <limits>
#include <cstring>
#include <string>

#include "psq/ply.h"

namespace psq {
namespace {

// A double for a message: the shortest text that reads back to it.
std::string number_text(double v) {
  char buf[32];
  auto r = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, r.ptr);
}

// Whether float type `t` holds `v` without overflowing to an infinity (NaN
// and infinities are written as they are).
bool fits(ScalarType t, double v) {
  return t != ScalarType::kFloat32 || !(std::fabs(v) > std::numeric_limits<float>::max()) || std::isinf(v);
}

// Appends `v` as type `t` to `out`: binary (little or big endian) or ascii.
class ValueEncoder {
 public:
  explicit ValueEncoder(PlyEncoding enc) : enc_(enc) {}

  // Errors: kBadValue when type `t` cannot hold `v` (for float, a finite
  // value beyond its range, which would become an infinity).
  Status put(ScalarType t, double v, std::string* out) const {
    if (scalar_is_float(t) ? !fits(t, v) : !scalar_holds(t, v)) {
      return Status(ErrorCode::kBadValue, "value " + number_text(v) + " does not fit PLY type " + scalar_name(t));
    }
    if (enc_ == PlyEncoding::kAscii) {
      char buf[64];
      std::to_chars_result r;
      if (t == ScalarType::kFloat32) {
        r = std::to_chars(buf, buf + sizeof buf, static_cast<float>(v));
      } else if (t == ScalarType::kFloat64) {
        r = std::to_chars(buf, buf + sizeof buf, v);
      } else {
        r = std::to_chars(buf, buf + sizeof buf, static_cast<int64_t>(v));
      }
      if (!out->empty() && out->back() != '\n') out->push_back(' ');
      out->append(buf, r.ptr);
      return Status();
    }
    char b[8];
    char* e = b;
    switch (t) {
      case ScalarType::kInt8: e = store(static_cast<int8_t>(v), b); break;
      case ScalarType::kUInt8: e = store(static_cast<uint8_t>(v), b); break;
      case ScalarType::kInt16: e = store(static_cast<int16_t>(v), b); break;
      case ScalarType::kUInt16: e = store(static_cast<uint16_t>(v), b); break;
      case ScalarType::kInt32: e = store(static_cast<int32_t>(v), b); break;
      case ScalarType::kUInt32: e = store(static_cast<uint32_t>(v), b); break;
      case ScalarType::kFloat32: e = store(static_cast<float>(v), b); break;
      case ScalarType::kFloat64: e = store(v, b); break;
    }
    out->append(b, e);
    return Status();
  }

  // Stores `x` at `at` as its bytes in the binary encoding's order (the
  // host is little-endian); returns the end. For values known to fit their
  // type, callers build a record with it: put() without its check and its
  // dispatch per value.
  template <class T>
  char* store(T x, char* at) const {
    std::memcpy(at, &x, sizeof(T));
    if (enc_ == PlyEncoding::kBinaryBigEndian) std::reverse(at, at + sizeof(T));
    return at + sizeof(T);
  }

  // Appends the flattened `values` of `props`. Errors: as put(), and
  // kInternal when `values` does not match `props`.
  Status put_all(const std::vector<Property>& props, const PropertyValues& values, std::string* out) const {
    size_t at = 0;
    for (const Property& p : props) {
      if (at >= values.size()) return Status(ErrorCode::kInternal, "fewer property values than the schema has");
      if (p.is_list) {
        double count = values[at++];
        PSQ_RETURN_IF_ERROR(put(p.count_type, count, out));
        if (count < 0 || count > static_cast<double>(values.size() - at)) {
          return Status(ErrorCode::kInternal, "list count overruns the property values");
        }
        for (size_t k = 0; k < static_cast<size_t>(count); ++k) PSQ_RETURN_IF_ERROR(put(p.type, values[at++], out));
      } else {
        PSQ_RETURN_IF_ERROR(put(p.type, values[at++], out));
      }
    }
    if (at != values.size()) return Status(ErrorCode::kInternal, "more property values than the schema has");
    return Status();
  }

 private:
  PlyEncoding enc_;
};

}  // namespace

struct PlyWriter::Impl {
  OutputFile* out = nullptr;
  PlyWriteOptions options;
  MeshSchema schema;
  ScalarType index_type = ScalarType::kInt32;
  ValueEncoder enc{PlyEncoding::kBinaryLittleEndian};
  bool direct = false;       // header written at begin(), elements go straight out
  SpoolFile vertex_spool;    // used unless direct
  SpoolFile face_spool;      // used unless direct and every vertex came first
  bool vertex_spooled = false;
  bool face_spooled = false;
  uint64_t vertices = 0;
  uint64_t triangles = 0;
  std::string record;

  Status write_header(uint64_t nv, uint64_t nt);
  Status emit_vertex(const char* data, size_t n);
  Status emit_face(const char* data, size_t n);
};

PlyWriter::PlyWriter(OutputFile* out, PlyWriteOptions options) : impl_(std::make_unique<Impl>()) {
  impl_->out = out;
  impl_->options = std::move(options);
  impl_->enc = ValueEncoder(impl_->options.encoding);
}

PlyWriter::~PlyWriter() = default;

namespace {

// The header of a PLY file of `schema` with nv vertices and nt faces.
std::string ply_header(const MeshSchema& schema, PlyEncoding encoding, ScalarType index_type, uint64_t nv,
                       uint64_t nt) {
  std::string h = "ply\nformat ";
  switch (encoding) {
    case PlyEncoding::kAscii: h += "ascii"; break;
    case PlyEncoding::kBinaryLittleEndian: h += "binary_little_endian"; break;
    case PlyEncoding::kBinaryBigEndian: h += "binary_big_endian"; break;
  }
  h += " 1.0\n";
  for (const std::string& c : schema.comments) {
    // A comment cannot hold a line break; keep the text on one line.
    std::string line = c;
    for (char& ch : line) {
      if (ch == '\n' || ch == '\r') ch = ' ';
    }
    if (line.rfind("obj_info ", 0) == 0) {
      h += line + "\n";
    } else {
      h += "comment " + line + "\n";
    }
  }
  auto prop_line = [](const Property& p) {
    if (p.is_list) return "property list " + std::string(scalar_name(p.count_type)) + " " + scalar_name(p.type) + " " + p.name + "\n";
    return "property " + std::string(scalar_name(p.type)) + " " + p.name + "\n";
  };
  h += "element vertex " + std::to_string(nv) + "\n";
  const char* pt = scalar_name(schema.position_type);
  h += std::string("property ") + pt + " x\nproperty " + pt + " y\nproperty " + pt + " z\n";
  for (const Property& p : schema.vertex_properties) h += prop_line(p);
  h += "element face " + std::to_string(nt) + "\n";
  h += std::string("property list uchar ") + scalar_name(index_type) + " vertex_indices\n";
  for (const Property& p : schema.face_properties) h += prop_line(p);
  h += "end_header\n";
  return h;
}

}  // namespace

Status PlyWriter::Impl::write_header(uint64_t nv, uint64_t nt) {
  return out->write(ply_header(schema, options.encoding, index_type, nv, nt));
}

Status PlyWriter::begin(const MeshSchema& schema) {
  Impl& m = *impl_;
  m.schema = schema;
  if (m.schema.position_type != ScalarType::kFloat64) m.schema.position_type = ScalarType::kFloat32;
  for (const Property& p : schema.vertex_properties) {
    if (p.name == "x" || p.name == "y" || p.name == "z") {
      return Status(ErrorCode::kUsage, "vertex property named '" + p.name + "' clashes with the position");
    }
  }
  // int indices unless there are more vertices than int can index.
  if (schema.vertex_count > 0x7fffffff) m.index_type = ScalarType::kUInt32;
  m.direct = schema.vertex_count != MeshSchema::kUnknown && schema.triangle_count != MeshSchema::kUnknown;
  if (m.direct) {
    return m.write_header(static_cast<uint64_t>(schema.vertex_count), static_cast<uint64_t>(schema.triangle_count));
  }
  if (schema.vertex_count == MeshSchema::kUnknown) m.index_type = ScalarType::kUInt32;
  PSQ_RETURN_IF_ERROR(m.vertex_spool.create(m.options.spool_dir));
  m.vertex_spooled = true;
  return Status();
}

Status PlyWriter::Impl::emit_vertex(const char* data, size_t n) {
  ++vertices;
  return direct ? out->write(data, n) : vertex_spool.write(data, n);
}

Status PlyWriter::Impl::emit_face(const char* data, size_t n) {
  ++triangles;
  bool vertices_done = direct && vertices == static_cast<uint64_t>(schema.vertex_count);
  if (vertices_done && !face_spooled) return out->write(data, n);
  if (!face_spooled) {
    PSQ_RETURN_IF_ERROR(face_spool.create(options.spool_dir));
    face_spooled = true;
  }
  return face_spool.write(data, n);
}

Status PlyWriter::vertex(const double p[3], const PropertyValues& values) {
  Impl& m = *impl_;
  m.record.clear();
  if (m.options.encoding != PlyEncoding::kAscii) {
    // Float types need no check (put()): the position without put()'s
    // dispatch per value, in one append.
    char b[24];
    char* e = b;
    for (int k = 0; k < 3; ++k)
      if (!fits(m.schema.position_type, p[k]))
        return Status(ErrorCode::kBadValue, "vertex " + std::to_string(m.vertices) + ": position " +
                                                number_text(p[k]) + " does not fit PLY type float");
    for (int k = 0; k < 3; ++k)
      e = m.schema.position_type == ScalarType::kFloat32 ? m.enc.store(static_cast<float>(p[k]), e)
                                                         : m.enc.store(p[k], e);
    // Without properties the record is complete: out from where it was built.
    if (values.empty() && m.schema.vertex_properties.empty()) return m.emit_vertex(b, static_cast<size_t>(e - b));
    m.record.append(b, e);
  } else {
    for (int k = 0; k < 3; ++k) PSQ_RETURN_IF_ERROR(m.enc.put(m.schema.position_type, p[k], &m.record));
  }
  PSQ_RETURN_IF_ERROR(m.enc.put_all(m.schema.vertex_properties, values, &m.record));
  if (m.options.encoding == PlyEncoding::kAscii) m.record.push_back('\n');
  return m.emit_vertex(m.record.data(), m.record.size());
}

Status PlyWriter::triangle(const uint32_t idx[3], const PropertyValues& values) {
  Impl& m = *impl_;
  m.record.clear();
  const uint32_t index_max = m.index_type == ScalarType::kInt32 ? 0x7fffffffu : 0xffffffffu;
  if (m.options.encoding != PlyEncoding::kAscii && idx[0] <= index_max && idx[1] <= index_max &&
      idx[2] <= index_max) {
    // The count and the indices fit their types: put() without its checks
    // and conversions per value, which would be most of a binary writer's work.
    // (An index up to index_max has the same bytes as int32 and uint32.)
    char b[13];
    char* e = m.enc.store(uint8_t{3}, b);
    for (int k = 0; k < 3; ++k) e = m.enc.store(idx[k], e);
    if (values.empty() && m.schema.face_properties.empty()) return m.emit_face(b, static_cast<size_t>(e - b));
    m.record.append(b, e);
  } else {
    PSQ_RETURN_IF_ERROR(m.enc.put(ScalarType::kUInt8, 3, &m.record));
    for (int k = 0; k < 3; ++k) PSQ_RETURN_IF_ERROR(m.enc.put(m.index_type, idx[k], &m.record));
  }
  PSQ_RETURN_IF_ERROR(m.enc.put_all(m.schema.face_properties, values, &m.record));
  if (m.options.encoding == PlyEncoding::kAscii) m.record.push_back('\n');
  return m.emit_face(m.record.data(), m.record.size());
}

namespace {

Status copy_spool(SpoolFile& spool, OutputFile* out) {
  PSQ_RETURN_IF_ERROR(spool.rewind());
  InputStream& in = spool.stream();
  for (;;) {
    size_t avail;
    PSQ_RETURN_IF_ERROR(in.fill(1 << 16, &avail));
    if (avail == 0) return Status();
    PSQ_RETURN_IF_ERROR(out->write(in.cursor(), avail));
    in.advance(avail);
  }
}

}  // namespace

Status PlyWriter::finish() {
  Impl& m = *impl_;
  if (m.direct) {
    if (m.vertices != static_cast<uint64_t>(m.schema.vertex_count) ||
        m.triangles != static_cast<uint64_t>(m.schema.triangle_count)) {
      return Status(ErrorCode::kInternal, "the source yielded " + std::to_string(m.vertices) + " vertices and " +
                                              std::to_string(m.triangles) + " triangles, not the counts it promised");
    }
  } else {
    PSQ_RETURN_IF_ERROR(m.write_header(m.vertices, m.triangles));
    PSQ_RETURN_IF_ERROR(copy_spool(m.vertex_spool, m.out));
  }
  if (m.face_spooled) PSQ_RETURN_IF_ERROR(copy_spool(m.face_spool, m.out));
  return Status();
}

}  // namespace psq

namespace psq {

namespace {

// Gives the whole pages inside [p, p + n) back to the system: memory that
// was written out and will not be read again.
void release_pages(const void* p, size_t n) {
  static const uintptr_t page = static_cast<uintptr_t>(::sysconf(_SC_PAGESIZE));
  const uintptr_t begin = (reinterpret_cast<uintptr_t>(p) + page - 1) & ~(page - 1);
  const uintptr_t end = (reinterpret_cast<uintptr_t>(p) + n) & ~(page - 1);
  if (end > begin) ::madvise(reinterpret_cast<void*>(begin), end - begin, MADV_DONTNEED);
}

}  // namespace

Status write_ply_by_segments(const std::string& path, OutputFile* out, int threads, uint64_t* vertices,
                             uint64_t* triangles) {
  auto cannot = [](const char* why) { return Status(ErrorCode::kUnsupported, why); };
  if (!out->seekable()) return cannot("the output cannot be written at offsets");
  uint32_t probe = 1;
  uint8_t first_byte;
  std::memcpy(&first_byte, &probe, 1);
  if (first_byte != 1) return cannot("a big-endian machine");
  MeshSchema schema;
  {
    InputStream in;
    PSQ_RETURN_IF_ERROR(in.open(path));
    PsqDecoder d;
    PSQ_RETURN_IF_ERROR(d.open(&in));
    schema = d.schema();
  }
  // The records of the arrays are the file's: float positions, and faces
  // of three indices with nothing else.
  if (schema.position_type != ScalarType::kFloat32 || !schema.vertex_properties.empty() ||
      !schema.face_properties.empty())
    return cannot("positions that are not float, or properties");
  auto open = [&](InputStream* in) { return in->open(path); };
  // The header once the counts are known: at the first flush, every
  // thread waits for it (the flushes of other segments come after).
  std::mutex mu;
  uint64_t header = 0, nv = 0;
  bool sized = false;
  MeshBuffers mesh;
  auto size_output = [&]() -> Status {
    std::lock_guard<std::mutex> lock(mu);
    if (sized) return Status();
    nv = mesh.positions.size() / 3;
    const uint64_t nt = mesh.indices.size() / 3;
    // The index type of PlyWriter when the counts come after the
    // elements (uint), so that the bytes are those of one thread.
    const std::string h = ply_header(schema, PlyEncoding::kBinaryLittleEndian, ScalarType::kUInt32, nv, nt);
    PSQ_RETURN_IF_ERROR(out->write(h));
    header = h.size();
    PSQ_RETURN_IF_ERROR(out->resize(header + 12 * nv + 13 * nt));
    sized = true;
    return Status();
  };
  auto flush = [&](size_t p0, size_t p1, size_t i0, size_t i1) -> Status {
    PSQ_RETURN_IF_ERROR(size_output());
    if (p1 > p0) PSQ_RETURN_IF_ERROR(out->write_at(header + 4 * p0, mesh.positions.data() + p0, 4 * (p1 - p0)));
    // Faces in pieces of 2^15 (416 KiB), through one buffer per thread.
    constexpr size_t kPiece = size_t{1} << 15;
    thread_local std::vector<char> faces;
    faces.resize(13 * kPiece);
    for (size_t i = i0; i < i1;) {
      const size_t n = std::min(kPiece, (i1 - i) / 3);
      for (size_t k = 0; k < n; ++k) {
        char* b = faces.data() + 13 * k;
        b[0] = 3;
        std::memcpy(b + 1, mesh.indices.data() + i + 3 * k, 12);
      }
      PSQ_RETURN_IF_ERROR(out->write_at(header + 12 * nv + 13 * (i / 3), faces.data(), 13 * n));
      i += 3 * n;
    }
    // What is written leaves memory: the arrays hold only what the
    // segments decode between two flushes.
    release_pages(mesh.positions.data() + p0, 4 * (p1 - p0));
    release_pages(mesh.indices.data() + i0, 4 * (i1 - i0));
    return Status();
  };
  Status s = decode_mesh_segments(open, threads, &mesh, flush);
  if (s.ok()) s = size_output();  // an empty mesh flushes nothing
  if (!s.ok()) {
    if (s.code() == ErrorCode::kUnsupported) PSQ_RETURN_IF_ERROR(out->restart());
    return s;
  }
  *vertices = mesh.positions.size() / 3;
  *triangles = mesh.indices.size() / 3;
  return Status();
}

}  // namespace psq
