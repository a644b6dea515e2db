// SPDX-License-Identifier: Apache-2.0
// psq/threaded_sink.h: events packed into byte batches on the producing
// thread, replayed into the wrapped sink by a worker.
#include "psq/threaded_sink.h"

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <cstring>
#include <deque>
#include <memory>
#include <mutex>
#include <system_error>
#include <thread>
#include <utility>
#include <vector>

namespace psq {
namespace {

// Event records in a batch, each a kind byte and its fields in native byte
// order (the batch never leaves the process):
//   vertex:   index, slot, reappears (u32), position (3 f64), n (u32), n f64
//   triangle: v (3 u32), op, the six masks (u8), vslot, eslot (3 u32 each),
//             n (u32), n f64
//   finalize: index (u32)
// A packed triangle takes 48 bytes plus its values instead of the ~150 of
// a SequenceEvent: the bytes that cross from one core to the other are
// what the thread costs.
enum : uint8_t { kVertexRecord = 0, kTriangleRecord = 1, kFinalizeRecord = 2 };

// Writes a record's fields into bytes reserved for it (one resize per
// record).
struct Writer {
  uint8_t* p;
  template <class T>
  void put(const T& v) {
    std::memcpy(p, &v, sizeof(T));
    p += sizeof(T);
  }
  void put_values(const PropertyValues& values) {
    put(static_cast<uint32_t>(values.size()));
    if (!values.empty()) std::memcpy(p, values.data(), values.size() * sizeof(double));
    p += values.size() * sizeof(double);
  }
};
// A batch: its bytes and how many hold records. Appending moves `used`
// (a vector's resize per record would zero the bytes first, and cost a
// call); the buffer grows only for a record that does not fit (many
// property values).
struct Batch {
  std::unique_ptr<uint8_t[]> data;
  size_t capacity = 0;
  size_t used = 0;
};
Writer grow(Batch* b, size_t bytes) {
  if (b->capacity - b->used < bytes) {
    const size_t capacity = std::max(b->used + bytes, 2 * b->capacity);
    std::unique_ptr<uint8_t[]> bigger(new uint8_t[capacity]);
    if (b->used > 0) std::memcpy(bigger.get(), b->data.get(), b->used);
    b->data = std::move(bigger);
    b->capacity = capacity;
  }
  Writer w{b->data.get() + b->used};
  b->used += bytes;
  return w;
}

// Reads what Writer wrote; the batch is ours, so no bounds checks beyond
// the producer's own.
struct Reader {
  const uint8_t* p;
  template <class T>
  T get() {
    T v;
    std::memcpy(&v, p, sizeof(T));
    p += sizeof(T);
    return v;
  }
  void get_values(PropertyValues* values) {
    const uint32_t n = get<uint32_t>();
    values->resize(n);
    if (n) std::memcpy(values->data(), p, n * sizeof(double));
    p += n * sizeof(double);
  }
};

}  // namespace

// A bounded queue of byte batches between one producer and one worker. The
// producer appends records to batch `cur_`; a batch that holds
// `batch_bytes` or more goes to `full_`, and replayed ones come back
// through `free_` (keeping their capacity: steady state allocates nothing).
struct ThreadedSequenceSink::Impl {
  Impl(SequenceSink* n, size_t batch_bytes, size_t batches)
      : next(n), batch_bytes_(batch_bytes < 1 ? 1 : batch_bytes), pool_(batches < 2 ? 2 : batches) {
    for (size_t b = 1; b < pool_.size(); ++b) free_.push_back(b);
    for (Batch& b : pool_) {
      b.capacity = batch_bytes_ + 256;
      b.data.reset(new uint8_t[b.capacity]);
    }
    try {
      worker_ = std::thread([this] { run(); });
      threaded_ = true;
    } catch (const std::system_error&) {
      threaded_ = false;  // forward on the caller's thread (header)
    }
  }

  ~Impl() {
    if (!worker_.joinable()) return;
    {
      std::lock_guard<std::mutex> lock(mu_);
      abandon_ = closing_ = true;
    }
    work_cv_.notify_one();
    worker_.join();
  }

  // The batch to append the next record to, or null with *s set when the
  // producer may not add events (before begin(), after finish(), after the
  // wrapped sink's error).
  Batch* batch(Status* s) {
    if (!begun_ || closed_) {
      *s = Status(ErrorCode::kUsage, closed_ ? "event after finish() of a threaded sink"
                                             : "event before begin() of a threaded sink");
      return nullptr;
    }
    if (threaded_ ? failed_.load(std::memory_order_acquire) : !error_.ok()) {
      // Sticky: every event after the wrapped sink's error returns it.
      std::lock_guard<std::mutex> lock(mu_);
      *s = error_;
      return nullptr;
    }
    return &pool_[cur_];
  }

  // begin() of the wrapped sink, on the caller's thread: before the first
  // event, so that the worker is idle.
  Status begin(const MeshSchema& schema) {
    if (begun_ || closed_) return Status(ErrorCode::kUsage, "begin() twice or after finish() on a threaded sink");
    begun_ = true;
    return next->begin(schema);
  }

  // After a record was appended: replays it at once without a thread, or
  // hands the batch over once it is full.
  Status appended() {
    if (!threaded_) {
      Batch& b = pool_[cur_];
      error_ = replay(b);
      b.used = 0;
      return error_;
    }
    if (pool_[cur_].used < batch_bytes_) return Status();
    std::unique_lock<std::mutex> lock(mu_);
    full_.push_back(cur_);
    work_cv_.notify_one();
    // The worker always returns batches, also after an error (it drops them).
    free_cv_.wait(lock, [&] { return !free_.empty(); });
    cur_ = free_.front();
    free_.pop_front();
    return failed_.load(std::memory_order_relaxed) ? error_ : Status();
  }

