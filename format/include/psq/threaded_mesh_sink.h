// SPDX-License-Identifier: Apache-2.0
// psq/threaded_mesh_sink.h: a StreamingMeshSink (psq/mesh_stream.h) run on
// a thread of its own.
//
// A filter's output side (the converter and the .psq encoder, or a mesh
// writer) can take as long as the filter itself: on 10% of a mesh's
// triangles, psq simplify spends about as much on the output as on reading
// the input. Put this stage in front of the output and it runs on a worker
// thread while the filter goes on. The events cross in the byte batches of
// ThreadedSequenceSink (psq/threaded_sink.h), with its guarantees: the
// wrapped sink sees exactly the events, in order, that it would have seen
// without the thread (the same output bytes); memory is a few batches;
// the wrapped sink's first error is sticky and comes back from a later
// event call or from finish(); begin() and finish() of the wrapped sink run
// on the caller's thread, the other events on the worker; without a
// thread, everything runs on the caller's.
//
// Only the output of a filter crosses (a tenth or a hundredth of its input
// events, for a simplifier), so the handover costs little even when no
// second core is free.
#ifndef PSQ_THREADED_MESH_SINK_H_
#define PSQ_THREADED_MESH_SINK_H_

#include <memory>

#include "psq/mesh_stream.h"
#include "psq/threaded_sink.h"

namespace psq {

class ThreadedMeshSink : public StreamingMeshSink {
 public:
  // Starts the worker. `next` must outlive this stage and not be used by
  // anyone else meanwhile.
  explicit ThreadedMeshSink(StreamingMeshSink* next);
  ~ThreadedMeshSink() override;
  ThreadedMeshSink(const ThreadedMeshSink&) = delete;
  ThreadedMeshSink& operator=(const ThreadedMeshSink&) = delete;

  Status begin(const MeshSchema& schema) override;
  Status vertex(uint32_t id, const double position[3], const PropertyValues& values) override;
  Status triangle(const uint32_t id[3], const PropertyValues& values) override;
  Status finalize(uint32_t id) override;
  // Waits until the worker passed every event on, then finishes the
  // wrapped sink. Returns the first error.
  Status finish() override;

 private:
  struct Replay;  // the worker's side: sequence records back to mesh events
  std::unique_ptr<Replay> replay_;
  std::unique_ptr<ThreadedSequenceSink> thread_;
  SequenceVertex v_;
  SequenceTriangle t_;
};

}  // namespace psq

#endif  // PSQ_THREADED_MESH_SINK_H_
