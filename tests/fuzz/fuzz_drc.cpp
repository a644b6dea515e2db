// SPDX-License-Identifier: Apache-2.0
// libFuzzer target: DracoReader (check_draco_header, then libdraco) over
// arbitrary bytes.
//
// Any Status is an acceptable answer; crashes, sanitizer reports, leaks,
// timeouts and out-of-memory are bugs. The reader runs under a 4 MiB memory
// budget, so a file whose counts would make libdraco allocate more must be
// refused by the pre-check (libFuzzer's -rss_limit_mb and -malloc_limit_mb
// catch it otherwise). libdraco itself is not instrumented: its own memory
// errors show only as crashes. When the reader accepts the whole input, the
// mesh is read again into build_sequence (as in the other reader targets),
// and the processing sequence must pass SequenceChecker.
#include <cstddef>
#include <cstdint>

#include "common.h"
#include "psq/draco.h"
#include "psq/io.h"

namespace {

// Small enough that the estimate's blind spot (many wide attributes, see
// check_draco_header) stays far below libFuzzer's memory limits.
constexpr uint64_t kBudget = uint64_t{4} << 20;

// DracoReader with the one-argument open() that fuzz_reader calls.
class BudgetDracoReader : public psq::DracoReader {
 public:
  psq::Status open(psq::InputStream* in) { return DracoReader::open(in, kBudget); }
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  (void)psq::check_draco_header(data, size, kBudget);
  return psq::fuzz::fuzz_reader<BudgetDracoReader>(data, size, "Draco");
}
