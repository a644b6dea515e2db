// SPDX-License-Identifier: Apache-2.0
// Merge rules of vertex and face properties (psq/property_merge.h).
#include "psq/property_merge.h"

#include <cmath>
#include <cstring>
#include "float_round.h"

namespace psq {
namespace {

bool one_of(const std::string& name, std::initializer_list<const char*> names) {
  for (const char* n : names)
    if (name == n) return true;
  return false;
}

double round_to_type(double v, ScalarType type) {
  if (std::isnan(v)) return scalar_is_float(type) ? v : 0.0;
  switch (type) {
    case ScalarType::kFloat32: return detail::round_to_float(v);
    case ScalarType::kFloat64: return v;
    default: break;
  }
  double lo = 0, hi = 0;
  switch (type) {
    case ScalarType::kInt8: lo = -128, hi = 127; break;
    case ScalarType::kUInt8: lo = 0, hi = 255; break;
    case ScalarType::kInt16: lo = -32768, hi = 32767; break;
    case ScalarType::kUInt16: lo = 0, hi = 65535; break;
    case ScalarType::kInt32: lo = -2147483648.0, hi = 2147483647.0; break;
    case ScalarType::kUInt32: lo = 0, hi = 4294967295.0; break;
    default: break;
  }
  return std::min(hi, std::max(lo, std::floor(v + 0.5)));
}

constexpr size_t kOrder = 0;  // accumulator layout: order, count, then one value per kept property
constexpr size_t kCount = 1;
constexpr size_t kHead = 2;

}  // namespace

const char* merge_rule_name(MergeRule rule) {
  switch (rule) {
    case MergeRule::kAverage: return "average";
    case MergeRule::kFirst: return "first";
    case MergeRule::kDrop: return "drop";
  }
  return "?";
}

MergeRule default_merge_rule(const Property& p) {
  if (p.is_list) return MergeRule::kDrop;
  const std::string& n = p.name;
  if (one_of(n, {"nx", "ny", "nz", "normal_x", "normal_y", "normal_z"})) return MergeRule::kAverage;
  if (one_of(n, {"red", "green", "blue", "alpha", "r", "g", "b", "a", "diffuse_red", "diffuse_green", "diffuse_blue",
                 "diffuse_alpha"}))
    return MergeRule::kAverage;
  if (one_of(n, {"u", "v", "s", "t", "texture_u", "texture_v", "texture_s", "texture_t"})) return MergeRule::kAverage;
  return MergeRule::kFirst;
}

MergePolicy default_merge_policy(const MeshSchema& schema) {
  MergePolicy p;
  for (const Property& x : schema.vertex_properties) p.vertex.push_back(default_merge_rule(x));
  for (const Property& x : schema.face_properties) p.face.push_back(default_merge_rule(x));
  return p;
}

MeshSchema merged_schema(const MeshSchema& schema, const MergePolicy& policy) {
  MeshSchema out = schema;
  out.vertex_count = MeshSchema::kUnknown;
  out.triangle_count = MeshSchema::kUnknown;
  out.vertex_properties.clear();
  out.face_properties.clear();
  for (size_t i = 0; i < schema.vertex_properties.size(); ++i)
    if (!schema.vertex_properties[i].is_list && policy.vertex.at(i) != MergeRule::kDrop)
      out.vertex_properties.push_back(schema.vertex_properties[i]);
  for (size_t i = 0; i < schema.face_properties.size(); ++i)
    if (!schema.face_properties[i].is_list && policy.face.at(i) != MergeRule::kDrop)
      out.face_properties.push_back(schema.face_properties[i]);
  return out;
}

PropertyMerger::PropertyMerger(const std::vector<Property>& props, const std::vector<MergeRule>& rules) {
  for (size_t i = 0; i < props.size(); ++i) {
    is_list_.push_back(props[i].is_list);
    if (props[i].is_list || rules.at(i) == MergeRule::kDrop) continue;
    kept_.push_back(Kept{i, props[i].type, rules[i]});
  }
  width_ = kept_.empty() ? 0 : kHead + kept_.size();
  // An averaged normal of float components is renormalized as a whole.
  const char* const names[2][3] = {{"nx", "ny", "nz"}, {"normal_x", "normal_y", "normal_z"}};
  for (const auto& set : names) {
    int at[3] = {-1, -1, -1};
    for (size_t k = 0; k < kept_.size(); ++k)
      for (int c = 0; c < 3; ++c)
        if (props[kept_[k].index].name == set[c] && kept_[k].rule == MergeRule::kAverage &&
            scalar_is_float(kept_[k].type))
          at[c] = static_cast<int>(k);
    if (at[0] >= 0 && at[1] >= 0 && at[2] >= 0) std::memcpy(normal_, at, sizeof at);
  }
}

void PropertyMerger::reset(double* acc) const {
  if (width_ == 0) return;
  acc[kOrder] = 0;
  acc[kCount] = 0;
  for (size_t k = 0; k < kept_.size(); ++k) acc[kHead + k] = 0;
}

void PropertyMerger::add(double* acc, const PropertyValues& values, uint64_t order) const {
  if (width_ == 0) return;
  const bool first = acc[kCount] == 0 || static_cast<double>(order) < acc[kOrder];
  // Walk the flattened values (lists are a count and that many values).
  size_t at = 0, k = 0;
  for (size_t i = 0; i < is_list_.size() && at < values.size(); ++i) {
    const double v = values[at];
    if (is_list_[i]) {
      at += 1 + static_cast<size_t>(v > 0 ? v : 0);
      continue;
    }
    ++at;
    if (k < kept_.size() && kept_[k].index == i) {
      double& slot = acc[kHead + k];
      if (kept_[k].rule == MergeRule::kAverage) {
        slot += v;
      } else if (first) {
        slot = v;
      }
      ++k;
    }
  }
  if (first) acc[kOrder] = static_cast<double>(order);
  acc[kCount] += 1;
}

void PropertyMerger::merge(double* into, const double* from) const {
  if (width_ == 0 || from[kCount] == 0) return;
  const bool first = into[kCount] == 0 || from[kOrder] < into[kOrder];
  for (size_t k = 0; k < kept_.size(); ++k) {
    if (kept_[k].rule == MergeRule::kAverage) {
      into[kHead + k] += from[kHead + k];
    } else if (first) {
      into[kHead + k] = from[kHead + k];
    }
  }
  if (first) into[kOrder] = from[kOrder];
  into[kCount] += from[kCount];
}

void PropertyMerger::result(const double* acc, PropertyValues* out) const {
  out->resize(kept_.size());
  if (kept_.empty()) return;
  const double n = acc[kCount] > 0 ? acc[kCount] : 1;
  for (size_t k = 0; k < kept_.size(); ++k) {
    const double v = acc[kHead + k];
    (*out)[k] = kept_[k].rule == MergeRule::kAverage ? v / n : v;
  }
  if (normal_[0] >= 0) {
    double& x = (*out)[normal_[0]];
    double& y = (*out)[normal_[1]];
    double& z = (*out)[normal_[2]];
    const double len = std::sqrt(x * x + y * y + z * z);
    if (len > 0 && std::isfinite(len)) {
      x /= len;
      y /= len;
      z /= len;
    }
  }
  for (size_t k = 0; k < kept_.size(); ++k) {
    if (kept_[k].rule == MergeRule::kAverage) (*out)[k] = round_to_type((*out)[k], kept_[k].type);
  }
}

}  // namespace psq
