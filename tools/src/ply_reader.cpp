// Streaming PLY reader (psq/ply.h): header parsing, ascii and binary element
// decoding, polygon fans and triangle strips, one element in memory at a time.
//
// PLY is Greg Turk's format (1994); the header grammar and the type names
// follow the description shipped with the original ply library.
#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstring>
#include <string>
#include <string_view>
#include <vector>

#include "psq/ply.h"

namespace psq {
namespace {

constexpr size_t kMaxHeader = size_t{1} << 20;
// The most corners of one face (or values of one list) psq reads; a longer
// list is rejected so that a corrupt count cannot grow memory without bound.
constexpr uint64_t kMaxList = uint64_t{1} << 20;
constexpr uint64_t kMaxVertices = 0xffffffffu;  // indices are 32-bit

bool parse_type(std::string_view s, ScalarType* t) {
  static const struct {
    const char* name;
    ScalarType type;
  } kNames[] = {
      {"char", ScalarType::kInt8},      {"int8", ScalarType::kInt8},
      {"uchar", ScalarType::kUInt8},    {"uint8", ScalarType::kUInt8},
      {"short", ScalarType::kInt16},    {"int16", ScalarType::kInt16},
      {"ushort", ScalarType::kUInt16},  {"uint16", ScalarType::kUInt16},
      {"int", ScalarType::kInt32},      {"int32", ScalarType::kInt32},
      {"uint", ScalarType::kUInt32},    {"uint32", ScalarType::kUInt32},
      {"float", ScalarType::kFloat32},  {"float32", ScalarType::kFloat32},
      {"double", ScalarType::kFloat64}, {"float64", ScalarType::kFloat64},
  };
  for (const auto& n : kNames) {
    if (s == n.name) {
      *t = n.type;
      return true;
    }
  }
  return false;
}

// Splits `line` at blanks (space, tab, and any other control character).
void split(std::string_view line, std::vector<std::string_view>* out) {
  out->clear();
  size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && static_cast<unsigned char>(line[i]) <= ' ') ++i;
    size_t j = i;
    while (j < line.size() && static_cast<unsigned char>(line[j]) > ' ') ++j;
    if (j > i) out->push_back(line.substr(i, j - i));
    i = j;
  }
}

enum class Role { kKeep, kX, kY, kZ, kIndices, kSkip };

struct PlyProperty {
  Property prop;
  Role role = Role::kKeep;
};

enum class ElementKind { kVertex, kFace, kStrips, kOther };

struct PlyElement {
  std::string name;
  uint64_t count = 0;
  ElementKind kind = ElementKind::kOther;
  std::vector<PlyProperty> props;
  uint64_t header_line = 0;
};

template <typename T>
T load(const uint8_t* p, bool swap) {
  uint8_t b[sizeof(T)];
  std::memcpy(b, p, sizeof(T));
  if (swap) std::reverse(b, b + sizeof(T));
  T v;
  std::memcpy(&v, b, sizeof(T));
  return v;
}

double decode(ScalarType t, const uint8_t* p, bool swap) {
  switch (t) {
    case ScalarType::kInt8: return static_cast<int8_t>(p[0]);
    case ScalarType::kUInt8: return p[0];
    case ScalarType::kInt16: return load<int16_t>(p, swap);
    case ScalarType::kUInt16: return load<uint16_t>(p, swap);
    case ScalarType::kInt32: return load<int32_t>(p, swap);
    case ScalarType::kUInt32: return load<uint32_t>(p, swap);
    case ScalarType::kFloat32: return load<float>(p, swap);
    case ScalarType::kFloat64: return load<double>(p, swap);
  }
  return 0;
}

}  // namespace

bool looks_like_ply(const uint8_t* data, size_t size) {
  return size >= 4 && std::memcmp(data, "ply", 3) == 0 && (data[3] == '\n' || data[3] == '\r');
}

struct PlyReader::Impl {
  InputStream* in = nullptr;
  PlyEncoding encoding = PlyEncoding::kAscii;
  bool swap = false;
  MeshSchema schema;
  SourceReport report;
  std::vector<PlyElement> elements;
  Status error;
  uint64_t line = 0;  // lines consumed so far (ascii)

