// SPDX-License-Identifier: Apache-2.0
// The stream edge-collapse simplifier (psq/stream_qem.h) and the streaming
// smoother (psq/taubin_smooth.h), on meshes made in code: targets, topology,
// borders, determinism, bounded against whole-mesh buffers.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <map>
#include <set>

#include "psq/mesh_formats.h"
#include "psq/ply.h"
#include "psq/sequence_builder.h"
#include "psq/sequence_check.h"
#include "psq/stream_qem.h"
#include "psq/taubin_smooth.h"
#include "corner_values.h"
#include "test_util.h"

namespace psq {
namespace {

using test::Mesh;
using Pos = std::array<double, 3>;

class Collected : public SequenceSink {
 public:
  Status begin(const MeshSchema& s) override {
    schema = s;
    return checker.begin(s);
  }
  Status vertex(const SequenceVertex& v) override {
    positions.push_back({v.position[0], v.position[1], v.position[2]});
    vertex_values.push_back(v.values);
    return checker.vertex(v);
  }
  Status triangle(const SequenceTriangle& t) override {
    triangles.push_back({t.v[0], t.v[1], t.v[2]});
    face_values.push_back(t.values);
    for (int k = 0; k < 3; ++k)
      if (t.border_mask & (1u << k)) {
        border_vertices.insert(t.v[k]);
        border_vertices.insert(t.v[(k + 1) % 3]);
      }
    return checker.triangle(t);
  }
  Status finalize(uint32_t i) override { return checker.finalize(i); }
  Status finish() override {
    finished = true;
    return checker.finish();
  }
  std::multiset<std::array<Pos, 3>> geometry() const {
    std::multiset<std::array<Pos, 3>> out;
    for (const auto& t : triangles) {
      std::array<Pos, 3> g = {positions[t[0]], positions[t[1]], positions[t[2]]};
      while (g[0] > g[1] || g[0] > g[2]) std::rotate(g.begin(), g.begin() + 1, g.end());
      out.insert(g);
    }
    return out;
  }
  Pos normal(size_t t) const {
    const Pos& a = positions[triangles[t][0]];
    const Pos& b = positions[triangles[t][1]];
    const Pos& c = positions[triangles[t][2]];
    const Pos e1 = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, e2 = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    return {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
  }
  MeshSchema schema;
  SequenceChecker checker;
  std::vector<Pos> positions;
  std::vector<PropertyValues> vertex_values, face_values;
  std::vector<std::array<uint32_t, 3>> triangles;
  std::set<uint32_t> border_vertices;
  bool finished = false;
};

Status run(const Mesh& m, SequenceSink& sink) {
  test::MemorySource source(m);
  BuildReport report;
  return build_sequence(source, sink, BuildOptions(), &report);
}

Status simplify(const Mesh& m, const QemOptions& o, Collected* out, QemReport* report = nullptr) {
  StreamQem qem(out, o);
  Status s = run(m, qem);
  if (report) *report = qem.report();
  return s;
}

// RMS over triangles of the distance of their centroids and corners from
// the unit sphere.
double sphere_error(const Collected& c) {
  double sum = 0;
  size_t n = 0;
  for (const auto& t : c.triangles) {
    Pos centroid = {0, 0, 0};
    for (uint32_t v : t) {
      const Pos& p = c.positions[v];
      const double r = std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
      sum += (r - 1) * (r - 1);
      ++n;
      for (int i = 0; i < 3; ++i) centroid[i] += p[i] / 3;
    }
    const double r = std::sqrt(centroid[0] * centroid[0] + centroid[1] * centroid[1] + centroid[2] * centroid[2]);
    sum += (r - 1) * (r - 1);
    ++n;
  }
  return std::sqrt(sum / std::max<size_t>(n, 1));
}

void expect_clean_closed(const Collected& c, uint64_t components, int64_t handles) {
  ASSERT_TRUE(c.finished);
  const SequenceStats& st = c.checker.stats();
  EXPECT_EQ(st.components, components);
  EXPECT_EQ(st.handles, handles);
  EXPECT_EQ(st.border_edges, 0u);
  EXPECT_EQ(st.nonmanifold_vertices, 0u);
  EXPECT_EQ(st.nonmanifold_edges, 0u);
  for (size_t t = 0; t < c.triangles.size(); ++t) {
    const Pos n = c.normal(t);
    EXPECT_GT(n[0] * n[0] + n[1] * n[1] + n[2] * n[2], 0) << "degenerate triangle " << t;
  }
}

bool within_one_percent(uint64_t got, uint64_t want) {
  const double d = std::fabs(static_cast<double>(got) - static_cast<double>(want));
  return d <= std::max(2.0, 0.01 * static_cast<double>(want));
}

TEST(StreamQem, SphereToTenPercentBoundedAndWhole) {
  const Mesh m = test::make_sphere(60, 80);
  for (uint32_t buffer : {1500u, 1u << 28}) {
    QemOptions o;
    o.ratio = 0.1;
    o.buffer_triangles = buffer;
    Collected out;
    QemReport r;
    ASSERT_TRUE(simplify(m, o, &out, &r).ok()) << buffer;
    EXPECT_EQ(r.input_triangles, m.triangles.size());
    EXPECT_EQ(r.output_triangles, out.triangles.size());
    EXPECT_EQ(r.target_triangles, 944u);
    EXPECT_TRUE(within_one_percent(out.triangles.size(), 944)) << out.triangles.size();
    EXPECT_LE(r.max_buffer_triangles, std::min<uint64_t>(buffer, m.triangles.size()) + 1);
    expect_clean_closed(out, 1, 0);
    // No flipped triangle: on a sphere every normal points outwards.
    for (size_t t = 0; t < out.triangles.size(); ++t) {
      const Pos n = out.normal(t);
      const Pos& p = out.positions[out.triangles[t][0]];
      const double nl = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
      const double pl = std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
      EXPECT_GT((n[0] * p[0] + n[1] * p[1] + n[2] * p[2]) / (nl * pl), 0.2) << "flipped triangle " << t << " area " << nl;
    }
    EXPECT_LT(sphere_error(out), 0.01);
    EXPECT_GT(r.max_error, 0);
    EXPECT_LT(r.max_error, 0.05);
  }
}

// The achieved count is the target's, rounded, within 1% (the issue's
// check), streaming through a small buffer as through one holding the
// whole mesh, on closed meshes of about 100k triangles of genus 0 and 1.
TEST(StreamQem, CountWithinOnePercentOnAHundredThousandTriangles) {
  const Mesh sphere = test::make_sphere(250, 200);
  const Mesh torus = test::make_torus(400, 125);
  for (const Mesh* m : {&sphere, &torus}) {
    const uint64_t n = m->triangles.size();
    ASSERT_GT(n, 95000u);
    ASSERT_LT(n, 105000u);
    for (double ratio : {0.1, 0.01}) {
      for (uint32_t buffer : {0u, 4000u}) {
        QemOptions o;
        o.ratio = ratio;
        o.buffer_triangles = buffer;
        Collected out;
        QemReport r;
        ASSERT_TRUE(simplify(*m, o, &out, &r).ok());
        const uint64_t want = static_cast<uint64_t>(std::llround(ratio * static_cast<double>(n)));
        EXPECT_EQ(r.target_triangles, want);
        EXPECT_EQ(r.output_triangles, out.triangles.size());
        EXPECT_LE(std::fabs(static_cast<double>(out.triangles.size()) - static_cast<double>(want)), 0.01 * want)
            << n << " triangles, ratio " << ratio << ", buffer " << buffer << ": " << out.triangles.size();
        EXPECT_EQ(r.components_dropped, 0u);
        expect_clean_closed(out, 1, m == &torus ? 1 : 0);
      }
    }
    // A count target, not a multiple of the ratio's steps.
    QemOptions o;
    o.target_triangles = 1234;
    o.input_triangles = n;
    Collected out;
    ASSERT_TRUE(simplify(*m, o, &out).ok());
    EXPECT_LE(std::fabs(static_cast<double>(out.triangles.size()) - 1234), 12.34) << out.triangles.size();
  }
}

// A sphere with many small bubbles around it (a foam's small components):
// each bubble can shrink only to a tetrahedron. At 10% the target is met
// with every bubble kept; at 1% it cannot be, so bubbles go whole,
// no more than needed, and the sphere stays.
TEST(StreamQem, BubblesGoWholeOnlyWhenTheTargetNeedsIt) {
  const Mesh sphere = test::make_sphere(100, 120);
  const Mesh bubble = test::make_sphere(5, 8);
  std::vector<Pos> positions = sphere.positions;
  std::vector<std::array<uint32_t, 3>> triangles = sphere.triangles;
  std::mt19937 rng(5);
  std::normal_distribution<double> gauss;
  const int kBubbles = 200;
  for (int i = 0; i < kBubbles; ++i) {
    Pos c = {gauss(rng), gauss(rng), gauss(rng)};
    const double l = std::sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
    for (double& x : c) x *= 1.15 / l;
    const uint32_t base = static_cast<uint32_t>(positions.size());
    for (const Pos& p : bubble.positions)
      positions.push_back({c[0] + 0.004 * p[0], c[1] + 0.004 * p[1], c[2] + 0.004 * p[2]});
    for (const auto& t : bubble.triangles) triangles.push_back({base + t[0], base + t[1], base + t[2]});
  }
  const Mesh m = test::make_mesh(positions, triangles);
  const uint64_t n = m.triangles.size();
  for (uint32_t buffer : {0u, 6000u}) {
    for (double ratio : {0.1, 0.01}) {
      QemOptions o;
      o.ratio = ratio;
      o.buffer_triangles = buffer;
      Collected out;
      QemReport r;
      ASSERT_TRUE(simplify(m, o, &out, &r).ok());
      const double want = std::round(ratio * static_cast<double>(n));
      EXPECT_LE(std::fabs(static_cast<double>(out.triangles.size()) - want), 0.01 * want)
          << "ratio " << ratio << ", buffer " << buffer << ": " << out.triangles.size() << " for " << want
          << ", dropped " << r.components_dropped << ", components " << out.checker.stats().components << ", max error "
          << r.max_error;
      const SequenceStats& st = out.checker.stats();
      EXPECT_EQ(st.nonmanifold_vertices, 0u);
      EXPECT_EQ(st.nonmanifold_edges, 0u);
      EXPECT_EQ(st.border_edges, 0u);
      EXPECT_EQ(st.handles, 0);
      EXPECT_EQ(st.components + r.components_dropped, kBubbles + 1u);
      if (ratio == 0.1) {
        EXPECT_EQ(r.components_dropped, 0u);
      } else {
        // Even as tetrahedra the bubbles are more than the target.
        EXPECT_GT(r.components_dropped, 0u);
        EXPECT_EQ(r.triangles_dropped, 4 * r.components_dropped);
        // What stays is near the sphere or a bubble: the sphere kept.
        size_t on_sphere = 0;
        for (const auto& t : out.triangles) {
          const Pos& p = out.positions[t[0]];
          if (std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]) < 1.05) ++on_sphere;
        }
        EXPECT_GT(on_sphere, 100u);
      }
    }
  }
}

// Parts that no collapse can reduce (tetrahedra), and no collapse to set an
// error scale: when the count needs it they go all the same, the smallest
// first, one at a time until the count is as near the target as whole
// parts allow.
TEST(StreamQem, PartsGoBeyondTheCollapseErrorWhenTheCountNeedsIt) {
  std::vector<Pos> positions;
  std::vector<std::array<uint32_t, 3>> triangles;
  const int kParts = 10;
  for (int i = 0; i < kParts; ++i) {
    const double s = 1 + i;  // part i is the (i + 1)-th smallest
    const double x = 30.0 * i;
    const uint32_t b = static_cast<uint32_t>(positions.size());
    positions.push_back({x, 0, 0});
    positions.push_back({x + s, 0, 0});
    positions.push_back({x, s, 0});
    positions.push_back({x, 0, s});
    for (const auto& t : std::vector<std::array<uint32_t, 3>>{{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}})
      triangles.push_back({b + t[0], b + t[1], b + t[2]});
  }
  const Mesh m = test::make_mesh(positions, triangles);
  for (uint64_t target : {20u, 22u, 40u}) {
    QemOptions o;
    o.target_triangles = target;
    o.input_triangles = triangles.size();
    Collected out;
    QemReport r;
    const Status s = simplify(m, o, &out, &r);
    ASSERT_TRUE(s.ok()) << s.to_string();
    // 22 is as near to 20 as to 24: the nearer, never past the target,
    // unless that is nearer.
    const uint64_t want = target == 22 ? 24 : target;
    EXPECT_EQ(out.triangles.size(), want) << "target " << target;
    EXPECT_EQ(r.components_dropped, (40 - want) / 4) << "target " << target;
    // The largest parts stay.
    double largest = 0;
    for (const Pos& p : out.positions) largest = std::max(largest, p[0]);
    EXPECT_EQ(largest, 30.0 * (kParts - 1) + kParts) << "target " << target;
  }
}

// A torus keeps its handle while the target allows (at 10%); for a target
// below what a torus can have (a closed surface of genus 1 needs 14
// triangles) the tube is cut where three edges go round it, each side
// closed by a triangle, and the sphere left simplifies to the target.
TEST(StreamQem, HandlesAreCutOnlyWhenTheTargetNeedsIt) {
  const Mesh m = test::make_torus(120, 40);
  for (uint32_t buffer : {0u, 2000u}) {
    QemOptions o;
    o.ratio = 0.1;
    o.buffer_triangles = buffer;
    Collected kept;
    QemReport r;
    ASSERT_TRUE(simplify(m, o, &kept, &r).ok());
    EXPECT_EQ(r.handles_cut, 0u);
    expect_clean_closed(kept, 1, 1);
    QemOptions tiny;
    tiny.target_triangles = 8;
    tiny.input_triangles = m.triangles.size();
    tiny.buffer_triangles = buffer;
    Collected cut;
    ASSERT_TRUE(simplify(m, tiny, &cut, &r).ok());
    EXPECT_EQ(cut.triangles.size(), 8u);
    EXPECT_GE(r.handles_cut, 1u);
    EXPECT_EQ(r.components_dropped, 0u);
    expect_clean_closed(cut, 1, 0);
  }
}

// Every output triangle faces within 90 degrees of the input triangle it
// descends from (the collapse's flip test; triangles keep their face
// values, here their input numbers), on a folded, noisy surface.
TEST(StreamQem, NoTriangleTurnsAwayFromItsInputTriangle) {
  Mesh m = test::make_torus(300, 80, 0.08);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> noise(-0.004, 0.004);
  for (auto& p : m.positions)
    for (double& x : p) x += noise(rng);
  m.schema.face_properties.push_back({"id", ScalarType::kUInt32});
  for (size_t t = 0; t < m.triangles.size(); ++t) m.face_values[t] = {static_cast<double>(t)};
  auto normal = [](const Pos& a, const Pos& b, const Pos& c) {
    const Pos e1 = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, e2 = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    return Pos{e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
  };
  for (double ratio : {0.1, 0.01}) {
    QemOptions o;
    o.ratio = ratio;
    o.buffer_triangles = 3000;
    Collected out;
    ASSERT_TRUE(simplify(m, o, &out).ok());
    ASSERT_EQ(out.face_values.size(), out.triangles.size());
    for (size_t t = 0; t < out.triangles.size(); ++t) {
      const size_t id = static_cast<size_t>(out.face_values[t].at(0));
      ASSERT_LT(id, m.triangles.size());
      const auto& f = m.triangles[id];
      const Pos a = normal(m.positions[f[0]], m.positions[f[1]], m.positions[f[2]]);
      const Pos b = out.normal(t);
      EXPECT_GT(a[0] * b[0] + a[1] * b[1] + a[2] * b[2], 0) << "ratio " << ratio << ", triangle " << t;
    }
  }
}

TEST(StreamQem, WholeBufferIsNoWorseThanABoundedOne) {
  const Mesh m = test::make_sphere(80, 100);
  double whole = 0, bounded = 0;
  for (uint64_t seed : {1, 2, 3}) {
    for (uint32_t buffer : {2000u, 1u << 28}) {
      QemOptions o;
      o.ratio = 0.05;
      o.buffer_triangles = buffer;
      o.seed = seed;
      Collected out;
      ASSERT_TRUE(simplify(m, o, &out).ok());
      (buffer == 2000u ? bounded : whole) += sphere_error(out);
    }
  }
  EXPECT_LE(whole, bounded * 1.05) << whole << " " << bounded;
}

TEST(StreamQem, SameOptionsSameOutput) {
  // Large enough that the candidates are sampled (small sets are compared
  // whole, whatever the seed).
  const Mesh m = test::make_torus(240, 60);
  QemOptions o;
  o.ratio = 0.2;
  o.buffer_triangles = 8000;
  Collected a, b, c;
  ASSERT_TRUE(simplify(m, o, &a).ok());
  ASSERT_TRUE(simplify(m, o, &b).ok());
  EXPECT_EQ(a.positions, b.positions);
  EXPECT_EQ(a.triangles, b.triangles);
  o.seed = 7;
  ASSERT_TRUE(simplify(m, o, &c).ok());
  EXPECT_NE(a.positions, c.positions);
  expect_clean_closed(c, 1, 1);
}

TEST(StreamQem, TorusKeepsItsHandle) {
  const Mesh m = test::make_torus(80, 30);
  QemOptions o;
  o.ratio = 0.02;
  o.buffer_triangles = 1000;
  Collected out;
  ASSERT_TRUE(simplify(m, o, &out).ok());
  EXPECT_TRUE(within_one_percent(out.triangles.size(), 96)) << out.triangles.size();
  expect_clean_closed(out, 1, 1);
}

// A grid bent into a smooth bump, with a straight square border.
Mesh bumpy_grid(int n) {
  Mesh m = test::make_grid(n);
  for (auto& p : m.positions) {
    const double x = p[0] / n - 0.5, y = p[1] / n - 0.5;
    volatile float z = static_cast<float>(0.3 * n * std::exp(-8 * (x * x + y * y)));
    p[2] = z;
  }
  return m;
}

TEST(StreamQem, BorderOnlyShrinks) {
  const int n = 40;
  const Mesh m = bumpy_grid(n);
  QemOptions o;
  o.ratio = 0.05;
  o.buffer_triangles = 600;
  Collected out;
  ASSERT_TRUE(simplify(m, o, &out).ok());
  EXPECT_TRUE(within_one_percent(out.triangles.size(), 160)) << out.triangles.size();
  const SequenceStats& st = out.checker.stats();
  EXPECT_EQ(st.components, 1u);
  EXPECT_EQ(st.border_loops, 1u);
  EXPECT_LE(st.border_edges, 4u * n);
  EXPECT_EQ(st.nonmanifold_vertices, 0u);
  // Border vertices stay on the square; no vertex leaves it.
  for (uint32_t v : out.border_vertices) {
    const Pos& p = out.positions[v];
    const double d = std::min({std::fabs(p[0]), std::fabs(p[0] - n), std::fabs(p[1]), std::fabs(p[1] - n)});
    EXPECT_LT(d, 1e-3 * n) << p[0] << " " << p[1];
  }
  for (const Pos& p : out.positions) {
    EXPECT_GE(p[0], -1e-6);
    EXPECT_LE(p[0], n + 1e-6);
    EXPECT_GE(p[1], -1e-6);
    EXPECT_LE(p[1], n + 1e-6);
  }
}

TEST(StreamQem, LockBorderKeepsEveryBorderVertexBitExact) {
  const int n = 40;
  const Mesh m = bumpy_grid(n);
  std::set<Pos> border_in;
  for (const Pos& p : m.positions)
    if (p[0] == 0 || p[0] == n || p[1] == 0 || p[1] == n) border_in.insert(p);
  QemOptions o;
  o.ratio = 0.1;
  o.lock_border = true;
  o.buffer_triangles = 600;
  Collected out;
  ASSERT_TRUE(simplify(m, o, &out).ok());
  std::set<Pos> border_out;
  for (uint32_t v : out.border_vertices) border_out.insert(out.positions[v]);
  EXPECT_EQ(border_out, border_in);
  EXPECT_EQ(out.checker.stats().border_edges, 4u * n);
  EXPECT_TRUE(within_one_percent(out.triangles.size(), 320)) << out.triangles.size();
}

TEST(StreamQem, MaxErrorBoundsEveryCollapse) {
  const Mesh m = test::make_sphere(60, 80);
  QemOptions o;
  o.max_error = 0.002;
  o.buffer_triangles = 2000;
  Collected out;
  QemReport r;
  ASSERT_TRUE(simplify(m, o, &out, &r).ok());
  EXPECT_LE(r.max_error, 0.002);
  EXPECT_LT(out.triangles.size(), m.triangles.size() / 2);
  EXPECT_EQ(r.target_triangles, 0u);
  expect_clean_closed(out, 1, 0);
  // A flat grid costs nothing: it goes as far as the topology allows.
  Mesh flat = test::make_grid(30);
  Collected flat_out;
  ASSERT_TRUE(simplify(flat, o, &flat_out).ok());
  EXPECT_LT(flat_out.triangles.size(), 40u);
}

TEST(StreamQem, TargetTrianglesNeedsTheInputCount) {
  const Mesh m = test::make_sphere(40, 50);
  QemOptions o;
  o.target_triangles = 500;
  Collected out;
  // The sequence builder does not promise a count.
  EXPECT_EQ(simplify(m, o, &out).code(), ErrorCode::kUsage);
  o.input_triangles = m.triangles.size();
  Collected out2;
  ASSERT_TRUE(simplify(m, o, &out2).ok());
  EXPECT_TRUE(within_one_percent(out2.triangles.size(), 500)) << out2.triangles.size();
  QemOptions none;
  Collected out3;
  EXPECT_EQ(simplify(m, none, &out3).code(), ErrorCode::kUsage);
  QemOptions bad;
  bad.ratio = 0.5;
  bad.candidates = 0;
  Collected out4;
  EXPECT_EQ(simplify(m, bad, &out4).code(), ErrorCode::kUsage);
}

TEST(StreamQem, PropertiesTravelWithTheirElements) {
  Mesh m = test::make_sphere(30, 40);
  m.schema.vertex_properties.push_back({"id", ScalarType::kUInt32});
  m.schema.face_properties.push_back({"tag", ScalarType::kUInt8});
  for (size_t v = 0; v < m.positions.size(); ++v) m.vertex_values[v] = {static_cast<double>(v)};
  for (size_t t = 0; t < m.triangles.size(); ++t) m.face_values[t] = {static_cast<double>(t % 7)};
  QemOptions o;
  o.ratio = 0.25;
  o.buffer_triangles = 500;
  Collected out;
  ASSERT_TRUE(simplify(m, o, &out).ok());
  ASSERT_EQ(out.schema.vertex_properties.size(), 1u);
  ASSERT_EQ(out.schema.face_properties.size(), 1u);
  std::set<double> ids;
  for (const PropertyValues& v : out.vertex_values) {
    ASSERT_EQ(v.size(), 1u);
    EXPECT_LT(v[0], m.positions.size());
    ids.insert(v[0]);
  }
  EXPECT_EQ(ids.size(), out.vertex_values.size());  // a merged vertex keeps one end's values
  for (const PropertyValues& f : out.face_values) {
    ASSERT_EQ(f.size(), 1u);
    EXPECT_LT(f[0], 7);
  }
}

Mesh subdivided_cube(int n);  // below, with the smoother's tests

// The face lists corner_uv and corner_normals (an OBJ's vt and vn, per
// corner) for each triangle of m, from functions of the position: the
// texture coordinates of `uv`, and `normal`, of corner k of triangle t.
template <class Uv, class Normal>
void add_corner_lists(Mesh* m, Uv uv, Normal normal) {
  m->schema.face_properties.push_back({"corner_uv", ScalarType::kFloat32, true, ScalarType::kUInt8});
  m->schema.face_properties.push_back({"corner_normals", ScalarType::kFloat32, true, ScalarType::kUInt8});
  for (size_t t = 0; t < m->triangles.size(); ++t) {
    PropertyValues f = {6};
    for (uint32_t k = 0; k < 3; ++k) {
      const std::array<double, 2> c = uv(t, k);
      f.insert(f.end(), c.begin(), c.end());
    }
    f.push_back(9);
    for (uint32_t k = 0; k < 3; ++k) {
      const Pos n = normal(t, k);
      f.insert(f.end(), n.begin(), n.end());
    }
    m->face_values[t] = f;
  }
}

// m simplified to `ratio` of its triangles in a buffer of 600.
Status simplify_in_600(const Mesh& m, double ratio, Collected* out) {
  QemOptions o;
  o.ratio = ratio;
  o.buffer_triangles = 600;
  return simplify(m, o, out);
}

// Longitude and latitude of a point of the unit sphere, as texture
// coordinates in [0, 1).
std::array<double, 2> lat_long(const Pos& p) {
  const double pi = 3.14159265358979323846;
  double u = std::atan2(p[1], p[0]) / (2 * pi);
  if (u < 0) u += 1;
  return {u, std::acos(std::max(-1.0, std::min(1.0, p[2]))) / pi};
}

// A globe's texture: one chart, cut along the meridian where u wraps
// from 1 to 0 (a seam: the corners of the triangles east of it have
// u near 1, those west near 0) and at the poles (a corner per triangle).
// After simplification, every corner still has its chart's coordinates at
// its vertex, and no triangle spans the texture (a torn seam would make
// one that does); the smooth normals stay those of the sphere.
TEST(StreamQem, CornerTexturesAndNormalsFollowTheirCharts) {
  Mesh m = test::make_sphere(30, 40);
  add_corner_lists(
      &m,
      [&](size_t t, uint32_t k) {
        std::array<double, 2> c[3];
        for (int i = 0; i < 3; ++i) c[i] = lat_long(m.positions[m.triangles[t][i]]);
        for (int i = 0; i < 3; ++i)  // east of the seam
          for (int j = 0; j < 3; ++j)
            if (c[j][0] - c[i][0] > 0.5) c[i][0] += 1;
        for (int i = 0; i < 3; ++i)  // a pole: the triangle's longitude
          if (std::abs(m.positions[m.triangles[t][i]][2]) == 1) c[i][0] = (c[(i + 1) % 3][0] + c[(i + 2) % 3][0]) / 2;
        return c[k];
      },
      [&](size_t t, uint32_t k) { return m.positions[m.triangles[t][k]]; });
  Collected out;
  ASSERT_TRUE(simplify_in_600(m, 0.2, &out).ok());
  EXPECT_LE(out.triangles.size(), m.triangles.size() / 4);
  ASSERT_EQ(out.schema.face_properties.size(), 2u);
  double worst_u = 0, worst_v = 0, worst_normal = 0, widest = 0;
  for (size_t t = 0; t < out.triangles.size(); ++t) {
    const PropertyValues& f = out.face_values[t];
    ASSERT_EQ(f.size(), 17u);
    double lo = 2, hi = -1;
    for (int k = 0; k < 3; ++k) {
      const Pos& p = out.positions[out.triangles[t][k]];
      const double r = std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
      const Pos unit = {p[0] / r, p[1] / r, p[2] / r};
      const std::array<double, 2> want = lat_long(unit);
      const double u = f[1 + 2 * k], v = f[2 + 2 * k];
      lo = std::min(lo, u);
      hi = std::max(hi, u);
      worst_v = std::max(worst_v, std::abs(v - want[1]) * 3.14159265358979323846);
      if (std::abs(unit[2]) < 0.99) {
        const double du = std::abs(u - want[0]);
        // In lengths on the sphere: a turn of longitude is 2 pi sin(latitude) long.
        worst_u = std::max(worst_u, std::min(du, std::abs(du - 1)) * 2 * 3.14159265358979323846 * std::sqrt(1 - unit[2] * unit[2]));
      }
      const double* n = &f[8 + 3 * k];
      const double dot = (n[0] * unit[0] + n[1] * unit[1] + n[2] * unit[2]) / std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
      worst_normal = std::max(worst_normal, std::acos(std::min(1.0, dot)));
    }
    widest = std::max(widest, hi - lo);
  }
  // Interpolated along chords of a curved chart: a tenth of an output
  // edge (about 0.25 long). Each triangle's own input values, kept as they
  // were, are off by a whole edge.
  EXPECT_LT(worst_u, 0.08);
  EXPECT_LT(worst_v, 0.08);
  EXPECT_LT(worst_normal, 0.02);
  EXPECT_LT(widest, 0.5);
}

// A cube of six charts, one a face, each face flat with its own normal
// (hard edges: every cube edge is a seam of both lists). The faces
// simplify to a few triangles each, and every corner keeps its face's
// normal and its face's planar texture coordinates exactly.
TEST(StreamQem, CornerSeamsAlongHardEdgesStay) {
  Mesh m = subdivided_cube(8);
  auto face_of = [&](size_t t) {
    const Pos& a = m.positions[m.triangles[t][0]];
    const Pos& b = m.positions[m.triangles[t][1]];
    const Pos& c = m.positions[m.triangles[t][2]];
    const Pos e1 = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, e2 = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    const Pos n = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
    int axis = 0;
    for (int i = 1; i < 3; ++i)
      if (std::abs(n[i]) > std::abs(n[axis])) axis = i;
    return 2 * axis + (n[axis] > 0 ? 1 : 0);
  };
  auto chart = [](int face, const Pos& p) {  // face f's chart: the plane's coordinates, moved to [2f, 2f + 1]
    const int axis = face / 2;
    return std::array<double, 2>{2.0 * face + p[(axis + 1) % 3], p[(axis + 2) % 3]};
  };
  auto normal = [](int face) {
    Pos n = {0, 0, 0};
    n[static_cast<size_t>(face / 2)] = face % 2 ? 1 : -1;
    return n;
  };
  add_corner_lists(
      &m, [&](size_t t, uint32_t k) { return chart(face_of(t), m.positions[m.triangles[t][k]]); },
      [&](size_t t, uint32_t) { return normal(face_of(t)); });
  QemOptions o;
  o.ratio = 0.1;
  Collected out;
  ASSERT_TRUE(simplify(m, o, &out).ok());
  EXPECT_LE(out.triangles.size(), m.triangles.size() / 8);
  for (size_t t = 0; t < out.triangles.size(); ++t) {
    const PropertyValues& f = out.face_values[t];
    ASSERT_EQ(f.size(), 17u);
    const int face = static_cast<int>(std::floor(f[1] / 2));
    ASSERT_GE(face, 0);
    ASSERT_LT(face, 6);
    for (int k = 0; k < 3; ++k) {
      const std::array<double, 2> want = chart(face, out.positions[out.triangles[t][k]]);
      EXPECT_NEAR(f[1 + 2 * k], want[0], 1e-5) << "triangle " << t << " corner " << k;
      EXPECT_NEAR(f[2 + 2 * k], want[1], 1e-5) << "triangle " << t << " corner " << k;
      for (int i = 0; i < 3; ++i) EXPECT_NEAR(f[8 + 3 * k + i], normal(face)[static_cast<size_t>(i)], 1e-6);
    }
  }
}

// A seam from the border into the grid that ends inside it: a slit along
// y = 1/2 for x < 1/2, across which v jumps by 2 (1/2 - x), closing at
// the slit's end (a single-valued vertex). No triangle may span the gap
// (a corner of the lower side beside one of the upper), and border
// vertices, the seam's end on the border too, stay on the border.
TEST(StreamQem, SeamThatEndsInsideAndMeetsTheBorder) {
  const int n = 40;
  Mesh m = bumpy_grid(n);
  auto gap = [](double x) { return std::max(0.0, 0.5 - x) * 2; };
  add_corner_lists(
      &m,
      [&](size_t t, uint32_t k) {
        double cy = 0;
        for (int i = 0; i < 3; ++i) cy += m.positions[m.triangles[t][i]][1] / (3.0 * n);
        const Pos& p = m.positions[m.triangles[t][k]];
        const double x = p[0] / n, y = p[1] / n;
        return std::array<double, 2>{x, cy > 0.5 ? y + gap(x) : y};
      },
      [&](size_t, uint32_t) { return Pos{0, 0, 1}; });
  Collected out;
  ASSERT_TRUE(simplify_in_600(m, 0.1, &out).ok());
  EXPECT_LE(out.triangles.size(), m.triangles.size() / 5);
  int torn = 0, lost = 0;
  for (size_t t = 0; t < out.triangles.size(); ++t) {
    bool lower = false, upper = false;
    for (int k = 0; k < 3; ++k) {
      const Pos& p = out.positions[out.triangles[t][k]];
      const double x = p[0] / n, y = p[1] / n, u = out.face_values[t][1 + 2 * k], v = out.face_values[t][2 + 2 * k];
      EXPECT_NEAR(u, x, 0.02);
      const double g = gap(x);
      if (g < 0.1) continue;  // near the slit's end (and the kink of v at x = 1/2)
      const bool l = std::abs(v - y) < g / 4, h = std::abs(v - y - g) < g / 4;
      lower = lower || l;
      upper = upper || h;
      lost += !l && !h;
    }
    torn += lower && upper;
  }
  EXPECT_EQ(torn, 0);
  EXPECT_EQ(lost, 0);
  for (uint32_t v : out.border_vertices) {
    const Pos& p = out.positions[v];
    const double d = std::min({std::fabs(p[0]), std::fabs(p[0] - n), std::fabs(p[1]), std::fabs(p[1] - n)});
    EXPECT_LT(d, 1e-3 * n) << p[0] << " " << p[1];
  }
}

// The events of a sequence into a TriangleBuffer's input side.
class IntoBuffer : public SequenceSink {
 public:
  explicit IntoBuffer(TriangleBuffer* b) : b_(b) {}
  Status begin(const MeshSchema& s) override { return b_->begin(s); }
  Status vertex(const SequenceVertex& v) override { return b_->vertex(v); }
  Status triangle(const SequenceTriangle& t) override {
    uint32_t id;
    return b_->triangle(t, &id);
  }
  Status finalize(uint32_t i) override { return b_->finalize(i); }
  Status finish() override { return Status(); }

 private:
  TriangleBuffer* b_;
};

// The wedge rule at the end of a seam: on a 4 x 4 grid slit along y = 2
// from the border to E = (2, 2), where the two sides' values meet again,
// E (one value) cannot merge into K = (1, 2) on the slit (two values): its
// corners above the slit would take K's value below it. Along the grid's
// middle, away from the slit, a merge is planned.
TEST(CornerValues, ASeamThatEndsAtTheMergedVertexIsRefused) {
  Mesh m = test::make_grid(4);
  add_corner_lists(
      &m,
      [&](size_t t, uint32_t k) {
        double cy = 0;
        for (int i = 0; i < 3; ++i) cy += m.positions[m.triangles[t][i]][1] / 3;
        const Pos& p = m.positions[m.triangles[t][k]];
        return std::array<double, 2>{p[0], cy > 2 ? p[1] + std::max(0.0, 2 - p[0]) : p[1]};
      },
      [&](size_t, uint32_t) { return Pos{0, 0, 1}; });
  Collected sink;
  TriangleBuffer buffer(&sink);
  IntoBuffer into(&buffer);
  ASSERT_TRUE(run(m, into).ok());
  detail::CornerValues corners;
  ASSERT_TRUE(corners.init(m.schema));
  auto vertex_at = [&](double x, double y) {
    for (uint32_t v = 0; v < buffer.vertex_capacity(); ++v)
      if (buffer.first_corner(v) != TriangleBuffer::kNone && buffer.position(v)[0] == x && buffer.position(v)[1] == y)
        return v;
    return TriangleBuffer::kNone;
  };
  auto edge = [&](uint32_t from, uint32_t to) {
    for (uint32_t c = buffer.first_corner(from); c != TriangleBuffer::kNone; c = buffer.next_corner(c))
      if (buffer.vertex_of(TriangleBuffer::next(c)) == to) return c;
    return TriangleBuffer::kNone;
  };
  const uint32_t e = vertex_at(2, 2), k = vertex_at(1, 2), r = vertex_at(3, 2), a = vertex_at(2, 3);
  ASSERT_NE(e, TriangleBuffer::kNone);
  ASSERT_NE(k, TriangleBuffer::kNone);
  EXPECT_FALSE(corners.seam_vertex(buffer, e));
  EXPECT_TRUE(corners.seam_vertex(buffer, k));
  uint32_t h = edge(e, k);
  if (h == TriangleBuffer::kNone) h = edge(k, e);
  ASSERT_NE(h, TriangleBuffer::kNone);
  EXPECT_TRUE(corners.seam_edge(buffer, h));
  const bool keep_start = buffer.vertex_of(h) == k;
  EXPECT_FALSE(corners.plan(buffer, h, keep_start, buffer.position(k)));
  // E into its neighbour R beyond the slit's end, at their midpoint.
  h = edge(e, r);
  if (h == TriangleBuffer::kNone) h = edge(r, e);
  ASSERT_NE(h, TriangleBuffer::kNone);
  EXPECT_FALSE(corners.seam_edge(buffer, h));
  const double mid[3] = {2.5, 2, 0};
  EXPECT_TRUE(corners.plan(buffer, h, buffer.vertex_of(h) == r, mid));
  // A above E: a vertex of the upper side only, its values one chart.
  EXPECT_FALSE(corners.seam_vertex(buffer, a));
}

// A recorded sequence as a pull source.
class Replay : public SequenceSource {
 public:
  Status begin(const MeshSchema& s) {
    schema_ = s;
    return Status();
  }
  const MeshSchema& schema() const override { return schema_; }
  Status next(SequenceEvent* e) override {
    if (at_ >= events.size()) {
      e->kind = SequenceEvent::Kind::kEnd;
      return Status();
    }
    *e = events[at_++];
    return Status();
  }
  std::vector<SequenceEvent> events;
  MeshSchema schema_;

 private:
  size_t at_ = 0;
};

class Record : public SequenceSink {
 public:
  explicit Record(Replay* r) : r_(r) {}
  Status begin(const MeshSchema& s) override { return r_->begin(s); }
  Status vertex(const SequenceVertex& v) override {
    SequenceEvent e;
    e.kind = SequenceEvent::Kind::kVertex;
    e.vertex = v;
    r_->events.push_back(e);
    return Status();
  }
  Status triangle(const SequenceTriangle& t) override {
    SequenceEvent e;
    e.kind = SequenceEvent::Kind::kTriangle;
    e.triangle = t;
    r_->events.push_back(e);
    return Status();
  }
  Status finalize(uint32_t i) override {
    SequenceEvent e;
    e.kind = SequenceEvent::Kind::kFinalize;
    e.finalized = i;
    r_->events.push_back(e);
    return Status();
  }
  Status finish() override { return Status(); }

 private:
  Replay* r_;
};

TEST(StreamQem, PullFromASourceAsFromPushes) {
  const Mesh m = test::make_torus(40, 20);
  Replay source;
  Record record(&source);
  ASSERT_TRUE(run(m, record).ok());
  QemOptions o;
  o.ratio = 0.3;
  o.buffer_triangles = 700;
  Collected pulled, pushed;
  QemReport r;
  ASSERT_TRUE(simplify_qem(source, pulled, o, &r).ok());
  ASSERT_TRUE(simplify(m, o, &pushed).ok());
  EXPECT_EQ(pulled.triangles, pushed.triangles);
  EXPECT_EQ(pulled.positions, pushed.positions);
  EXPECT_EQ(r.output_triangles, pulled.triangles.size());
}

// ---- Taubin smoothing.

Mesh noisy(const Mesh& clean, double amount, uint32_t seed) {
  Mesh m = clean;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-amount, amount);
  for (auto& p : m.positions) {
    const double f = 1 + u(rng);
    for (double& c : p) {
      volatile float r = static_cast<float>(c * f);
      c = r;
    }
  }
  return m;
}

double vertex_sphere_error(const Collected& c) {
  double sum = 0;
  for (const Pos& p : c.positions) {
    const double r = std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
    sum += (r - 1) * (r - 1);
  }
  return std::sqrt(sum / c.positions.size());
}

TEST(TaubinSmoother, ReducesNoiseOnAMeshLargerThanTheBuffer) {
  const Mesh clean = test::make_sphere(60, 80);
  const Mesh m = noisy(clean, 0.02, 5);
  Collected before;
  {
    SmoothOptions none;
    none.iterations = 0;
    TaubinSmoother s(&before, none);
    ASSERT_TRUE(run(m, s).ok());
    EXPECT_EQ(before.geometry().size(), m.triangles.size());
  }
  const double e0 = vertex_sphere_error(before);
  SmoothOptions o;
  o.iterations = 10;
  Collected whole, bounded, tiny;
  SmoothReport rw, rb, rt;
  {
    o.buffer_triangles = 1u << 28;
    TaubinSmoother s(&whole, o);
    ASSERT_TRUE(run(m, s).ok());
    rw = s.report();
  }
  {
    o.buffer_triangles = 3000;  // a fifth of the mesh, more than the band
    TaubinSmoother s(&bounded, o);
    ASSERT_TRUE(run(m, s).ok());
    rb = s.report();
  }
  {
    o.buffer_triangles = 300;
    TaubinSmoother s(&tiny, o);
    ASSERT_TRUE(run(m, s).ok());
    rt = s.report();
  }
  EXPECT_EQ(rw.stopped_vertices, 0u);
  EXPECT_EQ(rb.stopped_vertices, 0u);
  EXPECT_LE(rb.max_buffer_triangles, 3001u);
  EXPECT_EQ(rw.smoothed_vertices, m.positions.size() - 0);
  // Bounded but holding every neighbourhood: exactly the whole-mesh result.
  EXPECT_EQ(bounded.geometry(), whole.geometry());
  const double e_whole = vertex_sphere_error(whole);
  EXPECT_LT(e_whole, 0.5 * e0) << e_whole << " " << e0;
  // A buffer too small for the neighbourhoods: some vertices stop early,
  // the noise still drops.
  EXPECT_GT(rt.stopped_vertices, 0u);
  EXPECT_LT(vertex_sphere_error(tiny), 0.8 * e0);
  for (const Collected* c : {&whole, &bounded, &tiny}) {
    ASSERT_TRUE(c->finished);
    EXPECT_EQ(c->triangles.size(), m.triangles.size());
    EXPECT_EQ(c->checker.stats().components, 1u);
    EXPECT_EQ(c->checker.stats().border_edges, 0u);
  }
}

// A closed cube of n x n squares a face, outward: flat faces meet at
// creases.
Mesh subdivided_cube(int n) {
  std::map<std::array<int, 3>, uint32_t> index;
  std::vector<std::array<double, 3>> positions;
  std::vector<std::array<uint32_t, 3>> triangles;
  auto id = [&](const std::array<int, 3>& c) {
    auto it = index.find(c);
    if (it != index.end()) return it->second;
    const uint32_t i = static_cast<uint32_t>(positions.size());
    index[c] = i;
    positions.push_back({static_cast<double>(c[0]) / n, static_cast<double>(c[1]) / n, static_cast<double>(c[2]) / n});
    return i;
  };
  for (int axis = 0; axis < 3; ++axis)
    for (int side = 0; side < 2; ++side)
      for (int a = 0; a < n; ++a)
        for (int b = 0; b < n; ++b) {
          auto at = [&](int u, int v) {
            std::array<int, 3> c;
            c[axis] = side * n;
            c[(axis + 1) % 3] = u;
            c[(axis + 2) % 3] = v;
            return id(c);
          };
          const uint32_t p00 = at(a, b), p10 = at(a + 1, b), p11 = at(a + 1, b + 1), p01 = at(a, b + 1);
          if (side == 1) {
            triangles.push_back({p00, p10, p11});
            triangles.push_back({p00, p11, p01});
          } else {
            triangles.push_back({p00, p11, p10});
            triangles.push_back({p00, p01, p11});
          }
        }
  return test::make_mesh(positions, triangles);
}

TEST(TaubinSmoother, VerticesStayInTheInputsBox) {
  // The output's quantization grid is the input's box. Next to a crease,
  // a vertex of a flat face keeps its place in the lambda step while its
  // neighbours on the crease move in; the mu step then pushes it past the
  // face, and it must stay on it.
  const Mesh m = subdivided_cube(12);
  SmoothOptions o;
  o.iterations = 4;
  Collected out;
  TaubinSmoother s(&out, o);
  ASSERT_TRUE(run(m, s).ok());
  ASSERT_TRUE(out.schema.has_bounds);
  ASSERT_EQ(out.positions.size(), m.positions.size());
  for (const Pos& p : out.positions)
    for (int i = 0; i < 3; ++i) {
      EXPECT_GE(p[i], out.schema.bounds_min[i]);
      EXPECT_LE(p[i], out.schema.bounds_max[i]);
    }
}

TEST(TaubinSmoother, BorderVerticesStay) {
  const int n = 30;
  Mesh m = noisy(bumpy_grid(n), 0.01, 3);
  SmoothOptions o;
  o.buffer_triangles = 400;
  Collected out;
  TaubinSmoother s(&out, o);
  ASSERT_TRUE(run(m, s).ok());
  std::set<Pos> border_in, border_out;
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i)
      if (i == 0 || j == 0 || i == n || j == n) border_in.insert(m.positions[j * (n + 1) + i]);
  for (uint32_t v : out.border_vertices) border_out.insert(out.positions[v]);
  EXPECT_EQ(border_in, border_out);
  EXPECT_EQ(out.triangles.size(), m.triangles.size());
}

