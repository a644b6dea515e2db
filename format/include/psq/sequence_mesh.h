// SPDX-License-Identifier: Apache-2.0
// psq/sequence_mesh.h: a processing sequence read as an indexed mesh.
//
// SequenceMeshSource pulls any SequenceSource (the .psq decoder, a filter's
// output read back, a parsed dump) and yields the mesh the sequence
// describes: each vertex when it is introduced, each triangle when it comes
// (so vertices and triangles interleave, and indices always refer to
// vertices already yielded), and re-appearing vertices (non-manifold cuts,
// paper section 3; spec/psq-dump.md A.2.1) merged back into the vertex they
// re-appear, so that the output is the input mesh again, uncut. Finalize
// events carry nothing a mesh needs and are skipped.
//
// Memory: 8 bytes per re-appearing vertex (a sorted table from its dense
// index to the vertex it re-appears), nothing per ordinary vertex.
// Safe on untrusted sequences as far as this adapter goes: a re-appearance
// of an index not introduced before, or indices out of order, are
// kBadSequence errors; the source's own errors pass through (sticky).
#ifndef PSQ_SEQUENCE_MESH_H_
#define PSQ_SEQUENCE_MESH_H_

#include <cstdint>
#include <vector>

#include "psq/indexed_mesh.h"
#include "psq/sequence.h"

namespace psq {

class SequenceMeshSource : public MeshSource {
 public:
  // `source` must outlive this one. The schema is the source's with the
  // counts unknown: re-appearances make the sequence's counts differ from
  // the mesh's.
  explicit SequenceMeshSource(SequenceSource* source);
  const MeshSchema& schema() const override { return schema_; }
  // Errors: the source's; kBadSequence (see above).
  Status next(MeshItem* item) override;
  const SourceReport& report() const override { return report_; }

 private:
  uint32_t mesh_index(uint32_t dense) const;

  SequenceSource* source_;
  MeshSchema schema_;
  SourceReport report_;
  SequenceEvent event_;
  Status error_;
  uint32_t next_dense_ = 0;  // the dense index the next vertex event must carry
  // Dense indices of re-appearing vertices (increasing) and the mesh index
  // of the vertex each re-appears.
  std::vector<uint32_t> reappearing_, first_;
};

}  // namespace psq

#endif  // PSQ_SEQUENCE_MESH_H_
