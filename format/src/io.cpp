// SPDX-License-Identifier: Apache-2.0
#include "psq/io.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <mutex>

namespace psq {
namespace {

constexpr size_t kBufferSize = size_t{1} << 20;

Status io_error(const std::string& what, const std::string& name) {
  return Status(ErrorCode::kIo, what + " " + name + ": " + std::strerror(errno));
}

// Temporary output paths still to be removed if the process is interrupted.
// A fixed table of plain char arrays so that the signal handler only calls
// unlink(), which is async-signal-safe.
constexpr int kMaxPending = 16;
constexpr size_t kMaxPath = 4096;
char g_pending[kMaxPending][kMaxPath];
std::atomic<bool> g_pending_used[kMaxPending];
std::mutex g_pending_mutex;

// Set when a write failed with EPIPE: the reader of a pipe is gone.
std::atomic<bool> g_pipe_closed{false};

int register_pending(const std::string& path) {
  if (path.size() >= kMaxPath) return -1;
  std::lock_guard<std::mutex> lock(g_pending_mutex);
  for (int i = 0; i < kMaxPending; ++i) {
    if (!g_pending_used[i].load()) {
      std::memcpy(g_pending[i], path.c_str(), path.size() + 1);
      g_pending_used[i].store(true);
      return i;
    }
  }
  return -1;
}

void unregister_pending(const std::string& path) {
  std::lock_guard<std::mutex> lock(g_pending_mutex);
  for (int i = 0; i < kMaxPending; ++i) {
    if (g_pending_used[i].load() && path == g_pending[i]) g_pending_used[i].store(false);
  }
}

}  // namespace

namespace detail {

Status write_all(int fd, const void* data, size_t n, const std::string& what) {
  const auto* p = static_cast<const uint8_t*>(data);
  while (n > 0) {
    ssize_t w = ::write(fd, p, n);
    if (w < 0) {
      if (errno == EINTR) continue;
      if (errno == EPIPE) g_pipe_closed.store(true);
      return io_error("cannot write", what);
    }
    p += w;
    n -= static_cast<size_t>(w);
  }
  return Status();
}

Status create_unlinked_temp(const std::string& dir, const char* prefix, int* fd) {
  std::string d = dir;
  if (d.empty()) {
    const char* env = std::getenv("TMPDIR");
    d = (env != nullptr && *env != '\0') ? env : "/tmp";
  }
  std::string tmpl = d + "/" + prefix + "-XXXXXX";
  std::vector<char> name(tmpl.begin(), tmpl.end());
  name.push_back('\0');
  int f = ::mkostemp(name.data(), O_CLOEXEC);
  if (f < 0) return Status(ErrorCode::kIo, "cannot create a temporary file in " + d + ": " + std::strerror(errno));
  ::unlink(name.data());
  *fd = f;
  return Status();
}

Status pread_exact(int fd, uint64_t offset, void* dst, size_t n) {
  auto* p = static_cast<uint8_t*>(dst);
  while (n > 0) {
    ssize_t r = ::pread(fd, p, n, static_cast<off_t>(offset));
    if (r < 0) {
      if (errno == EINTR) continue;
      return Status(ErrorCode::kIo, std::string("cannot read a temporary file: ") + std::strerror(errno), offset);
    }
    if (r == 0) return Status(ErrorCode::kTruncated, "temporary file ends early", offset);
    p += r;
    n -= static_cast<size_t>(r);
    offset += static_cast<uint64_t>(r);
  }
  return Status();
}

}  // namespace detail

using detail::write_all;

bool output_pipe_closed() { return g_pipe_closed.load(); }

void remove_pending_outputs_from_signal() {
  for (int i = 0; i < kMaxPending; ++i) {
    if (g_pending_used[i].load()) ::unlink(g_pending[i]);
  }
}

// ---------------------------------------------------------------- InputStream

InputStream::InputStream() = default;

InputStream::~InputStream() {
  if (own_fd_ && fd_ >= 0) ::close(fd_);
}

Status InputStream::open(const std::string& path) {
  if (path == "-") return open_fd(STDIN_FILENO, false, path);
  int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) {
    name_ = path;
    return Status(ErrorCode::kIo, std::string("cannot open: ") + std::strerror(errno));
  }
  return open_fd(fd, true, path);
}

