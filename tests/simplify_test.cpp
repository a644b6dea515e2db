// SPDX-License-Identifier: Apache-2.0
// Vertex clustering on the processing boundary (simplify/, paper section
// 5): the quadric solver, the grid, the three cell modes' promises (valid
// output sequences, every vertex in its cell, closed stays closed, holes
// stay holes, layers stay apart in connected mode, memory that follows
// the boundary), determinism, hostile sequences, and psq simplify.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <random>
#include <set>

#include "psq/clustering.h"
#include "psq/converter.h"
#include "psq/io.h"
#include "psq/ply.h"
#include "psq/sequence_builder.h"
#include "psq/sequence_check.h"
#include "psq/sequence_mesh.h"
#include "psq/threaded_sink.h"
#include "quadric.h"
#include "test_util.h"

namespace psq {
namespace {

using test::Mesh;
using Pos = std::array<double, 3>;
using Tri = std::array<uint32_t, 3>;

// ------------------------------------------------------------ test meshes

// A mesh of triangles over positions, vertices welded by exact position
// (so that faces generated apart share their edges).
class Welder {
 public:
  uint32_t at(const Pos& p) {
    auto it = index_.find(p);
    if (it != index_.end()) return it->second;
    const uint32_t i = static_cast<uint32_t>(positions_.size());
    positions_.push_back(p);
    index_[p] = i;
    return i;
  }
  void triangle(const Pos& a, const Pos& b, const Pos& c) { triangles_.push_back({at(a), at(b), at(c)}); }
  // Two triangles for the quad a b c d (counter-clockwise).
  void quad(const Pos& a, const Pos& b, const Pos& c, const Pos& d) {
    triangle(a, b, c);
    triangle(a, c, d);
  }
  Mesh mesh() const { return test::make_mesh(positions_, triangles_); }

 private:
  std::map<Pos, uint32_t> index_;
  std::vector<Pos> positions_;
  std::vector<Tri> triangles_;
};

// The closed surface of the box lo..hi, each face an n-by-n grid of quads
// per unit... `steps` quads along each axis, outward oriented.
Mesh make_box(const Pos& lo, const Pos& hi, const std::array<int, 3>& steps) {
  Welder w;
  auto lerp = [&](int axis, int i) { return lo[axis] + (hi[axis] - lo[axis]) * i / steps[axis]; };
  for (int axis = 0; axis < 3; ++axis) {
    const int u = (axis + 1) % 3, v = (axis + 2) % 3;
    for (int side = 0; side < 2; ++side) {
      for (int i = 0; i < steps[u]; ++i) {
        for (int j = 0; j < steps[v]; ++j) {
          auto p = [&](int a, int b) {
            Pos q;
            q[axis] = side ? hi[axis] : lo[axis];
            q[u] = lerp(u, a);
            q[v] = lerp(v, b);
            return q;
          };
          if (side)
            w.quad(p(i, j), p(i + 1, j), p(i + 1, j + 1), p(i, j + 1));
          else
            w.quad(p(i, j), p(i, j + 1), p(i + 1, j + 1), p(i + 1, j));
        }
      }
    }
  }
  return w.mesh();
}

// An n-by-n grid of unit quads in z = 0 without the quads in the given
// squares (holes): x0, y0, size.
Mesh make_plane_with_holes(int n, const std::vector<std::array<int, 3>>& holes) {
  Welder w;
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      bool hole = false;
      for (const auto& h : holes) hole = hole || (i >= h[0] && i < h[0] + h[2] && j >= h[1] && j < h[1] + h[2]);
      if (hole) continue;
      const double x = i, y = j;
      w.quad({x, y, 0}, {x + 1, y, 0}, {x + 1, y + 1, 0}, {x, y + 1, 0});
    }
  }
  return w.mesh();
}

// A torus (closed, genus 1) of `rings` x `segments` quads.
Mesh make_torus(int rings, int segments, double r_big, double r_small) {
  Mesh m;
  const double pi = 3.14159265358979323846;
  for (int i = 0; i < rings; ++i) {
    for (int j = 0; j < segments; ++j) {
      const double u = 2 * pi * i / rings, v = 2 * pi * j / segments;
      volatile float x = static_cast<float>((r_big + r_small * std::cos(v)) * std::cos(u));
      volatile float y = static_cast<float>((r_big + r_small * std::cos(v)) * std::sin(u));
      volatile float z = static_cast<float>(r_small * std::sin(v));
      m.positions.push_back({x, y, z});
    }
  }
  auto id = [&](int i, int j) { return static_cast<uint32_t>((i % rings) * segments + (j % segments)); };
  for (int i = 0; i < rings; ++i) {
    for (int j = 0; j < segments; ++j) {
      m.triangles.push_back({id(i, j), id(i + 1, j), id(i + 1, j + 1)});
      m.triangles.push_back({id(i, j), id(i + 1, j + 1), id(i, j + 1)});
    }
  }
  test::reset_values(&m);
  return m;
}

// ----------------------------------------------------------------- helpers

struct Result {
  Status status;
  ClusteringStats stats;
  ConverterStats converter;
  SequenceStats sequence;  // the output's, by SequenceChecker
  Status check;            // the checker's verdict
  Mesh mesh;               // the output, re-appearances merged
  std::string text;        // the output sequence
};

// The input mesh through the sequence builder, the filter and the
// converter; the output sequence checked and read back as a mesh.
Result simplify(const Mesh& m, const ClusteringOptions& o, bool threaded = false) {
  Result r;
  test::MemorySource source(m);
  test::EventLog log;
  SequenceConverter converter(&log);
  ClusteringFilter filter(&converter, o);
  std::unique_ptr<ThreadedSequenceSink> thread;
  SequenceSink* in = &filter;
  if (threaded) {
    thread = std::make_unique<ThreadedSequenceSink>(&filter);
    in = thread.get();
  }
  BuildReport report;
  r.status = build_sequence(source, *in, BuildOptions(), &report);
  thread.reset();
  r.stats = filter.stats();
  r.converter = converter.stats();
  if (!r.status.ok()) return r;
  EXPECT_TRUE(log.finished);
  SequenceChecker checker;
  test::EventReplay replay(log);
  r.check = pump_sequence(replay, checker);
  r.sequence = checker.stats();
  test::EventReplay again(log);
  SequenceMeshSource mesh(&again);
  test::MemorySink sink;
  Status s = pump(mesh, sink);
  EXPECT_TRUE(s.ok()) << s.to_string();
  r.mesh = sink.mesh;
  r.text = log.text();
  return r;
}

ClusteringOptions with_grid(CellMode mode, uint32_t grid) {
  ClusteringOptions o;
  o.cells = mode;
  o.grid = grid;
  return o;
}

ClusteringOptions with_cell(CellMode mode, double cell) {
  ClusteringOptions o;
  o.cells = mode;
  o.grid = 0;
  o.cell_size = cell;
  return o;
}

int count_lines(const std::string& s) { return static_cast<int>(std::count(s.begin(), s.end(), '\n')); }

const CellMode kModes[] = {CellMode::kGlobal, CellMode::kActive, CellMode::kConnected};

std::set<uint64_t> occupied_cells(const Mesh& m, const ClusterGrid& g) {
  std::set<uint64_t> cells;
  for (const Pos& p : m.positions) cells.insert(g.key_of(p.data()));
  return cells;
}

