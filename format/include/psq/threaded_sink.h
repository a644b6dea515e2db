// SPDX-License-Identifier: Apache-2.0
// psq/threaded_sink.h: a pipeline stage that runs a sink on a thread of
// its own.
//
// A streaming pipeline such as `PlyReader -> Converter -> Encoder` runs on
// one thread: the encoder waits while the reader parses, and the reader
// waits while the encoder codes. Put a threaded sink in front of the
// encoder and it runs on a worker thread while the caller's thread goes on
// producing: on two cores the pipeline takes about as long as its slower
// half instead of the sum of both (bench/RESULTS.md, "Two threads in psq
// convert").
//
// The threaded sink packs each event into a batch of bytes and hands full
// batches to the worker, which replays them into the wrapped sink in the
// same order; the wrapped sink therefore sees exactly the events it would
// have seen without the thread, and writes the same bytes. Memory is
// bounded: at most `batches` batches of about `batch_bytes` bytes are in
// flight (by default 4 x 64 KiB; a triangle takes 48 bytes plus 8 per
// property value), and the producer waits when all are full.
//
// Handing events to another core costs memory traffic: the stage behind
// the thread must do enough work per event to pay for it. The .psq encoder
// does; a binary PLY writer behind the decoder does not (bench/RESULTS.md,
// "Two threads in psq convert").
//
// Errors: the wrapped sink's first error is sticky. The producer learns it
// from the next event call after it happened (every later call returns
// it too) or from finish() at the latest; batches in flight after the error
// are dropped. Events before begin() or after finish(), and a second
// begin() or finish(), are kUsage errors.
// Destroying a threaded sink without finish() (the producer failed) drops
// what is in flight and joins the worker. If no thread can be started, the
// sink forwards every event on the caller's thread instead.
//
// The wrapped sink must outlive the threaded sink and must not be used by
// anyone else meanwhile. begin() and finish() of the wrapped sink run on
// the caller's thread (finish() after the worker has replayed everything);
// vertex(), triangle() and finalize() run on the worker.
#ifndef PSQ_THREADED_SINK_H_
#define PSQ_THREADED_SINK_H_

#include <cstddef>
#include <cstdint>
#include <memory>

#include "psq/sequence.h"
#include "psq/status.h"

namespace psq {

class ThreadedSequenceSink : public SequenceSink {
 public:
  // Starts the worker thread. A batch is handed over once it holds
  // `batch_bytes` or more (at least 1); `batches` (at least 2) are in use.
  explicit ThreadedSequenceSink(SequenceSink* next, size_t batch_bytes = 64 * 1024, size_t batches = 4);
  ~ThreadedSequenceSink() override;
  ThreadedSequenceSink(const ThreadedSequenceSink&) = delete;
  ThreadedSequenceSink& operator=(const ThreadedSequenceSink&) = delete;

  // Forwards to the wrapped sink's begin() on the caller's thread (the
  // worker is idle until the first event).
  Status begin(const MeshSchema& schema) override;
  // Queue the event; return the wrapped sink's error once it failed.
  Status vertex(const SequenceVertex& v) override;
  Status triangle(const SequenceTriangle& t) override;
  Status finalize(uint32_t index) override;
  // Waits until the worker replayed every event, then calls the wrapped
  // sink's finish() (unless it failed). Returns the first error.
  Status finish() override;

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

}  // namespace psq

#endif  // PSQ_THREADED_SINK_H_
