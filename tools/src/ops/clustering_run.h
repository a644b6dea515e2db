// SPDX-License-Identifier: Apache-2.0
// tools/src/ops (see json.h): the passes of psq simplify --method
// clustering (and psq.simplify) before the one that writes: the bounding
// box of a lossless .psq, and the trial passes that pick the grid for a
// target triangle count (--triangles, --ratio).
#ifndef PSQ_TOOLS_OPS_CLUSTERING_RUN_H_
#define PSQ_TOOLS_OPS_CLUSTERING_RUN_H_

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "psq/clustering.h"
#include "psq/psq_codec.h"

namespace psq::detail {

// A lossless .psq declares no bounding box, and the grid needs one before
// the first vertex: one pass of `decoder` (used up then) measures it into
// `options`. Errors: the decoder's.
Status measure_bounds(PsqDecoder& decoder, ClusteringOptions* options);

// The target of `ratio` (0, 1] of an input that declares
// `declared_triangles` (0 when it declares none: the first trial pass
// counts them).
uint64_t ratio_target(double ratio, int64_t declared_triangles);

// One trial pass: the clustering filter with `options` over a fresh
// opening of the input, its output counted, not written. Sets the input's
// triangles and the output's.
using ClusteringTrial =
    std::function<Status(const ClusteringOptions& options, uint64_t* triangles_in, uint64_t* triangles_out)>;

// Picks the grid that gives about `*target` triangles (within 2%, or as
// near as the trials get): the output grows about as the grid squared, so
// one trial from `options->grid` (first_grid_for_triangles()), a second
// only when the first was far off, then the final grid interpolated in
// log-log through both. With `*target` 0 and a `ratio`, the first pass
// counts the input and sets `*target`. On return `options->grid` is the
// grid to write with. Errors: the trial's.
Status search_grid(uint64_t* target, double ratio, ClusteringOptions* options, const ClusteringTrial& trial);

// The notes of a clustering run: the input's list properties dropped
// (lists do not merge), `writer_notes` (what the output format could not
// hold), and why an output is empty.
std::vector<std::string> clustering_notes(const MeshSchema& input, const ClusteringStats& stats,
                                          const std::vector<std::string>& writer_notes);

}  // namespace psq::detail

#endif  // PSQ_TOOLS_OPS_CLUSTERING_RUN_H_
