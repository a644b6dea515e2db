// SPDX-License-Identifier: Apache-2.0
// ObjReader and looks_like_obj: reading Wavefront OBJ as an indexed mesh
// (see psq/obj.h for what is supported and how memory is used).

#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <string>
#include <string_view>
#include <system_error>
#include <utility>
#include <vector>

#include "psq/obj.h"
#include "text_parse.h"

namespace psq {
namespace {

using detail::Parse;
using detail::parse_float;
using detail::quoted;
using detail::parse_int;
using detail::skip_plus;

// Element counts stay below this so that uint32 indices hold every vertex,
// normal and texture coordinate, and the values above remain free as markers.
constexpr uint64_t kMaxCount = 0xFFFFFFF0u;
constexpr uint32_t kAbsent = 0xFFFFFFFFu;  // a corner without vt or vn
constexpr uint32_t kUnset = 0xFFFFFFFEu;   // a position no corner gave one yet
constexpr uint32_t kMixed = 0xFFFFFFFDu;   // a position its corners gave several

// Leading comments are kept as schema comments, but only a bounded amount:
// a file could start with megabytes of them.
constexpr size_t kMaxComments = 64;
constexpr size_t kMaxCommentBytes = 16 * 1024;

bool is_space(char c) { return c == ' ' || c == '\t' || c == '\v' || c == '\f'; }

// Whitespace-separated tokens of a statement, without copies.
class Tokens {
 public:
  explicit Tokens(std::string_view s) : s_(s) {}

  bool next(std::string_view* tok) {
    size_t i = 0;
    while (i < s_.size() && is_space(s_[i])) ++i;
    if (i == s_.size()) {
      s_ = std::string_view();
      return false;
    }
    size_t j = i;
    while (j < s_.size() && !is_space(s_[j])) ++j;
    *tok = s_.substr(i, j - i);
    s_.remove_prefix(j);
    return true;
  }

  size_t count() const {
    Tokens copy(s_);
    std::string_view tok;
    size_t n = 0;
    while (copy.next(&tok)) ++n;
    return n;
  }

 private:
  std::string_view s_;
};


// Removes a trailing comment and trailing whitespace.
std::string_view strip(std::string_view line) {
  size_t hash = line.find('#');
  if (hash != std::string_view::npos) line = line.substr(0, hash);
  while (!line.empty() && is_space(line.back())) line.remove_suffix(1);
  return line;
}

// Yields OBJ statements: lines without comments, with continuation lines
// (ending in '\') joined, blank ones skipped. Knows the line numbers.
class StatementReader {
 public:
  void start(InputStream* in) {
    in_ = in;
    line_ = 0;
    first_line_ = 0;
    comments_ = nullptr;
  }

  // Keeps the comment lines that precede the first statement.
  void collect_comments(std::vector<std::string>* out) {
    comments_ = out;
    comment_bytes_ = 0;
  }

  // The statement stays valid until the next call.
  Status next(std::string_view* stmt, bool* eof) {
    for (;;) {
      std::string_view line;
      PSQ_RETURN_IF_ERROR(read(&line, eof));
      if (*eof) return Status();
      first_line_ = line_;
      if (comments_ != nullptr) collect(line);
      std::string_view s = strip(line);
      if (!s.empty() && s.back() == '\\') PSQ_RETURN_IF_ERROR(join(s, &s));
      size_t i = 0;
      while (i < s.size() && is_space(s[i])) ++i;
      if (i == s.size()) continue;
      comments_ = nullptr;
      *stmt = s.substr(i);
      *eof = false;
      return Status();
    }
  }

  // First line of the last statement.
  uint64_t line() const { return first_line_; }

 private:
  Status read(std::string_view* line, bool* eof) {
    Status s = in_->read_line(line, eof);
    if (!s.ok()) return Status(s.code(), s.message(), s.offset(), line_ + 1);
    if (!*eof) ++line_;
    return Status();
  }

