// SPDX-License-Identifier: Apache-2.0
// The filter pipeline's pieces in format/: the streaming mesh interface and
// its adapters (psq/mesh_stream.h), the sequence-to-mesh adapter
// (psq/sequence_mesh.h), property merge rules (psq/property_merge.h) and
// the memory budget (psq/memory_budget.h).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <set>

#include "psq/converter.h"
#include "psq/memory_budget.h"
#include "psq/mesh_stream.h"
#include "psq/property_merge.h"
#include "psq/sequence_builder.h"
#include "psq/sequence_check.h"
#include "psq/sequence_mesh.h"
#include "psq/threaded_mesh_sink.h"
#include "test_util.h"

namespace psq {
namespace {

using test::Mesh;

using test::EventLog;

// The triangles as position triples, each rotated to start at its
// smallest corner, sorted: compares meshes whatever their vertex order.
std::vector<std::array<std::array<double, 3>, 3>> position_triangles(const Mesh& m) {
  std::vector<std::array<std::array<double, 3>, 3>> out;
  for (const auto& t : m.triangles) {
    std::array<std::array<double, 3>, 3> p = {m.positions[t[0]], m.positions[t[1]], m.positions[t[2]]};
    while (p[0] > p[1] || p[0] > p[2]) std::rotate(p.begin(), p.begin() + 1, p.end());
    out.push_back(p);
  }
  std::sort(out.begin(), out.end());
  return out;
}

Mesh sequence_to_mesh(SequenceSource& source) {
  SequenceMeshSource mesh(&source);
  test::MemorySink sink;
  Status s = pump(mesh, sink);
  EXPECT_TRUE(s.ok()) << s.to_string();
  return sink.mesh;
}

TEST(DenseMeshSink, RenumbersIdsInVertexOrder) {
  test::MemorySink mesh;
  DenseMeshSink dense(&mesh);
  MeshSchema schema;
  ASSERT_TRUE(dense.begin(schema).ok());
  const double p[3] = {1, 2, 3};
  for (uint32_t id : {70u, 5u, 900000u, 12u}) ASSERT_TRUE(dense.vertex(id, p, {}).ok());
  const uint32_t t1[3] = {5, 900000, 70};
  ASSERT_TRUE(dense.triangle(t1, {}).ok());
  ASSERT_TRUE(dense.finalize(70).ok());
  const uint32_t t2[3] = {5, 12, 900000};
  ASSERT_TRUE(dense.triangle(t2, {}).ok());
  for (uint32_t id : {5u, 12u, 900000u}) ASSERT_TRUE(dense.finalize(id).ok());
  ASSERT_TRUE(dense.finish().ok());
  ASSERT_EQ(mesh.mesh.triangles.size(), 2u);
  EXPECT_EQ(mesh.mesh.triangles[0], (std::array<uint32_t, 3>{1, 2, 0}));
  EXPECT_EQ(mesh.mesh.triangles[1], (std::array<uint32_t, 3>{1, 3, 2}));
  EXPECT_EQ(dense.vertices(), 4u);
  EXPECT_EQ(dense.triangles(), 2u);
  EXPECT_TRUE(mesh.finished);
}

TEST(DenseMeshSink, RejectsWhatItCannotRenumber) {
  const double p[3] = {0, 0, 0};
  const uint32_t t[3] = {1, 2, 3};
  {
    test::MemorySink mesh;
    DenseMeshSink dense(&mesh);
    EXPECT_EQ(dense.vertex(1, p, {}).code(), ErrorCode::kUsage);  // before begin()
  }
  {
    test::MemorySink mesh;
    DenseMeshSink dense(&mesh);
    ASSERT_TRUE(dense.begin(MeshSchema()).ok());
    ASSERT_TRUE(dense.vertex(1, p, {}).ok());
    EXPECT_EQ(dense.vertex(1, p, {}).code(), ErrorCode::kBadIndex);
    // Sticky.
    EXPECT_EQ(dense.vertex(2, p, {}).code(), ErrorCode::kBadIndex);
  }
  {
    test::MemorySink mesh;
    DenseMeshSink dense(&mesh);
    ASSERT_TRUE(dense.begin(MeshSchema()).ok());
    for (uint32_t id : {1u, 2u}) ASSERT_TRUE(dense.vertex(id, p, {}).ok());
    EXPECT_EQ(dense.triangle(t, {}).code(), ErrorCode::kBadIndex);  // 3 was not given
  }
  {
    test::MemorySink mesh;
    DenseMeshSink dense(&mesh);
    ASSERT_TRUE(dense.begin(MeshSchema()).ok());
    for (uint32_t id : {1u, 2u, 3u}) ASSERT_TRUE(dense.vertex(id, p, {}).ok());
    ASSERT_TRUE(dense.finalize(3).ok());
    EXPECT_EQ(dense.triangle(t, {}).code(), ErrorCode::kBadIndex);  // 3 is finalized
  }
  {
    test::MemorySink mesh;
    DenseMeshSink dense(&mesh);
    ASSERT_TRUE(dense.begin(MeshSchema()).ok());
    EXPECT_EQ(dense.finalize(8).code(), ErrorCode::kBadIndex);
    EXPECT_EQ(dense.finish().code(), ErrorCode::kBadIndex);
  }
  {
    test::MemorySink mesh;
    DenseMeshSink dense(&mesh);
    ASSERT_TRUE(dense.begin(MeshSchema()).ok());
    EXPECT_EQ(dense.vertex(0xffffffffu, p, {}).code(), ErrorCode::kBadIndex);
  }
}

// The converter and DenseMeshSink take the same stream through the same
// interface, and give the same mesh (up to order and cut vertices).
TEST(StreamingMeshSink, ConverterAndDenseSinkGiveTheSameMesh) {
  Mesh sphere = test::make_sphere(12, 16);
  for (int which = 0; which < 2; ++which) {
    EventLog log;
    SequenceConverter conv(&log);
    test::MemorySink direct;
    DenseMeshSink dense(&direct);
    StreamingMeshSink* sink = which == 0 ? static_cast<StreamingMeshSink*>(&conv) : &dense;
    ASSERT_TRUE(sink->begin(sphere.schema).ok());
    for (uint32_t i = 0; i < sphere.positions.size(); ++i)
      ASSERT_TRUE(sink->vertex(1000 + 3 * i, sphere.positions[i].data(), {}).ok());
    for (const auto& t : sphere.triangles) {
      const uint32_t id[3] = {1000 + 3 * t[0], 1000 + 3 * t[1], 1000 + 3 * t[2]};
      ASSERT_TRUE(sink->triangle(id, {}).ok());
    }
    for (uint32_t i = 0; i < sphere.positions.size(); ++i) ASSERT_TRUE(sink->finalize(1000 + 3 * i).ok());
    ASSERT_TRUE(sink->finish().ok());
    test::EventReplay replay(log);
    Mesh got = which == 0 ? sequence_to_mesh(replay) : direct.mesh;
    EXPECT_EQ(got.positions.size(), sphere.positions.size());
    EXPECT_EQ(position_triangles(got), position_triangles(sphere));
  }
}

// A sink that fails at its n-th triangle.
class FailingSink : public CountingMeshSink {
 public:
  explicit FailingSink(uint64_t n) : n_(n) {}
  Status triangle(const uint32_t* id, const PropertyValues& v) override {
    if (triangles == n_) return Status(ErrorCode::kIo, "disk full");
    return CountingMeshSink::triangle(id, v);
  }

