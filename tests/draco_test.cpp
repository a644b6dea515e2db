// SPDX-License-Identifier: Apache-2.0
// Draco (.drc) reading and writing: round trips, attributes, corrupt input,
// the memory budget, and the CLI.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <random>
#include <set>
#include <string>

#include "psq/draco.h"
#include "psq/mesh_formats.h"
#include "psq/ply.h"
#include "test_util.h"

namespace psq {
namespace {

using test::Mesh;
using test::run_psq;

// A sphere with normals, uchar colors, u/v, two other scalar properties, a
// list property and a face property.
Mesh decorated_sphere() {
  Mesh m = test::make_sphere(12, 20);
  auto& vp = m.schema.vertex_properties;
  for (const char* n : {"nx", "ny", "nz"}) vp.push_back({n, ScalarType::kFloat32});
  for (const char* n : {"red", "green", "blue"}) vp.push_back({n, ScalarType::kUInt8});
  for (const char* n : {"u", "v"}) vp.push_back({n, ScalarType::kFloat32});
  vp.push_back({"confidence", ScalarType::kFloat32});
  vp.push_back({"label", ScalarType::kUInt16});
  Property list;
  list.name = "tags";
  list.type = ScalarType::kInt32;
  list.is_list = true;
  vp.push_back(list);
  m.schema.face_properties.push_back({"segment", ScalarType::kInt32});
  for (size_t i = 0; i < m.positions.size(); ++i) {
    const auto& p = m.positions[i];
    const double len = std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
    m.vertex_values[i] = {static_cast<float>(p[0] / len), static_cast<float>(p[1] / len), static_cast<float>(p[2] / len),
                          static_cast<double>(i % 256), static_cast<double>((i * 7) % 256), 200,
                          static_cast<float>(0.5 + 0.5 * p[0]), static_cast<float>(0.5 + 0.5 * p[1]),
                          static_cast<float>(0.25 + i * 0.125), static_cast<double>(i % 9),
                          2, 1, -static_cast<double>(i)};
  }
  for (size_t t = 0; t < m.triangles.size(); ++t) m.face_values[t] = {static_cast<double>(t)};
  return m;
}

// Encodes `m` to a .drc file at `path`; returns the writer's status.
Status write_drc(const Mesh& m, const std::string& path, DracoWriteOptions options,
                 std::vector<std::string>* dropped = nullptr) {
  OutputFile out;
  Status s = out.open(path, true);
  if (!s.ok()) return s;
  DracoWriter w(&out, options);
  test::MemorySource src(m);
  s = pump(src, w);
  if (!s.ok()) return s;
  if (dropped) *dropped = w.dropped();
  return out.commit();
}

// Reads a .drc held in memory with the given budget.
Status read_drc(const std::string& bytes, uint64_t budget, Mesh* mesh) {
  InputStream in;
  in.open_memory(bytes.data(), bytes.size(), "mem.drc");
  DracoReader r;
  Status s = r.open(&in, budget);
  if (!s.ok()) return s;
  test::MemorySink sink;
  s = pump(r, sink);
  *mesh = sink.mesh;
  return s;
}

int prop_index(const Mesh& m, const std::string& name) {
  const auto& vp = m.schema.vertex_properties;
  for (size_t i = 0; i < vp.size(); ++i)
    if (vp[i].name == name) return static_cast<int>(i);
  return -1;
}

// Matches each vertex of `got` to the nearest vertex of `want` (within
// `tol` on every axis, one to one) and checks that the triangles are the
// same under that matching. Returns the matching.
std::vector<uint32_t> match(const Mesh& want, const Mesh& got, double tol) {
  std::vector<uint32_t> to_want(got.positions.size(), 0);
  std::set<uint32_t> taken;
  for (size_t i = 0; i < got.positions.size(); ++i) {
    double best = 1e300;
    uint32_t bi = 0;
    for (size_t j = 0; j < want.positions.size(); ++j) {
      double d = 0;
      for (int k = 0; k < 3; ++k) d = std::max(d, std::fabs(got.positions[i][k] - want.positions[j][k]));
      if (d < best) best = d, bi = static_cast<uint32_t>(j);
    }
    EXPECT_LE(best, tol) << "vertex " << i;
    EXPECT_TRUE(taken.insert(bi).second) << "two vertices match original vertex " << bi;
    to_want[i] = bi;
  }
  Mesh mapped = got;
  for (auto& t : mapped.triangles)
    for (auto& v : t) v = to_want[v];
  EXPECT_EQ(test::canonical_triangles(mapped), test::canonical_triangles(want));
  return to_want;
}

TEST(Draco, DetectsByContent) {
  const uint8_t drc[] = {'D', 'R', 'A', 'C', 'O', 2, 2, 1, 1};
  EXPECT_TRUE(looks_like_draco(drc, sizeof drc));
  EXPECT_EQ(detect_format(drc, sizeof drc, sizeof drc), MeshFormat::kDraco);
  EXPECT_FALSE(looks_like_draco(drc, 4));
  EXPECT_EQ(format_from_extension("a/b.drc"), MeshFormat::kDraco);
  EXPECT_EQ(format_from_name("drc"), MeshFormat::kDraco);
  EXPECT_STREQ(format_name(MeshFormat::kDraco), "drc");
}

TEST(Draco, RoundTripKeepsCountsPositionsAndAttributes) {
  test::TempDir dir;
  Mesh m = decorated_sphere();
  DracoWriteOptions o;
  o.bits = 14;
  std::vector<std::string> dropped;
  ASSERT_TRUE(write_drc(m, dir.file("a.drc"), o, &dropped).ok());
  EXPECT_EQ(dropped, (std::vector<std::string>{"tags", "segment"}));

  Mesh got;
  Status s = read_drc(test::read_file(dir.file("a.drc")), uint64_t{64} << 20, &got);
  ASSERT_TRUE(s.ok()) << s.to_string();
  ASSERT_EQ(got.positions.size(), m.positions.size());
  ASSERT_EQ(got.triangles.size(), m.triangles.size());
  EXPECT_EQ(got.schema.vertex_count, static_cast<int64_t>(m.positions.size()));
  EXPECT_EQ(got.schema.triangle_count, static_cast<int64_t>(m.triangles.size()));
  // The sphere spans 2 units: half a step of the 14-bit grid, plus float rounding.
  const double half_step = 2.0 / ((1 << 14) - 1) / 2;
  std::vector<uint32_t> to_want = match(m, got, half_step * 1.001 + 1e-6);

  for (const char* n : {"nx", "ny", "nz", "red", "green", "blue", "u", "v", "confidence", "label"})
    ASSERT_GE(prop_index(got, n), 0) << n;
  EXPECT_EQ(prop_index(got, "tags"), -1);
  EXPECT_TRUE(got.schema.face_properties.empty());
  EXPECT_EQ(got.schema.vertex_properties[prop_index(got, "red")].type, ScalarType::kUInt8);
  EXPECT_EQ(got.schema.vertex_properties[prop_index(got, "label")].type, ScalarType::kUInt16);
  for (size_t i = 0; i < got.positions.size(); ++i) {
    const PropertyValues& w = m.vertex_values[to_want[i]];
    const PropertyValues& g = got.vertex_values[i];
    const char* normal[3] = {"nx", "ny", "nz"};
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(g[prop_index(got, normal[k])], w[k], 0.01);
    EXPECT_EQ(g[prop_index(got, "red")], w[3]);
    EXPECT_EQ(g[prop_index(got, "green")], w[4]);
    EXPECT_EQ(g[prop_index(got, "blue")], w[5]);
    EXPECT_NEAR(g[prop_index(got, "u")], w[6], 1.0 / 4095);
    EXPECT_NEAR(g[prop_index(got, "v")], w[7], 1.0 / 4095);
    EXPECT_EQ(g[prop_index(got, "confidence")], w[8]);
    EXPECT_EQ(g[prop_index(got, "label")], w[9]);
  }
}

// Normals and texture coordinates per corner (the face lists of psq's OBJ
// reader, spec 8.5) go to Draco as points per distinct vertex and corner
// values with welded positions, and come back welded, per corner.
TEST(Draco, CornerAttributesRoundTripWelded) {
  test::TempDir dir;
  Mesh m = test::make_sphere(12, 20);
  m.schema.vertex_properties = {{"red", ScalarType::kUInt8}, {"green", ScalarType::kUInt8}, {"blue", ScalarType::kUInt8}};
  for (size_t i = 0; i < m.positions.size(); ++i) m.vertex_values[i] = {static_cast<double>(i % 256), 9, 200};
  Property normals, uv;
  normals.name = "corner_normals";
  uv.name = "corner_uv";
  for (Property* p : {&normals, &uv}) {
    p->type = ScalarType::kFloat32;
    p->is_list = true;
    p->count_type = ScalarType::kUInt8;
  }
  m.schema.face_properties = {normals, uv};
  for (size_t f = 0; f < m.triangles.size(); ++f) {
    const auto& t = m.triangles[f];
    const auto &a = m.positions[t[0]], &b = m.positions[t[1]], &c = m.positions[t[2]];
    double n[3] = {(b[1] - a[1]) * (c[2] - a[2]) - (b[2] - a[2]) * (c[1] - a[1]),
                   (b[2] - a[2]) * (c[0] - a[0]) - (b[0] - a[0]) * (c[2] - a[2]),
                   (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])};
    const double l = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    PropertyValues v{9};
    for (int k = 0; k < 3; ++k)
      for (int d = 0; d < 3; ++d) v.push_back(static_cast<float>(n[d] / l));  // flat: a crease at every edge
    v.push_back(6);
    const double half = (a[0] + b[0] + c[0]) > 0 ? 0.5 : 0;  // two charts, a seam between
    for (uint32_t i : t) {
      v.push_back(static_cast<float>(half + 0.25 * (1 + m.positions[i][1])));
      v.push_back(static_cast<float>(0.5 + 0.5 * m.positions[i][2]));
    }
    m.face_values[f] = v;
  }
  DracoWriteOptions o;
  o.bits = 14;
  std::vector<std::string> dropped;
  ASSERT_TRUE(write_drc(m, dir.file("c.drc"), o, &dropped).ok());
  EXPECT_TRUE(dropped.empty());
  Mesh got;
  const Status s = read_drc(test::read_file(dir.file("c.drc")), uint64_t{64} << 20, &got);
  ASSERT_TRUE(s.ok()) << s.to_string();
  ASSERT_EQ(got.positions.size(), m.positions.size());  // welded again
  ASSERT_EQ(got.schema.face_properties.size(), 2u);
  EXPECT_EQ(got.schema.face_properties[0].name, "corner_normals");
  EXPECT_EQ(got.schema.face_properties[1].name, "corner_uv");
  EXPECT_EQ(prop_index(got, "red"), 0);
  const double half_step = 2.0 / ((1 << 14) - 1) / 2;
  const std::vector<uint32_t> to_want = match(m, got, half_step * 1.001 + 1e-6);
  std::map<std::array<uint32_t, 3>, size_t> face_of;
  for (size_t f = 0; f < m.triangles.size(); ++f) {
    std::array<uint32_t, 3> k = m.triangles[f];
    std::sort(k.begin(), k.end());
    face_of[k] = f;
  }
  for (size_t i = 0; i < got.positions.size(); ++i)
    EXPECT_EQ(got.vertex_values[i][0], m.vertex_values[to_want[i]][0]);
  for (size_t f = 0; f < got.triangles.size(); ++f) {
    std::array<uint32_t, 3> w;
    for (int k = 0; k < 3; ++k) w[k] = to_want[got.triangles[f][k]];
    std::array<uint32_t, 3> key = w;
    std::sort(key.begin(), key.end());
    ASSERT_TRUE(face_of.count(key)) << "triangle " << f;
    const size_t of = face_of[key];
    const PropertyValues& a = m.face_values[of];
    const PropertyValues& b = got.face_values[f];
    ASSERT_EQ(b.size(), a.size());
    for (int k = 0; k < 3; ++k) {
      int j = 0;
      while (m.triangles[of][j] != w[k]) ++j;
      for (int d = 0; d < 3; ++d) EXPECT_NEAR(b[1 + 3 * k + d], a[1 + 3 * j + d], 0.01) << "triangle " << f;
      for (int d = 0; d < 2; ++d) EXPECT_NEAR(b[11 + 2 * k + d], a[11 + 2 * j + d], 1.0 / 4095) << "triangle " << f;
    }
  }
}

TEST(Draco, LosslessKeepsPositionsBitExact) {
  test::TempDir dir;
  Mesh m = test::make_grid(9);
  for (auto& p : m.positions) p[2] = static_cast<float>(0.1 * p[0] * p[1] + 1e-3);
  DracoWriteOptions o;
  o.lossless = true;
  ASSERT_TRUE(write_drc(m, dir.file("a.drc"), o).ok());
  Mesh got;
  ASSERT_TRUE(read_drc(test::read_file(dir.file("a.drc")), uint64_t{64} << 20, &got).ok());
  ASSERT_EQ(got.positions.size(), m.positions.size());
  match(m, got, 0.0);
}

TEST(Draco, PointCloudGivesVerticesOnly) {
  test::TempDir dir;
  Mesh m = test::make_grid(5);
  m.triangles.clear();
  m.face_values.clear();
  m.schema.triangle_count = 0;
  ASSERT_TRUE(write_drc(m, dir.file("p.drc"), {}).ok());
  Mesh got;
  Status s = read_drc(test::read_file(dir.file("p.drc")), uint64_t{64} << 20, &got);
  ASSERT_TRUE(s.ok()) << s.to_string();
  EXPECT_EQ(got.positions.size(), m.positions.size());
  EXPECT_TRUE(got.triangles.empty());
}

TEST(Draco, CorruptInputGivesCleanErrors) {
  test::TempDir dir;
  ASSERT_TRUE(write_drc(decorated_sphere(), dir.file("a.drc"), {}).ok());
  const std::string good = test::read_file(dir.file("a.drc"));
  auto check = [](const std::string& bytes, const std::string& what) {
    Mesh got;
    Status s = read_drc(bytes, uint64_t{64} << 20, &got);
    if (s.ok()) return;
    // kLimit: a corrupt count that asks libdraco for more memory than there is.
    EXPECT_TRUE(s.code() == ErrorCode::kBadValue || s.code() == ErrorCode::kUnknownFormat ||
                s.code() == ErrorCode::kBadIndex || s.code() == ErrorCode::kLimit ||
                s.code() == ErrorCode::kTruncated || s.code() == ErrorCode::kBadHeader ||
                s.code() == ErrorCode::kUnsupported)
        << what << ": " << s.to_string();
    EXPECT_FALSE(s.message().empty()) << what;
    EXPECT_EQ(s.message().find('\n'), std::string::npos) << what;
  };
  // Every cut of the header, and cuts through the body.
  for (size_t n = 0; n < good.size(); n += (n < 64 ? 1 : 7)) {
    Mesh got;
    Status s = read_drc(good.substr(0, n), uint64_t{64} << 20, &got);
    EXPECT_FALSE(s.ok()) << "cut at " << n;
    check(good.substr(0, n), "cut at " + std::to_string(n));
  }
  std::mt19937 rng(12345);
  for (int trial = 0; trial < 300; ++trial) {
    std::string bad = good;
    const int flips = 1 + trial % 4;
    for (int f = 0; f < flips; ++f) bad[rng() % bad.size()] ^= static_cast<char>(1 + rng() % 255);
    check(bad, "trial " + std::to_string(trial));
  }
}

// ---------------------------------------------------------- hostile input

// The 11-byte header: magic, version, geometry type, method, flags.
std::string drc_header(int major, int minor, int type, int method, int flags = 0) {
  std::string h = "DRACO";
  for (int b : {major, minor, type, method, flags & 0xff, flags >> 8}) h.push_back(static_cast<char>(b));
  return h;
}

// `v` as Draco's LEB128 varint.
std::string varint(uint64_t v) {
  std::string out;
  do {
    uint8_t b = v & 0x7f;
    v >>= 7;
    out.push_back(static_cast<char>(v ? (b | 0x80) : b));
  } while (v);
  return out;
}

// An edgebreaker mesh header (bitstream 2.2) with the given counts,
// followed by `tail` filler bytes.
std::string edgebreaker(int traversal, uint64_t vertices, uint64_t faces, uint64_t symbols, size_t tail = 64) {
  return drc_header(2, 2, 1, 1) + static_cast<char>(traversal) + varint(vertices) + varint(faces) +
         std::string(1, '\0') + varint(symbols) + varint(0) + std::string(tail, '\0');
}

// A failed read of `bytes` must be `code`, carry a byte offset inside the
// file, and be one line.
void expect_refused(const std::string& bytes, ErrorCode code, const std::string& what,
                    uint64_t budget = uint64_t{64} << 20) {
  Mesh got;
  Status s = read_drc(bytes, budget, &got);
  ASSERT_FALSE(s.ok()) << what;
  EXPECT_EQ(s.code(), code) << what << ": " << s.to_string() << " (" << error_name(s.code()) << ")";
  EXPECT_NE(s.offset(), Status::kNoPlace) << what << ": " << s.to_string();
  if (s.offset() != Status::kNoPlace) {
    EXPECT_LE(s.offset(), bytes.size()) << what;
  }
  EXPECT_EQ(s.message().find('\n'), std::string::npos) << what;
}

TEST(DracoHostile, TruncatedAtSeveralLengths) {
  test::TempDir dir;
  ASSERT_TRUE(write_drc(decorated_sphere(), dir.file("a.drc"), {}).ok());
  const std::string good = test::read_file(dir.file("a.drc"));
  ASSERT_TRUE(check_draco_header(reinterpret_cast<const uint8_t*>(good.data()), good.size(), uint64_t{64} << 20).ok());
  // In the header: the magic, the version, the flags.
  expect_refused(good.substr(0, 3), ErrorCode::kUnknownFormat, "cut in the magic");
  for (size_t n : {5, 6, 8, 10}) expect_refused(good.substr(0, n), ErrorCode::kTruncated, "cut at " + std::to_string(n));
  // In the metadata the writer adds for the generic attributes, and in the
  // element counts.
  ASSERT_EQ(static_cast<uint8_t>(good[10]) & 0x80, 0x80);
  // A count that the bytes left cannot hold may be corrupt as well as cut
  // short: kBadValue or kTruncated.
  for (size_t n : {11, 12, 14, 20, 30}) {
    Mesh got;
    Status s = read_drc(good.substr(0, n), uint64_t{64} << 20, &got);
    EXPECT_TRUE(s.code() == ErrorCode::kTruncated || s.code() == ErrorCode::kBadValue) << n << ": " << s.to_string();
    EXPECT_NE(s.offset(), Status::kNoPlace) << n;
    EXPECT_LE(s.offset(), n) << s.to_string();
  }
  // In the body: libdraco refuses; the offset is where it stopped.
  for (size_t n : {good.size() / 4, good.size() / 2, good.size() - 1}) {
    Mesh got;
    Status s = read_drc(good.substr(0, n), uint64_t{64} << 20, &got);
    ASSERT_FALSE(s.ok()) << n;
    EXPECT_NE(s.offset(), Status::kNoPlace) << n << ": " << s.to_string();
    EXPECT_LE(s.offset(), n) << s.to_string();
  }
}

TEST(DracoHostile, CorruptHeader) {
  const std::string body = edgebreaker(0, 3, 1, 1).substr(11);
  auto with_byte = [&](size_t at, int value) {
    std::string b = drc_header(2, 2, 1, 1) + body;
    b[at] = static_cast<char>(value);
    return b;
  };
  expect_refused(with_byte(0, 'd'), ErrorCode::kUnknownFormat, "magic");
  expect_refused(with_byte(5, 3), ErrorCode::kUnsupported, "major version 3");
  expect_refused(with_byte(6, 3), ErrorCode::kUnsupported, "mesh version 2.3");
  expect_refused(with_byte(5, 0), ErrorCode::kUnsupported, "major version 0");
  expect_refused(with_byte(7, 2), ErrorCode::kBadHeader, "geometry type 2");
  expect_refused(with_byte(8, 4), ErrorCode::kBadHeader, "method 4");
  expect_refused(with_byte(9, 1), ErrorCode::kBadHeader, "unknown flag");
  expect_refused(with_byte(11, 7), ErrorCode::kBadHeader, "edgebreaker traversal 7");
  // The offsets name the bad field.
  Mesh got;
  EXPECT_EQ(read_drc(with_byte(5, 3), uint64_t{1} << 20, &got).offset(), 5u);
  EXPECT_EQ(read_drc(with_byte(7, 2), uint64_t{1} << 20, &got).offset(), 7u);
  EXPECT_EQ(read_drc(with_byte(8, 4), uint64_t{1} << 20, &got).offset(), 8u);
  // Metadata whose counts the bytes cannot hold, or nested without end.
  expect_refused(drc_header(2, 2, 1, 1, 0x8000) + varint(1000000) + std::string(40, '\0'), ErrorCode::kBadValue,
                 "a million attribute metadata");
  expect_refused(drc_header(2, 2, 1, 1, 0x8000) + varint(0) + varint(4000000000u) + std::string(40, '\0'),
                 ErrorCode::kBadValue, "4e9 metadata entries");
  std::string deep = drc_header(2, 2, 1, 1, 0x8000) + varint(0) + varint(0) + varint(1);
  for (int i = 0; i < 100; ++i) deep += std::string(1, '\0') + varint(0) + varint(1);
  expect_refused(deep + std::string(40, '\0'), ErrorCode::kUnsupported, "metadata 100 levels deep");
  // A varint longer than 32 bits.
  expect_refused(drc_header(2, 2, 1, 1) + std::string(1, '\0') + std::string(5, '\xff') + std::string(20, '\x01'),
                 ErrorCode::kBadValue, "six-byte varint");
}

TEST(DracoHostile, AbsurdCounts) {
  // Edgebreaker counts that contradict each other.
  expect_refused(edgebreaker(2, 3, 1, 2), ErrorCode::kBadValue, "more symbols than faces");
  expect_refused(edgebreaker(2, 1000, 10, 10), ErrorCode::kBadValue, "more vertices than corners");
  expect_refused(edgebreaker(2, 3, 0xffffffffu, 1), ErrorCode::kBadValue, "2^32-1 faces");
  // Standard traversal: a bit per symbol at least.
  expect_refused(edgebreaker(0, 300000000, 100000000, 100000000), ErrorCode::kBadValue,
                 "1e8 symbols in 64 bytes");
  // Valence traversal (entropy coded): the memory estimate.
  expect_refused(edgebreaker(2, 30000000, 10000000, 10000000), ErrorCode::kLimit, "1e7 faces, 64 MiB");
  {
    Mesh got;
    Status s = read_drc(edgebreaker(2, 30000000, 10000000, 10000000), uint64_t{64} << 20, &got);
    EXPECT_EQ(s.offset(), 12u) << s.to_string();  // the counts, after the traversal byte
    EXPECT_NE(s.message().find("--memory"), std::string::npos) << s.to_string();
  }
  // Sequential mesh with raw indices that are not in the file.
  expect_refused(drc_header(2, 2, 1, 0) + varint(1000) + varint(100) + '\x01' + std::string(100, '\0'),
                 ErrorCode::kBadValue, "1000 faces of raw indices in 100 bytes");
  expect_refused(drc_header(2, 2, 1, 0) + varint(100000000) + varint(3) + '\x00' + std::string(100, '\0'),
                 ErrorCode::kLimit, "1e8 compressed faces");
  // Point clouds: an int32 count.
  auto cloud = [](uint32_t points) {
    std::string b = drc_header(2, 3, 0, 0);
    for (int k = 0; k < 4; ++k) b.push_back(static_cast<char>(points >> (8 * k)));
    return b + std::string(64, '\0');
  };
  expect_refused(cloud(0x80000000u), ErrorCode::kBadValue, "negative point count");
  expect_refused(cloud(0x7fffffffu), ErrorCode::kLimit, "2^31-1 points");
  expect_refused(cloud(2000000), ErrorCode::kLimit, "2e6 points, 16 MiB", uint64_t{16} << 20);
}

TEST(DracoHostile, CliNamesFileAndOffset) {
  test::TempDir dir;
  test::write_file(dir.file("huge.drc"), edgebreaker(2, 30000000, 10000000, 10000000));
  std::string out, err;
  EXPECT_EQ(run_psq("convert --memory 64M " + dir.file("huge.drc") + " " + dir.file("x.ply"), &out, &err), 1) << err;
  EXPECT_NE(err.find("psq: error: " + dir.file("huge.drc") + ": byte 12: "), std::string::npos) << err;
  EXPECT_NE(err.find("--memory"), std::string::npos) << err;
  EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;
  EXPECT_FALSE(test::file_exists(dir.file("x.ply")));
  // Counts within the budget: libdraco then refuses the filler, and the
  // error still names the file and a byte.
  test::write_file(dir.file("filler.drc"), edgebreaker(2, 3000, 1000, 1000));
  EXPECT_EQ(run_psq("convert " + dir.file("filler.drc") + " " + dir.file("x.ply"), &out, &err), 1) << err;
  EXPECT_NE(err.find("psq: error: " + dir.file("filler.drc") + ": byte "), std::string::npos) << err;
  EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;
  test::write_file(dir.file("bad.drc"), drc_header(9, 0, 1, 1) + std::string(20, '\0'));
  EXPECT_EQ(run_psq("info " + dir.file("bad.drc"), &out, &err), 1) << err;
  EXPECT_NE(err.find("psq: error: " + dir.file("bad.drc") + ": byte 5: "), std::string::npos) << err;
}

TEST(Draco, MemoryBudgetIsEnforced) {
  test::TempDir dir;
  Mesh m = decorated_sphere();
  ASSERT_TRUE(write_drc(m, dir.file("a.drc"), {}).ok());
  const std::string bytes = test::read_file(dir.file("a.drc"));
  Mesh got;
  // Smaller than the file.
  Status s = read_drc(bytes, bytes.size() / 2, &got);
  EXPECT_EQ(s.code(), ErrorCode::kLimit) << s.to_string();
  EXPECT_NE(s.message().find("memory"), std::string::npos);
  // Holds the file but not the decoded mesh.
  s = read_drc(bytes, bytes.size() + 16, &got);
  EXPECT_EQ(s.code(), ErrorCode::kLimit) << s.to_string();
  // The writer.
  DracoWriteOptions o;
  o.memory_budget = 4096;
  s = write_drc(m, dir.file("b.drc"), o);
  EXPECT_EQ(s.code(), ErrorCode::kLimit) << s.to_string();
}

TEST(Draco, WriterRefusesBadBits) {
  test::TempDir dir;
  DracoWriteOptions o;
  o.bits = 31;
  EXPECT_EQ(write_drc(test::make_grid(2), dir.file("a.drc"), o).code(), ErrorCode::kUsage);
}

// Writes a generated mesh as binary PLY.
void write_ply(const Mesh& m, const std::string& path) {
  OutputFile out;
  ASSERT_TRUE(out.open(path, false).ok());
  PlyWriter w(&out);
  test::MemorySource src(m);
  ASSERT_TRUE(pump(src, w).ok());
  ASSERT_TRUE(out.commit().ok());
}

TEST(DracoCli, PlyToDrcToPsqToInfo) {
  test::TempDir dir;
  Mesh m = decorated_sphere();
  write_ply(m, dir.file("a.ply"));
  std::string out, err;
  ASSERT_EQ(run_psq("convert " + dir.file("a.ply") + " " + dir.file("a.drc"), &out, &err), 0) << err;
  EXPECT_NE(err.find("'segment' dropped"), std::string::npos) << err;
  ASSERT_EQ(run_psq("convert " + dir.file("a.drc") + " " + dir.file("b.psq"), &out, &err), 0) << err;
  ASSERT_EQ(run_psq("info " + dir.file("b.psq") + " --json", &out, &err), 0) << err;
  EXPECT_NE(out.find(std::to_string(m.positions.size())), std::string::npos) << out;
  EXPECT_NE(out.find(std::to_string(m.triangles.size())), std::string::npos) << out;
  ASSERT_EQ(run_psq("info " + dir.file("a.drc"), &out, &err), 0) << err;
  EXPECT_NE(out.find("drc"), std::string::npos) << out;
  // .psq -> .drc and back to PLY.
  ASSERT_EQ(run_psq("convert " + dir.file("b.psq") + " " + dir.file("c.drc"), &out, &err), 0) << err;
  ASSERT_EQ(run_psq("convert " + dir.file("c.drc") + " " + dir.file("c.ply"), &out, &err), 0) << err;
  Mesh back;
  ASSERT_TRUE(test::load_mesh(dir.file("c.ply"), &back).ok());
  EXPECT_EQ(back.positions.size(), m.positions.size());
  EXPECT_EQ(back.triangles.size(), m.triangles.size());
}

TEST(DracoCli, PlyDrcPlyRoundTrip) {
  test::TempDir dir;
  Mesh m = test::make_sphere(8, 12);
  write_ply(m, dir.file("a.ply"));
  std::string out, err;
  ASSERT_EQ(run_psq("convert --bits 12 " + dir.file("a.ply") + " " + dir.file("a.drc"), &out, &err), 0) << err;
  ASSERT_EQ(run_psq("convert " + dir.file("a.drc") + " " + dir.file("b.ply"), &out, &err), 0) << err;
  Mesh got;
  ASSERT_TRUE(test::load_mesh(dir.file("b.ply"), &got).ok());
  ASSERT_EQ(got.positions.size(), m.positions.size());
  match(m, got, 2.0 / 4095 / 2 * 1.001 + 1e-6);
  // Lossless.
  ASSERT_EQ(run_psq("convert --lossless " + dir.file("a.ply") + " " + dir.file("l.drc"), &out, &err), 0) << err;
  ASSERT_EQ(run_psq("convert " + dir.file("l.drc") + " " + dir.file("l.ply"), &out, &err), 0) << err;
  ASSERT_TRUE(test::load_mesh(dir.file("l.ply"), &got).ok());
  match(m, got, 0.0);
}

TEST(DracoCli, NotesWhatEdgebreakerDrops) {
  test::TempDir dir;
  test::write_file(dir.file("a.ply"),
                   "ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\nproperty float y\n"
                   "property float z\nelement face 3\nproperty list uchar int vertex_indices\nend_header\n"
                   "0 0 0\n1 0 0\n0 1 0\n0 0 1\n5 5 5\n3 0 1 2\n3 0 2 3\n3 0 0 1\n");
  std::string out, err;
  ASSERT_EQ(run_psq("convert " + dir.file("a.ply") + " " + dir.file("a.drc"), &out, &err), 0) << err;
  EXPECT_NE(err.find("1 unreferenced vertex(es) dropped"), std::string::npos) << err;
  EXPECT_NE(err.find("1 degenerate triangle(s) dropped"), std::string::npos) << err;
  Mesh got;
  ASSERT_TRUE(test::load_mesh(dir.file("a.drc"), &got).ok());
  EXPECT_EQ(got.positions.size(), 4u);
  EXPECT_EQ(got.triangles.size(), 2u);
}

TEST(DracoCli, ErrorsAndLimits) {
  test::TempDir dir;
  write_ply(decorated_sphere(), dir.file("a.ply"));
  std::string out, err;
  EXPECT_EQ(run_psq("convert --bits 31 " + dir.file("a.ply") + " " + dir.file("x.drc"), &out, &err), 2) << err;
  EXPECT_FALSE(test::file_exists(dir.file("x.drc")));
  EXPECT_EQ(run_psq("convert --memory 4K " + dir.file("a.ply") + " " + dir.file("x.drc"), &out, &err), 1) << err;
  EXPECT_NE(err.find("memory"), std::string::npos) << err;
  EXPECT_FALSE(test::file_exists(dir.file("x.drc")));
  ASSERT_EQ(run_psq("convert " + dir.file("a.ply") + " " + dir.file("a.drc"), &out, &err), 0) << err;
  EXPECT_EQ(run_psq("convert --memory 1K " + dir.file("a.drc") + " " + dir.file("x.ply"), &out, &err), 1) << err;
  EXPECT_NE(err.find("memory"), std::string::npos) << err;
  std::string bytes = test::read_file(dir.file("a.drc"));
  test::write_file(dir.file("cut.drc"), bytes.substr(0, bytes.size() / 2));
  EXPECT_EQ(run_psq("convert " + dir.file("cut.drc") + " " + dir.file("x.ply"), &out, &err), 1) << err;
  EXPECT_NE(err.find("psq: error: " + dir.file("cut.drc")), std::string::npos) << err;
  EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;
  ASSERT_EQ(run_psq("convert --help", &out, &err), 0);
  EXPECT_NE(out.find("Draco"), std::string::npos);
  EXPECT_NE(out.find("--memory"), std::string::npos);
}

}  // namespace
}  // namespace psq
