// SPDX-License-Identifier: Apache-2.0
// tools/src/ops/corner_weld.cpp: see corner_weld.h. The merge is by value,
// as the OBJ reader's per-corner attributes are by index: a position whose
// corners all carry one normal keeps it per vertex.
#include "corner_weld.h"

#include <array>
#include <cstring>
#include <string>
#include <unordered_map>

namespace psq::detail {
namespace {

bool is_real(const Property& p) {
  return !p.is_list && (p.type == ScalarType::kFloat32 || p.type == ScalarType::kFloat64);
}

// The names of a normal's and a texture coordinate's components, the
// first complete set found (as the codec recognizes them, spec 8.3).
bool find_components(const std::vector<Property>& props, int kind, std::array<int, 3>* out) {
  static const std::vector<std::vector<const char*>> kNames[2] = {
      {{"nx", "ny", "nz"}},
      {{"u", "v"}, {"s", "t"}, {"texture_u", "texture_v"}, {"texture_s", "texture_t"}}};
  for (const auto& names : kNames[kind]) {
    bool all = true;
    for (size_t k = 0; k < names.size() && all; ++k) {
      (*out)[k] = -1;
      for (size_t i = 0; i < props.size(); ++i)
        if (props[i].name == names[k] && is_real(props[i])) (*out)[k] = static_cast<int>(i);
      all = (*out)[k] >= 0;
    }
    if (all) return true;
  }
  return false;
}

void append_bits(double v, std::string* key) {
  if (v == 0) v = 0;  // -0.0 equal to 0.0
  char b[8];
  std::memcpy(b, &v, 8);
  key->append(b, 8);
}

}  // namespace

struct CornerWelder::Impl {
  std::unique_ptr<MeshSource> input;
  uint64_t budget = 0;
  uint64_t used = 0;
  MeshSchema schema;
  SourceReport report;
  std::array<int, 3> comp[2] = {{-1, -1, -1}, {-1, -1, -1}};  // property indices of the normal, texture coordinate
  int arity[2] = {3, 2};
  bool present[2] = {false, false};
  bool per_corner[2] = {false, false};
  std::vector<int> role;  // per input vertex property: kind * 3 + component, or -1
  // The input, and how its vertices merge.
  std::vector<std::array<double, 3>> positions;
  std::vector<PropertyValues> vertex_values;
  std::vector<std::array<uint32_t, 3>> triangles;
  std::vector<PropertyValues> face_values;
  std::vector<uint32_t> merged;  // by input vertex: its output vertex
  std::vector<uint32_t> first;   // by output vertex: its first input vertex
  size_t next_vertex = 0, next_triangle = 0;
  uint64_t dropped = 0;

