// SPDX-License-Identifier: Apache-2.0
// format/src/external_sort.h: sorting more fixed-size records than fit in memory.
//
// The converter's external spatial sort (paper section 3: vertices sorted by
// spatial key, triangles by their smallest vertex key, "implemented using a
// few external sorts" [Lindstrom and Silva 2001]) orders tens of millions of
// small records under the --memory budget. ExternalSorter is a two-phase merge
// sort:
//
//   1. add() collects records in a buffer of at most the budget; when it is
//      full it is sorted (std::sort) and spilled as one run to a temporary
//      file.
//   2. finish() merges the runs with a loser tree over one read buffer per
//      run. When there are more runs than the budget can give a read buffer
//      of at least kMinMergeBuffer (64 KiB) each, intermediate passes first
//      merge the smallest runs into longer ones, just enough for the final
//      merge to fit. next() then yields the final merge record by record.
//
// When no run was spilled, finish() sorts in memory and no file is ever made.
//
// Memory. The records and buffers the sorter allocates never exceed the
// budget (clamped to at least kMinBudget): the run buffer grows geometrically
// while the old and new buffers together fit, and is released before the
// merge buffers ((fan-in + 1) buffers of budget / (fan-in + 1) bytes, each at
// most kMaxMergeBuffer) are allocated. Only bookkeeping of a few words per
// run comes on top.
//
// Temporary files. Each file is created in ExternalSortOptions::tmpdir and
// unlinked at once, like SpoolFile, so it vanishes when the sorter is
// destroyed, fails, or the process dies. The runs of one pass share one file
// read at offsets (pread) into the sorter's own buffers: unlike one SpoolFile
// per run, that needs no hidden 1 MiB buffer per run outside the budget and at
// most three descriptors at any time however many runs there are.
//
// Order. The output is a deterministic function of the input sequence, the
// comparator, the budget and max_fan_in. Records that compare equal come out
// in an unspecified order (std::sort is not stable) that may change with the
// budget, so callers that need the same output on every machine and budget
// must make the comparator total (break ties by an id, as the converter does
// with vertex and triangle numbers).
//
// Not thread-safe: use one sorter per thread.
#ifndef PSQ_FORMAT_EXTERNAL_SORT_H_
#define PSQ_FORMAT_EXTERNAL_SORT_H_

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <functional>
#include <limits>
#include <memory>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "psq/status.h"

namespace psq {

struct ExternalSortOptions {
  // Bytes for the in-memory run and the merge buffers; at least kMinBudget is
  // used whatever is given.
  uint64_t memory_budget = uint64_t{512} << 20;
  // Directory for the temporary files; empty: $TMPDIR, or /tmp.
  std::string tmpdir;
  // The most runs merged at once; 0: as many as the budget allows with
  // read buffers of at least 64 KiB (budget / 64 KiB - 1). Smaller values
  // (at least 2) force intermediate merge passes, for tests; larger values
  // are lowered to the budget's limit.
  uint32_t max_fan_in = 0;
};

namespace detail {

constexpr uint64_t kMinBudget = uint64_t{1} << 20;
constexpr size_t kMinMergeBuffer = size_t{64} << 10;
constexpr size_t kMaxMergeBuffer = size_t{8} << 20;
// The first allocation of the run buffer; it then doubles up to the budget
// so that small inputs do not allocate the whole budget.
constexpr size_t kFirstRunBuffer = size_t{64} << 10;

// A temporary file, unlinked at creation, without a buffer of its own:
// written by appending and read at explicit offsets, so that several runs
// share it and the caller's buffers are the only memory used.
class SortFile {
 public:
  SortFile() = default;
  ~SortFile();  // closes the descriptor; the data goes with it
  SortFile(const SortFile&) = delete;
  SortFile& operator=(const SortFile&) = delete;

  // Creates the file in `dir` (empty: $TMPDIR, else /tmp) and unlinks it at
  // once. Errors: kIo (the directory does not exist, is not writable...).
  Status create(const std::string& dir);
  // Appends `n` bytes at the end. Errors: kIo (for example a full disk).
  Status append(const void* data, size_t n);
  // Reads exactly `n` bytes at byte `offset`. Errors: kTruncated (with the
  // offset where data ran out) when the file is shorter than that, kIo.
  Status read_at(uint64_t offset, void* dst, size_t n) const;
  // Bytes appended so far.
  uint64_t size() const { return size_; }

