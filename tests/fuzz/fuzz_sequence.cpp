// SPDX-License-Identifier: Apache-2.0
// libFuzzer target: build_sequence over arbitrary index soups.
//
// The bytes describe a small indexed mesh:
//   byte 0: bits 0-5: vertex count n - 1 (n in [1, 64]);
//           bit 6: the source yields the triangles before the vertices;
//           bit 7: vertices carry a uchar property, triangles an int one;
//   then each 3 bytes: one triangle, each index = byte mod n (at most 200).
// Vertex i is at (i, i*i mod 7, i mod 3): positions are distinct. Such a
// soup reaches every non-manifold case (edges of 3+ triangles, misoriented
// pairs, pinched fans, degenerate and duplicate triangles, isolated
// vertices), and every one of them must still give a valid processing
// sequence: build_sequence runs with the default options and with the
// forced external sort under a 1 MiB budget into a SequenceChecker, and any
// error, or a sequence that loses input vertices or triangles, traps.
#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "common.h"
#include "psq/indexed_mesh.h"
#include "psq/sequence_builder.h"

namespace {

constexpr size_t kMaxTriangles = 200;
using psq::fuzz::Soup;
using psq::fuzz::SoupSource;

void run(const Soup& soup, uint64_t degenerate, const psq::BuildOptions& options, const char* what) {
  SoupSource source(soup);
  psq::fuzz::RecordingChecker checker;
  psq::BuildReport report;
  psq::Status s = psq::build_sequence(source, checker, options, &report);
  if (checker.rejected) psq::fuzz::die(what, checker.first_error);
  if (!s.ok()) psq::fuzz::die(what, s);
  const psq::SequenceStats& st = checker.checker.stats();
  if (st.vertices != soup.n) {
    psq::fuzz::die(what, psq::Status(psq::ErrorCode::kInternal,
                                     "sequence has " + std::to_string(st.vertices) + " input vertices, mesh " +
                                         std::to_string(soup.n)));
  }
  if (st.triangles != soup.triangles.size() - degenerate) {
    psq::fuzz::die(what, psq::Status(psq::ErrorCode::kInternal,
                                     "sequence has " + std::to_string(st.triangles) + " triangles, mesh " +
                                         std::to_string(soup.triangles.size() - degenerate) +
                                         " non-degenerate"));
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  Soup soup;
  soup.n = 1u + (data[0] & 63u);
  soup.faces_first = (data[0] & 0x40) != 0;
  soup.with_values = (data[0] & 0x80) != 0;
  uint64_t degenerate = 0;
  for (size_t p = 1; p + 3 <= size && soup.triangles.size() < kMaxTriangles; p += 3) {
    std::array<uint32_t, 3> t = {data[p] % soup.n, data[p + 1] % soup.n, data[p + 2] % soup.n};
    if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) ++degenerate;
    soup.triangles.push_back(t);
  }
  run(soup, degenerate, psq::BuildOptions(), "build_sequence (default)");
  run(soup, degenerate, psq::fuzz::sort_options(), "build_sequence (force_sort, 1 MiB)");
  return 0;
}
