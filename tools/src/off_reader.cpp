// SPDX-License-Identifier: Apache-2.0
// OffReader and looks_like_off: streaming ascii OFF (see psq/off.h).
//
// OFF is Geomview's Object File Format; the keyword prefixes ([ST][C][N][4]
// [n]OFF) and the line layout follow Geomview's OFF(5) manual page.
#include <charconv>
#include <cmath>
#include <cstring>
#include <string>
#include <string_view>
#include <system_error>
#include <vector>

#include "psq/off.h"
#include "text_parse.h"

namespace psq {
namespace {

using detail::Parse;
using detail::parse_float;
using detail::quoted;
using detail::parse_int;
using detail::skip_plus;

constexpr uint64_t kMaxVertices = 0xffffffffu;  // indices are 32-bit
// The fewest bytes a vertex line ("0 0 0\n") or a face line takes; a count
// that needs more bytes than follow the header is rejected up front.
constexpr uint64_t kMinLineBytes = 6;
// Most values after a face's indices: a colour (r g b a).
constexpr size_t kMaxFaceColour = 4;
// Leading comments are kept as schema comments, but only a bounded amount.
constexpr size_t kMaxComments = 64;
constexpr size_t kMaxCommentBytes = 16 * 1024;
// The most bytes before the end of the counts line.
constexpr uint64_t kMaxHeader = uint64_t{1} << 20;

bool is_blank(unsigned char c) { return c <= ' '; }

// Splits `line` at blanks (space, tab and any other control character).
void split(std::string_view line, std::vector<std::string_view>* out) {
  out->clear();
  size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && is_blank(static_cast<unsigned char>(line[i]))) ++i;
    size_t j = i;
    while (j < line.size() && !is_blank(static_cast<unsigned char>(line[j]))) ++j;
    if (j > i) out->push_back(line.substr(i, j - i));
    i = j;
  }
}

// The line without its comment.
std::string_view strip_comment(std::string_view line) {
  size_t hash = line.find('#');
  return hash == std::string_view::npos ? line : line.substr(0, hash);
}


// The header keyword: [ST][C][N][4][n]OFF.
struct Keyword {
  bool st = false, colour = false, normal = false, four = false, ndim = false;
};

// Parses a keyword at the start of `s`; returns its length, 0 if none.
size_t parse_keyword(std::string_view s, Keyword* k) {
  size_t i = 0;
  auto take = [&](std::string_view p) {
    if (s.substr(i, p.size()) != p) return false;
    i += p.size();
    return true;
  };
  k->st = take("ST");
  k->colour = take("C");
  k->normal = take("N");
  k->four = take("4");
  k->ndim = take("n");
  return take("OFF") ? i : 0;
}

bool all_digits(std::string_view s) {
  if (s.empty()) return false;
  for (char c : s) {
    if (c < '0' || c > '9') return false;
  }
  return true;
}

}  // namespace

bool looks_like_off(const uint8_t* data, size_t size) {
  size_t i = 0;
  if (size >= 3 && std::memcmp(data, "\xEF\xBB\xBF", 3) == 0) i = 3;  // UTF-8 BOM
  for (;;) {
    while (i < size && (data[i] == ' ' || data[i] == '\t' || data[i] == '\r' || data[i] == '\n')) ++i;
    if (i == size) return false;
    if (data[i] != '#') break;
    while (i < size && data[i] != '\n' && data[i] != '\r') ++i;
  }
  Keyword k;
  size_t n = parse_keyword(std::string_view(reinterpret_cast<const char*>(data + i), size - i), &k);
  if (n == 0) return false;
  i += n;
  if (i == size) return true;
  unsigned char c = data[i];
  return c == ' ' || c == '\t' || c == '\r' || c == '\n' || c == '#' || (c >= '0' && c <= '9');
}