 private:
  uint64_t n_;
};

TEST(ThreadedMeshSink, PassesEveryEventInOrder) {
  Mesh sphere = test::make_sphere(30, 40);
  sphere.schema.vertex_properties = {{"q", ScalarType::kFloat64}};
  sphere.schema.face_properties = {{"f", ScalarType::kInt32}};
  test::MemorySink direct, threaded;
  for (test::MemorySink* out : {&direct, &threaded}) {
    DenseMeshSink dense(out);
    std::unique_ptr<ThreadedMeshSink> thread;
    StreamingMeshSink* sink = &dense;
    if (out == &threaded) {
      thread = std::make_unique<ThreadedMeshSink>(&dense);
      sink = thread.get();
    }
    ASSERT_TRUE(sink->begin(sphere.schema).ok());
    for (uint32_t i = 0; i < sphere.positions.size(); ++i)
      ASSERT_TRUE(sink->vertex(7 * i + 1, sphere.positions[i].data(), {0.5 * i}).ok());
    for (size_t t = 0; t < sphere.triangles.size(); ++t) {
      const auto& tr = sphere.triangles[t];
      const uint32_t id[3] = {7 * tr[0] + 1, 7 * tr[1] + 1, 7 * tr[2] + 1};
      ASSERT_TRUE(sink->triangle(id, {static_cast<double>(t)}).ok());
    }
    for (uint32_t i = 0; i < sphere.positions.size(); ++i) ASSERT_TRUE(sink->finalize(7 * i + 1).ok());
    ASSERT_TRUE(sink->finish().ok());
  }
  EXPECT_EQ(threaded.mesh.positions, direct.mesh.positions);
  EXPECT_EQ(threaded.mesh.vertex_values, direct.mesh.vertex_values);
  EXPECT_EQ(threaded.mesh.triangles, direct.mesh.triangles);
  EXPECT_EQ(threaded.mesh.face_values, direct.mesh.face_values);
  EXPECT_TRUE(threaded.finished);
}

TEST(ThreadedMeshSink, TheWrappedSinksErrorComesBack) {
  FailingSink failing(100);
  Status s;
  {
    ThreadedMeshSink thread(&failing);
    ASSERT_TRUE(thread.begin(MeshSchema()).ok());
    const double p[3] = {0, 0, 0};
    for (uint32_t i = 0; i < 3 && s.ok(); ++i) s = thread.vertex(i, p, {});
    for (int t = 0; t < 100000 && s.ok(); ++t) {
      const uint32_t id[3] = {0, 1, 2};
      s = thread.triangle(id, {});
    }
    if (s.ok()) s = thread.finish();
  }
  EXPECT_EQ(s.code(), ErrorCode::kIo);
  EXPECT_EQ(failing.triangles, 100u);
}

TEST(StreamingMeshSink, TeeAndCountingSinks) {
  CountingMeshSink a, b;
  TeeMeshSink tee(&a, &b);
  const double p[3] = {0, 0, 0};
  ASSERT_TRUE(tee.begin(MeshSchema()).ok());
  for (uint32_t id : {4u, 5u, 6u}) ASSERT_TRUE(tee.vertex(id, p, {}).ok());
  const uint32_t t[3] = {4, 5, 6};
  ASSERT_TRUE(tee.triangle(t, {}).ok());
  ASSERT_TRUE(tee.finish().ok());
  EXPECT_EQ(a.vertices, 3u);
  EXPECT_EQ(b.triangles, 1u);
}

// Two triangles sharing only a vertex: the sequence cuts it (a
// re-appearance); the adapter merges it back.
TEST(SequenceMeshSource, MergesReappearingVertices) {
  Mesh bowtie = test::make_mesh({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {-1, 0, 0}, {0, -1, 0}, {2, 2, 2}},
                                {{0, 1, 2}, {0, 3, 4}});
  test::MemorySource source(bowtie);
  EventLog log;
  BuildReport report;
  ASSERT_TRUE(build_sequence(source, log, BuildOptions(), &report).ok());
  size_t reappearing = 0;
  for (const SequenceEvent& e : log.events)
    reappearing += e.kind == SequenceEvent::Kind::kVertex && e.vertex.reappears != kNoVertex;
  EXPECT_EQ(reappearing, 1u);
  test::EventReplay replay(log);
  Mesh got = sequence_to_mesh(replay);
  EXPECT_EQ(got.positions.size(), 6u);  // the isolated vertex too
  // Same triangles over the same positions.
  ASSERT_EQ(got.triangles.size(), 2u);
  std::set<std::array<double, 3>> corners;
  for (const auto& t : got.triangles)
    for (uint32_t v : t) corners.insert(got.positions[v]);
  EXPECT_EQ(corners.size(), 5u);
  EXPECT_FALSE(got.schema.has_bounds && got.schema.vertex_count != MeshSchema::kUnknown);
}

TEST(SequenceMeshSource, RejectsBrokenReferences) {
  for (int which = 0; which < 3; ++which) {
    EventLog log;
    SequenceVertex v;
    v.index = 0;
    ASSERT_TRUE(log.vertex(v).ok());
    v.index = which == 0 ? 5 : 1;  // 0: out of order
    if (which == 1) v.reappears = 1;  // re-appears itself
    ASSERT_TRUE(log.vertex(v).ok());
    SequenceTriangle t;
    t.v[0] = 0, t.v[1] = 1, t.v[2] = which == 2 ? 7 : 0;  // 2: a vertex never introduced
    ASSERT_TRUE(log.triangle(t).ok());
    test::EventReplay replay(log);
    SequenceMeshSource mesh(&replay);
    MeshItem item;
    Status s;
    for (int i = 0; i < 8 && s.ok(); ++i) s = mesh.next(&item);
    EXPECT_EQ(s.code(), ErrorCode::kBadSequence) << which;
    EXPECT_EQ(mesh.next(&item).code(), ErrorCode::kBadSequence);  // sticky
  }
}

TEST(PropertyMerge, DefaultRules) {
  auto rule = [](const char* name, ScalarType t = ScalarType::kFloat32, bool list = false) {
    Property p;
    p.name = name;
    p.type = t;
    p.is_list = list;
    return default_merge_rule(p);
  };
  EXPECT_EQ(rule("nx"), MergeRule::kAverage);
  EXPECT_EQ(rule("normal_z"), MergeRule::kAverage);
  EXPECT_EQ(rule("red", ScalarType::kUInt8), MergeRule::kAverage);
  EXPECT_EQ(rule("alpha", ScalarType::kUInt8), MergeRule::kAverage);
  EXPECT_EQ(rule("u"), MergeRule::kAverage);
  EXPECT_EQ(rule("texture_v"), MergeRule::kAverage);
  EXPECT_EQ(rule("confidence"), MergeRule::kFirst);
  EXPECT_EQ(rule("label", ScalarType::kInt32), MergeRule::kFirst);
  EXPECT_EQ(rule("nx", ScalarType::kFloat32, true), MergeRule::kDrop);
  EXPECT_STREQ(merge_rule_name(MergeRule::kFirst), "first");
}

TEST(PropertyMerge, AveragesRoundsRenormalizesAndKeepsTheFirst) {
  MeshSchema schema;
  schema.vertex_properties = {{"nx", ScalarType::kFloat32}, {"ny", ScalarType::kFloat32},
                              {"nz", ScalarType::kFloat32}, {"red", ScalarType::kUInt8},
                              {"label", ScalarType::kInt32}, {"list", ScalarType::kInt32, true},
                              {"u", ScalarType::kFloat32},  {"gone", ScalarType::kFloat64}};
  MergePolicy policy = default_merge_policy(schema);
  policy.vertex[7] = MergeRule::kDrop;
  MeshSchema out = merged_schema(schema, policy);
  ASSERT_EQ(out.vertex_properties.size(), 6u);  // the list and "gone" dropped
  EXPECT_EQ(out.vertex_properties[4].name, "label");
  EXPECT_EQ(out.vertex_properties[5].name, "u");

  PropertyMerger m(schema.vertex_properties, policy.vertex);
  ASSERT_GT(m.width(), 0u);
  std::vector<double> a(m.width()), b(m.width());
  m.reset(a.data());
  m.reset(b.data());
  // Values: nx ny nz red label [count list...] u gone.
  m.add(a.data(), {1, 0, 0, 10, 7, 2, 5, 6, 0.1, 9}, 30);
  m.add(a.data(), {0, 1, 0, 11, 8, 0, 0.2, 9}, 20);  // order 20: its label is the first
  m.add(b.data(), {0, 1, 0, 255, 9, 1, 4, 0.3, 9}, 40);
  m.merge(a.data(), b.data());
  PropertyValues v;
  m.result(a.data(), &v);
  ASSERT_EQ(v.size(), 6u);
  const double n = std::sqrt(1.0 + 4.0);
  EXPECT_FLOAT_EQ(v[0], static_cast<float>(1 / n));
  EXPECT_FLOAT_EQ(v[1], static_cast<float>(2 / n));
  EXPECT_EQ(v[2], 0);
  EXPECT_EQ(v[3], 92);  // (10 + 11 + 255) / 3 = 92
  EXPECT_EQ(v[4], 8);   // the label of order 20
  EXPECT_TRUE(scalar_holds(ScalarType::kFloat32, v[5]));
  EXPECT_NEAR(v[5], 0.2, 1e-6);
  for (size_t i = 0; i < out.vertex_properties.size(); ++i) EXPECT_TRUE(scalar_holds(out.vertex_properties[i].type, v[i]));

  // Merging in the other order gives the same.
  std::vector<double> c(m.width()), d(m.width());
  m.reset(c.data());
  m.reset(d.data());
  m.add(d.data(), {0, 1, 0, 255, 9, 1, 4, 0.3, 9}, 40);
  m.add(c.data(), {0, 1, 0, 11, 8, 0, 0.2, 9}, 20);
  m.add(c.data(), {1, 0, 0, 10, 7, 2, 5, 6, 0.1, 9}, 30);
  m.merge(d.data(), c.data());
  PropertyValues w;
  m.result(d.data(), &w);
  EXPECT_EQ(v, w);
}

TEST(PropertyMerge, IntegerAveragesStayInRange) {
  std::vector<Property> props = {{"q", ScalarType::kInt8}};
  PropertyMerger m(props, {MergeRule::kAverage});
  std::vector<double> a(m.width());
  m.reset(a.data());
  m.add(a.data(), {-128}, 0);
  m.add(a.data(), {-127}, 1);
  PropertyValues v;
  m.result(a.data(), &v);
  EXPECT_TRUE(scalar_holds(ScalarType::kInt8, v[0]));
  EXPECT_EQ(v[0], -127);  // -127.5 rounds half up
}

TEST(PropertyMerge, NothingKeptNeedsNoAccumulator) {
  std::vector<Property> props = {{"l", ScalarType::kUInt8, true}};
  PropertyMerger m(props, {MergeRule::kFirst});
  EXPECT_EQ(m.width(), 0u);
  PropertyValues v = {1};
  m.result(nullptr, &v);
  EXPECT_TRUE(v.empty());
}

TEST(MemoryBudget, SharesAddUpAndPhasesGiveBack) {
  MemoryBudget b(1000);
  EXPECT_EQ(b.draw(1, 2), 500u);
  EXPECT_EQ(b.draw(1, 4), 250u);
  EXPECT_EQ(b.draw(1, 2), 250u);  // only what is left
  EXPECT_EQ(b.left(), 0u);
  EXPECT_EQ(b.draw_bytes(7), 0u);
  b.give_back(300);
  EXPECT_EQ(b.left(), 300u);
  EXPECT_EQ(b.draw_rest(), 300u);
  EXPECT_EQ(b.total(), 1000u);
  MemoryBudget huge(~uint64_t{0});
  EXPECT_EQ(huge.draw(1, 4), ~uint64_t{0} / 4);
}

}  // namespace
}  // namespace psq