  // Position in the data: element `elem`, item `item` of it.
  size_t elem = 0;
  uint64_t item = 0;
  uint64_t vertex_count = 0;

  // The face being yielded as triangles (fan or strip).
  std::vector<uint32_t> corners;
  PropertyValues face_values;
  size_t corner_at = 0;     // next triangle's position in `corners`
  bool strip = false;
  size_t strip_start = 0;   // position in `corners` where the strip began

  std::vector<std::string_view> tokens;
  std::vector<uint64_t> raw_indices;  // for checking before accepting

  Status fail(Status s) {
    error = s;
    return s;
  }

  Status read_header();
  Status parse_header_line(std::string_view line, uint64_t lineno, bool* done);
  Status next(MeshItem* item);
  Status read_element_binary(const PlyElement& e, MeshItem* item, bool* yields);
  Status read_element_ascii(const PlyElement& e, MeshItem* item, bool* yields);
  Status accept_face(const PlyElement& e, uint64_t place_offset, uint64_t place_line);
  bool emit_triangle(MeshItem* item);
};

Status PlyReader::Impl::read_header() {
  // Header lines are read byte-wise: the line end style of the first line
  // ("ply\n", "ply\r\n" or "ply\r") decides how end_header's line ends, so
  // that binary data starting with 0x0a after a CR-only header is not eaten.
  std::string text;
  std::string eol;
  uint64_t lineno = 0;
  uint64_t header_bytes = 0;
  bool done = false;
  while (!done) {
    text.clear();
    for (;;) {
      size_t avail;
      PSQ_RETURN_IF_ERROR(in->fill(2, &avail));
      if (avail == 0) {
        return Status(ErrorCode::kBadHeader, "header ends without end_header", in->offset(), lineno + 1);
      }
      uint8_t c = *in->cursor();
      if (c == '\n' || c == '\r') {
        std::string this_eol(1, static_cast<char>(c));
        if (c == '\r' && avail >= 2 && in->cursor()[1] == '\n') this_eol = "\r\n";
        if (eol.empty()) eol = this_eol;
        // After end_header consume exactly the style of the first line.
        bool is_end = text.find("end_header") != std::string::npos;
        size_t take = this_eol.size();
        if (is_end && eol.size() < take) take = eol.size();
        in->advance(take);
        header_bytes += take;
        break;
      }
      text.push_back(static_cast<char>(c));
      in->advance(1);
      if (++header_bytes > kMaxHeader) {
        return Status(ErrorCode::kLimit, "header longer than 1 MiB (no end_header?)", in->offset());
      }
    }
    ++lineno;
    if (lineno == 1) {
      std::vector<std::string_view> t;
      split(text, &t);
      if (t.size() != 1 || t[0] != "ply") return Status(ErrorCode::kBadHeader, "not a PLY file (no 'ply' magic)", 0, 1);
      continue;
    }
    PSQ_RETURN_IF_ERROR(parse_header_line(text, lineno, &done));
  }
  this->line = lineno;
  return Status();
}

