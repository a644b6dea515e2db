// SPDX-License-Identifier: Apache-2.0
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
// Unknown header lines get a note each up to this many, then one in all.
constexpr uint64_t kMaxIgnoredNotes = 8;

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

// The two layouts that most binary files have, read without the loop over
// properties (read_element_binary): a vertex of float x, y, z alone, and a
// face of a uchar count and int or uint indices alone (a triangle; other
// counts take the loop).
enum class Layout { kAny, kXyzFloat, kFaceUCharInt, kFaceUCharUInt };

struct PlyElement {
  std::string name;
  uint64_t count = 0;
  ElementKind kind = ElementKind::kOther;
  std::vector<PlyProperty> props;
  uint64_t header_line = 0;
  Layout layout = Layout::kAny;  // binary, in the host's byte order
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
  bool format_seen = false;
  uint64_t ignored_lines = 0;  // unknown header lines read as comments
  // Appended to data errors when end_header's line end was ambiguous.
  std::string eol_note;

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
  Status parse_header_line(std::string_view text, const std::vector<std::string_view>& t, uint64_t lineno);
  Status unknown_header_line(std::string_view text, const std::vector<std::string_view>& t, uint64_t lineno);
  // The bytes of the data when no element has a list property.
  bool fixed_data_size(uint64_t* size) const;
  Status next(MeshItem* item);
  Status read_element_binary(const PlyElement& e, MeshItem* item, bool* yields);
  // A binary vertex read: its position must be finite.
  Status finish_vertex(uint64_t start, MeshItem* item, bool* yields);
  Status read_element_ascii(const PlyElement& e, MeshItem* item, bool* yields);
  Status accept_face(const PlyElement& e, uint64_t place_offset, uint64_t place_line);
  bool emit_triangle(MeshItem* item);
};

namespace {

// A byte that text never holds: a control character other than the blanks
// tab, vertical tab and form feed (CR and LF end lines). Such a byte in the
// header means that binary data began before any end_header.
bool is_binary_byte(uint8_t c) { return (c < 0x20 && c != '\t' && c != '\v' && c != '\f') || c == 0x7f; }

// The line for a note: control bytes as '?', at most 80 bytes.
std::string printable(std::string_view text) {
  std::string out;
  for (char c : text.substr(0, 80)) out.push_back(static_cast<unsigned char>(c) < 0x20 ? '?' : c);
  if (text.size() > 80) out += "...";
  return out;
}

}  // namespace

