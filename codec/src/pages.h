// SPDX-License-Identifier: Apache-2.0
// codec/src/pages.h: asking the kernel for an array's pages ahead of use.
#ifndef PSQ_CODEC_PAGES_H_
#define PSQ_CODEC_PAGES_H_

#include <cstddef>

namespace psq {
namespace codec {

// Asks the kernel to back the whole pages within the `bytes` bytes at `p`
// with memory now, writable, in one call (Linux's MADV_POPULATE_WRITE),
// instead of one page fault at each page's first write. A hint: nothing
// happens where the kernel lacks it (before Linux 5.14; after the first
// refusal it is not asked again), on other systems, or when psq is built
// with PSQ_NO_POPULATE defined (for sandboxes whose system call filter
// kills a process on an advice it does not list); the memory's contents
// are unchanged either way. Worth it only for memory about to be written
// in full: decode_mesh()'s arrays, whose pages cost far less populated in
// one call than faulted in one at a time (bench/HISTORY.md, "Arrays not
// zeroed, pages populated").
void populate_for_write(void* p, size_t bytes);

}  // namespace codec
}  // namespace psq

#endif  // PSQ_CODEC_PAGES_H_