std::vector<std::array<Pos, 3>> position_triangles(const Mesh& m) {
  std::vector<std::array<Pos, 3>> out;
  for (const Tri& t : m.triangles) {
    std::array<Pos, 3> p = {m.positions[t[0]], m.positions[t[1]], m.positions[t[2]]};
    while (p[0] > p[1] || p[0] > p[2]) std::rotate(p.begin(), p.begin() + 1, p.end());
    out.push_back(p);
  }
  std::sort(out.begin(), out.end());
  return out;
}

// Handmade sequences for the filter alone.
MeshSchema unit_box() {
  MeshSchema s;
  s.has_bounds = true;
  for (int a = 0; a < 3; ++a) s.bounds_max[a] = 1;
  return s;
}

SequenceVertex vtx(uint32_t index, uint32_t slot, double x = 0.5) {
  SequenceVertex v;
  v.index = index;
  v.slot = slot;
  v.position[0] = x;
  v.position[1] = x / 2;
  v.position[2] = x / 3;
  return v;
}

SequenceTriangle tri(uint32_t a, uint32_t b, uint32_t c, uint32_t sa, uint32_t sb, uint32_t sc) {
  SequenceTriangle t;
  t.v[0] = a, t.v[1] = b, t.v[2] = c;
  t.vslot[0] = sa, t.vslot[1] = sb, t.vslot[2] = sc;
  return t;
}

// --------------------------------------------------------------- quadrics

TEST(Quadric, EigenDecompositionReconstructsTheMatrix) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-3, 3);
  for (int trial = 0; trial < 200; ++trial) {
    double a[6];
    for (double& x : a) x = u(rng);
    double w[3], v[3][3];
    detail::symmetric_eigen(a, w, v);
    const double m[3][3] = {{a[0], a[1], a[2]}, {a[1], a[3], a[4]}, {a[2], a[4], a[5]}};
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) {
        double r = 0, dot = 0;
        for (int k = 0; k < 3; ++k) {
          r += v[i][k] * w[k] * v[j][k];
          dot += v[k][i] * v[k][j];
        }
        EXPECT_NEAR(r, m[i][j], 1e-9);
        EXPECT_NEAR(dot, i == j ? 1.0 : 0.0, 1e-9);
      }
    }
  }
}

TEST(Quadric, MinimizerIsRobustWhenSingular) {
  const double mean[3] = {0.2, 0.3, 0.4};
  double x[3];
  // Three planes through (1, 2, 3): their intersection.
  detail::Quadric corner;
  const double n1[3] = {1, 0, 0}, n2[3] = {0, 2, 0}, n3[3] = {1, 1, 1};
  corner.add_plane(n1, -1, 1);
  corner.add_plane(n2, -4, 1);
  corner.add_plane(n3, -6, 0.5);
  detail::minimize_quadric(corner, mean, 1e-3, x);
  EXPECT_NEAR(x[0], 1, 1e-9);
  EXPECT_NEAR(x[1], 2, 1e-9);
  EXPECT_NEAR(x[2], 3, 1e-9);
  EXPECT_NEAR(corner.error(x), 0, 1e-9);
  // One plane z = 1: the mean moved onto it.
  detail::Quadric plane;
  const double nz[3] = {0, 0, 3};
  plane.add_plane(nz, -3, 2);
  detail::minimize_quadric(plane, mean, 1e-3, x);
  EXPECT_NEAR(x[0], 0.2, 1e-12);
  EXPECT_NEAR(x[1], 0.3, 1e-12);
  EXPECT_NEAR(x[2], 1, 1e-12);
  // Two planes: the point of their line nearest the mean.
  detail::Quadric line = plane;
  line.add_plane(n1, -1, 1);
  detail::minimize_quadric(line, mean, 1e-3, x);
  EXPECT_NEAR(x[0], 1, 1e-12);
  EXPECT_NEAR(x[1], 0.3, 1e-12);
  EXPECT_NEAR(x[2], 1, 1e-12);
  // Nearly parallel planes: the tiny direction is dropped, no far solution.
  detail::Quadric sliver;
  const double a[3] = {0, 0, 1}, b[3] = {1e-5, 0, 1};
  sliver.add_plane(a, 0, 1);
  sliver.add_plane(b, -1e-3, 1);  // solved exactly, x would be 100
  detail::minimize_quadric(sliver, mean, 1e-3, x);
  EXPECT_NEAR(x[0], 0.2, 1e-5);
  // Zero: the mean.
  detail::minimize_quadric(detail::Quadric(), mean, 1e-3, x);
  EXPECT_EQ(x[2], 0.4);
}

// The closed forms of minimize_quadric() against the truncated solve in
// Jacobi's eigenbasis, on random quadrics of every rank with noise.
TEST(Quadric, ClosedFormsAgreeWithTheEigenDecomposition) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1, 1);
  int cases[4] = {0, 0, 0, 0};
  for (int trial = 0; trial < 3000; ++trial) {
    detail::Quadric q;
    const int planes = 1 + trial % 6;
    const double noise = trial % 3 == 0 ? 0 : std::pow(10.0, -1 - trial % 7);
    double axis[3] = {u(rng), u(rng), u(rng)};
    for (int k = 0; k < planes; ++k) {
      // Planes around a common axis (a cylinder-like cluster) or arbitrary.
      double n[3] = {u(rng), u(rng), u(rng)};
      if (trial % 2) {
        const double dot = (n[0] * axis[0] + n[1] * axis[1] + n[2] * axis[2]) /
                           (axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]);
        for (int c = 0; c < 3; ++c) n[c] -= (1 - noise) * dot * axis[c];
      }
      q.add_plane(n, u(rng), 0.5 + u(rng) * 0.4);
    }
    const double mean[3] = {u(rng), u(rng), u(rng)};
    double x[3];
    detail::minimize_quadric(q, mean, 1e-3, x);
    // Reference.
    double w[3], v[3][3];
    detail::symmetric_eigen(q.a, w, v);
    const double largest = std::max({w[0], w[1], w[2]});
    const double r[3] = {-(q.a[0] * mean[0] + q.a[1] * mean[1] + q.a[2] * mean[2] + q.b[0]),
                         -(q.a[1] * mean[0] + q.a[3] * mean[1] + q.a[4] * mean[2] + q.b[1]),
                         -(q.a[2] * mean[0] + q.a[4] * mean[1] + q.a[5] * mean[2] + q.b[2])};
    double ref[3] = {mean[0], mean[1], mean[2]};
    int kept = 0;
    bool near_cut = false;
    for (int i = 0; i < 3; ++i) {
      near_cut = near_cut || std::fabs(w[i] - 1e-3 * largest) < 1e-6 * largest;
      if (!(w[i] > 1e-3 * largest)) continue;
      ++kept;
      const double proj = (v[0][i] * r[0] + v[1][i] * r[1] + v[2][i] * r[2]) / w[i];
      for (int k = 0; k < 3; ++k) ref[k] += proj * v[k][i];
    }
    if (near_cut) continue;  // the two may decide differently there
    ++cases[kept];
    double step = 0;
    for (int k = 0; k < 3; ++k) step = std::max(step, std::fabs(ref[k] - mean[k]));
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(x[k], ref[k], 1e-8 * (1 + step)) << trial << " kept " << kept;
  }
  EXPECT_GT(cases[1], 100);
  EXPECT_GT(cases[2], 100);
  EXPECT_GT(cases[3], 100);
}