Status PlyReader::Impl::parse_header_line(std::string_view text, uint64_t lineno, bool* done) {
  auto bad = [lineno](const std::string& m) { return Status(ErrorCode::kBadHeader, m, Status::kNoPlace, lineno); };
  std::vector<std::string_view> t;
  split(text, &t);
  if (t.empty()) return Status();  // blank lines are tolerated
  if (t[0] == "comment" || t[0] == "obj_info") {
    size_t at = text.find(t[0]) + t[0].size();
    std::string_view rest = text.substr(at);
    while (!rest.empty() && static_cast<unsigned char>(rest.front()) <= ' ') rest.remove_prefix(1);
    while (!rest.empty() && static_cast<unsigned char>(rest.back()) <= ' ') rest.remove_suffix(1);
    std::string c = t[0] == "obj_info" ? "obj_info " : "";
    schema.comments.push_back(c + std::string(rest));
    return Status();
  }
  if (t[0] == "format") {
    if (t.size() != 3) return bad("malformed format line");
    if (t[1] == "ascii") {
      encoding = PlyEncoding::kAscii;
    } else if (t[1] == "binary_little_endian") {
      encoding = PlyEncoding::kBinaryLittleEndian;
    } else if (t[1] == "binary_big_endian") {
      encoding = PlyEncoding::kBinaryBigEndian;
    } else {
      return bad("unknown PLY format '" + std::string(t[1]) + "'");
    }
    if (t[2] != "1.0" && t[2] != "1") return bad("unsupported PLY version '" + std::string(t[2]) + "'");
    swap = encoding == PlyEncoding::kBinaryBigEndian;
    return Status();
  }
  if (t[0] == "element") {
    if (t.size() != 3) return bad("malformed element line");
    PlyElement e;
    e.name = std::string(t[1]);
    e.header_line = lineno;
    auto r = std::from_chars(t[2].data(), t[2].data() + t[2].size(), e.count);
    if (r.ec != std::errc() || r.ptr != t[2].data() + t[2].size()) {
      return bad("element count '" + std::string(t[2]) + "' is not a non-negative integer");
    }
    if (e.name == "vertex") {
      e.kind = ElementKind::kVertex;
    } else if (e.name == "face") {
      e.kind = ElementKind::kFace;
    } else if (e.name == "tristrips") {
      e.kind = ElementKind::kStrips;
    }
    for (const PlyElement& o : elements) {
      if (o.name == e.name && e.kind != ElementKind::kOther) return bad("element '" + e.name + "' declared twice");
    }
    elements.push_back(std::move(e));
    return Status();
  }
  if (t[0] == "property") {
    if (elements.empty()) return bad("property before any element");
    PlyElement& e = elements.back();
    PlyProperty p;
    if (t.size() == 5 && t[1] == "list") {
      p.prop.is_list = true;
      if (!parse_type(t[2], &p.prop.count_type) || !parse_type(t[3], &p.prop.type)) {
        return bad("unknown type in list property '" + std::string(t[4]) + "'");
      }
      if (scalar_is_float(p.prop.count_type)) return bad("list count of '" + std::string(t[4]) + "' has a float type");
      p.prop.name = std::string(t[4]);
    } else if (t.size() == 3) {
      if (!parse_type(t[1], &p.prop.type)) return bad("unknown property type '" + std::string(t[1]) + "'");
      p.prop.name = std::string(t[2]);
    } else {
      return bad("malformed property line");
    }
    for (const PlyProperty& o : e.props) {
      if (o.prop.name == p.prop.name) return bad("property '" + p.prop.name + "' declared twice in element '" + e.name + "'");
    }
    e.props.push_back(std::move(p));
    return Status();
  }
  if (t[0] == "end_header") {
    if (t.size() != 1) return bad("malformed end_header line");
    *done = true;
    return Status();
  }
  return bad("unknown header keyword '" + std::string(t[0]) + "'");
}

