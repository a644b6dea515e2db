// SPDX-License-Identifier: Apache-2.0
// ThreadedMeshSink (psq/threaded_mesh_sink.h): a streaming mesh's events
// carried over ThreadedSequenceSink's batches. A vertex travels as a
// sequence vertex (its id in the index), a triangle as a sequence
// triangle (its ids in v), a finalization as itself; the worker turns them
// back. The sequence fields that a mesh stream has no use for cross as
// their defaults: ThreadedSequenceSink checks nothing, it only carries.
#include "psq/threaded_mesh_sink.h"

#include <algorithm>

namespace psq {

struct ThreadedMeshSink::Replay : SequenceSink {
  explicit Replay(StreamingMeshSink* n) : next(n) {}
  Status begin(const MeshSchema& schema) override { return next->begin(schema); }
  Status vertex(const SequenceVertex& v) override { return next->vertex(v.index, v.position, v.values); }
  Status triangle(const SequenceTriangle& t) override { return next->triangle(t.v, t.values); }
  Status finalize(uint32_t id) override { return next->finalize(id); }
  Status finish() override { return next->finish(); }
  StreamingMeshSink* next;
};

ThreadedMeshSink::ThreadedMeshSink(StreamingMeshSink* next)
    : replay_(std::make_unique<Replay>(next)), thread_(std::make_unique<ThreadedSequenceSink>(replay_.get())) {}

ThreadedMeshSink::~ThreadedMeshSink() {
  thread_.reset();  // joins the worker before the replay it uses goes
}

Status ThreadedMeshSink::begin(const MeshSchema& schema) { return thread_->begin(schema); }

Status ThreadedMeshSink::vertex(uint32_t id, const double position[3], const PropertyValues& values) {
  v_.index = id;
  std::copy(position, position + 3, v_.position);
  v_.values = values;
  return thread_->vertex(v_);
}

Status ThreadedMeshSink::triangle(const uint32_t id[3], const PropertyValues& values) {
  std::copy(id, id + 3, t_.v);
  t_.values = values;
  return thread_->triangle(t_);
}

Status ThreadedMeshSink::finalize(uint32_t id) { return thread_->finalize(id); }

Status ThreadedMeshSink::finish() { return thread_->finish(); }

}  // namespace psq