// ------------------------------------------------------------------- grid

TEST(ClusterGrid, CellsAlongTheLongestSide) {
  const double lo[3] = {-1, 0, 10}, hi[3] = {3, 1, 10};
  ClusterGrid g;
  ASSERT_TRUE(grid_with_cells(lo, hi, 8, &g).ok());
  EXPECT_EQ(g.dims[0], 8u);
  EXPECT_EQ(g.dims[1], 2u);
  EXPECT_EQ(g.dims[2], 1u);
  uint32_t c[3];
  g.cell_of(hi, c);  // the far corner stays in the last cell
  EXPECT_EQ(c[0], 7u);
  EXPECT_EQ(c[1], 1u);
  const double outside[3] = {-50, 50, std::nan("")};
  g.cell_of(outside, c);
  EXPECT_EQ(c[0], 0u);
  EXPECT_EQ(c[1], 1u);
  EXPECT_EQ(c[2], 0u);
  ASSERT_TRUE(grid_with_size(lo, hi, 0.25, &g).ok());
  EXPECT_EQ(g.dims[0], 16u);
  EXPECT_EQ(grid_with_size(lo, hi, 1e-9, &g).code(), ErrorCode::kLimit);
  EXPECT_EQ(grid_with_size(lo, hi, -1, &g).code(), ErrorCode::kUsage);
  EXPECT_EQ(grid_with_cells(lo, hi, 0, &g).code(), ErrorCode::kUsage);
  const double inf[3] = {HUGE_VAL, 0, 0};
  EXPECT_EQ(grid_with_cells(lo, inf, 4, &g).code(), ErrorCode::kUsage);
  EXPECT_EQ(grid_with_cells(hi, lo, 4, &g).code(), ErrorCode::kUsage);
  // A box of no extent: one cell.
  ASSERT_TRUE(grid_with_cells(lo, lo, 100, &g).ok());
  EXPECT_EQ(g.cells(), 1u);
}

TEST(ClusterGrid, GridForATriangleCount) {
  EXPECT_GE(first_grid_for_triangles(1), 1u);
  EXPECT_EQ(first_grid_for_triangles(80000), 100u);
  EXPECT_EQ(corrected_grid_for_triangles(40000, 100, 10000), 200u);
  EXPECT_EQ(corrected_grid_for_triangles(1000, 100, 0), 400u);
  EXPECT_LT(corrected_grid_for_triangles(uint64_t{1} << 40, ClusterGrid::kMaxDim - 1, 1), ClusterGrid::kMaxDim);
}

// ------------------------------------------------------------ the filter

TEST(Clustering, EveryModeGivesAValidClosedSequence) {
  const Mesh shapes[] = {test::make_sphere(40, 80), make_torus(60, 30, 1, 0.3)};
  for (const Mesh& m : shapes) {
    for (CellMode mode : kModes) {
      for (uint32_t grid : {6u, 12u, 30u}) {
        Result r = simplify(m, with_grid(mode, grid));
        ASSERT_TRUE(r.status.ok()) << r.status.to_string();
        EXPECT_TRUE(r.check.ok()) << cell_mode_name(mode) << " " << grid << ": " << r.check.to_string();
        EXPECT_GT(r.stats.triangles_out, 0u);
        EXPECT_LT(r.stats.triangles_out, m.triangles.size());
        EXPECT_EQ(r.mesh.triangles.size(), r.stats.triangles_out);
        EXPECT_EQ(r.mesh.positions.size(), r.stats.vertices_out);
        // Closed in, closed out: no edge with one triangle.
        EXPECT_EQ(r.converter.border_edges, 0u) << cell_mode_name(mode) << " " << grid;
        EXPECT_EQ(r.converter.degenerate_dropped, 0u);
        // Every output vertex is used.
        std::set<uint32_t> used;
        for (const Tri& t : r.mesh.triangles) used.insert(t.begin(), t.end());
        EXPECT_EQ(used.size(), r.mesh.positions.size());
      }
    }
  }
}

TEST(Clustering, FineGridsKeepAClosedSurfaceManifold) {
  const Mesh sphere = test::make_sphere(60, 120);
  for (CellMode mode : {CellMode::kActive, CellMode::kConnected}) {
    Result r = simplify(sphere, with_grid(mode, 24));
    ASSERT_TRUE(r.status.ok());
    EXPECT_EQ(r.converter.nonmanifold_vertices, 0u) << cell_mode_name(mode);
    EXPECT_EQ(r.converter.nonmanifold_edges, 0u);
    EXPECT_EQ(r.sequence.components, 1u);
    EXPECT_EQ(r.sequence.handles, 0);
    EXPECT_EQ(r.sequence.border_edges, 0u);
  }
}

TEST(Clustering, EveryOutputVertexLiesInItsCell) {
  const Mesh shapes[] = {test::make_sphere(50, 90), make_torus(70, 40, 1, 0.25),
                         make_box({0, 0, 0}, {4, 1, 0.05}, {80, 20, 2})};
  for (const Mesh& m : shapes) {
    for (CellMode mode : kModes) {
      for (uint32_t grid : {5u, 17u, 40u}) {
        Result r = simplify(m, with_grid(mode, grid));
        ASSERT_TRUE(r.status.ok());
        const ClusterGrid& g = r.stats.grid;
        const std::set<uint64_t> occupied = occupied_cells(m, g);
        std::map<uint64_t, int> per_cell;
        for (const Pos& p : r.mesh.positions) {
          const uint64_t c = g.key_of(p.data());
          EXPECT_TRUE(occupied.count(c)) << "an output vertex in a cell no input vertex occupies";
          ++per_cell[c];
        }
        // Global: one vertex per cell, so each is in its own cell.
        if (mode == CellMode::kGlobal) {
          for (const auto& pc : per_cell) EXPECT_EQ(pc.second, 1);
        }
        // A triangle's corners lie in three different cells, as its clusters do.
        for (const Tri& t : r.mesh.triangles) {
          const uint64_t a = g.key_of(r.mesh.positions[t[0]].data()), b = g.key_of(r.mesh.positions[t[1]].data()),
                         c = g.key_of(r.mesh.positions[t[2]].data());
          EXPECT_TRUE(a != b && b != c && a != c);
        }
      }
    }
  }
}

TEST(Clustering, AGridThatKeepsEverythingGivesTheInputBack) {
  Mesh grid = test::make_grid(30);
  Mesh sphere = test::make_sphere(20, 30);
  for (CellMode mode : kModes) {
    Result r = simplify(grid, with_cell(mode, 0.5));
    ASSERT_TRUE(r.status.ok());
    EXPECT_EQ(position_triangles(r.mesh), position_triangles(grid)) << cell_mode_name(mode);
    // Cells far smaller than a float's spacing: every vertex is its own
    // cluster and stays where it was.
    Result s = simplify(sphere, with_cell(mode, 1e-5));
    ASSERT_TRUE(s.status.ok());
    EXPECT_EQ(position_triangles(s.mesh), position_triangles(sphere)) << cell_mode_name(mode);
  }
}

