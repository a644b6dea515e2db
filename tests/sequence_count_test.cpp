// SPDX-License-Identifier: Apache-2.0
// SequenceCounter: the same statistics as SequenceChecker (whose union-finds
// span the whole mesh) from the boundary slots alone, on sequences from the
// converter and from the decoder; and the input mesh's counts equal what the
// converter counted of that mesh.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "psq/mesh_formats.h"
#include "psq/psq_codec.h"
#include "psq/sequence_builder.h"
#include "psq/sequence_check.h"
#include "psq/sequence_count.h"
#include "test_util.h"

namespace psq {
namespace {

using test::Mesh;
using Tri = std::array<uint32_t, 3>;

// Feeds a checker and a counter alike.
class Both : public SequenceSink {
 public:
  Status begin(const MeshSchema& s) override {
    PSQ_RETURN_IF_ERROR(checker.begin(s));
    return counter.begin(s);
  }
  Status vertex(const SequenceVertex& v) override {
    PSQ_RETURN_IF_ERROR(checker.vertex(v));
    return counter.vertex(v);
  }
  Status triangle(const SequenceTriangle& t) override {
    PSQ_RETURN_IF_ERROR(checker.triangle(t));
    return counter.triangle(t);
  }
  Status finalize(uint32_t i) override {
    PSQ_RETURN_IF_ERROR(checker.finalize(i));
    return counter.finalize(i);
  }
  Status finish() override {
    PSQ_RETURN_IF_ERROR(checker.finish());
    return counter.finish();
  }
  SequenceChecker checker;
  SequenceCounter counter;
};

void expect_same(const SequenceStats& a, const SequenceStats& b, const std::string& what) {
  EXPECT_EQ(a.vertices, b.vertices) << what;
  EXPECT_EQ(a.reappearances, b.reappearances) << what;
  EXPECT_EQ(a.isolated_vertices, b.isolated_vertices) << what;
  EXPECT_EQ(a.triangles, b.triangles) << what;
  for (int i = 0; i < 5; ++i) EXPECT_EQ(a.ops[i], b.ops[i]) << what << ", op " << i;
  EXPECT_EQ(a.components, b.components) << what;
  EXPECT_EQ(a.border_edges, b.border_edges) << what;
  EXPECT_EQ(a.border_loops, b.border_loops) << what;
  EXPECT_EQ(a.handles, b.handles) << what;
  EXPECT_EQ(a.nonmanifold_vertices, b.nonmanifold_vertices) << what;
  EXPECT_EQ(a.nonmanifold_edges, b.nonmanifold_edges) << what;
  EXPECT_EQ(a.max_boundary_vertices, b.max_boundary_vertices) << what;
  EXPECT_EQ(a.max_boundary_edges, b.max_boundary_edges) << what;
  EXPECT_EQ(a.unreferenced_vertices, b.unreferenced_vertices) << what;
  EXPECT_EQ(a.degenerate_triangles, b.degenerate_triangles) << what;
  EXPECT_EQ(a.mesh_border_edges, b.mesh_border_edges) << what;
  EXPECT_EQ(a.mesh_nonmanifold_edges, b.mesh_nonmanifold_edges) << what;
  EXPECT_EQ(a.mesh_misoriented_edges, b.mesh_misoriented_edges) << what;
}

// Vertices no non-degenerate triangle uses: what a sequence keeps isolated.
uint64_t unreferenced(const Mesh& m) {
  std::vector<bool> used(m.positions.size());
  for (const Tri& t : m.triangles) {
    if (t[0] == t[1] || t[1] == t[2] || t[2] == t[0]) continue;
    for (uint32_t v : t) used[v] = true;
  }
  return static_cast<uint64_t>(std::count(used.begin(), used.end(), false));
}

// Builds the sequence of `m` into a checker and a counter, then encodes it
// in both profiles and counts the decoded sequences too: every count agrees,
// and the mesh's agree with the converter's. Returns the counter's stats.
SequenceStats count_all_ways(const Mesh& m, bool force_sort, const std::string& what) {
  SequenceStats result;
  {
    test::MemorySource src(m);
    Both both;
    BuildOptions o;
    o.force_sort = force_sort;
    BuildReport report;
    Status s = build_sequence(src, both, o, &report);
    EXPECT_TRUE(s.ok()) << what << ": " << s.to_string();
    if (!s.ok()) return result;
    result = both.counter.stats();
    expect_same(both.checker.stats(), result, what + ", converted");
    const ConverterStats& c = report.converter;
    EXPECT_EQ(result.vertices, c.vertices_in) << what;
    EXPECT_EQ(result.triangles, c.triangles_in - c.degenerate_dropped) << what;
    EXPECT_EQ(result.mesh_border_edges, c.border_edges) << what;
    EXPECT_EQ(result.mesh_nonmanifold_edges, c.nonmanifold_edges) << what;
    EXPECT_EQ(result.mesh_misoriented_edges, c.misoriented_edges) << what;
    EXPECT_EQ(result.nonmanifold_vertices, c.nonmanifold_vertices) << what;
    EXPECT_EQ(result.unreferenced_vertices, unreferenced(m)) << what;
    EXPECT_EQ(result.degenerate_triangles, 0u) << what;  // the converter drops them
  }
  for (bool fast : {false, true}) {
    std::vector<uint8_t> bytes;
    {
      test::MemorySource src(m);
      VectorWriter w(&bytes);
      EncodeOptions eo;
      eo.fast = fast;
      PsqEncoder enc(&w, eo);
      BuildOptions o;
      o.force_sort = force_sort;
      BuildReport report;
      Status s = build_sequence(src, enc, o, &report);
      EXPECT_TRUE(s.ok()) << what << ": " << s.to_string();
      if (!s.ok()) return result;
    }
    InputStream in;
    in.open_memory(bytes.data(), bytes.size(), "mem.psq");
    PsqDecoder dec;
    Status s = dec.open(&in);
    EXPECT_TRUE(s.ok()) << s.to_string();
    if (!s.ok()) return result;
    Both both;
    s = dec.pump(both);
    EXPECT_TRUE(s.ok()) << what << ": " << s.to_string();
    const std::string how = what + (fast ? ", decoded fast" : ", decoded compact");
    expect_same(both.checker.stats(), both.counter.stats(), how);
    // The stream holds the converter's sequence: the same counts.
    expect_same(result, both.counter.stats(), how + " vs converted");
  }
  return result;
}

// A mesh of float positions (rounded so).
Mesh from(std::vector<std::array<double, 3>> p, std::vector<Tri> t) {
  for (auto& q : p)
    for (double& c : q) {
      volatile float f = static_cast<float>(c);
      c = f;
    }
  return test::make_mesh(std::move(p), std::move(t));
}

using test::shuffled;

// A torus of r x s quads: one handle.
Mesh torus(int r, int s) {
  std::vector<std::array<double, 3>> p;
  std::vector<Tri> t;
  const double pi = 3.14159265358979323846;
  for (int i = 0; i < r; ++i)
    for (int j = 0; j < s; ++j) {
      double a = 2 * pi * i / r, b = 2 * pi * j / s;
      p.push_back({(2 + std::cos(b)) * std::cos(a), (2 + std::cos(b)) * std::sin(a), std::sin(b)});
    }
  auto id = [&](int i, int j) { return static_cast<uint32_t>((i % r) * s + j % s); };
  for (int i = 0; i < r; ++i)
    for (int j = 0; j < s; ++j) {
      t.push_back({id(i, j), id(i + 1, j), id(i + 1, j + 1)});
      t.push_back({id(i, j), id(i + 1, j + 1), id(i, j + 1)});
    }
  return from(p, t);
}

TEST(SequenceCounter, ClosedOpenAndHandles) {
  for (bool sort : {false, true}) {
    SequenceStats st = count_all_ways(test::make_sphere(20, 30), sort, "sphere");
    EXPECT_EQ(st.components, 1u);
    EXPECT_EQ(st.handles, 0);
    st = count_all_ways(shuffled(test::make_grid(30), 3), sort, "grid");
    EXPECT_EQ(st.border_loops, 1u);
    EXPECT_EQ(st.mesh_border_edges, 120u);
    st = count_all_ways(torus(40, 16), sort, "torus");
    EXPECT_EQ(st.handles, 1);
    EXPECT_EQ(st.border_loops, 0u);
  }
}

TEST(SequenceCounter, ManyComponentsAndIsolatedVertices) {
  std::mt19937 rng(5);
  std::vector<std::array<double, 3>> p;
  std::vector<Tri> t;
  for (uint32_t i = 0; i < 2000; ++i) {
    for (int k = 0; k < 3; ++k) p.push_back({double(rng() % 1000), double(rng() % 1000), double(k)});
    t.push_back({3 * i, 3 * i + 1, 3 * i + 2});
  }
  for (int i = 0; i < 50; ++i) p.push_back({double(i), 0, 7});  // isolated
  t.push_back({0, 0, 1});                                          // degenerate: dropped
  for (bool sort : {false, true}) {
    SequenceStats st = count_all_ways(shuffled(from(p, t), 11), sort, "soup");
    EXPECT_EQ(st.components, 2000u);
    EXPECT_EQ(st.border_loops, 2000u);
    EXPECT_EQ(st.unreferenced_vertices, 50u);
    EXPECT_EQ(st.isolated_vertices, 50u);
  }
}

TEST(SequenceCounter, NonManifoldInput) {
  struct Case {
    const char* name;
    Mesh mesh;
  } cases[] = {
      {"bowtie", from({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {-1, 0, 0}, {0, -1, 0}}, {{0, 1, 2}, {0, 3, 4}})},
      {"three on an edge", from({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}}, {{0, 1, 2}, {1, 0, 3}, {0, 1, 4}})},
      {"misoriented", from({{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}}, {{0, 1, 2}, {0, 3, 2}})},
  };
  for (bool sort : {false, true}) {
    for (const Case& c : cases) count_all_ways(c.mesh, sort, c.name);
  }
  SequenceStats st = count_all_ways(cases[0].mesh, false, "bowtie");
  EXPECT_EQ(st.nonmanifold_vertices, 1u);
  EXPECT_EQ(st.components, 1u);
  EXPECT_EQ(st.border_loops, 1u);  // the two triangles' borders meet at the cut vertex
  st = count_all_ways(cases[1].mesh, false, "three on an edge");
  EXPECT_EQ(st.mesh_nonmanifold_edges, 1u);
  st = count_all_ways(cases[2].mesh, false, "misoriented");
  EXPECT_EQ(st.mesh_misoriented_edges, 1u);
  EXPECT_EQ(st.mesh_nonmanifold_edges, 0u);
}

TEST(SequenceCounter, RandomNonManifoldMesses) {
  std::mt19937 rng(23);
  for (int trial = 0; trial < 60; ++trial) {
    uint32_t nv = 5 + rng() % 30;
    std::vector<std::array<double, 3>> p;
    for (uint32_t i = 0; i < nv; ++i) p.push_back({double(i), double(i * i % 7), double(i % 3)});
    std::vector<Tri> t;
    uint32_t nt = 1 + rng() % 60;
    for (uint32_t i = 0; i < nt; ++i) {
      t.push_back({static_cast<uint32_t>(rng() % nv), static_cast<uint32_t>(rng() % nv), static_cast<uint32_t>(rng() % nv)});
    }
    count_all_ways(from(p, t), trial % 2 == 1, "mess " + std::to_string(trial));
  }
}

TEST(SequenceCounter, ShippedMeshes) {
  for (const char* name : {"nonmanifold_wrap.ply", "max_export_nm.ply", "spider.ply", "cube_quads.obj"}) {
    Mesh m;
    ASSERT_TRUE(test::load_mesh(std::string(PSQ_TEST_DATA) + "/" + name, &m).ok()) << name;
    SequenceStats st = count_all_ways(m, false, name);
    if (std::string(name) == "max_export_nm.ply") {
      EXPECT_EQ(st.components, 24u);
      EXPECT_EQ(st.mesh_nonmanifold_edges, 16u);
    }
  }
}

// A valid sequence that no converter writes: a re-appearance of an isolated
// vertex (which makes it referenced) and a triangle on a vertex and its
// re-appearance (degenerate in the input mesh).
TEST(SequenceCounter, ReappearancesOfIsolatedVerticesAndDegenerateTriangles) {
  Both both;
  ASSERT_TRUE(both.begin(MeshSchema()).ok());
  auto vertex = [&](uint32_t index, uint32_t slot, uint32_t reappears) {
    SequenceVertex v;
    v.index = index;
    v.slot = slot;
    v.reappears = reappears;
    return both.vertex(v);
  };
  auto triangle = [&](Tri c, Tri slots, Op op, uint8_t new_mask, uint8_t border) {
    SequenceTriangle t;
    for (int k = 0; k < 3; ++k) {
      t.v[k] = c[k];
      t.vslot[k] = slots[k];
    }
    t.op = op;
    t.new_mask = new_mask;
    t.border_mask = border;
    return both.triangle(t);
  };
  ASSERT_TRUE(vertex(0, 0, kNoVertex).ok());  // isolated
  ASSERT_TRUE(both.finalize(0).ok());
  ASSERT_TRUE(vertex(1, 0, kNoVertex).ok());
  ASSERT_TRUE(vertex(2, 1, kNoVertex).ok());
  ASSERT_TRUE(vertex(3, 2, kNoVertex).ok());
  // Edges 1-2 and 2-3 are borders, 3-1 enters the boundary.
  ASSERT_TRUE(triangle({1, 2, 3}, {0, 1, 2}, Op::kStart, 7, 3).ok());
  ASSERT_TRUE(both.finalize(2).ok());
  ASSERT_TRUE(vertex(4, 1, 1).ok());  // re-appears 1
  // Completes 3-1 as 1-3; 3-4 and 4-1 are borders; origins 1, 3, 1.
  ASSERT_TRUE(triangle({1, 3, 4}, {0, 2, 1}, Op::kAdd, 4, 6).ok());
  for (uint32_t v : {1u, 3u, 4u}) ASSERT_TRUE(both.finalize(v).ok());
  ASSERT_TRUE(vertex(5, 0, 0).ok());  // re-appears the isolated vertex 0
  ASSERT_TRUE(vertex(6, 1, kNoVertex).ok());
  ASSERT_TRUE(vertex(7, 2, kNoVertex).ok());
  ASSERT_TRUE(triangle({5, 6, 7}, {0, 1, 2}, Op::kStart, 7, 7).ok());
  for (uint32_t v : {5u, 6u, 7u}) ASSERT_TRUE(both.finalize(v).ok());
  Status s = both.finish();
  ASSERT_TRUE(s.ok()) << s.to_string();
  const SequenceStats& st = both.counter.stats();
  expect_same(both.checker.stats(), st, "hand-made");
  EXPECT_EQ(st.vertices, 6u);
  EXPECT_EQ(st.reappearances, 2u);
  EXPECT_EQ(st.isolated_vertices, 1u);
  EXPECT_EQ(st.unreferenced_vertices, 0u);
  EXPECT_EQ(st.degenerate_triangles, 1u);
  EXPECT_EQ(st.components, 2u);
  EXPECT_EQ(st.nonmanifold_vertices, 2u);
}

TEST(SequenceCounter, NeedsSlotsThatHoldTheirVertices) {
  SequenceCounter c;
  ASSERT_TRUE(c.begin(MeshSchema()).ok());
  SequenceVertex v;
  v.index = 0;
  ASSERT_TRUE(c.vertex(v).ok());  // no slot: isolated, or an error at its triangle
  SequenceTriangle t;
  EXPECT_EQ(c.triangle(t).code(), ErrorCode::kBadSequence);
  ASSERT_TRUE(c.begin(MeshSchema()).ok());
  v.slot = SequenceCounter::kMaxSlot;
  EXPECT_EQ(c.vertex(v).code(), ErrorCode::kBadSequence);
  ASSERT_TRUE(c.begin(MeshSchema()).ok());
  for (uint32_t i = 0; i < 3; ++i) {
    v.index = i;
    v.slot = i;
    ASSERT_TRUE(c.vertex(v).ok());
  }
  t.op = Op::kJoin;  // reads every corner's slot
  t.v[0] = 0, t.v[1] = 1, t.v[2] = 2;
  t.vslot[0] = 0, t.vslot[1] = 2, t.vslot[2] = 1;  // slots 2 and 1 hold vertices 2 and 1
  EXPECT_EQ(c.triangle(t).code(), ErrorCode::kBadSequence);
  t.vslot[1] = 1, t.vslot[2] = 1000;  // never given
  EXPECT_EQ(c.triangle(t).code(), ErrorCode::kBadSequence);
}

}  // namespace
}  // namespace psq
