// SPDX-License-Identifier: Apache-2.0
// psq/clustering.h: out-of-core simplification by vertex clustering on the
// processing boundary (Isenburg, Lindstrom, Gumhold, Snoeyink 2003, section
// 5; Lindstrom's OoCS, 2000).
//
// ClusteringFilter is a SequenceSink: it reads a processing sequence (the
// .psq decoder, or any mesh through build_sequence()) and writes the
// simplified mesh to a StreamingMeshSink (psq/mesh_stream.h): through a
// SequenceConverter to the .psq encoder, or through a DenseMeshSink to a
// PLY, OBJ or Draco writer. It never holds the mesh.
//
// Space is cut into a uniform grid of cubic cells. Every input vertex falls
// into a cell; the vertices of a cell are grouped into clusters, each
// cluster becomes one output vertex, and an input triangle whose three
// corners fall into three different cells becomes an output triangle over
// their clusters (each distinct triangle once). What a cluster is depends
// on the cell mode:
//
// - kGlobal: the original OoCS: a cell is one cluster for the whole run.
//   Its quadric lives until the end, so memory grows with the output, and
//   everything is output at finish(). Surfaces that pass through one cell
//   are pinched together.
// - kActive: a cell is a cluster while it holds vertices of the processing
//   boundary (paper, Figure 4): a counter per cell counts its vertices not
//   yet finalized; when it drops to zero, the cluster's vertex is computed
//   and output and the cell is freed. A boundary that comes back to the cell
//   later starts a new cluster there, so layers that the sequence visits at
//   different times are not pinched.
// - kConnected (the default): a cluster is a connected component of the
//   cell: every new vertex starts a cluster, and two clusters of the same
//   cell merge when an edge of a triangle joins them (which is collapsing
//   every edge whose ends share a cell). Counters add when clusters merge;
//   a cluster is output when its own counter drops to zero. Layers that
//   are not connected inside a cell stay apart (paper, Figures 5 and 6).
//
// The output vertex of a cluster minimizes its quadric: the area-weighted
// plane quadrics of the input triangles at its vertices (Garland and
// Heckbert 1997; a triangle adds its plane once per corner, so a cluster's
// quadric is the sum of its vertices' quadrics), plus, for border edges
// (the mesh's own holes and rims, known from the sequence's border mask;
// edges that are borders only because a non-manifold input was cut are
// not), the quadric of the plane through the edge perpendicular to its
// triangle, weighted like a strip one cell wide along the edge times
// `border_weight`. The minimization drops ill-conditioned directions
// (eigenvalues below 1/1000 of the largest) and solves relative to the
// cluster's mean position (Lindstrom 2000), and the result is clamped to
// the cell (and the input's bounds), so that every output vertex lies in
// the cell of its cluster: the error is bounded by the cell. With float
// positions the vertex is a float, still inside its cell. A cluster of
// one vertex is that vertex exactly (a grid that keeps everything gives the
// input back).
//
// Non-manifold input vertices re-appear in the sequence (cut apart, paper
// section 3). Global and active cells put all occurrences of a vertex in
// its cell's cluster; in connected mode a re-appearance joins the cluster
// of its first occurrence while that is still on the boundary, and starts
// its own otherwise (the sequence visits the other fan later, like a layer
// that comes back).
//
// Output triangles wait (in the filter) until their three clusters are
// output, then go to the sink, duplicates (the same three clusters in the
// same orientation) dropped; a cluster's vertex is finalized when its last
// triangle went out. So the sink always gets a triangle's vertices before
// the triangle. A cluster that no output triangle uses (a component that
// collapsed into fewer than three cells) leaves no vertex. Output vertex
// ids are 0, 1, 2, ... in the order the vertices are output. Property
// values merge by the rules of psq/property_merge.h.
//
// Memory: kConnected and kActive keep a record per cluster alive on the
// processing boundary, per boundary vertex, and per output triangle waiting
// for its clusters: proportional to the boundary's length, never to the
// mesh or the output. kGlobal keeps one record per occupied cell. The
// filter fails with kLimit when its structures would exceed
// `memory_budget`.
//
// Deterministic: the same sequence, options and build give the same
// output events, on one thread or behind a ThreadedSequenceSink.
//
// Safe on untrusted sequences: events that break the processing-sequence
// rules the filter relies on (an unknown or reused slot, a vertex used
// after its finalization, a slot beyond 2^28) are kBadSequence errors,
// never a crash.
#ifndef PSQ_CLUSTERING_H_
#define PSQ_CLUSTERING_H_

#include <cstdint>
#include <memory>
#include <string>

#include "psq/mesh_stream.h"
#include "psq/property_merge.h"
#include "psq/sequence.h"
#include "psq/status.h"

