// SPDX-License-Identifier: Apache-2.0
// psq/psq_mesh.h: a .psq stream read as an indexed mesh.
//
// PsqMeshSource pulls a PsqDecoder and yields the mesh the processing
// sequence describes: each vertex when it is introduced, each triangle when
// it is decoded (so vertices and triangles interleave; indices always refer
// to vertices already yielded), and re-appearing vertices (non-manifold
// cuts, spec/psq-dump.md A.2.1) merged back into the vertex they re-appear,
// so that the output is the input mesh again. It is SequenceMeshSource
// (psq/sequence_mesh.h) over the decoder. Memory: the decoder's, plus 8
// bytes per re-appearing vertex.
#ifndef PSQ_PSQ_MESH_H_
#define PSQ_PSQ_MESH_H_

#include "psq/psq_codec.h"
#include "psq/sequence_mesh.h"

namespace psq {

class PsqMeshSource : public SequenceMeshSource {
 public:
  // `decoder` must be open and outlive the source. Errors of next(): the
  // decoder's.
  explicit PsqMeshSource(PsqDecoder* decoder) : SequenceMeshSource(decoder) {}
};

}  // namespace psq

#endif  // PSQ_PSQ_MESH_H_