  // A backslash continues the statement on the next line; it stands for a
  // space so that tokens never run across lines.
  Status join(std::string_view first, std::string_view* out) {
    joined_.assign(first.data(), first.size() - 1);
    joined_ += ' ';
    for (;;) {
      std::string_view line;
      bool eof = false;
      PSQ_RETURN_IF_ERROR(read(&line, &eof));
      if (eof) break;
      std::string_view t = strip(line);
      bool more = !t.empty() && t.back() == '\\';
      if (more) t.remove_suffix(1);
      if (joined_.size() + t.size() > InputStream::kMaxLine) {
        return Status(ErrorCode::kLimit, "statement continued over more than 1 MiB",
                      Status::kNoPlace, first_line_);
      }
      joined_.append(t.data(), t.size());
      if (!more) break;
      joined_ += ' ';
    }
    *out = joined_;
    return Status();
  }

  void collect(std::string_view line) {
    size_t i = 0;
    while (i < line.size() && is_space(line[i])) ++i;
    if (i == line.size() || line[i] != '#') return;
    std::string_view text = line.substr(i + 1);
    while (!text.empty() && is_space(text.front())) text.remove_prefix(1);
    while (!text.empty() && is_space(text.back())) text.remove_suffix(1);
    if (comments_->size() >= kMaxComments || comment_bytes_ + text.size() > kMaxCommentBytes) return;
    comment_bytes_ += text.size();
    comments_->emplace_back(text);
  }

  InputStream* in_ = nullptr;
  uint64_t line_ = 0;
  uint64_t first_line_ = 0;
  std::string joined_;
  std::vector<std::string>* comments_ = nullptr;
  size_t comment_bytes_ = 0;
};

struct Corner {
  uint32_t v, t, n;  // 0-based; t and n may be kAbsent
};

Property float_property(const char* name) {
  Property p;
  p.name = name;
  p.type = ScalarType::kFloat32;
  return p;
}

Property float_list_property(const char* name) {
  Property p = float_property(name);
  p.is_list = true;
  p.count_type = ScalarType::kUInt8;
  return p;
}

// One kind of attribute (normals or texture coordinates) of a file read in
// memory. OBJ indexes attributes per corner; psq keeps every `v` line as one
// vertex, so the attribute is a vertex property when each position has a
// single one, and a per-corner face property otherwise.
struct Attribute {
  size_t arity = 0;             // floats per element: 3 (vn) or 2 (vt)
  std::vector<float> elements;  // the vn or vt lines
  std::vector<uint32_t> of_vertex;  // per position: the index, kUnset or kMixed
  std::vector<uint32_t> corners;    // per triangle corner: the index or kAbsent
  uint64_t mixed = 0;               // positions used with several indices
  bool per_corner = false;

  void use(uint32_t v, uint32_t index) {
    corners.push_back(index);
    if (index == kAbsent) return;  // compatible with any index
    uint32_t& a = of_vertex[v];
    if (a == kUnset) {
      a = index;
    } else if (a != kMixed && a != index) {
      a = kMixed;
      ++mixed;
    }
  }

