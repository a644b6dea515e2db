// SPDX-License-Identifier: Apache-2.0
// codec/src/crc32c.h: CRC-32C (Castagnoli), the checksum of every .psq
// header, chunk and stream (spec/psq-format.md section 3.3).
#ifndef PSQ_CODEC_CRC32C_H_
#define PSQ_CODEC_CRC32C_H_

#include <cstddef>
#include <cstdint>

namespace psq {
namespace codec {

// Continues a CRC-32C over `size` more bytes; start with crc = 0. The
// value is the standard one (init and final xor 0xffffffff, reflected
// polynomial 0x82f63b78): crc32c_update(0, "123456789", 9) == 0xe3069283.
// With SSE 4.2 on x86-64 it uses the processor's CRC32 instruction, else
// crc32c_update_portable().
uint32_t crc32c_update(uint32_t crc, const void* data, size_t size);

// The same by table lookup on any processor (the tests compare the two).
uint32_t crc32c_update_portable(uint32_t crc, const void* data, size_t size);

}  // namespace codec
}  // namespace psq

#endif  // PSQ_CODEC_CRC32C_H_