Status PlyReader::Impl::read_header() {
  // Header lines are read byte-wise, so that nothing after end_header's line
  // end is consumed. Each line ends in LF, CRLF or a lone CR; writers mix
  // them (some end every line in LF but end_header's in CRLF), so
  // each line's own end counts, end_header's above all: binary data starts
  // right after it. The one ambiguous case is "end_header\r\n" in a header
  // whose other lines end in a lone CR: a CR line end followed by data whose
  // first byte is 0x0a, or a CRLF. It is settled by the data's size when
  // every element has a fixed size, and otherwise read as a CR (the
  // header's own style) with a word about it in any later error.
  enum class End { kNone, kLf, kCr, kCrLf };
  const uint64_t start = in->offset();
  std::string text;
  std::vector<std::string_view> t;
  uint64_t lineno = 0;
  uint64_t ends_cr = 0;      // earlier lines ending in a lone CR
  uint64_t ends_other = 0;   // earlier lines ending in LF or CRLF
  for (;;) {
    text.clear();
    uint64_t binary_at = Status::kNoPlace;  // the line's first binary byte
    End end = End::kNone;
    for (;;) {
      if (in->offset() - start >= kMaxHeader) {
        return Status(ErrorCode::kLimit, "missing end_header in the first 1 MiB (a header may not be longer)",
                      in->offset(), lineno + 1);
      }
      size_t avail;
      PSQ_RETURN_IF_ERROR(in->fill(2, &avail));
      if (avail == 0) break;
      const uint8_t c = *in->cursor();
      if (c == '\n') {
        end = End::kLf;
        break;
      }
      if (c == '\r') {
        end = avail >= 2 && in->cursor()[1] == '\n' ? End::kCrLf : End::kCr;
        break;
      }
      if (is_binary_byte(c) && binary_at == Status::kNoPlace) binary_at = in->offset();
      text.push_back(static_cast<char>(c));
      in->advance(1);
    }
    ++lineno;
    split(text, &t);
    const bool is_end = t.size() == 1 && t[0] == "end_header";
    if (lineno == 1) {
      if (end == End::kNone && text.empty()) return Status(ErrorCode::kBadHeader, "not a PLY file (empty input)", 0, 1);
      if (t.size() != 1 || t[0] != "ply") return Status(ErrorCode::kBadHeader, "not a PLY file (no 'ply' magic)", 0, 1);
    } else if (binary_at != Status::kNoPlace && !is_end &&
               !(!t.empty() && (t[0] == "comment" || t[0] == "obj_info"))) {
      // Control bytes outside a comment: the data has begun, but no
      // end_header said where.
      return Status(ErrorCode::kBadHeader,
                    "missing end_header: header line " + std::to_string(lineno) + " holds binary data (byte " +
                        std::to_string(binary_at) + ") before any end_header",
                    binary_at, lineno);
    }
    if (end == End::kNone && !is_end) {
      return Status(ErrorCode::kBadHeader,
                    "missing end_header: the input ends in header line " + std::to_string(lineno) + " (byte " +
                        std::to_string(in->offset()) + ")",
                    in->offset(), lineno);
    }
    size_t take = end == End::kCrLf ? 2 : end == End::kNone ? 0 : 1;
    if (is_end && end == End::kCrLf && ends_cr > 0 && ends_other == 0 && encoding != PlyEncoding::kAscii) {
      take = 1;
      uint64_t fixed = 0;
      bool settled = false;
      if (in->size() >= 0 && fixed_data_size(&fixed)) {
        const uint64_t after_cr = static_cast<uint64_t>(in->size()) - (in->offset() + 1);
        if (after_cr == fixed + 1) take = 2;
        settled = after_cr == fixed || after_cr == fixed + 1;
      }
      if (!settled) {
        eol_note = "; end_header's line end was read as a lone CR like the header's other lines, taking the 0x0a "
                   "after it as data (if it was CRLF, the data starts one byte later)";
      }
    }
    in->advance(take);
    if (end == End::kCr) {
      ++ends_cr;
    } else if (end != End::kNone) {
      ++ends_other;
    }
    if (lineno == 1) continue;
    if (is_end) break;
    PSQ_RETURN_IF_ERROR(parse_header_line(text, t, lineno));
  }
  if (!format_seen) return Status(ErrorCode::kBadHeader, "no format line before end_header", Status::kNoPlace, lineno);
  if (ignored_lines > kMaxIgnoredNotes) {
    report.notes.push_back(std::to_string(ignored_lines - kMaxIgnoredNotes) +
                           " more header lines that are not PLY read as comments");
  }
  this->line = lineno;
  return Status();
}

bool PlyReader::Impl::fixed_data_size(uint64_t* size) const {
  uint64_t total = 0;
  for (const PlyElement& e : elements) {
    uint64_t per = 0;
    for (const PlyProperty& p : e.props) {
      if (p.prop.is_list) return false;
      per += static_cast<uint64_t>(scalar_size(p.prop.type));
    }
    if (per != 0 && e.count > (~uint64_t{0} - total) / per) return false;
    total += e.count * per;
  }
  *size = total;
  return true;
}