  Status charge(uint64_t bytes) {
    used += bytes;
    if (used > budget)
      return Status(ErrorCode::kLimit, "--weld=corners reads the mesh in memory: it exceeds the memory budget (--memory)");
    return Status();
  }
  // A vertex's attribute values (kind, component) and, when `key` is
  // given, the key of everything else: its position and other values.
  void split(const std::array<double, 3>& p, const PropertyValues& values, double attr[2][3], std::string* key) const {
    if (key) key->clear();
    if (key)
      for (double c : p) append_bits(c, key);
    const auto& props = input->schema().vertex_properties;
    size_t at = 0;
    for (size_t i = 0; i < role.size(); ++i) {
      if (role[i] >= 0) {
        attr[role[i] / 3][role[i] % 3] = values[at++];
        continue;
      }
      const size_t n = props[i].is_list ? 1 + static_cast<size_t>(values[at]) : 1;
      if (key)
        for (size_t k = 0; k < n; ++k) append_bits(values[at + k], key);
      at += n;
    }
  }
};

CornerWelder::CornerWelder(std::unique_ptr<MeshSource> input, uint64_t memory_budget)
    : impl_(std::make_unique<Impl>()) {
  impl_->input = std::move(input);
  impl_->budget = memory_budget;
}
CornerWelder::~CornerWelder() = default;

Status CornerWelder::open() {
  Impl& m = *impl_;
  const MeshSchema& in = m.input->schema();
  m.schema = in;
  for (const Property& p : in.face_properties)
    if (p.name == "corner_normals" || p.name == "corner_uv")
      return Status(ErrorCode::kBadValue, "--weld=corners: the mesh has a face property " + p.name + " already");
  m.role.assign(in.vertex_properties.size(), -1);
  for (int kind = 0; kind < 2; ++kind) {
    m.present[kind] = find_components(in.vertex_properties, kind, &m.comp[kind]);
    if (m.present[kind])
      for (int k = 0; k < m.arity[kind]; ++k) m.role[static_cast<size_t>(m.comp[kind][k])] = kind * 3 + k;
  }
  // The input, whole.
  MeshItem item;
  for (;;) {
    PSQ_RETURN_IF_ERROR(m.input->next(&item));
    if (item.kind == MeshItem::Kind::kEnd) break;
    if (item.kind == MeshItem::Kind::kVertex) {
      PSQ_RETURN_IF_ERROR(m.charge(24 + 16 * item.values.size() + 160));
      m.positions.push_back({item.position[0], item.position[1], item.position[2]});
      m.vertex_values.push_back(item.values);
    } else {
      PSQ_RETURN_IF_ERROR(m.charge(12 + 8 * item.values.size() + 48 + 120));
      m.triangles.push_back({item.index[0], item.index[1], item.index[2]});
      m.face_values.push_back(item.values);
    }
  }
  // Merge by position and the other values.
  const size_t nv = m.positions.size();
  std::unordered_map<std::string, uint32_t> output_of;
  std::vector<std::array<double, 6>> attr_of;  // by output vertex: its first vertex's normal and texture coordinate
  std::vector<uint8_t> mixed;                   // by output vertex: bit kind when its vertices differ in it
  m.merged.resize(nv);
  std::string key;
  for (size_t v = 0; v < nv; ++v) {
    double attr[2][3] = {{0, 0, 0}, {0, 0, 0}};
    m.split(m.positions[v], m.vertex_values[v], attr, &key);
    auto it = output_of.emplace(key, static_cast<uint32_t>(m.first.size()));
    const uint32_t o = it.first->second;
    m.merged[v] = o;
    const std::array<double, 6> a = {attr[0][0], attr[0][1], attr[0][2], attr[1][0], attr[1][1], attr[1][2]};
    if (it.second) {
      m.first.push_back(static_cast<uint32_t>(v));
      attr_of.push_back(a);
      mixed.push_back(0);
      continue;
    }
    for (int kind = 0; kind < 2; ++kind)
      for (int k = 0; k < m.arity[kind]; ++k)
        if (std::memcmp(&a[kind * 3 + k], &attr_of[o][kind * 3 + k], 8) != 0) mixed[o] |= 1 << kind;
  }
  uint64_t count[2] = {0, 0};
  for (uint8_t x : mixed)
    for (int kind = 0; kind < 2; ++kind) count[kind] += x >> kind & 1;
  // The output schema: the per-corner attributes leave the vertex
  // properties for face lists.
  m.schema.vertex_properties.clear();
  for (size_t i = 0; i < in.vertex_properties.size(); ++i)
    if (m.role[i] < 0 || count[m.role[i] / 3] == 0) m.schema.vertex_properties.push_back(in.vertex_properties[i]);
  for (int kind = 0; kind < 2; ++kind) {
    m.per_corner[kind] = m.present[kind] && count[kind] > 0;
    if (!m.per_corner[kind]) continue;
    Property list;
    list.name = kind == 0 ? "corner_normals" : "corner_uv";
    list.type = ScalarType::kFloat32;
    for (int k = 0; k < m.arity[kind]; ++k)
      if (in.vertex_properties[static_cast<size_t>(m.comp[kind][k])].type == ScalarType::kFloat64)
        list.type = ScalarType::kFloat64;
    list.is_list = true;
    list.count_type = ScalarType::kUInt8;
    m.schema.face_properties.push_back(list);
  }
  // Triangles the merge makes degenerate are dropped.
  uint64_t& dropped = m.dropped;
  for (const auto& t : m.triangles) {
    const uint32_t a = m.merged[t[0]], b = m.merged[t[1]], c = m.merged[t[2]];
    dropped += a == b || b == c || a == c;
  }
  m.schema.vertex_count = static_cast<int64_t>(m.first.size());
  m.schema.triangle_count = static_cast<int64_t>(m.triangles.size() - dropped);
  m.schema.has_bounds = false;
  m.report = m.input->report();
  m.report.notes.push_back("--weld=corners merged " + std::to_string(nv - m.first.size()) + " of " +
                           std::to_string(nv) + " vertices (the same position and other properties)");
  const char* what[2] = {"normals", "texture coordinates"};
  for (int kind = 0; kind < 2; ++kind)
    if (m.per_corner[kind])
      m.report.notes.push_back(std::string(what[kind]) + " vary per corner at " + std::to_string(count[kind]) +
                               " vertices: kept as per-corner face property " +
                               (kind == 0 ? "corner_normals" : "corner_uv"));
  if (dropped)
    m.report.notes.push_back(std::to_string(dropped) + " triangle(s) degenerate after the merge dropped");
  return Status();
}

const MeshSchema& CornerWelder::schema() const { return impl_->schema; }
uint64_t CornerWelder::input_vertices() const { return impl_->positions.size(); }
uint64_t CornerWelder::input_triangles() const { return impl_->triangles.size(); }
uint64_t CornerWelder::merged_vertices() const { return impl_->positions.size() - impl_->first.size(); }
uint64_t CornerWelder::dropped_triangles() const { return impl_->dropped; }
const SourceReport& CornerWelder::report() const { return impl_->report; }

Status CornerWelder::next(MeshItem* item) {
  Impl& m = *impl_;
  item->values.clear();
  const auto& props = m.input->schema().vertex_properties;
  if (m.next_vertex < m.first.size()) {
    const uint32_t v = m.first[m.next_vertex++];
    item->kind = MeshItem::Kind::kVertex;
    for (int k = 0; k < 3; ++k) item->position[k] = m.positions[v][k];
    const PropertyValues& in = m.vertex_values[v];
    size_t at = 0;
    for (size_t i = 0; i < props.size(); ++i) {
      const size_t n = props[i].is_list ? 1 + static_cast<size_t>(in[at]) : 1;
      if (m.role[i] < 0 || !m.per_corner[m.role[i] / 3])
        item->values.insert(item->values.end(), in.begin() + static_cast<std::ptrdiff_t>(at),
                            in.begin() + static_cast<std::ptrdiff_t>(at + n));
      at += n;
    }
    return Status();
  }
  while (m.next_triangle < m.triangles.size()) {
    const size_t f = m.next_triangle++;
    const auto& t = m.triangles[f];
    for (int k = 0; k < 3; ++k) item->index[k] = m.merged[t[k]];
    if (item->index[0] == item->index[1] || item->index[1] == item->index[2] || item->index[0] == item->index[2])
      continue;
    item->kind = MeshItem::Kind::kTriangle;
    item->values = m.face_values[f];
    for (int kind = 0; kind < 2; ++kind) {
      if (!m.per_corner[kind]) continue;
      item->values.push_back(3.0 * m.arity[kind]);
      for (int k = 0; k < 3; ++k) {
        double attr[2][3];
        m.split(m.positions[t[k]], m.vertex_values[t[k]], attr, nullptr);
        for (int d = 0; d < m.arity[kind]; ++d) item->values.push_back(attr[kind][d]);
      }
    }
    return Status();
  }
  item->kind = MeshItem::Kind::kEnd;
  return Status();
}

}  // namespace psq::detail
