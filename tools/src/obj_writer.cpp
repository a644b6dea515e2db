// SPDX-License-Identifier: Apache-2.0
// ObjWriter: writing an indexed mesh as Wavefront OBJ text, streaming (see
// psq/obj.h for which properties OBJ can hold).

#include <charconv>
#include <cmath>
#include <limits>
#include <cstdint>
#include <cstring>
#include <string>
#include <string_view>
#include <vector>

#include "psq/obj.h"

namespace psq {
namespace {

// Room for one vertex's v, vn and vt lines, or for one triangle's three vn,
// three vt and one f line: a number takes at most 25 characters with its
// space, an index 20.
constexpr size_t kLineBuffer = 1024;

// How a written value is converted from the property's own value.
enum class Conversion { kFloat, kDouble, kByteColour, kShortColour };

struct Slot {
  int property = -1;  // index in the schema's vertex properties
  Conversion conversion = Conversion::kFloat;
};

int find_scalar(const std::vector<Property>& props, std::string_view name) {
  for (size_t i = 0; i < props.size(); ++i) {
    if (!props[i].is_list && props[i].name == name) return static_cast<int>(i);
  }
  return -1;
}

bool float_conversion(ScalarType t, Conversion* c) {
  if (t == ScalarType::kFloat32) *c = Conversion::kFloat;
  else if (t == ScalarType::kFloat64) *c = Conversion::kDouble;
  else return false;
  return true;
}

// OBJ colours are in [0, 1]; integer colours are scaled from their range.
bool colour_conversion(ScalarType t, Conversion* c) {
  if (t == ScalarType::kUInt8) *c = Conversion::kByteColour;
  else if (t == ScalarType::kUInt16) *c = Conversion::kShortColour;
  else return float_conversion(t, c);
  return true;
}

// Finds all of `names` with acceptable types, or none.
template <size_t N>
bool find_slots(const std::vector<Property>& props, const char* const (&names)[N],
                bool (*convert)(ScalarType, Conversion*), Slot (&slots)[N]) {
  Slot found[N];
  for (size_t k = 0; k < N; ++k) {
    found[k].property = find_scalar(props, names[k]);
    if (found[k].property < 0) return false;
    if (!convert(props[found[k].property].type, &found[k].conversion)) return false;
  }
  for (size_t k = 0; k < N; ++k) slots[k] = found[k];
  return true;
}

// Where each property's value (or list count) sits in an element's values:
// a list moves every property after it by its length.
class Layout {
 public:
  void reset(const std::vector<Property>& props) {
    is_list_.assign(props.size(), false);
    has_list_ = false;
    for (size_t i = 0; i < props.size(); ++i) {
      is_list_[i] = props[i].is_list;
      has_list_ = has_list_ || props[i].is_list;
    }
    offsets_.resize(props.size());
    for (size_t i = 0; i < props.size(); ++i) offsets_[i] = i;
  }

  // False when `values` is too short for the schema.
  bool locate(const PropertyValues& values) {
    if (!has_list_) return values.size() >= offsets_.size();
    size_t at = 0;
    for (size_t i = 0; i < offsets_.size(); ++i) {
      if (at >= values.size()) return false;
      offsets_[i] = at++;
      if (is_list_[i]) {
        double n = values[at - 1];
        if (!(n >= 0) || n > static_cast<double>(values.size() - at)) return false;
        at += static_cast<size_t>(n);
      }
    }
    return true;
  }

  size_t offset(int property) const { return offsets_[static_cast<size_t>(property)]; }

 private:
  std::vector<bool> is_list_;
  bool has_list_ = false;
  std::vector<size_t> offsets_;
};

// A face list property with one attribute per corner, as ObjReader makes
// them: corner_normals (nx ny nz per corner, written as vn lines) or
// corner_uv (u v per corner, written as vt lines).
struct CornerSlot {
  const char* name = "";
  const char* keyword = "";
  size_t arity = 0;
  int property = -1;  // index in the schema's face properties, or none
  Conversion conversion = Conversion::kFloat;
  uint64_t lines = 0;      // vn or vt lines written so far
  double last[3] = {0, 0, 0};  // the values of the last one

  bool active() const { return property >= 0; }

