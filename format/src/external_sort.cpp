// The temporary files of the external merge sort (psq/external_sort.h), after
// the external sorts of Lindstrom and Silva, "A memory insensitive technique
// for large model simplification" (IEEE Visualization 2001).
#include "psq/external_sort.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>

namespace psq::detail {

SortFile::~SortFile() {
  if (fd_ >= 0) ::close(fd_);
}

Status SortFile::create(const std::string& dir) {
  std::string d = dir;
  if (d.empty()) {
    const char* env = std::getenv("TMPDIR");
    d = (env != nullptr && *env != '\0') ? env : "/tmp";
  }
  std::string tmpl = d + "/psq-sort-XXXXXX";
  std::vector<char> name(tmpl.begin(), tmpl.end());
  name.push_back('\0');
  int fd = ::mkstemp(name.data());
  if (fd < 0) {
    return Status(ErrorCode::kIo,
                  "cannot create a temporary file in " + d + ": " + std::strerror(errno));
  }
  // Unlinked at once: the data lives only as long as the descriptor.
  ::unlink(name.data());
  ::fcntl(fd, F_SETFD, FD_CLOEXEC);
  if (fd_ >= 0) ::close(fd_);
  fd_ = fd;
  size_ = 0;
  return Status();
}

Status SortFile::append(const void* data, size_t n) {
  const auto* p = static_cast<const uint8_t*>(data);
  while (n > 0) {
    ssize_t w = ::write(fd_, p, n);
    if (w < 0) {
      if (errno == EINTR) continue;
      return Status(ErrorCode::kIo,
                    std::string("cannot write a temporary sort file: ") + std::strerror(errno),
                    size_);
    }
    p += w;
    n -= static_cast<size_t>(w);
    size_ += static_cast<uint64_t>(w);
  }
  return Status();
}

Status SortFile::read_at(uint64_t offset, void* dst, size_t n) const {
  auto* p = static_cast<uint8_t*>(dst);
  while (n > 0) {
    ssize_t r = ::pread(fd_, p, n, static_cast<off_t>(offset));
    if (r < 0) {
      if (errno == EINTR) continue;
      return Status(ErrorCode::kIo,
                    std::string("cannot read a temporary sort file: ") + std::strerror(errno),
                    offset);
    }
    if (r == 0) {
      return Status(ErrorCode::kTruncated, "temporary sort file is shorter than written", offset);
    }
    p += r;
    n -= static_cast<size_t>(r);
    offset += static_cast<uint64_t>(r);
  }
  return Status();
}

}  // namespace psq::detail