Status PlyReader::open(InputStream* in) {
  impl_ = std::make_unique<Impl>();
  Impl& m = *impl_;
  m.in = in;
  Status s = m.read_header();
  if (!s.ok()) return m.fail(s);

  // Give each property its role and build the schema.
  const PlyElement* vertex = nullptr;
  const PlyElement* face_like = nullptr;
  for (PlyElement& e : m.elements) {
    auto bad = [&e](const std::string& msg) {
      return Status(ErrorCode::kBadHeader, msg, Status::kNoPlace, e.header_line);
    };
    if (e.kind == ElementKind::kVertex) {
      vertex = &e;
      int found = 0;
      bool wide = false;
      for (PlyProperty& p : e.props) {
        if (p.prop.name == "x" || p.prop.name == "y" || p.prop.name == "z") {
          if (p.prop.is_list) return m.fail(bad("vertex property '" + p.prop.name + "' is a list"));
          p.role = p.prop.name == "x" ? Role::kX : p.prop.name == "y" ? Role::kY : Role::kZ;
          ++found;
          if (p.prop.type == ScalarType::kFloat64 || p.prop.type == ScalarType::kInt32 ||
              p.prop.type == ScalarType::kUInt32) {
            wide = true;
          }
        } else {
          m.schema.vertex_properties.push_back(p.prop);
        }
      }
      if (found != 3) return m.fail(bad("vertex element lacks an x, y or z property"));
      m.schema.position_type = wide ? ScalarType::kFloat64 : ScalarType::kFloat32;
      if (e.count > kMaxVertices) return m.fail(Status(ErrorCode::kLimit, "more than 4294967295 vertices", Status::kNoPlace, e.header_line));
      m.vertex_count = e.count;
      m.schema.vertex_count = static_cast<int64_t>(e.count);
    } else if (e.kind == ElementKind::kFace || e.kind == ElementKind::kStrips) {
      std::vector<Property> face_props;
      int lists = 0;
      for (PlyProperty& p : e.props) {
        if (p.prop.name == "vertex_indices" || p.prop.name == "vertex_index") {
          if (!p.prop.is_list) return m.fail(bad("'" + p.prop.name + "' is not a list"));
          if (scalar_is_float(p.prop.type)) return m.fail(bad("'" + p.prop.name + "' has a float type"));
          p.role = Role::kIndices;
          ++lists;
        } else {
          face_props.push_back(p.prop);
        }
      }
      if (lists != 1) return m.fail(bad("element '" + e.name + "' lacks a vertex_indices list"));
      if (face_like != nullptr && face_props != m.schema.face_properties) {
        return m.fail(Status(ErrorCode::kUnsupported, "'face' and 'tristrips' elements with different properties",
                             Status::kNoPlace, e.header_line));
      }
      face_like = &e;
      m.schema.face_properties = std::move(face_props);
    } else {
      for (PlyProperty& p : e.props) p.role = Role::kSkip;
      ++m.report.skipped_elements;
      m.report.notes.push_back("element '" + e.name + "' (" + std::to_string(e.count) + " items) skipped");
    }
  }
  if (vertex == nullptr) return m.fail(Status(ErrorCode::kBadHeader, "no vertex element", Status::kNoPlace, m.line));
  // A file with only triangles of a face element reports its triangle count
  // once read; up front it is unknown (faces may be polygons).
  if (face_like == nullptr) m.schema.triangle_count = 0;

  // A header's counts must fit in the bytes that follow: a value takes at
  // least its size in binary, and a digit and a separator in ascii. This
  // rejects absurd counts before anything is read.
  if (in->size() >= 0) {
    uint64_t avail = static_cast<uint64_t>(in->size()) - in->offset() + 1;  // +1: no final newline
    uint64_t need = 0;
    for (const PlyElement& e : m.elements) {
      uint64_t per = 0;
      for (const PlyProperty& p : e.props) {
        per += m.encoding == PlyEncoding::kAscii
                   ? 2
                   : static_cast<uint64_t>(scalar_size(p.prop.is_list ? p.prop.count_type : p.prop.type));
      }
      if (per == 0) continue;
      if (e.count > (avail - need) / per) {
        return m.fail(Status(ErrorCode::kTruncated,
                             "header declares " + std::to_string(e.count) + " '" + e.name + "' elements but only " +
                                 std::to_string(avail - 1) + " bytes of data follow",
                             in->offset()));
      }
      need += e.count * per;
    }
  }
  return Status();
}

PlyEncoding PlyReader::encoding() const { return impl_->encoding; }
const MeshSchema& PlyReader::schema() const { return impl_->schema; }
const SourceReport& PlyReader::report() const { return impl_->report; }
PlyReader::PlyReader() = default;
PlyReader::~PlyReader() = default;

Status PlyReader::next(MeshItem* item) {
  if (!impl_) return Status(ErrorCode::kUsage, "PlyReader::next before open");
  if (!impl_->error.ok()) return impl_->error;
  Status s = impl_->next(item);
  if (!s.ok()) impl_->error = s;
  return s;
}

