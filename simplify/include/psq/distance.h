// SPDX-License-Identifier: Apache-2.0
// psq/distance.h: the surface distance between two triangle meshes, as
// Metro measures it (Cignoni, Rocchini, Scopigno, "Metro: measuring error
// on simplified surfaces", Computer Graphics Forum 17(2), 1998).
//
// Each direction samples one mesh and measures every sample's distance to
// the other mesh's SURFACE (the exact distance to the nearest point of the
// nearest triangle, not to its vertices): A to B samples A, B to A samples B.
// The samples of a mesh are every vertex that a triangle uses, then points
// on its triangles, distributed by area (systematic sampling along the
// triangles' cumulative area with a random offset, each point uniform in its
// triangle). Per direction: the largest distance (the one-sided Hausdorff
// distance), the mean and the root mean square; the symmetric Hausdorff
// distance is the larger of the two maxima.
//
// Size. One mesh is HELD in memory: its triangles in a bounding volume
// hierarchy (BVH; about 110 bytes a triangle) and its samples in a second
// one (about 60 bytes a sample). The other STREAMS: it is read once, its
// positions kept (4 bytes a coordinate for float input, 8 otherwise) and
// its triangles spooled to an unlinked temporary file (12 bytes each),
// then its triangles go by in batches:
//   - its own samples, made as its triangles go by, are measured against
//     the held mesh's triangle BVH;
//   - the held mesh's samples are measured against each batch. Every held
//     sample first gets an upper bound on its distance from up to 4M of
//     the streamed mesh's vertices (any point of a surface bounds the
//     distance to it); each node of the samples' BVH keeps the largest
//     bound below it, and a batch (in a BVH of its own) reaches only the
//     samples it could bring closer. The result is the minimum over all
//     triangles, the same number the all-in-memory path computes: exact,
//     not an estimate.
// A 50M-triangle mesh (float PLY) against a 1M-triangle one takes about
// 800 MB.
//
// Determinism. For a given seed, every number in DistanceResult but the
// time is the same on every run and for every thread count and hold: the
// samples depend only on the seed, the mesh and the sample count; a
// sample's distance is a minimum (order-free); sums run in the samples'
// order. Distances below 2^-40 times the largest coordinate magnitude of
// the two meshes are below the rounding of the computation and count as 0,
// so that a mesh measured against itself gives exactly 0.
//
// Safe on untrusted input: sources check their input (psq/indexed_mesh.h);
// the work is bounded by the counts the sources yield and the sample count.
#ifndef PSQ_DISTANCE_H_
#define PSQ_DISTANCE_H_

#include <cstdint>
#include <string>
#include <vector>

#include "psq/indexed_mesh.h"
#include "psq/status.h"

namespace psq {

// Samples per direction when none are asked for: this many per triangle of
// the sampled mesh, at most kDefaultMaxSamples, and never fewer than the
// mesh's used vertices.
constexpr uint64_t kDefaultSamplesPerTriangle = 10;
constexpr uint64_t kDefaultMaxSamples = 4000000;
// The most samples a direction may be asked for (DistanceOptions::samples).
constexpr uint64_t kMaxSamples = 1000000000;
// Below this many triangles in the larger mesh, kAuto holds both meshes.
constexpr uint64_t kAutoInMemoryTriangles = 2000000;

// Which meshes are held in memory (the rest streams).
enum class DistanceHold : uint8_t {
  // Both when the schemas promise at most kAutoInMemoryTriangles triangles
  // each; else the one whose schema promises fewer triangles (a count the
  // schema does not know counts as more; B when neither is known).
  kAuto,
  kA,     // A is held, B streams
  kB,     // B is held, A streams
  kBoth,  // all in memory: both meshes in triangle BVHs, nothing streams
};

struct DistanceOptions {
  // Samples per direction, vertices included; 0: the default above. When a
  // mesh has more used vertices than this, all of them are its samples and
  // no point on its triangles is added. At most kMaxSamples.
  uint64_t samples = 0;
  uint64_t seed = 1;
  int threads = 0;  // 0: one per processor
  DistanceHold hold = DistanceHold::kAuto;
  std::string tmpdir;  // for the streamed mesh's triangle spool; empty: $TMPDIR
};

struct DirectionDistance {
  uint64_t samples = 0;         // all samples of the direction
  uint64_t vertex_samples = 0;  // of which vertices
  double max = 0;               // the one-sided Hausdorff distance
  double mean = 0;
  double rms = 0;
};

struct MeshDistanceSummary {
  uint64_t vertices = 0;       // as the source yielded them
  uint64_t used_vertices = 0;  // used by at least one triangle
  uint64_t triangles = 0;
  double area = 0;
  double bounds_min[3] = {0, 0, 0};  // of all vertices
  double bounds_max[3] = {0, 0, 0};
  bool held = false;                 // held in memory (else streamed)
};

struct DistanceResult {
  MeshDistanceSummary a, b;
  DirectionDistance a_to_b;  // samples on A, distances to B's surface
  DirectionDistance b_to_a;
  double hausdorff = 0;  // max(a_to_b.max, b_to_a.max)
  double diagonal = 0;   // of A's bounding box; relative values divide by it
  double seconds = 0;    // reading and measuring, wall clock
  // On error: 1 when it concerns A (its source's error, or nothing to
  // measure on it), 2 for B, 0 for neither (a temporary file).
  int error_input = 0;
};

// Reads A and B (each once, to the end; the held one first) and measures
// the distance between them as described above. Errors: a source's error;
// kBadValue when a mesh has no triangle (there is no surface to measure
// to); kUsage for samples > kMaxSamples; kLimit for more than 2^32 - 1
// vertices; kIo from the spool file. A mesh whose triangles all have zero
// area is measured by its vertices alone.
Status measure_distance(MeshSource& a, MeshSource& b, const DistanceOptions& options,
                        DistanceResult* result);

struct NearestTriangle {
  double distance = 0;           // from the point to the mesh's surface
  uint64_t triangle = 0;         // the nearest triangle (its index in the mesh; the smallest of equally near ones)
  double normal[3] = {0, 0, 0};  // its unit normal, (b - a) x (c - a); 0 for a triangle of zero area
};

// For each point of `xyz` (3 doubles a point), the nearest triangle of
// `mesh`, found as measure_distance() finds the held samples' distances to
// a streamed mesh: the points are held, the mesh streams (its positions
// kept, its triangles spooled to options.tmpdir), exactly. Uses
// options.threads. Errors: a source's error; kBadValue when the mesh has
// no triangle; kUsage for a size not a multiple of 3 or a coordinate that
// is not finite; kLimit and kIo as measure_distance().
Status nearest_triangles(MeshSource& mesh, const std::vector<double>& xyz, const DistanceOptions& options,
                         std::vector<NearestTriangle>* out);

// The points that measure_distance() samples on `mesh` for `samples` (0:
// the default) and `seed`, in their order: the used vertices by index, then
// the points on the triangles by triangle. 3 doubles a point. Holds the
// mesh in memory. Errors: as measure_distance().
Status sample_surface(MeshSource& mesh, uint64_t samples, uint64_t seed, std::vector<double>* xyz);

}  // namespace psq

#endif  // PSQ_DISTANCE_H_
