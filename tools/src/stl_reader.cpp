// SPDX-License-Identifier: Apache-2.0
// StlReader and looks_like_stl: binary and ascii STL read in core, vertices
// welded by exact position (see psq/stl.h).
#include <charconv>
#include <cmath>
#include <cstring>
#include <string>
#include <string_view>
#include <system_error>
#include <vector>

#include "psq/stl.h"
#include "text_parse.h"

namespace psq {
namespace {

using detail::Parse;
using detail::parse_float;
using detail::quoted;

constexpr uint64_t kHeaderBytes = 84;
constexpr uint64_t kTriangleBytes = 50;
constexpr uint32_t kMaxVertices = 0xffffffffu;  // indices are 32-bit
constexpr uint32_t kEmptySlot = 0xffffffffu;
// Solid names kept as schema comments, bounded: a file may hold many solids.
constexpr size_t kMaxComments = 64;
constexpr size_t kMaxCommentBytes = 16 * 1024;
// How much of the input decides the encoding.
constexpr size_t kSniffBytes = 4096;

bool is_blank(unsigned char c) { return c <= ' '; }

char lower(char c) { return (c >= 'A' && c <= 'Z') ? static_cast<char>(c - 'A' + 'a') : c; }

bool iequals(std::string_view a, std::string_view b) {
  if (a.size() != b.size()) return false;
  for (size_t i = 0; i < a.size(); ++i) {
    if (lower(a[i]) != b[i]) return false;
  }
  return true;
}

uint32_t le32(const uint8_t* p) {
  return static_cast<uint32_t>(p[0]) | static_cast<uint32_t>(p[1]) << 8 | static_cast<uint32_t>(p[2]) << 16 |
         static_cast<uint32_t>(p[3]) << 24;
}

float le_float(const uint8_t* p) {
  uint32_t bits = le32(p);
  float f;
  std::memcpy(&f, &bits, sizeof f);
  return f;
}

// True when `data` starts (after blanks) with a line "solid [name]" and the
// next word is "facet" or "endsolid" (any case).
bool looks_ascii(const uint8_t* data, size_t size) {
  std::string_view s(reinterpret_cast<const char*>(data), size);
  size_t i = 0;
  while (i < s.size() && is_blank(static_cast<unsigned char>(s[i]))) ++i;
  if (s.size() - i < 5 || !iequals(s.substr(i, 5), "solid")) return false;
  i += 5;
  if (i < s.size() && !is_blank(static_cast<unsigned char>(s[i]))) return false;
  while (i < s.size() && s[i] != '\n' && s[i] != '\r') ++i;
  while (i < s.size() && is_blank(static_cast<unsigned char>(s[i]))) ++i;
  size_t j = i;
  while (j < s.size() && !is_blank(static_cast<unsigned char>(s[j]))) ++j;
  std::string_view word = s.substr(i, j - i);
  return iequals(word, "facet") || iequals(word, "endsolid");
}


// Distinct positions, numbered in order of first appearance, found through
// an open-addressing hash table of vertex numbers (load at most 1/2).
class Welder {
 public:
  // Sets *index to the number of the position `p` (finite; -0.0 is taken
  // as 0.0). Returns false when a new position would exceed the limit.
  bool add(const float p[3], uint32_t* index) {
    uint32_t key[3];
    for (int k = 0; k < 3; ++k) {
      float f = p[k] == 0.0f ? 0.0f : p[k];
      std::memcpy(&key[k], &f, sizeof f);
    }
    if ((count_ + 1) * 2 > slots_.size()) grow();
    size_t mask = slots_.size() - 1;
    for (size_t at = hash(key) & mask;; at = (at + 1) & mask) {
      uint32_t v = slots_[at];
      if (v == kEmptySlot) {
        if (count_ >= kMaxVertices) return false;
        slots_[at] = static_cast<uint32_t>(count_);
        keys_.insert(keys_.end(), key, key + 3);
        *index = static_cast<uint32_t>(count_++);
        return true;
      }
      if (std::memcmp(&keys_[3 * size_t{v}], key, sizeof key) == 0) {
        *index = v;
        return true;
      }
    }
  }

