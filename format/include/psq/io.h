// SPDX-License-Identifier: Apache-2.0
// psq/io.h: buffered byte input with offsets, and atomic output files.
//
// InputStream reads a file, standard input or a memory buffer through one
// buffer and always knows the byte offset of its cursor, so that every reader
// built on it can say where an error is. OutputFile writes a regular file
// through a temporary file in the destination's directory and renames it
// over the destination only on commit(): a failed or interrupted run leaves
// no half-written file. Pipes and devices are written in place (see open()).
#ifndef PSQ_IO_H_
#define PSQ_IO_H_

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "psq/status.h"

namespace psq {

class InputStream {
 public:
  // The longest text line read_line() accepts; longer lines are an error
  // (kLimit) so that a file without line ends cannot grow the buffer.
  static constexpr size_t kMaxLine = size_t{1} << 20;

  InputStream();
  ~InputStream();
  InputStream(const InputStream&) = delete;
  InputStream& operator=(const InputStream&) = delete;

  // Opens `path` for reading; "-" is standard input. Errors: kIo.
  Status open(const std::string& path);
  // Reads from an open descriptor (starting at its current position); the
  // stream closes it when `take_ownership`. Errors: kIo.
  Status open_fd(int fd, bool take_ownership, std::string name);
  // Reads from `size` bytes at `data`, which must outlive the stream.
  void open_memory(const void* data, size_t size, std::string name = "<memory>");

  // The name given to open(): the path, "-" or the memory name.
  const std::string& name() const { return name_; }
  // Byte offset of the cursor from the start of the input.
  uint64_t offset() const { return base_ + pos_; }
  // Total size when known (a regular file or memory), otherwise -1 (a pipe).
  int64_t size() const { return size_; }

  // Makes at least `n` bytes (n <= the buffer's capacity, 1 MiB) available at
  // cursor() unless the input ends first; returns how many are available.
  // Errors: kIo.
  Status fill(size_t n, size_t* available);
  const uint8_t* cursor() const { return data_ + pos_; }
  size_t buffered() const { return end_ - pos_; }
  void advance(size_t n) { pos_ += n; }

  // For memory input (open_memory): the next `n` bytes in place, valid as
  // long as that memory, with the cursor moved past them, so that a reader
  // needs no copy. nullptr for a file or pipe, for n == 0, or when fewer
  // than n bytes remain (the cursor stays; read_exact() then reports it).
  const uint8_t* view(size_t n);

  // True when rewind() works: a regular file or memory.
  bool can_rewind() const { return size_ >= 0; }
  // Moves the cursor back to offset 0. Errors: kIo (a pipe cannot rewind).
  Status rewind() { return seek(0); }
  // Moves the cursor to `offset`, at most size(). Errors: kIo (a pipe, or
  // an offset beyond the end).
  Status seek(uint64_t offset);

  // Reads exactly `n` bytes. Errors: kTruncated (with the offset) at end of
  // input, kIo.
  Status read_exact(void* dst, size_t n);
  // True when no byte is left. Errors: kIo.
  Status at_end(bool* end);

  // Reads one text line without its terminator ("\n", "\r\n" or "\r") into
  // `line`, valid until the next call. Sets *eof (and leaves `line` empty)
  // when no byte is left. Errors: kLimit for a line over kMaxLine, kIo.
  Status read_line(std::string_view* line, bool* eof);

 private:
  Status refill();

  std::string name_;
  int fd_ = -1;
  bool own_fd_ = false;
  bool eof_ = false;
  // Not zeroed: a page of it is touched only when input is read into it.
  std::unique_ptr<uint8_t[]> buffer_;
  size_t capacity_ = 0;            // of buffer_
  const uint8_t* data_ = nullptr;  // buffer_ or the memory input
  size_t pos_ = 0;                 // cursor within data_
  size_t end_ = 0;                 // valid bytes in data_
  uint64_t base_ = 0;              // input offset of data_[0]
  int64_t size_ = -1;
};

class OutputFile {
 public:
  OutputFile() = default;
  ~OutputFile();  // removes the temporary file unless commit() succeeded
  OutputFile(const OutputFile&) = delete;
  OutputFile& operator=(const OutputFile&) = delete;

  // Opens the output `path`:
  // - "-": standard output, written directly;
  // - a new or existing regular file: a temporary file beside it, renamed
  //   over it by commit(). Replacing an existing file needs `overwrite`;
  //   the new file keeps the old one's permission bits (rwx for user, group
  //   and others) and, where the system allows, its owner and group. A new
  //   file gets 0666 less the umask. (Other hard links to the old file keep
  //   the old contents; extended attributes and ACLs are not copied.)
  // - a FIFO or a character device (/dev/null, a terminal): written in
  //   place, never renamed over, with or without `overwrite`; a block
  //   device likewise, but only with `overwrite`. What was written before
  //   an error stays written, as with "-".
  // - a symbolic link: followed (through every link) to the file it names,
  //   which is then treated as above: the link stays a link and its target
  //   gets the new contents, as cp does. A link to a missing file is
  //   refused (kIo).
  // - a directory, a path ending in '/', or a socket: refused (kUsage).
  // Errors: kIo, and kUsage when `path` exists and !overwrite (a regular
  // file or block device).
  Status open(const std::string& path, bool overwrite);
  const std::string& name() const { return path_; }
  // Bytes written so far.
  uint64_t size() const { return written_; }

