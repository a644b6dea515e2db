// SPDX-License-Identifier: Apache-2.0
// codec/src/pages.cpp: see pages.h.
#include "pages.h"

#include <cstdint>

#if defined(__linux__) && !defined(PSQ_NO_POPULATE)
#include <errno.h>
#include <sys/mman.h>
#include <unistd.h>

#include <atomic>
#endif

namespace psq {
namespace codec {

void populate_for_write(void* p, size_t bytes) {
#if defined(__linux__) && !defined(PSQ_NO_POPULATE)
#ifdef MADV_POPULATE_WRITE
  constexpr int kPopulateWrite = MADV_POPULATE_WRITE;
#else
  constexpr int kPopulateWrite = 23;  // Linux's value, for C library headers that predate it
#endif
  // After a refusal that will not change (a kernel before 5.14: EINVAL; a
  // sandbox that filters the call: ENOSYS or EPERM), no more calls.
  static std::atomic<bool> refused{false};
  if (refused.load(std::memory_order_relaxed)) return;
  static const uintptr_t page = static_cast<uintptr_t>(sysconf(_SC_PAGESIZE));
  if (page == 0 || (page & (page - 1)) != 0) return;
  const uintptr_t begin = (reinterpret_cast<uintptr_t>(p) + page - 1) & ~(page - 1);
  const uintptr_t end = (reinterpret_cast<uintptr_t>(p) + bytes) & ~(page - 1);
  if (end <= begin) return;
  if (madvise(reinterpret_cast<void*>(begin), end - begin, kPopulateWrite) != 0 &&
      (errno == EINVAL || errno == ENOSYS || errno == EPERM))
    refused.store(true, std::memory_order_relaxed);
#else
  (void)p;
  (void)bytes;
#endif
}

}  // namespace codec
}  // namespace psq
