// SPDX-License-Identifier: Apache-2.0
// libFuzzer target: the .psq decoder on arbitrary bytes.
//
// Fuzzing builds skip the checksum comparisons (FUZZING_BUILD_MODE_UNSAFE_
// FOR_PRODUCTION, see codec/src/decoder.cpp), so mutated records reach the
// connectivity, geometry and property decoders. The decoder must return an
// error or a sequence; a sequence it yields must be valid (SequenceChecker)
// and must not end without its end record having been checked, and
// decode_mesh() must agree with it, on one thread and on two. A crash, hang, sanitizer report, an
// invalid sequence or a disagreement traps.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>

#include "psq/psq_codec.h"
#include "psq/psq_memory.h"
#include "psq/sequence_check.h"

namespace {

// The events path (PsqDecoder::next), every event checked.
psq::Status decode_events(const uint8_t* data, size_t size) {
  psq::InputStream in;
  in.open_memory(data, size, "<memory>");
  psq::PsqDecoder decoder;
  PSQ_RETURN_IF_ERROR(decoder.open(&in));
  psq::SequenceChecker checker;
  if (!checker.begin(decoder.schema()).ok()) std::abort();
  psq::SequenceEvent e;
  for (;;) {
    PSQ_RETURN_IF_ERROR(decoder.next(&e));  // rejected: fine, as long as it did not crash
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
    if (e.kind == psq::SequenceEvent::Kind::kEnd) return psq::Status();
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const psq::Status events = decode_events(data, size);
  // decode_mesh() decodes the common records of a fast stream in a loop of
  // its own (codec/src/record_decoder.cpp): it must fail exactly as the
  // events path does, and leave no mesh behind.
  psq::MeshBuffers mesh;
  const psq::Status direct = psq::decode_mesh(data, size, &mesh, 1);
  if (direct.to_string() != events.to_string()) {
    std::fprintf(stderr, "decode_mesh: %s\nevents: %s\n", direct.to_string().c_str(), events.to_string().c_str());
    std::abort();
  }
  if (!direct.ok() && (!mesh.positions.empty() || !mesh.indices.empty())) std::abort();
  // A stream of several segments decodes on two threads (spec 4.6): the
  // same streams are accepted, into the same mesh (the errors may name
  // another place: each segment reports its own first).
  psq::MeshBuffers parallel;
  const psq::Status segments = psq::decode_mesh(data, size, &parallel, 2);
  if (segments.ok() != direct.ok() || parallel.positions != mesh.positions || parallel.indices != mesh.indices) {
    std::fprintf(stderr, "decode_mesh on two threads: %s\none thread: %s\n", segments.to_string().c_str(),
                 direct.to_string().c_str());
    std::abort();
  }
  return 0;
}