TEST(Clustering, AGridOfOneCellLeavesNothing) {
  for (CellMode mode : kModes) {
    Result r = simplify(test::make_sphere(10, 10), with_grid(mode, 1));
    ASSERT_TRUE(r.status.ok());
    EXPECT_TRUE(r.check.ok());
    EXPECT_EQ(r.stats.triangles_out, 0u);
    EXPECT_EQ(r.stats.vertices_out, 0u);
    EXPECT_EQ(r.stats.clusters_unused, r.stats.clusters);
  }
}

TEST(Clustering, EmptyAndIsolatedInputs) {
  for (CellMode mode : kModes) {
    Mesh empty = test::make_mesh({}, {});
    Result r = simplify(empty, with_grid(mode, 10));
    ASSERT_TRUE(r.status.ok()) << r.status.to_string();
    EXPECT_EQ(r.stats.vertices_out, 0u);
    Mesh points = test::make_mesh({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}, {});
    r = simplify(points, with_grid(mode, 10));
    ASSERT_TRUE(r.status.ok()) << r.status.to_string();
    EXPECT_EQ(r.stats.vertices_in, 3u);
    EXPECT_EQ(r.stats.vertices_out, 0u);
    EXPECT_EQ(r.stats.clusters, 0u);
  }
}

TEST(Clustering, APlaneWithHolesKeepsItsHoles) {
  const Mesh plane = make_plane_with_holes(60, {{8, 8, 10}, {35, 10, 12}, {10, 40, 9}, {38, 38, 14}});
  for (CellMode mode : kModes) {
    for (uint32_t grid : {20u, 30u}) {
      Result r = simplify(plane, with_grid(mode, grid));
      ASSERT_TRUE(r.status.ok());
      EXPECT_TRUE(r.check.ok());
      EXPECT_EQ(r.sequence.border_loops, 5u) << cell_mode_name(mode) << " " << grid;
      EXPECT_EQ(r.sequence.components, 1u);
    }
  }
}

// Border quadrics pull the vertices of a cluster on a border onto the
// border: on a plane with a square hole, every output vertex of a border
// edge lies on the outer square or on the hole's.
TEST(Clustering, BorderQuadricsKeepBordersInPlace) {
  const Mesh plane = make_plane_with_holes(40, {{10, 10, 16}});
  auto on_border = [](const Pos& p) {
    auto near = [](double a, double b) { return std::fabs(a - b) < 1e-4; };
    const bool outer = near(p[0], 0) || near(p[0], 40) || near(p[1], 0) || near(p[1], 40);
    const bool inner = (near(p[0], 10) || near(p[0], 26)) && p[1] > 9.99 && p[1] < 26.01;
    const bool inner2 = (near(p[1], 10) || near(p[1], 26)) && p[0] > 9.99 && p[0] < 26.01;
    return outer || inner || inner2;
  };
  for (double weight : {1.0, 0.0}) {
    ClusteringOptions o = with_grid(CellMode::kConnected, 13);  // cells do not line up with the hole
    o.border_weight = weight;
    Result r = simplify(plane, o);
    ASSERT_TRUE(r.status.ok());
    // Border edges: used by one triangle.
    std::map<std::pair<uint32_t, uint32_t>, int> edges;
    for (const Tri& t : r.mesh.triangles)
      for (int k = 0; k < 3; ++k) ++edges[std::minmax(t[k], t[(k + 1) % 3])];
    int off = 0, total = 0;
    for (const auto& e : edges) {
      if (e.second != 1) continue;
      for (uint32_t v : {e.first.first, e.first.second}) {
        ++total;
        off += !on_border(r.mesh.positions[v]);
      }
    }
    EXPECT_GT(total, 0);
    if (weight > 0) {
      EXPECT_EQ(off, 0);
    } else {
      EXPECT_GT(off, 0);  // without them, vertex means drift off the border
    }
  }
}

// Two sheets closer than a cell: the original OoCS pinches them into one
// (non-manifold) surface; connected layers keep them apart.
TEST(Clustering, ConnectedLayersDoNotPinchThinParts) {
  const Mesh plate = make_box({0, 0, 0}, {10, 10, 0.1}, {100, 100, 1});
  Result global = simplify(plate, with_grid(CellMode::kGlobal, 10));
  Result active = simplify(plate, with_grid(CellMode::kActive, 10));
  Result connected = simplify(plate, with_grid(CellMode::kConnected, 10));
  ASSERT_TRUE(global.status.ok() && active.status.ok() && connected.status.ok());
  EXPECT_GT(global.converter.nonmanifold_vertices + global.converter.nonmanifold_edges, 0u);
  EXPECT_LT(connected.converter.nonmanifold_vertices, global.converter.nonmanifold_vertices);
  EXPECT_LE(active.converter.nonmanifold_vertices, global.converter.nonmanifold_vertices);
  // The plate stays a closed surface with a top and a bottom.
  EXPECT_GT(connected.stats.vertices_out, global.stats.vertices_out);
  EXPECT_EQ(connected.converter.border_edges, 0u);
  double zmin = 1, zmax = -1;
  for (const Pos& p : connected.mesh.positions) {
    zmin = std::min(zmin, p[2]);
    zmax = std::max(zmax, p[2]);
  }
  EXPECT_NEAR(zmin, 0, 1e-6);
  EXPECT_NEAR(zmax, 0.1, 1e-6);
}

// Separate components in one cell: global merges them, connected does not.
TEST(Clustering, ComponentsInOneCellStayApartWhenConnected) {
  // Cells of 0.25 from x = 0: the faces x = 1.1 and x = 1.15 share cells.
  Mesh a = make_box({0, 0, 0}, {1.1, 1, 1}, {4, 4, 4});
  Mesh b = make_box({1.15, 0, 0}, {2, 1, 1}, {4, 4, 4});
  Mesh both = a;
  const uint32_t base = static_cast<uint32_t>(a.positions.size());
  both.positions.insert(both.positions.end(), b.positions.begin(), b.positions.end());
  for (Tri t : b.triangles) both.triangles.push_back({t[0] + base, t[1] + base, t[2] + base});
  test::reset_values(&both);
  Result connected = simplify(both, with_grid(CellMode::kConnected, 8));
  Result global = simplify(both, with_grid(CellMode::kGlobal, 8));
  ASSERT_TRUE(connected.status.ok() && global.status.ok());
  EXPECT_EQ(connected.sequence.components, 2u);
  EXPECT_EQ(global.sequence.components, 1u);
}

TEST(Clustering, SameOutputEveryRunAndOnAThread) {
  const Mesh m = make_torus(80, 40, 1, 0.4);
  for (CellMode mode : kModes) {
    Result a = simplify(m, with_grid(mode, 20));
    Result b = simplify(m, with_grid(mode, 20));
    Result c = simplify(m, with_grid(mode, 20), true);
    ASSERT_TRUE(a.status.ok() && b.status.ok() && c.status.ok());
    EXPECT_FALSE(a.text.empty());
    EXPECT_EQ(a.text, b.text);
    EXPECT_EQ(a.text, c.text);
  }
}

