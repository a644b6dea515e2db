// SPDX-License-Identifier: Apache-2.0
// PLY reader and writer: every encoding, type and layout, and hostile input.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <csignal>
#include <cstring>
#include <random>
#include <string>
#include <thread>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include "psq/mesh_formats.h"
#include "psq/ply.h"
#include "test_util.h"

namespace psq {
namespace {

using test::Mesh;

// Reads `bytes` as PLY through a memory stream; returns the status of the
// first failing step.
Status read_ply(const std::string& bytes, Mesh* mesh, SourceReport* report = nullptr) {
  InputStream in;
  in.open_memory(bytes.data(), bytes.size(), "test.ply");
  PlyReader reader;
  PSQ_RETURN_IF_ERROR(reader.open(&in));
  test::MemorySink sink;
  PSQ_RETURN_IF_ERROR(pump(reader, sink));
  *mesh = std::move(sink.mesh);
  if (report != nullptr) *report = reader.report();
  return Status();
}

std::string write_ply(const Mesh& mesh, PlyEncoding enc) {
  test::TempDir dir;
  OutputFile out;
  EXPECT_TRUE(out.open(dir.file("m.ply"), false).ok());
  PlyWriteOptions o;
  o.encoding = enc;
  o.spool_dir = dir.path();
  PlyWriter writer(&out, o);
  test::MemorySource source(mesh);
  Status s = pump(source, writer);
  EXPECT_TRUE(s.ok()) << s.to_string();
  EXPECT_TRUE(out.commit().ok());
  return test::read_file(dir.file("m.ply"));
}

// A sphere with one vertex property of every scalar type, a vertex list, and
// face properties including a list.
Mesh rich_sphere() {
  Mesh m = test::make_sphere(6, 9);
  const ScalarType types[] = {ScalarType::kInt8,  ScalarType::kUInt8,  ScalarType::kInt16,   ScalarType::kUInt16,
                              ScalarType::kInt32, ScalarType::kUInt32, ScalarType::kFloat32, ScalarType::kFloat64};
  for (ScalarType t : types) m.schema.vertex_properties.push_back({std::string("p_") + scalar_name(t), t});
  m.schema.vertex_properties.push_back({"weights", ScalarType::kFloat32, true, ScalarType::kUInt16});
  m.schema.face_properties.push_back({"flags", ScalarType::kUInt8});
  m.schema.face_properties.push_back({"texcoord", ScalarType::kFloat32, true, ScalarType::kUInt8});
  for (size_t i = 0; i < m.positions.size(); ++i) {
    double s = (i % 2) ? -1 : 1;
    PropertyValues v = {s * 100, 200, s * 30000, 60000, s * 2000000000, 4000000000.0, 0.25f * i, 1.0 / (i + 3)};
    size_t n = i % 4;
    v.push_back(static_cast<double>(n));
    for (size_t k = 0; k < n; ++k) v.push_back(0.5 * k);
    m.vertex_values[i] = v;
  }
  for (size_t t = 0; t < m.triangles.size(); ++t) {
    m.face_values[t] = {static_cast<double>(t % 256), 6, 0, 0, 1, 0, 0.5, 1};
  }
  return m;
}

void expect_same(const Mesh& a, const Mesh& b) {
  ASSERT_EQ(a.positions.size(), b.positions.size());
  ASSERT_EQ(a.triangles.size(), b.triangles.size());
  for (size_t i = 0; i < a.positions.size(); ++i) {
    for (int k = 0; k < 3; ++k) ASSERT_EQ(a.positions[i][k], b.positions[i][k]) << "vertex " << i;
    ASSERT_EQ(a.vertex_values[i], b.vertex_values[i]) << "vertex " << i;
  }
  EXPECT_EQ(a.triangles, b.triangles);
  EXPECT_EQ(a.face_values, b.face_values);
  EXPECT_EQ(a.schema.vertex_properties, b.schema.vertex_properties);
  EXPECT_EQ(a.schema.face_properties, b.schema.face_properties);
}

TEST(Ply, RoundTripEveryEncodingAndType) {
  Mesh m = rich_sphere();
  for (PlyEncoding enc : {PlyEncoding::kAscii, PlyEncoding::kBinaryLittleEndian, PlyEncoding::kBinaryBigEndian}) {
    std::string bytes = write_ply(m, enc);
    Mesh back;
    Status s = read_ply(bytes, &back);
    ASSERT_TRUE(s.ok()) << s.to_string();
    expect_same(m, back);
  }
}

TEST(Ply, DoublePositionsStayExact) {
  Mesh m = test::make_grid(3);
  m.schema.position_type = ScalarType::kFloat64;
  m.positions[5] = {0.1, 1.0 / 3.0, 1e-300};
  for (PlyEncoding enc : {PlyEncoding::kAscii, PlyEncoding::kBinaryLittleEndian, PlyEncoding::kBinaryBigEndian}) {
    Mesh back;
    ASSERT_TRUE(read_ply(write_ply(m, enc), &back).ok());
    EXPECT_EQ(back.schema.position_type, ScalarType::kFloat64);
    expect_same(m, back);
  }
}

TEST(Ply, UnknownCountsAreSpooled) {
  Mesh m = rich_sphere();
  m.schema.vertex_count = MeshSchema::kUnknown;
  m.schema.triangle_count = MeshSchema::kUnknown;
  Mesh back;
  ASSERT_TRUE(read_ply(write_ply(m, PlyEncoding::kBinaryLittleEndian), &back).ok());
  expect_same(m, back);
}

std::string header(const std::string& format, const std::string& body, const std::string& eol = "\n") {
  std::string h = "ply" + eol + "format " + format + " 1.0" + eol;
  size_t at = 0;
  while (at < body.size()) {
    size_t nl = body.find('\n', at);
    h += body.substr(at, nl - at) + eol;
    at = nl + 1;
  }
  return h + "end_header" + eol;
}

TEST(Ply, HeaderLineEndsCrLfAndCrWithBinaryStartingWithLf) {
  // The first float's low byte is 0x0a: a CR-only header must not eat it.
  float xs[3] = {0, 0, 0};
  uint32_t bits = 0x3f80000a;
  std::memcpy(&xs[0], &bits, 4);
  std::string data(reinterpret_cast<const char*>(xs), 12);
  for (const std::string eol : {"\n", "\r\n", "\r"}) {
    std::string f = header("binary_little_endian", "element vertex 1\nproperty float x\nproperty float y\nproperty float z\n", eol) + data;
    Mesh m;
    Status s = read_ply(f, &m);
    ASSERT_TRUE(s.ok()) << s.to_string();
    ASSERT_EQ(m.positions.size(), 1u);
    EXPECT_EQ(m.positions[0][0], static_cast<double>(xs[0]));
  }
}

TEST(Ply, PolygonsAreFansAndCounted) {
  std::string f = header("ascii", "element vertex 5\nproperty float x\nproperty float y\nproperty float z\n"
                                  "element face 2\nproperty list uchar int vertex_index\nproperty uchar c\n") +
                  "0 0 0\n1 0 0\n1 1 0\n0 1 0\n2 2 0\n4 0 1 2 3 7\n3 1 4 2 8\n";
  Mesh m;
  SourceReport r;
  ASSERT_TRUE(read_ply(f, &m, &r).ok());
  EXPECT_EQ(m.triangles, (std::vector<std::array<uint32_t, 3>>{{0, 1, 2}, {0, 2, 3}, {1, 4, 2}}));
  EXPECT_EQ(m.face_values, (std::vector<PropertyValues>{{7}, {7}, {8}}));
  EXPECT_EQ(r.polygons_triangulated, 1u);
}

TEST(Ply, TriangleStripsWithRestarts) {
  std::string f = header("ascii", "element vertex 7\nproperty float x\nproperty float y\nproperty float z\n"
                                  "element tristrips 1\nproperty list int int vertex_indices\n") +
                  "0 0 0\n1 0 0\n0 1 0\n1 1 0\n0 2 0\n1 2 0\n2 2 0\n"
                  "9 0 1 2 3 -1 4 5 6 6\n";
  Mesh m;
  SourceReport r;
  Status s = read_ply(f, &m, &r);
  ASSERT_TRUE(s.ok()) << s.to_string();
  // (0,1,2), flipped (2,1,3); restart; (4,5,6); (6,5,6) is degenerate: dropped.
  EXPECT_EQ(m.triangles, (std::vector<std::array<uint32_t, 3>>{{0, 1, 2}, {2, 1, 3}, {4, 5, 6}}));
  EXPECT_EQ(r.strip_triangles, 3u);
}

TEST(Ply, ExtraElementsAreSkippedInAsciiAndBinary) {
  Mesh m = test::make_grid(2);
  for (PlyEncoding enc : {PlyEncoding::kAscii, PlyEncoding::kBinaryLittleEndian}) {
    std::string bytes = write_ply(m, enc);
    // Insert an element with a list before the vertices and one after.
    size_t eh = bytes.find("end_header\n") + 11;
    std::string head = bytes.substr(0, eh), data = bytes.substr(eh);
    head.replace(head.find("element vertex"), 0, "element camera 2\nproperty list uchar float pose\nproperty int id\n");
    head.replace(head.find("end_header"), 0, "element material 1\nproperty uchar r\n");
    std::string pre, post;
    if (enc == PlyEncoding::kAscii) {
      pre = "2 0.5 1.5 7\n0 8\n";
      post = "255\n";
    } else {
      float fl[2] = {0.5f, 1.5f};
      int32_t ids[2] = {7, 8};
      pre += '\x02';
      pre.append(reinterpret_cast<const char*>(fl), 8);
      pre.append(reinterpret_cast<const char*>(&ids[0]), 4);
      pre += '\x00';
      pre.append(reinterpret_cast<const char*>(&ids[1]), 4);
      post = "\xff";
    }
    Mesh back;
    SourceReport r;
    Status s = read_ply(head + pre + data + post, &back, &r);
    ASSERT_TRUE(s.ok()) << s.to_string();
    expect_same(m, back);
    EXPECT_EQ(r.skipped_elements, 2u);
  }
}

TEST(Ply, TabsAndExtraBlanksInHeader) {
  std::string f = "ply\nformat   ascii 1.0\t\ncomment\t\thi\n element vertex\t3\nproperty float x\n"
                  "property      float y\nproperty float z\n\telement face 1\nproperty list uchar int vertex_indices \n"
                  "end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
  Mesh m;
  Status s = read_ply(f, &m);
  ASSERT_TRUE(s.ok()) << s.to_string();
  EXPECT_EQ(m.triangles.size(), 1u);
  EXPECT_EQ(m.schema.comments, (std::vector<std::string>{"hi"}));
}

struct BadCase {
  const char* name;
  std::string bytes;
  ErrorCode code;
};

std::string tri_header(const std::string& fmt = "ascii", int nv = 3, int nf = 1) {
  return header(fmt, "element vertex " + std::to_string(nv) + "\nproperty float x\nproperty float y\nproperty float z\n" +
                         "element face " + std::to_string(nf) + "\nproperty list uchar int vertex_indices\n");
}

TEST(Ply, MalformedInputGivesCleanErrors) {
  std::vector<BadCase> cases = {
      {"empty", "", ErrorCode::kBadHeader},
      {"no magic", "plx\nformat ascii 1.0\nend_header\n", ErrorCode::kBadHeader},
      {"no end_header", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n", ErrorCode::kBadHeader},
      {"unknown format", header("binary_middle_endian", "element vertex 0\nproperty float x\nproperty float y\nproperty float z\n"), ErrorCode::kBadHeader},
      {"unknown type", header("ascii", "element vertex 0\nproperty half x\n"), ErrorCode::kBadHeader},
      {"property before element", header("ascii", "property float x\n"), ErrorCode::kBadHeader},
      {"no vertex element", header("ascii", "element face 0\nproperty list uchar int vertex_indices\n"), ErrorCode::kBadHeader},
      {"no z", header("ascii", "element vertex 0\nproperty float x\nproperty float y\n"), ErrorCode::kBadHeader},
      {"float indices", header("ascii", "element vertex 0\nproperty float x\nproperty float y\nproperty float z\nelement face 0\nproperty list uchar float vertex_indices\n"), ErrorCode::kBadHeader},
      {"negative count", header("ascii", "element vertex -1\n"), ErrorCode::kBadHeader},
      {"absurd count", tri_header("binary_little_endian", 1000000000, 1), ErrorCode::kTruncated},
      {"absurd count ascii", tri_header("ascii", 3, 2000000000) + "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", ErrorCode::kTruncated},
      {"truncated ascii", tri_header() + "0 0 0\n1 0 0\n", ErrorCode::kTruncated},
      {"index out of range", tri_header() + "0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n", ErrorCode::kBadIndex},
      {"negative index", tri_header() + "0 0 0\n1 0 0\n0 1 0\n3 0 -1 2\n", ErrorCode::kBadIndex},
      {"nan", tri_header() + "0 nan 0\n1 0 0\n0 1 0\n3 0 1 2\n", ErrorCode::kBadValue},
      {"inf", tri_header() + "0 0 inf\n1 0 0\n0 1 0\n3 0 1 2\n", ErrorCode::kBadValue},
      {"list overruns line", tri_header() + "0 0 0\n1 0 0\n0 1 0\n4 0 1 2\n", ErrorCode::kBadValue},
      {"two corners", tri_header() + "0 0 0\n1 0 0\n0 1 0\n2 0 1\n", ErrorCode::kBadValue},
      {"malformed number", tri_header() + "0 0 0\n1 0x 0\n0 1 0\n3 0 1 2\n", ErrorCode::kBadValue},
      {"uchar out of range", tri_header() + "0 0 0\n1 0 0\n0 1 0\n300 0 1 2\n", ErrorCode::kBadValue},
      {"extra values", tri_header() + "0 0 0 5\n1 0 0\n0 1 0\n3 0 1 2\n", ErrorCode::kBadValue},
      {"trailing data", tri_header() + "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n3 0 1 2\n", ErrorCode::kBadValue},
      {"duplicate property", header("ascii", "element vertex 0\nproperty float x\nproperty float x\n"), ErrorCode::kBadHeader},
      {"header too long", "ply\nformat ascii 1.0\ncomment " + std::string(2 << 20, 'c') + "\n", ErrorCode::kLimit},
  };
  for (const BadCase& c : cases) {
    Mesh m;
    Status s = read_ply(c.bytes, &m);
    EXPECT_EQ(s.code(), c.code) << c.name << ": " << s.to_string();
    EXPECT_FALSE(s.message().empty()) << c.name;
    EXPECT_EQ(s.message().find('\n'), std::string::npos) << c.name;
  }
}

TEST(Ply, HugeElementWithoutPropertiesIsSkippedAtOnce) {
  // No property: the element takes no bytes, whatever its count claims.
  std::string f = header("binary_little_endian",
                         "element junk 18446744073709551615\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\n");
  Mesh m;
  Status s = read_ply(f, &m);
  EXPECT_TRUE(s.ok()) << s.to_string();
  EXPECT_TRUE(m.positions.empty());
}

TEST(Ply, ErrorsNameTheLineOrOffset) {
  Mesh m;
  Status s = read_ply(tri_header() + "0 0 0\n1 0 0\n0 1 0\n3 0 1 9\n", &m);
  EXPECT_EQ(s.line(), 13u) << s.to_string();
  std::string bin = write_ply(test::make_grid(1), PlyEncoding::kBinaryLittleEndian);
  size_t eh = bin.find("end_header\n") + 11;
  bin[eh + 4 * 12 + 1 + 13 + 4] = 9;  // second triangle's second index
  s = read_ply(bin, &m);
  EXPECT_EQ(s.code(), ErrorCode::kBadIndex);
  EXPECT_EQ(s.offset(), eh + 4 * 12 + 13) << s.to_string();
}

// A binary PLY of float x y z vertices and uchar-counted faces of `index`
// (int or uint) indices: mostly triangles, every 97th face a quad, in
// either byte order. Over 1 MiB, so that records straddle a file refill.
std::string layout_ply(bool big_endian, const char* index, uint32_t nv, uint32_t nf) {
  std::string f = std::string("ply\nformat ") + (big_endian ? "binary_big_endian" : "binary_little_endian") +
                  " 1.0\nelement vertex " + std::to_string(nv) +
                  "\nproperty float x\nproperty float y\nproperty float z\nelement face " + std::to_string(nf) +
                  "\nproperty list uchar " + index + " vertex_indices\nend_header\n";
  auto put = [&](const void* p, size_t n) {
    std::string b(static_cast<const char*>(p), n);
    if (big_endian) std::reverse(b.begin(), b.end());
    f += b;
  };
  for (uint32_t i = 0; i < nv; ++i) {
    const float xyz[3] = {static_cast<float>(i) * 0.25f, -static_cast<float>(i), 1.0f / static_cast<float>(i + 1)};
    for (float x : xyz) put(&x, 4);
  }
  for (uint32_t k = 0; k < nf; ++k) {
    const uint8_t n = k % 97 == 0 ? 4 : 3;
    f += static_cast<char>(n);
    for (uint32_t c = 0; c < n; ++c) {
      const uint32_t v = (k + c * 7) % nv;
      put(&v, 4);
    }
  }
  return f;
}

TEST(Ply, CommonBinaryLayoutsReadAsTheGeneralPath) {
  // Little-endian float x y z and uchar/int (or uint) triangles are read
  // without the loop over properties; big-endian files of the same layout
  // take the loop. Both give the same mesh, and the same errors at the
  // same offsets, from memory and from a file.
  test::TempDir dir;
  for (const char* index : {"int", "uint"}) {
    const std::string le = layout_ply(false, index, 50000, 110000);
    const std::string be = layout_ply(true, index, 50000, 110000);
    ASSERT_GT(le.size(), size_t{1} << 20);
    Mesh a, b;
    ASSERT_TRUE(read_ply(le, &a).ok());
    ASSERT_TRUE(read_ply(be, &b).ok());
    EXPECT_EQ(a.positions, b.positions);
    EXPECT_EQ(a.triangles, b.triangles);
    ASSERT_EQ(a.positions.size(), 50000u);
    EXPECT_EQ(a.positions[8][0], 2.0);
    EXPECT_EQ(a.triangles.size(), 110000u + (110000u + 96) / 97);
    EXPECT_EQ(a.triangles[1], (std::array<uint32_t, 3>{0, 14, 21}));  // face 0 is a quad
    EXPECT_EQ(a.triangles[2], (std::array<uint32_t, 3>{1, 8, 15}));
    // From a file: records straddle the stream's refills.
    test::write_file(dir.file("le.ply"), le);
    Mesh c;
    Status s = test::load_mesh(dir.file("le.ply"), &c);
    ASSERT_TRUE(s.ok()) << s.to_string();
    EXPECT_EQ(c.positions, a.positions);
    EXPECT_EQ(c.triangles, a.triangles);
    // Corruptions: an index out of range, a negative one (int), a face of
    // two corners, a position that is not finite, a file cut inside a face.
    // Places count from the data's start: the headers differ in length.
    const size_t hl = le.size() - (50000 * 12 + 110000u * 13 + (110000u + 96) / 97 * 4);
    const size_t hb = be.size() - (le.size() - hl);
    const size_t face_500 = 50000 * 12 + 500 * 13 + 6 * 4;  // after 6 quads
    const size_t vertex_9 = 9 * 12;
    std::vector<std::pair<std::string, std::string>> bad;
    auto corrupt = [&](size_t at, const std::string& bytes_le, const std::string& bytes_be) {
      std::string x = le, y = be;
      x.replace(hl + at, bytes_le.size(), bytes_le);
      y.replace(hb + at, bytes_be.size(), bytes_be);
      bad.push_back({x, y});
    };
    corrupt(face_500 + 1, std::string("\x50\xc3\x00\x00", 4), std::string("\x00\x00\xc3\x50", 4));  // 50000
    corrupt(face_500 + 5, std::string("\xff\xff\xff\xff", 4), std::string("\xff\xff\xff\xff", 4));  // -1 or 2^32-1
    corrupt(face_500, std::string("\x02", 1), std::string("\x02", 1));
    corrupt(vertex_9 + 4, std::string("\x00\x00\xc0\x7f", 4), std::string("\x7f\xc0\x00\x00", 4));  // NaN
    for (size_t i = 0; i < bad.size(); ++i) {
      Mesh m;
      Status sl = read_ply(bad[i].first, &m);
      Status sb = read_ply(bad[i].second, &m);
      EXPECT_FALSE(sl.ok()) << index << " case " << i;
      EXPECT_EQ(sl.code(), sb.code()) << index << " case " << i;
      EXPECT_EQ(sl.message(), sb.message()) << index << " case " << i;
      EXPECT_EQ(sl.offset() - hl, sb.offset() - hb) << index << " case " << i;
    }
  }
}

TEST(Ply, EveryTruncatedPrefixFailsCleanly) {
  std::string full = write_ply(rich_sphere(), PlyEncoding::kBinaryBigEndian);
  size_t step = full.size() / 400 + 1;
  for (size_t n = 0; n < full.size(); n += step) {
    Mesh m;
    Status s = read_ply(full.substr(0, n), &m);
    ASSERT_FALSE(s.ok()) << "prefix " << n;
  }
  std::string ascii = write_ply(rich_sphere(), PlyEncoding::kAscii);
  for (size_t n = 0; n + 1 < ascii.size(); n += ascii.size() / 300 + 1) {
    Mesh m;
    Status s = read_ply(ascii.substr(0, n), &m);
    // A cut exactly at a line end inside the data is still a short file.
    ASSERT_FALSE(s.ok()) << "prefix " << n;
  }
}

TEST(Ply, RandomCorruptionNeverCrashes) {
  std::string full = write_ply(rich_sphere(), PlyEncoding::kBinaryLittleEndian);
  std::mt19937 rng(42);
  int failures = 0;
  for (int i = 0; i < 300; ++i) {
    std::string bad = full;
    for (int k = 0; k < 4; ++k) bad[rng() % bad.size()] ^= static_cast<char>(1 << (rng() % 8));
    Mesh m;
    if (!read_ply(bad, &m).ok()) ++failures;
  }
  EXPECT_GT(failures, 0);
}

// A float PLY cannot hold a finite double beyond float range: the writer
// refuses it (naming the vertex) rather than write an infinity, in every
// encoding; doubles stay doubles.
TEST(Ply, WriterRefusesFloatsBeyondTheirRange) {
  for (PlyEncoding enc : {PlyEncoding::kAscii, PlyEncoding::kBinaryLittleEndian, PlyEncoding::kBinaryBigEndian}) {
    Mesh m = test::make_grid(1);
    m.positions[2][1] = -3.5e38;
    test::TempDir dir;
    OutputFile out;
    ASSERT_TRUE(out.open(dir.file("m.ply"), false).ok());
    PlyWriteOptions o;
    o.encoding = enc;
    PlyWriter writer(&out, o);
    test::MemorySource source(m);
    Status s = pump(source, writer);
    EXPECT_EQ(s.code(), ErrorCode::kBadValue) << s.to_string();
    EXPECT_NE(s.message().find("-3.5e+38"), std::string::npos) << s.to_string();
    // A float property.
    m = test::make_grid(1);
    m.schema.vertex_properties.push_back({"quality", ScalarType::kFloat32});
    for (auto& v : m.vertex_values) v = {1};
    m.vertex_values[3] = {1e300};
    OutputFile out2;
    ASSERT_TRUE(out2.open(dir.file("n.ply"), false).ok());
    PlyWriter writer2(&out2, o);
    test::MemorySource source2(m);
    s = pump(source2, writer2);
    EXPECT_EQ(s.code(), ErrorCode::kBadValue) << s.to_string();
    // Doubles are written.
    m = test::make_grid(1);
    m.schema.position_type = ScalarType::kFloat64;
    m.positions[2][1] = -3.5e300;
    Mesh back;
    ASSERT_TRUE(read_ply(write_ply(m, enc), &back).ok());
    EXPECT_EQ(back.positions[2][1], -3.5e300);
  }
}

// ------------------------------------------------------ header leniency

// One triangle's header and binary little-endian data: float x y z, then a
// face with an int index list.
std::string binary_triangle_data() {
  std::string d;
  const float xyz[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  d.append(reinterpret_cast<const char*>(xyz), sizeof xyz);
  d.push_back(3);
  const int32_t idx[3] = {0, 1, 2};
  d.append(reinterpret_cast<const char*>(idx), sizeof idx);
  return d;
}

TEST(PlyHeader, BareTextLineIsReadAsACommentWithANote) {
  // Blender 2.47 wrote this line without "comment".
  const std::string line = "Created by Blender3D 247 - www.blender.org, source file: ''";
  std::string f = "ply\nformat ascii 1.0\n" + line + "\nelement vertex 3\nproperty float x\nproperty float y\n"
                  "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
                  "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
  Mesh m;
  SourceReport r;
  Status s = read_ply(f, &m, &r);
  ASSERT_TRUE(s.ok()) << s.to_string();
  EXPECT_EQ(m.triangles.size(), 1u);
  ASSERT_EQ(r.notes.size(), 1u);
  EXPECT_NE(r.notes[0].find("header line 3"), std::string::npos) << r.notes[0];
  EXPECT_NE(r.notes[0].find("Created by Blender3D"), std::string::npos) << r.notes[0];
  ASSERT_EQ(m.schema.comments.size(), 1u);
  EXPECT_EQ(m.schema.comments[0], line);
  // Also between declarations, and in a binary file.
  f = "ply\nformat binary_little_endian 1.0\nelement vertex 3\nexported by some tool, v1.2\nproperty float x\n"
      "property float y\nproperty float z\nelement face 1\n  made on a Tuesday  \nproperty list uchar int "
      "vertex_indices\nend_header\n" + binary_triangle_data();
  s = read_ply(f, &m, &r);
  ASSERT_TRUE(s.ok()) << s.to_string();
  EXPECT_EQ(m.triangles.size(), 1u);
  EXPECT_EQ(r.notes.size(), 2u);
  EXPECT_EQ(m.schema.comments.back(), "made on a Tuesday");
}

TEST(PlyHeader, ManyUnknownLinesGiveBoundedNotes) {
  std::string f = "ply\nformat ascii 1.0\n";
  for (int i = 0; i < 1000; ++i) f += "some text " + std::to_string(i) + " here\n";
  f += "element vertex 0\nproperty float x\nproperty float y\nproperty float z\nend_header\n";
  Mesh m;
  SourceReport r;
  Status s = read_ply(f, &m, &r);
  ASSERT_TRUE(s.ok()) << s.to_string();
  ASSERT_LE(r.notes.size(), 10u);
  EXPECT_NE(r.notes.back().find("992 more"), std::string::npos) << r.notes.back();
}

TEST(PlyHeader, UnknownLinesThatCouldBeStructureAreErrors) {
  const std::string tail = "element vertex 0\nproperty float x\nproperty float y\nproperty float z\nend_header\n";
  struct Case {
    const char* name;
    std::string bytes;
    const char* says;
  } cases[] = {
      {"before format", "ply\nCreated by me\nformat ascii 1.0\n" + tail, "before the format line"},
      {"keyword case", "ply\nformat ascii 1.0\nElement vertex 0\n" + tail, "lower case"},
      {"upper property", "ply\nformat ascii 1.0\nelement vertex 0\nPROPERTY float x\n", "lower case"},
      {"misspelled property", "ply\nformat ascii 1.0\nelement vertex 0\npropery float x\n", "property declaration"},
      {"misspelled list", "ply\nformat ascii 1.0\n" + tail.substr(0, tail.size() - 11) +
                              "element face 0\nprop list uchar int vertex_indices\nend_header\n",
       "property declaration"},
      {"misspelled element", "ply\nformat ascii 1.0\nelemnt vertex 3\n" + tail, "element declaration"},
      {"no format", "ply\n" + tail, "no format line"},
      {"two formats", "ply\nformat ascii 1.0\nformat binary_little_endian 1.0\n" + tail, "second format"},
  };
  for (const Case& c : cases) {
    Mesh m;
    Status s = read_ply(c.bytes, &m);
    EXPECT_EQ(s.code(), ErrorCode::kBadHeader) << c.name << ": " << s.to_string();
    EXPECT_NE(s.message().find(c.says), std::string::npos) << c.name << ": " << s.to_string();
    EXPECT_NE(s.line(), Status::kNoPlace) << c.name;
  }
}

// The header's lines end in `eol`, end_header's in `end_eol`.
std::string mixed_header(const std::string& body, const std::string& eol, const std::string& end_eol,
                         const std::string& format = "binary_little_endian") {
  std::string h = header(format, body, eol);
  return h.substr(0, h.size() - eol.size()) + end_eol;
}

const char kTriangleBody[] =
    "element vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
    "element face 1\nproperty list uchar int vertex_indices\n";
const char kPointBody[] = "element vertex 1\nproperty float x\nproperty float y\nproperty float z\n";

TEST(PlyHeader, EndHeaderLineEndDecidesWhereBinaryDataStarts) {
  // Each line's own end counts: an LF header whose end_header ends in CRLF
  // (and every other mix) reads the same triangle.
  for (const char* eol : {"\n", "\r\n", "\r"}) {
    for (const char* end_eol : {"\n", "\r\n", "\r"}) {
      if (std::string(eol) == "\r" && std::string(end_eol) == "\r\n") continue;  // ambiguous: below
      std::string f = mixed_header(kTriangleBody, eol, end_eol) + binary_triangle_data();
      Mesh m;
      Status s = read_ply(f, &m);
      ASSERT_TRUE(s.ok()) << "eol " << int(eol[0]) << " end " << int(end_eol[0]) << ": " << s.to_string();
      ASSERT_EQ(m.triangles.size(), 1u);
      EXPECT_EQ(m.positions[1][0], 1.0);
    }
  }
  // Mixed within the header too.
  std::string f = "ply\r\nformat binary_little_endian 1.0\nelement vertex 3\rproperty float x\r\nproperty float y\n"
                  "property float z\relement face 1\nproperty list uchar int vertex_indices\r\nend_header\r\n" +
                  binary_triangle_data();
  Mesh m;
  Status s = read_ply(f, &m);
  ASSERT_TRUE(s.ok()) << s.to_string();
  EXPECT_EQ(m.triangles.size(), 1u);
}

TEST(PlyHeader, CrHeaderWithCrLfEndHeaderIsSettledByTheDataSize) {
  // A CR-only header, "end_header\r\n": either a CR line end and data whose
  // first byte is 0x0a, or a CRLF. Fixed-size data settles it.
  float xs[3] = {0, 2, 3};
  uint32_t bits = 0x3f80000a;  // low byte 0x0a
  std::memcpy(&xs[0], &bits, 4);
  std::string data(reinterpret_cast<const char*>(xs), 12);
  Mesh m;
  // CR, then data starting with 0x0a.
  Status s = read_ply(mixed_header(kPointBody, "\r", "\r") + data, &m);
  ASSERT_TRUE(s.ok()) << s.to_string();
  ASSERT_EQ(m.positions.size(), 1u);
  EXPECT_EQ(m.positions[0][0], static_cast<double>(xs[0]));
  // CRLF, then the data.
  const float ys[3] = {5, 6, 7};
  s = read_ply(mixed_header(kPointBody, "\r", "\r\n") + std::string(reinterpret_cast<const char*>(ys), 12), &m);
  ASSERT_TRUE(s.ok()) << s.to_string();
  ASSERT_EQ(m.positions.size(), 1u);
  EXPECT_EQ(m.positions[0][0], 5.0);
  // With a list the size does not settle it: read as the header's CR, and
  // an error that follows names the doubt.
  s = read_ply(mixed_header(kTriangleBody, "\r", "\r\n") + binary_triangle_data(), &m);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("end_header's line end was read as a lone CR"), std::string::npos) << s.to_string();
}

TEST(PlyHeader, MissingEndHeaderIsNamedWithItsPlace) {
  const std::string head = "ply\nformat binary_little_endian 1.0\n" + std::string(kTriangleBody);
  Mesh m;
  // The header runs to the end of the input.
  Status s = read_ply(head, &m);
  EXPECT_EQ(s.code(), ErrorCode::kBadHeader);
  EXPECT_NE(s.message().find("missing end_header"), std::string::npos) << s.to_string();
  EXPECT_EQ(s.line(), 9u) << s.to_string();
  // Binary data where end_header should be.
  s = read_ply(head + binary_triangle_data(), &m);
  EXPECT_EQ(s.code(), ErrorCode::kBadHeader);
  EXPECT_NE(s.message().find("missing end_header"), std::string::npos) << s.to_string();
  EXPECT_EQ(s.offset(), head.size()) << s.to_string();
  EXPECT_EQ(s.line(), 9u) << s.to_string();
  // An absurdly long header: blank lines or one long line, from a pipe too,
  // end at 1 MiB.
  for (const std::string& filler : {std::string(3 << 20, '\n'), std::string(3 << 20, 'x')}) {
    s = read_ply("ply\nformat ascii 1.0\n" + filler, &m);
    EXPECT_EQ(s.code(), ErrorCode::kLimit) << s.to_string();
    EXPECT_NE(s.message().find("missing end_header"), std::string::npos) << s.to_string();
  }
  // end_header at the very end, without a line end: an empty mesh.
  s = read_ply("ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\nend_header", &m);
  EXPECT_TRUE(s.ok()) << s.to_string();
  // "end_header" inside a comment is not the end.
  s = read_ply("ply\nformat ascii 1.0\ncomment end_header\n", &m);
  EXPECT_NE(s.message().find("missing end_header"), std::string::npos) << s.to_string();
}

TEST(PlyHeader, LongHeaderFromAPipeStopsAtTheLimit) {
  std::signal(SIGPIPE, SIG_IGN);
  test::TempDir dir;
  std::string path = dir.file("fifo");
  ASSERT_EQ(::mkfifo(path.c_str(), 0600), 0);
  std::thread writer([&] {
    int fd = ::open(path.c_str(), O_WRONLY);
    std::string chunk = "ply\nformat ascii 1.0\n";
    std::string blank(1 << 16, '\n');
    bool ok = ::write(fd, chunk.data(), chunk.size()) > 0;
    // Far more than the limit: the reader must stop on its own.
    for (int i = 0; ok && i < 64; ++i) ok = ::write(fd, blank.data(), blank.size()) > 0;
    ::close(fd);
  });
  {
    InputStream in;
    ASSERT_TRUE(in.open(path).ok());
    PlyReader reader;
    Status s = reader.open(&in);
    EXPECT_EQ(s.code(), ErrorCode::kLimit) << s.to_string();
    EXPECT_LE(in.offset(), (1u << 20) + 64);
  }  // closes the pipe: the writer's next write fails (EPIPE, ignored)
  writer.join();
}

// ---------------------------------------------------------- shared real data

std::string shared(const std::string& rel) { return std::string(PSQ_SHARED_DATA) + "/" + rel; }

TEST(PlyShared, FandiskInEveryEncodingAgrees) {
  if (!test::file_exists(shared("meshes/fandisk.ply"))) GTEST_SKIP() << "../shared/data not present";
  Mesh ref;
  ASSERT_TRUE(test::load_mesh(shared("meshes/fandisk.ply"), &ref).ok());
  EXPECT_EQ(ref.positions.size(), 6475u);
  EXPECT_EQ(ref.triangles.size(), 12946u);
  for (const char* v : {"inputs/fandisk.ascii.ply", "inputs/fandisk.be.ply", "inputs/fandisk.crlf.ply", "inputs/fandisk.rich.ply"}) {
    Mesh m;
    Status s = test::load_mesh(shared(v), &m);
    ASSERT_TRUE(s.ok()) << v << ": " << s.to_string();
    EXPECT_EQ(m.triangles, ref.triangles) << v;
    ASSERT_EQ(m.positions.size(), ref.positions.size()) << v;
    for (size_t i = 0; i < m.positions.size(); ++i) {
      for (int k = 0; k < 3; ++k) {
        ASSERT_NEAR(m.positions[i][k], ref.positions[i][k], 1e-6) << v << " vertex " << i;
      }
    }
  }
  Mesh rich;
  ASSERT_TRUE(test::load_mesh(shared("inputs/fandisk.rich.ply"), &rich).ok());
  ASSERT_EQ(rich.schema.vertex_properties.size(), 6u);
  EXPECT_EQ(rich.schema.vertex_properties[0].name, "nx");
  ASSERT_EQ(rich.schema.face_properties.size(), 1u);
  EXPECT_EQ(rich.schema.face_properties[0].name, "flags");
}

TEST(PlyShared, BadFilesFail) {
  if (!test::file_exists(shared("bad/fandisk.bad_nan.ply"))) GTEST_SKIP() << "../shared/data not present";
  const std::pair<const char*, ErrorCode> cases[] = {
      {"bad/fandisk.bad_truncated.ply", ErrorCode::kTruncated},
      {"bad/fandisk.bad_index_range.ply", ErrorCode::kBadIndex},
      {"bad/fandisk.bad_index_negative.ply", ErrorCode::kBadIndex},
      {"bad/fandisk.bad_count_too_big.ply", ErrorCode::kTruncated},
      {"bad/fandisk.bad_no_end_header.ply", ErrorCode::kBadHeader},
      {"bad/fandisk.bad_list_count.ply", ErrorCode::kBadValue},
      {"bad/fandisk.bad_nan.ply", ErrorCode::kBadValue},
      {"bad/assimp_empty.ply", ErrorCode::kUnknownFormat},
  };
  for (const auto& c : cases) {
    Mesh m;
    Status s = test::load_mesh(shared(c.first), &m);
    EXPECT_EQ(s.code(), c.second) << c.first << ": " << s.to_string();
  }
}

}  // namespace
}  // namespace psq
