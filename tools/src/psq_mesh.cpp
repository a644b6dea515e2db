// psq/psq_mesh.h: a .psq stream as an indexed mesh.
#include "psq/psq_mesh.h"

#include <algorithm>

namespace psq {

PsqMeshSource::PsqMeshSource(PsqDecoder* decoder) : decoder_(decoder), schema_(decoder->schema()) {
  // The stream's counts are those of the sequence, which re-appearances
  // may exceed: the mesh's are not known up front.
  schema_.vertex_count = MeshSchema::kUnknown;
  schema_.triangle_count = MeshSchema::kUnknown;
}

// The mesh index of dense vertex `dense`: re-appearances are merged into
// their first occurrence and take no index of their own.
uint32_t PsqMeshSource::mesh_index(uint32_t dense) const {
  if (reappearing_.empty()) return dense;
  auto it = std::lower_bound(reappearing_.begin(), reappearing_.end(), dense);
  if (it != reappearing_.end() && *it == dense) return mesh_index(first_[it - reappearing_.begin()]);
  return dense - static_cast<uint32_t>(it - reappearing_.begin());
}

Status PsqMeshSource::next(MeshItem* item) {
  for (;;) {
    PSQ_RETURN_IF_ERROR(decoder_->next(&event_));
    switch (event_.kind) {
      case SequenceEvent::Kind::kVertex: {
        const SequenceVertex& v = event_.vertex;
        if (v.reappears != kNoVertex) {
          reappearing_.push_back(v.index);
          first_.push_back(v.reappears);
          continue;
        }
        item->kind = MeshItem::Kind::kVertex;
        std::copy(v.position, v.position + 3, item->position);
        item->values.swap(event_.vertex.values);
        return Status();
      }
      case SequenceEvent::Kind::kTriangle: {
        const SequenceTriangle& t = event_.triangle;
        item->kind = MeshItem::Kind::kTriangle;
        for (int k = 0; k < 3; ++k) item->index[k] = mesh_index(t.v[k]);
        item->values.swap(event_.triangle.values);
        return Status();
      }
      case SequenceEvent::Kind::kFinalize:
        continue;
      case SequenceEvent::Kind::kEnd:
        item->kind = MeshItem::Kind::kEnd;
        item->values.clear();
        return Status();
    }
  }
}

}  // namespace psq
