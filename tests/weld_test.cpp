// SPDX-License-Identifier: Apache-2.0
// Welding in build_sequence() (BuildOptions::weld): a triangle soup welds
// back to the indexed mesh it was made from, property values keep vertices
// apart unless only positions count, triangles made degenerate are dropped
// and counted, and the weld's external sort spills under a small budget.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <random>
#include <set>

#include "psq/sequence_builder.h"
#include "psq/sequence_check.h"
#include "test_util.h"

namespace psq {
namespace {

using test::Mesh;
using Pos = std::array<double, 3>;
using PosTri = std::array<Pos, 3>;

// Records the sequence (checked by SequenceChecker) as triangles of
// positions, and counts its distinct vertices.
class Recorder : public SequenceSink {
 public:
  Status begin(const MeshSchema& s) override { return checker.begin(s); }
  Status vertex(const SequenceVertex& v) override {
    positions.push_back({v.position[0], v.position[1], v.position[2]});
    values.push_back(v.values);
    if (v.reappears == kNoVertex) ++distinct;
    return checker.vertex(v);
  }
  Status triangle(const SequenceTriangle& t) override {
    triangles.push_back({positions[t.v[0]], positions[t.v[1]], positions[t.v[2]]});
    return checker.triangle(t);
  }
  Status finalize(uint32_t i) override { return checker.finalize(i); }
  Status finish() override { return checker.finish(); }