Status InputStream::open_fd(int fd, bool take_ownership, std::string name) {
  name_ = std::move(name);
  fd_ = fd;
  own_fd_ = take_ownership;
  // A stream opened again (SpoolFile::rewind() a second time) starts over.
  pos_ = end_ = 0;
  base_ = 0;
  eof_ = false;
  size_ = -1;
  struct stat st;
  if (::fstat(fd_, &st) == 0) {
    if (S_ISDIR(st.st_mode)) return Status(ErrorCode::kIo, "is a directory");
    if (S_ISREG(st.st_mode)) size_ = static_cast<int64_t>(st.st_size);
  }
  if (capacity_ < kBufferSize) {
    buffer_.reset(new uint8_t[kBufferSize]);
    capacity_ = kBufferSize;
  }
  data_ = buffer_.get();
  return Status();
}

void InputStream::open_memory(const void* data, size_t size, std::string name) {
  name_ = std::move(name);
  data_ = static_cast<const uint8_t*>(data);
  end_ = size;
  size_ = static_cast<int64_t>(size);
  eof_ = true;
}

const uint8_t* InputStream::view(size_t n) {
  if (fd_ >= 0 || n == 0 || data_ == nullptr || end_ - pos_ < n) return nullptr;
  const uint8_t* p = data_ + pos_;
  pos_ += n;
  return p;
}

Status InputStream::seek(uint64_t offset) {
  if (!can_rewind()) return Status(ErrorCode::kIo, "input cannot seek (a pipe)");
  if (offset > static_cast<uint64_t>(size_)) return Status(ErrorCode::kIo, "seek beyond the end of the input");
  if (fd_ < 0) {  // memory
    pos_ = static_cast<size_t>(offset);
    return Status();
  }
  if (::lseek(fd_, static_cast<off_t>(offset), SEEK_SET) != static_cast<off_t>(offset))
    return Status(ErrorCode::kIo, "input cannot seek");
  pos_ = end_ = 0;
  base_ = offset;
  eof_ = false;
  return Status();
}

Status InputStream::refill() {
  if (eof_) return Status();
  // Move the unread tail to the front, then read as much as fits.
  if (pos_ > 0) {
    std::memmove(buffer_.get(), buffer_.get() + pos_, end_ - pos_);
    base_ += pos_;
    end_ -= pos_;
    pos_ = 0;
  }
  while (end_ < capacity_) {
    ssize_t r = ::read(fd_, buffer_.get() + end_, capacity_ - end_);
    if (r < 0) {
      if (errno == EINTR) continue;
      return Status(ErrorCode::kIo, std::string("read failed: ") + std::strerror(errno), offset());
    }
    if (r == 0) {
      eof_ = true;
      break;
    }
    end_ += static_cast<size_t>(r);
    if (end_ - pos_ >= 65536) break;  // enough for now; keeps pipes responsive
  }
  return Status();
}

Status InputStream::fill(size_t n, size_t* available) {
  // Callers bound n (read_line by kMaxLine + 2); grow the buffer to fit.
  if (fd_ >= 0 && n > capacity_) {
    std::unique_ptr<uint8_t[]> grown(new uint8_t[n]);
    std::memcpy(grown.get(), buffer_.get() + pos_, end_ - pos_);
    base_ += pos_;
    end_ -= pos_;
    pos_ = 0;
    buffer_ = std::move(grown);
    capacity_ = n;
    data_ = buffer_.get();
  }
  while (end_ - pos_ < n && !eof_) {
    size_t before = end_ - pos_;
    PSQ_RETURN_IF_ERROR(refill());
    if (end_ - pos_ == before && !eof_ && end_ == capacity_) break;  // n > capacity
  }
  *available = end_ - pos_;
  return Status();
}

