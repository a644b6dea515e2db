// SPDX-License-Identifier: Apache-2.0
// psq distance (psq/distance.h): analytic cases, an independent brute-force
// measure of the same samples, the streaming path against the all-in-memory
// one, determinism, degenerate and hostile input, and the CLI.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <random>
#include <regex>
#include <string>
#include <vector>

#include "psq/distance.h"
#include "psq/ply.h"
#include "test_util.h"

namespace psq {
namespace {

using test::Mesh;
using P3 = std::array<double, 3>;

// ------------------------------------------------------------- meshes

Mesh translated(Mesh m, double dx, double dy, double dz) {
  for (auto& p : m.positions) p = {p[0] + dx, p[1] + dy, p[2] + dz};
  m.schema.position_type = ScalarType::kFloat64;
  return m;
}

// The icosahedron inscribed in the unit sphere.
Mesh icosahedron() {
  const double t = (1 + std::sqrt(5.0)) / 2;
  std::vector<P3> v = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0}, {0, -1, t}, {0, 1, t},
                       {0, -1, -t}, {0, 1, -t}, {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
  for (P3& p : v) {
    double l = std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
    p = {p[0] / l, p[1] / l, p[2] / l};
  }
  std::vector<std::array<uint32_t, 3>> f = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                                            {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                                            {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                                            {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
  Mesh m = test::make_mesh(v, f);
  m.schema.position_type = ScalarType::kFloat64;
  return m;
}

// A geodesic sphere: each face of the icosahedron cut into k^2 triangles,
// every vertex pushed onto the unit sphere. For k divisible by 3 it has a
// vertex in the direction of every face centre of the icosahedron.
Mesh geodesic_sphere(int k) {
  Mesh ico = icosahedron();
  std::vector<P3> pos;
  std::vector<std::array<uint32_t, 3>> tris;
  for (const auto& f : ico.triangles) {
    const P3 &a = ico.positions[f[0]], &b = ico.positions[f[1]], &c = ico.positions[f[2]];
    auto index = [&](int i, int j) {  // lattice point a + i/k (b - a) + j/k (c - a)
      return static_cast<uint32_t>(pos.size() - (k + 1) * (k + 2) / 2 + i * (k + 1) - i * (i - 1) / 2 + j);
    };
    for (int i = 0; i <= k; ++i) {
      for (int j = 0; i + j <= k; ++j) {
        const int l = k - i - j;
        P3 p;
        for (int d = 0; d < 3; ++d) p[d] = (l * a[d] + i * b[d] + j * c[d]) / k;
        double n = std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
        pos.push_back({p[0] / n, p[1] / n, p[2] / n});
      }
    }
    for (int i = 0; i < k; ++i) {
      for (int j = 0; i + j < k; ++j) {
        tris.push_back({index(i, j), index(i + 1, j), index(i, j + 1)});
        if (i + j + 1 < k) tris.push_back({index(i + 1, j), index(i + 1, j + 1), index(i, j + 1)});
      }
    }
  }
  Mesh m = test::make_mesh(pos, tris);
  m.schema.position_type = ScalarType::kFloat64;
  return m;
}

// A bumpy sphere: each vertex moved along its direction by a fixed pattern.
Mesh bumpy_sphere(int rings, int segments, double amp) {
  Mesh m = test::make_sphere(rings, segments);
  for (auto& p : m.positions) {
    double r = 1 + amp * std::sin(5 * p[0]) * std::cos(3 * p[1] + p[2]);
    p = {p[0] * r, p[1] * r, p[2] * r};
  }
  m.schema.position_type = ScalarType::kFloat64;
  return m;
}

DistanceResult measure(const Mesh& a, const Mesh& b, DistanceOptions o = DistanceOptions()) {
  test::MemorySource sa(a), sb(b);
  DistanceResult r;
  Status s = measure_distance(sa, sb, o, &r);
  EXPECT_TRUE(s.ok()) << s.to_string();
  return r;
}

DistanceOptions with(DistanceHold hold, int threads = 0, uint64_t samples = 0, uint64_t seed = 1) {
  DistanceOptions o;
  o.hold = hold;
  o.threads = threads;
  o.samples = samples;
  o.seed = seed;
  return o;
}

// Every number of a result but the time and the held flags, bit for bit.
void expect_same(const DistanceResult& x, const DistanceResult& y) {
  for (auto [d, e] : {std::pair{&x.a_to_b, &y.a_to_b}, std::pair{&x.b_to_a, &y.b_to_a}}) {
    EXPECT_EQ(d->samples, e->samples);
    EXPECT_EQ(d->vertex_samples, e->vertex_samples);
    EXPECT_EQ(d->max, e->max);
    EXPECT_EQ(d->mean, e->mean);
    EXPECT_EQ(d->rms, e->rms);
  }
  EXPECT_EQ(x.hausdorff, y.hausdorff);
  EXPECT_EQ(x.diagonal, y.diagonal);
  EXPECT_EQ(x.a.area, y.a.area);
  EXPECT_EQ(x.b.area, y.b.area);
}

// --------------------------------------------------- an independent measure

// Closest point on a triangle by Voronoi regions in barycentric form
// (vertex, edge and face regions tested in turn): another way than the
// library's plane-and-edges test.
double reference_d2(const P3& p, const P3& a, const P3& b, const P3& c) {
  auto sub = [](const P3& u, const P3& v) { return P3{u[0] - v[0], u[1] - v[1], u[2] - v[2]}; };
  auto dot = [](const P3& u, const P3& v) { return u[0] * v[0] + u[1] * v[1] + u[2] * v[2]; };
  auto d2 = [&](const P3& q) {
    P3 d = sub(p, q);
    return dot(d, d);
  };
  auto lerp = [](const P3& u, const P3& v, double t) {
    return P3{u[0] + t * (v[0] - u[0]), u[1] + t * (v[1] - u[1]), u[2] + t * (v[2] - u[2])};
  };
  auto seg = [&](const P3& u, const P3& v) {
    P3 uv = sub(v, u);
    double l = dot(uv, uv), t = l > 0 ? std::clamp(dot(sub(p, u), uv) / l, 0.0, 1.0) : 0;
    return d2(lerp(u, v, t));
  };
  P3 ab = sub(b, a), ac = sub(c, a), ap = sub(p, a);
  // A segment or a point (the region tests below divide by zero): its edges.
  P3 n = {ab[1] * ac[2] - ab[2] * ac[1], ab[2] * ac[0] - ab[0] * ac[2], ab[0] * ac[1] - ab[1] * ac[0]};
  if (dot(n, n) <= 1e-24 * dot(ab, ab) * dot(ac, ac)) return std::min({seg(a, b), seg(b, c), seg(c, a)});
  double d1 = dot(ab, ap), d2v = dot(ac, ap);
  if (d1 <= 0 && d2v <= 0) return d2(a);
  P3 bp = sub(p, b);
  double d3 = dot(ab, bp), d4 = dot(ac, bp);
  if (d3 >= 0 && d4 <= d3) return d2(b);
  double vc = d1 * d4 - d3 * d2v;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return d2(lerp(a, b, d1 / (d1 - d3)));
  P3 cp = sub(p, c);
  double d5 = dot(ab, cp), d6 = dot(ac, cp);
  if (d6 >= 0 && d5 <= d6) return d2(c);
  double vb = d5 * d2v - d1 * d6;
  if (vb <= 0 && d2v >= 0 && d6 <= 0) return d2(lerp(a, c, d2v / (d2v - d6)));
  double va = d3 * d6 - d5 * d4;
  if (va <= 0 && d4 - d3 >= 0 && d5 - d6 >= 0) return d2(lerp(b, c, (d4 - d3) / ((d4 - d3) + (d5 - d6))));
  double den = va + vb + vc;
  double v = vb / den, w = vc / den;
  return d2(P3{a[0] + ab[0] * v + ac[0] * w, a[1] + ab[1] * v + ac[1] * w, a[2] + ab[2] * v + ac[2] * w});
}

struct Stats {
  double max = 0, mean = 0, rms = 0;
};

// Every point against every triangle.
Stats brute_force(const std::vector<double>& pts, const Mesh& m) {
  Stats s;
  double sum = 0, sq = 0;
  const size_t n = pts.size() / 3;
  for (size_t i = 0; i < n; ++i) {
    P3 p = {pts[3 * i], pts[3 * i + 1], pts[3 * i + 2]};
    double best = INFINITY;
    for (const auto& t : m.triangles)
      best = std::min(best, reference_d2(p, m.positions[t[0]], m.positions[t[1]], m.positions[t[2]]));
    s.max = std::max(s.max, std::sqrt(best));
    sum += std::sqrt(best);
    sq += best;
  }
  s.mean = sum / n;
  s.rms = std::sqrt(sq / n);
  return s;
}

// Uniform points by area, drawn independently of the library's sampler.
std::vector<double> own_samples(const Mesh& m, size_t n, uint32_t seed) {
  std::vector<double> cum;
  double total = 0;
  for (const auto& t : m.triangles) {
    const P3 &a = m.positions[t[0]], &b = m.positions[t[1]], &c = m.positions[t[2]];
    P3 u = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, v = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    P3 x = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
    total += 0.5 * std::sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]);
    cum.push_back(total);
  }
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> U(0, 1);
  std::vector<double> out;
  for (size_t i = 0; i < n; ++i) {
    size_t t = std::lower_bound(cum.begin(), cum.end(), U(rng) * total) - cum.begin();
    t = std::min(t, cum.size() - 1);
    double r1 = std::sqrt(U(rng)), r2 = U(rng);
    const auto& f = m.triangles[t];
    for (int d = 0; d < 3; ++d) {
      out.push_back((1 - r1) * m.positions[f[0]][d] + r1 * (1 - r2) * m.positions[f[1]][d] +
                    r1 * r2 * m.positions[f[2]][d]);
    }
  }
  return out;
}

std::vector<double> samples_of(const Mesh& m, uint64_t n, uint64_t seed = 1) {
  test::MemorySource src(m);
  std::vector<double> xyz;
  EXPECT_TRUE(sample_surface(src, n, seed, &xyz).ok());
  return xyz;
}

// --------------------------------------------------------------- analytic

TEST(Distance, PlaneAndTheSamePlaneMoved) {
  Mesh a = test::make_grid(24);
  for (double d : {0.125, 0.1, 3.0}) {
    Mesh b = translated(a, 0, 0, d);
    for (DistanceHold hold : {DistanceHold::kBoth, DistanceHold::kA, DistanceHold::kB}) {
      DistanceResult r = measure(a, b, with(hold, 2, 20000));
      for (const DirectionDistance* x : {&r.a_to_b, &r.b_to_a}) {
        EXPECT_NEAR(x->max, d, 1e-14 * d);
        EXPECT_NEAR(x->mean, d, 1e-14 * d);
        EXPECT_NEAR(x->rms, d, 1e-14 * d);
        EXPECT_EQ(x->vertex_samples, 25u * 25u);
        EXPECT_NEAR(static_cast<double>(x->samples), 20000.0, 1.0);
      }
      EXPECT_NEAR(r.hausdorff, d, 1e-14 * d);
    }
  }
}

TEST(Distance, SphereAgainstItsInscribedIcosahedron) {
  Mesh ico = icosahedron();
  // The icosahedron's inradius: the distance from the centre to a face's centroid.
  const auto& f = ico.triangles[0];
  double c[3];
  for (int d = 0; d < 3; ++d)
    c[d] = (ico.positions[f[0]][d] + ico.positions[f[1]][d] + ico.positions[f[2]][d]) / 3;
  const double inradius = std::sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
  EXPECT_NEAR(inradius, 0.7946544722917661, 1e-15);
  // The sphere's point farthest from the icosahedron lies over a face
  // centre, 1 - inradius away; a geodesic sphere of frequency 3m has a
  // vertex there, and its other points are inside the unit sphere, so no
  // nearer to the icosahedron's inscribed ball.
  Mesh sphere = geodesic_sphere(24);
  for (DistanceHold hold : {DistanceHold::kBoth, DistanceHold::kA, DistanceHold::kB}) {
    DistanceResult r = measure(sphere, ico, with(hold));
    EXPECT_NEAR(r.a_to_b.max, 1 - inradius, 1e-13);
    EXPECT_LT(r.a_to_b.mean, r.a_to_b.rms);
    EXPECT_LT(r.a_to_b.rms, r.a_to_b.max);
    // The icosahedron is inside the sphere: its vertices on it, its face
    // centres 1 - inradius below it, nearer to the flat facets around.
    EXPECT_LT(r.b_to_a.max, 1 - inradius);
    EXPECT_GT(r.b_to_a.max, 0.9 * (1 - inradius));
    EXPECT_EQ(r.hausdorff, r.a_to_b.max);
    EXPECT_NEAR(r.diagonal, 2 * std::sqrt(3.0) * sphere.positions[0][1], 1.0);  // about 2 sqrt(3) * 1
  }
}

TEST(Distance, AMeshAgainstItselfIsZero) {
  for (const Mesh& m : {test::make_sphere(20, 32), bumpy_sphere(30, 40, 0.2), geodesic_sphere(9)}) {
    for (DistanceHold hold : {DistanceHold::kBoth, DistanceHold::kB}) {
      DistanceResult r = measure(m, m, with(hold));
      EXPECT_EQ(r.a_to_b.max, 0);
      EXPECT_EQ(r.b_to_a.max, 0);
      EXPECT_EQ(r.a_to_b.rms, 0);
      EXPECT_EQ(r.hausdorff, 0);
      EXPECT_GT(r.a_to_b.samples, m.triangles.size());
    }
  }
}

// ------------------------------------------------- against a reference

TEST(Distance, SameSamplesMeasuredByBruteForce) {
  Mesh a = bumpy_sphere(16, 24, 0.15), b = test::make_sphere(11, 17);
  for (DistanceHold hold : {DistanceHold::kBoth, DistanceHold::kA, DistanceHold::kB}) {
    DistanceResult r = measure(a, b, with(hold, 2, 6000, 7));
    Stats ab = brute_force(samples_of(a, 6000, 7), b), ba = brute_force(samples_of(b, 6000, 7), a);
    EXPECT_NEAR(r.a_to_b.max, ab.max, 1e-12);
    EXPECT_NEAR(r.a_to_b.mean, ab.mean, 1e-12);
    EXPECT_NEAR(r.a_to_b.rms, ab.rms, 1e-12);
    EXPECT_NEAR(r.b_to_a.max, ba.max, 1e-12);
    EXPECT_NEAR(r.b_to_a.mean, ba.mean, 1e-12);
    EXPECT_NEAR(r.b_to_a.rms, ba.rms, 1e-12);
  }
}

TEST(Distance, PointsAroundTrianglesOfEveryShape) {
  // B: triangles acute, obtuse, right, a needle, a cap (nearly a segment),
  // collinear, a point and an edge, each with its corners in the three
  // rotations, at heights 0, 2 and 4.
  const std::vector<P3> corners = {{0, 0, 0}, {1, 0, 0}, {0.4, 0.8, 0},            // acute
                                   {3, 0, 0}, {5, 0, 0.1}, {3.6, 0.3, 0},          // obtuse (about 150 degrees)
                                   {0, 3, 0}, {1, 3, 0}, {0, 4, 1},                // right
                                   {-3, 0, 0}, {-1, 0.01, 0}, {-1, -0.01, 0.002},  // needle
                                   {-3, 3, 0}, {-1, 3, 0}, {-2, 3.0001, 0},        // cap
                                   {2, 3, 0}, {3, 3, 0}, {4, 3, 0},                // collinear
                                   {0, -3, 0}, {0, -3, 0}, {0, -3, 0},             // a point
                                   {2, -3, 1}, {3, -3, 1}, {2, -3, 1}};            // an edge
  std::vector<P3> bpos;
  std::vector<std::array<uint32_t, 3>> btris;
  for (int rot = 0; rot < 3; ++rot) {
    for (size_t t = 0; t < corners.size() / 3; ++t) {
      const uint32_t base = static_cast<uint32_t>(bpos.size());
      for (int k = 0; k < 3; ++k) {
        const P3& c = corners[3 * t + (k + rot) % 3];
        bpos.push_back({c[0], c[1], c[2] + 2 * rot});
      }
      btris.push_back({base, base + 1, base + 2});
    }
  }
  Mesh b = test::make_mesh(bpos, btris);
  b.schema.position_type = ScalarType::kFloat64;
  // A: one tiny triangle at each of many random points; its samples are its
  // vertices only.
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> U(-5, 6);
  std::vector<P3> pos;
  std::vector<std::array<uint32_t, 3>> tris;
  for (uint32_t i = 0; i < 4000; ++i) {
    P3 p = {U(rng), U(rng), U(rng) * 0.6 + 1.5};
    pos.push_back(p);
    pos.push_back({p[0] + 1e-3, p[1], p[2]});
    pos.push_back({p[0], p[1] + 1e-3, p[2]});
    tris.push_back({3 * i, 3 * i + 1, 3 * i + 2});
  }
  Mesh a = test::make_mesh(pos, tris);
  a.schema.position_type = ScalarType::kFloat64;
  Stats ref = brute_force(samples_of(a, 1), b);
  for (DistanceHold hold : {DistanceHold::kBoth, DistanceHold::kB, DistanceHold::kA}) {
    DistanceResult r = measure(a, b, with(hold, 2, 1));
    EXPECT_EQ(r.a_to_b.samples, 12000u);
    EXPECT_NEAR(r.a_to_b.max, ref.max, 1e-12);
    EXPECT_NEAR(r.a_to_b.mean, ref.mean, 1e-12);
    EXPECT_NEAR(r.a_to_b.rms, ref.rms, 1e-12);
  }
}

TEST(Distance, AgreesWithIndependentSampling) {
  // Far apart and overlapping; an independent sampler with many points.
  Mesh a = bumpy_sphere(14, 20, 0.25), b = translated(test::make_sphere(9, 13), 0.3, -0.2, 0.1);
  DistanceResult r = measure(a, b, with(DistanceHold::kB, 2, 400000));
  Stats ab = brute_force(own_samples(a, 160000, 3), b), ba = brute_force(own_samples(b, 160000, 4), a);
  EXPECT_NEAR(r.a_to_b.mean, ab.mean, 0.01 * ab.mean);
  EXPECT_NEAR(r.a_to_b.rms, ab.rms, 0.01 * ab.rms);
  EXPECT_NEAR(r.b_to_a.mean, ba.mean, 0.01 * ba.mean);
  EXPECT_NEAR(r.b_to_a.rms, ba.rms, 0.01 * ba.rms);
  // The maxima: the library's samples include the vertices and are denser.
  EXPECT_GE(r.a_to_b.max, ab.max * 0.99);
  EXPECT_LE(r.a_to_b.max, ab.max * 1.05);
  EXPECT_GE(r.b_to_a.max, ba.max * 0.99);
  EXPECT_LE(r.b_to_a.max, ba.max * 1.05);
}

TEST(Distance, SamplesAreVerticesThenPointsOnTriangles) {
  Mesh m = test::make_sphere(8, 12);
  std::vector<double> s = samples_of(m, 1000);
  ASSERT_NEAR(s.size() / 3.0, 1000.0, 1.0);
  for (size_t v = 0; v < m.positions.size(); ++v) {
    EXPECT_EQ(s[3 * v], m.positions[v][0]);
    EXPECT_EQ(s[3 * v + 2], m.positions[v][2]);
  }
  // Every point lies on the mesh.
  Stats st = brute_force(s, m);
  EXPECT_LT(st.max, 1e-15);
  // Fewer requested than vertices: the vertices alone.
  EXPECT_EQ(samples_of(m, 10).size() / 3, m.positions.size());
  // The default: 10 per triangle.
  EXPECT_NEAR(samples_of(m, 0).size() / 3.0, 10.0 * m.triangles.size(), 1.0);
  // Another seed, other points; the same seed, the same points.
  EXPECT_NE(samples_of(m, 1000, 2), s);
  EXPECT_EQ(samples_of(m, 1000, 1), s);
}

TEST(Distance, NearestTriangles) {
  Mesh m = bumpy_sphere(18, 26, 0.2);
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> U(-1.6, 1.6);
  std::vector<double> pts;
  for (int i = 0; i < 3000; ++i) pts.insert(pts.end(), {U(rng), U(rng), U(rng)});
  // Points on the mesh too: its vertices.
  for (int i = 0; i < 50; ++i) pts.insert(pts.end(), m.positions[7 * i].begin(), m.positions[7 * i].end());
  std::vector<NearestTriangle> one, three;
  for (auto [threads, out] : {std::pair{1, &one}, std::pair{3, &three}}) {
    test::MemorySource src(m);
    ASSERT_TRUE(nearest_triangles(src, pts, with(DistanceHold::kAuto, threads), out).ok());
  }
  ASSERT_EQ(one.size(), pts.size() / 3);
  for (size_t i = 0; i < one.size(); ++i) {
    P3 p = {pts[3 * i], pts[3 * i + 1], pts[3 * i + 2]};
    double best = INFINITY;
    for (const auto& t : m.triangles)
      best = std::min(best, reference_d2(p, m.positions[t[0]], m.positions[t[1]], m.positions[t[2]]));
    ASSERT_LT(one[i].triangle, m.triangles.size());
    const auto& t = m.triangles[one[i].triangle];
    const P3 &a = m.positions[t[0]], &b = m.positions[t[1]], &c = m.positions[t[2]];
    EXPECT_NEAR(one[i].distance, std::sqrt(best), 1e-12);
    EXPECT_NEAR(std::sqrt(reference_d2(p, a, b, c)), std::sqrt(best), 1e-12);
    P3 u = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, v = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    P3 n = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
    double len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(one[i].normal[k], n[k] / len, 1e-12);
    EXPECT_EQ(one[i].triangle, three[i].triangle);
    EXPECT_EQ(one[i].distance, three[i].distance);
  }
  for (size_t i = 3000; i < one.size(); ++i) EXPECT_EQ(one[i].distance, 0);
  // Bad points and an empty mesh.
  test::MemorySource src(m);
  EXPECT_EQ(nearest_triangles(src, {1, 2}, DistanceOptions(), &one).code(), ErrorCode::kUsage);
  test::MemorySource src2(m);
  EXPECT_EQ(nearest_triangles(src2, {1, 2, NAN}, DistanceOptions(), &one).code(), ErrorCode::kUsage);
  test::MemorySource none(test::make_mesh({{0, 0, 0}}, {}));
  EXPECT_EQ(nearest_triangles(none, {1, 2, 3}, DistanceOptions(), &one).code(), ErrorCode::kBadValue);
}

// ------------------------------------------------ streaming and determinism

TEST(Distance, StreamingGivesTheAllInMemoryNumbers) {
  const std::vector<std::pair<Mesh, Mesh>> pairs = {
      {bumpy_sphere(30, 44, 0.1), test::make_sphere(12, 18)},
      {test::make_sphere(25, 31), translated(bumpy_sphere(9, 11, 0.3), 2.5, 0.5, 0)},  // far apart
      {test::make_grid(40), translated(geodesic_sphere(6), 0.5, 0.5, 0.2)},
  };
  for (const auto& [a, b] : pairs) {
    DistanceResult mem = measure(a, b, with(DistanceHold::kBoth, 2));
    EXPECT_TRUE(mem.a.held && mem.b.held);
    DistanceResult ha = measure(a, b, with(DistanceHold::kA, 2));
    EXPECT_TRUE(ha.a.held && !ha.b.held);
    DistanceResult hb = measure(a, b, with(DistanceHold::kB, 2));
    EXPECT_TRUE(!hb.a.held && hb.b.held);
    expect_same(mem, ha);
    expect_same(mem, hb);
    EXPECT_GT(mem.hausdorff, 0);
  }
}

TEST(Distance, SameNumbersForEveryThreadCountAndRun) {
  Mesh a = bumpy_sphere(40, 60, 0.05), b = test::make_sphere(15, 21);
  for (DistanceHold hold : {DistanceHold::kBoth, DistanceHold::kB, DistanceHold::kA}) {
    DistanceResult one = measure(a, b, with(hold, 1, 50000));
    for (int t : {2, 3, 8}) expect_same(one, measure(a, b, with(hold, t, 50000)));
    expect_same(one, measure(a, b, with(hold, 1, 50000)));
  }
  // Swapping A and B swaps the directions.
  DistanceResult ab = measure(a, b, with(DistanceHold::kBoth, 2, 50000));
  DistanceResult ba = measure(b, a, with(DistanceHold::kBoth, 2, 50000));
  EXPECT_EQ(ab.a_to_b.mean, ba.b_to_a.mean);
  EXPECT_EQ(ab.b_to_a.max, ba.a_to_b.max);
}

TEST(Distance, SeedChangesTheFaceSamplesOnly) {
  Mesh a = bumpy_sphere(20, 30, 0.1), b = test::make_sphere(10, 14);
  DistanceResult r1 = measure(a, b, with(DistanceHold::kBoth, 2, 30000, 1));
  DistanceResult r2 = measure(a, b, with(DistanceHold::kBoth, 2, 30000, 2));
  EXPECT_NE(r1.a_to_b.mean, r2.a_to_b.mean);
  EXPECT_NEAR(r1.a_to_b.mean, r2.a_to_b.mean, 0.02 * r1.a_to_b.mean);
}

// ----------------------------------------------- degenerate and hostile

// A source that yields the triangles before the vertices (a PLY whose face
// element comes first).
class FacesFirstSource : public MeshSource {
 public:
  explicit FacesFirstSource(Mesh m) : m_(std::move(m)) {}
  const MeshSchema& schema() const override { return m_.schema; }
  const SourceReport& report() const override { return report_; }
  Status next(MeshItem* item) override {
    item->values.clear();
    if (at_ < m_.triangles.size()) {
      item->kind = MeshItem::Kind::kTriangle;
      for (int k = 0; k < 3; ++k) item->index[k] = m_.triangles[at_][k];
    } else if (at_ < m_.triangles.size() + m_.positions.size()) {
      item->kind = MeshItem::Kind::kVertex;
      for (int k = 0; k < 3; ++k) item->position[k] = m_.positions[at_ - m_.triangles.size()][k];
    } else {
      item->kind = MeshItem::Kind::kEnd;
      return Status();
    }
    ++at_;
    return Status();
  }

 private:
  Mesh m_;
  size_t at_ = 0;
  SourceReport report_;
};

TEST(Distance, TrianglesBeforeVertices) {
  Mesh a = bumpy_sphere(12, 16, 0.2), b = test::make_sphere(9, 12);
  DistanceResult expect = measure(a, b, with(DistanceHold::kBoth, 2, 5000));
  for (DistanceHold hold : {DistanceHold::kBoth, DistanceHold::kA, DistanceHold::kB}) {
    FacesFirstSource fa(a);
    test::MemorySource sb(b);
    DistanceResult r;
    ASSERT_TRUE(measure_distance(fa, sb, with(hold, 2, 5000), &r).ok());
    expect_same(expect, r);
  }
}

TEST(Distance, ZeroAreaMeshIsMeasuredByItsVertices) {
  // Three collinear triangles along the x axis, and a unit grid.
  Mesh line = test::make_mesh({{0, 0, 0}, {0.5, 0, 0}, {1, 0, 0}, {0.25, 0, 0}}, {{0, 1, 2}, {0, 3, 1}, {1, 3, 2}});
  Mesh grid = translated(test::make_grid(4), 0, 0, 0.5);
  for (DistanceHold hold : {DistanceHold::kBoth, DistanceHold::kA, DistanceHold::kB}) {
    DistanceResult r = measure(line, grid, with(hold));
    EXPECT_EQ(r.a.area, 0);
    EXPECT_EQ(r.a_to_b.samples, 4u);
    EXPECT_EQ(r.a_to_b.vertex_samples, 4u);
    EXPECT_NEAR(r.a_to_b.max, 0.5, 1e-15);
    // The grid's points against the segment [0, 1] on the x axis.
    EXPECT_NEAR(r.b_to_a.max, std::sqrt(3 * 3 + 4 * 4 + 0.25), 1e-12);  // from the corner (4, 4)
    EXPECT_GT(r.b_to_a.samples, 100u);
  }
}

TEST(Distance, MeshWithoutTrianglesIsAnError) {
  Mesh points = test::make_mesh({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}, {});
  Mesh empty = test::make_mesh({}, {});
  Mesh sphere = test::make_sphere(6, 8);
  for (DistanceHold hold : {DistanceHold::kAuto, DistanceHold::kBoth, DistanceHold::kA, DistanceHold::kB}) {
    for (const Mesh* bad : {&points, &empty}) {
      DistanceResult r;
      test::MemorySource s1(*bad), s2(sphere);
      Status st = measure_distance(s1, s2, with(hold), &r);
      EXPECT_EQ(st.code(), ErrorCode::kBadValue);
      EXPECT_EQ(r.error_input, 1);
      test::MemorySource s3(sphere), s4(*bad);
      st = measure_distance(s3, s4, with(hold), &r);
      EXPECT_EQ(st.code(), ErrorCode::kBadValue);
      EXPECT_EQ(r.error_input, 2);
    }
  }
}

TEST(Distance, TooManySamplesIsAUsageError) {
  Mesh m = test::make_sphere(6, 8);
  test::MemorySource a(m), b(m);
  DistanceResult r;
  EXPECT_EQ(measure_distance(a, b, with(DistanceHold::kBoth, 1, kMaxSamples + 1), &r).code(), ErrorCode::kUsage);
}

// A source that fails after some items, as a truncated file does.
class FailingSource : public test::MemorySource {
 public:
  FailingSource(Mesh m, int after) : MemorySource(std::move(m)), left_(after) {}
  Status next(MeshItem* item) override {
    if (left_-- <= 0) return Status(ErrorCode::kTruncated, "input ends early", 1234);
    return MemorySource::next(item);
  }

 private:
  int left_;
};

TEST(Distance, SourceErrorsNameTheirInput) {
  Mesh m = test::make_sphere(6, 8);
  for (DistanceHold hold : {DistanceHold::kBoth, DistanceHold::kA, DistanceHold::kB}) {
    for (int which : {1, 2}) {
      FailingSource bad(m, 40);
      test::MemorySource good(m);
      DistanceResult r;
      Status s = which == 1 ? measure_distance(bad, good, with(hold), &r) : measure_distance(good, bad, with(hold), &r);
      EXPECT_EQ(s.code(), ErrorCode::kTruncated);
      EXPECT_EQ(s.offset(), 1234u);
      EXPECT_EQ(r.error_input, which);
    }
  }
}

TEST(Distance, DoublePositionsAreKeptExactly) {
  // Coordinates that no float holds, declared float64, and a mesh that
  // declares float32 but is not (the source yields doubles either way).
  Mesh a = test::make_grid(10);
  for (auto& p : a.positions) p = {p[0] * 0.1 + 1e-9, p[1] * 0.3, 0.1};
  Mesh b = translated(a, 0, 0, 1e-7);
  for (ScalarType t : {ScalarType::kFloat64, ScalarType::kFloat32}) {
    a.schema.position_type = b.schema.position_type = t;
    for (DistanceHold hold : {DistanceHold::kBoth, DistanceHold::kA}) {
      DistanceResult r = measure(a, b, with(hold, 2, 3000));
      EXPECT_NEAR(r.a_to_b.max, 1e-7, 1e-15);
      EXPECT_NEAR(r.b_to_a.mean, 1e-7, 1e-15);
    }
  }
}

// ------------------------------------------------------------------- CLI

std::string write_ply(const test::TempDir& dir, const std::string& name, const Mesh& m) {
  OutputFile out;
  EXPECT_TRUE(out.open(dir.file(name), true).ok());
  PlyWriter w(&out);
  test::MemorySource src(m);
  EXPECT_TRUE(pump(src, w).ok());
  EXPECT_TRUE(out.commit().ok());
  return dir.file(name);
}

// The JSON without its timing object.
std::string numbers(const std::string& json) {
  return std::regex_replace(json, std::regex("\"timing\": \\{[^}]*\\}"), "");
}

TEST(DistanceCli, HelpSaysWhatIsHeld) {
  std::string out, err;
  ASSERT_EQ(test::run_psq("distance --help", &out, &err), 0);
  EXPECT_NE(out.find("Usage: psq distance A B"), std::string::npos);
  EXPECT_NE(out.find("held"), std::string::npos);
  EXPECT_NE(out.find("stream"), std::string::npos);
  ASSERT_EQ(test::run_psq("--help", &out, &err), 0);
  EXPECT_NE(out.find("distance A B"), std::string::npos);
}

TEST(DistanceCli, TextAndJson) {
  test::TempDir dir;
  std::string a = write_ply(dir, "a.ply", test::make_grid(8));
  std::string b = write_ply(dir, "b.ply", translated(test::make_grid(8), 0, 0, 0.25));
  std::string out, err;
  ASSERT_EQ(test::run_psq("distance " + a + " " + b, &out, &err), 0) << err;
  EXPECT_NE(out.find("A -> B"), std::string::npos) << out;
  EXPECT_NE(out.find("B -> A"), std::string::npos);
  EXPECT_NE(out.find("symmetric"), std::string::npos);
  EXPECT_NE(out.find("0.25"), std::string::npos);
  EXPECT_NE(err.find("samples/s"), std::string::npos);
  ASSERT_EQ(test::run_psq("distance --json --samples 1000 " + a + " " + b, &out, &err), 0) << err;
  for (const char* key : {"\"a_to_b\": {\"samples\": 1000,", "\"b_to_a\": {\"samples\": 1000,", "\"hausdorff\": 0.25,",
                          "\"diagonal\": 11.313708498984761,", "\"relative\": {\"a_to_b\": {\"max\": 0.0220970869120796",
                          "\"timing\": {\"seconds\": ", "\"samples_per_second\": "}) {
    EXPECT_NE(out.find(key), std::string::npos) << key << "\n" << out;
  }
}

TEST(DistanceCli, SameOutputForEveryRunThreadCountAndHold) {
  test::TempDir dir;
  std::string a = write_ply(dir, "a.ply", bumpy_sphere(30, 40, 0.1));
  std::string b = write_ply(dir, "b.ply", test::make_sphere(12, 15));
  std::string first, out, err;
  ASSERT_EQ(test::run_psq("distance " + a + " " + b, &first, &err), 0) << err;
  for (const char* opts : {"", "--threads 1", "--threads 2", "--threads 5"}) {
    ASSERT_EQ(test::run_psq(std::string("distance ") + opts + " " + a + " " + b, &out, &err), 0) << err;
    EXPECT_EQ(out, first) << opts;
  }
  std::string json;
  ASSERT_EQ(test::run_psq("distance --json " + a + " " + b, &json, &err), 0) << err;
  const std::regex held("\"held\": (true|false)");
  for (const char* opts : {"--hold A", "--hold B", "--in-memory", "--threads 1 --hold b"}) {
    ASSERT_EQ(test::run_psq(std::string("distance --json ") + opts + " " + a + " " + b, &out, &err), 0) << err;
    EXPECT_EQ(std::regex_replace(numbers(out), held, ""), std::regex_replace(numbers(json), held, "")) << opts;
  }
}

TEST(DistanceCli, StandardInput) {
  test::TempDir dir;
  std::string a = write_ply(dir, "a.ply", test::make_sphere(10, 12));
  std::string b = write_ply(dir, "b.ply", bumpy_sphere(8, 9, 0.1));
  std::string file, piped, err;
  ASSERT_EQ(test::run_psq("distance --json " + a + " " + b, &file, &err), 0) << err;
  ASSERT_EQ(test::run_psq("distance --json - " + b, &piped, &err, a), 0) << err;
  EXPECT_EQ(numbers(std::regex_replace(piped, std::regex("\"file\": \"-\""), "\"file\": \"" + a + "\"")),
            numbers(file));
  ASSERT_EQ(test::run_psq("distance --json --hold B " + a + " - ", &piped, &err, b), 0) << err;
  EXPECT_NE(piped.find("\"file\": \"-\""), std::string::npos);
}

TEST(DistanceCli, UsageErrors) {
  test::TempDir dir;
  std::string a = write_ply(dir, "a.ply", test::make_sphere(6, 8));
  std::string out, err;
  for (const std::string& args : {std::string("distance"), "distance " + a, "distance " + a + " " + a + " " + a,
                                  std::string("distance - -"), "distance --samples 0 " + a + " " + a,
                                  "distance --samples x " + a + " " + a, "distance --samples 2G " + a + " " + a,
                                  "distance --seed -1 " + a + " " + a, "distance --threads 0 " + a + " " + a,
                                  "distance --hold C " + a + " " + a, "distance --hold A --in-memory " + a + " " + a,
                                  "distance --bogus " + a + " " + a}) {
    EXPECT_EQ(test::run_psq(args, &out, &err), 2) << args;
    EXPECT_NE(err.find("psq: error: "), std::string::npos) << args;
    EXPECT_TRUE(out.empty()) << args;
  }
}

TEST(DistanceCli, BadInputIsOneLineNamingTheFile) {
  test::TempDir dir;
  std::string good = write_ply(dir, "good.ply", test::make_sphere(6, 8));
  std::string bytes = test::read_file(good);
  test::write_file(dir.file("cut.ply"), bytes.substr(0, bytes.size() - 50));
  test::write_file(dir.file("junk.ply"), "this is not a mesh\n");
  test::write_file(dir.file("nofaces.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\n");
  test::write_file(dir.file("badindex.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n");
  test::write_file(dir.file("nan.obj"), "v 0 0 0\nv 1 0 nan\nv 0 1 0\nf 1 2 3\n");
  for (const char* name : {"cut.ply", "junk.ply", "nofaces.obj", "badindex.obj", "nan.obj", "missing.ply"}) {
    for (const char* opts : {"", "--hold A ", "--hold B ", "--in-memory "}) {
      for (bool first : {true, false}) {
        std::string bad = dir.file(name);
        std::string args = std::string("distance ") + opts + (first ? bad + " " + good : good + " " + bad);
        std::string out, err;
        EXPECT_EQ(test::run_psq(args, &out, &err), 1) << args;
        EXPECT_EQ(err.rfind("psq: error: " + bad + ": ", 0), 0u) << args << "\n" << err;
        EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;
        EXPECT_TRUE(out.empty()) << args;
      }
    }
  }
}

}  // namespace
}  // namespace psq
