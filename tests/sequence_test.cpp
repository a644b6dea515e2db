// Processing sequences: the converter and builder produce valid sequences
// (checked independently by SequenceChecker) that hold exactly the input's
// triangles, on manifold, non-manifold, shuffled and soup meshes.
#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <random>
#include <set>

#include "psq/converter.h"
#include "psq/mesh_formats.h"
#include "psq/sequence_builder.h"
#include "psq/sequence_check.h"
#include "psq/sequence_dump.h"
#include "test_util.h"

namespace psq {
namespace {

using test::Mesh;
using Tri = std::array<uint32_t, 3>;

// Forwards to a checker and records triangles by input vertex id (the last
// vertex property of the test meshes is "id").
class Recorder : public SequenceSink {
 public:
  Status begin(const MeshSchema& s) override {
    id_slot_ = s.vertex_properties.size() - 1;
    return checker.begin(s);
  }
  Status vertex(const SequenceVertex& v) override {
    ids.push_back(static_cast<uint32_t>(v.values.at(id_slot_)));
    if (v.reappears != kNoVertex) {
      EXPECT_EQ(ids[v.reappears], ids.back());
    }
    return checker.vertex(v);
  }
  Status triangle(const SequenceTriangle& t) override {
    triangles.push_back({ids[t.v[0]], ids[t.v[1]], ids[t.v[2]]});
    face_values.push_back(t.values);
    return checker.triangle(t);
  }
  Status finalize(uint32_t i) override { return checker.finalize(i); }
  Status finish() override { return checker.finish(); }

  SequenceChecker checker;
  std::vector<uint32_t> ids;
  std::vector<Tri> triangles;
  std::vector<PropertyValues> face_values;

