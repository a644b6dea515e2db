// SPDX-License-Identifier: Apache-2.0
// tools/src/ops (see json.h): what psq info counts in a mesh file, and the
// JSON object `psq info --json` prints (psq.info returns it as a dict).
#ifndef PSQ_TOOLS_OPS_INFO_H_
#define PSQ_TOOLS_OPS_INFO_H_

#include <cstdint>
#include <string>

#include "pipeline.h"
#include "psq/psq_codec.h"
#include "psq/sequence_check.h"

namespace psq::detail {

// The numbers of psq info. For a .psq the sequence figures are the file's
// own, counted as it is decoded (nothing rebuilt) and the mesh figures
// those of the mesh it holds; any other input is turned into the
// processing sequence psq convert would build.
struct InfoReport {
  MeshFormat format = MeshFormat::kUnknown;
  MeshSchema schema;
  uint64_t vertices = 0, triangles = 0, unreferenced = 0, degenerate = 0;
  uint64_t polygons_triangulated = 0, strip_triangles = 0;  // the reader's
  double bbox_min[3] = {0, 0, 0}, bbox_max[3] = {0, 0, 0};
  uint64_t border_edges = 0, nonmanifold_vertices = 0, nonmanifold_edges = 0, misoriented_edges = 0;
  SequenceStats sequence;  // components, loops, handles, ops, boundary
  bool from_file = false;  // a .psq: its own sequence, and `header`, `psq`
  BuildReport build;       // else: how the sequence was built
  PsqHeader header;
  PsqStats psq;
  std::vector<std::string> notes;  // the reader's
};

// Reads `mesh` (just opened) through and counts. The sequence builder
// takes `build`'s budget and directory. Errors: the reader's, the
// decoder's, the builder's.
Status measure_info(OpenedMesh& mesh, const BuildOptions& build, InfoReport* report, RunObserver* observer = nullptr);

// `psq info --json`: one object, a field a line, ending in a newline.
std::string info_json(const std::string& file, const InfoReport& report);

}  // namespace psq::detail

#endif  // PSQ_TOOLS_OPS_INFO_H_
