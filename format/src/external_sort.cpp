// SPDX-License-Identifier: Apache-2.0
// The temporary files of the external merge sort (external_sort.h), after
// the external sorts of Lindstrom and Silva, "A memory insensitive technique
// for large model simplification" (IEEE Visualization 2001).
#include "external_sort.h"

#include <unistd.h>

#include "psq/io.h"

namespace psq::detail {

SortFile::~SortFile() {
  if (fd_ >= 0) ::close(fd_);
}

Status SortFile::create(const std::string& dir) {
  int fd;
  PSQ_RETURN_IF_ERROR(create_unlinked_temp(dir, "psq-sort", &fd));
  if (fd_ >= 0) ::close(fd_);
  fd_ = fd;
  size_ = 0;
  return Status();
}

Status SortFile::append(const void* data, size_t n) {
  PSQ_RETURN_IF_ERROR(write_all(fd_, data, n, "a temporary sort file"));
  size_ += n;
  return Status();
}

Status SortFile::read_at(uint64_t offset, void* dst, size_t n) const {
  return pread_exact(fd_, offset, dst, n);
}

}  // namespace psq::detail
