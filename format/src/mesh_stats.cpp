// SPDX-License-Identifier: Apache-2.0
#include "psq/mesh_stats.h"

#include <algorithm>

namespace psq {

Status MeshStats::begin(const MeshSchema& schema) {
  result_ = MeshStatsResult();
  result_.schema = schema;
  referenced_.clear();
  return Status();
}

Status MeshStats::vertex(const double p[3], const PropertyValues&) {
  if (result_.vertices == 0) {
    std::copy(p, p + 3, result_.bbox_min);
    std::copy(p, p + 3, result_.bbox_max);
  }
  for (int k = 0; k < 3; ++k) {
    result_.bbox_min[k] = std::min(result_.bbox_min[k], p[k]);
    result_.bbox_max[k] = std::max(result_.bbox_max[k], p[k]);
  }
  ++result_.vertices;
  // The bit set grows with the vertices actually read, never with a count
  // claimed by a header.
  if ((result_.vertices + 63) / 64 > referenced_.size()) referenced_.push_back(0);
  return Status();
}

Status MeshStats::triangle(const uint32_t idx[3], const PropertyValues&) {
  ++result_.triangles;
  if (idx[0] == idx[1] || idx[1] == idx[2] || idx[2] == idx[0]) ++result_.degenerate_triangles;
  for (int k = 0; k < 3; ++k) {
    uint64_t i = idx[k];
    // Sources check indices against the vertex count; a triangle may still
    // precede its vertices in a PLY whose face element comes first.
    if (i / 64 >= referenced_.size()) referenced_.resize(i / 64 + 1, 0);
    referenced_[i / 64] |= uint64_t{1} << (i % 64);
  }
  return Status();
}

Status MeshStats::finish() {
  uint64_t used = 0;
  uint64_t full_words = result_.vertices / 64;
  for (uint64_t w = 0; w < full_words && w < referenced_.size(); ++w) {
    used += static_cast<uint64_t>(__builtin_popcountll(referenced_[w]));
  }
  uint64_t rest = result_.vertices % 64;
  if (rest != 0 && full_words < referenced_.size()) {
    used += static_cast<uint64_t>(__builtin_popcountll(referenced_[full_words] & ((uint64_t{1} << rest) - 1)));
  }
  result_.unreferenced_vertices = result_.vertices - used;
  return Status();
}

}  // namespace psq