  SequenceChecker checker;
  std::vector<Pos> positions;
  std::vector<PropertyValues> values;
  std::vector<PosTri> triangles;
  uint64_t distinct = 0;
};

// Sorted, each rotated to start at its smallest corner (keeps orientation).
std::vector<PosTri> canonical(std::vector<PosTri> ts) {
  for (PosTri& t : ts) {
    while (t[1] < t[0] || t[2] < t[0]) std::rotate(t.begin(), t.begin() + 1, t.end());
  }
  std::sort(ts.begin(), ts.end());
  return ts;
}

std::vector<PosTri> position_triangles(const Mesh& m) {
  std::vector<PosTri> out;
  for (const auto& t : m.triangles) {
    if (t[0] == t[1] || t[1] == t[2] || t[2] == t[0]) continue;
    out.push_back({m.positions[t[0]], m.positions[t[1]], m.positions[t[2]]});
  }
  return out;
}

// Each triangle with its own three vertices (copies of the mesh's).
Mesh soup(const Mesh& m) {
  Mesh s;
  s.schema = m.schema;
  for (size_t t = 0; t < m.triangles.size(); ++t) {
    std::array<uint32_t, 3> idx;
    for (int k = 0; k < 3; ++k) {
      idx[k] = static_cast<uint32_t>(s.positions.size());
      s.positions.push_back(m.positions[m.triangles[t][k]]);
      s.vertex_values.push_back(m.vertex_values[m.triangles[t][k]]);
    }
    s.triangles.push_back(idx);
    s.face_values.push_back(m.face_values[t]);
  }
  s.schema.vertex_count = static_cast<int64_t>(s.positions.size());
  s.schema.triangle_count = static_cast<int64_t>(s.triangles.size());
  return s;
}

using test::shuffled;

struct Built {
  Status status;
  BuildReport report;
  Recorder rec;
};

void build(const Mesh& m, WeldMode weld, Built* b, uint64_t budget = uint64_t{64} << 20, bool force_sort = false) {
  test::MemorySource src(m);
  BuildOptions o;
  o.weld = weld;
  o.memory_budget = budget;
  o.force_sort = force_sort;
  b->status = build_sequence(src, b->rec, o, &b->report);
}

TEST(Weld, SoupWeldsToTheIndexedMesh) {
  const Mesh sphere = test::make_sphere(12, 20);
  const Mesh s = soup(sphere);
  for (bool shuffle : {false, true}) {
    for (bool force_sort : {false, true}) {
      SCOPED_TRACE(std::string(shuffle ? "shuffled" : "in order") + (force_sort ? ", sorted" : ""));
      Built b;
      build(shuffle ? shuffled(s, 7) : s, WeldMode::kAll, &b, uint64_t{64} << 20, force_sort);
      ASSERT_TRUE(b.status.ok()) << b.status.to_string();
      EXPECT_EQ(canonical(b.rec.triangles), canonical(position_triangles(sphere)));
      EXPECT_EQ(b.rec.distinct, sphere.positions.size());
      EXPECT_EQ(b.report.input_vertices, s.positions.size());
      EXPECT_EQ(b.report.vertices, sphere.positions.size());
      EXPECT_EQ(b.report.welded_vertices, s.positions.size() - sphere.positions.size());
      EXPECT_EQ(b.report.weld_dropped, 0u);
      // Welded, the soup is one closed component: no border edge.
      EXPECT_EQ(b.rec.checker.stats().border_edges, 0u);
    }
  }
  // Without welding the soup stays a soup, and the estimate (which
  // samples a sixteenth of the positions) says so.
  const Mesh large = test::make_sphere(100, 100);
  const Mesh large_soup = shuffled(soup(large), 5);
  Built off;
  build(large_soup, WeldMode::kOff, &off);
  ASSERT_TRUE(off.status.ok());
  EXPECT_EQ(off.rec.distinct, large_soup.positions.size());
  EXPECT_EQ(off.report.welded_vertices, 0u);
  EXPECT_GT(off.report.duplicate_share, 0.75);
  EXPECT_LT(off.report.duplicate_share, 0.9);
  Built indexed;
  build(large, WeldMode::kOff, &indexed);
  ASSERT_TRUE(indexed.status.ok());
  EXPECT_GE(indexed.report.duplicate_share, 0.0);
  EXPECT_LT(indexed.report.duplicate_share, 0.1);
}

TEST(Weld, PropertiesKeepVerticesApartUnlessPositionsOnly) {
  Mesh sphere = test::make_sphere(10, 16);
  sphere.schema.vertex_properties.push_back({"nz", ScalarType::kFloat32});
  for (auto& v : sphere.vertex_values) v = {0.25};
  Mesh s = soup(sphere);
  // A split normal: the copies a triangle of even index makes get another
  // value, so each position keeps up to two vertices.
  std::set<std::pair<Pos, double>> classes;
  for (size_t t = 0; t < s.triangles.size(); ++t) {
    for (int k = 0; k < 3; ++k) {
      const uint32_t v = s.triangles[t][k];
      if (t % 2 == 0) s.vertex_values[v] = {-0.5};
      classes.insert({s.positions[v], s.vertex_values[v][0]});
    }
  }
  ASSERT_GT(classes.size(), sphere.positions.size());
  Built all;
  build(s, WeldMode::kAll, &all);
  ASSERT_TRUE(all.status.ok()) << all.status.to_string();
  EXPECT_EQ(all.report.vertices, classes.size());
  EXPECT_EQ(all.report.welded_vertices, s.positions.size() - classes.size());
  EXPECT_EQ(canonical(all.rec.triangles), canonical(position_triangles(sphere)));
  // Each vertex kept its own value.
  std::set<std::pair<Pos, double>> seen;
  for (size_t i = 0; i < all.rec.positions.size(); ++i) seen.insert({all.rec.positions[i], all.rec.values[i][0]});
  EXPECT_EQ(seen, classes);

  Built positions;
  build(s, WeldMode::kPositions, &positions);
  ASSERT_TRUE(positions.status.ok()) << positions.status.to_string();
  EXPECT_EQ(positions.report.vertices, sphere.positions.size());
  EXPECT_EQ(positions.rec.distinct, sphere.positions.size());
  EXPECT_EQ(canonical(positions.rec.triangles), canonical(position_triangles(sphere)));
  // The first copy in file order keeps its value: triangle 0's corners -0.5.
  for (size_t i = 0; i < positions.rec.positions.size(); ++i) {
    if (positions.rec.positions[i] == s.positions[0]) {
      EXPECT_EQ(positions.rec.values[i][0], -0.5);
    }
  }
}

TEST(Weld, SignedZerosAreOneValueOtherBitsDiffer) {
  // Two triangles sharing an edge whose copies differ only in the sign of
  // a zero, and a third whose corner differs by one ulp.
  const double ulp = std::nextafter(1.0, 2.0);
  Mesh m = test::make_mesh({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {-0.0, 0, -0.0}, {0, 1, 0}, {1, 1, 0},
                            {ulp, 0, 0}, {1, 1, 0}, {2, 0, 0}},
                           {{0, 1, 2}, {3, 5, 4}, {6, 8, 7}});
  Built b;
  build(m, WeldMode::kAll, &b);
  ASSERT_TRUE(b.status.ok()) << b.status.to_string();
  // Merged: vertex 3 into 0, 4 into 2, 7 into 5; not 6 (one ulp off 1).
  EXPECT_EQ(b.report.welded_vertices, 3u);
  EXPECT_EQ(b.report.vertices, 6u);
}

TEST(Weld, TrianglesMadeDegenerateAreDroppedAndCounted) {
  // Vertices 3 and 4 repeat 0 and 1: triangle 1 (0, 3, 2) and triangle 2
  // (4, 1, 2) collapse; triangle 3 (2, 2, 1) was degenerate in the input and
  // is the converter's to drop, not counted as welded.
  Mesh m = test::make_mesh({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 0}, {1, 0, 0}},
                           {{0, 1, 2}, {0, 3, 2}, {4, 1, 2}, {2, 2, 1}});
  Built b;
  build(m, WeldMode::kAll, &b);
  ASSERT_TRUE(b.status.ok()) << b.status.to_string();
  EXPECT_EQ(b.report.welded_vertices, 2u);
  EXPECT_EQ(b.report.weld_dropped, 2u);
  EXPECT_EQ(b.report.triangles, 2u);
  EXPECT_EQ(b.report.converter.degenerate_dropped, 1u);
  ASSERT_EQ(b.rec.triangles.size(), 1u);
  EXPECT_EQ(b.rec.triangles[0], (PosTri{Pos{0, 0, 0}, Pos{1, 0, 0}, Pos{0, 1, 0}}));
}

TEST(Weld, SmallBudgetSpillsTheSortAndGivesTheSameSequence) {
  // 36,000 soup vertices: 1.7 MB of weld keys against a 512 KiB sort share.
  const Mesh sphere = test::make_sphere(60, 100);
  const Mesh s = shuffled(soup(sphere), 3);
  Built big, small;
  build(s, WeldMode::kAll, &big);
  build(s, WeldMode::kAll, &small, uint64_t{1} << 20);
  ASSERT_TRUE(big.status.ok()) << big.status.to_string();
  ASSERT_TRUE(small.status.ok()) << small.status.to_string();
  EXPECT_EQ(big.report.weld_sort_runs, 0u);
  EXPECT_GT(small.report.weld_sort_runs, 1u);
  EXPECT_EQ(small.report.vertices, sphere.positions.size());
  EXPECT_EQ(canonical(small.rec.triangles), canonical(position_triangles(sphere)));
  EXPECT_EQ(canonical(small.rec.triangles), canonical(big.rec.triangles));
  EXPECT_FALSE(small.report.weld_external);
  // A map of 4 bytes a vertex (144 KB) beyond its share (32 KiB of a
  // 64 KiB budget): the renumbering goes through external sorts instead,
  // with the same result.
  Built tiny;
  build(s, WeldMode::kAll, &tiny, uint64_t{64} << 10, true);
  ASSERT_TRUE(tiny.status.ok()) << tiny.status.to_string();
  EXPECT_TRUE(tiny.report.weld_external);
  EXPECT_EQ(tiny.report.vertices, sphere.positions.size());
  EXPECT_EQ(tiny.report.welded_vertices, small.report.welded_vertices);
  EXPECT_EQ(canonical(tiny.rec.triangles), canonical(small.rec.triangles));
}

TEST(Weld, ExternalRenumberingMatchesTheMap) {
  // Values that keep some copies apart, a triangle made degenerate and one
  // degenerate in the input, through both paths.
  Mesh sphere = test::make_sphere(60, 80);
  sphere.schema.vertex_properties.push_back({"nz", ScalarType::kFloat32});
  for (auto& v : sphere.vertex_values) v = {0.25};
  Mesh s = soup(sphere);
  for (size_t t = 0; t < s.triangles.size(); t += 3) s.vertex_values[s.triangles[t][0]] = {-1.0};
  s.positions.push_back(s.positions[0]);
  s.vertex_values.push_back(s.vertex_values[0]);
  const uint32_t copy = static_cast<uint32_t>(s.positions.size() - 1);
  s.triangles.push_back({0, copy, 1});
  s.triangles.push_back({2, 2, 1});
  s.face_values.resize(s.triangles.size());
  s = shuffled(s, 11);
  for (WeldMode mode : {WeldMode::kAll, WeldMode::kPositions}) {
    Built map, external;
    build(s, mode, &map);
    build(s, mode, &external, uint64_t{64} << 10, true);
    ASSERT_TRUE(map.status.ok()) << map.status.to_string();
    ASSERT_TRUE(external.status.ok()) << external.status.to_string();
    EXPECT_FALSE(map.report.weld_external);
    EXPECT_TRUE(external.report.weld_external);
    EXPECT_EQ(external.report.vertices, map.report.vertices);
    EXPECT_EQ(external.report.weld_dropped, 1u);
    EXPECT_EQ(map.report.weld_dropped, 1u);
    EXPECT_EQ(external.report.converter.degenerate_dropped, 1u);
    EXPECT_EQ(canonical(external.rec.triangles), canonical(map.rec.triangles));
    std::multiset<std::pair<Pos, double>> a, b;
    for (size_t i = 0; i < map.rec.positions.size(); ++i) a.insert({map.rec.positions[i], map.rec.values[i][0]});
    for (size_t i = 0; i < external.rec.positions.size(); ++i) {
      b.insert({external.rec.positions[i], external.rec.values[i][0]});
    }
    EXPECT_EQ(a, b);
  }
}

}  // namespace
}  // namespace psq
