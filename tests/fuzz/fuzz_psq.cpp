// libFuzzer target: the .psq decoder on arbitrary bytes.
//
// Fuzzing builds skip the checksum comparisons (FUZZING_BUILD_MODE_UNSAFE_
// FOR_PRODUCTION, see codec/src/decoder.cpp), so mutated records reach the
// connectivity, geometry and property decoders. The decoder must return an
// error or a sequence; a sequence it yields must be valid (SequenceChecker)
// and must not end without its end record having been checked. A crash,
// hang, sanitizer report, or an invalid sequence traps.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>

#include "psq/psq_codec.h"
#include "psq/sequence_check.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  psq::InputStream in;
  in.open_memory(data, size, "fuzz.psq");
  psq::PsqDecoder decoder;
  if (!decoder.open(&in).ok()) return 0;
  psq::SequenceChecker checker;
  if (!checker.begin(decoder.schema()).ok()) std::abort();
  psq::SequenceEvent e;
  for (;;) {
    psq::Status s = decoder.next(&e);
    if (!s.ok()) return 0;  // rejected: fine, as long as it did not crash
    psq::Status c;
    switch (e.kind) {
      case psq::SequenceEvent::Kind::kVertex: c = checker.vertex(e.vertex); break;
      case psq::SequenceEvent::Kind::kTriangle: c = checker.triangle(e.triangle); break;
      case psq::SequenceEvent::Kind::kFinalize: c = checker.finalize(e.finalized); break;
      case psq::SequenceEvent::Kind::kEnd: c = checker.finish(); break;
    }
    // The decoder checks everything it yields; the checker must agree.
    if (!c.ok()) {
      std::fprintf(stderr, "decoded sequence is invalid: %s\n", c.to_string().c_str());
      std::abort();
    }
    if (e.kind == psq::SequenceEvent::Kind::kEnd) return 0;
  }
}