 private:
  int fd_ = -1;
  uint64_t size_ = 0;
};

}  // namespace detail

// Sorts records of type T (trivially copyable and default constructible,
// typically 16-32 bytes) by `Less`, a strict weak ordering, within
// ExternalSortOptions::memory_budget. Use: add() every record, finish(), then
// next() until *done. Errors are sticky: after a failed call every later
// call returns the same error.
template <class T, class Less = std::less<T>>
class ExternalSorter {
  static_assert(std::is_trivially_copyable_v<T>,
                "ExternalSorter records are copied to and from files as bytes");
  static_assert(std::is_default_constructible_v<T>,
                "ExternalSorter allocates arrays of records");

 public:
  explicit ExternalSorter(ExternalSortOptions options = {}, Less less = Less())
      : tmpdir_(std::move(options.tmpdir)), less_(std::move(less)) {
    uint64_t budget = std::max(options.memory_budget, detail::kMinBudget);
    budget = std::min<uint64_t>(budget, std::numeric_limits<size_t>::max() / 2);
    budget_ = static_cast<size_t>(budget);
    run_limit_ = std::max<size_t>(budget_ / sizeof(T), 2);
    size_t fan_in = std::max<size_t>(budget_ / detail::kMinMergeBuffer, 3) - 1;
    if (options.max_fan_in != 0) {
      fan_in = std::min<size_t>(fan_in, std::max<uint32_t>(options.max_fan_in, 2));
    }
    fan_in_ = fan_in;
  }
  ~ExternalSorter() = default;
  ExternalSorter(const ExternalSorter&) = delete;
  ExternalSorter& operator=(const ExternalSorter&) = delete;
  // A moved-from sorter may only be destroyed or assigned to.
  ExternalSorter(ExternalSorter&&) = default;
  ExternalSorter& operator=(ExternalSorter&&) = default;

  // A hint, before the first add(): about `records` records will come. The
  // run buffer takes room for them at once (within the budget; address
  // space, no page touched) instead of growing by doubling, which copies
  // it and touches about twice its pages. The sorted output is the same.
  void reserve(uint64_t records) {
    if (phase_ != Phase::kAdding || run_capacity_ != 0 || records == 0) return;
    reallocate(static_cast<size_t>(std::min<uint64_t>(records, run_limit_)));
  }

  // Adds one record. When the run buffer is full, sorts it and writes it to
  // a temporary file. Errors: kIo (cannot create or write the temporary
  // file), kUsage after finish().
  Status add(const T& record) {
    if (phase_ != Phase::kAdding) return not_adding("add() after finish()");
    if (run_size_ == run_capacity_) {
      Status s = make_room();
      if (!s.ok()) return fail(std::move(s));
    }
    run_[run_size_++] = record;
    ++size_;
    return Status();
  }

  // Ends the input and prepares the sorted output: sorts in memory when no
  // run was spilled, otherwise spills the last run and performs the
  // intermediate merge passes, if any, so that next() only merges. Errors:
  // kIo, kTruncated (a temporary file shorter than written: a disk problem or
  // a psq bug), kUsage when called twice.
  Status finish() {
    if (phase_ != Phase::kAdding) return not_adding("finish() called twice");
    Status s = prepare_output();
    if (!s.ok()) return fail(std::move(s));
    return Status();
  }