  void find(const std::vector<Property>& props) {
    property = -1;
    lines = 0;
    for (size_t i = 0; i < props.size(); ++i) {
      if (props[i].is_list && props[i].name == name && float_conversion(props[i].type, &conversion)) {
        property = static_cast<int>(i);
        return;
      }
    }
  }
};

// Whether `v` can be written with conversion `c` without a finite value
// overflowing to an infinity (NaN and infinities are written as they are).
bool fits(double v, Conversion c) {
  return c != Conversion::kFloat || !(std::fabs(v) > std::numeric_limits<float>::max()) || std::isinf(v);
}

// A double for a message: the shortest text that reads back to it.
std::string number_text(double v) {
  char buf[32];
  auto r = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, r.ptr);
}

Status beyond_float(const char* what, uint64_t index, double v) {
  return Status(ErrorCode::kBadValue, std::string(what) + " " + std::to_string(index) + ": " + number_text(v) +
                                          " is beyond float range");
}

// Shortest text that reads back to the same float or double: float data
// round-trips bit-exactly and the files stay small.
char* put_number(char* p, double v, Conversion c) {
  *p++ = ' ';
  switch (c) {
    case Conversion::kFloat: return std::to_chars(p, p + 32, static_cast<float>(v)).ptr;
    case Conversion::kDouble: return std::to_chars(p, p + 32, v).ptr;
    case Conversion::kByteColour: return std::to_chars(p, p + 32, static_cast<float>(v / 255.0)).ptr;
    case Conversion::kShortColour: return std::to_chars(p, p + 32, static_cast<float>(v / 65535.0)).ptr;
  }
  return p;
}

char* put_text(char* p, std::string_view s) {
  for (char c : s) *p++ = c;
  return p;
}

char* put_index(char* p, uint64_t index) {
  return std::to_chars(p, p + 24, index + 1).ptr;  // OBJ counts from 1
}

// Writes the vn or vt lines of a triangle's corners at `*p` and sets `ids`
// to the (0-based) line each corner refers to. A corner equal to the line
// written last reuses it, so a flat-shaded face costs one line, not three.
Status put_corners(CornerSlot& c, const PropertyValues& values, size_t at, char** p, uint64_t ids[3]) {
  size_t n = 3 * c.arity;
  if (values[at] != static_cast<double>(n)) {
    return Status(ErrorCode::kInternal, std::string(c.name) + " of a triangle does not have " +
                                            std::to_string(n) + " values");
  }
  for (size_t k = 0; k < 3; ++k) {
    double v[3] = {0, 0, 0};
    for (size_t j = 0; j < c.arity; ++j) {
      double x = values[at + 1 + c.arity * k + j];
      if (!fits(x, c.conversion)) return beyond_float(c.name, c.lines, x);
      v[j] = c.conversion == Conversion::kFloat ? static_cast<double>(static_cast<float>(x)) : x;
    }
    if (c.lines > 0 && std::memcmp(v, c.last, sizeof v) == 0) {
      ids[k] = c.lines - 1;
      continue;
    }
    *p = put_text(*p, c.keyword);
    for (size_t j = 0; j < c.arity; ++j) *p = put_number(*p, v[j], c.conversion);
    *(*p)++ = '\n';
    std::memcpy(c.last, v, sizeof v);
    ids[k] = c.lines++;
  }
  return Status();
}

}  // namespace

struct ObjWriter::Impl {
  OutputFile* out = nullptr;
  Conversion position = Conversion::kFloat;
  Slot colour[3];
  Slot normal[3];
  Slot texcoord[2];
  bool has_colour = false;
  bool has_normal = false;
  bool has_texcoord = false;
  CornerSlot corner_normal;
  CornerSlot corner_uv;
  Layout vertex_layout;
  Layout face_layout;
  std::vector<std::string> dropped;
  std::vector<const Slot*> written;  // the colour, normal and texcoord slots in use
  uint64_t vertices = 0;             // written so far
  char line[kLineBuffer];

  double value(const PropertyValues& values, const Slot& s) const {
    return values[vertex_layout.offset(s.property)];
  }
};

ObjWriter::ObjWriter(OutputFile* out) : impl_(std::make_unique<Impl>()) {
  impl_->out = out;
  impl_->corner_normal.name = "corner_normals";
  impl_->corner_normal.keyword = "vn";
  impl_->corner_normal.arity = 3;
  impl_->corner_uv.name = "corner_uv";
  impl_->corner_uv.keyword = "vt";
  impl_->corner_uv.arity = 2;
}

ObjWriter::~ObjWriter() = default;