struct OffReader::Impl {
  InputStream* in = nullptr;
  MeshSchema schema;
  SourceReport report;
  Status error;
  uint64_t line = 0;  // lines read so far
  size_t comment_bytes = 0;  // kept in schema.comments
  // While the header is read: the offset it must end by. Comments and blank
  // lines before the keyword and the counts are skipped, but not without
  // end (a stream of them from a pipe would never finish).
  uint64_t header_end = ~uint64_t{0};

  bool normals = false;
  size_t colour_components = 0;  // 0, 3 or 4
  size_t vertex_values = 3;      // numbers on a vertex line
  uint64_t vertex_count = 0;
  uint64_t face_count = 0;
  uint64_t vertices_read = 0;
  uint64_t faces_read = 0;
  uint64_t faces_with_colour = 0;
  bool ended = false;

  // The first vertex line, read by open() to learn the colour layout.
  std::string pending_text;
  bool has_pending = false;
  uint64_t pending_line = 0;

  std::vector<std::string_view> tokens;
  std::vector<uint32_t> corners;  // of the face being split into a fan
  size_t corner_at = 0;           // next fan triangle is (0, corner_at, +1)

  Status fail(Status s) {
    error = s;
    return s;
  }

  // Reads lines until one has tokens (comments stripped) and splits it
  // into `tokens`; sets *eof instead when the input ends. `comments`
  // collects comment text on the way.
  Status content_line(bool* eof, std::vector<std::string>* comments = nullptr);
  Status open();
  Status next(MeshItem* item);
  Status read_vertex(MeshItem* item);
  Status read_face();
};

Status OffReader::Impl::content_line(bool* eof, std::vector<std::string>* comments) {
  for (;;) {
    if (in->offset() > header_end) {
      return Status(ErrorCode::kLimit, "no OFF keyword and counts in the first 1 MiB (a header may not be longer)",
                    in->offset(), line + 1);
    }
    std::string_view text;
    Status s = in->read_line(&text, eof);
    if (!s.ok()) return Status(s.code(), s.message(), s.offset(), line + 1);
    if (*eof) return Status();
    ++line;
    std::string_view body = strip_comment(text);
    if (comments != nullptr && body.size() < text.size() && comments->size() < kMaxComments) {
      std::string_view c = text.substr(body.size() + 1);
      while (!c.empty() && is_blank(static_cast<unsigned char>(c.front()))) c.remove_prefix(1);
      while (!c.empty() && is_blank(static_cast<unsigned char>(c.back()))) c.remove_suffix(1);
      if (comment_bytes + c.size() <= kMaxCommentBytes) {
        comment_bytes += c.size();
        comments->emplace_back(c);
      }
    }
    split(body, &tokens);
    if (!tokens.empty()) return Status();
  }
}

