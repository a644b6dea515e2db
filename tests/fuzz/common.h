// Shared pieces of psq's libFuzzer targets: a sink that discards, and the
// "every accepted mesh gives a valid processing sequence" oracle.
#ifndef PSQ_TESTS_FUZZ_COMMON_H_
#define PSQ_TESTS_FUZZ_COMMON_H_

#include <cstdint>
#include <cstdio>
#include <string>

#include "psq/indexed_mesh.h"
#include "psq/io.h"
#include "psq/mesh_formats.h"
#include "psq/sequence.h"
#include "psq/sequence_builder.h"
#include "psq/sequence_check.h"
#include "psq/status.h"

namespace psq::fuzz {

// Accepts everything, counts what it saw.
class DiscardSink : public MeshSink {
 public:
  Status begin(const MeshSchema&) override { return Status(); }
  Status vertex(const double[3], const PropertyValues&) override {
    ++vertices;
    return Status();
  }
  Status triangle(const uint32_t[3], const PropertyValues&) override {
    ++triangles;
    return Status();
  }
  Status finish() override { return Status(); }
  uint64_t vertices = 0;
  uint64_t triangles = 0;
};

// A SequenceChecker that remembers whether it rejected anything, so that a
// checker failure can be told apart from an error of the source.
class RecordingChecker : public SequenceSink {
 public:
  Status begin(const MeshSchema& s) override { return note(checker.begin(s)); }
  Status vertex(const SequenceVertex& v) override { return note(checker.vertex(v)); }
  Status triangle(const SequenceTriangle& t) override { return note(checker.triangle(t)); }
  Status finalize(uint32_t i) override { return note(checker.finalize(i)); }
  Status finish() override { return note(checker.finish()); }
  SequenceChecker checker;
  bool rejected = false;
  Status first_error;

 private:
  Status note(Status s) {
    if (!s.ok() && !rejected) {
      rejected = true;
      first_error = s;
    }
    return s;
  }
};

[[noreturn]] inline void die(const char* what, const Status& s) {
  std::fprintf(stderr, "psq fuzz: %s: %s (%s)\n", what, s.to_string().c_str(),
               error_name(s.code()));
  __builtin_trap();
}

// Builds the processing sequence of `source` into a SequenceChecker. Traps
// when the checker rejects the sequence or when build_sequence fails with
// an error that `source` (which must be a fresh source over input that was
// already read successfully once) cannot explain. kIo (temporary files) is
// the environment, not psq, and is ignored.
inline void check_sequence(MeshSource& source, const BuildOptions& options, const char* what) {
  RecordingChecker checker;
  BuildReport report;
  Status s = build_sequence(source, checker, options, &report);
  if (checker.rejected) die(what, checker.first_error);
  if (!s.ok() && s.code() != ErrorCode::kIo) die(what, s);
}

// Options of the forced external-sort path with a small budget.
inline BuildOptions sort_options() {
  BuildOptions o;
  o.force_sort = true;
  o.memory_budget = uint64_t{1} << 20;
  return o;
}

// The whole body of a reader's fuzz target: the reader over the bytes (any
// Status is fine); when it accepts them, the mesh again into build_sequence,
// with default options and with the forced external sort, whose sequence
// must pass SequenceChecker. Meshes over `max_elements` skip the second part
// (it would only be slower).
template <class Reader>
int fuzz_reader(const uint8_t* data, size_t size, const char* format, uint64_t max_elements = 100000) {
  (void)detect_format(data, size);  // content sniffing is a parser too
  DiscardSink sink;
  {
    InputStream in;
    in.open_memory(data, size, "<fuzz>");
    Reader reader;
    if (!reader.open(&in).ok()) return 0;
    if (!pump(reader, sink).ok()) return 0;
    (void)reader.report();
  }
  if (sink.vertices > max_elements || sink.triangles > max_elements) return 0;
  const BuildOptions options[2] = {BuildOptions(), sort_options()};
  const char* paths[2] = {"build_sequence (default)", "build_sequence (force_sort, 1 MiB)"};
  for (int i = 0; i < 2; ++i) {
    InputStream in;
    in.open_memory(data, size, "<fuzz>");
    Reader reader;
    Status s = reader.open(&in);
    if (!s.ok()) die("input accepted once, rejected the second time", s);
    std::string what = std::string(format) + " -> " + paths[i];
    check_sequence(reader, options[i], what.c_str());
  }
  return 0;
}

}  // namespace psq::fuzz

#endif  // PSQ_TESTS_FUZZ_COMMON_H_