// ---- psq simplify --method qem and psq smooth.

std::string write_ply(const test::TempDir& dir, const std::string& name, const Mesh& m) {
  OutputFile out;
  EXPECT_TRUE(out.open(dir.file(name), false).ok());
  PlyWriter w(&out);
  test::MemorySource src(m);
  EXPECT_TRUE(pump(src, w).ok());
  EXPECT_TRUE(out.commit().ok());
  return dir.file(name);
}

TEST(QemCli, PsqToPsqDeterministicThroughPipesToo) {
  test::TempDir dir;
  const std::string ply = write_ply(dir, "torus.ply", test::make_torus(120, 40));
  std::string out, err;
  ASSERT_EQ(test::run_psq("convert " + ply + " " + dir.file("in.psq"), &out, &err), 0) << err;
  ASSERT_EQ(test::run_psq("simplify --method qem " + dir.file("in.psq") + " " + dir.file("a.psq") + " --ratio 10% --buffer 2000 --json",
                          &out, &err),
            0)
      << err;
  EXPECT_NE(out.find("\"output_triangles\": "), std::string::npos) << out;
  EXPECT_NE(out.find("\"target_triangles\": 960"), std::string::npos) << out;
  EXPECT_TRUE(err.empty()) << err;
  ASSERT_EQ(test::run_psq("verify " + dir.file("a.psq"), &out, &err), 0) << err;
  ASSERT_EQ(test::run_psq("simplify --method qem " + dir.file("in.psq") + " " + dir.file("b.psq") + " --ratio 0.1 --buffer 2000", &out,
                          &err),
            0);
  EXPECT_EQ(test::read_file(dir.file("a.psq")), test::read_file(dir.file("b.psq")));
  // Standard input to standard output: the same bytes.
  ASSERT_EQ(test::run_psq("simplify --method qem - - --to psq --ratio 0.1 --buffer 2000", &out, &err, dir.file("in.psq")), 0) << err;
  EXPECT_EQ(out, test::read_file(dir.file("a.psq")));
  // The result as a mesh: a closed torus still.
  Mesh result;
  ASSERT_TRUE(test::load_mesh(dir.file("a.psq"), &result).ok());
  EXPECT_TRUE(within_one_percent(result.triangles.size(), 960)) << result.triangles.size();
  ASSERT_EQ(test::run_psq("simplify --method qem " + ply + " " + dir.file("c.ply") + " --triangles 1000", &out, &err), 0) << err;
  ASSERT_TRUE(test::load_mesh(dir.file("c.ply"), &result).ok());
  EXPECT_TRUE(within_one_percent(result.triangles.size(), 1000)) << result.triangles.size();
  // A .psq file without a declared count is counted first; from a pipe it cannot be.
  ASSERT_EQ(test::run_psq("simplify --method qem " + dir.file("in.psq") + " " + dir.file("d.psq") + " --triangles 2k", &out, &err), 0)
      << err;
  ASSERT_TRUE(test::load_mesh(dir.file("d.psq"), &result).ok());
  EXPECT_TRUE(within_one_percent(result.triangles.size(), 2000)) << result.triangles.size();
  EXPECT_EQ(test::run_psq("simplify --method qem - " + dir.file("e.psq") + " --triangles 2k", &out, &err, dir.file("in.psq")), 2);
  EXPECT_NE(err.find("--ratio"), std::string::npos) << err;
  EXPECT_FALSE(test::file_exists(dir.file("e.psq")));
}

