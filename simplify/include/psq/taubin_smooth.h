// SPDX-License-Identifier: Apache-2.0
// psq/taubin_smooth.h: Taubin's lambda|mu smoothing of a mesh larger than
// memory, streaming, in a triangle buffer (paper section 3, "buffer-based
// processing": iterative smoothing is one of its examples).
//
// TaubinSmoother is a sequence filter: a SequenceSink that reads a
// processing sequence and writes the smoothed mesh (the same triangles and
// vertices, moved) to another SequenceSink through the converter. Each step
// moves every interior vertex towards the average of its neighbours
// (uniform weights), by lambda on odd steps and by mu (negative: back
// out) on even ones, which smooths without the shrinking of plain
// Laplacian smoothing (Taubin, "A Signal Processing Approach to Fair
// Surface Design", SIGGRAPH 1995).
//
// Streaming: a vertex takes step s + 1 once the input finalized it (its
// neighbourhood is complete) and all its neighbours have taken step s, using
// their positions after step s; each vertex keeps its last two positions,
// so neighbours may be one step apart. The result is exactly that of
// running all steps over the whole mesh at once, for every vertex at least
// `iterations` rings from where the buffer had to write early: a triangle
// leaves the buffer once its three vertices have taken every step, and
// when the buffer is full before that, the triangles at its output
// boundary leave anyway and their vertices stop where they are (counted in
// the report). Border vertices and vertices of non-manifold cuts do not
// move (their neighbours still do).
//
// Memory: the buffer (psq/triangle_buffer.h) plus 26 bytes per buffered
// vertex, never the mesh.
#ifndef PSQ_TAUBIN_SMOOTH_H_
#define PSQ_TAUBIN_SMOOTH_H_

#include <cstdint>
#include <memory>

#include "psq/converter.h"
#include "psq/sequence.h"
#include "psq/status.h"

namespace psq {

struct SmoothOptions {
  // Smoothing steps, alternately lambda and mu, 0..255.
  int iterations = 10;
  double lambda = 0.5;
  double mu = -0.53;
  // Triangles in the buffer; 0: as many as memory_budget allows.
  uint32_t buffer_triangles = 0;
  // Bytes for the buffer and the converter's waiting area together.
  uint64_t memory_budget = uint64_t{48} << 20;
};

struct SmoothReport {
  uint64_t input_vertices = 0;   // used by triangles
  uint64_t input_triangles = 0;
  uint64_t output_vertices = 0;
  uint64_t output_triangles = 0;
  uint64_t smoothed_vertices = 0;  // took every step
  uint64_t stopped_vertices = 0;   // written before taking every step (buffer full)
  uint64_t isolated_dropped = 0;   // input vertices used by no triangle
  uint32_t buffer_triangles = 0;
  uint64_t max_buffer_triangles = 0;
  ConverterStats converter;
};

class TaubinSmoother : public SequenceSink {
 public:
  // `out` must outlive the smoother.
  TaubinSmoother(SequenceSink* out, const SmoothOptions& options);
  ~TaubinSmoother() override;
  TaubinSmoother(const TaubinSmoother&) = delete;
  TaubinSmoother& operator=(const TaubinSmoother&) = delete;

  // Errors: kUsage for options out of range; the sink's.
  Status begin(const MeshSchema& schema) override;
  // Errors: those of TriangleBuffer (kUsage for a sequence without slots or
  // masks, kBadSequence), the converter's and the sink's. Safe on untrusted
  // sequences. Errors are sticky.
  Status vertex(const SequenceVertex& v) override;
  Status triangle(const SequenceTriangle& t) override;
  Status finalize(uint32_t index) override;
  Status finish() override;

  // Complete after finish().
  const SmoothReport& report() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Reads all of `in` through a TaubinSmoother into `out`. `report` may be
// null. Errors: the source's and the smoother's.
Status smooth_taubin(SequenceSource& in, SequenceSink& out, const SmoothOptions& options, SmoothReport* report);

// The buffer size TaubinSmoother picks for a memory budget (bytes), in
// triangles.
uint32_t smooth_buffer_triangles(uint64_t memory_budget);

}  // namespace psq

#endif  // PSQ_TAUBIN_SMOOTH_H_
