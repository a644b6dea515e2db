// SPDX-License-Identifier: Apache-2.0
// psq/stream_qem.h: adaptive simplification by edge collapse in a fixed
// triangle buffer (Wu and Kobbelt 2003 on processing sequences, paper
// section 6).
//
// StreamQem is a sequence filter: a SequenceSink that reads a processing
// sequence as it arrives (from the .psq decoder's pump(), the sequence
// builder, any producer) and writes the simplified mesh, as a valid
// processing sequence, to another SequenceSink (the .psq encoder, a mesh
// writer), on the fly. Its memory is its triangle buffer
// (psq/triangle_buffer.h) and the converter's waiting area behind it,
// never the mesh:
//
// - READ: every input triangle enters the buffer and adds its plane, weighted
//   by its area, to the error quadrics of its vertices (Garland and
//   Heckbert); a border edge adds a plane through it, perpendicular to its
//   triangle, so that borders and holes are simplified as they go instead
//   of clogging the buffer (paper section 6).
// - DECIMATE: every 2048 triangles read (while they are in the processor's
//   caches), and whenever the buffer is full, edges are collapsed until the
//   triangles written and held are as many as the target allows for what
//   was read (the band along the input boundary, which nothing may change
//   yet, counted as it will be once simplified). Only edges with no vertex
//   on either boundary collapse. Each unlocked vertex keeps its cheapest
//   edge, updated as the buffer changes; the vertices are kept in bands of
//   a quarter octave of that cost, and each collapse is chosen by multiple
//   choice (Wu and Kobbelt): of `candidates` random vertices of the
//   cheapest band, the cheapest edge. A collapse costs each end's mean
//   squared distance to its planes, at the merged vertex's place: the
//   minimum of the summed quadric (gently pulled towards the edge's
//   midpoint where the quadric is flat) or an end, whichever is cheaper. A
//   border vertex stays on the border (a border edge collapses onto itself;
//   an interior vertex merges into a border neighbour), and a vertex that
//   must not move (a non-manifold cut, or a border with lock_border) keeps
//   its place and absorbs the other. A collapse is refused when it breaks
//   the link condition, leaves a vertex without triangles, flips a
//   triangle, turns one past a right angle from its normal when read, or
//   makes a sliver of a sound one; the vertex then offers its cheapest
//   collapse that passes, an end of an edge perhaps.
// - WRITE: when the buffer is full, triangles leave it across the output
//   boundary (TriangleBuffer::pick_output: end, fill, join, then the add
//   whose free vertex carries the largest error) until it is 7/8 full.
// At the end of the input, the rest is decimated to the target count
// (rounded to the nearest triangle) and written.
//
// Targets: a ratio of the input's triangles, a triangle count (which needs
// the input's count: the schema's, or QemOptions::input_triangles), and/or
// a largest error; decimation stops at the first reached. Components,
// handles and borders are kept unless the count target cannot be met
// otherwise: when no collapse is left and the count is still above the
// target's share of what was read (at the end, or when the buffer is
// full), first components that no collapse can reduce any more (every
// vertex of them refused), wholly in the buffer, of at most 1024
// triangles, go whole, the smallest first; then handles (or necks) that
// three edges go round, where the link condition refuses every collapse,
// are cut there and each side closed by a triangle (TriangleBuffer::cut),
// the narrowest first, and collapses go on. Either only within the largest
// error of a collapse so far and max_error (a dropped component's error is
// its half box diagonal, a cut's the circumradius of the cycle's longest
// edge); at the end, when nothing within that error is left, the count
// wins: one at a time, a component goes whatever it costs (the cheapest
// that fits in the excess, else the smallest when that leaves the count
// nearer the target), or else a handle is cut, still within max_error.
// Borders are kept, and where the target needs them gone it is not met
// (the report says what was achieved). The output is the same for the
// same input events and options (seeded choices).
//
// Vertex properties: a merged vertex keeps the values of the end it kept
// (the one nearer its new place); triangles keep theirs, except the
// corner lists corner_uv and corner_normals (texture coordinates and
// normals per corner, as an OBJ's vt and vn are read): the corners of a
// merged vertex take their chart's values at its new place, interpolated
// in the collapsed triangle of the same chart (normals renormalized). A
// seam of those values (a texture chart's border, a hard edge) is kept as
// a border is: a vertex on a seam merges only along it, and a collapse
// whose corners would leave their chart is refused.
#ifndef PSQ_STREAM_QEM_H_
#define PSQ_STREAM_QEM_H_