TEST(QemCli, UsageAndDataErrors) {
  test::TempDir dir;
  const std::string ply = write_ply(dir, "s.ply", test::make_sphere(10, 12));
  std::string out, err;
  EXPECT_EQ(test::run_psq("simplify --method qem " + ply + " " + dir.file("o.psq"), &out, &err), 2);  // no target
  EXPECT_NE(err.find("target"), std::string::npos);
  EXPECT_EQ(test::run_psq("simplify --method qem " + ply + " " + dir.file("o.psq") + " --ratio 0", &out, &err), 2);
  EXPECT_EQ(test::run_psq("simplify --method qem " + ply + " " + dir.file("o.psq") + " --ratio 2", &out, &err), 2);
  EXPECT_EQ(test::run_psq("simplify --method qem " + ply + " " + dir.file("o.psq") + " --ratio 0.5 --candidates 0", &out, &err), 2);
  EXPECT_EQ(test::run_psq("simplify --method qem " + ply + " " + dir.file("o.xyz") + " --ratio 0.5", &out, &err), 2);
  EXPECT_EQ(test::run_psq("simplify --method qem " + ply + " " + ply + " --ratio 0.5", &out, &err), 2);
  EXPECT_EQ(test::run_psq("smooth " + ply + " " + dir.file("o.psq") + " --iterations 300", &out, &err), 2);
  EXPECT_EQ(test::run_psq("smooth " + ply + " " + dir.file("o.psq") + " --mu 0.5", &out, &err), 2);
  EXPECT_FALSE(test::file_exists(dir.file("o.psq")));
  // Not a mesh: one line, exit 1, no output left behind.
  test::write_file(dir.file("junk.psq"), std::string("PSQ\x89\r\n\x1a\n") + std::string(100, '\x07'));
  EXPECT_EQ(test::run_psq("simplify --method qem " + dir.file("junk.psq") + " " + dir.file("o.psq") + " --ratio 0.5", &out, &err), 1);
  EXPECT_EQ(err.rfind("psq: error: ", 0), 0u) << err;
  EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;
  EXPECT_FALSE(test::file_exists(dir.file("o.psq")));
  // An existing output needs -f.
  test::write_file(dir.file("exists.ply"), "x");
  EXPECT_NE(test::run_psq("simplify --method qem " + ply + " " + dir.file("exists.ply") + " --ratio 0.5", &out, &err), 0);
  EXPECT_EQ(test::read_file(dir.file("exists.ply")), "x");
  EXPECT_EQ(test::run_psq("simplify --method qem " + ply + " " + dir.file("exists.ply") + " --ratio 0.5 -f", &out, &err), 0) << err;
}

