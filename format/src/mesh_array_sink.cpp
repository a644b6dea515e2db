// SPDX-License-Identifier: Apache-2.0
// format/src/mesh_array_sink.cpp: MeshArraySink (psq/mesh_arrays.h).
#include <cmath>
#include <string>

#include "psq/mesh_arrays.h"

namespace psq {

Status MeshArraySink::begin(const MeshSchema&) {
  mesh_->positions.clear();
  mesh_->indices.clear();
  identity_ = true;
  index_.clear();
  vertices_ = 0;
  return Status();
}

Status MeshArraySink::vertex(const SequenceVertex& v) {
  const uint32_t at = static_cast<uint32_t>(mesh_->positions.size() / 3);
  if (v.reappears != kNoVertex) {
    if (v.reappears >= vertices_)
      return Status(ErrorCode::kBadSequence, "vertex " + std::to_string(v.index) + " re-appears vertex " +
                                                 std::to_string(v.reappears) + ", which is not yet introduced");
    if (identity_) {
      // The map stops being the identity here: write it out.
      index_.resize(vertices_);
      for (uint32_t i = 0; i < vertices_; ++i) index_[i] = i;
      identity_ = false;
    }
    index_.push_back(index_[v.reappears]);
    ++vertices_;
    return Status();
  }
  float p[3];
  for (int k = 0; k < 3; ++k) {
    p[k] = static_cast<float>(v.position[k]);
    if (!std::isfinite(p[k]))
      return Status(ErrorCode::kLimit, "vertex " + std::to_string(v.index) +
                                           ": position beyond float range (the arrays hold floats)");
  }
  mesh_->positions.insert(mesh_->positions.end(), p, p + 3);
  if (!identity_) index_.push_back(at);
  ++vertices_;
  return Status();
}

Status MeshArraySink::triangle(const SequenceTriangle& t) {
  uint32_t v[3];
  for (int k = 0; k < 3; ++k) {
    if (t.v[k] >= vertices_)
      return Status(ErrorCode::kBadSequence, "triangle uses vertex " + std::to_string(t.v[k]) +
                                                 ", which is not yet introduced");
    v[k] = identity_ ? t.v[k] : index_[t.v[k]];
  }
  mesh_->indices.insert(mesh_->indices.end(), v, v + 3);
  return Status();
}

}  // namespace psq
