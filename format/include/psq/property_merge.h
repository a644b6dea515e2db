// SPDX-License-Identifier: Apache-2.0
// psq/property_merge.h: what a vertex or face property does when elements
// merge.
//
// A filter that merges vertices (vertex clustering, edge collapse) or
// triangles (duplicates of one simplified triangle) must say what becomes
// of their property values. Each property declares a rule:
//
// - kAverage: the mean of the merged values, rounded to the property's type
//   (to the nearest integer, clamped to the type's range, for integer
//   types; to the nearest float for float). A normal (nx, ny, nz averaged
//   together) is renormalized to unit length.
// - kFirst: the value of the first element merged (the one with the
//   smallest order the filter gives, so the result does not depend on the
//   order of merging).
// - kDrop: the property leaves the output schema.
//
// Defaults (default_merge_rule()): normals (nx ny nz, normal_x normal_y
// normal_z) averaged and renormalized; colours (red green blue alpha, r g
// b a, diffuse_red ...) averaged; texture coordinates (u v, s t, texture_u
// texture_v, texture_s texture_t) averaged, because a merged vertex stands
// for the middle of its cluster, and the mean coordinate of a continuous
// parametrization is the coordinate of that middle, while the first
// vertex's lies anywhere in the cluster (across a seam neither is right);
// every other scalar kept from the first (an id, a label, a confidence:
// an average of labels means nothing). List properties are dropped: their
// length varies, and a merged element has no single list to keep.
#ifndef PSQ_PROPERTY_MERGE_H_
#define PSQ_PROPERTY_MERGE_H_

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "psq/indexed_mesh.h"

namespace psq {

enum class MergeRule : uint8_t { kAverage = 0, kFirst = 1, kDrop = 2 };

// "average", "first" or "drop".
const char* merge_rule_name(MergeRule rule);
// The default rule of `p` (see above).
MergeRule default_merge_rule(const Property& p);

// One rule per property of a schema, in the schema's order.
struct MergePolicy {
  std::vector<MergeRule> vertex;
  std::vector<MergeRule> face;
};

// The default rule of every property of `schema`.
MergePolicy default_merge_policy(const MeshSchema& schema);
// `schema` without the properties `policy` drops (lists included), counts
// unknown. `policy` must have one rule per property.
MeshSchema merged_schema(const MeshSchema& schema, const MergePolicy& policy);

// Accumulates the values of merged elements in a fixed-width array of
// doubles (an accumulator), so that a filter keeps one per cluster without
// allocating, merges two clusters' accumulators, and reads the merged values.
class PropertyMerger {
 public:
  PropertyMerger() = default;
  // `rules` has one rule per property of `props`; lists are dropped
  // whatever their rule.
  PropertyMerger(const std::vector<Property>& props, const std::vector<MergeRule>& rules);

  // Doubles per accumulator; 0 when every property is dropped (then the
  // filter needs none, and result() gives empty values).
  size_t width() const { return width_; }
  // An accumulator of no element.
  void reset(double* acc) const;
  // Adds one element's values (well-formed for the properties) of order
  // `order` (for kFirst: the smallest order wins).
  void add(double* acc, const PropertyValues& values, uint64_t order) const;
  // Adds accumulator `from` into `into`.
  void merge(double* into, const double* from) const;
  // The merged values, for the properties merged_schema() keeps, in order.
  void result(const double* acc, PropertyValues* out) const;

 private:
  struct Kept {
    size_t index;  // among the properties
    ScalarType type;
    MergeRule rule;
  };
  std::vector<Kept> kept_;
  std::vector<bool> is_list_;   // per property
  int normal_[3] = {-1, -1, -1};  // positions in kept_ of an averaged normal, or -1
  size_t width_ = 0;
};

}  // namespace psq

#endif  // PSQ_PROPERTY_MERGE_H_
