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

namespace {

constexpr uint64_t kOracleMaxElements = 100000;

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  (void)psq::detect_format(data, size);
  (void)psq::looks_like_stl(data, size, static_cast<int64_t>(size));
  (void)psq::looks_like_stl(data, size, -1);

  psq::fuzz::DiscardSink sink;
  {
    psq::InputStream in;
    in.open_memory(data, size, "<fuzz>");
    psq::StlReader reader;
    if (!reader.open(&in).ok()) return 0;
    (void)reader.encoding();
    (void)reader.schema();
    if (!psq::pump(reader, sink).ok()) return 0;
    (void)reader.report();
  }
  if (sink.vertices > kOracleMaxElements || sink.triangles > kOracleMaxElements) return 0;

  const psq::BuildOptions options[2] = {psq::BuildOptions(), psq::fuzz::sort_options()};
  const char* names[2] = {"STL -> build_sequence (default)", "STL -> build_sequence (force_sort, 1 MiB)"};
  for (int i = 0; i < 2; ++i) {
    psq::InputStream in;
    in.open_memory(data, size, "<fuzz>");
    psq::StlReader reader;
    psq::Status s = reader.open(&in);
    if (!s.ok()) psq::fuzz::die("STL accepted once, rejected the second time", s);
    psq::fuzz::check_sequence(reader, options[i], names[i]);
  }
  return 0;
}