Status InputStream::read_exact(void* dst, size_t n) {
  auto* out = static_cast<uint8_t*>(dst);
  while (n > 0) {
    if (pos_ == end_) {
      PSQ_RETURN_IF_ERROR(refill());
      if (pos_ == end_) return Status(ErrorCode::kTruncated, "unexpected end of input", offset());
    }
    size_t k = std::min(n, end_ - pos_);
    std::memcpy(out, data_ + pos_, k);
    pos_ += k;
    out += k;
    n -= k;
  }
  return Status();
}

Status InputStream::at_end(bool* end) {
  if (pos_ == end_) PSQ_RETURN_IF_ERROR(refill());
  *end = pos_ == end_;
  return Status();
}

Status InputStream::read_line(std::string_view* line, bool* eof) {
  size_t scanned = 0;  // bytes after pos_ already known to hold no terminator
  for (;;) {
    const uint8_t* start = data_ + pos_;
    size_t avail = end_ - pos_;
    const uint8_t* nl = nullptr;
    for (size_t i = scanned; i < avail; ++i) {
      if (start[i] == '\n' || start[i] == '\r') {
        nl = start + i;
        break;
      }
    }
    if (nl != nullptr) {
      size_t len = static_cast<size_t>(nl - start);
      if (len > kMaxLine) return Status(ErrorCode::kLimit, "line longer than 1 MiB", offset());
      // A "\r" at the very end of the buffer may be the first half of "\r\n".
      if (*nl == '\r' && len + 1 == avail && !eof_) {
        scanned = len;
        size_t dummy;
        PSQ_RETURN_IF_ERROR(fill(avail + 1, &dummy));
        continue;
      }
      *line = std::string_view(reinterpret_cast<const char*>(start), len);
      size_t skip = len + 1;
      if (*nl == '\r' && len + 1 < avail && start[len + 1] == '\n') ++skip;
      pos_ += skip;
      *eof = false;
      return Status();
    }
    if (avail > kMaxLine) return Status(ErrorCode::kLimit, "line longer than 1 MiB", offset());
    if (eof_) {
      *eof = avail == 0;
      *line = std::string_view(reinterpret_cast<const char*>(start), avail);
      pos_ += avail;
      return Status();
    }
    scanned = avail;
    size_t dummy;
    PSQ_RETURN_IF_ERROR(fill(avail + 1, &dummy));
  }
}

// ----------------------------------------------------------------- OutputFile

OutputFile::~OutputFile() { discard(); }

namespace {

mode_t current_umask() {
  const mode_t m = ::umask(0);
  ::umask(m);
  return m;
}

}  // namespace

