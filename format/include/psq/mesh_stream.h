// SPDX-License-Identifier: Apache-2.0
// psq/mesh_stream.h: a streaming indexed mesh with finalization, the output
// interface of every filter (paper section 3, Figure 3).
//
// A filter (a simplifier, a smoother) produces vertices and triangles in an
// order of its own, not a processing sequence: a triangle of a simplified
// mesh is known before its vertices are, and a vertex is output when the
// filter has done with it. What it can say is when a vertex is *finalized*:
// no later triangle uses it. StreamingMeshSink is that output: vertices
// named by ids of the producer's choice, triangles over those ids, and the
// finalization of each id. Two implementations reach every output format
// the same way:
//
// - SequenceConverter (psq/converter.h), the waiting area, which re-orders
//   the stream into a processing sequence for a SequenceSink (the .psq
//   encoder, a checker, another filter);
// - DenseMeshSink (below), which renumbers the ids densely in the order the
//   vertices come and writes to a MeshSink (the PLY, OBJ and Draco writers).
//
// The contract: begin() once; vertex(id) once per id (any 32-bit number but
// 4294967295), before finalize(id); triangle() over ids not yet finalized;
// finalize(id) once per id; finish() once. SequenceConverter accepts a
// triangle before the vertices it uses; DenseMeshSink needs the vertices
// first (every filter of simplify/ gives them first). An id is given
// once: SequenceConverter remembers finalized ids and rejects them
// (kBadIndex); DenseMeshSink forgets an id at its finalization and would
// take it again as a new vertex.
#ifndef PSQ_MESH_STREAM_H_
#define PSQ_MESH_STREAM_H_

#include <cstdint>
#include <memory>

#include "psq/indexed_mesh.h"
#include "psq/status.h"

namespace psq {

class StreamingMeshSink {
 public:
  virtual ~StreamingMeshSink() = default;
  virtual Status begin(const MeshSchema& schema) = 0;
  virtual Status vertex(uint32_t id, const double position[3], const PropertyValues& values) = 0;
  virtual Status triangle(const uint32_t id[3], const PropertyValues& values) = 0;
  virtual Status finalize(uint32_t id) = 0;
  virtual Status finish() = 0;
};

// A StreamingMeshSink writing to a MeshSink: vertex ids become 0, 1, 2, ...
// in the order vertex() gives them, triangles are passed on with those
// indices, and finalization frees the id's entry. Memory: one map entry (8
// to 16 bytes) per vertex given and not yet finalized. Errors (sticky):
// kBadIndex for an id given twice, a triangle over an id not given or
// already finalized, or finalize() of an id not given; kUsage for events
// before begin() or after finish(); the MeshSink's errors.
class DenseMeshSink : public StreamingMeshSink {
 public:
  // `out` must outlive the adapter.
  explicit DenseMeshSink(MeshSink* out);
  ~DenseMeshSink() override;
  DenseMeshSink(const DenseMeshSink&) = delete;
  DenseMeshSink& operator=(const DenseMeshSink&) = delete;

  Status begin(const MeshSchema& schema) override;
  Status vertex(uint32_t id, const double position[3], const PropertyValues& values) override;
  Status triangle(const uint32_t id[3], const PropertyValues& values) override;
  Status finalize(uint32_t id) override;
  Status finish() override;

  uint64_t vertices() const;
  uint64_t triangles() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Counts what it is given and checks nothing else; for a filter's dry run
// (psq simplify --triangles counts the output of a trial grid with it).
class CountingMeshSink : public StreamingMeshSink {
 public:
  Status begin(const MeshSchema&) override { return Status(); }
  Status vertex(uint32_t, const double*, const PropertyValues&) override {
    ++vertices;
    return Status();
  }
  Status triangle(const uint32_t*, const PropertyValues&) override {
    ++triangles;
    return Status();
  }
  Status finalize(uint32_t) override { return Status(); }
  Status finish() override { return Status(); }

  uint64_t vertices = 0;
  uint64_t triangles = 0;
};

// Passes every event to two sinks, the first, then the second (for example
// a writer and a SequenceConverter that counts the output's non-manifold
// elements). Returns the first error.
class TeeMeshSink : public StreamingMeshSink {
 public:
  TeeMeshSink(StreamingMeshSink* a, StreamingMeshSink* b) : a_(a), b_(b) {}
  Status begin(const MeshSchema& schema) override;
  Status vertex(uint32_t id, const double position[3], const PropertyValues& values) override;
  Status triangle(const uint32_t id[3], const PropertyValues& values) override;
  Status finalize(uint32_t id) override;
  Status finish() override;

 private:
  StreamingMeshSink* a_;
  StreamingMeshSink* b_;
};

}  // namespace psq

#endif  // PSQ_MESH_STREAM_H_
