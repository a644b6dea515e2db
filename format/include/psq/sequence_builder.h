// SPDX-License-Identifier: Apache-2.0
// psq/sequence_builder.h: a processing sequence from any indexed mesh
// ("generating processing sequences from scratch", paper section 3).
//
// build_sequence() reads an indexed mesh in file order (the vertex and
// triangle blocks of a PLY or OBJ) and feeds the converter (psq/converter.h)
// so that every vertex is finalized as soon as no later triangle can use it.
// It spools the input once to unlinked temporary files, welds identical
// vertices when asked (BuildOptions::weld: a triangle soup becomes the
// indexed mesh it was made from), then takes one of two paths:
//
// - Coherent input (one pass): the triangles are fed in file order and the
//   vertices in index order as triangles reach them. While spooling, the
//   smallest index of each block of 4096 triangles is kept (4 bytes per
//   block); after block b, every vertex below the smallest index of all
//   later blocks is final. The input is coherent when the vertices this
//   keeps waiting during a block (the window) fit a share of
//   `memory_budget` and, if the sort's rank array fits it, are less than
//   half of the mesh (else the file order is not spatially coherent: one
//   pass would hold most of the mesh and grow regions full of holes; a
//   mesh of one block counts as such). Memory is the waiting area, never
//   the mesh.
// - Any other input (external spatial sort): vertices are sorted along the
//   longest axis of the bounding box, triangles by the rank of their first
//   vertex in that order, each with an external merge sort under
//   `memory_budget`; then for each vertex in order, the vertex, its
//   triangles and its finalization go to the converter. The only per-vertex
//   array in memory is the rank (4 bytes per vertex).
#ifndef PSQ_SEQUENCE_BUILDER_H_
#define PSQ_SEQUENCE_BUILDER_H_

#include <cstdint>
#include <string>

#include "psq/converter.h"
#include "psq/indexed_mesh.h"
#include "psq/sequence.h"

namespace psq {

// Which vertices build_sequence() merges before it builds the sequence
// (BuildOptions::weld). Identical means bit-identical values as the source
// gives them (a float input's values widened to double exactly), with +0.0
// and -0.0 taken as one value and a NaN equal only to the same NaN bits.
enum class WeldMode {
  kOff,        // every input vertex stays (the default: the mesh is kept exactly)
  kAll,        // identical positions and identical property values
  kPositions,  // identical positions; the first in file order keeps its values
};

struct BuildOptions {
  // The builder's share of the pipeline's budget (psq/memory_budget.h), in
  // bytes; it splits it between its external sorts, the rank array, the
  // spools and the converter's lookahead (sequence_builder.cpp, Shares).
  uint64_t memory_budget = uint64_t{512} << 20;
  std::string tmpdir;                            // spool and sort files; empty: $TMPDIR
  bool force_sort = false;                       // take the sort path even for coherent input
  // Welding: vertices identical under the mode become the first of them in
  // file order (the vertices keep their relative order); triangles are
  // renumbered, and a triangle two of whose corners become one vertex is
  // dropped (BuildReport::weld_dropped). Memory: an external sort of
  // 48-byte keys in the sort share and a map of 4 bytes per input vertex in
  // the rank array's share, or, when the map does not fit there, three more
  // external sorts and temporary files instead (BuildReport::weld_external).
  WeldMode weld = WeldMode::kOff;
};

struct BuildReport {
  bool sorted = false;        // the external sort path was taken
  uint64_t window = 0;        // most vertices the coherent path keeps waiting during a block
  uint64_t input_vertices = 0;   // as read
  uint64_t input_triangles = 0;
  uint64_t vertices = 0;         // after welding (the input's without)
  uint64_t triangles = 0;
  uint64_t welded_vertices = 0;  // merged into another: input_vertices - vertices
  uint64_t weld_dropped = 0;     // triangles dropped because welding made them degenerate
  uint64_t weld_sort_runs = 0;   // runs the weld's external sort spilled (0: it fit in memory)
  bool weld_external = false;    // the weld map did not fit: renumbered through external sorts
  // Without welding: the estimated share of the input's vertices whose
  // position repeats another's (a sample of the positions by hash; -1 when
  // too few to tell). A triangle soup is about 5/6.
  double duplicate_share = -1;
  ConverterStats converter;
};

// Reads all of `source` and writes its processing sequence to `sink`
// (begin ... finish), welding first when options.weld says so. Errors:
// the source's, kIo for temporary files, the sink's, kLimit when the rank
// array would not fit `memory_budget`, and kBadIndex
// when welding meets a triangle corner past the vertices.
Status build_sequence(MeshSource& source, SequenceSink& sink, const BuildOptions& options,
                      BuildReport* report);

}  // namespace psq

#endif  // PSQ_SEQUENCE_BUILDER_H_
