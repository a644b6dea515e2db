// SPDX-License-Identifier: Apache-2.0
// SequenceMeshSource (psq/sequence_mesh.h): a processing sequence as a mesh,
// re-appearing vertices merged (paper section 3, "non-manifold meshes").
#include "psq/sequence_mesh.h"

#include <algorithm>
#include <string>

namespace psq {

SequenceMeshSource::SequenceMeshSource(SequenceSource* source) : source_(source), schema_(source->schema()) {
  schema_.vertex_count = MeshSchema::kUnknown;
  schema_.triangle_count = MeshSchema::kUnknown;
}

// The mesh index of dense vertex `dense` (< next_dense_): re-appearances
// take the index of the vertex they re-appear and none of their own, so
// the index of an ordinary vertex is its dense index less the
// re-appearances before it.
uint32_t SequenceMeshSource::mesh_index(uint32_t dense) const {
  if (reappearing_.empty()) return dense;
  auto it = std::lower_bound(reappearing_.begin(), reappearing_.end(), dense);
  if (it != reappearing_.end() && *it == dense) return first_[it - reappearing_.begin()];
  return dense - static_cast<uint32_t>(it - reappearing_.begin());
}

Status SequenceMeshSource::next(MeshItem* item) {
  if (!error_.ok()) return error_;
  for (;;) {
    Status s = source_->next(&event_);
    if (!s.ok()) return error_ = std::move(s);
    switch (event_.kind) {
      case SequenceEvent::Kind::kVertex: {
        const SequenceVertex& v = event_.vertex;
        if (v.index != next_dense_)
          return error_ = Status(ErrorCode::kBadSequence, "vertex " + std::to_string(v.index) + " introduced out of order");
        ++next_dense_;
        if (v.reappears != kNoVertex) {
          if (v.reappears >= v.index)
            return error_ = Status(ErrorCode::kBadSequence, "vertex " + std::to_string(v.index) + " re-appears vertex " +
                                                                std::to_string(v.reappears) + ", not introduced before");
          const uint32_t first = mesh_index(v.reappears);
          reappearing_.push_back(v.index);
          first_.push_back(first);
          continue;
        }
        item->kind = MeshItem::Kind::kVertex;
        std::copy(v.position, v.position + 3, item->position);
        item->values.swap(event_.vertex.values);
        return Status();
      }
      case SequenceEvent::Kind::kTriangle: {
        const SequenceTriangle& t = event_.triangle;
        for (int k = 0; k < 3; ++k) {
          if (t.v[k] >= next_dense_)
            return error_ = Status(ErrorCode::kBadSequence, "a triangle uses vertex " + std::to_string(t.v[k]) +
                                                                 ", not introduced before");
          item->index[k] = mesh_index(t.v[k]);
        }
        item->kind = MeshItem::Kind::kTriangle;
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
