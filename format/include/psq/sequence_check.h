// SPDX-License-Identifier: Apache-2.0
// psq/sequence_check.h: validation and statistics of a processing sequence
// in one streaming pass (paper section 3 and Table 1).
//
// SequenceChecker is a SequenceSink that recomputes the processing boundary
// from the triangles alone and checks every claim of the stream against the
// rules of spec/psq-dump.md, A.2: each triangle's op (a join's third vertex
// on the boundary), its new corners (exactly the vertices introduced right
// before it), its border, leaving and entering edges, consistent orientation
// (an edge completes only a boundary edge of the opposite direction), that no
// triangle uses a closed edge (a border, or an edge two triangles completed),
// canonical finalization (a vertex is finalized right after the triangle
// that leaves no boundary edge at it, in corner order; an isolated vertex
// right after its vertex event), slots (a border edge has none), and that
// nothing stays open at the end.
//
// Masks: new_mask is always checked. leaving_mask, entering_mask and
// final_mask are checked from the first triangle that carries any of them
// on; a producer that computes none of them (a parsed dump) leaves all
// three zero on every triangle. Slots are checked where given (not kNoSlot).
//
// It also counts what `psq info` reports. Memory is proportional to the
// boundary (its vertices with their closed edges), plus about 24 bytes per
// vertex for the component, border-loop and hole union-finds, the first
// occurrences and the index of the active vertices. SequenceCounter
// (psq/sequence_count.h) counts the same without checking, in memory
// proportional to the boundary.
#ifndef PSQ_SEQUENCE_CHECK_H_
#define PSQ_SEQUENCE_CHECK_H_

#include <cstdint>
#include <memory>

#include "psq/sequence.h"

namespace psq {

struct SequenceStats {
  uint64_t vertices = 0;           // input vertices (re-appearances not counted)
  uint64_t reappearances = 0;      // vertices introduced again by a non-manifold cut
  uint64_t isolated_vertices = 0;  // used by no triangle
  uint64_t triangles = 0;
  uint64_t ops[5] = {0, 0, 0, 0, 0};  // triangles per Op
  uint64_t components = 0;         // connected by shared vertices (cuts re-joined)
  uint64_t border_edges = 0;       // edges used by one triangle, cut edges included
  uint64_t border_loops = 0;       // holes: connected loops of border edges that are not cuts
  int64_t handles = 0;             // genus, from the Euler characteristic of the cut mesh
  uint64_t nonmanifold_vertices = 0;  // input vertices that re-appear
  uint64_t nonmanifold_edges = 0;     // input edges cut (more than two triangles, misoriented, or split off a fan)
  uint64_t max_boundary_vertices = 0; // most vertices active (introduced, not finalized) at once
  uint64_t max_boundary_edges = 0;    // most open boundary edges at once
  // The input mesh: each re-appearing vertex merged into its first
  // occurrence (spec/psq-dump.md A.2.1), counted as SequenceConverter counts
  // its input (ConverterStats), so that a sequence and the mesh it was made
  // from give the same numbers. Cut edges are recognised by the
  // non-manifold flag, which A.2.1 puts on every triangle of a cut edge;
  // edges of degenerate triangles are not counted.
  uint64_t unreferenced_vertices = 0;   // input vertices no triangle uses
  uint64_t degenerate_triangles = 0;    // two corners are occurrences of one input vertex
  uint64_t mesh_border_edges = 0;       // used by one triangle (border edges not cut)
  uint64_t mesh_nonmanifold_edges = 0;  // cut edges of more than two triangles
  uint64_t mesh_misoriented_edges = 0;  // cut edges of two triangles of the same orientation
};

class SequenceChecker : public SequenceSink {
 public:
  SequenceChecker();
  ~SequenceChecker() override;

  // Each returns kBadSequence with a message naming the triangle (its
  // 0-based number in the stream) at the first violation.
  Status begin(const MeshSchema& schema) override;
  Status vertex(const SequenceVertex& v) override;
  Status triangle(const SequenceTriangle& t) override;
  Status finalize(uint32_t index) override;
  Status finish() override;

  // Complete after finish().
  const SequenceStats& stats() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace psq

#endif  // PSQ_SEQUENCE_CHECK_H_
