// psq/psq_mesh.h: a .psq stream read as an indexed mesh.
//
// PsqMeshSource pulls a PsqDecoder and yields the mesh the processing
// sequence describes: each vertex when it is introduced, each triangle when
// it is decoded (so vertices and triangles interleave; indices always refer
// to vertices already yielded), and re-appearing vertices (non-manifold
// cuts, spec/psq-dump.md A.2.1) merged back into the vertex they re-appear,
// so that the output is the input mesh again. Memory: the decoder's, plus 4
// bytes per re-appearing vertex.
#ifndef PSQ_PSQ_MESH_H_
#define PSQ_PSQ_MESH_H_

#include <cstdint>
#include <vector>

#include "psq/indexed_mesh.h"
#include "psq/psq_codec.h"

namespace psq {

class PsqMeshSource : public MeshSource {
 public:
  // `decoder` must be open and outlive the source.
  explicit PsqMeshSource(PsqDecoder* decoder);
  const MeshSchema& schema() const override { return schema_; }
  // Errors: the decoder's.
  Status next(MeshItem* item) override;
  const SourceReport& report() const override { return report_; }

 private:
  uint32_t mesh_index(uint32_t dense) const;

  PsqDecoder* decoder_;
  MeshSchema schema_;
  SourceReport report_;
  SequenceEvent event_;
  // Dense indices of re-appearing vertices (increasing) and the dense index
  // of the vertex each re-appears.
  std::vector<uint32_t> reappearing_, first_;
};

}  // namespace psq

#endif  // PSQ_PSQ_MESH_H_
