// SPDX-License-Identifier: Apache-2.0
// tools/src/ops/corner_weld.h: `psq convert --weld=corners`. A mesh whose
// texture seams and creases split vertices (one vertex per distinct
// position, normal and texture coordinate, as exporters write PLY from
// glTF or assimp) becomes one vertex per position with the normals and
// texture coordinates that differ between its corners kept per corner,
// the face lists corner_normals and corner_uv that the OBJ reader gives
// and the .psq codec codes per corner (spec/psq-format.md 8.5).
#ifndef PSQ_TOOLS_OPS_CORNER_WELD_H_
#define PSQ_TOOLS_OPS_CORNER_WELD_H_

#include <cstdint>
#include <memory>
#include <vector>

#include "psq/indexed_mesh.h"

namespace psq::detail {

// Reads the whole of `input` in memory (at most `memory_budget` bytes of
// it, else kLimit) and yields it welded: vertices merge when their
// positions and every property but a normal (nx ny nz) and a texture
// coordinate (u v, s t, texture_u texture_v, texture_s texture_t) are the
// same bits (-0.0 equal to 0.0); a normal or texture coordinate that
// differs among the vertices merged anywhere becomes a per-corner face
// list (float when its properties are, else double), else stays a vertex
// property. Triangles that the merge makes degenerate are dropped; the
// report's notes count what was merged and dropped.
class CornerWelder : public MeshSource {
 public:
  CornerWelder(std::unique_ptr<MeshSource> input, uint64_t memory_budget);
  ~CornerWelder() override;
  // Reads the input; errors are the input's, or kLimit.
  Status open();
  const MeshSchema& schema() const override;
  Status next(MeshItem* item) override;
  const SourceReport& report() const override;
  // What open() merged: the input's vertices and triangles, the vertices
  // merged into others and the triangles dropped.
  uint64_t input_vertices() const;
  uint64_t input_triangles() const;
  uint64_t merged_vertices() const;
  uint64_t dropped_triangles() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace psq::detail

#endif  // PSQ_TOOLS_OPS_CORNER_WELD_H_