Status OffReader::Impl::open() {
  auto header = [this](ErrorCode code, const std::string& m) { return Status(code, m, Status::kNoPlace, line); };
  bool eof = false;
  header_end = in->offset() + kMaxHeader;
  PSQ_RETURN_IF_ERROR(content_line(&eof, &schema.comments));
  if (eof) return Status(ErrorCode::kBadHeader, "not an OFF file (no OFF keyword)", Status::kNoPlace, line + 1);
  Keyword k;
  std::string_view first = tokens[0];
  if (first.size() >= 3 && std::memcmp(first.data(), "\xEF\xBB\xBF", 3) == 0) first.remove_prefix(3);
  size_t klen = parse_keyword(first, &k);
  std::string_view rest = first.substr(klen);
  if (klen == 0 || !(rest.empty() || all_digits(rest))) {
    return header(ErrorCode::kBadHeader, "not an OFF file (no OFF keyword; found " + quoted(tokens[0]) + ")");
  }
  std::string keyword(first.substr(0, klen));
  if (k.st) return header(ErrorCode::kUnsupported, keyword + ": OFF with texture coordinates (ST) is not supported");
  if (k.four) return header(ErrorCode::kUnsupported, keyword + ": OFF with homogeneous coordinates (4) is not supported");
  if (k.ndim) return header(ErrorCode::kUnsupported, keyword + ": n-dimensional OFF (nOFF) is not supported");
  normals = k.normal;
  bool colours = k.colour;

  // The counts follow the keyword on its line, or make up the next line.
  std::vector<std::string_view> counts;
  if (!rest.empty()) counts.push_back(rest);
  for (size_t i = 1; i < tokens.size(); ++i) counts.push_back(tokens[i]);
  if (!counts.empty() && counts[0] == "BINARY") {
    return header(ErrorCode::kUnsupported, "binary OFF (" + keyword + " BINARY) is not supported");
  }
  if (counts.empty()) {
    PSQ_RETURN_IF_ERROR(content_line(&eof, &schema.comments));
    if (eof) return Status(ErrorCode::kTruncated, "file ends before the vertex and face counts", Status::kNoPlace, line + 1);
    counts = tokens;
  }
  header_end = ~uint64_t{0};
  if (counts.size() < 2 || counts.size() > 3) {
    return header(ErrorCode::kBadHeader, "expected the counts 'vertices faces [edges]', found " +
                                             std::to_string(counts.size()) + " values");
  }
  uint64_t v[2] = {0, 0};
  const char* names[2] = {"vertex", "face"};
  for (size_t i = 0; i < 2; ++i) {
    const char* b = counts[i].data();
    const char* e = b + counts[i].size();
    std::from_chars_result r{b, std::errc::invalid_argument};
    if (skip_plus(&b, e)) r = std::from_chars(b, e, v[i]);
    if (r.ec == std::errc::result_out_of_range && r.ptr == e) {
      return header(ErrorCode::kLimit, std::string(names[i]) + " count " + quoted(counts[i]) + " exceeds 64 bits");
    }
    if (r.ec != std::errc() || r.ptr != e) {
      return header(ErrorCode::kBadHeader,
                    std::string(names[i]) + " count " + quoted(counts[i]) + " is not a non-negative integer");
    }
  }
  int64_t edges = 0;  // ignored, but must be an integer (some writers put -1)
  if (counts.size() == 3 && parse_int(counts[2], &edges) == Parse::kMalformed) {
    return header(ErrorCode::kBadHeader, "edge count " + quoted(counts[2]) + " is not an integer");
  }
  vertex_count = v[0];
  face_count = v[1];
  if (vertex_count > kMaxVertices) {
    return header(ErrorCode::kLimit, "header declares " + std::to_string(vertex_count) +
                                         " vertices; psq reads at most 4294967295");
  }
  // The counts must fit in the bytes that follow (no final line end: +1).
  if (in->size() >= 0) {
    uint64_t avail = static_cast<uint64_t>(in->size()) - in->offset() + 1;
    if (vertex_count > avail / kMinLineBytes) {
      return Status(ErrorCode::kTruncated, "header declares " + std::to_string(vertex_count) + " vertices but only " +
                                               std::to_string(avail - 1) + " bytes follow",
                    in->offset());
    }
    uint64_t left = avail - vertex_count * kMinLineBytes;
    if (face_count > left / kMinLineBytes) {
      return Status(ErrorCode::kTruncated, "header declares " + std::to_string(vertex_count) + " vertices and " +
                                               std::to_string(face_count) + " faces but only " +
                                               std::to_string(avail - 1) + " bytes follow",
                    in->offset());
    }
  }

  schema.position_type = ScalarType::kFloat32;
  schema.vertex_count = static_cast<int64_t>(vertex_count);
  schema.triangle_count = face_count == 0 ? 0 : MeshSchema::kUnknown;
  if (normals) {
    for (const char* n : {"nx", "ny", "nz"}) schema.vertex_properties.push_back({n, ScalarType::kFloat32});
  }
  vertex_values = normals ? 6 : 3;
  if (colours) {
    // The first vertex line tells 3 or 4 colour components; keep it for
    // next(). Without vertices, r g b is declared.
    colour_components = 3;
    if (vertex_count > 0) {
      PSQ_RETURN_IF_ERROR(content_line(&eof));
      if (eof) {
        return Status(ErrorCode::kTruncated, "file ends before vertex 0 of " + std::to_string(vertex_count),
                      Status::kNoPlace, line + 1);
      }
      if (tokens.size() != vertex_values + 3 && tokens.size() != vertex_values + 4) {
        return Status(ErrorCode::kBadValue,
                      "vertex 0: expected " + std::to_string(vertex_values + 3) + " or " +
                          std::to_string(vertex_values + 4) + " numbers (" + (normals ? "x y z nx ny nz" : "x y z") +
                          " r g b [a]), found " + std::to_string(tokens.size()),
                      Status::kNoPlace, line);
      }
      colour_components = tokens.size() - vertex_values;
      // Keep the line: copy it and point the tokens into the copy.
      size_t total = 0;
      for (std::string_view t : tokens) total += t.size() + 1;
      pending_text.clear();
      pending_text.reserve(total);
      for (std::string_view t : tokens) {
        pending_text.append(t.data(), t.size());
        pending_text += ' ';
      }
      split(pending_text, &tokens);
      has_pending = true;
      pending_line = line;
    }
    const char* cn[4] = {"red", "green", "blue", "alpha"};
    for (size_t i = 0; i < colour_components; ++i) schema.vertex_properties.push_back({cn[i], ScalarType::kFloat32});
    vertex_values += colour_components;
    report.notes.push_back("vertex colours carried as float " +
                           std::string(colour_components == 4 ? "red green blue alpha" : "red green blue") +
                           " as written (0-255 or 0-1)");
  }
  return Status();
}