 private:
  size_t id_slot_ = 0;
};

void add_ids(Mesh* m) {
  m->schema.vertex_properties.push_back({"id", ScalarType::kUInt32});
  for (size_t i = 0; i < m->positions.size(); ++i) m->vertex_values[i].push_back(static_cast<double>(i));
}

std::vector<Tri> canonical(std::vector<Tri> ts) {
  for (Tri& t : ts) {
    while (t[0] > t[1] || t[0] > t[2]) std::rotate(t.begin(), t.begin() + 1, t.end());
  }
  std::sort(ts.begin(), ts.end());
  return ts;
}

// Shuffles vertex and triangle order (and relabels), keeping ids.
Mesh shuffled(const Mesh& m, uint32_t seed) {
  std::mt19937 rng(seed);
  std::vector<uint32_t> perm(m.positions.size());
  for (uint32_t i = 0; i < perm.size(); ++i) perm[i] = i;
  std::shuffle(perm.begin(), perm.end(), rng);
  Mesh out = m;
  std::vector<uint32_t> where(perm.size());
  for (uint32_t i = 0; i < perm.size(); ++i) {
    out.positions[i] = m.positions[perm[i]];
    out.vertex_values[i] = m.vertex_values[perm[i]];
    where[perm[i]] = i;
  }
  for (Tri& t : out.triangles) {
    for (uint32_t& v : t) v = where[v];
  }
  std::vector<size_t> tp(out.triangles.size());
  for (size_t i = 0; i < tp.size(); ++i) tp[i] = i;
  std::shuffle(tp.begin(), tp.end(), rng);
  Mesh o2 = out;
  for (size_t i = 0; i < tp.size(); ++i) {
    o2.triangles[i] = out.triangles[tp[i]];
    o2.face_values[i] = out.face_values[tp[i]];
  }
  return o2;
}

// Builds the sequence of `m` and checks it; returns the checker's stats.
SequenceStats check(const Mesh& m, bool force_sort, uint64_t budget = uint64_t{64} << 20) {
  test::MemorySource src(m);
  Recorder rec;
  BuildOptions o;
  o.force_sort = force_sort;
  o.memory_budget = budget;
  BuildReport report;
  Status s = build_sequence(src, rec, o, &report);
  EXPECT_TRUE(s.ok()) << s.to_string();
  // Exactly the input's non-degenerate triangles, by input vertex id.
  std::vector<Tri> expected;
  for (const Tri& t : m.triangles) {
    if (t[0] != t[1] && t[1] != t[2] && t[2] != t[0]) {
      expected.push_back({static_cast<uint32_t>(m.vertex_values[t[0]].back()),
                          static_cast<uint32_t>(m.vertex_values[t[1]].back()),
                          static_cast<uint32_t>(m.vertex_values[t[2]].back())});
    }
  }
  EXPECT_EQ(canonical(rec.triangles), canonical(expected));
  // Every input vertex appears.
  std::set<uint32_t> seen(rec.ids.begin(), rec.ids.end());
  EXPECT_EQ(seen.size(), m.positions.size());
  return rec.checker.stats();
}

Mesh from(std::vector<std::array<double, 3>> p, std::vector<Tri> t) {
  Mesh m;
  m.positions = std::move(p);
  m.triangles = std::move(t);
  m.vertex_values.assign(m.positions.size(), {});
  m.face_values.assign(m.triangles.size(), {});
  m.schema.vertex_count = static_cast<int64_t>(m.positions.size());
  m.schema.triangle_count = static_cast<int64_t>(m.triangles.size());
  add_ids(&m);
  return m;
}

TEST(Sequence, SphereIsOneClosedComponent) {
  Mesh m = test::make_sphere(20, 30);
  add_ids(&m);
  for (bool sort : {false, true}) {
    SequenceStats st = check(m, sort);
    EXPECT_EQ(st.components, 1u);
    EXPECT_EQ(st.border_loops, 0u);
    EXPECT_EQ(st.handles, 0);
    EXPECT_EQ(st.nonmanifold_vertices, 0u);
    EXPECT_EQ(st.ops[static_cast<int>(Op::kStart)], 1u);
  }
}

TEST(Sequence, GridHasOneBorderLoop) {
  Mesh m = test::make_grid(30);
  add_ids(&m);
  SequenceStats st = check(shuffled(m, 3), false);
  EXPECT_EQ(st.components, 1u);
  EXPECT_EQ(st.border_loops, 1u);
  EXPECT_EQ(st.handles, 0);
  EXPECT_EQ(st.border_edges, 120u);
}

TEST(Sequence, ShuffledInputTakesTheSortPathAndStaysValid) {
  Mesh m = test::make_sphere(60, 80);
  add_ids(&m);
  Mesh s = shuffled(m, 7);
  test::MemorySource src(s);
  Recorder rec;
  BuildOptions o;
  o.memory_budget = uint64_t{1} << 20;  // tiny: many sort runs
  BuildReport report;
  ASSERT_TRUE(build_sequence(src, rec, o, &report).ok());
  EXPECT_TRUE(report.sorted);
  EXPECT_EQ(rec.checker.stats().components, 1u);
  EXPECT_EQ(rec.checker.stats().handles, 0);
  // The sweep keeps the boundary near a cross-section, far below the mesh.
  EXPECT_LT(rec.checker.stats().max_boundary_vertices, m.positions.size() / 4);
}

TEST(Sequence, BowtieVertexReappears) {
  // Two triangles sharing only vertex 0.
  Mesh m = from({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {-1, 0, 0}, {0, -1, 0}}, {{0, 1, 2}, {0, 3, 4}});
  for (bool sort : {false, true}) {
    SequenceStats st = check(m, sort);
    EXPECT_EQ(st.reappearances, 1u);
    EXPECT_EQ(st.nonmanifold_vertices, 1u);
    EXPECT_EQ(st.components, 1u);
  }
}

TEST(Sequence, ThreeTrianglesOnOneEdge) {
  Mesh m = from({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}}, {{0, 1, 2}, {1, 0, 3}, {0, 1, 4}});
  for (bool sort : {false, true}) {
    SequenceStats st = check(m, sort);
    EXPECT_EQ(st.nonmanifold_edges, 1u);
    EXPECT_EQ(st.components, 1u);
  }
}

TEST(Sequence, MisorientedNeighboursAreCut) {
  // A quad whose two triangles disagree on orientation.
  Mesh m = from({{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}}, {{0, 1, 2}, {0, 3, 2}});
  SequenceStats st = check(m, false);
  EXPECT_EQ(st.nonmanifold_edges, 1u);
}

TEST(Sequence, DegenerateTrianglesAreDroppedAndIsolatedVerticesKept) {
  Mesh m = from({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {9, 9, 9}}, {{0, 1, 2}, {0, 0, 1}});
  SequenceStats st = check(m, false);
  EXPECT_EQ(st.triangles, 1u);
  EXPECT_EQ(st.isolated_vertices, 1u);
}

TEST(Sequence, SoupOfManyComponents) {
  std::mt19937 rng(5);
  std::vector<std::array<double, 3>> p;
  std::vector<Tri> t;
  for (uint32_t i = 0; i < 3000; ++i) {
    for (int k = 0; k < 3; ++k) p.push_back({double(rng() % 1000), double(rng() % 1000), double(k)});
    t.push_back({3 * i, 3 * i + 1, 3 * i + 2});
  }
  Mesh m = from(p, t);
  for (bool sort : {false, true}) {
    SequenceStats st = check(shuffled(m, 11), sort);
    EXPECT_EQ(st.components, 3000u);
    EXPECT_EQ(st.border_loops, 3000u);
  }
}

TEST(Sequence, RandomNonManifoldMessesStayValid) {
  // Random triangles over few vertices: every kind of non-manifold case.
  std::mt19937 rng(17);
  for (int trial = 0; trial < 40; ++trial) {
    uint32_t nv = 5 + rng() % 20;
    std::vector<std::array<double, 3>> p;
    for (uint32_t i = 0; i < nv; ++i) p.push_back({double(i), double(i * i % 7), 0});
    std::vector<Tri> t;
    uint32_t nt = 1 + rng() % 40;
    for (uint32_t i = 0; i < nt; ++i) {
      t.push_back({static_cast<uint32_t>(rng() % nv), static_cast<uint32_t>(rng() % nv), static_cast<uint32_t>(rng() % nv)});
    }
    Mesh m = from(p, t);
    check(m, trial % 2 == 1);
  }
}

TEST(Sequence, DumpFormat) {
  Mesh m = from({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0.1f, 0.2f, 0.3f}}, {{0, 1, 2}, {1, 3, 2}});
  test::MemorySource src(m);
  test::TempDir dir;
  OutputFile out;
  ASSERT_TRUE(out.open(dir.file("d.txt"), false).ok());
  DumpWriter w(&out);
  BuildReport r;
  ASSERT_TRUE(build_sequence(src, w, BuildOptions(), &r).ok());
  ASSERT_TRUE(out.commit().ok());
  EXPECT_EQ(test::read_file(dir.file("d.txt")),
            "psq-dump 1\n"
            "v 0 0 0 id=0\nv 1 0 0 id=1\nv 0 1 0 id=2\nt 0 1 2 start 5\nx 0\n"
            "v 0.100000001 0.200000003 0.300000012 id=3\nt 1 3 2 add 3\nx 1\nx 3\nx 2\n");
}