  Status close() {
    if (closed_) return Status(ErrorCode::kUsage, "finish() twice on a threaded sink");
    closed_ = true;
    if (!threaded_) return error_;
    {
      std::lock_guard<std::mutex> lock(mu_);
      if (pool_[cur_].used != 0) full_.push_back(cur_);
      closing_ = true;
    }
    work_cv_.notify_one();
    worker_.join();
    return error_;  // the worker has stopped: no race
  }

  void run() {
    std::unique_lock<std::mutex> lock(mu_);
    for (;;) {
      work_cv_.wait(lock, [&] { return !full_.empty() || closing_; });
      if (full_.empty()) return;  // closing, and everything replayed
      const size_t b = full_.front();
      full_.pop_front();
      const bool skip = failed_.load(std::memory_order_relaxed) || abandon_;
      lock.unlock();
      Status s = skip ? Status() : replay(pool_[b]);
      pool_[b].used = 0;
      lock.lock();
      if (!s.ok()) {
        error_ = std::move(s);
        failed_.store(true, std::memory_order_release);
      }
      free_.push_back(b);
      free_cv_.notify_one();
    }
  }

  // Replays the records of a batch into `next` (on the worker, or on the
  // caller's thread without one); stops at the first error.
  Status replay(const Batch& batch) {
    Reader r{batch.data.get()};
    const uint8_t* end = batch.data.get() + batch.used;
    while (r.p < end) {
      const uint8_t kind = r.get<uint8_t>();
      if (kind == kVertexRecord) {
        sv.index = r.get<uint32_t>();
        sv.slot = r.get<uint32_t>();
        sv.reappears = r.get<uint32_t>();
        for (double& x : sv.position) x = r.get<double>();
        r.get_values(&sv.values);
        PSQ_RETURN_IF_ERROR(next->vertex(sv));
      } else if (kind == kTriangleRecord) {
        for (uint32_t& v : st.v) v = r.get<uint32_t>();
        st.op = static_cast<Op>(r.get<uint8_t>());
        for (uint8_t* m : {&st.new_mask, &st.final_mask, &st.border_mask, &st.nonmanifold_mask, &st.leaving_mask,
                           &st.entering_mask})
          *m = r.get<uint8_t>();
        for (uint32_t& s : st.vslot) s = r.get<uint32_t>();
        for (uint32_t& s : st.eslot) s = r.get<uint32_t>();
        r.get_values(&st.values);
        PSQ_RETURN_IF_ERROR(next->triangle(st));
      } else {
        PSQ_RETURN_IF_ERROR(next->finalize(r.get<uint32_t>()));
      }
    }
    return Status();
  }

  SequenceSink* next;
  // Replay's scratch events (their value vectors keep their capacity).
  SequenceVertex sv;
  SequenceTriangle st;
  const size_t batch_bytes_;
  std::vector<Batch> pool_;
  // Producer side only.
  size_t cur_ = 0;
  bool begun_ = false, closed_ = false;
  bool threaded_ = false;
  // Shared, under mu_ (error_ also when the worker is not running).
  std::mutex mu_;
  std::condition_variable work_cv_, free_cv_;
  std::deque<size_t> full_, free_;
  bool closing_ = false, abandon_ = false;
  Status error_;
  // The wrapped sink failed (error_ says how): set under mu_, and atomic so
  // that the producer's check per event needs no lock.
  std::atomic<bool> failed_{false};
  std::thread worker_;  // last: starts after everything above exists
};

ThreadedSequenceSink::ThreadedSequenceSink(SequenceSink* next, size_t batch_bytes, size_t batches)
    : impl_(std::make_unique<Impl>(next, batch_bytes, batches)) {}
ThreadedSequenceSink::~ThreadedSequenceSink() = default;

Status ThreadedSequenceSink::begin(const MeshSchema& schema) { return impl_->begin(schema); }

Status ThreadedSequenceSink::vertex(const SequenceVertex& v) {
  Status s;
  Batch* b = impl_->batch(&s);
  if (!b) return s;
  Writer w = grow(b, 1 + 3 * 4 + 3 * 8 + 4 + v.values.size() * 8);
  w.put(kVertexRecord);
  w.put(v.index);
  w.put(v.slot);
  w.put(v.reappears);
  for (double x : v.position) w.put(x);
  w.put_values(v.values);
  return impl_->appended();
}

Status ThreadedSequenceSink::triangle(const SequenceTriangle& t) {
  Status s;
  Batch* b = impl_->batch(&s);
  if (!b) return s;
  Writer w = grow(b, 1 + 3 * 4 + 7 + 6 * 4 + 4 + t.values.size() * 8);
  w.put(kTriangleRecord);
  for (uint32_t v : t.v) w.put(v);
  w.put(static_cast<uint8_t>(t.op));
  for (uint8_t m : {t.new_mask, t.final_mask, t.border_mask, t.nonmanifold_mask, t.leaving_mask, t.entering_mask})
    w.put(m);
  for (uint32_t x : t.vslot) w.put(x);
  for (uint32_t x : t.eslot) w.put(x);
  w.put_values(t.values);
  return impl_->appended();
}

Status ThreadedSequenceSink::finalize(uint32_t index) {
  Status s;
  Batch* b = impl_->batch(&s);
  if (!b) return s;
  Writer w = grow(b, 1 + 4);
  w.put(kFinalizeRecord);
  w.put(index);
  return impl_->appended();
}

Status ThreadedSequenceSink::finish() {
  PSQ_RETURN_IF_ERROR(impl_->close());
  return impl_->next->finish();
}

}  // namespace psq
