// codec/src/pages.cpp: see pages.h.
#include "pages.h"

#include <cstdint>

#if defined(__linux__)
#include <sys/mman.h>
#include <unistd.h>
#endif

namespace psq {
namespace codec {

void populate_for_write(void* p, size_t bytes) {
#if defined(__linux__)
  // The value of MADV_POPULATE_WRITE in Linux's uapi headers, for C
  // libraries whose headers predate it; a kernel without it returns
  // EINVAL, which is ignored like any other failure of a hint.
  constexpr int kPopulateWrite = 23;
  static const uintptr_t page = static_cast<uintptr_t>(sysconf(_SC_PAGESIZE));
  if (page == 0 || (page & (page - 1)) != 0) return;
  const uintptr_t begin = (reinterpret_cast<uintptr_t>(p) + page - 1) & ~(page - 1);
  const uintptr_t end = (reinterpret_cast<uintptr_t>(p) + bytes) & ~(page - 1);
  if (end > begin) (void)madvise(reinterpret_cast<void*>(begin), end - begin, kPopulateWrite);
#else
  (void)p;
  (void)bytes;
#endif
}

}  // namespace codec
}  // namespace psq