Status PlyReader::Impl::parse_header_line(std::string_view text, const std::vector<std::string_view>& t,
                                          uint64_t lineno) {
  auto bad = [lineno](const std::string& m) { return Status(ErrorCode::kBadHeader, m, Status::kNoPlace, lineno); };
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
    if (format_seen) return bad("a second format line");
    format_seen = true;
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
  if (t[0] == "end_header") return bad("malformed end_header line");
  return unknown_header_line(text, t, lineno);
}

// A header line with no PLY keyword. Several writers put bare text in the
// header (Blender 2.47: "Created by Blender3D 247 - www.blender.org, ..."),
// and widely used readers skip any line they do not know; psq reads such a
// line as a comment and says so in a note. It stays an error where skipping
// it could change how the data is read:
// - before the format line, which must come first (Turk's description; rply
//   refuses anything else there): until it, psq cannot tell a PLY file with
//   a stray line from another file that happens to start with "ply";
// - a structural keyword in the wrong case ("Element", "PROPERTY"), which a
//   writer meant as a declaration;
// - a line shaped like a declaration: a type name or "list" second (a
//   misspelled property: skipping it would shift every value after it) or,
//   like an element line, a name and a count ("elemnt face 12").
Status PlyReader::Impl::unknown_header_line(std::string_view text, const std::vector<std::string_view>& t,
                                            uint64_t lineno) {
  const std::string word(t[0]);
  auto bad = [&](const std::string& why) {
    return Status(ErrorCode::kBadHeader, "unknown header keyword '" + printable(word) + "' " + why, Status::kNoPlace,
                  lineno);
  };
  if (!format_seen) return bad("before the format line");
  std::string lower = word;
  for (char& c : lower) c = static_cast<char>(c >= 'A' && c <= 'Z' ? c - 'A' + 'a' : c);
  for (const char* k : {"ply", "format", "element", "property", "end_header", "comment", "obj_info"}) {
    if (lower == k) return bad("(PLY keywords are lower case)");
  }
  ScalarType type;
  if (t.size() >= 3 && (t[1] == "list" || parse_type(t[1], &type))) {
    return bad("in what looks like a property declaration (skipping it would misread the data)");
  }
  if (t.size() == 3 && !t[2].empty() && std::all_of(t[2].begin(), t[2].end(), [](char c) { return c >= '0' && c <= '9'; })) {
    return bad("in what looks like an element declaration (skipping it would misread the data)");
  }
  std::string_view rest = text;
  while (!rest.empty() && static_cast<unsigned char>(rest.front()) <= ' ') rest.remove_prefix(1);
  while (!rest.empty() && static_cast<unsigned char>(rest.back()) <= ' ') rest.remove_suffix(1);
  schema.comments.emplace_back(rest);
  if (++ignored_lines <= kMaxIgnoredNotes) {
    report.notes.push_back("header line " + std::to_string(lineno) + " is not PLY; read as a comment: '" +
                           printable(rest) + "'");
  }
  return Status();
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
  if (m.encoding != PlyEncoding::kAscii && !m.swap) {
    for (PlyElement& e : m.elements) {
      const std::vector<PlyProperty>& p = e.props;
      if (e.kind == ElementKind::kVertex && p.size() == 3 && p[0].role == Role::kX && p[1].role == Role::kY &&
          p[2].role == Role::kZ && p[0].prop.type == ScalarType::kFloat32 && p[1].prop.type == ScalarType::kFloat32 &&
          p[2].prop.type == ScalarType::kFloat32) {
        e.layout = Layout::kXyzFloat;
      } else if (e.kind == ElementKind::kFace && p.size() == 1 && p[0].role == Role::kIndices &&
                 p[0].prop.count_type == ScalarType::kUInt8) {
        if (p[0].prop.type == ScalarType::kInt32) e.layout = Layout::kFaceUCharInt;
        if (p[0].prop.type == ScalarType::kUInt32) e.layout = Layout::kFaceUCharUInt;
      }
    }
  }
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
  if (!s.ok()) {
    if (!impl_->eol_note.empty()) s = Status(s.code(), s.message() + impl_->eol_note, s.offset(), s.line());
    impl_->error = s;
  }
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
    if (face_values.empty()) {
      out->values.clear();
    } else {
      out->values = face_values;
    }
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
  // Makes the next n bytes readable at the cursor. Called only when fewer
  // are buffered: most values are, and the check inline costs less than
  // the call.
  auto fill = [&](size_t n) {
    size_t avail;
    PSQ_RETURN_IF_ERROR(in->fill(n, &avail));
    return avail < n ? truncated() : Status();
  };
  // The common layouts, when the whole record is buffered: the same values
  // and checks as the loop below.
  if (e.layout == Layout::kXyzFloat && in->buffered() >= 12) {
    float f[3];
    std::memcpy(f, in->cursor(), 12);
    in->advance(12);
    out->values.clear();
    for (int k = 0; k < 3; ++k) out->position[k] = f[k];
    return finish_vertex(start, out, yields);
  }
  if ((e.layout == Layout::kFaceUCharInt || e.layout == Layout::kFaceUCharUInt) && in->buffered() >= 13 &&
      in->cursor()[0] == 3) {
    const uint8_t* at = in->cursor() + 1;
    face_values.clear();
    raw_indices.resize(3);
    for (int k = 0; k < 3; ++k, at += 4) {
      raw_indices[k] = e.layout == Layout::kFaceUCharInt
                           ? static_cast<uint64_t>(static_cast<int64_t>(load<int32_t>(at, false)))
                           : static_cast<uint64_t>(load<uint32_t>(at, false));
    }
    in->advance(13);
    *yields = false;
    return accept_face(e, start, Status::kNoPlace);
  }
  PropertyValues& values = e.kind == ElementKind::kVertex ? out->values : face_values;
  values.clear();
  raw_indices.clear();
  for (const PlyProperty& p : e.props) {
    if (!p.prop.is_list) {
      int sz = scalar_size(p.prop.type);
      if (in->buffered() < static_cast<size_t>(sz)) PSQ_RETURN_IF_ERROR(fill(sz));
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
    if (in->buffered() < static_cast<size_t>(csz)) PSQ_RETURN_IF_ERROR(fill(csz));
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
    if (p.role == Role::kIndices && in->buffered() / sz >= n) {
      // A face's indices, all buffered (so that n is bounded by the data,
      // not only by the count): decoded in one go.
      const size_t base = raw_indices.size();
      raw_indices.resize(base + n);
      const uint8_t* at = in->cursor();
      for (uint64_t k = 0; k < n; ++k, at += sz)
        raw_indices[base + k] = static_cast<uint64_t>(static_cast<int64_t>(decode(p.prop.type, at, swap)));
      in->advance(n * sz);
      continue;
    }
    for (uint64_t k = 0; k < n; ++k) {
      if (in->buffered() < static_cast<size_t>(sz)) PSQ_RETURN_IF_ERROR(fill(sz));
      double v = decode(p.prop.type, in->cursor(), swap);
      in->advance(sz);
      if (p.role == Role::kKeep) {
        values.push_back(v);
      } else if (p.role == Role::kIndices) {
        raw_indices.push_back(static_cast<uint64_t>(static_cast<int64_t>(v)));
      }
    }
  }
  if (e.kind == ElementKind::kVertex) return finish_vertex(start, out, yields);
  if (e.kind != ElementKind::kOther) {
    PSQ_RETURN_IF_ERROR(accept_face(e, start, Status::kNoPlace));
    *yields = false;
  }
  return Status();
}

Status PlyReader::Impl::finish_vertex(uint64_t start, MeshItem* out, bool* yields) {
  for (int k = 0; k < 3; ++k) {
    if (!std::isfinite(out->position[k])) {
      return Status(ErrorCode::kBadValue, "vertex " + std::to_string(item) + ": position is not finite", start);
    }
  }
  out->kind = MeshItem::Kind::kVertex;
  *yields = true;
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