Status OutputFile::open(const std::string& path, bool overwrite) {
  path_ = path;
  buffer_.reset(new uint8_t[kBufferSize]);
  buffered_ = 0;
  if (path == "-") {
    is_stdout_ = true;
    fd_ = STDOUT_FILENO;
    return Status();
  }
  if (path.empty()) return Status(ErrorCode::kUsage, "empty output path");
  // Where the data goes: the path itself, or, for a symbolic link, the file
  // it names (resolved through every link), so that the link stays and its
  // target gets the new contents.
  std::string target = path;
  struct stat lst;
  if (::lstat(path.c_str(), &lst) == 0 && S_ISLNK(lst.st_mode)) {
    char* resolved = ::realpath(path.c_str(), nullptr);
    if (resolved == nullptr) {
      if (errno == ENOENT) return Status(ErrorCode::kIo, "is a symbolic link to a missing file; psq does not write through it");
      return Status(ErrorCode::kIo, std::string("cannot resolve the symbolic link: ") + std::strerror(errno));
    }
    target = resolved;
    std::free(resolved);
  }
  struct stat st;
  const bool exists = ::stat(target.c_str(), &st) == 0;
  if (!exists && errno != ENOENT) return Status(ErrorCode::kIo, std::string("cannot examine the output: ") + std::strerror(errno));
  if (exists) {
    if (S_ISDIR(st.st_mode)) return Status(ErrorCode::kUsage, "is a directory; name a file");
    if (S_ISSOCK(st.st_mode)) return Status(ErrorCode::kUsage, "is a socket; psq writes files, pipes and devices");
    // Pipes and character devices (/dev/null, a terminal) hold nothing that
    // writing would replace: they are written in place, with or without
    // overwrite. A block device holds data: in place, and only with
    // overwrite. Never renamed over: that would put a regular file where
    // the device or pipe was (/dev/null, as root).
    if (S_ISFIFO(st.st_mode) || S_ISCHR(st.st_mode) || S_ISBLK(st.st_mode)) {
      if (S_ISBLK(st.st_mode) && !overwrite) return Status(ErrorCode::kUsage, "output exists (use -f to overwrite)");
      fd_ = ::open(target.c_str(), O_WRONLY | O_CLOEXEC);
      if (fd_ < 0) return Status(ErrorCode::kIo, std::string("cannot open: ") + std::strerror(errno));
      in_place_ = true;
      return Status();
    }
    if (!overwrite) return Status(ErrorCode::kUsage, "output exists (use -f to overwrite)");
  } else if (target.back() == '/') {
    return Status(ErrorCode::kUsage, "names a directory; name a file");
  }
  target_ = target;
  std::string dir;
  std::string base = target;
  size_t slash = target.rfind('/');
  if (slash != std::string::npos) {
    dir = target.substr(0, slash + 1);
    base = target.substr(slash + 1);
  }
  std::string tmpl = dir + "." + base + ".psq-tmp-XXXXXX";
  std::vector<char> name(tmpl.begin(), tmpl.end());
  name.push_back('\0');
  fd_ = ::mkostemp(name.data(), O_CLOEXEC);
  if (fd_ < 0) return Status(ErrorCode::kIo, std::string("cannot create a temporary file beside the output: ") + std::strerror(errno));
  temp_path_ = name.data();
  register_pending(temp_path_);
  // The replaced file's permission bits (not set-user-ID, set-group-ID or
  // sticky), and its owner and group where the system lets us (as root, or
  // a group we are in); a new file gets what open(O_CREAT) with 0666 gives
  // (the umask applies).
  if (exists) {
    if (st.st_uid != ::geteuid() || st.st_gid != ::getegid()) {
      // Owner first, then group alone: a user may keep a group it is in.
      if (::fchown(fd_, st.st_uid, st.st_gid) != 0) (void)::fchown(fd_, static_cast<uid_t>(-1), st.st_gid);
    }
    ::fchmod(fd_, st.st_mode & 0777);
  } else {
    ::fchmod(fd_, 0666 & ~current_umask());
  }
  return Status();
}

Status OutputFile::flush() {
  if (buffered_ == 0) return Status();
  Status s = write_all(fd_, buffer_.get(), buffered_, path_);
  buffered_ = 0;
  return s;
}

Status OutputFile::write(const void* data, size_t n) {
  if (fd_ < 0) return Status(ErrorCode::kIo, "output is not open");
  written_ += n;
  if (n > kBufferSize - buffered_) {
    PSQ_RETURN_IF_ERROR(flush());
    if (n >= kBufferSize) return write_all(fd_, static_cast<const uint8_t*>(data), n, path_);
  }
  if (n > 0) std::memcpy(buffer_.get() + buffered_, data, n);
  buffered_ += n;
  return Status();
}

Status OutputFile::resize(uint64_t n) {
  if (!seekable()) return Status(ErrorCode::kIo, "output cannot be written at offsets");
  PSQ_RETURN_IF_ERROR(flush());
  if (::ftruncate(fd_, static_cast<off_t>(n)) != 0) return io_error("cannot resize", path_);
  if (::lseek(fd_, static_cast<off_t>(n), SEEK_SET) < 0) return io_error("cannot seek", path_);
  written_ = n;
  return Status();
}

