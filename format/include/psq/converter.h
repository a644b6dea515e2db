// psq/converter.h: the processing-sequence converter ("waiting area", paper
// section 3, Figure 3).
//
// It accepts indexed vertices and triangles in loosely local order, plus the
// finalization of each vertex ("no later triangle uses vertex v"), and emits
// a valid processing sequence (psq/sequence.h) to a SequenceSink. It grows
// regions: among the triangles it may emit it prefers those that complete
// boundary edges (end, fill, join, add, in that order, which keeps the
// boundary short) and starts a new region only when none is available.
//
// How it decides, and why it is correct:
// - A triangle waits until each of its vertices is settled: finalized, and
//   every vertex that shares a triangle with it finalized too. Then the fan of
//   each of its vertices is complete, and how the fan is cut is decided.
// - An edge with exactly two triangles of opposite orientation links them;
//   any other edge with two or more triangles is non-manifold and is cut.
// - Around a vertex, the triangles connected through links form fans. Each
//   fan becomes one vertex of the sequence; a second fan of the same input
//   vertex re-appears it (non-manifold vertex). Where a fan would hold two
//   triangles sharing a cut edge, the fan is split so that the sequence
//   stays an oriented manifold with borders.
// - Within that manifold every unemitted triangle of an active fan is
//   reachable across a boundary edge, so emission never gets stuck.
//
// Memory: the waiting area (triangles not yet emitted and their vertices),
// which a spatially coherent input keeps proportional to the sweep front,
// never to the mesh.
#ifndef PSQ_CONVERTER_H_
#define PSQ_CONVERTER_H_

#include <cstdint>
#include <memory>

#include "psq/indexed_mesh.h"
#include "psq/sequence.h"

namespace psq {

struct ConverterStats {
  uint64_t vertices_in = 0;
  uint64_t triangles_in = 0;
  uint64_t degenerate_dropped = 0;   // triangles with a repeated index
  // The input mesh's edges and vertices as the converter found them (each
  // edge counted once, degenerate triangles aside):
  uint64_t border_edges = 0;         // used by one triangle
  uint64_t nonmanifold_edges = 0;    // used by more than two triangles
  uint64_t misoriented_edges = 0;    // two triangles of the same orientation
  uint64_t nonmanifold_vertices = 0; // triangles form more than one fan (re-appears)
  uint64_t max_waiting_triangles = 0;
  uint64_t max_waiting_vertices = 0;
};

class SequenceConverter {
 public:
  // `out` must outlive the converter.
  explicit SequenceConverter(SequenceSink* out);
  ~SequenceConverter();
  SequenceConverter(const SequenceConverter&) = delete;
  SequenceConverter& operator=(const SequenceConverter&) = delete;

  // Passes the schema on to the sink. Errors: the sink's.
  Status begin(const MeshSchema& schema);
  // The data of input vertex `id` (any 32-bit number, given once). It may
  // come before or after triangles that use it, but before its finalize().
  // Errors: kBadIndex (given twice or after its finalization).
  Status vertex(uint32_t id, const double position[3], const PropertyValues& values);
  // A triangle over input vertex ids not yet finalized. Degenerate
  // triangles are dropped and counted. Errors: kBadIndex (a finalized vertex).
  Status triangle(const uint32_t id[3], const PropertyValues& values);
  // No triangle given from now on uses vertex `id`. Errors: kBadIndex (the
  // vertex was never given, or finalized twice), and the sink's errors.
  Status finalize(uint32_t id);
  // Everything was given and finalized; emits the rest and calls the sink's
  // finish(). Errors: kBadIndex (vertices never finalized), the sink's.
  Status finish();

  const ConverterStats& stats() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace psq

#endif  // PSQ_CONVERTER_H_
