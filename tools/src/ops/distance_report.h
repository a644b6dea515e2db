// SPDX-License-Identifier: Apache-2.0
// tools/src/ops (see json.h): psq distance's run and report: which mesh is
// held, the symmetric row, and the JSON object `psq distance --json`
// prints (psq.distance returns it as a dict).
#ifndef PSQ_TOOLS_OPS_DISTANCE_REPORT_H_
#define PSQ_TOOLS_OPS_DISTANCE_REPORT_H_

#include <cstdint>
#include <string>

#include "psq/distance.h"
#include "psq/mesh_formats.h"

namespace psq::detail {

// The triangles a mesh will have: its header's count, or a guess from its
// size (about 25 bytes a triangle for text formats), or UINT64_MAX when
// unknown (a pipe).
uint64_t estimated_triangles(const OpenedMesh& mesh);

// What DistanceHold::kAuto means for these two inputs: both held when
// neither has more than kAutoInMemoryTriangles (as estimated), else the
// smaller held and the other streamed.
DistanceHold auto_hold(const OpenedMesh& a, const OpenedMesh& b);

// The numbers of a distance report besides DistanceResult's.
struct DistanceSummary {
  DirectionDistance symmetric;  // the larger of the two directions
  double diagonal = 0;          // A's bounding box diagonal; NaN when A is a point
  double samples_per_second = 0;
  int threads = 1;              // what the run used
};
DistanceSummary summarize_distance(const DistanceResult& result, const DistanceOptions& options);

// The file a failed measure_distance() concerns: A, B, or the directory
// of its temporary file.
std::string distance_error_file(const DistanceResult& result, const std::string& a, const std::string& b,
                                const std::string& tmpdir);

// `psq distance --json`: one object, a field a line, ending in a newline.
std::string distance_json(const std::string& a, const std::string& b, const DistanceOptions& options,
                          const DistanceResult& result);

}  // namespace psq::detail

#endif  // PSQ_TOOLS_OPS_DISTANCE_REPORT_H_