// A non-manifold input vertex (a bowtie): the sequence cuts it, and the
// converter emits one fan after the other. Global cells merge the two
// occurrences again; active cells and connected layers see the first
// occurrence finalized before the second comes, and keep them apart (as
// the paper's layers that the boundary visits at different times).
TEST(Clustering, ReappearingVertices) {
  Mesh bowtie = test::make_mesh({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {-1, 0, 0}, {0, -1, 0}}, {{0, 1, 2}, {0, 3, 4}});
  for (CellMode mode : kModes) {
    Result r = simplify(bowtie, with_cell(mode, 0.25));
    ASSERT_TRUE(r.status.ok());
    EXPECT_TRUE(r.check.ok());
    EXPECT_EQ(r.stats.triangles_out, 2u);
    if (mode == CellMode::kGlobal) {
      EXPECT_EQ(r.stats.vertices_out, 5u);
      EXPECT_EQ(r.converter.nonmanifold_vertices, 1u);
    } else {
      EXPECT_EQ(r.stats.vertices_out, 6u) << cell_mode_name(mode);
    }
  }
}

// Connected layers: a re-appearance whose first occurrence is still on the
// boundary joins its cluster (they are one point of the input).
TEST(Clustering, AReappearanceJoinsItsActiveFirstOccurrence) {
  for (bool reappears : {true, false}) {
    CountingMeshSink out;
    ClusteringFilter f(&out, with_cell(CellMode::kConnected, 0.1));
    MeshSchema box;
    box.has_bounds = true;
    for (int a = 0; a < 3; ++a) box.bounds_min[a] = -1, box.bounds_max[a] = 1;
    ASSERT_TRUE(f.begin(box).ok());
    const double p[6][3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 0}, {-1, 0, 0}, {0, -1, 0}};
    for (uint32_t i = 0; i < 6; ++i) {
      SequenceVertex v;
      v.index = i;
      v.slot = i;
      std::copy(p[i], p[i] + 3, v.position);
      if (i == 3 && reappears) v.reappears = 0;
      ASSERT_TRUE(f.vertex(v).ok());
      if (i % 3 != 2) continue;
      SequenceTriangle t;
      for (uint32_t k = 0; k < 3; ++k) t.v[k] = t.vslot[k] = i - 2 + k;
      t.new_mask = 7;
      t.final_mask = i == 2 ? 6 : 7;  // vertex 0 stays on the boundary until the end
      ASSERT_TRUE(f.triangle(t).ok());
    }
    ASSERT_TRUE(f.finish().ok());
    EXPECT_EQ(out.triangles, 2u);
    EXPECT_EQ(out.vertices, reappears ? 5u : 6u);
  }
}

TEST(Clustering, DuplicateTrianglesGoOutOnce) {
  // The same triangle twice: the sequence cuts the second off as a
  // separate fan of re-appearances; global cells bring both to the same
  // three clusters, and one goes out.
  Mesh twice = test::make_mesh({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}, {{0, 1, 2}, {1, 2, 0}});
  Result r = simplify(twice, with_cell(CellMode::kGlobal, 0.25));
  ASSERT_TRUE(r.status.ok());
  EXPECT_EQ(r.stats.triangles_out, 1u);
  EXPECT_EQ(r.stats.duplicates, 1u);
  EXPECT_TRUE(r.check.ok());
  // Connected layers: two triangles of the same orientation whose corners
  // are joined pairwise by edges inside their cells (fed directly: the
  // sequence of such a mesh cuts the second triangle off as a fan of
  // re-appearances, which come when the clusters are gone).
  CountingMeshSink out;
  ClusteringFilter f(&out, with_cell(CellMode::kConnected, 0.25));
  ASSERT_TRUE(f.begin(unit_box()).ok());
  const double p[6][3] = {{0, 0, 0}, {0.9, 0, 0}, {0, 0.9, 0}, {0.01, 0.01, 0.01}, {0.91, 0.01, 0.01}, {0.01, 0.91, 0.01}};
  auto vertex = [&](uint32_t i) {
    SequenceVertex v;
    v.index = v.slot = i;
    std::copy(p[i], p[i] + 3, v.position);
    ASSERT_TRUE(f.vertex(v).ok());
  };
  auto triangle = [&](uint32_t a, uint32_t b, uint32_t c) { ASSERT_TRUE(f.triangle(tri(a, b, c, a, b, c)).ok()); };
  for (uint32_t i = 0; i < 3; ++i) vertex(i);
  triangle(0, 1, 2);
  vertex(3);
  triangle(0, 3, 1);
  vertex(4);
  triangle(1, 4, 2);
  vertex(5);
  triangle(2, 5, 0);
  triangle(3, 4, 5);
  ASSERT_TRUE(f.finish().ok());
  EXPECT_EQ(out.triangles, 1u);
  EXPECT_EQ(f.stats().duplicates, 1u);
}

TEST(Clustering, PropertiesMergeByTheirRules) {
  Mesh m = test::make_sphere(30, 40);
  m.schema.vertex_properties = {{"nx", ScalarType::kFloat32}, {"ny", ScalarType::kFloat32},
                                {"nz", ScalarType::kFloat32}, {"red", ScalarType::kUInt8},
                                {"label", ScalarType::kInt32}, {"tags", ScalarType::kUInt8, true}};
  m.schema.face_properties = {{"part", ScalarType::kUInt16}};
  std::set<double> labels;
  for (size_t i = 0; i < m.positions.size(); ++i) {
    const Pos& p = m.positions[i];
    volatile float nx = static_cast<float>(p[0]), ny = static_cast<float>(p[1]), nz = static_cast<float>(p[2]);
    const double label = 1000 + static_cast<double>(i);
    labels.insert(label);
    m.vertex_values[i] = {nx, ny, nz, static_cast<double>(i % 256), label, 2, 7, 8};
  }
  for (size_t i = 0; i < m.triangles.size(); ++i) m.face_values[i] = {static_cast<double>(i % 3)};
  Result r = simplify(m, with_grid(CellMode::kConnected, 8));
  ASSERT_TRUE(r.status.ok()) << r.status.to_string();
  ASSERT_EQ(r.mesh.schema.vertex_properties.size(), 5u);  // the list dropped
  ASSERT_EQ(r.mesh.schema.face_properties.size(), 1u);
  EXPECT_TRUE(r.mesh.schema.has_bounds);
  for (size_t i = 0; i < r.mesh.positions.size(); ++i) {
    const PropertyValues& v = r.mesh.vertex_values[i];
    ASSERT_EQ(v.size(), 5u);
    EXPECT_NEAR(std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]), 1, 1e-6);
    // The averaged normal of a sphere's cluster points near its vertex.
    const Pos& p = r.mesh.positions[i];
    EXPECT_GT(v[0] * p[0] + v[1] * p[1] + v[2] * p[2], 0.9);
    EXPECT_TRUE(scalar_holds(ScalarType::kUInt8, v[3]));
    EXPECT_TRUE(labels.count(v[4]));  // a label of a vertex, not an average
  }
  for (const PropertyValues& f : r.mesh.face_values) {
    ASSERT_EQ(f.size(), 1u);
    EXPECT_TRUE(f[0] == 0 || f[0] == 1 || f[0] == 2);
  }
}