  size_t size() const { return count_; }
  // Position `i` as floats.
  void position(size_t i, double out[3]) const {
    for (int k = 0; k < 3; ++k) {
      float f;
      std::memcpy(&f, &keys_[3 * i + k], sizeof f);
      out[k] = f;
    }
  }
  void release() {
    std::vector<uint32_t>().swap(slots_);
  }
  void clear() {
    release();
    std::vector<uint32_t>().swap(keys_);
    count_ = 0;
  }

 private:
  static uint64_t hash(const uint32_t k[3]) {
    uint64_t h = k[0] * 0x9E3779B97F4A7C15ull ^ k[1] * 0xC2B2AE3D27D4EB4Full ^ k[2] * 0x165667B19E3779F9ull;
    h ^= h >> 31;
    h *= 0xBF58476D1CE4E5B9ull;
    h ^= h >> 29;
    return h;
  }

  void grow() {
    size_t n = slots_.empty() ? 1024 : slots_.size() * 2;
    slots_.assign(n, kEmptySlot);
    size_t mask = n - 1;
    for (size_t i = 0; i < count_; ++i) {
      size_t at = hash(&keys_[3 * i]) & mask;
      while (slots_[at] != kEmptySlot) at = (at + 1) & mask;
      slots_[at] = static_cast<uint32_t>(i);
    }
  }

  std::vector<uint32_t> slots_;
  std::vector<uint32_t> keys_;  // 3 float bit patterns per position
  size_t count_ = 0;
};

// Whitespace-separated tokens of a text input across lines, with the line
// of each. A token is valid until the next call.
class Tokenizer {
 public:
  explicit Tokenizer(InputStream* in) : in_(in) {}

  // Sets *tok, or *end at the end of the input. Errors: kLimit, kIo.
  Status next(std::string_view* tok, bool* end) {
    for (;;) {
      size_t i = 0;
      while (i < rest_.size() && is_blank(static_cast<unsigned char>(rest_[i]))) ++i;
      rest_.remove_prefix(i);
      if (!rest_.empty()) {
        size_t j = 0;
        while (j < rest_.size() && !is_blank(static_cast<unsigned char>(rest_[j]))) ++j;
        *tok = rest_.substr(0, j);
        rest_.remove_prefix(j);
        *end = false;
        return Status();
      }
      bool eof = false;
      Status s = in_->read_line(&rest_, &eof);
      if (!s.ok()) return Status(s.code(), s.message(), s.offset(), line_ + 1);
      if (eof) {
        *end = true;
        return Status();
      }
      ++line_;
    }
  }

  // What is left of the current line; skip_line() drops it.
  std::string_view rest_of_line() const { return rest_; }
  void skip_line() { rest_ = std::string_view(); }
  // The line of the last token (lines read so far).
  uint64_t line() const { return line_; }

 private:
  InputStream* in_;
  std::string_view rest_;
  uint64_t line_ = 0;
};

}  // namespace

bool looks_like_stl(const uint8_t* data, size_t size, int64_t total_size) {
  if (total_size >= 0 && size >= kHeaderBytes &&
      static_cast<uint64_t>(total_size) == kHeaderBytes + kTriangleBytes * le32(data + 80)) {
    return true;
  }
  if (looks_ascii(data, size)) return true;
  return total_size < 0 && size >= kHeaderBytes;
}

struct StlReader::Impl {
  InputStream* in = nullptr;
  StlEncoding encoding = StlEncoding::kBinary;
  MeshSchema schema;
  SourceReport report;
  Welder welder;
  std::vector<uint32_t> triangles;  // 3 indices each
  uint64_t corners = 0;
  size_t comment_bytes = 0;
  bool opened = false;
  Status error;  // of open(), returned by every next()
  size_t next_vertex = 0;
  size_t next_triangle = 0;

