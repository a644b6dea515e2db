// SPDX-License-Identifier: Apache-2.0
// DenseMeshSink and TeeMeshSink (psq/mesh_stream.h).
#include "psq/mesh_stream.h"

#include <string>

#include "flat_map.h"

namespace psq {

struct DenseMeshSink::Impl {
  MeshSink* out = nullptr;
  detail::IdMap dense;  // id given and not finalized -> its index
  uint64_t vertices = 0, triangles = 0;
  bool begun = false, finished = false;
  Status error;

  Status fail(Status s) {
    error = std::move(s);
    return error;
  }
  bool open() const { return begun && !finished; }
};

DenseMeshSink::DenseMeshSink(MeshSink* out) : impl_(std::make_unique<Impl>()) { impl_->out = out; }
DenseMeshSink::~DenseMeshSink() = default;

uint64_t DenseMeshSink::vertices() const { return impl_->vertices; }
uint64_t DenseMeshSink::triangles() const { return impl_->triangles; }

Status DenseMeshSink::begin(const MeshSchema& schema) {
  Impl& m = *impl_;
  if (!m.error.ok()) return m.error;
  if (m.begun) return m.fail(Status(ErrorCode::kUsage, "begin() called twice"));
  m.begun = true;
  Status s = m.out->begin(schema);
  return s.ok() ? s : m.fail(std::move(s));
}

Status DenseMeshSink::vertex(uint32_t id, const double position[3], const PropertyValues& values) {
  Impl& m = *impl_;
  if (!m.error.ok()) return m.error;
  if (!m.open()) return m.fail(Status(ErrorCode::kUsage, "vertex() outside begin() and finish()"));
  if (id == detail::IdMap::kEmpty) return m.fail(Status(ErrorCode::kBadIndex, "vertex id 4294967295 is reserved"));
  if (m.dense.find(id) != detail::IdMap::kEmpty)
    return m.fail(Status(ErrorCode::kBadIndex, "vertex " + std::to_string(id) + " given twice"));
  if (m.vertices >= 0xffffffffu) return m.fail(Status(ErrorCode::kLimit, "more than 4294967295 vertices"));
  m.dense.insert(id, static_cast<uint32_t>(m.vertices++));
  Status s = m.out->vertex(position, values);
  return s.ok() ? s : m.fail(std::move(s));
}

Status DenseMeshSink::triangle(const uint32_t id[3], const PropertyValues& values) {
  Impl& m = *impl_;
  if (!m.error.ok()) return m.error;
  if (!m.open()) return m.fail(Status(ErrorCode::kUsage, "triangle() outside begin() and finish()"));
  uint32_t index[3];
  for (int k = 0; k < 3; ++k) {
    index[k] = m.dense.find(id[k]);
    if (index[k] == detail::IdMap::kEmpty || id[k] == detail::IdMap::kEmpty)
      return m.fail(Status(ErrorCode::kBadIndex,
                           "a triangle uses vertex " + std::to_string(id[k]) + ", which was not given or is finalized"));
  }
  ++m.triangles;
  Status s = m.out->triangle(index, values);
  return s.ok() ? s : m.fail(std::move(s));
}

Status DenseMeshSink::finalize(uint32_t id) {
  Impl& m = *impl_;
  if (!m.error.ok()) return m.error;
  if (!m.open()) return m.fail(Status(ErrorCode::kUsage, "finalize() outside begin() and finish()"));
  if (id == detail::IdMap::kEmpty || m.dense.find(id) == detail::IdMap::kEmpty)
    return m.fail(Status(ErrorCode::kBadIndex, "vertex " + std::to_string(id) + " finalized but not given, or twice"));
  m.dense.erase(id);
  return Status();
}

Status DenseMeshSink::finish() {
  Impl& m = *impl_;
  if (!m.error.ok()) return m.error;
  if (!m.open()) return m.fail(Status(ErrorCode::kUsage, "finish() without begin(), or twice"));
  m.finished = true;
  Status s = m.out->finish();
  return s.ok() ? s : m.fail(std::move(s));
}

Status TeeMeshSink::begin(const MeshSchema& schema) {
  PSQ_RETURN_IF_ERROR(a_->begin(schema));
  return b_->begin(schema);
}
Status TeeMeshSink::vertex(uint32_t id, const double position[3], const PropertyValues& values) {
  PSQ_RETURN_IF_ERROR(a_->vertex(id, position, values));
  return b_->vertex(id, position, values);
}
Status TeeMeshSink::triangle(const uint32_t id[3], const PropertyValues& values) {
  PSQ_RETURN_IF_ERROR(a_->triangle(id, values));
  return b_->triangle(id, values);
}
Status TeeMeshSink::finalize(uint32_t id) {
  PSQ_RETURN_IF_ERROR(a_->finalize(id));
  return b_->finalize(id);
}
Status TeeMeshSink::finish() {
  PSQ_RETURN_IF_ERROR(a_->finish());
  return b_->finish();
}

}  // namespace psq
