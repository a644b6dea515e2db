// SPDX-License-Identifier: Apache-2.0
// libFuzzer target: StlReader over arbitrary bytes (built once
// tools/src/stl_reader.cpp is part of psq_convert).
//
// Any Status is an acceptable answer; crashes, sanitizer reports, leaks and
// timeouts are bugs. When the reader accepts the whole input, the mesh is
// read a second time into build_sequence (default options, then the forced
// external sort under a 1 MiB budget) and SequenceChecker must accept it.
#include <cstddef>
#include <cstdint>

#include "common.h"
#include "psq/io.h"
#include "psq/mesh_formats.h"
#include "psq/stl.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return psq::fuzz::fuzz_reader<psq::StlReader>(data, size, "STL");
}
