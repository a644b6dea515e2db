// SPDX-License-Identifier: Apache-2.0
// Processing sequences: the converter and builder produce valid sequences
// (checked independently by SequenceChecker) that hold exactly the input's
// triangles, on manifold, non-manifold, shuffled and soup meshes.
#include <gtest/gtest.h>

#include <malloc.h>

#include <algorithm>
#include <filesystem>
#include <map>
#include <random>
#include <set>
#include <sstream>

#include "psq/converter.h"
#include "psq/mesh_formats.h"
#include "psq/sequence_builder.h"
#include "psq/sequence_check.h"
#include "sequence_dump.h"
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

using test::shuffled;

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
  Mesh m = test::make_mesh(std::move(p), std::move(t));
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

// A window of most of the mesh is no coherent order, even when it fits the
// memory budget: one pass would hold the whole mesh (and grow regions full
// of holes where triangles become ready in scattered places), so the sort
// path takes it. A mesh of one block of triangles counts as such.
TEST(Sequence, AWindowOfMostOfTheMeshTakesTheSortPath) {
  Mesh m = test::make_sphere(100, 120);  // 12,000 vertices in rings, 6 blocks
  add_ids(&m);
  Mesh small = test::make_sphere(20, 30);  // 1,200 triangles: one block
  add_ids(&small);
  struct Case {
    const Mesh* mesh;
    bool shuffle, sorted;
  };
  for (const Case& c : {Case{&m, false, false}, Case{&m, true, true}, Case{&small, false, true}}) {
    Mesh input = c.shuffle ? shuffled(*c.mesh, 5) : *c.mesh;
    test::MemorySource src(input);
    Recorder rec;
    BuildOptions o;  // the default budget holds these meshes many times over
    BuildReport report;
    ASSERT_TRUE(build_sequence(src, rec, o, &report).ok());
    EXPECT_EQ(report.sorted, c.sorted) << "shuffle " << c.shuffle << ", " << report.vertices << " vertices";
    EXPECT_EQ(2 * report.window > report.vertices, c.sorted) << "window " << report.window;
    EXPECT_EQ(rec.checker.stats().components, 1u);
  }
}