TEST(Clustering, GlobalMemoryGrowsWithTheOutputConnectedDoesNot) {
  // A long ribbon swept along its length: a short boundary.
  Mesh ribbon = make_box({0, 0, 0}, {400, 4, 1}, {2000, 20, 5});
  uint64_t peak[2][2];
  for (int fine = 0; fine < 2; ++fine) {
    for (int connected = 0; connected < 2; ++connected) {
      Result r = simplify(ribbon, with_grid(connected ? CellMode::kConnected : CellMode::kGlobal, fine ? 1600 : 400));
      ASSERT_TRUE(r.status.ok());
      peak[fine][connected] = r.stats.peak_bytes;
    }
  }
  EXPECT_GT(peak[1][0], 2 * peak[0][0]);  // global: four times the cells, more memory
  EXPECT_LT(peak[1][1], peak[1][0] / 4);  // connected: a fraction of it
  EXPECT_LT(peak[1][1], 4 * peak[0][1]);
}

TEST(Clustering, TheMemoryBudgetIsEnforced) {
  ClusteringOptions o = with_grid(CellMode::kGlobal, 64);
  o.memory_budget = 64 << 10;
  Result r = simplify(test::make_sphere(100, 200), o);
  EXPECT_EQ(r.status.code(), ErrorCode::kLimit);
  EXPECT_NE(r.status.message().find("global"), std::string::npos);
}

TEST(Clustering, NeedsBoundsAndValidOptions) {
  CountingMeshSink out;
  MeshSchema schema;
  {
    ClusteringFilter f(&out, ClusteringOptions());
    EXPECT_EQ(f.begin(schema).code(), ErrorCode::kUsage);
    EXPECT_EQ(f.finish().code(), ErrorCode::kUsage);  // sticky
  }
  schema.has_bounds = true;
  schema.bounds_max[0] = 1;
  {
    ClusteringOptions o;
    o.border_weight = -1;
    ClusteringFilter f(&out, o);
    EXPECT_EQ(f.begin(schema).code(), ErrorCode::kUsage);
  }
  {
    ClusteringOptions o;
    o.merge.vertex = {MergeRule::kFirst};  // the schema has no vertex property
    ClusteringFilter f(&out, o);
    EXPECT_EQ(f.begin(schema).code(), ErrorCode::kUsage);
  }
  {
    ClusteringOptions o;
    o.has_bounds = true;  // the options' box instead of the schema's
    o.bounds_max[0] = o.bounds_max[1] = o.bounds_max[2] = 2;
    o.grid = 4;
    ClusteringFilter f(&out, o);
    MeshSchema none;
    ASSERT_TRUE(f.begin(none).ok());
    EXPECT_EQ(f.stats().grid.dims[1], 4u);
    SequenceVertex v;
    EXPECT_TRUE(f.finish().ok());
  }
}

// ------------------------------------------------- hostile sequences

TEST(Clustering, HostileSequencesAreErrors) {
  CountingMeshSink out;
  auto fresh = [&]() {
    auto f = std::make_unique<ClusteringFilter>(&out, with_grid(CellMode::kConnected, 4));
    EXPECT_TRUE(f->begin(unit_box()).ok());
    return f;
  };
  {
    auto f = fresh();  // a triangle before any vertex
    EXPECT_EQ(f->triangle(tri(0, 1, 2, 0, 1, 2)).code(), ErrorCode::kBadSequence);
  }
  {
    auto f = fresh();  // a slot far beyond the boundary
    EXPECT_EQ(f->vertex(vtx(0, 1u << 30)).code(), ErrorCode::kBadSequence);
  }
  {
    auto f = fresh();  // a slot still in use
    ASSERT_TRUE(f->vertex(vtx(0, 3)).ok());
    EXPECT_EQ(f->vertex(vtx(1, 3)).code(), ErrorCode::kBadSequence);
  }
  {
    auto f = fresh();  // a triangle whose slot holds another vertex
    for (uint32_t i = 0; i < 3; ++i) ASSERT_TRUE(f->vertex(vtx(i, i, 0.1 * i)).ok());
    EXPECT_EQ(f->triangle(tri(0, 1, 7, 0, 1, 2)).code(), ErrorCode::kBadSequence);
  }
  {
    auto f = fresh();  // one vertex twice in a triangle
    for (uint32_t i = 0; i < 3; ++i) ASSERT_TRUE(f->vertex(vtx(i, i, 0.1 * i)).ok());
    EXPECT_EQ(f->triangle(tri(0, 1, 1, 0, 1, 1)).code(), ErrorCode::kBadSequence);
  }
  {
    auto f = fresh();  // slots, then none
    ASSERT_TRUE(f->vertex(vtx(0, 0)).ok());
    EXPECT_EQ(f->vertex(vtx(1, kNoSlot)).code(), ErrorCode::kBadSequence);
  }
  {
    auto f = fresh();  // not finite
    SequenceVertex v = vtx(0, 0);
    v.position[1] = std::nan("");
    EXPECT_EQ(f->vertex(v).code(), ErrorCode::kBadValue);
  }
  {
    auto f = fresh();  // a vertex used after its finalization (no slots: by index)
    for (uint32_t i = 0; i < 3; ++i) ASSERT_TRUE(f->vertex(vtx(i, kNoSlot, 0.3 * i)).ok());
    SequenceTriangle t = tri(0, 1, 2, kNoSlot, kNoSlot, kNoSlot);
    ASSERT_TRUE(f->triangle(t).ok());
    ASSERT_TRUE(f->finalize(2).ok());
    EXPECT_EQ(f->triangle(t).code(), ErrorCode::kBadSequence);
  }
}

// Random events, with and without slots: errors or a finished output,
// never a crash (the sanitizer build checks memory).
TEST(Clustering, RandomEventsNeverCrash) {
  std::mt19937 rng(11);
  for (int run = 0; run < 300; ++run) {
    CountingMeshSink out;
    ClusteringFilter f(&out, with_grid(kModes[run % 3], 1 + run % 7));
    ASSERT_TRUE(f.begin(unit_box()).ok());
    const bool slots = run % 2 == 0;
    std::uniform_int_distribution<uint32_t> small(0, 12), kind(0, 9);
    std::uniform_real_distribution<double> pos(-0.2, 1.2);
    uint32_t next = 0;
    Status s;
    for (int i = 0; i < 200 && s.ok(); ++i) {
      const uint32_t k = kind(rng);
      if (k < 4) {
        SequenceVertex v = vtx(next++, slots ? small(rng) : kNoSlot);
        for (double& c : v.position) c = pos(rng);
        v.reappears = k == 0 && next > 1 ? small(rng) % (next - 1) : kNoVertex;
        s = f.vertex(v);
      } else if (k < 8) {
        SequenceTriangle t = tri(small(rng), small(rng), small(rng), small(rng), small(rng), small(rng));
        t.final_mask = static_cast<uint8_t>(small(rng) & 7);
        t.border_mask = static_cast<uint8_t>(small(rng) & 7);
        s = f.triangle(t);
      } else {
        s = f.finalize(small(rng));
      }
    }
    if (s.ok()) s = f.finish();
    EXPECT_TRUE(s.ok() || s.code() == ErrorCode::kBadSequence) << s.to_string();
  }
}

// A filter in a pipeline of a real input: the sequence builder's slots and
// finalization drive it (no finalize() left for the end).
TEST(Clustering, ClustersCloseAsTheBoundaryMovesOn) {
  Mesh ribbon = make_box({0, 0, 0}, {200, 2, 1}, {800, 8, 4});
  Result r = simplify(ribbon, with_grid(CellMode::kConnected, 400));
  ASSERT_TRUE(r.status.ok());
  EXPECT_LT(r.stats.max_clusters, r.stats.clusters / 10) << r.stats.max_clusters << " " << r.stats.clusters;
  EXPECT_LT(r.stats.max_waiting, r.stats.triangles_out / 10) << r.stats.max_waiting << " " << r.stats.triangles_out;
}