namespace psq {

enum class CellMode : uint8_t { kGlobal = 0, kActive = 1, kConnected = 2 };

// "global", "active" or "connected".
const char* cell_mode_name(CellMode mode);
// Parses a name of cell_mode_name(); false for anything else.
bool parse_cell_mode(const std::string& name, CellMode* mode);

// The uniform grid: cubic cells of edge `cell` from `origin`, `dims` cells
// along each axis. A point's cell is floor((p - origin) / cell) per axis,
// clamped to 0 .. dims - 1.
struct ClusterGrid {
  static constexpr uint32_t kMaxDim = 1u << 21;  // cells along an axis, at most

  double origin[3] = {0, 0, 0};
  double cell = 1;
  uint32_t dims[3] = {1, 1, 1};

  void cell_of(const double p[3], uint32_t ijk[3]) const;
  // The cell packed into one number (21 bits per axis).
  uint64_t key_of(const double p[3]) const;
  uint64_t cells() const { return uint64_t{dims[0]} * dims[1] * dims[2]; }
};

// The grid over the box lo..hi with `n` (>= 1) cells along its longest
// side (a fraction makes cells of the longest side / n, the last one
// reaching past the box), or cells of edge `size` (> 0). A box of no
// extent gets one cell. Errors: kUsage (n < 1 or not finite, size not a
// positive finite number, a box that is not finite or inverted), kLimit
// (more than ClusterGrid::kMaxDim cells along an axis).
Status grid_with_cells(const double lo[3], const double hi[3], double n, ClusterGrid* grid);
Status grid_with_size(const double lo[3], const double hi[3], double size, ClusterGrid* grid);

// For a target triangle count (psq simplify --triangles): a first grid to
// try, and the grid that a trial's result suggests, in cells along the
// longest side (fractional: the count follows the cell size continuously,
// not in the steps of whole cells across). A surface's output has about
// c * n^2 triangles at n cells along the longest side (the cells a surface
// passes through grow with the square of the resolution), so one trial
// gives c and the correction n * sqrt(target / trial_triangles). Both give
// 1 .. kMaxDim - 1.
double first_grid_for_triangles(uint64_t target);
double corrected_grid_for_triangles(uint64_t target, double trial_grid, uint64_t trial_triangles);

struct ClusteringOptions {
  CellMode cells = CellMode::kConnected;
  // The grid: `grid` cells along the longest side of the input's bounds
  // (the schema's; see begin(); fractional: see grid_with_cells()), or,
  // when `grid` is 0, cells of edge `cell_size`.
  double grid = 256;
  double cell_size = 0;
  // The box the grid is built on, instead of the schema's bounds: for an
  // input that declares none (a lossless .psq), whose box a first pass
  // measured. It must hold every input vertex.
  bool has_bounds = false;
  double bounds_min[3] = {0, 0, 0};
  double bounds_max[3] = {0, 0, 0};
  // Weight of the border quadrics (0: none).
  double border_weight = 1;
  // The filter's share of the pipeline's memory (psq/memory_budget.h): its
  // structures fail with kLimit beyond it.
  uint64_t memory_budget = uint64_t{256} << 20;
  // Merge rules of the vertex and face properties, one per property of the
  // input schema; empty vectors mean default_merge_policy().
  MergePolicy merge;
};

struct ClusteringStats {
  ClusterGrid grid;             // valid after begin()
  uint64_t vertices_in = 0;     // vertex events (re-appearances included)
  uint64_t triangles_in = 0;
  uint64_t vertices_out = 0;
  uint64_t triangles_out = 0;
  uint64_t clusters = 0;          // clusters closed
  uint64_t clusters_unused = 0;   // closed without an output triangle: no vertex
  uint64_t duplicates = 0;        // output triangles dropped: the same clusters and orientation as another
  uint64_t max_clusters = 0;      // most clusters alive at once
  uint64_t max_waiting = 0;       // most output triangles waiting for their clusters at once
  uint64_t peak_bytes = 0;        // the filter's structures, at most (their allocated capacity)
  double area = 0;                // surface area of the input
};

class ClusteringFilter : public SequenceSink {
 public:
  // `out` must outlive the filter.
  ClusteringFilter(StreamingMeshSink* out, const ClusteringOptions& options);
  ~ClusteringFilter() override;
  ClusteringFilter(const ClusteringFilter&) = delete;
  ClusteringFilter& operator=(const ClusteringFilter&) = delete;

  // Builds the grid on the schema's bounds and begins the output with
  // merged_schema() (the input's bounds kept: every output vertex lies in
  // them, so a .psq encoder quantizes the output on the input's grid).
  // Errors: kUsage (neither the options nor the schema have bounds; bad
  // options; merge rules that do not match the schema), kLimit (the grid),
  // the sink's.
  Status begin(const MeshSchema& schema) override;
  // Errors (sticky): kBadSequence (see above), kLimit (memory_budget), the
  // sink's.
  Status vertex(const SequenceVertex& v) override;
  Status triangle(const SequenceTriangle& t) override;
  Status finalize(uint32_t index) override;
  // Outputs what is left (kGlobal: everything) and finishes the sink.
  Status finish() override;

  const ClusteringStats& stats() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace psq

#endif  // PSQ_CLUSTERING_H_