std::string shared(const std::string& rel) { return std::string(PSQ_SHARED_DATA) + "/" + rel; }

TEST(SequenceShared, EveryMeshGivesAValidSequence) {
  if (!test::file_exists(shared("meshes/bunny.ply"))) GTEST_SKIP() << "../shared/data not present";
  const char* files[] = {"bunny.ply", "fandisk.ply", "blade.ply", "elephant.ply", "elephant_with_holes.ply",
                         "mech_holes_shark.ply", "turbine.ply", "cheese.ply", "knot2.ply", "bones.ply",
                         "b9_mesh.ply", "boeing.ply", "blobby_shuffled.ply", "nonmanifold_wrap.ply",
                         "max_export_nm.ply", "spider.ply", "iso_ball_200k_shuffled.ply"};
  for (const char* f : files) {
    OpenedMesh om;
    ASSERT_TRUE(open_mesh(shared(std::string("meshes/") + f), OpenOptions(), &om).ok()) << f;
    SequenceChecker checker;
    BuildReport r;
    Status s = build_sequence(*om.source, checker, BuildOptions(), &r);
    EXPECT_TRUE(s.ok()) << f << ": " << s.to_string();
    const SequenceStats& st = checker.stats();
    EXPECT_EQ(st.vertices, r.vertices) << f;
    EXPECT_EQ(st.triangles + r.converter.degenerate_dropped, r.triangles) << f;
  }
}

}  // namespace
}  // namespace psq