  Status read_binary();
  Status read_ascii();
  void keep_comment(std::string_view text);
  // Welds the corners `v` (9 floats) into a triangle; false at the limit.
  bool add_triangle(const float v[9]) {
    uint32_t idx[3];
    for (int c = 0; c < 3; ++c) {
      if (!welder.add(v + 3 * c, &idx[c])) return false;
    }
    triangles.insert(triangles.end(), idx, idx + 3);
    corners += 3;
    return true;
  }
  Status limit(uint64_t offset, uint64_t line) const {
    return Status(ErrorCode::kLimit, "more than 4294967295 distinct vertices", offset, line);
  }
};

void StlReader::Impl::keep_comment(std::string_view text) {
  while (!text.empty() && is_blank(static_cast<unsigned char>(text.front()))) text.remove_prefix(1);
  while (!text.empty() && is_blank(static_cast<unsigned char>(text.back()))) text.remove_suffix(1);
  if (text.empty() || schema.comments.size() >= kMaxComments) return;
  for (char c : text) {
    if (static_cast<unsigned char>(c) < 0x20 || static_cast<unsigned char>(c) >= 0x7f) return;  // not printable
  }
  if (comment_bytes + text.size() > kMaxCommentBytes) return;
  comment_bytes += text.size();
  schema.comments.emplace_back(text);
}

Status StlReader::Impl::read_binary() {
  size_t avail = 0;
  PSQ_RETURN_IF_ERROR(in->fill(kHeaderBytes, &avail));
  if (avail < kHeaderBytes) {
    return Status(ErrorCode::kTruncated,
                  "binary STL ends inside its 84-byte header (" + std::to_string(avail) + " bytes)",
                  in->offset() + avail);
  }
  const uint8_t* head = in->cursor();
  const uint64_t count = le32(head + 80);
  size_t text = 80;
  while (text > 0 && (head[text - 1] == 0 || head[text - 1] == ' ')) --text;
  keep_comment(std::string_view(reinterpret_cast<const char*>(head), text));
  const uint64_t start = in->offset();
  in->advance(kHeaderBytes);

  // With a known size the count is checked before anything is allocated.
  const uint64_t expected = kHeaderBytes + kTriangleBytes * count;
  if (in->size() >= 0) {
    uint64_t size = static_cast<uint64_t>(in->size()) - start;
    if (size < expected) {
      return Status(ErrorCode::kTruncated,
                    "header declares " + std::to_string(count) + " triangles (" + std::to_string(expected) +
                        " bytes) but the input has " + std::to_string(size) + " bytes",
                    start + 80);
    }
    if (size > expected) {
      return Status(ErrorCode::kBadValue, std::to_string(size - expected) + " bytes after the last triangle",
                    start + expected);
    }
    triangles.reserve(3 * count);
  }

  uint64_t nonzero_attributes = 0;
  for (uint64_t t = 0; t < count; ++t) {
    PSQ_RETURN_IF_ERROR(in->fill(kTriangleBytes, &avail));
    if (avail < kTriangleBytes) {
      return Status(ErrorCode::kTruncated,
                    "input ends inside triangle " + std::to_string(t) + " of " + std::to_string(count),
                    in->offset() + avail);
    }
    const uint8_t* p = in->cursor();
    float v[9];
    for (int k = 0; k < 9; ++k) {
      v[k] = le_float(p + 12 + 4 * k);
      if (!std::isfinite(v[k])) {
        return Status(ErrorCode::kBadValue, "triangle " + std::to_string(t) + ": vertex coordinate is not finite",
                      in->offset());
      }
    }
    if (p[48] != 0 || p[49] != 0) ++nonzero_attributes;
    if (!add_triangle(v)) return limit(in->offset(), Status::kNoPlace);
    in->advance(kTriangleBytes);
  }
  bool end = false;
  PSQ_RETURN_IF_ERROR(in->at_end(&end));
  if (!end) return Status(ErrorCode::kBadValue, "data after the last triangle", in->offset());
  if (nonzero_attributes > 0) {
    report.notes.push_back(std::to_string(nonzero_attributes) + " non-zero attribute words ignored");
  }
  return Status();
}

Status StlReader::Impl::read_ascii() {
  Tokenizer tz(in);
  std::string_view tok;
  bool end = false;
  uint64_t facet = 0;  // facets read so far: the number of the current one

  uint64_t solid_line = 0;
  // The next token, which must exist: inside a facet, or else inside a
  // solid (messages are built only on failure).
  auto next = [&](bool in_facet) -> Status {
    PSQ_RETURN_IF_ERROR(tz.next(&tok, &end));
    if (!end) return Status();
    std::string where = in_facet ? "inside facet " + std::to_string(facet)
                                 : "inside the solid of line " + std::to_string(solid_line) + " (no endsolid)";
    return Status(ErrorCode::kTruncated, "input ends " + where, Status::kNoPlace, tz.line() + 1);
  };
  auto facet_error = [&](const std::string& m, uint64_t line) {
    return Status(ErrorCode::kBadValue, "facet " + std::to_string(facet) + ": " + m, Status::kNoPlace, line);
  };
  auto expect = [&](const char* word) -> Status {
    PSQ_RETURN_IF_ERROR(next(true));
    if (!iequals(tok, word)) return facet_error("expected '" + std::string(word) + "', found " + quoted(tok), tz.line());
    return Status();
  };
  // Three numbers after `keyword` (read at `line`) into `out`; a vertex's
  // must be finite floats, a normal's anything numeric (it is dropped).
  auto numbers = [&](const char* keyword, uint64_t line, float* out) -> Status {
    bool vertex = out != nullptr;
    for (int k = 0; k < 3; ++k) {
      PSQ_RETURN_IF_ERROR(next(true));
      float f = 0;
      Parse p = parse_float(tok, &f);
      if (p == Parse::kMalformed) {
        return facet_error("'" + std::string(keyword) + "' needs 3 numbers; found " + std::to_string(k) + ", then " +
                               quoted(tok),
                           line);
      }
      if (!vertex) continue;
      if (p == Parse::kOutOfRange) return facet_error("vertex coordinate " + quoted(tok) + " is beyond float range", line);
      if (!std::isfinite(f)) return facet_error("vertex coordinate " + quoted(tok) + " is not finite", line);
      out[k] = f;
    }
    return Status();
  };

  PSQ_RETURN_IF_ERROR(tz.next(&tok, &end));
  if (end || !iequals(tok, "solid")) {
    return Status(ErrorCode::kBadHeader, "not an ascii STL file (no 'solid' at the start)", Status::kNoPlace,
                  end ? 1 : tz.line());
  }
  for (;;) {
    // `tok` is "solid": the rest of its line is the name.
    keep_comment(tz.rest_of_line());
    tz.skip_line();
    solid_line = tz.line();
    for (;;) {
      PSQ_RETURN_IF_ERROR(next(false));
      if (iequals(tok, "endsolid")) {
        tz.skip_line();
        break;
      }
      if (!iequals(tok, "facet")) {
        return Status(ErrorCode::kBadValue, "expected 'facet' or 'endsolid', found " + quoted(tok), Status::kNoPlace,
                      tz.line());
      }
      PSQ_RETURN_IF_ERROR(next(true));
      if (iequals(tok, "normal")) {
        PSQ_RETURN_IF_ERROR(numbers("normal", tz.line(), nullptr));
        PSQ_RETURN_IF_ERROR(next(true));
      }
      if (!iequals(tok, "outer")) return facet_error("expected 'outer', found " + quoted(tok), tz.line());
      PSQ_RETURN_IF_ERROR(expect("loop"));
      float v[9];
      int n = 0;
      for (;;) {
        PSQ_RETURN_IF_ERROR(next(true));
        if (iequals(tok, "endloop")) break;
        if (!iequals(tok, "vertex")) {
          return facet_error("expected 'vertex' or 'endloop', found " + quoted(tok), tz.line());
        }
        if (n == 3) return facet_error("more than 3 vertices (STL facets are triangles)", tz.line());
        PSQ_RETURN_IF_ERROR(numbers("vertex", tz.line(), v + 3 * n));
        ++n;
      }
      if (n < 3) return facet_error(std::to_string(n) + " vertices; STL facets have 3", tz.line());
      PSQ_RETURN_IF_ERROR(expect("endfacet"));
      if (!add_triangle(v)) return limit(Status::kNoPlace, tz.line());
      ++facet;
    }
    PSQ_RETURN_IF_ERROR(tz.next(&tok, &end));
    if (end) break;
    if (!iequals(tok, "solid")) {
      return Status(ErrorCode::kBadValue, "expected 'solid' or the end of the input after 'endsolid', found " + quoted(tok),
                    Status::kNoPlace, tz.line());
    }
  }
  return Status();
}

StlReader::StlReader() = default;
StlReader::~StlReader() = default;

Status StlReader::open(InputStream* in) {
  impl_ = std::make_unique<Impl>();
  Impl& m = *impl_;
  m.in = in;
  size_t avail = 0;
  Status s = in->fill(kSniffBytes, &avail);
  if (!s.ok()) {
    m.error = s;
    return s;
  }
  const uint8_t* data = in->cursor();
  bool exact_binary = in->size() >= 0 && avail >= kHeaderBytes &&
                      static_cast<uint64_t>(in->size()) - in->offset() == kHeaderBytes + kTriangleBytes * le32(data + 80);
  m.encoding = !exact_binary && looks_ascii(data, avail) ? StlEncoding::kAscii : StlEncoding::kBinary;
  s = m.encoding == StlEncoding::kAscii ? m.read_ascii() : m.read_binary();
  m.welder.release();
  if (!s.ok()) {
    m.welder.clear();
    std::vector<uint32_t>().swap(m.triangles);
    m.error = s;
    return s;
  }
  m.schema.position_type = ScalarType::kFloat32;
  m.schema.vertex_count = static_cast<int64_t>(m.welder.size());
  m.schema.triangle_count = static_cast<int64_t>(m.triangles.size() / 3);
  if (!m.triangles.empty()) {
    m.report.notes.insert(m.report.notes.begin(), "facet normals not carried: psq computes none");
    m.report.notes.insert(m.report.notes.begin(), std::to_string(m.corners) + " corners welded into " +
                                                      std::to_string(m.welder.size()) +
                                                      " vertices by exact position");
  }
  m.in = nullptr;
  m.opened = true;
  return Status();
}

StlEncoding StlReader::encoding() const { return impl_ ? impl_->encoding : StlEncoding::kBinary; }

const MeshSchema& StlReader::schema() const {
  static const MeshSchema kEmpty;
  return impl_ ? impl_->schema : kEmpty;
}

const SourceReport& StlReader::report() const {
  static const SourceReport kEmpty;
  return impl_ ? impl_->report : kEmpty;
}

Status StlReader::next(MeshItem* item) {
  if (!impl_) return Status(ErrorCode::kUsage, "StlReader::next before open");
  Impl& m = *impl_;
  if (!m.opened) return m.error;
  item->values.clear();
  if (m.next_vertex < m.welder.size()) {
    item->kind = MeshItem::Kind::kVertex;
    m.welder.position(m.next_vertex++, item->position);
    return Status();
  }
  if (3 * m.next_triangle < m.triangles.size()) {
    item->kind = MeshItem::Kind::kTriangle;
    for (int k = 0; k < 3; ++k) item->index[k] = m.triangles[3 * m.next_triangle + k];
    ++m.next_triangle;
    return Status();
  }
  item->kind = MeshItem::Kind::kEnd;
  return Status();
}

}  // namespace psq
