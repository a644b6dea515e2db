// SPDX-License-Identifier: Apache-2.0
// psq distance's report of Metro's surface distance (Cignoni, Rocchini,
// Scopigno 1998; psq/distance.h); see distance_report.h.
#include "distance_report.h"

#include <algorithm>
#include <cmath>
#include <thread>

#include "json.h"

namespace psq::detail {
namespace {

std::string json_stats(const DirectionDistance& d, double div, bool counts) {
  std::string s = "{";
  if (counts) {
    s += "\"samples\": " + std::to_string(d.samples) + ", \"vertex_samples\": " + std::to_string(d.vertex_samples) +
         ", ";
  }
  s += "\"max\": " + json_number(d.max / div) + ", \"mean\": " + json_number(d.mean / div) +
       ", \"rms\": " + json_number(d.rms / div) + "}";
  return s;
}

std::string json_mesh(const std::string& file, const MeshDistanceSummary& m) {
  return "{\"file\": " + json_string(file) + ", \"vertices\": " + std::to_string(m.vertices) +
         ", \"used_vertices\": " + std::to_string(m.used_vertices) + ", \"triangles\": " +
         std::to_string(m.triangles) + ", \"area\": " + json_number(m.area) + ", \"held\": " +
         (m.held ? "true" : "false") + "}";
}

}  // namespace

uint64_t estimated_triangles(const OpenedMesh& m) {
  const int64_t t = m.source->schema().triangle_count;
  if (t >= 0) return static_cast<uint64_t>(t);
  const int64_t size = m.stream->size();
  if (size >= 0) return static_cast<uint64_t>(size) / 25;
  return UINT64_MAX;
}

DistanceHold auto_hold(const OpenedMesh& a, const OpenedMesh& b) {
  const uint64_t ta = estimated_triangles(a), tb = estimated_triangles(b);
  if (std::max(ta, tb) <= kAutoInMemoryTriangles) return DistanceHold::kBoth;
  return ta < tb ? DistanceHold::kA : DistanceHold::kB;
}

DistanceSummary summarize_distance(const DistanceResult& r, const DistanceOptions& options) {
  DistanceSummary s;
  s.symmetric.max = r.hausdorff;
  s.symmetric.mean = std::max(r.a_to_b.mean, r.b_to_a.mean);
  s.symmetric.rms = std::max(r.a_to_b.rms, r.b_to_a.rms);
  const uint64_t total = r.a_to_b.samples + r.b_to_a.samples;
  s.samples_per_second = r.seconds > 0 ? static_cast<double>(total) / r.seconds : 0;
  s.threads = options.threads > 0 ? options.threads
                                  : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  // Relative values are undefined when A's bounding box is a point.
  s.diagonal = r.diagonal > 0 ? r.diagonal : std::nan("");
  return s;
}

std::string distance_error_file(const DistanceResult& r, const std::string& a, const std::string& b,
                                const std::string& tmpdir) {
  if (r.error_input == 1) return a;
  if (r.error_input == 2) return b;
  return tmpdir.empty() ? "temporary file" : tmpdir;
}

std::string distance_json(const std::string& a, const std::string& b, const DistanceOptions& options,
                          const DistanceResult& r) {
  const DistanceSummary s = summarize_distance(r, options);
  const double diag = s.diagonal;
  std::string o = "{\n";
  o += "  \"a\": " + json_mesh(a, r.a) + ",\n";
  o += "  \"b\": " + json_mesh(b, r.b) + ",\n";
  o += "  \"seed\": " + std::to_string(options.seed) + ",\n";
  o += "  \"a_to_b\": " + json_stats(r.a_to_b, 1, true) + ",\n";
  o += "  \"b_to_a\": " + json_stats(r.b_to_a, 1, true) + ",\n";
  o += "  \"hausdorff\": " + json_number(r.hausdorff) + ",\n";
  o += "  \"symmetric\": " + json_stats(s.symmetric, 1, false) + ",\n";
  o += "  \"diagonal\": " + json_number(r.diagonal) + ",\n";
  o += "  \"relative\": {\"a_to_b\": " + json_stats(r.a_to_b, diag, false) + ", \"b_to_a\": " +
       json_stats(r.b_to_a, diag, false) + ", \"hausdorff\": " + json_number(r.hausdorff / diag) +
       ", \"symmetric\": " + json_stats(s.symmetric, diag, false) + "},\n";
  o += "  \"timing\": {\"seconds\": " + json_number(r.seconds) + ", \"samples_per_second\": " +
       json_number(s.samples_per_second) + ", \"threads\": " + std::to_string(s.threads) + "}\n}\n";
  return o;
}

}  // namespace psq::detail