// Yields the next triangle of the current face or strip; false when done.
bool PlyReader::Impl::emit_triangle(MeshItem* out) {
  constexpr uint32_t kRestart = 0xffffffffu;
  for (;;) {
    uint32_t a, b, c;
    if (strip) {
      // Triangle i of a strip is (v[i], v[i+1], v[i+2]), every other one
      // flipped to keep the orientation; -1 restarts a new strip.
      if (corner_at + 2 >= corners.size()) return false;
      size_t i = corner_at++;
      if (corners[i] == kRestart) {
        strip_start = i + 1;
        continue;
      }
      a = corners[i];
      b = corners[i + 1];
      c = corners[i + 2];
      if (b == kRestart || c == kRestart) continue;
      if ((i - strip_start) % 2 == 1) std::swap(a, b);
      // Repeated indices stitch strips together; they are not faces.
      if (a == b || b == c || c == a) continue;
      ++report.strip_triangles;
    } else {
      // A fan around the first corner.
      if (corner_at + 1 >= corners.size()) return false;
      a = corners[0];
      b = corners[corner_at];
      c = corners[corner_at + 1];
      ++corner_at;
    }
    out->kind = MeshItem::Kind::kTriangle;
    out->index[0] = a;
    out->index[1] = b;
    out->index[2] = c;
    out->values = face_values;
    return true;
  }
}

Status PlyReader::Impl::accept_face(const PlyElement& e, uint64_t off, uint64_t ln) {
  auto place = [&](ErrorCode code, const std::string& msg) {
    return Status(code, e.name + " " + std::to_string(item) + ": " + msg, ln == Status::kNoPlace ? off : Status::kNoPlace, ln);
  };
  corners.clear();
  for (uint64_t r : raw_indices) {
    int64_t v = static_cast<int64_t>(r);
    if (e.kind == ElementKind::kStrips && v == -1) {
      corners.push_back(0xffffffffu);
      continue;
    }
    if (v < 0) return place(ErrorCode::kBadIndex, "negative vertex index " + std::to_string(v));
    if (static_cast<uint64_t>(v) >= vertex_count) {
      return place(ErrorCode::kBadIndex, "vertex index " + std::to_string(v) + " out of range (" +
                                             std::to_string(vertex_count) + " vertices)");
    }
    corners.push_back(static_cast<uint32_t>(v));
  }
  if (e.kind == ElementKind::kFace && corners.size() < 3) {
    return place(ErrorCode::kBadValue, "face has " + std::to_string(corners.size()) + " corners; a face needs at least 3");
  }
  strip = e.kind == ElementKind::kStrips;
  strip_start = 0;
  corner_at = strip ? 0 : 1;
  if (!strip && corners.size() > 3) ++report.polygons_triangulated;
  return Status();
}