// ... unless the sort's rank array would not fit the budget: then the one
// pass it would replace still runs.
TEST(Sequence, ATinyBudgetKeepsAnIncoherentSmallMeshInOnePass) {
  Mesh m = test::make_sphere(8, 10);
  add_ids(&m);
  test::MemorySource src(shuffled(m, 3));
  Recorder rec;
  BuildOptions o;
  o.memory_budget = 8 * m.positions.size() - 8;  // rank array: 4 bytes per vertex in half the budget
  BuildReport report;
  ASSERT_TRUE(build_sequence(src, rec, o, &report).ok());
  EXPECT_FALSE(report.sorted);
  EXPECT_GT(2 * report.window, report.vertices);
  EXPECT_EQ(rec.checker.stats().components, 1u);
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

// Every mesh of the corpus (directory listing) on the path build_sequence
// picks for it.
std::vector<std::string> corpus_meshes() {
  std::vector<std::string> files;
  std::string dir = shared("meshes");
  if (!test::file_exists(dir + "/bunny.ply")) return files;
  for (const auto& e : std::filesystem::directory_iterator(dir)) {
    if (e.path().extension() == ".ply") files.push_back(e.path().filename().string());
  }
  std::sort(files.begin(), files.end());
  return files;
}

TEST(SequenceShared, EveryMeshGivesAValidSequence) {
  if (!test::file_exists(shared("meshes/bunny.ply"))) GTEST_SKIP() << "../shared/data not present";
  std::vector<std::string> files = corpus_meshes();
  EXPECT_GE(files.size(), 20u);
  for (const std::string& name : files) {
    const char* f = name.c_str();
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

namespace psq {
namespace {

// Runs a hand-written event script through a checker, begin to finish, and
// returns the first error. Lines: "v" introduces the next vertex; "t A B C OP
// M [f=F] [l=L] [e=E] [s=S0,S1,S2]" is a triangle with border mask M and
// optionally its final, leaving and entering masks and edge slots (-1 for
// none); new corners are found by first use; "x A" finalizes A.
Status run_script(const std::vector<std::string>& lines) {
  SequenceChecker c;
  PSQ_RETURN_IF_ERROR(c.begin(MeshSchema()));
  std::vector<char> fresh;
  for (const std::string& line : lines) {
    std::istringstream ls(line);
    std::string kind;
    ls >> kind;
    if (kind == "v") {
      SequenceVertex v;
      v.index = static_cast<uint32_t>(fresh.size());
      fresh.push_back(1);
      PSQ_RETURN_IF_ERROR(c.vertex(v));
    } else if (kind == "t") {
      SequenceTriangle t;
      std::string op;
      unsigned mask;
      ls >> t.v[0] >> t.v[1] >> t.v[2] >> op >> mask;
      const char* names[] = {"start", "add", "join", "fill", "end"};
      t.op = static_cast<Op>(std::find(names, names + 5, op) - names);
      t.border_mask = static_cast<uint8_t>(mask);
      for (int k = 0; k < 3; ++k) {
        if (t.v[k] < fresh.size() && fresh[t.v[k]]) t.new_mask |= static_cast<uint8_t>(1u << k);
      }
      for (int k = 0; k < 3; ++k) {
        if (t.v[k] < fresh.size()) fresh[t.v[k]] = 0;
      }
      std::string opt;
      while (ls >> opt) {
        if (opt.rfind("s=", 0) == 0) {
          std::istringstream ss(opt.substr(2));
          for (int k = 0; k < 3; ++k) {
            long x;
            char comma;
            ss >> x;
            if (k < 2) ss >> comma;
            t.eslot[k] = x < 0 ? kNoSlot : static_cast<uint32_t>(x);
          }
          continue;
        }
        uint8_t value = static_cast<uint8_t>(std::stoi(opt.substr(2)));
        if (opt[0] == 'f') t.final_mask = value;
        if (opt[0] == 'l') t.leaving_mask = value;
        if (opt[0] == 'e') t.entering_mask = value;
      }
      PSQ_RETURN_IF_ERROR(c.triangle(t));
    } else if (kind == "x") {
      uint32_t a;
      ls >> a;
      PSQ_RETURN_IF_ERROR(c.finalize(a));
    }
  }
  return c.finish();
}

// The example of spec/psq-dump.md, A.3.
const std::vector<std::string> kSpecExample = {"v", "v", "v", "t 0 1 2 start 5", "x 0", "v", "t 1 3 2 add 3",
                                               "x 1", "x 3", "x 2", "v", "x 4"};

void expect_rejected(const std::vector<std::string>& script, const std::string& needle) {
  Status s = run_script(script);
  EXPECT_EQ(s.code(), ErrorCode::kBadSequence) << s.to_string();
  EXPECT_NE(s.message().find(needle), std::string::npos) << s.to_string();
}

TEST(SequenceChecker, RequiresCanonicalFinalization) {
  EXPECT_TRUE(run_script(kSpecExample).ok());
  // Vertex 0 has no boundary edge after triangle 0 but is finalized later.
  expect_rejected({"v", "v", "v", "t 0 1 2 start 5", "v", "t 1 3 2 add 3", "x 1", "x 3", "x 2", "x 0"}, "triangle 0:");
  expect_rejected({"v", "v", "v", "t 0 1 2 start 5", "v", "t 1 3 2 add 3", "x 0", "x 1", "x 3", "x 2"}, "triangle 0:");
  // Not in corner order.
  expect_rejected({"v", "v", "v", "t 0 1 2 start 5", "x 0", "v", "t 1 3 2 add 3", "x 3", "x 1", "x 2"}, "triangle 1:");
  // Left open at the end.
  expect_rejected({"v", "v", "v", "t 0 1 2 start 7"}, "triangle 0:");
  // An isolated vertex is finalized right after its vertex event, not
  // after the next triangle.
  expect_rejected({"v", "v", "v", "t 0 1 2 start 0", "v", "v", "t 1 0 4 add 0", "x 3"},
                  "triangle 1: vertex 3 was introduced right before this triangle");
}

TEST(SequenceChecker, RequiresNewVerticesRightBeforeTheirTriangle) {
  // Vertex 3 is introduced before triangle 1, which does not use it.
  expect_rejected({"v", "v", "v", "t 0 1 2 start 0", "v", "t 2 1 0 end 0", "x 2", "x 1", "x 0", "x 3"},
                  "vertex 3 was introduced right before this triangle");
  // Four vertices before one triangle.
  expect_rejected({"v", "v", "v", "v"}, "fourth vertex");
  // An isolated vertex finalized while another waits for its triangle.
  expect_rejected({"v", "v", "v", "x 2"}, "waits for its triangle");
}

TEST(SequenceChecker, RejectsAReusedCompletedEdge) {
  // Triangle 1 completes edge 0-1; triangle 2 uses it a third time (and is a
  // valid fill otherwise): three triangles on one edge.
  expect_rejected({"v", "v", "v", "t 0 1 2 start 0", "v", "t 1 0 3 add 0", "t 1 0 2 fill 0", "x 2", "t 3 0 1 end 0",
                   "x 3", "x 0", "x 1"},
                  "triangle 2: edge 0 reuses a closed edge");
}

TEST(SequenceChecker, ChecksFinalMask) {
  EXPECT_TRUE(run_script({"v", "v", "v", "t 0 1 2 start 5 l=0 e=2 f=1", "x 0", "v", "t 1 3 2 add 3 l=4 e=0 f=7",
                          "x 1", "x 3", "x 2"})
                  .ok());
  expect_rejected({"v", "v", "v", "t 0 1 2 start 5 l=0 e=2 f=0", "x 0", "v", "t 1 3 2 add 3 l=4 e=0 f=7", "x 1",
                   "x 3", "x 2"},
                  "triangle 0: final_mask");
  expect_rejected({"v", "v", "v", "t 0 1 2 start 5 l=0 e=2 f=1", "x 0", "v", "t 1 3 2 add 3 l=4 e=0 f=3", "x 1",
                   "x 3", "x 2"},
                  "triangle 1: final_mask");
  // Once a producer gave masks it must give them on every triangle.
  expect_rejected({"v", "v", "v", "t 0 1 2 start 5 l=0 e=2 f=1", "x 0", "v", "t 1 3 2 add 3", "x 1", "x 3", "x 2"},
                  "triangle 1:");
}

TEST(SequenceChecker, RejectsASlotOnABorderEdge) {
  EXPECT_TRUE(run_script({"v", "v", "v", "t 0 1 2 start 5 s=-1,4,-1", "x 0", "v", "t 1 3 2 add 3 s=-1,-1,4", "x 1",
                          "x 3", "x 2"})
                  .ok());
  expect_rejected({"v", "v", "v", "t 0 1 2 start 5 s=7,4,-1", "x 0", "v", "t 1 3 2 add 3", "x 1", "x 3", "x 2"},
                  "triangle 0: edge 0 is a border but names edge slot 7");
}

TEST(SequenceChecker, RejectsAJoinOffTheBoundary) {
  // Triangle 2 joins vertex 3, whose edges are all borders (triangle 1).
  // Canonical finalization already forbids keeping vertex 3 after triangle
  // 1, so that is what the checker names: with rule 4, every used vertex
  // that is not finalized is on the boundary, as a join needs.
  expect_rejected({"v", "v", "v", "t 0 1 2 start 0", "v", "v", "v", "t 3 4 5 start 7", "t 1 0 3 join 0",
                   "t 2 1 3 fill 0", "t 0 2 3 end 0", "x 4", "x 5", "x 0", "x 2", "x 3", "x 1"},
                  "triangle 1: no boundary edge touches vertex 3");
}

}  // namespace
}  // namespace psq

namespace psq {
namespace {

// Counts events, keeps nothing.
class CountingSink : public SequenceSink {
 public:
  Status begin(const MeshSchema&) override { return Status(); }
  Status vertex(const SequenceVertex&) override {
    ++vertices;
    return Status();
  }
  Status triangle(const SequenceTriangle&) override {
    ++triangles;
    return Status();
  }
  Status finalize(uint32_t) override { return Status(); }
  Status finish() override { return Status(); }
  uint64_t vertices = 0, triangles = 0;
};

// Feeds an n x n grid of quads row by row, finalizing each row of vertices
// once the rows of quads around it are in; does not finish.
Status feed_grid(SequenceConverter& conv, uint32_t n) {
  const uint32_t w = n + 1;
  PropertyValues none;
  PSQ_RETURN_IF_ERROR(conv.begin(MeshSchema()));
  double p[3] = {0, 0, 0};
  for (uint32_t i = 0; i < w; ++i) PSQ_RETURN_IF_ERROR(conv.vertex(i, p, none));
  for (uint32_t j = 0; j < n; ++j) {
    for (uint32_t i = 0; i < w; ++i) PSQ_RETURN_IF_ERROR(conv.vertex((j + 1) * w + i, p, none));
    for (uint32_t i = 0; i < n; ++i) {
      uint32_t a = j * w + i, b = a + 1, c = a + w + 1, d = a + w;
      const uint32_t t0[3] = {a, b, c}, t1[3] = {a, c, d};
      PSQ_RETURN_IF_ERROR(conv.triangle(t0, none));
      PSQ_RETURN_IF_ERROR(conv.triangle(t1, none));
    }
    for (uint32_t i = 0; i < w; ++i) PSQ_RETURN_IF_ERROR(conv.finalize(j * w + i));
  }
  for (uint32_t i = 0; i < w; ++i) PSQ_RETURN_IF_ERROR(conv.finalize(n * w + i));
  return Status();
}

// Speed is measured in bench/ (BM_ConverterFan), not here: these tests
// check that huge valences give valid sequences (the quadratic converter
// took about 8 s per fan, the current one about 0.15 s).
TEST(Converter, FanOf100kTrianglesAroundOneVertex) {
  // An open and a closed fan of 100k triangles around vertex 0.
  const uint32_t n = 100000;
  for (bool closed : {false, true}) {
    SequenceChecker checker;
    SequenceConverter conv(&checker);
    PropertyValues none;
    ASSERT_TRUE(conv.begin(MeshSchema()).ok());
    double p[3] = {0, 0, 0};
    uint32_t ring = closed ? n : n + 1;
    for (uint32_t i = 0; i <= ring; ++i) ASSERT_TRUE(conv.vertex(i, p, none).ok());
    for (uint32_t i = 0; i < n; ++i) {
      const uint32_t t[3] = {0, 1 + i, 1 + (i + 1) % ring};
      ASSERT_TRUE(conv.triangle(t, none).ok());
    }
    for (uint32_t i = 0; i <= ring; ++i) ASSERT_TRUE(conv.finalize(i).ok());
    Status s = conv.finish();
    ASSERT_TRUE(s.ok()) << s.to_string();
    EXPECT_EQ(checker.stats().triangles, n);
    EXPECT_EQ(checker.stats().reappearances, 0u);
    EXPECT_EQ(checker.stats().border_edges, closed ? n : n + 2);
    EXPECT_EQ(conv.stats().border_edges, closed ? n : n + 2);
  }
}

TEST(Converter, ManyTrianglesOnOneEdge) {
  // 100k triangles on the edge 0-1, in both orientations: the edge is cut,
  // every triangle is its own fan at 0 and at 1.
  const uint32_t n = 100000;
  SequenceChecker checker;
  SequenceConverter conv(&checker);
  PropertyValues none;
  ASSERT_TRUE(conv.begin(MeshSchema()).ok());
  double p[3] = {0, 0, 0};
  for (uint32_t i = 0; i < n + 2; ++i) ASSERT_TRUE(conv.vertex(i, p, none).ok());
  for (uint32_t i = 0; i < n; ++i) {
    const uint32_t t0[3] = {0, 1, 2 + i}, t1[3] = {1, 0, 2 + i};
    ASSERT_TRUE(conv.triangle(i % 2 ? t1 : t0, none).ok());
  }
  Status s = conv.finish();
  ASSERT_TRUE(s.ok()) << s.to_string();
  EXPECT_EQ(checker.stats().triangles, n);
  EXPECT_EQ(checker.stats().reappearances, 2 * (n - 1));
  EXPECT_EQ(checker.stats().nonmanifold_edges, 1u);
  EXPECT_EQ(conv.stats().nonmanifold_edges, 1u);
  EXPECT_EQ(conv.stats().nonmanifold_vertices, 2u);
}

// Feeds an n x n grid like feed_grid, with vertex `id` at x = id and
// property values on some elements only (every 7th vertex, every 5th
// triangle), the first of them after the waiting area holds many. The
// converter sees vertex `id` as id_of(id).
Status feed_grid_with_values(SequenceConverter& conv, uint32_t n, uint32_t (*id_of)(uint32_t) = nullptr) {
  auto ext = [&](uint32_t id) { return id_of ? id_of(id) : id; };
  const uint32_t w = n + 1;
  PropertyValues none;
  uint32_t t_count = 0;
  auto vertex = [&](uint32_t id) {
    const double p[3] = {static_cast<double>(id), 0, 0};
    return conv.vertex(ext(id), p, id % 7 == 3 ? PropertyValues{id + 0.5, -1.0 * id} : none);
  };
  auto triangle = [&](uint32_t a, uint32_t b, uint32_t c) {
    const uint32_t t[3] = {ext(a), ext(b), ext(c)};
    const uint32_t k = t_count++;
    return conv.triangle(t, k % 5 == 4 ? PropertyValues{static_cast<double>(k)} : none);
  };
  PSQ_RETURN_IF_ERROR(conv.begin(MeshSchema()));
  for (uint32_t i = 0; i < w; ++i) PSQ_RETURN_IF_ERROR(vertex(i));
  for (uint32_t j = 0; j < n; ++j) {
    for (uint32_t i = 0; i < w; ++i) PSQ_RETURN_IF_ERROR(vertex((j + 1) * w + i));
    for (uint32_t i = 0; i < n; ++i) {
      uint32_t a = j * w + i, b = a + 1, c = a + w + 1, d = a + w;
      PSQ_RETURN_IF_ERROR(triangle(a, b, c));
      PSQ_RETURN_IF_ERROR(triangle(a, c, d));
    }
    for (uint32_t i = 0; i < w; ++i) PSQ_RETURN_IF_ERROR(conv.finalize(ext(j * w + i)));
  }
  for (uint32_t i = 0; i < w; ++i) PSQ_RETURN_IF_ERROR(conv.finalize(ext(n * w + i)));
  return conv.finish();
}

TEST(Converter, ReserveChangesNothingAndValuesArrive) {
  // reserve() is a hint: none, exact, short and far beyond the input give
  // the same events. Property values arrive with their elements although
  // their per-slot arrays are sized only on the first element with values.
  const uint32_t n = 200;  // 80k triangles: more than the lookahead minimum
  std::string first;
  for (uint64_t r : {uint64_t{0}, uint64_t{1000}, uint64_t{201 * 201}, uint64_t{1} << 40}) {
    test::EventLog log;
    SequenceConverter conv(&log);
    if (r != 0) conv.reserve(r, 2 * r);
    Status s = feed_grid_with_values(conv, n);
    ASSERT_TRUE(s.ok()) << s.to_string();
    if (first.empty()) {
      first = log.text();
      std::multiset<double> triangle_values;
      size_t vertices = 0;
      for (const SequenceEvent& e : log.events) {
        if (e.kind == SequenceEvent::Kind::kVertex) {
          ++vertices;
          const uint32_t id = static_cast<uint32_t>(e.vertex.position[0]);
          if (id % 7 == 3) {
            EXPECT_EQ(e.vertex.values, (PropertyValues{id + 0.5, -1.0 * id})) << id;
          } else {
            EXPECT_TRUE(e.vertex.values.empty()) << id;
          }
        } else if (e.kind == SequenceEvent::Kind::kTriangle) {
          ASSERT_LE(e.triangle.values.size(), 1u);
          if (!e.triangle.values.empty()) triangle_values.insert(e.triangle.values[0]);
        }
      }
      EXPECT_EQ(vertices, size_t{201} * 201);
      std::multiset<double> fed;
      for (uint32_t k = 4; k < 2 * n * n; k += 5) fed.insert(k);
      EXPECT_EQ(triangle_values, fed);
    } else {
      EXPECT_EQ(log.text(), first) << "reserve " << r;
    }
  }
}

TEST(Converter, AnyIdsGiveTheSameSequence) {
  // The converter finds waiting vertices by their ids' low bits first:
  // ids that all share their low 16 bits, or scattered over 32 bits, give
  // the events that dense ids give.
  const uint32_t n = 200;
  std::string dense;
  for (uint32_t (*id_of)(uint32_t) : {static_cast<uint32_t (*)(uint32_t)>(nullptr),
                                      +[](uint32_t id) { return (id << 16) | (id >> 16); },
                                      +[](uint32_t id) { return id * 2654435761u; }}) {
    test::EventLog log;
    SequenceConverter conv(&log);
    Status s = feed_grid_with_values(conv, n, id_of);
    ASSERT_TRUE(s.ok()) << s.to_string();
    if (dense.empty()) {
      dense = log.text();
    } else {
      EXPECT_EQ(log.text(), dense);
    }
  }
}

TEST(Converter, RejectsIdsFinalizedAndReleased) {
  // A 300 x 300 grid: 180k triangles, enough for regions to start and
  // vertices of the first rows to be emitted and leave the waiting area.
  PropertyValues none;
  double p[3] = {0, 0, 0};
  {
    CountingSink sink;
    SequenceConverter conv(&sink);
    ASSERT_TRUE(feed_grid(conv, 300).ok());
    ASSERT_GT(sink.triangles, 0u);
    Status s = conv.vertex(0, p, none);
    EXPECT_EQ(s.code(), ErrorCode::kBadIndex) << s.to_string();
  }
  {
    CountingSink sink;
    SequenceConverter conv(&sink);
    ASSERT_TRUE(feed_grid(conv, 300).ok());
    ASSERT_TRUE(conv.vertex(1000000, p, none).ok());
    ASSERT_TRUE(conv.vertex(1000001, p, none).ok());
    const uint32_t t[3] = {1000000, 1000001, 0};
    Status s = conv.triangle(t, none);
    EXPECT_EQ(s.code(), ErrorCode::kBadIndex) << s.to_string();
  }
  {
    CountingSink sink;
    SequenceConverter conv(&sink);
    ASSERT_TRUE(feed_grid(conv, 300).ok());
    Status s = conv.finalize(0);
    EXPECT_EQ(s.code(), ErrorCode::kBadIndex) << s.to_string();
    EXPECT_NE(s.message().find("twice"), std::string::npos) << s.to_string();
  }
  {
    // Ids finalized in random order over a wide range are remembered too.
    CountingSink sink;
    SequenceConverter conv(&sink);
    ASSERT_TRUE(conv.begin(MeshSchema()).ok());
    std::mt19937 rng(3);
    std::vector<uint32_t> ids;
    for (int i = 0; i < 20000; ++i) ids.push_back(static_cast<uint32_t>(rng() % 4000000000u));
    std::sort(ids.begin(), ids.end());
    ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
    std::shuffle(ids.begin(), ids.end(), rng);
    for (uint32_t id : ids) {
      ASSERT_TRUE(conv.vertex(id, p, none).ok());
      ASSERT_TRUE(conv.finalize(id).ok());
    }
    EXPECT_EQ(sink.vertices, ids.size());  // isolated: emitted and released at once
    for (size_t i = 0; i < ids.size(); i += 97) {
      SequenceConverter again(&sink);
      ASSERT_TRUE(again.begin(MeshSchema()).ok());
      ASSERT_TRUE(again.vertex(ids[i], p, none).ok());  // another converter: fine
    }
    EXPECT_EQ(conv.vertex(ids[ids.size() / 2], p, none).code(), ErrorCode::kBadIndex);
  }
  // Dense ids finalized in random order: ranges of 2^16 ids go from a list
  // to a bitmap to full. Each probe needs a converter of its own (errors
  // are sticky).
  std::vector<uint32_t> dense(140000);
  for (uint32_t i = 0; i < dense.size(); ++i) dense[i] = i;
  std::shuffle(dense.begin(), dense.end(), std::mt19937(9));
  for (uint32_t probe : {5u, 70000u, 131071u, 139999u}) {
    CountingSink sink;
    SequenceConverter conv(&sink);
    ASSERT_TRUE(conv.begin(MeshSchema()).ok());
    for (uint32_t id : dense) {
      ASSERT_TRUE(conv.vertex(id, p, none).ok());
      ASSERT_TRUE(conv.finalize(id).ok());
    }
    ASSERT_TRUE(conv.vertex(140001, p, none).ok());
    EXPECT_EQ(conv.vertex(probe, p, none).code(), ErrorCode::kBadIndex) << probe;
  }
}

TEST(Converter, ErrorsAreSticky) {
  CountingSink sink;
  SequenceConverter conv(&sink);
  PropertyValues none;
  double p[3] = {0, 0, 0};
  ASSERT_TRUE(conv.begin(MeshSchema()).ok());
  ASSERT_TRUE(conv.vertex(5, p, none).ok());
  Status first = conv.vertex(5, p, none);
  ASSERT_EQ(first.code(), ErrorCode::kBadIndex);
  const uint32_t t[3] = {5, 6, 7};
  for (Status s : {conv.vertex(6, p, none), conv.vertex(7, p, none), conv.triangle(t, none), conv.finalize(5),
                   conv.finish(), conv.begin(MeshSchema())}) {
    EXPECT_EQ(s.code(), first.code());
    EXPECT_EQ(s.message(), first.message());
  }
  EXPECT_EQ(sink.vertices, 0u);
}

#if defined(__GLIBC__) && (__GLIBC__ > 2 || (__GLIBC__ == 2 && __GLIBC_MINOR__ >= 33))
TEST(Converter, MemoryOfCutLinksIsReleased) {
  // Many small non-manifold pieces in a row: around vertex v the spoke v-a
  // has three triangles, so a fan walk cuts the link v-b between (v,a,b) and
  // (v,b,c). What the converter remembers of such cuts must leave with the
  // triangles: heap use stays flat once the waiting area is warm.
  CountingSink sink;
  SequenceConverter conv(&sink);
  PropertyValues none;
  double p[3] = {0, 0, 0};
  ASSERT_TRUE(conv.begin(MeshSchema()).ok());
  size_t warm = 0;
  for (uint32_t u = 0; u < 140000; ++u) {
    if (u == 40000) warm = mallinfo2().uordblks;
    uint32_t v = 5 * u, a = v + 1, b = v + 2, c = v + 3, d = v + 4;
    for (uint32_t i = v; i < v + 5; ++i) ASSERT_TRUE(conv.vertex(i, p, none).ok());
    const uint32_t ts[4][3] = {{v, a, b}, {v, b, c}, {v, c, a}, {v, a, d}};
    for (const auto& t : ts) ASSERT_TRUE(conv.triangle(t, none).ok());
    for (uint32_t i = v; i < v + 5; ++i) ASSERT_TRUE(conv.finalize(i).ok());
  }
  size_t end = mallinfo2().uordblks;
  EXPECT_LT(end, warm + (size_t{1} << 20)) << "heap grew by " << (end - warm) << " bytes over 100k cut links";
  ASSERT_TRUE(conv.finish().ok());
  EXPECT_EQ(sink.triangles, 4u * 140000);
  EXPECT_GE(conv.stats().nonmanifold_edges, 140000u);
}
#endif

// The forced sort path on every corpus mesh under 2 MB (the large ones take
// seconds there and add nothing the small ones do not cover).
TEST(SequenceShared, EveryCorpusMeshOnTheSortPath) {
  if (!test::file_exists(shared("meshes/bunny.ply"))) GTEST_SKIP() << "../shared/data not present";
  for (const std::string& name : corpus_meshes()) {
    std::string f = shared("meshes/" + name);
    if (std::filesystem::file_size(f) > (2u << 20)) continue;
    OpenedMesh om;
    ASSERT_TRUE(open_mesh(f, OpenOptions(), &om).ok()) << f;
    SequenceChecker checker;
    BuildOptions o;
    o.force_sort = true;
    BuildReport r;
    Status s = build_sequence(*om.source, checker, o, &r);
    EXPECT_TRUE(s.ok()) << f << ": " << s.to_string();
    EXPECT_EQ(checker.stats().triangles + r.converter.degenerate_dropped, r.triangles) << f;
  }
}

}  // namespace
}  // namespace psq
