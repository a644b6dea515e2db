// psq/sequence_builder.h: a processing sequence from any indexed mesh
// ("generating processing sequences from scratch", paper section 3).
//
// build_sequence() reads an indexed mesh in file order (the vertex and
// triangle blocks of a PLY or OBJ) and feeds the converter (psq/converter.h)
// so that every vertex is finalized as soon as no later triangle can use it.
// It spools the input once to unlinked temporary files, then takes one of
// two paths:
//
// - Coherent input (one pass): when every triangle's smallest vertex index
//   is at most `lag` below the largest smallest index seen before it, vertex
//   v is final once that running maximum passes v + lag. The triangles are
//   fed in file order and the vertices in index order. Memory is the
//   waiting area, never the mesh.
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
  uint64_t memory_budget = uint64_t{512} << 20;  // bytes, for the external sorts
  std::string tmpdir;                            // spool and sort files; empty: $TMPDIR
  bool force_sort = false;                       // take the sort path even for coherent input
};

struct BuildReport {
  bool sorted = false;        // the external sort path was taken
  uint64_t lag = 0;           // measured index lag of the input
  uint64_t span = 0;          // largest index spread within one triangle
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