Status PlyReader::Impl::read_element_binary(const PlyElement& e, MeshItem* out, bool* yields) {
  const uint64_t start = in->offset();
  auto truncated = [&]() {
    return Status(ErrorCode::kTruncated,
                  "data ends inside " + e.name + " " + std::to_string(item) + " of " + std::to_string(e.count),
                  in->offset());
  };
  PropertyValues& values = e.kind == ElementKind::kVertex ? out->values : face_values;
  values.clear();
  raw_indices.clear();
  for (const PlyProperty& p : e.props) {
    size_t avail;
    if (!p.prop.is_list) {
      int sz = scalar_size(p.prop.type);
      PSQ_RETURN_IF_ERROR(in->fill(sz, &avail));
      if (avail < static_cast<size_t>(sz)) return truncated();
      double v = decode(p.prop.type, in->cursor(), swap);
      in->advance(sz);
      switch (p.role) {
        case Role::kX: out->position[0] = v; break;
        case Role::kY: out->position[1] = v; break;
        case Role::kZ: out->position[2] = v; break;
        case Role::kKeep: values.push_back(v); break;
        default: break;
      }
      continue;
    }
    int csz = scalar_size(p.prop.count_type);
    PSQ_RETURN_IF_ERROR(in->fill(csz, &avail));
    if (avail < static_cast<size_t>(csz)) return truncated();
    double count = decode(p.prop.count_type, in->cursor(), swap);
    uint64_t count_offset = in->offset();
    in->advance(csz);
    if (count < 0) {
      return Status(ErrorCode::kBadValue, e.name + " " + std::to_string(item) + ": negative list count", count_offset);
    }
    if (count > static_cast<double>(kMaxList)) {
      return Status(ErrorCode::kLimit, e.name + " " + std::to_string(item) + ": list of " +
                                           std::to_string(static_cast<uint64_t>(count)) + " values (limit 1048576)",
                    count_offset);
    }
    uint64_t n = static_cast<uint64_t>(count);
    int sz = scalar_size(p.prop.type);
    if (p.role == Role::kKeep) values.push_back(count);
    for (uint64_t k = 0; k < n; ++k) {
      PSQ_RETURN_IF_ERROR(in->fill(sz, &avail));
      if (avail < static_cast<size_t>(sz)) return truncated();
      double v = decode(p.prop.type, in->cursor(), swap);
      in->advance(sz);
      if (p.role == Role::kKeep) {
        values.push_back(v);
      } else if (p.role == Role::kIndices) {
        raw_indices.push_back(static_cast<uint64_t>(static_cast<int64_t>(v)));
      }
    }
  }
  if (e.kind == ElementKind::kVertex) {
    for (int k = 0; k < 3; ++k) {
      if (!std::isfinite(out->position[k])) {
        return Status(ErrorCode::kBadValue, "vertex " + std::to_string(item) + ": position is not finite", start);
      }
    }
    out->kind = MeshItem::Kind::kVertex;
    *yields = true;
  } else if (e.kind != ElementKind::kOther) {
    PSQ_RETURN_IF_ERROR(accept_face(e, start, Status::kNoPlace));
    *yields = false;
  }
  return Status();
}

namespace {

// Parses one ascii token as a value of type `t`; false when malformed or out
// of the type's range.
bool parse_ascii(std::string_view tok, ScalarType t, double* out) {
  const char* b = tok.data();
  const char* e = b + tok.size();
  if (b != e && *b == '+') ++b;
  if (scalar_is_float(t)) {
    if (t == ScalarType::kFloat32) {
      float f;
      auto r = std::from_chars(b, e, f);
      if (r.ec != std::errc() || r.ptr != e) return false;
      *out = f;
    } else {
      double d;
      auto r = std::from_chars(b, e, d);
      if (r.ec != std::errc() || r.ptr != e) return false;
      *out = d;
    }
    return true;
  }
  int64_t v;
  auto r = std::from_chars(b, e, v);
  if (r.ec != std::errc() || r.ptr != e) return false;
  *out = static_cast<double>(v);
  return scalar_holds(t, *out);
}

}  // namespace