Status OffReader::Impl::read_vertex(MeshItem* out) {
  uint64_t at_line;
  if (has_pending) {
    has_pending = false;
    at_line = pending_line;
  } else {
    bool eof = false;
    PSQ_RETURN_IF_ERROR(content_line(&eof));
    if (eof) {
      return Status(ErrorCode::kTruncated,
                    "file ends before vertex " + std::to_string(vertices_read) + " of " + std::to_string(vertex_count),
                    Status::kNoPlace, line + 1);
    }
    at_line = line;
  }
  auto bad = [&](ErrorCode code, const std::string& m) {
    return Status(code, "vertex " + std::to_string(vertices_read) + ": " + m, Status::kNoPlace, at_line);
  };
  if (tokens.size() != vertex_values) {
    return bad(ErrorCode::kBadValue, "expected " + std::to_string(vertex_values) + " numbers, found " +
                                         std::to_string(tokens.size()));
  }
  out->values.clear();
  for (size_t i = 0; i < tokens.size(); ++i) {
    float f = 0;
    Parse p = parse_float(tokens[i], &f);
    if (p == Parse::kMalformed) return bad(ErrorCode::kBadValue, quoted(tokens[i]) + " is not a number");
    if (p == Parse::kOutOfRange) return bad(ErrorCode::kBadValue, quoted(tokens[i]) + " is beyond float range");
    if (!std::isfinite(f)) {
      return bad(ErrorCode::kBadValue, i < 3 ? "position is not finite" : quoted(tokens[i]) + " is not finite");
    }
    if (i < 3) {
      out->position[i] = f;
    } else {
      out->values.push_back(f);
    }
  }
  out->kind = MeshItem::Kind::kVertex;
  return Status();
}

