// SPDX-License-Identifier: Apache-2.0
// libFuzzer target: ObjReader over arbitrary bytes.
//
// Any Status is an acceptable answer; crashes, sanitizer reports, leaks and
// timeouts are bugs. When the reader accepts the whole input, the mesh is
// read a second time into build_sequence (default options, then the forced
// external sort under a 1 MiB budget) and the processing sequence must pass
// SequenceChecker: a valid mesh always gives a valid sequence.
#include <cstddef>
#include <cstdint>

#include "common.h"
#include "psq/io.h"
#include "psq/mesh_formats.h"
#include "psq/obj.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return psq::fuzz::fuzz_reader<psq::ObjReader>(data, size, "OBJ");
}
