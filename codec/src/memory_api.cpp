// SPDX-License-Identifier: Apache-2.0
// codec/src/memory_api.cpp: psq/psq_memory.h, the in-memory door over the
// streaming encoder and decoder.
#include <cmath>
#include <string>

#include "psq/psq_memory.h"

#include "psq/psq_codec.h"
#include "psq/sequence_builder.h"

namespace psq {

namespace {

// The arrays as a mesh source (psq/indexed_mesh.h): every vertex, then
// every triangle, checked as a source must check them.
class ArrayMeshSource : public MeshSource {
 public:
  ArrayMeshSource(const float* positions, size_t vertices, const uint32_t* indices, size_t triangles)
      : positions_(positions), vertices_(vertices), indices_(indices), triangles_(triangles) {
    schema_.position_type = ScalarType::kFloat32;
    schema_.vertex_count = static_cast<int64_t>(vertices);
    schema_.triangle_count = static_cast<int64_t>(triangles);
  }
  const MeshSchema& schema() const override { return schema_; }
  const SourceReport& report() const override { return report_; }
  Status next(MeshItem* item) override {
    if (!error_.ok()) return error_;
    if (at_ < vertices_) {
      item->kind = MeshItem::Kind::kVertex;
      for (int k = 0; k < 3; ++k) {
        const float p = positions_[3 * at_ + static_cast<size_t>(k)];
        if (!std::isfinite(p))
          return error_ = Status(ErrorCode::kBadValue, "vertex " + std::to_string(at_) + ": position is not finite");
        item->position[k] = p;
      }
      item->values.clear();
      ++at_;
      return Status();
    }
    const size_t t = at_ - vertices_;
    if (t < triangles_) {
      item->kind = MeshItem::Kind::kTriangle;
      for (int k = 0; k < 3; ++k) {
        const uint32_t v = indices_[3 * t + static_cast<size_t>(k)];
        if (v >= vertices_)
          return error_ = Status(ErrorCode::kBadValue, "triangle " + std::to_string(t) + ": index " +
                                                           std::to_string(v) + " is not below the vertex count " +
                                                           std::to_string(vertices_));
        item->index[k] = v;
      }
      item->values.clear();
      ++at_;
      return Status();
    }
    item->kind = MeshItem::Kind::kEnd;
    return Status();
  }

 private:
  const float* positions_;
  size_t vertices_;
  const uint32_t* indices_;
  size_t triangles_;
  size_t at_ = 0;
  MeshSchema schema_;
  SourceReport report_;
  Status error_;
};

}  // namespace

Status encode_mesh(const float* positions, size_t vertex_count, const uint32_t* indices, size_t triangle_count,
                   const EncodeOptions& options, std::vector<uint8_t>* out) {
  if (vertex_count >= 0xffffffffull)
    return Status(ErrorCode::kLimit, "more than 4294967294 vertices");
  ArrayMeshSource source(positions, vertex_count, indices, triangle_count);
  std::vector<uint8_t> bytes;
  VectorWriter writer(&bytes);
  PsqEncoder encoder(&writer, options);
  BuildReport report;
  PSQ_RETURN_IF_ERROR(build_sequence(source, encoder, BuildOptions(), &report));
  out->insert(out->end(), bytes.begin(), bytes.end());
  return Status();
}

}  // namespace psq