#include <cstdint>
#include <memory>

#include "psq/converter.h"
#include "psq/sequence.h"
#include "psq/status.h"
#include "psq/triangle_buffer.h"

namespace psq {

struct QemOptions {
  // Keep this fraction of the input's triangles (0 < ratio <= 1); 0: none.
  double ratio = 0;
  // Keep this many triangles; 0: none. Needs the input's triangle count.
  uint64_t target_triangles = 0;
  // Collapse only while the error stays at most this distance, relative to
  // the diagonal of the input's bounding box (the schema's bounds; else the
  // box of the vertices read so far); negative: no limit.
  double max_error = -1;
  // The input's triangle count when its schema does not declare one (a
  // count made by the caller), for target_triangles; 0: unknown.
  uint64_t input_triangles = 0;
  // Triangles in the buffer; 0: as many as memory_budget allows.
  uint32_t buffer_triangles = 0;
  // Bytes for the buffer and the converter's waiting area together (the
  // converter's floor of 65536 waiting triangles is about 18 MB).
  uint64_t memory_budget = uint64_t{48} << 20;
  // Random candidates compared for each collapse (Wu and Kobbelt's
  // multiple choice), 1..64.
  int candidates = 8;
  // Keep every border vertex where it is (tiles that must fit together).
  bool lock_border = false;
  uint64_t seed = 1;
};

struct QemReport {
  uint64_t input_vertices = 0;     // used by triangles
  uint64_t input_triangles = 0;
  uint64_t output_vertices = 0;    // as given to the converter
  uint64_t output_triangles = 0;
  uint64_t target_triangles = 0;   // what the ratio or count asked for; 0 without
  uint64_t collapses = 0;
  // Components removed whole (each at the least size collapses could give
  // it) because the count target could not be met otherwise.
  uint64_t components_dropped = 0;
  uint64_t triangles_dropped = 0;
  // Handles (or necks) cut where three edges went round them, for the
  // same reason.
  uint64_t handles_cut = 0;
  uint64_t isolated_dropped = 0;   // input vertices used by no triangle
  // Largest error of a collapse, relative to the box diagonal as max_error.
  double max_error = 0;
  uint32_t buffer_triangles = 0;   // the buffer's size
  uint64_t max_buffer_triangles = 0;
  uint64_t max_buffer_vertices = 0;
  ConverterStats converter;
};

class StreamQem : public SequenceSink {
 public:
  // `out` must outlive the simplifier.
  StreamQem(SequenceSink* out, const QemOptions& options);
  ~StreamQem() override;
  StreamQem(const StreamQem&) = delete;
  StreamQem& operator=(const StreamQem&) = delete;

  // Sets QemOptions::input_triangles; before begin().
  void set_input_triangles(uint64_t count);

  // Errors: kUsage for options out of range, no target, or a triangle count
  // target without a known input count; the sink's.
  Status begin(const MeshSchema& schema) override;
  // Errors: those of TriangleBuffer (kUsage for a sequence without slots or
  // masks, kBadSequence), the converter's and the sink's. Safe on untrusted
  // sequences. Errors are sticky.
  Status vertex(const SequenceVertex& v) override;
  Status triangle(const SequenceTriangle& t) override;
  Status finalize(uint32_t index) override;
  Status finish() override;

  // Complete after finish().
  const QemReport& report() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Reads all of `in` through a StreamQem into `out` (begin ... finish).
// `report` may be null. Errors: the source's and StreamQem's.
Status simplify_qem(SequenceSource& in, SequenceSink& out, const QemOptions& options, QemReport* report);

// The buffer size StreamQem picks for a memory budget (bytes), in triangles.
uint32_t qem_buffer_triangles(uint64_t memory_budget);

}  // namespace psq

#endif  // PSQ_STREAM_QEM_H_