  // Yields the next record in sorted order into *record and sets *done =
  // false, or sets *done = true (leaving *record alone) once every record
  // has been yielded, and on every later call. Memory and temporary files are
  // released as soon as the end is reached. Errors: kIo, kTruncated (a
  // temporary file shorter than written), kUsage before finish().
  Status next(T* record, bool* done) {
    if (phase_ == Phase::kMemory) {
      if (pos_ < run_size_) {
        *record = run_[pos_++];
        *done = false;
        return Status();
      }
      release();
      phase_ = Phase::kDone;
    } else if (phase_ == Phase::kMerging) {
      Source& s = sources_[winner_];
      if (s.cur != nullptr) {
        *record = *s.cur;
        *done = false;
        if (++s.cur == s.end) {
          Status st = refill(&s);
          if (!st.ok()) return fail(std::move(st));
        }
        replay(winner_);
        return Status();
      }
      release();
      phase_ = Phase::kDone;
    } else if (phase_ == Phase::kAdding) {
      return Status(ErrorCode::kUsage, "external sort: next() before finish()");
    } else if (phase_ == Phase::kFailed) {
      return error_;
    }
    *done = true;
    return Status();
  }

  // Records added so far.
  uint64_t size() const { return size_; }
  // Sorted runs spilled to temporary files by add() and finish(); 0 when
  // everything fit in memory.
  uint64_t runs() const { return spilled_runs_; }
  // Intermediate merge passes finish() made (0 when the runs were merged in
  // one final merge).
  uint64_t merge_passes() const { return merge_passes_; }
  // The most runs merged at once under this budget and options.
  size_t fan_in() const { return fan_in_; }

 private:
  enum class Phase : uint8_t { kAdding, kMemory, kMerging, kDone, kFailed };

  // A sorted run: `count` records at byte `offset` of files_[file].
  struct Run {
    size_t file;
    uint64_t offset;
    uint64_t count;
  };

  // One input of a merge: the buffered records [cur, end) and what is left
  // of its run on disk. cur == nullptr marks an exhausted input.
  struct Source {
    const T* cur;
    const T* end;
    T* buffer;
    size_t capacity;  // records
    const detail::SortFile* file;
    uint64_t offset;     // byte offset of the next unread record
    uint64_t remaining;  // records not yet read
  };

  Status not_adding(const char* usage) const {
    if (phase_ == Phase::kFailed) return error_;
    return Status(ErrorCode::kUsage, std::string("external sort: ") + usage);
  }

  Status fail(Status s) {
    error_ = s;
    phase_ = Phase::kFailed;
    release();
    return s;
  }

  void release() {
    run_.reset();
    run_size_ = run_capacity_ = pos_ = 0;
    merge_memory_.reset();
    sources_.clear();
    sources_.shrink_to_fit();
    losers_.clear();
    losers_.shrink_to_fit();
    runs_.clear();
    runs_.shrink_to_fit();
    files_.clear();
    files_.shrink_to_fit();
  }

  // Replaces the run buffer by one of `capacity` records, keeping its
  // contents.
  void reallocate(size_t capacity) {
    std::unique_ptr<T[]> bigger(new T[capacity]);
    if (run_size_ > 0) std::memcpy(bigger.get(), run_.get(), run_size_ * sizeof(T));
    run_ = std::move(bigger);
    run_capacity_ = capacity;
  }

  // Called with a full run buffer: grows it while the old and the new buffer
  // together stay within the budget, otherwise spills it as a run and, after
  // the first spill, gives it the whole budget (the input is large).
  Status make_room() {
    if (run_capacity_ < run_limit_) {
      const size_t first = std::max<size_t>(detail::kFirstRunBuffer / sizeof(T), 1);
      size_t grown = run_capacity_ == 0 ? std::min(first, run_limit_)
                                        : std::min(2 * run_capacity_, run_limit_ - run_capacity_);
      if (grown > run_capacity_) {
        reallocate(grown);
        return Status();
      }
    }
    Status s = spill();
    if (!s.ok()) return s;
    if (run_capacity_ < run_limit_) {
      run_.reset();  // free before allocating: both would not fit
      run_capacity_ = 0;
      reallocate(run_limit_);
    }
    return Status();
  }

  Status spill() {
    std::sort(run_.get(), run_.get() + run_size_, less_);
    if (files_.empty()) {
      auto file = std::make_unique<detail::SortFile>();
      Status s = file->create(tmpdir_);
      if (!s.ok()) return s;
      files_.push_back(std::move(file));
    }
    detail::SortFile& file = *files_.back();
    runs_.push_back(Run{files_.size() - 1, file.size(), run_size_});
    Status s = file.append(run_.get(), run_size_ * sizeof(T));
    if (!s.ok()) return s;
    ++spilled_runs_;
    run_size_ = 0;
    return Status();
  }