namespace psq {
namespace {

// Connectivity reconstruction through boundary slots (paper section 3): a
// consumer that stores, per edge slot, the triangle that entered the edge
// finds each triangle's neighbour when the edge completes, and per vertex
// slot counts its triangles, without hashing any index. Compared with the
// same computed by hashing.
class SlotUser : public SequenceSink {
 public:
  Status begin(const MeshSchema&) override { return Status(); }
  Status vertex(const SequenceVertex& v) override {
    valence_[v.slot] = 0;
    return Status();
  }
  Status triangle(const SequenceTriangle& t) override {
    uint32_t me = triangles++;
    for (int k = 0; k < 3; ++k) {
      ++valence_[t.vslot[k]];
      if (t.entering_mask & (1u << k)) entered_by_[t.eslot[k]] = me;
      if (t.leaving_mask & (1u << k)) neighbours.push_back({entered_by_[t.eslot[k]], me});
      // The same, by hashing the edge's dense vertex pair.
      uint32_t a = t.v[k], b = t.v[(k + 1) % 3];
      if (t.border_mask & (1u << k)) continue;
      auto it = by_hash_.find(key(b, a));
      if (it != by_hash_.end()) {
        hashed.push_back({it->second, me});
        by_hash_.erase(it);
      } else {
        by_hash_[key(a, b)] = me;
      }
    }
    for (int k = 0; k < 3; ++k) last_valence_[t.v[k]] = valence_[t.vslot[k]];
    return Status();
  }
  Status finalize(uint32_t index) override {
    valences.push_back(last_valence_[index]);
    return Status();
  }
  Status finish() override { return Status(); }

  uint32_t triangles = 0;
  std::vector<std::pair<uint32_t, uint32_t>> neighbours, hashed;
  std::vector<uint32_t> valences;

 private:
  static uint64_t key(uint32_t a, uint32_t b) { return (uint64_t{a} << 32) | b; }
  BoundaryData<uint32_t> valence_;
  BoundaryData<uint32_t> entered_by_;
  std::map<uint64_t, uint32_t> by_hash_;
  std::map<uint32_t, uint32_t> last_valence_;
};

TEST(Sequence, BoundarySlotsReconstructConnectivity) {
  Mesh m = test::make_sphere(30, 40);
  add_ids(&m);
  for (bool sort : {false, true}) {
    test::MemorySource src(shuffled(m, 5));
    SlotUser user;
    BuildOptions o;
    o.force_sort = sort;
    BuildReport r;
    ASSERT_TRUE(build_sequence(src, user, o, &r).ok());
    std::sort(user.neighbours.begin(), user.neighbours.end());
    std::sort(user.hashed.begin(), user.hashed.end());
    EXPECT_EQ(user.neighbours, user.hashed);
    EXPECT_EQ(user.neighbours.size(), 3 * m.triangles.size() / 2);
    // Every vertex of a closed sphere has 4 to 40 triangles (poles: 40).
    for (uint32_t v : user.valences) {
      EXPECT_GE(v, 4u);
      EXPECT_LE(v, 40u);
    }
  }
}

}  // namespace
}  // namespace psq