Status ObjWriter::begin(const MeshSchema& schema) {
  Impl& w = *impl_;
  const std::vector<Property>& props = schema.vertex_properties;
  w.position = schema.position_type == ScalarType::kFloat64 ? Conversion::kDouble : Conversion::kFloat;
  static const char* const kColour[] = {"red", "green", "blue"};
  static const char* const kNormal[] = {"nx", "ny", "nz"};
  static const char* const kTexcoords[][2] = {{"u", "v"}, {"s", "t"}, {"texture_u", "texture_v"}};
  w.has_colour = find_slots(props, kColour, colour_conversion, w.colour);
  w.has_normal = find_slots(props, kNormal, float_conversion, w.normal);
  w.has_texcoord = false;
  for (const auto& names : kTexcoords) {
    if (find_slots(props, names, float_conversion, w.texcoord)) {
      w.has_texcoord = true;
      break;
    }
  }
  // An OBJ corner has one normal and one texture coordinate: per-vertex
  // ones win over per-corner ones.
  w.corner_normal.find(schema.face_properties);
  if (w.has_normal) w.corner_normal.property = -1;
  w.corner_uv.find(schema.face_properties);
  if (w.has_texcoord) w.corner_uv.property = -1;

  std::vector<bool> written(props.size(), false);
  if (w.has_colour) for (const Slot& s : w.colour) written[s.property] = true;
  if (w.has_normal) for (const Slot& s : w.normal) written[s.property] = true;
  if (w.has_texcoord) for (const Slot& s : w.texcoord) written[s.property] = true;
  w.dropped.clear();
  for (size_t i = 0; i < props.size(); ++i) {
    if (!written[i]) w.dropped.push_back(props[i].name);
  }
  for (size_t i = 0; i < schema.face_properties.size(); ++i) {
    int index = static_cast<int>(i);
    if (index == w.corner_normal.property || index == w.corner_uv.property) continue;
    w.dropped.push_back(schema.face_properties[i].name);
  }

  w.written.clear();
  if (w.has_colour) for (const Slot& s : w.colour) w.written.push_back(&s);
  if (w.has_normal) for (const Slot& s : w.normal) w.written.push_back(&s);
  if (w.has_texcoord) for (const Slot& s : w.texcoord) w.written.push_back(&s);
  w.vertices = 0;
  w.vertex_layout.reset(props);
  w.face_layout.reset(schema.face_properties);

  // The reader keeps leading comments; "psq" is this line, not repeated.
  std::string header = "# psq\n";
  for (const std::string& c : schema.comments) {
    if (c == "psq") continue;
    header += "# ";
    for (char ch : c) header += (ch == '\n' || ch == '\r') ? ' ' : ch;
    header += '\n';
  }
  return w.out->write(header);
}

Status ObjWriter::vertex(const double position[3], const PropertyValues& values) {
  Impl& w = *impl_;
  if (!w.vertex_layout.locate(values)) return Status(ErrorCode::kInternal, "vertex values do not match the schema");
  for (int k = 0; k < 3; ++k)
    if (!fits(position[k], w.position)) return beyond_float("vertex", w.vertices, position[k]);
  for (const Slot* s : w.written)
    if (!fits(w.value(values, *s), s->conversion)) return beyond_float("vertex", w.vertices, w.value(values, *s));
  ++w.vertices;
  char* p = w.line;
  p = put_text(p, "v");
  for (int k = 0; k < 3; ++k) p = put_number(p, position[k], w.position);
  if (w.has_colour) {
    for (const Slot& s : w.colour) p = put_number(p, w.value(values, s), s.conversion);
  }
  *p++ = '\n';
  if (w.has_normal) {
    p = put_text(p, "vn");
    for (const Slot& s : w.normal) p = put_number(p, w.value(values, s), s.conversion);
    *p++ = '\n';
  }
  if (w.has_texcoord) {
    p = put_text(p, "vt");
    for (const Slot& s : w.texcoord) p = put_number(p, w.value(values, s), s.conversion);
    *p++ = '\n';
  }
  return w.out->write(w.line, static_cast<size_t>(p - w.line));
}

Status ObjWriter::triangle(const uint32_t index[3], const PropertyValues& values) {
  Impl& w = *impl_;
  char* p = w.line;
  // Per-vertex attributes are numbered like the vertex; per-corner ones get
  // lines of their own, written just before the face.
  uint64_t t[3] = {index[0], index[1], index[2]};
  uint64_t n[3] = {index[0], index[1], index[2]};
  if (w.corner_normal.active() || w.corner_uv.active()) {
    if (!w.face_layout.locate(values)) return Status(ErrorCode::kInternal, "triangle values do not match the schema");
    if (w.corner_normal.active()) {
      PSQ_RETURN_IF_ERROR(put_corners(w.corner_normal, values, w.face_layout.offset(w.corner_normal.property), &p, n));
    }
    if (w.corner_uv.active()) {
      PSQ_RETURN_IF_ERROR(put_corners(w.corner_uv, values, w.face_layout.offset(w.corner_uv.property), &p, t));
    }
  }
  bool with_t = w.has_texcoord || w.corner_uv.active();
  bool with_n = w.has_normal || w.corner_normal.active();
  p = put_text(p, "f");
  for (int k = 0; k < 3; ++k) {
    *p++ = ' ';
    p = put_index(p, index[k]);
    if (with_t || with_n) {
      *p++ = '/';
      if (with_t) p = put_index(p, t[k]);
      if (with_n) {
        *p++ = '/';
        p = put_index(p, n[k]);
      }
    }
  }
  *p++ = '\n';
  return w.out->write(w.line, static_cast<size_t>(p - w.line));
}

// The owner of the OutputFile commits it; everything is already written.
Status ObjWriter::finish() { return Status(); }

const std::vector<std::string>& ObjWriter::dropped() const { return impl_->dropped; }

}  // namespace psq