// --------------------------------------------------------- psq simplify

std::string write_mesh_ply(const test::TempDir& dir, const std::string& name, const Mesh& m) {
  OutputFile out;
  EXPECT_TRUE(out.open(dir.file(name), false).ok());
  PlyWriter w(&out);
  test::MemorySource src(m);
  EXPECT_TRUE(pump(src, w).ok());
  EXPECT_TRUE(out.commit().ok());
  return dir.file(name);
}

// The value of "key": in a one-line JSON object (a number or null).
std::string json_field(const std::string& json, const std::string& key) {
  const size_t at = json.find("\"" + key + "\": ");
  if (at == std::string::npos) return "";
  const size_t from = at + key.size() + 4;
  return json.substr(from, json.find_first_of(",}", from) - from);
}

int shell(const std::string& command) {
  const int rc = std::system(command.c_str());
  return WIFEXITED(rc) ? WEXITSTATUS(rc) : 128;
}

TEST(CliSimplify, HelpListsTheMethods) {
  std::string out, err;
  ASSERT_EQ(test::run_psq("simplify --help", &out, &err), 0);
  EXPECT_NE(out.find("Methods (--method):\n  clustering"), std::string::npos);
  EXPECT_NE(out.find("--cells"), std::string::npos);
  ASSERT_EQ(test::run_psq("--help", &out, &err), 0);
  EXPECT_NE(out.find("simplify IN OUT"), std::string::npos);
}

TEST(CliSimplify, EveryFormatInAndOut) {
  test::TempDir dir;
  const std::string ply = write_mesh_ply(dir, "torus.ply", make_torus(80, 40, 1, 0.3));
  std::string out, err;
  ASSERT_EQ(test::run_psq("convert " + ply + " " + dir.file("torus.psq"), &out, &err), 0) << err;
  std::string triangles;
  for (const char* in : {"torus.ply", "torus.psq"}) {
    for (const char* ext : {"psq", "ply", "obj", "drc"}) {
      const std::string o = dir.file(std::string("s_") + in + "." + ext);
      ASSERT_EQ(test::run_psq("simplify " + dir.file(in) + " " + o + " --grid 20 --json", &out, &err), 0) << err;
      EXPECT_EQ(count_lines(out), 1) << out;
      EXPECT_EQ(json_field(out, "input_format"), std::string("\"") + (in[6] == 'p' && in[7] == 'l' ? "ply" : "psq") + "\"");
      EXPECT_EQ(json_field(out, "triangles_in"), "6400");
      EXPECT_EQ(json_field(out, "nonmanifold_edges"), "0") << out;
      if (triangles.empty()) triangles = json_field(out, "triangles");
      // The .psq input is quantized: nearly the same output.
      const int t = std::stoi(json_field(out, "triangles"));
      EXPECT_NEAR(t, std::stoi(triangles), 0.02 * t) << in << " " << ext;
      Mesh m;
      ASSERT_TRUE(test::load_mesh(o, &m).ok()) << o;
      EXPECT_EQ(m.triangles.size(), static_cast<size_t>(t));
    }
  }
  ASSERT_EQ(test::run_psq("verify " + dir.file("s_torus.psq.psq"), &out, &err), 0) << err;
}

TEST(CliSimplify, PipesLosslessInputAndTheSameBytes) {
  test::TempDir dir;
  const std::string ply = write_mesh_ply(dir, "s.ply", test::make_sphere(60, 90));
  std::string out, err;
  ASSERT_EQ(test::run_psq("convert " + ply + " " + dir.file("s.psq"), &out, &err), 0) << err;
  ASSERT_EQ(test::run_psq("convert --lossless " + ply + " " + dir.file("l.psq"), &out, &err), 0) << err;
  const std::string psq = PSQ_BINARY;
  // .psq in and out through pipes, then to PLY.
  ASSERT_EQ(shell("cat " + dir.file("s.psq") + " | " + psq + " simplify - - --grid 12 --to psq | " + psq +
                  " convert - " + dir.file("piped.ply") + " 2>/dev/null"),
            0);
  ASSERT_EQ(test::run_psq("simplify " + dir.file("s.psq") + " " + dir.file("direct.psq") + " --grid 12", &out, &err), 0);
  ASSERT_EQ(test::run_psq("simplify --threads 1 " + dir.file("s.psq") + " " + dir.file("one.psq") + " --grid 12", &out,
                          &err),
            0);
  ASSERT_EQ(test::run_psq("simplify --threads 2 " + dir.file("s.psq") + " " + dir.file("two.psq") + " --grid 12", &out,
                          &err),
            0);
  ASSERT_EQ(test::run_psq("simplify --threads 3 " + dir.file("s.psq") + " " + dir.file("three.ply") + " --grid 12", &out,
                          &err),
            0);
  ASSERT_EQ(test::run_psq("simplify --threads 1 " + dir.file("s.psq") + " " + dir.file("one.ply") + " --grid 12", &out,
                          &err),
            0);
  EXPECT_EQ(test::read_file(dir.file("three.ply")), test::read_file(dir.file("one.ply")));
  ASSERT_EQ(shell(psq + " simplify " + dir.file("s.psq") + " - --grid 12 --to psq >" + dir.file("stdout.psq")), 0);
  const std::string direct = test::read_file(dir.file("direct.psq"));
  EXPECT_EQ(direct, test::read_file(dir.file("one.psq")));
  EXPECT_EQ(direct, test::read_file(dir.file("two.psq")));
  EXPECT_EQ(direct, test::read_file(dir.file("stdout.psq")));
  Mesh piped, back;
  ASSERT_TRUE(test::load_mesh(dir.file("piped.ply"), &piped).ok());
  ASSERT_TRUE(test::load_mesh(dir.file("direct.psq"), &back).ok());
  EXPECT_EQ(piped.triangles.size(), back.triangles.size());
  // A lossless .psq has no bounding box in its header: a first pass
  // measures it, from a file or from a pipe (spooled).
  ASSERT_EQ(test::run_psq("simplify " + dir.file("l.psq") + " " + dir.file("l1.psq") + " --grid 12 --json", &out, &err),
            0)
      << err;
  EXPECT_EQ(json_field(out, "passes"), "2");
  ASSERT_EQ(shell("cat " + dir.file("l.psq") + " | " + psq + " simplify - " + dir.file("l2.psq") + " --grid 12"), 0);
  EXPECT_EQ(test::read_file(dir.file("l1.psq")), test::read_file(dir.file("l2.psq")));
  ASSERT_EQ(test::run_psq("verify " + dir.file("l2.psq"), &out, &err), 0) << err;
  // Lossless in, lossless out.
  ASSERT_EQ(test::run_psq("simplify --lossless " + dir.file("l.psq") + " " + dir.file("l3.psq") + " --grid 12", &out, &err),
            0)
      << err;
}

