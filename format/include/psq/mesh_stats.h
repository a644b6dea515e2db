// SPDX-License-Identifier: Apache-2.0
// psq/mesh_stats.h: statistics of an indexed mesh in one streaming pass.
//
// MeshStats is a MeshSink that counts what `psq info` reports for any input.
// Its memory is one bit per vertex (to find unreferenced vertices), never the
// mesh itself.
#ifndef PSQ_MESH_STATS_H_
#define PSQ_MESH_STATS_H_

#include <cstdint>
#include <vector>

#include "psq/indexed_mesh.h"

namespace psq {

struct MeshStatsResult {
  MeshSchema schema;
  uint64_t vertices = 0;
  uint64_t triangles = 0;
  uint64_t unreferenced_vertices = 0;   // used by no triangle
  uint64_t degenerate_triangles = 0;    // two or three equal indices
  double bbox_min[3] = {0, 0, 0};       // zero when there is no vertex
  double bbox_max[3] = {0, 0, 0};
};

class MeshStats : public MeshSink {
 public:
  Status begin(const MeshSchema& schema) override;
  Status vertex(const double position[3], const PropertyValues& values) override;
  Status triangle(const uint32_t index[3], const PropertyValues& values) override;
  Status finish() override;

  // Valid after finish().
  const MeshStatsResult& result() const { return result_; }

 private:
  MeshStatsResult result_;
  std::vector<uint64_t> referenced_;  // one bit per vertex index
};

}  // namespace psq

#endif  // PSQ_MESH_STATS_H_