Status OffReader::Impl::read_face() {
  bool eof = false;
  PSQ_RETURN_IF_ERROR(content_line(&eof));
  if (eof) {
    return Status(ErrorCode::kTruncated,
                  "file ends before face " + std::to_string(faces_read) + " of " + std::to_string(face_count),
                  Status::kNoPlace, line + 1);
  }
  auto bad = [&](ErrorCode code, const std::string& m) {
    return Status(code, "face " + std::to_string(faces_read) + ": " + m, Status::kNoPlace, line);
  };
  int64_t n = 0;
  Parse p = parse_int(tokens[0], &n);
  if (p != Parse::kOk) return bad(ErrorCode::kBadValue, "corner count " + quoted(tokens[0]) + " is not an integer");
  if (n < 3) {
    return bad(ErrorCode::kBadValue, std::to_string(n) + " corners; a face needs at least 3");
  }
  if (static_cast<uint64_t>(n) > tokens.size() - 1) {
    return bad(ErrorCode::kBadValue, "face declares " + std::to_string(n) + " corners but its line has " +
                                         std::to_string(tokens.size() - 1) + " indices");
  }
  size_t extra = tokens.size() - 1 - static_cast<size_t>(n);
  if (extra > kMaxFaceColour) {
    return bad(ErrorCode::kBadValue, std::to_string(extra) + " values after the " + std::to_string(n) +
                                         " indices (a face colour has at most 4)");
  }
  corners.clear();
  for (size_t i = 1; i <= static_cast<size_t>(n); ++i) {
    int64_t v = 0;
    p = parse_int(tokens[i], &v);
    if (p == Parse::kMalformed) return bad(ErrorCode::kBadValue, "index " + quoted(tokens[i]) + " is not an integer");
    if (p == Parse::kOutOfRange || v < 0 || static_cast<uint64_t>(v) >= vertex_count) {
      ErrorCode code = ErrorCode::kBadIndex;
      if (p == Parse::kOk && v < 0) return bad(code, "negative vertex index " + std::to_string(v));
      return bad(code, "vertex index " + quoted(tokens[i]) + " out of range (" + std::to_string(vertex_count) +
                           " vertices)");
    }
    corners.push_back(static_cast<uint32_t>(v));
  }
  for (size_t i = tokens.size() - extra; i < tokens.size(); ++i) {
    float f = 0;
    if (parse_float(tokens[i], &f) == Parse::kMalformed) {
      return bad(ErrorCode::kBadValue, "face colour value " + quoted(tokens[i]) + " is not a number");
    }
  }
  if (extra > 0) ++faces_with_colour;
  if (n > 3) ++report.polygons_triangulated;
  corner_at = 1;
  return Status();
}

Status OffReader::Impl::next(MeshItem* out) {
  if (vertices_read < vertex_count) {
    PSQ_RETURN_IF_ERROR(read_vertex(out));
    ++vertices_read;
    return Status();
  }
  for (;;) {
    if (corner_at + 1 < corners.size()) {
      out->kind = MeshItem::Kind::kTriangle;
      out->index[0] = corners[0];
      out->index[1] = corners[corner_at];
      out->index[2] = corners[corner_at + 1];
      out->values.clear();
      ++corner_at;
      return Status();
    }
    corners.clear();
    corner_at = 0;
    if (faces_read == face_count) break;
    PSQ_RETURN_IF_ERROR(read_face());
    ++faces_read;
  }
  if (!ended) {
    bool eof = false;
    PSQ_RETURN_IF_ERROR(content_line(&eof));
    if (!eof) {
      return Status(ErrorCode::kBadValue,
                    "content after the last face (the header declares " + std::to_string(face_count) + " faces)",
                    Status::kNoPlace, line);
    }
    if (faces_with_colour > 0) {
      report.notes.push_back("face colours ignored (" + std::to_string(faces_with_colour) + " faces had one)");
    }
    ended = true;
  }
  out->kind = MeshItem::Kind::kEnd;
  out->values.clear();
  return Status();
}

OffReader::OffReader() = default;
OffReader::~OffReader() = default;

Status OffReader::open(InputStream* in) {
  impl_ = std::make_unique<Impl>();
  impl_->in = in;
  Status s = impl_->open();
  if (!s.ok()) return impl_->fail(s);
  return Status();
}

const MeshSchema& OffReader::schema() const {
  static const MeshSchema kEmpty;
  return impl_ ? impl_->schema : kEmpty;
}

const SourceReport& OffReader::report() const {
  static const SourceReport kEmpty;
  return impl_ ? impl_->report : kEmpty;
}

Status OffReader::next(MeshItem* item) {
  if (!impl_) return Status(ErrorCode::kUsage, "OffReader::next before open");
  if (!impl_->error.ok()) return impl_->error;
  Status s = impl_->next(item);
  if (!s.ok()) impl_->error = s;
  return s;
}

}  // namespace psq
