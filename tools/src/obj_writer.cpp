// ObjWriter: writing an indexed mesh as Wavefront OBJ text, streaming (see
// psq/obj.h for which properties OBJ can hold).

#include <charconv>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "psq/obj.h"

namespace psq {
namespace {

// Room for one vertex's v, vn and vt lines or one f line: a number takes at
// most 24 characters.
constexpr size_t kLineBuffer = 512;

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

char* put_index(char* p, uint32_t index) {
  return std::to_chars(p, p + 16, uint64_t{index} + 1).ptr;  // OBJ counts from 1
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
  size_t property_count = 0;
  bool has_list = false;        // offsets of values vary per vertex
  std::vector<bool> is_list;    // per vertex property
  std::vector<size_t> offsets;  // of each vertex property in its values
  std::vector<std::string> dropped;
  char line[kLineBuffer];

  double value(const PropertyValues& values, const Slot& s) const { return values[offsets[s.property]]; }
};

ObjWriter::ObjWriter(OutputFile* out) : impl_(std::make_unique<Impl>()) { impl_->out = out; }
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

  std::vector<bool> written(props.size(), false);
  if (w.has_colour) for (const Slot& s : w.colour) written[s.property] = true;
  if (w.has_normal) for (const Slot& s : w.normal) written[s.property] = true;
  if (w.has_texcoord) for (const Slot& s : w.texcoord) written[s.property] = true;
  w.dropped.clear();
  for (size_t i = 0; i < props.size(); ++i) {
    if (!written[i]) w.dropped.push_back(props[i].name);
  }
  for (const Property& p : schema.face_properties) w.dropped.push_back(p.name);

  w.property_count = props.size();
  w.has_list = false;
  w.is_list.assign(props.size(), false);
  for (size_t i = 0; i < props.size(); ++i) {
    w.is_list[i] = props[i].is_list;
    w.has_list = w.has_list || props[i].is_list;
  }
  w.offsets.resize(props.size());
  for (size_t i = 0; i < props.size(); ++i) w.offsets[i] = i;

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
  if (w.has_list) {
    // A list before a property moves its value by the list's length.
    size_t at = 0;
    for (size_t i = 0; i < w.property_count; ++i) {
      if (at >= values.size()) return Status(ErrorCode::kInternal, "vertex values do not match the schema");
      w.offsets[i] = at++;
      if (w.is_list[i]) {
        double n = values[at - 1];
        if (!(n >= 0) || n > static_cast<double>(values.size() - at)) {
          return Status(ErrorCode::kInternal, "vertex values do not match the schema");
        }
        at += static_cast<size_t>(n);
      }
    }
  } else if (values.size() < w.property_count) {
    return Status(ErrorCode::kInternal, "vertex values do not match the schema");
  }
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

Status ObjWriter::triangle(const uint32_t index[3], const PropertyValues& /*values*/) {
  Impl& w = *impl_;
  char* p = w.line;
  p = put_text(p, "f");
  for (int k = 0; k < 3; ++k) {
    *p++ = ' ';
    p = put_index(p, index[k]);
    // Each vertex has its own vt and vn, numbered like the vertex.
    if (w.has_texcoord || w.has_normal) {
      *p++ = '/';
      if (w.has_texcoord) p = put_index(p, index[k]);
      if (w.has_normal) {
        *p++ = '/';
        p = put_index(p, index[k]);
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