  // Buffered write. Errors: kIo (for example a full disk).
  Status write(const void* data, size_t n);
  Status write(std::string_view s) { return write(s.data(), s.size()); }

  // Positional writes, for a writer that fills a regular file from
  // several threads. Whether the output allows them: a regular file (not
  // "-", a pipe or a device).
  bool seekable() const { return fd_ >= 0 && !is_stdout_ && !in_place_; }
  // Flushes, then sets the file's size and size() to n. Errors: kIo.
  Status resize(uint64_t n);
  // Writes n bytes at `offset` within size() (resize() first), unbuffered;
  // safe from several threads at once. Errors: kIo.
  Status write_at(uint64_t offset, const void* data, size_t n);
  // Empties the file and starts over at offset 0. Errors: kIo.
  Status restart();

  // Flushes, closes and renames the temporary file to the destination (a
  // pipe or device is only flushed and closed). Errors: kIo.
  Status commit();
  // Closes and removes the temporary file; idempotent. (Output to "-", a
  // pipe or a device cannot be taken back.)
  void discard();

 private:
  Status flush();

  std::string path_;
  std::string target_;     // the file renamed over: path_, or a link's target
  std::string temp_path_;
  int fd_ = -1;
  bool is_stdout_ = false;
  bool in_place_ = false;  // a pipe or device, written directly
  // A fixed buffer and its fill: a writer appends a few bytes at a time
  // (a PLY vertex, a spooled record), which a memcpy serves without the
  // bookkeeping of a vector's insert. Left uninitialized, its pages are
  // touched only as far as it fills.
  std::unique_ptr<uint8_t[]> buffer_;
  size_t buffered_ = 0;
  uint64_t written_ = 0;
};

// True once a write of an OutputFile or SpoolFile failed because the reader
// of its pipe or socket had gone (EPIPE; the process ignores SIGPIPE, as the
// psq tool does). The write's Status is kIo; a tool can tell this case,
// "psq ... | head", from a real failure and exit quietly.
bool output_pipe_closed();

// Removes every temporary output file still open; async-signal-safe, for a
// SIGINT/SIGTERM handler of a tool.
void remove_pending_outputs_from_signal();

// A temporary spool file (in `dir`, or $TMPDIR, or /tmp) that is unlinked on
// creation: it disappears with the process whatever happens. Write, then
// rewind() and read it back through stream().
class SpoolFile {
 public:
  SpoolFile() = default;
  ~SpoolFile();
  SpoolFile(const SpoolFile&) = delete;
  SpoolFile& operator=(const SpoolFile&) = delete;

  // Errors: kIo.
  Status create(const std::string& dir = "");
  Status write(const void* data, size_t n);
  uint64_t size() const { return written_; }
  // Flushes and opens the contents for reading from the start. Errors: kIo.
  Status rewind();
  // Reads `n` bytes at `offset` (after rewind(), which flushes), without
  // moving stream(). Errors: kIo, kTruncated past the end.
  Status read_at(uint64_t offset, void* dst, size_t n) const;
  // After rewind(): when the contents take at most `max_bytes`, reads them
  // into memory, so that read_at() costs no system call (the sort path of
  // build_sequence() reads property values by record, in another order
  // than they were written). Sets *loaded to whether it did. stream()
  // still reads the file. Errors: kIo.
  Status load(uint64_t max_bytes, bool* loaded);
  InputStream& stream() { return in_; }

 private:
  int fd_ = -1;
  std::vector<uint8_t> loaded_;  // the contents, after load()
  bool is_loaded_ = false;
  std::unique_ptr<uint8_t[]> buffer_;  // as OutputFile's
  size_t buffered_ = 0;
  uint64_t written_ = 0;
  InputStream in_;
};

namespace detail {

// Creates a temporary file named PREFIX-XXXXXX in `dir` (empty: $TMPDIR, or
// /tmp) and unlinks it at once, so that it disappears with its descriptor
// whatever happens. Sets *fd (close-on-exec). Errors: kIo.
Status create_unlinked_temp(const std::string& dir, const char* prefix, int* fd);
// Reads exactly `n` bytes at `offset` of `fd`. Errors: kIo, kTruncated when
// the file ends first.
Status pread_exact(int fd, uint64_t offset, void* dst, size_t n);
// Writes all `n` bytes to `fd`. Errors: kIo (naming `what`).
Status write_all(int fd, const void* data, size_t n, const std::string& what);

}  // namespace detail
}  // namespace psq

#endif  // PSQ_IO_H_