Status OutputFile::write_at(uint64_t offset, const void* data, size_t n) {
  if (!seekable() || offset > written_ || n > written_ - offset)
    return Status(ErrorCode::kIo, "write beyond the output's size");
  const auto* p = static_cast<const uint8_t*>(data);
  while (n > 0) {
    const ssize_t w = ::pwrite(fd_, p, n, static_cast<off_t>(offset));
    if (w < 0) {
      if (errno == EINTR) continue;
      return io_error("cannot write", path_);
    }
    p += w;
    n -= static_cast<size_t>(w);
    offset += static_cast<uint64_t>(w);
  }
  return Status();
}

Status OutputFile::restart() {
  PSQ_RETURN_IF_ERROR(resize(0));
  return Status();
}

Status OutputFile::commit() {
  if (fd_ < 0) return Status(ErrorCode::kIo, "output is not open");
  PSQ_RETURN_IF_ERROR(flush());
  if (is_stdout_) {
    fd_ = -1;
    return Status();
  }
  if (::close(fd_) != 0) {
    fd_ = -1;
    return io_error("cannot close", path_);
  }
  fd_ = -1;
  if (in_place_) return Status();
  if (::rename(temp_path_.c_str(), target_.c_str()) != 0) return io_error("cannot rename to", target_);
  unregister_pending(temp_path_);
  temp_path_.clear();
  return Status();
}

void OutputFile::discard() {
  if (is_stdout_) {
    fd_ = -1;
    return;
  }
  if (fd_ >= 0) {
    ::close(fd_);
    fd_ = -1;
  }
  if (!temp_path_.empty()) {
    ::unlink(temp_path_.c_str());
    unregister_pending(temp_path_);
    temp_path_.clear();
  }
}

// ------------------------------------------------------------------ SpoolFile

SpoolFile::~SpoolFile() {
  if (fd_ >= 0) ::close(fd_);
}

Status SpoolFile::create(const std::string& dir) {
  PSQ_RETURN_IF_ERROR(detail::create_unlinked_temp(dir, "psq-spool", &fd_));
  buffer_.reset(new uint8_t[kBufferSize]);
  buffered_ = 0;
  return Status();
}

Status SpoolFile::write(const void* data, size_t n) {
  written_ += n;
  const auto* p = static_cast<const uint8_t*>(data);
  if (!buffer_) buffer_.reset(new uint8_t[kBufferSize]);  // written again after rewind()
  if (n > kBufferSize - buffered_) {
    PSQ_RETURN_IF_ERROR(write_all(fd_, buffer_.get(), buffered_, "temporary file"));
    buffered_ = 0;
    if (n >= kBufferSize) return write_all(fd_, p, n, "temporary file");
  }
  if (n > 0) std::memcpy(buffer_.get() + buffered_, p, n);
  buffered_ += n;
  return Status();
}

Status SpoolFile::rewind() {
  PSQ_RETURN_IF_ERROR(write_all(fd_, buffer_.get(), buffered_, "temporary file"));
  buffered_ = 0;
  buffer_.reset();
  if (::lseek(fd_, 0, SEEK_SET) != 0) return io_error("cannot rewind", "temporary file");
  // The stream reads through our descriptor; it does not close it.
  return in_.open_fd(fd_, false, "temporary file");
}

Status SpoolFile::read_at(uint64_t offset, void* dst, size_t n) const {
  if (!is_loaded_) return detail::pread_exact(fd_, offset, dst, n);
  if (offset > loaded_.size() || n > loaded_.size() - offset)
    return Status(ErrorCode::kTruncated, "temporary file ends early", std::min<uint64_t>(offset, loaded_.size()));
  if (n > 0) std::memcpy(dst, loaded_.data() + offset, n);
  return Status();
}

Status SpoolFile::load(uint64_t max_bytes, bool* loaded) {
  *loaded = is_loaded_;
  if (is_loaded_ || written_ > max_bytes) return Status();
  std::vector<uint8_t> data(static_cast<size_t>(written_));
  PSQ_RETURN_IF_ERROR(detail::pread_exact(fd_, 0, data.data(), data.size()));
  loaded_.swap(data);
  is_loaded_ = *loaded = true;
  return Status();
}

}  // namespace psq