TEST(QemCli, LockBorderAndSmooth) {
  test::TempDir dir;
  const int n = 30;
  const std::string ply = write_ply(dir, "g.ply", bumpy_grid(n));
  std::string out, err;
  ASSERT_EQ(test::run_psq("simplify --method qem " + ply + " " + dir.file("l.ply") + " --ratio 0.2 --lock-border", &out, &err), 0) << err;
  Mesh in, locked;
  ASSERT_TRUE(test::load_mesh(ply, &in).ok());
  ASSERT_TRUE(test::load_mesh(dir.file("l.ply"), &locked).ok());
  std::set<Pos> border_in, kept;
  for (const Pos& p : in.positions)
    if (p[0] == 0 || p[0] == n || p[1] == 0 || p[1] == n) border_in.insert(p);
  for (const Pos& p : locked.positions)
    if (border_in.count(p)) kept.insert(p);
  EXPECT_EQ(kept, border_in);
  // Smoothing a noisy sphere brings it closer to the sphere, in a buffer
  // smaller than the mesh.
  const Mesh clean = test::make_sphere(60, 80);
  const std::string noisy_ply = write_ply(dir, "n.ply", noisy(clean, 0.02, 9));
  ASSERT_EQ(test::run_psq("smooth " + noisy_ply + " " + dir.file("s.psq") + " --lossless --buffer 3000 --json", &out,
                          &err),
            0)
      << err;
  EXPECT_NE(out.find("\"stopped_vertices\": 0"), std::string::npos) << out;
  Mesh smoothed, rough;
  ASSERT_TRUE(test::load_mesh(dir.file("s.psq"), &smoothed).ok());
  ASSERT_TRUE(test::load_mesh(noisy_ply, &rough).ok());
  auto error = [](const Mesh& m) {
    double sum = 0;
    for (const Pos& p : m.positions) {
      const double r = std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
      sum += (r - 1) * (r - 1);
    }
    return std::sqrt(sum / m.positions.size());
  };
  EXPECT_EQ(smoothed.triangles.size(), rough.triangles.size());
  EXPECT_LT(error(smoothed), 0.5 * error(rough));
}

}  // namespace
}  // namespace psq
