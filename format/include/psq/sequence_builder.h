// SPDX-License-Identifier: Apache-2.0
// psq/sequence_builder.h: a processing sequence from any indexed mesh
// ("generating processing sequences from scratch", paper section 3).
//
// build_sequence() reads an indexed mesh in file order (the vertex and
// triangle blocks of a PLY or OBJ) and feeds the converter (psq/converter.h)
// so that every vertex is finalized as soon as no later triangle can use it.
// It spools the input once to unlinked temporary files, then takes one of
// two paths:
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

struct BuildOptions {
  // The builder's share of the pipeline's budget (psq/memory_budget.h), in
  // bytes; it splits it between its external sorts, the rank array, the
  // spools and the converter's lookahead (sequence_builder.cpp, Shares).
  uint64_t memory_budget = uint64_t{512} << 20;
  std::string tmpdir;                            // spool and sort files; empty: $TMPDIR
  bool force_sort = false;                       // take the sort path even for coherent input
};

struct BuildReport {
  bool sorted = false;        // the external sort path was taken
  uint64_t window = 0;        // most vertices the coherent path keeps waiting during a block
  uint64_t vertices = 0;
  uint64_t triangles = 0;
  ConverterStats converter;
};

// Reads all of `source` and writes its processing sequence to `sink`
// (begin ... finish). Errors: the source's, kIo for temporary files, the
// sink's, and kLimit when the rank array would not fit `memory_budget`.
Status build_sequence(MeshSource& source, SequenceSink& sink, const BuildOptions& options,
                      BuildReport* report);

}  // namespace psq

#endif  // PSQ_SEQUENCE_BUILDER_H_