  Status prepare_output() {
    if (runs_.empty()) {
      std::sort(run_.get(), run_.get() + run_size_, less_);
      phase_ = Phase::kMemory;
      return Status();
    }
    if (run_size_ > 0) PSQ_RETURN_IF_ERROR(spill());
    run_.reset();  // the merge buffers take the budget
    run_capacity_ = 0;
    while (runs_.size() > fan_in_) PSQ_RETURN_IF_ERROR(merge_pass());
    size_t n = runs_.size();
    size_t records = buffer_records(n);
    merge_memory_.reset(new T[n * records]);
    PSQ_RETURN_IF_ERROR(start_merge(runs_.data(), n, records, merge_memory_.get()));
    phase_ = Phase::kMerging;
    return Status();
  }

  // Records per merge buffer when `buffers` buffers share the budget.
  size_t buffer_records(size_t buffers) const {
    size_t bytes = std::min(budget_ / buffers, detail::kMaxMergeBuffer);
    return std::max<size_t>(bytes / sizeof(T), 1);
  }

  // One intermediate pass over R > fan-in runs: merges the smallest runs,
  // in groups of at most fan-in, into a new file until T runs are left,
  // where T is the largest power of the fan-in below R. Every later pass
  // then merges full groups, down to fan-in runs for the final merge, and
  // each record is written about ceil(log_fan-in(R)) - 1 times in all.
  Status merge_pass() {
    const size_t k = fan_in_;
    const size_t count = runs_.size();
    size_t target = k;
    while (target * k < count) target *= k;
    const size_t reduce = count - target;  // each k-way merge removes k - 1
    const size_t merges = (reduce + k - 2) / (k - 1);
    const size_t first = reduce - (merges - 1) * (k - 1) + 1;  // in [2, k]

    std::sort(runs_.begin(), runs_.end(), [](const Run& a, const Run& b) {
      if (a.count != b.count) return a.count < b.count;
      if (a.file != b.file) return a.file < b.file;
      return a.offset < b.offset;
    });
    auto out = std::make_unique<detail::SortFile>();
    PSQ_RETURN_IF_ERROR(out->create(tmpdir_));
    files_.push_back(std::move(out));
    const size_t out_index = files_.size() - 1;

    std::vector<Run> merged;
    merged.reserve(target);
    size_t at = 0;
    for (size_t m = 0; m < merges; ++m) {
      size_t group = m == 0 ? first : k;
      Run run;
      PSQ_RETURN_IF_ERROR(merge_group(&runs_[at], group, out_index, &run));
      merged.push_back(run);
      at += group;
    }
    merged.insert(merged.end(), runs_.begin() + static_cast<ptrdiff_t>(at), runs_.end());
    runs_ = std::move(merged);

    // Drop the files no run lives in any more.
    std::vector<bool> used(files_.size(), false);
    for (const Run& r : runs_) used[r.file] = true;
    for (size_t f = 0; f < files_.size(); ++f) {
      if (!used[f]) files_[f].reset();
    }
    ++merge_passes_;
    return Status();
  }

  // Merges `n` runs into one new run appended to files_[out_index].
  Status merge_group(const Run* group, size_t n, size_t out_index, Run* result) {
    size_t records = buffer_records(n + 1);
    std::unique_ptr<T[]> memory(new T[(n + 1) * records]);
    PSQ_RETURN_IF_ERROR(start_merge(group, n, records, memory.get()));
    detail::SortFile& out = *files_[out_index];
    *result = Run{out_index, out.size(), 0};
    T* const out_buffer = memory.get() + n * records;
    size_t buffered = 0;
    for (;;) {
      Source& s = sources_[winner_];
      if (s.cur == nullptr) break;
      out_buffer[buffered] = *s.cur;
      if (++s.cur == s.end) PSQ_RETURN_IF_ERROR(refill(&s));
      replay(winner_);
      if (++buffered == records) {
        PSQ_RETURN_IF_ERROR(out.append(out_buffer, buffered * sizeof(T)));
        result->count += buffered;
        buffered = 0;
      }
    }
    PSQ_RETURN_IF_ERROR(out.append(out_buffer, buffered * sizeof(T)));
    result->count += buffered;
    sources_.clear();
    return Status();
  }