TEST(CliSimplify, ATargetTriangleCount) {
  test::TempDir dir;
  const std::string ply = write_mesh_ply(dir, "t.ply", make_torus(300, 100, 1, 0.3));
  std::string out, err;
  for (const char* target : {"2000", "20000"}) {
    ASSERT_EQ(test::run_psq("simplify " + ply + " " + dir.file("t.ply.psq") + " -f --json --triangles " + target, &out,
                            &err),
              0)
        << err;
    const double want = std::stod(target);
    const double got = std::stod(json_field(out, "triangles"));
    EXPECT_NEAR(got, want, 0.15 * want) << out;
    EXPECT_EQ(json_field(out, "target_triangles"), target);
    EXPECT_LE(std::stoi(json_field(out, "passes")), 3);
  }
  // From a pipe: spooled.
  ASSERT_EQ(shell("cat " + ply + " | " + std::string(PSQ_BINARY) + " simplify - " + dir.file("p.psq") +
                  " --triangles 2000 -q"),
            0);
  // --ratio: the same target, from the input's count (declared by a PLY
  // header, counted by the first pass of an OBJ from a pipe).
  const double input = 2.0 * 300 * 100;
  ASSERT_EQ(test::run_psq("simplify " + ply + " " + dir.file("r.psq") + " -f --json --ratio 10%", &out, &err), 0) << err;
  EXPECT_EQ(json_field(out, "target_triangles"), "6000");
  EXPECT_NEAR(std::stod(json_field(out, "triangles")), 0.1 * input, 0.015 * input) << out;
  ASSERT_EQ(test::run_psq("convert " + ply + " " + dir.file("t.obj"), &out, &err), 0) << err;
  ASSERT_EQ(shell("cat " + dir.file("t.obj") + " | " + std::string(PSQ_BINARY) + " simplify - " + dir.file("o.psq") +
                  " --to psq --json --ratio 0.1 > " + dir.file("o.json")),
            0);
  EXPECT_EQ(json_field(test::read_file(dir.file("o.json")), "target_triangles"), "6000");
}

TEST(CliSimplify, MergeRulesFromTheCommandLine) {
  test::TempDir dir;
  Mesh m = test::make_sphere(20, 30);
  m.schema.vertex_properties = {{"red", ScalarType::kUInt8}, {"label", ScalarType::kInt32}};
  for (size_t i = 0; i < m.positions.size(); ++i) m.vertex_values[i] = {static_cast<double>(i % 200), 1000.0 + i};
  const std::string ply = write_mesh_ply(dir, "c.ply", m);
  std::string out, err;
  ASSERT_EQ(test::run_psq("simplify " + ply + " " + dir.file("d.ply") + " --grid 6 --merge label=drop,red=first", &out,
                          &err),
            0)
      << err;
  Mesh d;
  ASSERT_TRUE(test::load_mesh(dir.file("d.ply"), &d).ok());
  ASSERT_EQ(d.schema.vertex_properties.size(), 1u);
  EXPECT_EQ(d.schema.vertex_properties[0].name, "red");
  std::set<double> reds;
  for (size_t i = 0; i < m.positions.size(); ++i) reds.insert(m.vertex_values[i][0]);
  for (const PropertyValues& v : d.vertex_values) EXPECT_TRUE(reds.count(v[0]));  // a vertex's, not an average
  EXPECT_EQ(test::run_psq("simplify " + ply + " " + dir.file("e.ply") + " --merge nosuch=drop", &out, &err), 2);
  EXPECT_NE(err.find("no property 'nosuch'"), std::string::npos);
  EXPECT_EQ(test::run_psq("simplify " + ply + " " + dir.file("e.ply") + " --merge red=sum", &out, &err), 2);
  EXPECT_FALSE(test::file_exists(dir.file("e.ply")));
}

TEST(CliSimplify, ErrorsAndUsage) {
  test::TempDir dir;
  const std::string ply = write_mesh_ply(dir, "s.ply", test::make_sphere(10, 10));
  const std::string out_file = dir.file("o.psq");
  std::string out, err;
  for (const std::string& args :
       {"simplify " + ply, "simplify " + ply + " " + out_file + " --method qem",
        "simplify " + ply + " " + out_file + " --cells some", "simplify " + ply + " " + out_file + " --grid 0",
        "simplify " + ply + " " + out_file + " --grid 4 --cell 1", "simplify " + ply + " " + out_file + " --cell -2",
        "simplify " + ply + " " + out_file + " --triangles x",
        "simplify " + ply + " " + out_file + " --ratio 0", "simplify " + ply + " " + out_file + " --ratio 2 --grid 3",
        "simplify " + ply + " " + out_file + " --border-weight -1",
        "simplify " + ply + " " + out_file + " --bits 40", "simplify " + ply + " - --json --to psq",
        "simplify " + ply + " " + dir.file("o.xyz"), "simplify " + ply + " " + ply}) {
    EXPECT_EQ(test::run_psq(args, &out, &err), 2) << args;
    EXPECT_NE(err.find("psq: error: "), std::string::npos) << args;
    EXPECT_TRUE(out.empty());
  }
  EXPECT_FALSE(test::file_exists(out_file));
  // Bad input: one line, exit 1, no output.
  test::write_file(dir.file("bad.ply"), "ply\nformat binary_little_endian 1.0\nelement vertex 5\nproperty float x\n");
  EXPECT_EQ(test::run_psq("simplify " + dir.file("bad.ply") + " " + out_file, &out, &err), 1);
  EXPECT_EQ(count_lines(err), 1) << err;
  EXPECT_EQ(err.rfind("psq: error: " + dir.file("bad.ply") + ": ", 0), 0u) << err;
  EXPECT_FALSE(test::file_exists(out_file));
  // A truncated .psq.
  ASSERT_EQ(test::run_psq("convert " + ply + " " + dir.file("s.psq"), &out, &err), 0);
  const std::string bytes = test::read_file(dir.file("s.psq"));
  test::write_file(dir.file("cut.psq"), bytes.substr(0, bytes.size() / 2));
  EXPECT_EQ(test::run_psq("simplify " + dir.file("cut.psq") + " " + out_file, &out, &err), 1);
  EXPECT_EQ(count_lines(err), 1) << err;
  EXPECT_FALSE(test::file_exists(out_file));
  // No overwriting without -f.
  ASSERT_EQ(test::run_psq("simplify " + ply + " " + out_file + " --grid 4", &out, &err), 0) << err;
  EXPECT_EQ(test::run_psq("simplify " + ply + " " + out_file + " --grid 4", &out, &err), 2);  // as psq convert
  EXPECT_EQ(test::run_psq("simplify " + ply + " " + out_file + " --grid 4 -f", &out, &err), 0);
  // A grid of one cell: an empty mesh and a note.
  ASSERT_EQ(test::run_psq("simplify " + ply + " " + dir.file("empty.ply") + " --grid 1", &out, &err), 0) << err;
  EXPECT_NE(err.find("the output is empty"), std::string::npos) << err;
  Mesh empty;
  ASSERT_TRUE(test::load_mesh(dir.file("empty.ply"), &empty).ok());
  EXPECT_TRUE(empty.triangles.empty());
  // Too little memory for the global mode's cells.
  EXPECT_EQ(test::run_psq("simplify " + ply + " " + dir.file("g.psq") + " --grid 4 --cells global --memory 1K", &out,
                          &err),
            1);
  EXPECT_NE(err.find("--memory"), std::string::npos) << err;
}

}  // namespace
}  // namespace psq