  // Appends `arity` values of element `index`, zeros when there is none.
  void append(uint32_t index, PropertyValues* out) const {
    bool any = index < kMixed;
    for (size_t k = 0; k < arity; ++k) out->push_back(any ? elements[arity * size_t{index} + k] : 0.0);
  }
};

}  // namespace

// The statements of the OBJ specification (Wavefront's Appendix B1); psq
// reads v, vt, vn and f, counts l and p, and skips the others quietly.
bool is_obj_keyword(std::string_view kw) {
  static constexpr std::string_view kAll[] = {
      "v",     "vt",       "vn",       "vp",     "cstype", "deg",       "bmat",      "step",  "p",     "l",
      "f",     "curv",     "curv2",    "surf",   "parm",   "trim",      "hole",      "scrv",  "sp",    "end",
      "con",   "g",        "s",        "mg",     "o",      "bevel",     "c_interp",  "d_interp", "lod", "usemtl",
      "mtllib", "shadow_obj", "trace_obj", "ctech", "stech", "maplib", "usemap", "call", "csh"};
  for (std::string_view k : kAll)
    if (kw == k) return true;
  return false;
}

bool looks_like_obj(const uint8_t* data, size_t size) {
  size_t i = 0;
  for (;;) {
    while (i < size && (is_space(static_cast<char>(data[i])) || data[i] == '\r' || data[i] == '\n')) ++i;
    if (i == size) return false;
    if (data[i] != '#') break;
    while (i < size && data[i] != '\n' && data[i] != '\r') ++i;
  }
  size_t start = i;
  while (i < size && data[i] >= 'a' && data[i] <= 'z') ++i;
  std::string_view word(reinterpret_cast<const char*>(data + start), i - start);
  static constexpr std::string_view kKeywords[] = {"v", "vn", "vt", "f", "o", "g", "s",
                                                   "usemtl", "mtllib", "l", "p", "vp"};
  bool known = false;
  for (std::string_view k : kKeywords) known = known || word == k;
  if (!known) return false;
  if (i < size && !is_space(static_cast<char>(data[i])) && data[i] != '\r' && data[i] != '\n') return false;
  // The rest of the first statement must be text, which binary data is not.
  for (; i < size && data[i] != '\n' && data[i] != '\r'; ++i) {
    if (data[i] < 0x20 && data[i] != '\t') return false;
    if (data[i] == 0x7f) return false;
  }
  return true;
}

struct ObjReader::Impl {
  enum class Mode { kClosed, kStream, kMemory };

  Status open(InputStream* input, const std::string& spool_dir);
  Status prescan();
  Status next(MeshItem* item);
  Status next_streamed(MeshItem* item);
  Status next_in_memory(MeshItem* item);
  Status load();
  Status read_vertex(Tokens& tk, float xyz[3], float rgb[3]);
  Status read_numbers(Tokens& tk, const char* what, float* out, size_t max, size_t* count);
  Status read_face(Tokens& tk);
  Status read_corner(std::string_view tok, Corner* c);
  Status resolve(std::string_view tok, uint64_t defined, const char* what, uint32_t* out);
  Status check_unused(std::string_view tok, const char* what);
  void decide_attributes();
  void add_final_notes();

  Status error(ErrorCode code, std::string message) const {
    return Status(code, std::move(message), Status::kNoPlace, reader.line());
  }

  InputStream* in = nullptr;
  std::unique_ptr<SpoolFile> spool;
  StatementReader reader;
  MeshSchema schema;
  SourceReport report;
  Status status;
  Mode mode = Mode::kClosed;

  // Learned by the prescan.
  uint64_t file_vertices = 0;
  uint64_t file_triangles = 0;
  bool has_vn = false;
  bool has_vt = false;
  bool colours = false;      // the first `v` line has r g b
  bool interleaved = false;  // a `v` line follows an `f` line

  // Elements defined so far in the current pass.
  uint64_t v_count = 0;
  uint64_t vt_count = 0;
  uint64_t vn_count = 0;
  uint64_t unknown_statements = 0;  // with no OBJ keyword: noted, skipped
  uint64_t first_unknown_line = 0;
  std::string first_unknown;
  uint64_t colours_ignored = 0;
  uint64_t texcoord_refs_ignored = 0;
  uint64_t normal_refs_ignored = 0;
  std::vector<Corner> corners;  // of the current face

  // Streaming: the fan of the current face still to yield. An interleaved
  // file is read twice (vertices, then faces) so that every vertex comes
  // before every triangle, as sinks that write PLY need.
  std::vector<uint32_t> fan;
  size_t fan_next = 0;
  bool yield_vertices = true;
  bool yield_faces = true;
  uint64_t vertices_yielded = 0;
  uint64_t triangles_yielded = 0;
  bool ended = false;