  // Sets up a merge of `n` runs, each read through `records` records of
  // `memory`, and plays the loser tree's first tournament.
  Status start_merge(const Run* group, size_t n, size_t records, T* memory) {
    sources_.clear();
    sources_.reserve(n);
    for (size_t i = 0; i < n; ++i) {
      const Run& r = group[i];
      sources_.push_back(Source{nullptr, nullptr, memory + i * records, records,
                                files_[r.file].get(), r.offset, r.count});
      PSQ_RETURN_IF_ERROR(refill(&sources_.back()));
    }
    // Leaves n..2n-1 stand for the inputs; internal node i (1 <= i < n) keeps
    // the loser of the match between its children 2i and 2i+1.
    losers_.assign(n, 0);
    std::vector<uint32_t> winners(2 * n);
    for (size_t i = 0; i < n; ++i) winners[n + i] = static_cast<uint32_t>(i);
    for (size_t node = n - 1; node >= 1; --node) {
      uint32_t a = winners[2 * node];
      uint32_t b = winners[2 * node + 1];
      if (beats(b, a)) std::swap(a, b);
      winners[node] = a;
      losers_[node] = b;
    }
    winner_ = winners[1];
    return Status();
  }

  // True when input a's head comes strictly before input b's (an exhausted
  // input comes after everything).
  bool beats(uint32_t a, uint32_t b) const {
    const T* x = sources_[a].cur;
    const T* y = sources_[b].cur;
    if (x == nullptr) return false;
    if (y == nullptr) return true;
    return less_(*x, *y);
  }

  // After input s's head changed: replays its matches up to the root.
  void replay(uint32_t s) {
    // beats() unrolled with the candidate's head kept in a register: this
    // loop is where the merge spends its time.
    const Source* sources = sources_.data();
    uint32_t* losers = losers_.data();
    uint32_t candidate = s;
    const T* head = sources[s].cur;
    for (size_t node = (s + sources_.size()) >> 1; node > 0; node >>= 1) {
      uint32_t loser = losers[node];
      const T* loser_head = sources[loser].cur;
      if (loser_head != nullptr && (head == nullptr || less_(*loser_head, *head))) {
        losers[node] = candidate;
        candidate = loser;
        head = loser_head;
      }
    }
    winner_ = candidate;
  }

  // Reads the next buffer of an input whose buffer is used up.
  Status refill(Source* s) {
    if (s->remaining == 0) {
      s->cur = s->end = nullptr;
      return Status();
    }
    size_t n = static_cast<size_t>(std::min<uint64_t>(s->remaining, s->capacity));
    PSQ_RETURN_IF_ERROR(s->file->read_at(s->offset, s->buffer, n * sizeof(T)));
    s->cur = s->buffer;
    s->end = s->buffer + n;
    s->offset += n * sizeof(T);
    s->remaining -= n;
    return Status();
  }

  std::string tmpdir_;
  Less less_;
  size_t budget_ = 0;     // bytes
  size_t run_limit_ = 0;  // records in a full-budget run buffer
  size_t fan_in_ = 2;
  Phase phase_ = Phase::kAdding;
  Status error_;

  // The run being collected (and, in kMemory, the sorted output).
  std::unique_ptr<T[]> run_;
  size_t run_size_ = 0;
  size_t run_capacity_ = 0;
  size_t pos_ = 0;  // next record next() yields in kMemory

  std::vector<std::unique_ptr<detail::SortFile>> files_;  // null once unused
  std::vector<Run> runs_;
  uint64_t size_ = 0;
  uint64_t spilled_runs_ = 0;
  uint64_t merge_passes_ = 0;

  // The merge in progress: its inputs and the loser tree over them.
  std::unique_ptr<T[]> merge_memory_;
  std::vector<Source> sources_;
  std::vector<uint32_t> losers_;
  uint32_t winner_ = 0;
};

}  // namespace psq

#endif  // PSQ_FORMAT_EXTERNAL_SORT_H_