Status PlyReader::Impl::read_element_ascii(const PlyElement& e, MeshItem* out, bool* yields) {
  std::string_view text;
  bool eof = false;
  do {
    PSQ_RETURN_IF_ERROR(in->read_line(&text, &eof));
    if (eof) {
      return Status(ErrorCode::kTruncated,
                    "file ends before " + e.name + " " + std::to_string(item) + " of " + std::to_string(e.count),
                    Status::kNoPlace, line + 1);
    }
    ++line;
    split(text, &tokens);
  } while (tokens.empty());
  auto bad = [&](ErrorCode code, const std::string& m) {
    return Status(code, e.name + " " + std::to_string(item) + ": " + m, Status::kNoPlace, line);
  };
  PropertyValues& values = e.kind == ElementKind::kVertex ? out->values : face_values;
  values.clear();
  raw_indices.clear();
  size_t at = 0;
  auto take = [&](ScalarType t, const std::string& what, double* v) -> Status {
    if (at >= tokens.size()) return bad(ErrorCode::kBadValue, "line ends before " + what);
    if (!parse_ascii(tokens[at], t, v)) {
      return bad(ErrorCode::kBadValue, "'" + std::string(tokens[at]) + "' is not a valid " + scalar_name(t) + " for " + what);
    }
    ++at;
    return Status();
  };
  for (const PlyProperty& p : e.props) {
    double v;
    if (!p.prop.is_list) {
      PSQ_RETURN_IF_ERROR(take(p.prop.type, p.prop.name, &v));
      switch (p.role) {
        case Role::kX: out->position[0] = v; break;
        case Role::kY: out->position[1] = v; break;
        case Role::kZ: out->position[2] = v; break;
        case Role::kKeep: values.push_back(v); break;
        default: break;
      }
      continue;
    }
    double count;
    PSQ_RETURN_IF_ERROR(take(p.prop.count_type, "the count of " + p.prop.name, &count));
    if (count < 0) return bad(ErrorCode::kBadValue, "negative list count");
    if (count > static_cast<double>(tokens.size() - at)) {
      return bad(ErrorCode::kBadValue, "list count " + std::to_string(static_cast<int64_t>(count)) + " of " +
                                           p.prop.name + " overruns the line");
    }
    uint64_t n = static_cast<uint64_t>(count);
    if (p.role == Role::kKeep) values.push_back(count);
    for (uint64_t k = 0; k < n; ++k) {
      PSQ_RETURN_IF_ERROR(take(p.prop.type, p.prop.name, &v));
      if (p.role == Role::kKeep) {
        values.push_back(v);
      } else if (p.role == Role::kIndices) {
        raw_indices.push_back(static_cast<uint64_t>(static_cast<int64_t>(v)));
      }
    }
  }
  if (at != tokens.size()) {
    return bad(ErrorCode::kBadValue, std::to_string(tokens.size() - at) + " values more than the header declares");
  }
  if (e.kind == ElementKind::kVertex) {
    for (int k = 0; k < 3; ++k) {
      if (!std::isfinite(out->position[k])) return bad(ErrorCode::kBadValue, "position is not finite");
    }
    out->kind = MeshItem::Kind::kVertex;
    *yields = true;
  } else if (e.kind != ElementKind::kOther) {
    PSQ_RETURN_IF_ERROR(accept_face(e, Status::kNoPlace, line));
    *yields = false;
  }
  return Status();
}

Status PlyReader::Impl::next(MeshItem* out) {
  for (;;) {
    if (emit_triangle(out)) return Status();
    corners.clear();
    while (elem < elements.size() && item >= elements[elem].count) {
      ++elem;
      item = 0;
    }
    if (elem == elements.size()) {
      // Trailing bytes after the last element are tolerated only as
      // whitespace in ascii files; binary files must end exactly.
      bool end;
      if (encoding == PlyEncoding::kAscii) {
        std::string_view text;
        bool eof = false;
        for (;;) {
          PSQ_RETURN_IF_ERROR(in->read_line(&text, &eof));
          if (eof) break;
          ++line;
          split(text, &tokens);
          if (!tokens.empty()) {
            return Status(ErrorCode::kBadValue, "data after the last element the header declares", Status::kNoPlace, line);
          }
        }
      } else {
        PSQ_RETURN_IF_ERROR(in->at_end(&end));
        if (!end) return Status(ErrorCode::kBadValue, "data after the last element the header declares", in->offset());
      }
      out->kind = MeshItem::Kind::kEnd;
      out->values.clear();
      return Status();
    }
    const PlyElement& e = elements[elem];
    if (e.props.empty()) {
      // An element with no properties takes no bytes in binary (and an empty
      // line per item in ascii, which the next element's reading skips):
      // skip it whole instead of looping over a count the header may inflate.
      item = e.count;
      continue;
    }
    bool yields = false;
    if (encoding == PlyEncoding::kAscii) {
      PSQ_RETURN_IF_ERROR(read_element_ascii(e, out, &yields));
    } else {
      PSQ_RETURN_IF_ERROR(read_element_binary(e, out, &yields));
    }
    ++item;
    if (yields) return Status();
  }
}

}  // namespace psq
