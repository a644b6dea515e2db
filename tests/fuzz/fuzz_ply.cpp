// libFuzzer target: PlyReader over arbitrary bytes.
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
#include "psq/ply.h"

namespace {

// Meshes above this size skip the sequence oracle (the sort path's rank
// array under 1 MiB holds 131072 vertices; the fuzzer's inputs are far
// smaller anyway).
constexpr uint64_t kOracleMaxElements = 100000;

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  (void)psq::detect_format(data, size);  // content sniffing is a parser too

  psq::fuzz::DiscardSink sink;
  {
    psq::InputStream in;
    in.open_memory(data, size, "<fuzz>");
    psq::PlyReader reader;
    if (!reader.open(&in).ok()) return 0;
    (void)reader.encoding();
    (void)reader.schema();
    if (!psq::pump(reader, sink).ok()) return 0;
    (void)reader.report();
  }
  if (sink.vertices > kOracleMaxElements || sink.triangles > kOracleMaxElements) return 0;

  const psq::BuildOptions options[2] = {psq::BuildOptions(), psq::fuzz::sort_options()};
  const char* names[2] = {"PLY -> build_sequence (default)", "PLY -> build_sequence (force_sort, 1 MiB)"};
  for (int i = 0; i < 2; ++i) {
    psq::InputStream in;
    in.open_memory(data, size, "<fuzz>");
    psq::PlyReader reader;
    psq::Status s = reader.open(&in);
    if (!s.ok()) psq::fuzz::die("PLY header accepted once, rejected the second time", s);
    psq::fuzz::check_sequence(reader, options[i], names[i]);
  }
  return 0;
}
