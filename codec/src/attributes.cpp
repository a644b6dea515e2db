// SPDX-License-Identifier: Apache-2.0
// codec/src/attributes.cpp: see attributes.h and spec/psq-format.md 8.3
// and 8.4. Normals on the octahedron as in Meyer, Sherman and Strzodka,
// "On floating-point normal vectors" (EGSR 2010) and Cigolle et al., "A
// survey of efficient representations for independent unit vectors"
// (JCGT 2014), predicted by the area-weighted normal of the vertex's
// triangles (as Draco's decoder, which has all connectivity first,
// predicts them), coded once the streaming decoder has those triangles;
// texture coordinates
// predicted by the new vertex's place beside the gate edge in space,
// carried into the texture (as Draco's texture coordinate predictor does),
// else by the parallelogram in texture space as in Isenburg and Snoeyink,
// "Compressing texture coordinates with selective linear predictions" (CGI
// 2003); residuals coded as signed residuals of the range coder (spec
// 5.6) with the adaptive back-end, as length symbols and raw bits (13.8.3,
// 13.8.4) with the rANS back-end.
#include "attributes.h"

#include <algorithm>
#include <cmath>
#include <initializer_list>
#include <string>

#include "container.h"
#include "records.h"
#include "geometry.h"

namespace psq {
namespace codec {
namespace {

bool is_real(const Property& p) {
  return !p.is_list && (p.type == ScalarType::kFloat32 || p.type == ScalarType::kFloat64);
}
bool is_byte(const Property& p) { return !p.is_list && p.type == ScalarType::kUInt8; }
bool is_real_list(const Property& p) {
  return p.is_list && (p.type == ScalarType::kFloat32 || p.type == ScalarType::kFloat64);
}

int find(const std::vector<Property>& props, const char* name) {
  for (size_t i = 0; i < props.size(); ++i)
    if (props[i].name == name) return static_cast<int>(i);
  return -1;
}

// The indices of the named properties when all exist and pass `ok`.
template <class Ok>
bool find_all(const std::vector<Property>& props, std::initializer_list<const char*> names, Ok ok,
              std::vector<uint32_t>* out) {
  out->clear();
  for (const char* n : names) {
    const int i = find(props, n);
    if (i < 0 || !ok(props[static_cast<size_t>(i)])) return false;
    out->push_back(static_cast<uint32_t>(i));
  }
  return true;
}

int64_t mid(int64_t a, int64_t b) { return (a >> 1) + (b >> 1) + (a & b & 1); }

// The distance of two values, modulo `mod` when it is not 0.
uint64_t distance(int64_t a, int64_t b, int64_t mod) {
  const uint64_t d = static_cast<uint64_t>(a > b ? a - b : b - a);
  return mod != 0 ? std::min<uint64_t>(d, static_cast<uint64_t>(mod) - d) : d;
}

int components_of(CodedAttribute::Kind k) {
  return k == CodedAttribute::Kind::kNormal ? 3 : k == CodedAttribute::Kind::kTexcoord ? 2 : 0;
}

}  // namespace

std::vector<CodedAttribute> recognize_attributes(const MeshSchema& schema, int normal_bits, int uv_bits) {
  const std::vector<Property>& vertex = schema.vertex_properties;
  std::vector<CodedAttribute> out;
  CodedAttribute a;
  if (normal_bits > 0 && find_all(vertex, {"nx", "ny", "nz"}, is_real, &a.properties)) {
    a.kind = CodedAttribute::Kind::kNormal;
    a.bits = normal_bits;
    out.push_back(a);
  }
  if (uv_bits > 0) {
    for (auto names : {std::initializer_list<const char*>{"u", "v"}, {"s", "t"}, {"texture_u", "texture_v"},
                       {"texture_s", "texture_t"}})
      if (find_all(vertex, names, is_real, &a.properties)) {
        a.kind = CodedAttribute::Kind::kTexcoord;
        a.bits = uv_bits;
        out.push_back(a);
        break;
      }
  }
  for (auto names : {std::initializer_list<const char*>{"red", "green", "blue"}, {"r", "g", "b"}})
    if (find_all(vertex, names, is_byte, &a.properties)) {
      const int alpha = find(vertex, names.size() && std::string(*names.begin()) == "red" ? "alpha" : "a");
      if (alpha >= 0 && is_byte(vertex[static_cast<size_t>(alpha)])) a.properties.push_back(static_cast<uint32_t>(alpha));
      a.kind = CodedAttribute::Kind::kColor;
      a.bits = 8;
      out.push_back(a);
      break;
    }
  // Spec 8.5: per corner, as the OBJ reader names them.
  const int cn = find(schema.face_properties, "corner_normals");
  if (normal_bits > 0 && cn >= 0 && is_real_list(schema.face_properties[static_cast<size_t>(cn)]))
    out.push_back(CodedAttribute{CodedAttribute::Kind::kCornerNormal, normal_bits, {static_cast<uint32_t>(cn)}});
  const int cu = find(schema.face_properties, "corner_uv");
  if (uv_bits > 0 && cu >= 0 && is_real_list(schema.face_properties[static_cast<size_t>(cu)]))
    out.push_back(CodedAttribute{CodedAttribute::Kind::kCornerTexcoord, uv_bits, {static_cast<uint32_t>(cu)}});
  return out;
}

bool rotation_kept(const MeshSchema& schema, const std::vector<CodedAttribute>& attrs) {
  size_t corner = 0;
  for (const CodedAttribute& a : attrs) corner += a.per_corner();
  return schema.face_properties.size() > corner;
}

std::string attribute_table_error(const MeshSchema& schema, const std::vector<CodedAttribute>& attrs) {
  const std::vector<Property>& vertex = schema.vertex_properties;
  const std::vector<Property>& face = schema.face_properties;
  std::vector<bool> used(vertex.size(), false), face_used(face.size(), false);
  bool kind_seen[6] = {false, false, false, false, false, false};
  for (const CodedAttribute& a : attrs) {
    const int k = static_cast<int>(a.kind);
    if (k < 1 || k > 5) return "attribute kind " + std::to_string(k) + " is unknown";
    if (kind_seen[k]) return "attribute kind " + std::to_string(k) + " appears twice";
    kind_seen[k] = true;
    const size_t n = a.properties.size();
    if (a.per_corner()) {
      const int hi = a.kind == CodedAttribute::Kind::kCornerNormal ? 16 : 24;
      if (n != 1) return "corner attribute of kind " + std::to_string(k) + " has " + std::to_string(n) + " components";
      if (a.bits < (hi == 16 ? 2 : 1) || a.bits > hi)
        return "attribute of kind " + std::to_string(k) + " has bits " + std::to_string(a.bits);
      const uint32_t i = a.properties[0];
      if (i >= face.size()) return "corner attribute component " + std::to_string(i) + " is not a face property";
      if (face_used[i]) return "face property '" + face[i].name + "' is in two corner attributes";
      face_used[i] = true;
      if (!is_real_list(face[i])) return "face property '" + face[i].name + "' is no float or double list";
      continue;
    }
    const bool color = a.kind == CodedAttribute::Kind::kColor;
    if (color ? n != 3 && n != 4 : n != static_cast<size_t>(components_of(a.kind)))
      return "attribute of kind " + std::to_string(k) + " has " + std::to_string(n) + " components";
    const int lo = color ? 8 : a.kind == CodedAttribute::Kind::kNormal ? 2 : 1;
    const int hi = color ? 8 : a.kind == CodedAttribute::Kind::kNormal ? 16 : 24;
    if (a.bits < lo || a.bits > hi)
      return "attribute of kind " + std::to_string(k) + " has bits " + std::to_string(a.bits) + " not in " +
             std::to_string(lo) + ".." + std::to_string(hi);
    for (uint32_t i : a.properties) {
      if (i >= vertex.size()) return "attribute component " + std::to_string(i) + " is not a vertex property";
      if (used[i]) return "vertex property '" + vertex[i].name + "' is in two attribute components";
      used[i] = true;
      if (color ? !is_byte(vertex[i]) : !is_real(vertex[i]))
        return "vertex property '" + vertex[i].name + "' has the wrong type for its attribute";
    }
  }
  return std::string();
}

void octahedral_decode(int32_t s, int32_t t, int32_t c, double out[3]) {
  // Spec 8.3, in binary64, operation by operation.
  const double cd = static_cast<double>(c);
  double x = static_cast<double>(s - c) / cd;
  double y = static_cast<double>(t - c) / cd;
  const double ax = std::fabs(x), ay = std::fabs(y);
  const double z = (1.0 - ax) - ay;
  if (z < 0) {
    const double fx = (1.0 - ay) * (x < 0 ? -1.0 : 1.0);
    const double fy = (1.0 - ax) * (y < 0 ? -1.0 : 1.0);
    x = fx;
    y = fy;
  }
  const double n = std::sqrt((x * x + y * y) + z * z);
  out[0] = x / n;
  out[1] = y / n;
  out[2] = z / n;
}

bool octahedral_round(const double n[3], int32_t c, int64_t* s, int64_t* t) {
  const double l1 = (std::fabs(n[0]) + std::fabs(n[1])) + std::fabs(n[2]);
  if (!(l1 > 0)) return false;
  double x = n[0] / l1, y = n[1] / l1;
  if (n[2] < 0) {
    const double fx = (1.0 - std::fabs(y)) * (x < 0 ? -1.0 : 1.0);
    const double fy = (1.0 - std::fabs(x)) * (y < 0 ? -1.0 : 1.0);
    x = fx;
    y = fy;
  }
  const double cd = static_cast<double>(c);
  *s = std::min<int64_t>(std::max<int64_t>(static_cast<int64_t>(std::floor(x * cd + 0.5)) + c, 0), 2 * int64_t{c});
  *t = std::min<int64_t>(std::max<int64_t>(static_cast<int64_t>(std::floor(y * cd + 0.5)) + c, 0), 2 * int64_t{c});
  return true;
}

bool octahedral_encode(const double n[3], int32_t c, int32_t* s, int32_t* t) {
  for (int i = 0; i < 3; ++i)
    if (!std::isfinite(n[i])) return false;
  const double l1 = std::fabs(n[0]) + std::fabs(n[1]) + std::fabs(n[2]);
  if (!std::isfinite(l1)) return false;
  if (l1 == 0) {  // no direction: coded as +z
    *s = *t = c;
    return true;
  }
  double x = n[0] / l1, y = n[1] / l1;
  if (n[2] < 0) {
    const double fx = (1.0 - std::fabs(y)) * (x < 0 ? -1.0 : 1.0);
    const double fy = (1.0 - std::fabs(x)) * (y < 0 ? -1.0 : 1.0);
    x = fx;
    y = fy;
  }
  // The four grid points around (x, y): the one whose normal is closest.
  const double norm = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
  const double gx = (x + 1.0) * c, gy = (y + 1.0) * c;
  const int32_t sx = static_cast<int32_t>(std::floor(gx)), sy = static_cast<int32_t>(std::floor(gy));
  double best = -2;
  for (int dx = 0; dx < 2; ++dx)
    for (int dy = 0; dy < 2; ++dy) {
      const int32_t cs = std::min(std::max(sx + dx, 0), 2 * c), ct = std::min(std::max(sy + dy, 0), 2 * c);
      double d[3];
      octahedral_decode(cs, ct, c, d);
      const double dot = (d[0] * n[0] + d[1] * n[1] + d[2] * n[2]) / norm;
      if (dot > best) {
        best = dot;
        *s = cs;
        *t = ct;
      }
    }
  return true;
}

AttributeCoder::AttributeCoder(const MeshSchema& schema, const std::vector<CodedAttribute>& attrs)
    : vertex_(schema.vertex_properties),
      face_(schema.face_properties),
      role_(vertex_.size(), -1),
      face_role_(face_.size(), -1) {
  for (const CodedAttribute& at : attrs) {
    if (!at.per_corner()) {
      attrs_.push_back(at);
      continue;
    }
    face_role_[at.properties[0]] = static_cast<int>(corner_.size());
    Corner c;
    c.kind = at.kind;
    c.bits = at.bits;
    for (Component& x : c.comp) {
      if (at.kind == CodedAttribute::Kind::kCornerNormal) {
        x.bits = at.bits;
        x.mod = 2 * ((int64_t{1} << (at.bits - 1)) - 1) + 1;
        x.lo = 0;
        x.hi = x.mod - 1;
      } else {
        x.lo = -int64_t{0x7fffffff};
        x.hi = int64_t{0x7fffffff};
      }
    }
    c.comp[0].first = true;
    c.models.resize(static_cast<size_t>(5 * 2 * kLengthContexts));
    late_corners_ = late_corners_ || at.kind == CodedAttribute::Kind::kCornerNormal;
    corner_.push_back(std::move(c));
  }
  for (size_t i = 0; i < face_.size(); ++i)
    if (face_role_[i] < 0) face_columns_.push_back(face_[i]);
  const std::vector<Property>& vertex = vertex_;
  int k = 0;  // components (properties); a normal's three take two coded values
  for (const CodedAttribute& at : attrs_) {
    const int coded = at.kind == CodedAttribute::Kind::kNormal ? 2 : static_cast<int>(at.properties.size());
    for (int j = 0; j < coded; ++j) {
      Component& c = comp_[dims_ + j];
      c.first = j == 0;
      switch (at.kind) {
        case CodedAttribute::Kind::kNormal: {
          const int64_t half = (int64_t{1} << (at.bits - 1)) - 1;
          c.bits = at.bits;
          c.late = true;
          late_d_ = dims_;
          c.mod = 2 * half + 1;
          c.lo = 0;
          c.hi = 2 * half;
          last_[dims_ + j] = static_cast<int32_t>(half);
          break;
        }
        case CodedAttribute::Kind::kTexcoord:
          c.lo = -int64_t{0x7fffffff};
          c.hi = int64_t{0x7fffffff};
          c.parallelogram = true;
          break;
        default:  // kColor (corner attributes are apart)
          c.mod = 256;
          c.lo = 0;
          c.hi = 255;
          break;
      }
    }
    dims_ += coded;
    for (uint32_t i : at.properties) role_[i] = k++;
  }
  for (size_t i = 0; i < vertex.size(); ++i)
    if (role_[i] < 0) columns_.push_back(vertex[i]);
  models_.resize(static_cast<size_t>(2 * dims_ * kLengthContexts));
  restart_models();
}

void AttributeCoder::restart_models() {
  for (ResidualModel& m : models_) m = ResidualModel();
  waiting_.clear();
  // Spec 8.3: the length trees start from a prior (init_length_prior()).
  for (int kind = 0; kind < 2; ++kind)
    for (int d = 0; d < dims_; ++d)
      for (int c = 0; c < kLengthContexts; ++c) init_length_prior(model(kind, d, c), c);
  // Spec 8.5: the corner attributes start afresh, their vertices with no
  // values (a segment renumbers the slots).
  for (Corner& a : corner_) {
    for (size_t i = 0; i < a.models.size(); ++i) {
      a.models[i] = ResidualModel();
      init_length_prior(a.models[i], static_cast<int>(i % kLengthContexts));
    }
    for (SymbolModel& m : a.wedge) m = SymbolModel(4);
    const int32_t half = a.kind == CodedAttribute::Kind::kCornerNormal ? (int32_t{1} << (a.bits - 1)) - 1 : 0;
    a.last[0] = a.last[1] = half;
    a.orientation = 1;
  }
  wedges_.clear();
  corner_waiting_.clear();
  waiters_.clear();
  free_waiters_.clear();
  serial_ = 0;
}

int32_t* AttributeCoder::grow(std::vector<int32_t>* a, uint32_t slot) {
  // Slots stay below the boundary limit (spec 6.1.1); none other is ever
  // asked for, and none may make the arrays grow beyond it.
  thread_local int32_t none[kMaxAttributeComponents] = {};
  if (slot >= (1u << 28)) return none;
  const size_t need = (static_cast<size_t>(slot) + 1) * static_cast<size_t>(dims_);
  if (a->size() < need) a->resize(std::max(need, 2 * a->size()), 0);
  return a->data() + static_cast<size_t>(slot) * static_cast<size_t>(dims_);
}

Status AttributeCoder::split(const PropertyValues& in, uint64_t vertex, PropertyValues* columns, int32_t* q) const {
  columns->clear();
  double value[kMaxAttributeComponents];
  size_t at = 0;
  for (size_t i = 0; i < vertex_.size(); ++i) {
    if (at >= in.size()) return Status(ErrorCode::kBadValue, "vertex property values do not match the schema");
    if (role_[i] >= 0) {
      if (!scalar_holds(vertex_[i].type, in[at]))
        return Status(ErrorCode::kBadValue,
                      "vertex " + std::to_string(vertex) + ": a property value does not fit its type");
      value[role_[i]] = in[at++];
      continue;
    }
    size_t n = 1;
    if (vertex_[i].is_list) n += static_cast<size_t>(in[at]);
    if (in.size() - at < n) return Status(ErrorCode::kBadValue, "vertex property values do not match the schema");
    columns->insert(columns->end(), in.begin() + static_cast<std::ptrdiff_t>(at),
                    in.begin() + static_cast<std::ptrdiff_t>(at + n));
    at += n;
  }
  int d = 0, k = 0;  // coded values, components
  for (const CodedAttribute& a : attrs_) {
    const double* v = value + k;
    k += static_cast<int>(a.properties.size());
    switch (a.kind) {
      case CodedAttribute::Kind::kNormal:
        if (!octahedral_encode(v, (1 << (a.bits - 1)) - 1, &q[d], &q[d + 1]))
          return Status(ErrorCode::kBadValue, "vertex " + std::to_string(vertex) +
                                                  ": the normal is not finite (keep normals exact: "
                                                  "normal bits 0, or lossless)");
        d += 2;
        continue;
      case CodedAttribute::Kind::kTexcoord:
        for (int j = 0; j < 2; ++j) {
          const double g = std::ldexp(v[j], a.bits);
          if (!(std::fabs(g) < 2147483647.0))
            return Status(ErrorCode::kBadValue, "vertex " + std::to_string(vertex) +
                                                    ": texture coordinate not finite or beyond the grid of " +
                                                    std::to_string(a.bits) + " bits (keep them exact: uv bits 0)");
          q[d + j] = static_cast<int32_t>(std::llround(g));
        }
        break;
      default:  // kColor
        for (size_t j = 0; j < a.properties.size(); ++j) q[d + static_cast<int>(j)] = static_cast<int32_t>(v[j]);
        break;
    }
    d += static_cast<int>(a.properties.size());
  }
  return Status();
}

void AttributeCoder::merge(const PropertyValues& columns, const int32_t* q, PropertyValues* out) const {
  double value[kMaxAttributeComponents];
  int d = 0, k = 0;  // coded values, components
  for (const CodedAttribute& a : attrs_) {
    double* v = value + k;
    switch (a.kind) {
      case CodedAttribute::Kind::kNormal:
        octahedral_decode(q[d], q[d + 1], (1 << (a.bits - 1)) - 1, v);
        d += 2;
        break;
      case CodedAttribute::Kind::kTexcoord:
        for (int j = 0; j < 2; ++j) v[j] = std::ldexp(static_cast<double>(q[d + j]), -a.bits);
        d += 2;
        break;
      default:  // kColor
        for (size_t j = 0; j < a.properties.size(); ++j) v[j] = q[d++];
        break;
    }
    for (size_t j = 0; j < a.properties.size(); ++j)
      if (vertex_[a.properties[j]].type == ScalarType::kFloat32) v[j] = round_to_float(v[j]);
    k += static_cast<int>(a.properties.size());
  }
  out->clear();
  size_t at = 0;
  for (size_t i = 0; i < vertex_.size(); ++i) {
    if (role_[i] >= 0) {
      out->push_back(value[role_[i]]);
      continue;
    }
    size_t n = 1;
    if (vertex_[i].is_list) n += static_cast<size_t>(columns[at]);
    out->insert(out->end(), columns.begin() + static_cast<std::ptrdiff_t>(at),
                columns.begin() + static_cast<std::ptrdiff_t>(at + n));
    at += n;
  }
}

// Spec 8.3: each new vertex in order of introduction, predicted from the
// gate (an add) or from the vertex before (a start's, an isolated one);
// then the new corners' values kept by vertex slot and each entering
// edge's opposite vertex's values by edge slot. Normals wait (8.4): the
// record's triangle adds its area vector to its corners' rings, and the
// normals of the vertices that settle are coded after the other values.
// `code(kind, pred, extent, x, late)` codes one vertex's residuals, those
// of its late components or of the others.
template <class Code>
bool AttributeCoder::walk(const AttributeRecord& r, int32_t* q, Code&& code) {
  const int D = dims_;
  settled_.clear();
  int j = -1;  // an add's new corner
  if (r.triangle && r.nnew == 1)
    for (int k = 0; k < 3; ++k)
      if (r.new_mask >> k & 1) j = k;
  for (int i = 0; i < r.nnew; ++i) {
    int32_t* v = q + i * D;
    int64_t pred[kMaxAttributeComponents];
    int extent[kMaxAttributeComponents];
    int kind = 1;
    if (j >= 0) {
      kind = 0;
      const int32_t* a = vertex_values(r.c[(j + 1) % 3]);
      const int32_t* b = vertex_values(r.c[(j + 2) % 3]);
      const int32_t* o = edge_values(r.e[(j + 1) % 3]);
      for (int d = 0; d < D; ++d) {
        const Component& c = comp_[d];
        uint64_t spread = distance(a[d], b[d], c.mod);
        if (c.parallelogram) {
          pred[d] = std::min(std::max(int64_t{a[d]} + b[d] - o[d], c.lo), c.hi);
          spread = std::max({spread, distance(a[d], o[d], 0), distance(b[d], o[d], 0)});
        } else {
          pred[d] = mid(a[d], b[d]);
        }
        extent[d] = bit_length64(spread);
      }
      for (int d = 0; d < D; ++d)
        if (comp_[d].first && comp_[d].parallelogram && r.pos[0] != nullptr) predict_texcoord(r, j, d, a, b, o, pred);
    } else {
      for (int d = 0; d < D; ++d) {
        pred[d] = last_[d];
        extent[d] = 0;
      }
    }
    if (!code(kind, pred, extent, v, false)) return false;
    for (int d = 0; d < D; ++d)
      if (!comp_[d].late) last_[d] = v[d];
  }
  if (!r.triangle) {
    // An isolated vertex has no ring: its normal is coded at once.
    for (int i = 0; i < r.nnew && late_d_ >= 0; ++i)
      if (!settle(1, nullptr, r.index[i], q + i * D, code)) return false;
  } else {
    for (int k = 0; k < 3; ++k) {
      if (!(r.new_mask >> k & 1)) continue;
      for (int i = 0; i < r.nnew; ++i)
        if (r.index[i] == r.v[k]) std::copy(q + i * D, q + (i + 1) * D, vertex_values(r.c[k]));
    }
    // An edge keeps no normal (8.4: it may still be to come).
    for (int k = 0; k < 3; ++k)
      if (r.entering_mask >> k & 1) {
        const int32_t* from = vertex_values(r.c[(k + 2) % 3]);
        int32_t* to = edge_values(r.e[k]);
        for (int d = 0; d < D; ++d)
          if (!comp_[d].late) to[d] = from[d];
      }
    if (late_d_ >= 0 && !ring_step(r, code)) return false;
  }
  if (late_d_ >= 0) {
    // Spec 8.4: a normal waits at most kMaxNormalWait records, and none
    // past the end of its chunk.
    while (!waiting_.empty() && (r.flush || waiting_.front().record + kMaxNormalWait <= records_)) {
      const Waiting w = waiting_.front();
      waiting_.pop_front();
      Ring& g = rings_[w.slot];
      if (g.waiting && g.index == w.index && !settle(1, &g, w.index, vertex_values(w.slot), code)) return false;
    }
  }
  if (!r.flush) ++records_;
  return true;
}

// Spec 8.4: the new corners start their rings, in order of introduction;
// the triangle's area vector (exact in integers, so that every rotation
// of the triangle gives the same) joins each waiting corner's ring; the
// finalized corners' normals are coded in order of their dense indices.
template <class Code>
bool AttributeCoder::ring_step(const AttributeRecord& r, Code& code) {
  for (int i = 0; i < r.nnew; ++i)
    for (int k = 0; k < 3; ++k)
      if ((r.new_mask >> k & 1) && r.v[k] == r.index[i]) {
        if (r.c[k] >= (1u << 28)) continue;  // beyond any boundary limit (spec 6.1.1)
        if (rings_.size() <= r.c[k]) rings_.resize(std::max<size_t>(size_t{r.c[k]} + 1, 2 * rings_.size()));
        Ring& g = rings_[r.c[k]];
        g = Ring();
        g.index = r.index[i];
        g.waiting = true;
        waiting_.push_back(Waiting{r.c[k], r.index[i], records_});
      }
  double n[3];
  area_vector(r, n);
  for (int k = 0; k < 3; ++k) {
    if (r.c[k] >= rings_.size()) continue;
    Ring& g = rings_[r.c[k]];
    if (!g.waiting || g.index != r.v[k]) continue;
    for (int i = 0; i < 3; ++i) g.n[i] = g.n[i] + n[i];
  }
  int order[3] = {0, 1, 2};
  std::sort(order, order + 3, [&](int a, int b) { return r.v[a] < r.v[b]; });
  for (int k : order) {
    if (!(r.final_mask >> k & 1) || r.c[k] >= rings_.size()) continue;
    Ring& g = rings_[r.c[k]];
    if (g.waiting && g.index == r.v[k] && !settle(0, &g, r.v[k], vertex_values(r.c[k]), code)) return false;
  }
  return true;
}

// Spec 8.4: a normal predicted by the direction of its ring's area
// vector, taken to the grid, else by the normal coded before.
template <class Code>
bool AttributeCoder::settle(int kind, Ring* ring, uint32_t index, int32_t* x, Code& code) {
  const int d = late_d_;
  const int32_t c = (int32_t{1} << (comp_[d].bits - 1)) - 1;
  int64_t pred[kMaxAttributeComponents] = {};
  int extent[kMaxAttributeComponents] = {};
  pred[d] = last_[d];
  pred[d + 1] = last_[d + 1];
  if (ring != nullptr) {
    octahedral_round(ring->n, c, &pred[d], &pred[d + 1]);  // a zero sum keeps the normal before
    ring->waiting = false;
  }
  if (!code(kind, pred, extent, x, true)) return false;
  last_[d] = x[d];
  last_[d + 1] = x[d + 1];
  Settled s;
  s.index = index;
  std::copy(x, x + dims_, s.q);
  settled_.push_back(s);
  return true;
}

// Spec 8.3: a texture coordinate predicted by where the new vertex lies
// beside the gate edge in space: its foot on the edge and its distance
// from it, as fractions of the edge's length, carried to the edge in the
// texture, on the side away from the gate triangle's third vertex. Where
// that is not defined (a gate of zero length, or the third vertex on the
// edge in the texture) the parallelogram stays.
void AttributeCoder::predict_texcoord(const AttributeRecord& r, int j, int d, const int32_t* a, const int32_t* b,
                                      const int32_t* o, int64_t* pred) const {
  double t, h;
  if (!beside_edge(r, j, &t, &h)) return;
  const double eu = static_cast<double>(b[d]) - a[d], ev = static_cast<double>(b[d + 1]) - a[d + 1];
  const double side = eu * (static_cast<double>(o[d + 1]) - a[d + 1]) - ev * (static_cast<double>(o[d]) - a[d]);
  if (side == 0) return;
  texture_point(a + d, b + d, t, side > 0 ? -h : h, comp_[d], pred + d);  // away from the third vertex
}

bool AttributeCoder::beside_edge(const AttributeRecord& r, int j, double* t, double* h) {
  const int64_t* x = r.pos[j];
  const int64_t* p = r.pos[(j + 1) % 3];
  const int64_t* q = r.pos[(j + 2) % 3];
  double e[3], f[3];
  for (int i = 0; i < 3; ++i) {
    e[i] = static_cast<double>(q[i] - p[i]);
    f[i] = static_cast<double>(x[i] - p[i]);
  }
  const double ee = (e[0] * e[0] + e[1] * e[1]) + e[2] * e[2];
  if (!(ee > 0)) return false;
  *t = ((f[0] * e[0] + f[1] * e[1]) + f[2] * e[2]) / ee;
  double h2 = 0;
  for (int i = 0; i < 3; ++i) {
    const double g = f[i] - *t * e[i];
    h2 = h2 + g * g;
  }
  *h = std::sqrt(h2 / ee);
  return true;
}

void AttributeCoder::texture_point(const int32_t* a, const int32_t* b, double t, double w, const Component& c,
                                   int64_t* pred) {
  const double eu = static_cast<double>(b[0]) - a[0], ev = static_cast<double>(b[1]) - a[1];
  const double pu = (a[0] + t * eu) - w * ev, pv = (a[1] + t * ev) + w * eu;
  if (!(std::fabs(pu) < 4.0e9) || !(std::fabs(pv) < 4.0e9)) return;
  pred[0] = std::min(std::max(static_cast<int64_t>(std::floor(pu + 0.5)), c.lo), c.hi);
  pred[1] = std::min(std::max(static_cast<int64_t>(std::floor(pv + 0.5)), c.lo), c.hi);
}


int64_t AttributeCoder::component_residual(const Component& c, int64_t pred, int64_t value) {
  int64_t res = value - pred;
  if (c.mod != 0) {
    const int64_t lo = -(c.mod / 2);
    if (res < lo) res += c.mod;
    if (res > lo + c.mod - 1) res -= c.mod;
  }
  return res;
}

const char* AttributeCoder::component_value(const Component& c, int64_t pred, int64_t res, int32_t* out) {
  int64_t value;
  if (c.mod != 0) {
    const int64_t lo = -(c.mod / 2);
    if (res < lo || res > lo + c.mod - 1) return "attribute residual beyond its modulus";
    value = pred + res;
    if (value < 0) value += c.mod;
    if (value >= c.mod) value -= c.mod;
  } else {
    if (res < -(int64_t{1} << 40) || res > (int64_t{1} << 40)) return "texture coordinate outside its grid";
    value = pred + res;
    if (value < c.lo || value > c.hi) return "texture coordinate outside its grid";
  }
  *out = static_cast<int32_t>(value);
  return nullptr;
}


namespace {

// Spec 13.8.3: a residual as its length symbol in `table`, then raw bits.
PSQ_INLINE int fast_put(FastAttributeWriter& w, int table, int64_t res) {
  const uint64_t mag = res < 0 ? 0 - static_cast<uint64_t>(res) : static_cast<uint64_t>(res);
  const int k = bit_length64(mag);
  const int sym = fast_length_symbol(k, mag);
  w.symbols.push_back(RansSymbol{static_cast<uint16_t>(table), static_cast<uint8_t>(sym)});
  ++w.counts[static_cast<size_t>(table) * kFastLengthSymbols + static_cast<size_t>(sym)];
  if (sym == kFastLengthEscape) {
    w.raw.put(static_cast<uint32_t>(k - 33), 5);
    w.raw.put(static_cast<uint32_t>((mag >> (k - 2)) & 1), 1);
  }
  const int nbits = fast_raw_bit_count(k);
  const int low_bits = nbits - static_cast<int>(k != 0);
  const uint64_t value = (static_cast<uint64_t>(res < 0) << low_bits) | (mag & ((uint64_t{1} << low_bits) - 1));
  if (nbits > 32) {
    w.raw.put(static_cast<uint32_t>(value), 32);
    w.raw.put(static_cast<uint32_t>(value >> 32), nbits - 32);
  } else {
    w.raw.put(static_cast<uint32_t>(value), nbits);
  }
  return k;
}

// Spec 13.8.3: a length symbol's residual from the raw bits.
PSQ_INLINE const char* fast_get(FastAttributeReader& rd, int table, int64_t* res, int* length) {
  RawReader& raw = *rd.raw;
  const int s = rd.rans->decode(rd.tables[static_cast<size_t>(table)]);
  uint64_t mag;
  int len;
  if (s < kFastLengthEscape) {
    len = s < 2 ? s : (s + 2) >> 1;
    const int low_bits = len >= 2 ? len - 2 : 0;
    const uint64_t lead = len == 0 ? 0 : len == 1 ? 1 : (uint64_t{2} | static_cast<uint64_t>(s & 1)) << (len - 2);
    mag = lead | (len == 0 ? 0 : raw.get(low_bits));
  } else if (s == kFastLengthEscape) {
    len = 33 + static_cast<int>(raw.get(5));
    mag = uint64_t{1} << (len - 1) | static_cast<uint64_t>(raw.get(1)) << (len - 2);
    const int low_bits = len - 2;
    mag |= low_bits > 32 ? raw.get(32) | static_cast<uint64_t>(raw.get(low_bits - 32)) << 32 : raw.get(low_bits);
  } else {
    return "attribute symbol of an absent table";
  }
  const bool negative = len != 0 && raw.get(1) != 0;
  if (!negative && mag >= (uint64_t{1} << 63)) return "attribute residual longer than 64 bits";
  *res = negative ? static_cast<int64_t>(0 - mag) : static_cast<int64_t>(mag);
  *length = len;
  return nullptr;
}

}  // namespace

// The four ways to code a record: the adaptive and the rANS back-end,
// encoding and decoding. Each codes a residual of a model (adaptive) or a
// table (rANS), and a corner's wedge symbol (8.5) likewise. Inlined into
// code_record(), which calls them for every value knowing their type
// (corner_walk() calls them through Coding).
struct AttributeCoder::AdaptiveOut final : Coding {
  explicit AdaptiveOut(Encoder& x) : enc(x) {}
  Encoder& enc;
  PSQ_INLINE bool residual(int, ResidualModel& m, const Component& c, int64_t pred, int32_t* x, int* length) override {
    *length = enc.residual(m, component_residual(c, pred, *x));
    return true;
  }
  PSQ_INLINE bool symbol(int, SymbolModel& m, uint32_t* s) override {
    enc.symbol<4>(m, *s);
    return true;
  }
};
struct AttributeCoder::AdaptiveIn final : Coding {
  explicit AdaptiveIn(Decoder& x) : dec(x) {}
  Decoder& dec;
  PSQ_INLINE bool residual(int, ResidualModel& m, const Component& c, int64_t pred, int32_t* x, int* length) override {
    int64_t res;
    if (!dec.residual(m, &res, length)) return why = "attribute residual longer than 64 bits", false;
    return !(why = component_value(c, pred, res, x));
  }
  PSQ_INLINE bool symbol(int, SymbolModel& m, uint32_t* s) override {
    *s = dec.symbol<4>(m);
    return true;
  }
};
struct AttributeCoder::FastOut final : Coding {
  explicit FastOut(FastAttributeWriter& x) : w(x) {}
  FastAttributeWriter& w;
  PSQ_INLINE bool residual(int table, ResidualModel&, const Component& c, int64_t pred, int32_t* x,
                           int* length) override {
    *length = fast_put(w, table, component_residual(c, pred, *x));
    return true;
  }
  PSQ_INLINE bool symbol(int table, SymbolModel&, uint32_t* s) override {
    w.symbols.push_back(RansSymbol{static_cast<uint16_t>(table), static_cast<uint8_t>(*s)});
    ++w.counts[static_cast<size_t>(table) * kFastLengthSymbols + *s];
    return true;
  }
};
struct AttributeCoder::FastIn final : Coding {
  explicit FastIn(FastAttributeReader& x) : rd(x) {}
  FastAttributeReader& rd;
  PSQ_INLINE bool residual(int table, ResidualModel&, const Component& c, int64_t pred, int32_t* x,
                           int* length) override {
    int64_t res;
    if ((why = fast_get(rd, table, &res, length))) return false;
    return !(why = component_value(c, pred, res, x));
  }
  PSQ_INLINE bool symbol(int table, SymbolModel&, uint32_t* s) override {
    const int v = rd.rans->decode(rd.tables[static_cast<size_t>(table)]);
    if (v < 0 || v >= kFastLengthSymbols) return why = "attribute symbol of an absent table", false;
    *s = static_cast<uint32_t>(v);
    return true;
  }
};

// A record: the vertices' values (walk()), then the triangle's corners'
// (code_corners()).
template <class C>
const char* AttributeCoder::code_record(const AttributeRecord& r, int32_t* q, C& code) {
  const bool ok = walk(r, q, [&](int kind, const int64_t* pred, const int* extent, int32_t* x, bool late) {
    int longest = 0;
    for (int d = 0; d < dims_; ++d) {
      const Component& c = comp_[d];
      if (c.late != late) continue;
      if (c.first) longest = 0;
      const int ctx = attribute_context(kind, c.first, extent[d], longest);
      int length;
      if (!code.residual(fast_table(kind, d, ctx), model(kind, d, ctx), c, pred[d], &x[d], &length)) return false;
      longest = std::max(longest, length);
    }
    return true;
  });
  if (!ok) return code.why ? code.why : "attribute data is corrupt";
  // A stream without corner attributes runs none of 8.5's steps.
  return corner_.empty() ? nullptr : code_corners(r, code);
}

void AttributeCoder::encode(Encoder& enc, const AttributeRecord& r, const int32_t* q) {
  AdaptiveOut out(enc);
  code_record(r, const_cast<int32_t*>(q), out);  // only reads the values it is given
}

const char* AttributeCoder::decode(Decoder& dec, const AttributeRecord& r, int32_t* q) {
  AdaptiveIn in(dec);
  return code_record(r, q, in);
}

void AttributeCoder::encode_fast(FastAttributeWriter& w, const AttributeRecord& r, const int32_t* q) {
  if (w.counts.empty()) w.counts.assign(static_cast<size_t>(fast_tables()) * kFastLengthSymbols, 0);
  FastOut out(w);
  code_record(r, const_cast<int32_t*>(q), out);
}

const char* AttributeCoder::decode_fast(FastAttributeReader& rd, const AttributeRecord& r, int32_t* q) {
  FastIn in(rd);
  return code_record(r, q, in);
}

void AttributeCoder::finish_fast(FastAttributeWriter& w, std::vector<uint8_t>* out) const {
  // Spec 13.8.4: laid out as a record section of the rANS back-end
  // (13.2): the table block, the rANS block and the raw block, the first
  // two with their lengths.
  const int n = fast_tables();
  if (w.counts.empty()) w.counts.assign(static_cast<size_t>(n) * kFastLengthSymbols, 0);
  std::vector<RansTable> tables(static_cast<size_t>(n));
  RawWriter tw;
  for (int i = 0; i < n; ++i) {
    const uint64_t* c = &w.counts[static_cast<size_t>(i) * kFastLengthSymbols];
    bool present = false;
    for (int sym = 0; sym < kFastLengthSymbols; ++sym) present = present || c[sym] != 0;
    tw.put(present, 1);
    if (present) tables[static_cast<size_t>(i)].build(c, kFastLengthSymbols);
  }
  for (const RansTable& t : tables)
    if (!t.empty()) t.write(tw);
  const std::vector<uint8_t> table_bytes = tw.finish();
  std::vector<uint8_t> rans_bytes;
  rans_encode(w.symbols.data(), w.symbols.size(), tables.data(), tables.size(), &rans_bytes);
  put_rans_section(table_bytes, rans_bytes, w.raw.finish(), out);
  w.symbols.clear();
  std::fill(w.counts.begin(), w.counts.end(), 0);
}

const char* AttributeCoder::open_fast(FastAttributeReader& rd, const uint8_t* data, size_t size) const {
  RansSection sec;
  if (const char* why = split_rans_section(data, size, &sec)) return why;
  RawReader tables(sec.tables, sec.table_bytes);
  const int n = fast_tables();
  rd.tables.resize(static_cast<size_t>(n));
  std::vector<bool> present(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) present[static_cast<size_t>(i)] = tables.get(1) != 0;
  for (int i = 0; i < n; ++i) {
    RansTable& t = rd.tables[static_cast<size_t>(i)];
    if (!present[static_cast<size_t>(i)]) {
      t.set_absent();
    } else if (!t.read(tables, kFastLengthSymbols)) {
      return "an attribute table is invalid";
    }
  }
  if (!tables.at_clean_end()) return "the table block does not end with its last table";
  rd.rans = std::make_unique<RansDecoder>(sec.rans, sec.rans_bytes);
  rd.raw = std::make_unique<RawReader>(sec.raw, sec.raw_bytes);
  return nullptr;
}

}  // namespace codec
}  // namespace psq