  // In memory: everything, then yielded from `at`.
  std::vector<float> positions;
  std::vector<float> vertex_colours;
  Attribute normals;
  Attribute texcoords;
  std::vector<uint32_t> triangles;
  uint64_t at = 0;
};

Status ObjReader::Impl::open(InputStream* input, const std::string& spool_dir) {
  if (input == nullptr) return Status(ErrorCode::kUsage, "no input stream");
  if (!input->can_rewind()) {
    // OBJ needs two passes (and streaming mode a rewind), which a pipe
    // cannot give: keep a copy.
    spool = std::make_unique<SpoolFile>();
    PSQ_RETURN_IF_ERROR(spool->create(spool_dir));
    for (;;) {
      size_t available = 0;
      PSQ_RETURN_IF_ERROR(input->fill(size_t{1} << 16, &available));
      if (available == 0) break;
      PSQ_RETURN_IF_ERROR(spool->write(input->cursor(), available));
      input->advance(available);
    }
    PSQ_RETURN_IF_ERROR(spool->rewind());
    input = &spool->stream();
  }
  in = input;
  PSQ_RETURN_IF_ERROR(prescan());
  PSQ_RETURN_IF_ERROR(in->rewind());
  reader.start(in);

  if (has_vn || has_vt) {
    mode = Mode::kMemory;
    PSQ_RETURN_IF_ERROR(load());
  }

  // OBJ text is almost always single precision and carries no type, so
  // positions and attributes are declared (and parsed as) float; a writer
  // then reproduces them exactly.
  schema.position_type = ScalarType::kFloat32;
  if (has_vn && !normals.per_corner) {
    for (const char* name : {"nx", "ny", "nz"}) schema.vertex_properties.push_back(float_property(name));
  }
  if (colours) {
    for (const char* name : {"red", "green", "blue"}) schema.vertex_properties.push_back(float_property(name));
  }
  if (has_vt && !texcoords.per_corner) {
    for (const char* name : {"u", "v"}) schema.vertex_properties.push_back(float_property(name));
  }
  if (normals.per_corner) schema.face_properties.push_back(float_list_property("corner_normals"));
  if (texcoords.per_corner) schema.face_properties.push_back(float_list_property("corner_uv"));
  if (mode == Mode::kMemory) return Status();

  mode = Mode::kStream;
  schema.vertex_count = static_cast<int64_t>(file_vertices);
  schema.triangle_count = static_cast<int64_t>(file_triangles);
  if (interleaved) yield_faces = false;
  return Status();
}

// One cheap pass over first tokens: how to read the file, and its counts.
Status ObjReader::Impl::prescan() {
  reader.start(in);
  reader.collect_comments(&schema.comments);
  bool seen_face = false;
  uint64_t lines_points = 0;
  for (;;) {
    std::string_view stmt;
    bool eof = false;
    PSQ_RETURN_IF_ERROR(reader.next(&stmt, &eof));
    if (eof) break;
    Tokens tk(stmt);
    std::string_view kw;
    tk.next(&kw);
    if (kw == "v") {
      if (file_vertices == 0) colours = tk.count() == 6;
      ++file_vertices;
      if (seen_face) interleaved = true;
    } else if (kw == "f") {
      size_t n = tk.count();
      if (n >= 3) file_triangles += n - 2;
      if (n >= 4) ++report.polygons_triangulated;
      seen_face = true;
    } else if (kw == "vn") {
      has_vn = true;
    } else if (kw == "vt") {
      has_vt = true;
    } else if (kw == "l" || kw == "p") {
      ++lines_points;
    } else if (!is_obj_keyword(kw)) {
      // Not an OBJ statement (a bare "Created by ..." line, or bytes that
      // are not text): skipped, as readers do, but not silently.
      if (unknown_statements++ == 0) {
        first_unknown_line = reader.line();
        first_unknown = std::string(stmt.substr(0, 60));
        for (char& c : first_unknown) c = static_cast<unsigned char>(c) < 0x20 ? '?' : c;
        if (stmt.size() > 60) first_unknown += "...";
      }
    }
  }
  if (lines_points > 0) report.notes.push_back(std::to_string(lines_points) + " line/point elements ignored");
  if (unknown_statements > 0) {
    report.notes.push_back(std::to_string(unknown_statements) +
                           " statement(s) with no OBJ keyword ignored (the first, line " +
                           std::to_string(first_unknown_line) + ": '" + first_unknown + "')");
  }
  return Status();
}

Status ObjReader::Impl::read_numbers(Tokens& tk, const char* what, float* out, size_t max,
                                     size_t* count) {
  std::string_view tok;
  size_t n = 0;
  while (tk.next(&tok)) {
    if (n < max) {
      Parse p = parse_float(tok, &out[n]);
      if (p == Parse::kMalformed) {
        return error(ErrorCode::kBadValue, std::string("malformed number ") + quoted(tok) + " in " + what);
      }
      if (p == Parse::kOutOfRange) {
        return error(ErrorCode::kBadValue, std::string("number ") + quoted(tok) + " in " + what +
                                               " is out of range for float");
      }
    }
    ++n;
  }
  *count = n;
  return Status();
}

Status ObjReader::Impl::read_vertex(Tokens& tk, float xyz[3], float rgb[3]) {
  float v[6];
  size_t n = 0;
  PSQ_RETURN_IF_ERROR(read_numbers(tk, "vertex", v, 6, &n));
  if (n != 3 && n != 4 && n != 6) {
    return error(ErrorCode::kBadValue, "vertex has " + std::to_string(n) +
                                           " coordinates; expected 3, 4 (x y z w) or 6 (x y z r g b)");
  }
  if (colours && n != 6) {
    return error(ErrorCode::kBadValue,
                 "vertex has " + std::to_string(n) + " coordinates but earlier vertices have colours");
  }
  if (!colours && n == 6) ++colours_ignored;
  for (int k = 0; k < 3; ++k) {
    if (!std::isfinite(v[k])) return error(ErrorCode::kBadValue, "position is not finite");
    xyz[k] = v[k];
    rgb[k] = v[3 + k];  // meaningful only with colours
  }
  if (v_count >= kMaxCount) return error(ErrorCode::kLimit, "too many vertices for 32-bit indices");
  ++v_count;
  return Status();
}

Status ObjReader::Impl::resolve(std::string_view tok, uint64_t defined, const char* what,
                                uint32_t* out) {
  int64_t raw = 0;
  Parse p = parse_int(tok, &raw);
  if (p == Parse::kMalformed) {
    return error(ErrorCode::kBadValue, std::string("malformed ") + what + " index " + quoted(tok));
  }
  if (p == Parse::kOutOfRange) {
    return error(ErrorCode::kBadIndex, std::string(what) + " index " + quoted(tok) + " is out of range");
  }
  if (raw == 0) return error(ErrorCode::kBadIndex, "index 0 is not valid in OBJ (indices start at 1)");
  // Negative indices count back from the last element defined so far.
  auto d = static_cast<int64_t>(defined);
  if (raw > 0 && raw <= d) {
    *out = static_cast<uint32_t>(raw - 1);
    return Status();
  }
  if (raw < 0 && raw >= -d) {
    *out = static_cast<uint32_t>(d + raw);
    return Status();
  }
  return error(ErrorCode::kBadIndex, std::string(what) + " index " + std::to_string(raw) +
                                         " refers to an undefined " + what + " (" +
                                         std::to_string(defined) + " defined so far)");
}

Status ObjReader::Impl::read_corner(std::string_view tok, Corner* c) {
  size_t s1 = tok.find('/');
  std::string_view vs = tok.substr(0, s1);
  std::string_view ts, ns;
  if (s1 != std::string_view::npos) {
    std::string_view rest = tok.substr(s1 + 1);
    size_t s2 = rest.find('/');
    ts = rest.substr(0, s2);
    if (s2 != std::string_view::npos) {
      ns = rest.substr(s2 + 1);
      if (ns.find('/') != std::string_view::npos) {
        return error(ErrorCode::kBadValue, "malformed face corner " + quoted(tok));
      }
    }
  }
  if (vs.empty()) return error(ErrorCode::kBadValue, "face corner " + quoted(tok) + " has no vertex index");
  PSQ_RETURN_IF_ERROR(resolve(vs, v_count, "vertex", &c->v));
  c->t = c->n = kAbsent;
  if (!ts.empty()) {
    if (has_vt) {
      PSQ_RETURN_IF_ERROR(resolve(ts, vt_count, "texture coordinate", &c->t));
    } else {
      PSQ_RETURN_IF_ERROR(check_unused(ts, "texture coordinate"));
      ++texcoord_refs_ignored;
    }
  }
  if (!ns.empty()) {
    if (has_vn) {
      PSQ_RETURN_IF_ERROR(resolve(ns, vn_count, "normal", &c->n));
    } else {
      PSQ_RETURN_IF_ERROR(check_unused(ns, "normal"));
      ++normal_refs_ignored;
    }
  }
  return Status();
}

// Some writers emit `f a//a` with no `vn` line at all (and likewise for vt);
// such indices can refer to nothing, so they are ignored, but they must
// still be well-formed.
Status ObjReader::Impl::check_unused(std::string_view tok, const char* what) {
  int64_t raw = 0;
  Parse p = parse_int(tok, &raw);
  if (p == Parse::kMalformed) {
    return error(ErrorCode::kBadValue, std::string("malformed ") + what + " index " + quoted(tok));
  }
  if (p == Parse::kOk && raw == 0) {
    return error(ErrorCode::kBadIndex, "index 0 is not valid in OBJ (indices start at 1)");
  }
  return Status();
}

Status ObjReader::Impl::read_face(Tokens& tk) {
  corners.clear();
  std::string_view tok;
  while (tk.next(&tok)) {
    Corner c;
    PSQ_RETURN_IF_ERROR(read_corner(tok, &c));
    corners.push_back(c);
  }
  if (corners.size() < 3) {
    return error(ErrorCode::kBadValue,
                 "face has " + std::to_string(corners.size()) + " corners; a face needs at least 3");
  }
  return Status();
}

void ObjReader::Impl::add_final_notes() {
  if (texcoord_refs_ignored > 0) {
    report.notes.push_back(std::to_string(texcoord_refs_ignored) +
                           " texture coordinate indices ignored: the file has no vt lines");
  }
  if (normal_refs_ignored > 0) {
    report.notes.push_back(std::to_string(normal_refs_ignored) + " normal indices ignored: the file has no vn lines");
  }
  if (colours_ignored > 0) {
    report.notes.push_back("colours of " + std::to_string(colours_ignored) +
                           " vertices ignored: the first vertex has none");
  }
  if (normals.per_corner) {
    report.notes.push_back("normals vary per corner at " + std::to_string(normals.mixed) +
                           " vertices: kept as per-corner face property corner_normals");
  }
  if (texcoords.per_corner) {
    report.notes.push_back("texture coordinates vary per corner at " + std::to_string(texcoords.mixed) +
                           " vertices: kept as per-corner face property corner_uv");
  }
}

Status ObjReader::Impl::next(MeshItem* item) {
  if (!status.ok()) return status;
  if (mode == Mode::kClosed) return Status(ErrorCode::kUsage, "the OBJ reader is not open");
  Status s = mode == Mode::kStream ? next_streamed(item) : next_in_memory(item);
  if (!s.ok()) status = s;
  return s;
}

Status ObjReader::Impl::next_streamed(MeshItem* item) {
  for (;;) {
    if (fan_next + 1 < fan.size()) {
      item->kind = MeshItem::Kind::kTriangle;
      item->index[0] = fan[0];
      item->index[1] = fan[fan_next];
      item->index[2] = fan[fan_next + 1];
      item->values.clear();
      ++fan_next;
      ++triangles_yielded;
      return Status();
    }
    if (ended) {
      item->kind = MeshItem::Kind::kEnd;
      item->values.clear();
      return Status();
    }
    std::string_view stmt;
    bool eof = false;
    PSQ_RETURN_IF_ERROR(reader.next(&stmt, &eof));
    if (eof) {
      if (!yield_faces) {
        PSQ_RETURN_IF_ERROR(in->rewind());
        reader.start(in);
        v_count = 0;
        yield_vertices = false;
        yield_faces = true;
        continue;
      }
      // The counts promised in the schema came from the prescan.
      if (vertices_yielded != file_vertices || triangles_yielded != file_triangles) {
        return Status(ErrorCode::kIo, "the input changed while it was read");
      }
      add_final_notes();
      ended = true;
      continue;
    }
    Tokens tk(stmt);
    std::string_view kw;
    tk.next(&kw);
    if (kw == "v") {
      if (!yield_vertices) {
        ++v_count;  // parsed and checked in the first pass
        continue;
      }
      float xyz[3], rgb[3];
      PSQ_RETURN_IF_ERROR(read_vertex(tk, xyz, rgb));
      item->kind = MeshItem::Kind::kVertex;
      item->values.clear();
      for (int k = 0; k < 3; ++k) item->position[k] = xyz[k];
      if (colours) item->values.assign(rgb, rgb + 3);
      ++vertices_yielded;
      return Status();
    }
    if (kw == "f") {
      if (!yield_faces) continue;
      PSQ_RETURN_IF_ERROR(read_face(tk));
      fan.clear();
      for (const Corner& c : corners) fan.push_back(c.v);
      fan_next = 1;
      continue;
    }
    if (kw == "vn" || kw == "vt") return Status(ErrorCode::kIo, "the input changed while it was read");
  }
}

Status ObjReader::Impl::load() {
  positions.reserve(3 * file_vertices);
  if (colours) vertex_colours.reserve(3 * file_vertices);
  normals.arity = 3;
  texcoords.arity = 2;
  if (has_vn) normals.of_vertex.assign(file_vertices, kUnset);
  if (has_vt) texcoords.of_vertex.assign(file_vertices, kUnset);
  for (;;) {
    std::string_view stmt;
    bool eof = false;
    PSQ_RETURN_IF_ERROR(reader.next(&stmt, &eof));
    if (eof) break;
    Tokens tk(stmt);
    std::string_view kw;
    tk.next(&kw);
    if (kw == "v") {
      float xyz[3], rgb[3];
      PSQ_RETURN_IF_ERROR(read_vertex(tk, xyz, rgb));
      if (v_count > file_vertices) return Status(ErrorCode::kIo, "the input changed while it was read");
      positions.insert(positions.end(), xyz, xyz + 3);
      if (colours) vertex_colours.insert(vertex_colours.end(), rgb, rgb + 3);
    } else if (kw == "vt") {
      float uvw[3] = {0, 0, 0};
      size_t n = 0;
      PSQ_RETURN_IF_ERROR(read_numbers(tk, "texture coordinate", uvw, 3, &n));
      if (n < 1 || n > 3) {
        return error(ErrorCode::kBadValue,
                     "texture coordinate has " + std::to_string(n) + " values; expected 1 to 3");
      }
      if (vt_count >= kMaxCount) return error(ErrorCode::kLimit, "too many texture coordinates");
      texcoords.elements.insert(texcoords.elements.end(), uvw, uvw + 2);
      ++vt_count;
    } else if (kw == "vn") {
      float xyz[3];
      size_t n = 0;
      PSQ_RETURN_IF_ERROR(read_numbers(tk, "normal", xyz, 3, &n));
      if (n != 3) {
        return error(ErrorCode::kBadValue, "normal has " + std::to_string(n) + " values; expected 3");
      }
      if (vn_count >= kMaxCount) return error(ErrorCode::kLimit, "too many normals");
      normals.elements.insert(normals.elements.end(), xyz, xyz + 3);
      ++vn_count;
    } else if (kw == "f") {
      PSQ_RETURN_IF_ERROR(read_face(tk));
      // A fan: corners 0, i - 1, i.
      for (size_t i = 2; i < corners.size(); ++i) {
        for (const Corner& c : {corners[0], corners[i - 1], corners[i]}) {
          triangles.push_back(c.v);
          if (has_vn) normals.use(c.v, c.n);
          if (has_vt) texcoords.use(c.v, c.t);
        }
      }
    }
  }
  if (v_count != file_vertices) return Status(ErrorCode::kIo, "the input changed while it was read");
  decide_attributes();
  schema.vertex_count = static_cast<int64_t>(file_vertices);
  schema.triangle_count = static_cast<int64_t>(triangles.size() / 3);
  add_final_notes();
  // Everything is in memory: the spool file can go.
  in = nullptr;
  spool.reset();
  return Status();
}

// Keeps of each attribute only the indices that will be yielded.
void ObjReader::Impl::decide_attributes() {
  for (Attribute* a : {&normals, &texcoords}) {
    a->per_corner = a->mixed > 0;
    if (a->per_corner) {
      a->of_vertex = {};
    } else {
      a->corners = {};
    }
  }
}

Status ObjReader::Impl::next_in_memory(MeshItem* item) {
  uint64_t triangle_total = triangles.size() / 3;
  item->values.clear();
  if (at < file_vertices) {
    size_t v = static_cast<size_t>(at);
    item->kind = MeshItem::Kind::kVertex;
    for (int k = 0; k < 3; ++k) item->position[k] = positions[3 * v + k];
    if (has_vn && !normals.per_corner) normals.append(normals.of_vertex[v], &item->values);
    if (colours) {
      for (int k = 0; k < 3; ++k) item->values.push_back(vertex_colours[3 * v + k]);
    }
    if (has_vt && !texcoords.per_corner) texcoords.append(texcoords.of_vertex[v], &item->values);
    ++at;
    return Status();
  }
  if (at < file_vertices + triangle_total) {
    size_t t = static_cast<size_t>(at - file_vertices);
    item->kind = MeshItem::Kind::kTriangle;
    for (int k = 0; k < 3; ++k) item->index[k] = triangles[3 * t + k];
    // The flattened list: its count, then the values of corners 0, 1, 2.
    for (const Attribute* a : {&normals, &texcoords}) {
      if (!a->per_corner) continue;
      item->values.push_back(static_cast<double>(3 * a->arity));
      for (int k = 0; k < 3; ++k) a->append(a->corners[3 * t + k], &item->values);
    }
    ++at;
    return Status();
  }
  item->kind = MeshItem::Kind::kEnd;
  return Status();
}

ObjReader::ObjReader() : impl_(std::make_unique<Impl>()) {}
ObjReader::~ObjReader() = default;

Status ObjReader::open(InputStream* in, const std::string& spool_dir) {
  impl_ = std::make_unique<Impl>();
  Status s = impl_->open(in, spool_dir);
  if (!s.ok()) impl_->status = s;
  return s;
}

const MeshSchema& ObjReader::schema() const { return impl_->schema; }

Status ObjReader::next(MeshItem* item) { return impl_->next(item); }

const SourceReport& ObjReader::report() const { return impl_->report; }

}  // namespace psq
