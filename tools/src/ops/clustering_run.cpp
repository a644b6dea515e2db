// SPDX-License-Identifier: Apache-2.0
// The passes of out-of-core vertex clustering (Lindstrom's OoCS, with the
// processing-sequence extensions of Isenburg et al. 2003, section 5)
// before the one that writes; see clustering_run.h.
#include "clustering_run.h"

#include <algorithm>
#include <cmath>

#include "pipeline.h"

namespace psq::detail {

Status measure_bounds(PsqDecoder& decoder, ClusteringOptions* options) {
  SequenceBox box;
  PSQ_RETURN_IF_ERROR(decoder.pump(box));
  options->has_bounds = true;
  std::copy(box.lo, box.lo + 3, options->bounds_min);
  std::copy(box.hi, box.hi + 3, options->bounds_max);
  return Status();
}

uint64_t ratio_target(double ratio, int64_t declared_triangles) {
  if (declared_triangles <= 0) return 0;
  return std::max<uint64_t>(1, static_cast<uint64_t>(std::llround(ratio * static_cast<double>(declared_triangles))));
}

Status search_grid(uint64_t* target, double ratio, ClusteringOptions* options, const ClusteringTrial& trial) {
  double trial_grid[2] = {options->grid, 0};
  uint64_t trial_triangles[2] = {0, 0};
  for (int t = 0; t < 2; ++t) {
    ClusteringOptions o = *options;
    o.grid = trial_grid[t];
    uint64_t in = 0;
    PSQ_RETURN_IF_ERROR(trial(o, &in, &trial_triangles[t]));
    if (*target == 0) {
      // A ratio of an input that declares no count: this pass counted it,
      // and the trials start over from the grid the target implies.
      *target = std::max<uint64_t>(1, static_cast<uint64_t>(std::llround(ratio * static_cast<double>(in))));
      options->grid = trial_grid[0] = first_grid_for_triangles(*target);
      t = -1;
      continue;
    }
    const double goal = static_cast<double>(*target);
    const double off = std::fabs(static_cast<double>(trial_triangles[t]) - goal) / goal;
    if (off <= 0.02) {
      options->grid = trial_grid[t];
      break;
    }
    if (t == 0) {
      options->grid = corrected_grid_for_triangles(*target, trial_grid[0], trial_triangles[0]);
      // Close enough for the square law to hold: no second trial.
      const double change = options->grid / trial_grid[0];
      if (change > 0.8 && change < 1.25) break;
      trial_grid[1] = options->grid;
    } else if (trial_triangles[0] > 0 && trial_triangles[1] > 0 && trial_triangles[0] != trial_triangles[1]) {
      // Interpolated in log-log through both trials.
      const double slope = std::log(static_cast<double>(trial_triangles[1]) / trial_triangles[0]) /
                           std::log(trial_grid[1] / trial_grid[0]);
      options->grid = slope > 0.5 ? trial_grid[1] * std::pow(goal / trial_triangles[1], 1 / slope)
                                  : corrected_grid_for_triangles(*target, trial_grid[1], trial_triangles[1]);
      options->grid = std::min<double>(ClusterGrid::kMaxDim - 1, std::max(1.0, options->grid));
    } else {
      options->grid = corrected_grid_for_triangles(*target, trial_grid[1], trial_triangles[1]);
    }
  }
  return Status();
}

std::vector<std::string> clustering_notes(const MeshSchema& input, const ClusteringStats& stats,
                                          const std::vector<std::string>& writer_notes) {
  std::vector<std::string> notes;
  for (const Property& p : input.vertex_properties)
    if (p.is_list) notes.push_back("vertex property '" + p.name + "' dropped: lists do not merge");
  for (const Property& p : input.face_properties) {
    if (!p.is_list) continue;
    // Texture coordinates and normals per corner (an OBJ's vt and vn):
    // the edge-collapse simplifier keeps them in their charts.
    const bool corner = p.name == "corner_uv" || p.name == "corner_normals";
    notes.push_back("face property '" + p.name + "' dropped: lists do not merge" +
                    (corner ? " (--method qem keeps them)" : ""));
  }
  notes.insert(notes.end(), writer_notes.begin(), writer_notes.end());
  if (stats.triangles_in > 0 && stats.triangles_out == 0)
    notes.push_back("no triangle has its corners in three cells: the output is empty (use a finer grid)");
  return notes;
}

}  // namespace psq::detail
