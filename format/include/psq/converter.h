// SPDX-License-Identifier: Apache-2.0
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
//   Each edge is decided once, when the first of its two ends is finalized
//   (all its triangles are in then).
// - Around a vertex, the triangles connected through links form fans. Each
//   fan becomes one vertex of the sequence; a second fan of the same input
//   vertex re-appears it (non-manifold vertex). Where a fan would hold two
//   triangles sharing a cut edge, the fan is split so that the sequence
//   stays an oriented manifold with borders.
// - Within that manifold every unemitted triangle of an active fan is
//   reachable across a boundary edge, so emission never gets stuck. A fan's
//   boundary edges are exactly its links between emitted and unemitted
//   triangles, so a sequence vertex is finalized right after the triangle
//   that emits the last triangle of its fan, which is when no boundary edge
//   touches it any more: finalization is canonical (spec/psq-dump.md, A.2
//   rule 4), in the triangle's corner order; an isolated vertex is
//   finalized right after its vertex event.
//
// Cost: linear in the input, also around a vertex of any valence (the
// triangles of a vertex are grouped by neighbour through a mark on the
// neighbour, never by comparing pairs).
//
// Memory: the waiting area (triangles not yet emitted and their vertices),
// which a spatially coherent input keeps proportional to the sweep front,
// never to the mesh; plus the set of finalized input ids (see vertex()):
// per range of 2^16 ids, nothing once all its ids are finalized, else the
// smaller of 2 bytes per finalized id and 8 KiB (a bitmap). Ids numbered
// densely and finalized roughly in increasing order (any coherent input)
// thus cost a few KiB; in any order, about one bit per id of the ranges
// in use; plus a fixed 512 KiB (a cache of id lookups).
//
// Errors are sticky: after a call fails, every later call (begin included)
// returns the same error and does nothing.
#ifndef PSQ_CONVERTER_H_
#define PSQ_CONVERTER_H_

#include <cstdint>
#include <memory>

#include "psq/indexed_mesh.h"
#include "psq/mesh_stream.h"
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

// The converter is the StreamingMeshSink (psq/mesh_stream.h) through
// which a filter's output becomes a processing sequence.
class SequenceConverter final : public StreamingMeshSink {
 public:
  // `out` must outlive the converter.
  explicit SequenceConverter(SequenceSink* out);
  ~SequenceConverter() override;
  SequenceConverter(const SequenceConverter&) = delete;
  SequenceConverter& operator=(const SequenceConverter&) = delete;

  // Bounds the lookahead: while input still arrives, the converter keeps
  // ready triangles waiting, at least 65536 and 32 per open boundary edge,
  // so that a region grows into triangles that already arrived; beyond
  // 65536 they take at most `bytes` (about 200 bytes each; default 128
  // MiB). Call before the first triangle.
  void set_lookahead_budget(uint64_t bytes);
  // Lowers (or raises) that minimum of 65536 ready triangles (at least 1),
  // for a pipeline whose memory matters more than the last percent of its
  // compression: a filter's output (psq simplify keeps 4096; on a
  // simplified foam of 200k triangles, 1.1% more bytes for two thirds of
  // the converter's memory). Call before the first triangle.
  void set_lookahead_minimum(uint64_t triangles);
  // A hint: the input has about `vertices` vertices and `triangles`
  // triangles, so that the waiting area takes its room at once instead of
  // growing by copies. Reserves address space only (no page is touched),
  // at most the lookahead's budget's worth; the output does not depend on
  // it. Call after set_lookahead_budget(), before the first vertex.
  void reserve(uint64_t vertices, uint64_t triangles);
  // A hint: a triangle over these ids comes a few calls from now, so that
  // the records of those already given start loading. Changes nothing.
  void prefetch(const uint32_t id[3]) const;
  // Passes the schema on to the sink. Errors: the sink's.
  Status begin(const MeshSchema& schema) override;
  // The data of input vertex `id` (any 32-bit number but 4294967295, given
  // once). It may come before or after triangles that use it, but before its
  // finalize(). Errors: kBadIndex (given twice, or after its finalization,
  // also long after: finalized ids are remembered, see Memory above).
  Status vertex(uint32_t id, const double position[3], const PropertyValues& values) override;
  // A triangle over input vertex ids not yet finalized. Degenerate
  // triangles are dropped and counted. Errors: kBadIndex (a finalized
  // vertex, however long ago), kLimit (more than 2^30 triangles waiting).
  Status triangle(const uint32_t id[3], const PropertyValues& values) override;
  // No triangle given from now on uses vertex `id`. Errors: kBadIndex (the
  // vertex was never given, or finalized twice), and the sink's errors.
  Status finalize(uint32_t id) override;
  // Everything was given; emits the rest and calls the sink's finish().
  // Vertices not finalized yet are finalized here. Errors: kBadIndex (a
  // vertex that triangles use was never given), the sink's.
  Status finish() override;

  const ConverterStats& stats() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace psq

#endif  // PSQ_CONVERTER_H_
