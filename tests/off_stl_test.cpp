// SPDX-License-Identifier: Apache-2.0
// Tests of the OFF and STL readers (psq/off.h, psq/stl.h): layouts, welding,
// detection and hostile input.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstring>
#include <limits>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "psq/off.h"
#include "psq/ply.h"
#include "psq/stl.h"
#include "test_util.h"

namespace psq {
namespace {

using test::Mesh;
using test::MemorySink;
using Tri = std::array<uint32_t, 3>;
using Pos = std::array<double, 3>;

const std::string kShared = PSQ_SHARED_DATA;

std::string shared(const std::string& rel) { return kShared + "/" + rel; }

template <typename Reader>
Status read_all(InputStream* in, Mesh* mesh, SourceReport* report) {
  Reader reader;
  PSQ_RETURN_IF_ERROR(reader.open(in));
  MemorySink sink;
  Status s = pump(reader, sink);
  if (report != nullptr) *report = reader.report();
  PSQ_RETURN_IF_ERROR(s);
  // Errors are sticky; after the end, kEnd again.
  MeshItem item;
  PSQ_RETURN_IF_ERROR(reader.next(&item));
  if (item.kind != MeshItem::Kind::kEnd) return Status(ErrorCode::kInternal, "no kEnd after the end");
  *mesh = std::move(sink.mesh);
  return Status();
}

template <typename Reader>
Status read_memory(const std::string& bytes, Mesh* mesh = nullptr, SourceReport* report = nullptr) {
  InputStream in;
  in.open_memory(bytes.data(), bytes.size(), "test");
  Mesh scratch;
  return read_all<Reader>(&in, mesh != nullptr ? mesh : &scratch, report);
}

template <typename Reader>
Status read_path(const std::string& path, Mesh* mesh, SourceReport* report = nullptr) {
  InputStream in;
  PSQ_RETURN_IF_ERROR(in.open(path));
  return read_all<Reader>(&in, mesh, report);
}

// Through a pipe: the size is unknown.
template <typename Reader>
Status read_pipe(const std::string& bytes, Mesh* mesh = nullptr) {
  std::signal(SIGPIPE, SIG_IGN);  // the reader may stop early
  int fds[2];
  if (::pipe(fds) != 0) return Status(ErrorCode::kIo, "pipe failed");
  std::thread writer([&] {
    size_t done = 0;
    while (done < bytes.size()) {
      ssize_t w = ::write(fds[1], bytes.data() + done, bytes.size() - done);
      if (w <= 0) break;
      done += static_cast<size_t>(w);
    }
    ::close(fds[1]);
  });
  Status s;
  {
    InputStream in;
    s = in.open_fd(fds[0], true, "pipe");
    if (s.ok() && in.size() >= 0) s = Status(ErrorCode::kInternal, "a pipe has no size");
    Mesh scratch;
    if (s.ok()) s = read_all<Reader>(&in, mesh != nullptr ? mesh : &scratch, nullptr);
  }  // closes the read end: a blocked writer gets EPIPE
  writer.join();
  return s;
}

bool has_note(const SourceReport& r, const std::string& part) {
  for (const std::string& n : r.notes) {
    if (n.find(part) != std::string::npos) return true;
  }
  return false;
}

bool looks_off(const std::string& s) {
  return looks_like_off(reinterpret_cast<const uint8_t*>(s.data()), s.size());
}

bool looks_stl(const std::string& s, bool known_size = true) {
  return looks_like_stl(reinterpret_cast<const uint8_t*>(s.data()), s.size(),
                        known_size ? static_cast<int64_t>(s.size()) : -1);
}

// ---------------------------------------------------------------- OFF

const char kCube[] =
    "OFF 8 6 0\n"
    "0 0 0\n1 0 0\n1 1 0\n0 1 0\n0 0 1\n1 0 1\n1 1 1\n0 1 1\n"
    "4 0 3 2 1\n4 4 5 6 7\n4 0 1 5 4\n4 1 2 6 5\n4 2 3 7 6\n4 3 0 4 7\n";

TEST(Off, CubeOfQuads) {
  Mesh m;
  SourceReport r;
  ASSERT_TRUE(read_memory<OffReader>(kCube, &m, &r).ok());
  EXPECT_EQ(m.schema.vertex_count, 8);
  EXPECT_EQ(m.schema.triangle_count, MeshSchema::kUnknown);
  EXPECT_EQ(m.schema.position_type, ScalarType::kFloat32);
  EXPECT_TRUE(m.schema.vertex_properties.empty());
  EXPECT_TRUE(m.schema.face_properties.empty());
  ASSERT_EQ(m.positions.size(), 8u);
  EXPECT_EQ(m.positions[6], (Pos{1, 1, 1}));
  ASSERT_EQ(m.triangles.size(), 12u);
  EXPECT_EQ(m.triangles[0], (Tri{0, 3, 2}));
  EXPECT_EQ(m.triangles[1], (Tri{0, 2, 1}));
  EXPECT_EQ(r.polygons_triangulated, 6u);
  for (const PropertyValues& v : m.vertex_values) EXPECT_TRUE(v.empty());
}

TEST(Off, HeaderLayouts) {
  const std::string body = "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
  for (const std::string& head :
       {std::string("OFF\n3 1 0\n"), std::string("OFF\n3 1\n"), std::string("OFF 3 1 0\n"), std::string("OFF3 1 0\n"),
        std::string("# a comment\n\nOFF # keyword\n# more\n\n  3   1   3  \n"), std::string("\xEF\xBB\xBFOFF\n3 1 0\n"),
        std::string("OFF\n+3 +1 -1\n")}) {
    Mesh m;
    Status s = read_memory<OffReader>(head + body, &m);
    ASSERT_TRUE(s.ok()) << head << ": " << s.to_string();
    EXPECT_EQ(m.positions.size(), 3u) << head;
    EXPECT_EQ(m.triangles, (std::vector<Tri>{{0, 1, 2}})) << head;
  }
  // CRLF and CR line ends, comments and blank lines between elements, '+'.
  Mesh m;
  SourceReport r;
  Status s = read_memory<OffReader>(
      "# made by hand\r\nOFF\r\n3 1 0\r\n\r\n+0.5 0 0 # first\r0 1e-2 0\r\n# gap\r\n0 0 -1.5\r\n3 0 1 2\r\n\r\n# end\r\n",
      &m, &r);
  ASSERT_TRUE(s.ok()) << s.to_string();
  EXPECT_EQ(m.positions, (std::vector<Pos>{{0.5, 0, 0}, {0, 0.01f, 0}, {0, 0, -1.5}}));
  EXPECT_EQ(m.schema.comments, (std::vector<std::string>{"made by hand"}));
  EXPECT_EQ(m.schema.triangle_count, MeshSchema::kUnknown);
  // No faces: the triangle count is known.
  ASSERT_TRUE(read_memory<OffReader>("OFF\n1 0 0\n1 2 3\n", &m).ok());
  EXPECT_EQ(m.schema.triangle_count, 0);
  EXPECT_EQ(m.positions.size(), 1u);
  ASSERT_TRUE(read_memory<OffReader>("OFF\n0 0 0\n", &m).ok());
  EXPECT_TRUE(m.positions.empty());
}

TEST(Off, ColoursAndNormals) {
  Mesh m;
  SourceReport r;
  ASSERT_TRUE(read_memory<OffReader>("COFF\n3 1 0\n0 0 0 255 0 0 255\n1 0 0 0 255 0 128\n0 1 0 0 0 255 0\n3 0 1 2\n",
                                     &m, &r)
                  .ok());
  ASSERT_EQ(m.schema.vertex_properties.size(), 4u);
  EXPECT_EQ(m.schema.vertex_properties[0].name, "red");
  EXPECT_EQ(m.schema.vertex_properties[3].name, "alpha");
  EXPECT_EQ(m.schema.vertex_properties[3].type, ScalarType::kFloat32);
  EXPECT_EQ(m.vertex_values[1], (PropertyValues{0, 255, 0, 128}));
  EXPECT_TRUE(has_note(r, "vertex colours"));

  ASSERT_TRUE(read_memory<OffReader>("CNOFF 3 1 0\n0 0 0 0 0 1 1 0.5 0\n1 0 0 0 0 1 0 1 0\n0 1 0 0 0 -1 0 0 1\n"
                                     "3 0 1 2\n",
                                     &m)
                  .ok());
  ASSERT_EQ(m.schema.vertex_properties.size(), 6u);
  const char* names[] = {"nx", "ny", "nz", "red", "green", "blue"};
  for (int i = 0; i < 6; ++i) EXPECT_EQ(m.schema.vertex_properties[i].name, names[i]);
  EXPECT_EQ(m.vertex_values[0], (PropertyValues{0, 0, 1, 1, 0.5, 0}));
  EXPECT_EQ(m.vertex_values[2], (PropertyValues{0, 0, -1, 0, 0, 1}));
  for (size_t i = 0; i < m.positions.size(); ++i) {
    EXPECT_TRUE(values_match(m.schema.vertex_properties, m.vertex_values[i]));
  }

  ASSERT_TRUE(read_memory<OffReader>("NOFF\n3 1 0\n0 0 0 0 0 1\n1 0 0 0 0 1\n0 1 0 0 0 1\n3 0 1 2\n", &m).ok());
  ASSERT_EQ(m.schema.vertex_properties.size(), 3u);
  EXPECT_EQ(m.vertex_values[1], (PropertyValues{0, 0, 1}));

  // COFF without vertices declares r g b.
  ASSERT_TRUE(read_memory<OffReader>("COFF\n0 0 0\n", &m).ok());
  EXPECT_EQ(m.schema.vertex_properties.size(), 3u);

  // The first vertex line decides 3 or 4 components for every line.
  Status s = read_memory<OffReader>("COFF\n2 0 0\n0 0 0 1 1 1\n0 0 0 1 1 1 1\n");
  EXPECT_EQ(s.code(), ErrorCode::kBadValue);
  EXPECT_EQ(s.line(), 4u);
  s = read_memory<OffReader>("COFF\n2 0 0\n0 0 0 1 1\n0 0 0 1 1 1\n");
  EXPECT_EQ(s.code(), ErrorCode::kBadValue);
  EXPECT_EQ(s.line(), 3u);
}

TEST(Off, FaceColoursAreSkipped) {
  Mesh m;
  SourceReport r;
  ASSERT_TRUE(read_memory<OffReader>("OFF\n4 2 0\n0 0 0\n1 0 0\n0 1 0\n1 1 0\n3 0 1 2 255 0 0\n3 1 3 2\n", &m, &r).ok());
  EXPECT_EQ(m.triangles, (std::vector<Tri>{{0, 1, 2}, {1, 3, 2}}));
  EXPECT_TRUE(has_note(r, "face colours ignored (1 faces"));
  ASSERT_TRUE(read_memory<OffReader>(kCube, &m, &r).ok());
  EXPECT_FALSE(has_note(r, "face colours"));
  // More than a colour after the indices.
  Status s = read_memory<OffReader>("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2 1 1 1 1 1\n");
  EXPECT_EQ(s.code(), ErrorCode::kBadValue);
  EXPECT_EQ(s.line(), 6u);
  s = read_memory<OffReader>("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2 red\n");
  EXPECT_EQ(s.code(), ErrorCode::kBadValue);
}

struct BadCase {
  const char* text;
  ErrorCode code;
  uint64_t line;
};

TEST(Off, BadInput) {
  const BadCase cases[] = {
      {"", ErrorCode::kBadHeader, 1},
      {"# only a comment\n", ErrorCode::kBadHeader, 2},
      {"PLY\n3 1 0\n", ErrorCode::kBadHeader, 1},
      {"OFFICE 3 1 0\n", ErrorCode::kBadHeader, 1},
      {"STOFF\n3 1 0\n", ErrorCode::kUnsupported, 1},
      {"4OFF\n3 1 0\n", ErrorCode::kUnsupported, 1},
      {"nOFF\n3\n3 1 0\n", ErrorCode::kUnsupported, 1},
      {"OFF BINARY\n", ErrorCode::kUnsupported, 1},
      {"OFF\n", ErrorCode::kTruncated, 2},
      {"OFF\n3\n", ErrorCode::kBadHeader, 2},
      {"OFF\n3 1 0 7\n", ErrorCode::kBadHeader, 2},
      {"OFF\n3 x 0\n", ErrorCode::kBadHeader, 2},
      {"OFF\n-3 1 0\n", ErrorCode::kBadHeader, 2},
      {"OFF\n3 1 e\n", ErrorCode::kBadHeader, 2},
      {"OFF\n99999999999999999999999 1 0\n", ErrorCode::kLimit, 2},
      {"OFF\n5000000000 1 0\n", ErrorCode::kLimit, 2},
      {"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n2 0 1\n", ErrorCode::kBadValue, 6},
      {"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n-3 0 1 2\n", ErrorCode::kBadValue, 6},
      {"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n4 0 1 2\n", ErrorCode::kBadValue, 6},
      {"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n", ErrorCode::kBadIndex, 6},
      {"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 -1 2\n", ErrorCode::kBadIndex, 6},
      {"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 99999999999999999999\n", ErrorCode::kBadIndex, 6},
      {"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 1.5\n", ErrorCode::kBadValue, 6},
      {"OFF\n3 1 0\n0 0 0\nnan 0 0\n0 1 0\n3 0 1 2\n", ErrorCode::kBadValue, 4},
      {"OFF\n3 1 0\n0 0 0\n1 0 0\n0 inf 0\n3 0 1 2\n", ErrorCode::kBadValue, 5},
      {"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1e39 0\n3 0 1 2\n", ErrorCode::kBadValue, 5},
      {"OFF\n3 1 0\n0 0 0\n1 0\n0 1 0\n3 0 1 2\n", ErrorCode::kBadValue, 4},
      {"OFF\n3 1 0\n0 0 0\n1 0 0 0\n0 1 0\n3 0 1 2\n", ErrorCode::kBadValue, 4},
      {"OFF\n3 1 0\n0 0 0\n1 x 0\n0 1 0\n3 0 1 2\n", ErrorCode::kBadValue, 4},
      {"OFF\n3 1 0\n0 0 0\n1 ++0 0\n0 1 0\n3 0 1 2\n", ErrorCode::kBadValue, 4},
      {"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n3 0 1 2\n", ErrorCode::kBadValue, 7},
      {"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\nend\n", ErrorCode::kBadValue, 7},
      {"OFF\n3 2 0\n0.0000 0 0\n1.0000 0 0\n0.0000 1 0\n3 0 1 2\n", ErrorCode::kTruncated, 7},
      {"OFF\n3 2 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n# comment\n\n                   \n", ErrorCode::kTruncated, 10},
  };
  for (const BadCase& c : cases) {
    Status s = read_memory<OffReader>(c.text);
    EXPECT_EQ(s.code(), c.code) << c.text << " -> " << s.to_string();
    EXPECT_EQ(s.line(), c.line) << c.text << " -> " << s.to_string();
    EXPECT_EQ(s.to_string().find('\n'), std::string::npos);
  }
}

// Comments and blank lines before the keyword and counts are skipped, but
// only within 1 MiB: a header that never ends is an error, not a hang.
TEST(Off, HeaderIsBounded) {
  std::string comments;
  while (comments.size() < (3u << 20)) comments += "# a comment line of some length\n";
  for (const std::string& text : {comments + "OFF\n3 1 0\n", std::string(3u << 20, '\n') + "OFF\n3 1 0\n",
                                  "OFF\n" + std::string(3u << 20, '\n') + "3 1 0\n"}) {
    Status s = read_memory<OffReader>(text);
    EXPECT_EQ(s.code(), ErrorCode::kLimit) << s.to_string();
    EXPECT_NE(s.message().find("first 1 MiB"), std::string::npos) << s.to_string();
  }
  // Within the limit, the comments are fine.
  Status s = read_memory<OffReader>(comments.substr(0, 500000) + "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
  EXPECT_TRUE(s.ok()) << s.to_string();
}

TEST(Off, CountsBeyondTheFileFailUpFront) {
  // A count the remaining bytes cannot hold: kTruncated with the offset
  // where the data begins, before any line is read.
  Status s = read_memory<OffReader>("OFF\n1000 0 0\n0 0 0\n");
  EXPECT_EQ(s.code(), ErrorCode::kTruncated);
  EXPECT_EQ(s.offset(), 13u);
  EXPECT_NE(s.message().find("1000 vertices"), std::string::npos) << s.message();
  s = read_memory<OffReader>("OFF\n3 4000000000000 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
  EXPECT_EQ(s.code(), ErrorCode::kTruncated);
  EXPECT_NE(s.message().find("4000000000000 faces"), std::string::npos) << s.message();
  // Exactly the minimum fits; a final line without its line end too.
  EXPECT_TRUE(read_memory<OffReader>("OFF\n3 1 0\n0 0 0\n0 0 0\n0 0 0\n3 0 1 2").ok());
  // Through a pipe the size is unknown: the file ends early instead.
  s = read_pipe<OffReader>("OFF\n3 4000000000000 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
  EXPECT_EQ(s.code(), ErrorCode::kTruncated);
  EXPECT_EQ(s.line(), 7u);
  s = read_pipe<OffReader>("OFF\n5000000000 1 0\n");
  EXPECT_EQ(s.code(), ErrorCode::kLimit);
}

TEST(Off, EveryPrefixFailsCleanly) {
  const std::string full = "# c\nCOFF 4 2 0\n0 0 0 1 0 0\n1 0 0 0 1 0\n0 1 0 0 0 1\n1 1 0 1 1 1\n3 0 1 2\n4 1 3 2 0\n";
  Mesh ref;
  ASSERT_TRUE(read_memory<OffReader>(full, &ref).ok());
  EXPECT_EQ(ref.triangles.size(), 3u);
  for (size_t n = 0; n < full.size(); ++n) {
    std::string prefix = full.substr(0, n);
    Mesh m;
    Status s = read_memory<OffReader>(prefix, &m);
    if (n + 1 == full.size()) {
      EXPECT_TRUE(s.ok()) << s.to_string();  // only the final line end is missing
      continue;
    }
    EXPECT_FALSE(s.ok()) << n;
    EXPECT_TRUE(s.code() == ErrorCode::kTruncated || s.code() == ErrorCode::kBadValue ||
                s.code() == ErrorCode::kBadHeader || s.code() == ErrorCode::kBadIndex)
        << n << ": " << s.to_string();
  }
}

TEST(Off, ReadsFromAPipe) {
  std::string text = "OFF\n";
  const int n = 200;
  text += std::to_string((n + 1) * (n + 1)) + " " + std::to_string(n * n) + " 0\n";
  for (int y = 0; y <= n; ++y) {
    for (int x = 0; x <= n; ++x) text += std::to_string(x) + " " + std::to_string(y) + " 0\n";
  }
  for (int y = 0; y < n; ++y) {
    for (int x = 0; x < n; ++x) {
      int a = y * (n + 1) + x;
      text += "4 " + std::to_string(a) + " " + std::to_string(a + 1) + " " + std::to_string(a + n + 2) + " " +
              std::to_string(a + n + 1) + "\n";
    }
  }
  ASSERT_GT(text.size(), size_t{1} << 17);
  Mesh m;
  Status s = read_pipe<OffReader>(text, &m);
  ASSERT_TRUE(s.ok()) << s.to_string();
  EXPECT_EQ(m.positions.size(), static_cast<size_t>((n + 1) * (n + 1)));
  EXPECT_EQ(m.triangles.size(), static_cast<size_t>(2 * n * n));
  EXPECT_EQ(m.positions.back(), (Pos{static_cast<double>(n), static_cast<double>(n), 0}));
}

TEST(Off, LooksLikeOff) {
  for (const char* yes : {"OFF\n", "OFF", "OFF 8 6 0\n", "OFF8 6 0\n", "COFF\n", "NOFF\r\n", "CNOFF\n", "  \n# x\n\nOFF\n",
                          "OFF#c\n", "STOFF\n", "4OFF\n", "nOFF\n", "\xEF\xBB\xBFOFF\n", "OFF BINARY\n"}) {
    EXPECT_TRUE(looks_off(yes)) << yes;
  }
  for (const char* no : {"", "\n\n", "# OFF\n", "OFFICE\n", "off\n", "ply\n", "v 0 0 0\n", "solid x\n", "NCOFF\n", " O FF"}) {
    EXPECT_FALSE(looks_off(no)) << no;
  }
}

TEST(Off, SharedFandisk) {
  const std::string path = shared("inputs/fandisk.off");
  if (!test::file_exists(path)) GTEST_SKIP() << "shared data not present";
  std::string head = test::read_file(path).substr(0, 4096);
  EXPECT_TRUE(looks_off(head));
  EXPECT_FALSE(looks_stl(head));
  EXPECT_TRUE(looks_stl(head, false));  // a pipe: binary STL has no magic, so callers ask STL last
  Mesh m;
  SourceReport r;
  Status s = read_path<OffReader>(path, &m, &r);
  ASSERT_TRUE(s.ok()) << s.to_string();
  EXPECT_EQ(m.positions.size(), 6475u);
  EXPECT_EQ(m.triangles.size(), 12946u);
  EXPECT_EQ(r.polygons_triangulated, 0u);
  // The same mesh as the PLY it was written from.
  const std::string ply = shared("meshes/fandisk.ply");
  if (!test::file_exists(ply)) return;
  InputStream in;
  ASSERT_TRUE(in.open(ply).ok());
  Mesh ref;
  ASSERT_TRUE(read_all<PlyReader>(&in, &ref, nullptr).ok());
  EXPECT_EQ(m.positions, ref.positions);
  EXPECT_EQ(m.triangles, ref.triangles);
}

TEST(Off, SharedBadFiles) {
  const std::string oom = shared("bad/assimp_OutOfMemory.off");
  if (!test::file_exists(oom)) GTEST_SKIP() << "shared data not present";
  auto start = std::chrono::steady_clock::now();
  Mesh m;
  Status s = read_path<OffReader>(oom, &m);
  EXPECT_TRUE(s.code() == ErrorCode::kLimit || s.code() == ErrorCode::kTruncated) << s.to_string();
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(1));
  // Through a pipe too: no allocation by the count.
  std::string bytes = test::read_file(oom);
  s = read_pipe<OffReader>(bytes);
  EXPECT_FALSE(s.ok());

  const std::string invalid = shared("bad/assimp_invalid.off");
  s = read_path<OffReader>(invalid, &m);
  EXPECT_TRUE(s.code() == ErrorCode::kBadValue || s.code() == ErrorCode::kTruncated) << s.to_string();
  EXPECT_NE(s.line(), Status::kNoPlace);

  const std::string empty = shared("bad/assimp_empty.off");
  std::string e = test::read_file(empty);
  EXPECT_TRUE(e.empty());
  EXPECT_FALSE(looks_off(e));
  EXPECT_FALSE(looks_stl(e));
  EXPECT_FALSE(looks_stl(e, false));
  EXPECT_EQ(read_path<OffReader>(empty, &m).code(), ErrorCode::kBadHeader);
}

// ---------------------------------------------------------------- STL

const float kTetra[4][3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
const int kTetraFaces[4][3] = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};

std::string tetra_ascii() {
  std::string s = "solid tetra\n";
  for (const auto& f : kTetraFaces) {
    s += "  facet normal 0 0 0\n    outer loop\n";
    for (int c : f) {
      s += "      vertex " + std::to_string(kTetra[c][0]) + " " + std::to_string(kTetra[c][1]) + " " +
           std::to_string(kTetra[c][2]) + "\n";
    }
    s += "    endloop\n  endfacet\n";
  }
  return s + "endsolid tetra\n";
}

void put_u32(std::string* s, uint32_t v) {
  for (int i = 0; i < 4; ++i) s->push_back(static_cast<char>((v >> (8 * i)) & 0xff));
}

void put_float(std::string* s, float f) {
  uint32_t bits;
  std::memcpy(&bits, &f, 4);
  put_u32(s, bits);
}

// A binary STL of `tris` (9 floats each), with `header` padded to 80 bytes.
std::string binary_stl(const std::vector<std::array<float, 9>>& tris, const std::string& header = "",
                       uint16_t attribute = 0) {
  std::string s = header;
  s.resize(80, '\0');
  put_u32(&s, static_cast<uint32_t>(tris.size()));
  for (const auto& t : tris) {
    for (int k = 0; k < 3; ++k) put_float(&s, 0);
    for (float f : t) put_float(&s, f);
    s.push_back(static_cast<char>(attribute & 0xff));
    s.push_back(static_cast<char>(attribute >> 8));
  }
  return s;
}

std::vector<std::array<float, 9>> tetra_triangles() {
  std::vector<std::array<float, 9>> out;
  for (const auto& f : kTetraFaces) {
    std::array<float, 9> t;
    for (int c = 0; c < 3; ++c) {
      for (int k = 0; k < 3; ++k) t[3 * c + k] = kTetra[f[c]][k];
    }
    out.push_back(t);
  }
  return out;
}

void expect_tetra(const Mesh& m) {
  // Numbered in order of first appearance: 0, 2, 1, 3.
  EXPECT_EQ(m.schema.vertex_count, 4);
  EXPECT_EQ(m.schema.triangle_count, 4);
  EXPECT_EQ(m.schema.position_type, ScalarType::kFloat32);
  EXPECT_EQ(m.positions, (std::vector<Pos>{{0, 0, 0}, {0, 1, 0}, {1, 0, 0}, {0, 0, 1}}));
  EXPECT_EQ(m.triangles, (std::vector<Tri>{{0, 1, 2}, {0, 2, 3}, {0, 3, 1}, {2, 1, 3}}));
}

// Triangles as position triples, rotated so the smallest comes first (keeps
// orientation), as a set.
std::set<std::array<Pos, 3>> position_triangles(const Mesh& m) {
  std::set<std::array<Pos, 3>> out;
  for (const Tri& t : m.triangles) {
    std::array<Pos, 3> p = {m.positions[t[0]], m.positions[t[1]], m.positions[t[2]]};
    while (!(p[0] <= p[1] && p[0] <= p[2])) std::rotate(p.begin(), p.begin() + 1, p.end());
    out.insert(p);
  }
  return out;
}

TEST(Stl, AsciiTetrahedron) {
  Mesh m;
  SourceReport r;
  std::string text = tetra_ascii();
  ASSERT_TRUE(read_memory<StlReader>(text, &m, &r).ok());
  expect_tetra(m);
  EXPECT_EQ(m.schema.comments, (std::vector<std::string>{"tetra"}));
  EXPECT_TRUE(has_note(r, "facet normals not carried"));
  EXPECT_TRUE(has_note(r, "12 corners welded into 4 vertices"));
  EXPECT_TRUE(looks_stl(text));
  EXPECT_TRUE(looks_stl(text, false));
  InputStream in;
  in.open_memory(text.data(), text.size());
  StlReader reader;
  ASSERT_TRUE(reader.open(&in).ok());
  EXPECT_EQ(reader.encoding(), StlEncoding::kAscii);
  ASSERT_TRUE(read_pipe<StlReader>(text, &m).ok());
  expect_tetra(m);
}

TEST(Stl, BinaryTetrahedron) {
  // A header starting with "solid" and "facet" right after: the exact size
  // decides.
  std::string bytes = binary_stl(tetra_triangles(), "solid tetra\nfacet");
  EXPECT_TRUE(looks_stl(bytes));
  EXPECT_TRUE(looks_stl(bytes, false));
  Mesh m;
  SourceReport r;
  ASSERT_TRUE(read_memory<StlReader>(bytes, &m, &r).ok());
  expect_tetra(m);
  EXPECT_TRUE(m.schema.comments.empty());  // the header is not printable
  EXPECT_FALSE(has_note(r, "attribute"));
  InputStream in;
  in.open_memory(bytes.data(), bytes.size());
  StlReader reader;
  ASSERT_TRUE(reader.open(&in).ok());
  EXPECT_EQ(reader.encoding(), StlEncoding::kBinary);

  bytes = binary_stl(tetra_triangles(), "made by hand   ", 0x8000);
  ASSERT_TRUE(read_memory<StlReader>(bytes, &m, &r).ok());
  expect_tetra(m);
  EXPECT_EQ(m.schema.comments, (std::vector<std::string>{"made by hand"}));
  EXPECT_TRUE(has_note(r, "4 non-zero attribute words ignored"));
  ASSERT_TRUE(read_pipe<StlReader>(bytes, &m).ok());
  expect_tetra(m);

  // No triangles at all.
  ASSERT_TRUE(read_memory<StlReader>(binary_stl({}), &m, &r).ok());
  EXPECT_EQ(m.schema.vertex_count, 0);
  EXPECT_EQ(m.schema.triangle_count, 0);
  EXPECT_TRUE(r.notes.empty());
}

TEST(Stl, WeldingDetails) {
  // -0.0 and 0.0 are one vertex (yielded as 0.0); a triangle that becomes
  // degenerate is kept; first appearance decides the numbering.
  std::vector<std::array<float, 9>> tris = {
      {1, 1, 1, -0.0f, 0, 0, 0, 1, 0},
      {0, 0, -0.0f, 0, 1, 0, 0, 1, 0},
      {1, 1, 1, 1, 1, 1, 1, 1, 1},
  };
  Mesh m;
  ASSERT_TRUE(read_memory<StlReader>(binary_stl(tris), &m).ok());
  ASSERT_EQ(m.positions.size(), 3u);
  EXPECT_EQ(m.positions[1], (Pos{0, 0, 0}));
  EXPECT_FALSE(std::signbit(m.positions[1][0]));
  EXPECT_EQ(m.triangles, (std::vector<Tri>{{0, 1, 2}, {1, 2, 2}, {0, 0, 0}}));
  // Nearby but not bit-identical positions stay apart.
  tris = {{0, 0, 0, 1, 0, 0, 0, 1, 0}, {0, 0, 0, std::nextafter(1.0f, 2.0f), 0, 0, 0, 1, 0}};
  ASSERT_TRUE(read_memory<StlReader>(binary_stl(tris), &m).ok());
  EXPECT_EQ(m.positions.size(), 4u);
  // Many distinct vertices: the hash table grows.
  tris.clear();
  for (int i = 0; i < 5000; ++i) {
    float x = static_cast<float>(i);
    tris.push_back({x, 0, 0, x + 1, 0, 0, x, 1, 0});
  }
  ASSERT_TRUE(read_memory<StlReader>(binary_stl(tris), &m).ok());
  EXPECT_EQ(m.positions.size(), 5001u * 2 - 1);
  EXPECT_EQ(m.triangles[4999], (Tri{9997, 9999, 10000}));
}

TEST(Stl, AsciiLayouts) {
  // Case-insensitive keywords, no normal, tokens across lines, CRLF and
  // tabs, '+' signs, several solids, names with spaces, endsolid without a
  // name, a solid without facets.
  const std::string text =
      "SOLID my part 1\r\n"
      "FACET Normal 0 0 1\r\n\tOuter Loop\r\n vertex 0 0 0\r\nvertex +1 0 0 VERTEX\r\n0 1\r\n0\r\nENDLOOP ENDFACET\r\n"
      "endsolid\r\n"
      "solid\n"
      "facet outer loop vertex 0 0 0 vertex 0 1 0 vertex 0 0 1 endloop endfacet\n"
      "endsolid second\n"
      "solid empty\nendsolid empty\n\n  \n";
  Mesh m;
  Status s = read_memory<StlReader>(text, &m);
  ASSERT_TRUE(s.ok()) << s.to_string();
  EXPECT_EQ(m.positions, (std::vector<Pos>{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}}));
  EXPECT_EQ(m.triangles, (std::vector<Tri>{{0, 1, 2}, {0, 2, 3}}));
  EXPECT_EQ(m.schema.comments, (std::vector<std::string>{"my part 1", "empty"}));
  // An empty solid alone.
  ASSERT_TRUE(read_memory<StlReader>("solid x\nendsolid x\n", &m).ok());
  EXPECT_EQ(m.schema.vertex_count, 0);
  EXPECT_TRUE(looks_stl("solid x\nendsolid x\n"));
}

TEST(Stl, AsciiErrorsNameTheLine) {
  const std::string head = "solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\n";  // lines 1-4
  const BadCase cases[] = {
      // 'vertex' with 2 numbers: reported at its own line.
      {"vertex 1 0\nvertex 0 1 0\nendloop\nendfacet\nendsolid t\n", ErrorCode::kBadValue, 5},
      {"vertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\nendsolid t\n", ErrorCode::kOk, 0},
      {"vertex 1 0 0\nvertex 0 nan 0\nendloop\nendfacet\nendsolid t\n", ErrorCode::kBadValue, 6},
      {"vertex 1 0 0\nvertex 0 -inf 0\nendloop\nendfacet\nendsolid t\n", ErrorCode::kBadValue, 6},
      {"vertex 1 0 0\nvertex 0 1e40 0\nendloop\nendfacet\nendsolid t\n", ErrorCode::kBadValue, 6},
      {"vertex 1 0 0\nvertex 0 1 0 0\nendloop\nendfacet\nendsolid t\n", ErrorCode::kBadValue, 6},
      {"vertex 1 0 0\nendloop\nendfacet\nendsolid t\n", ErrorCode::kBadValue, 6},
      {"vertex 1 0 0\nvertex 0 1 0\nvertex 1 1 0\nendloop\nendfacet\nendsolid t\n", ErrorCode::kBadValue, 7},
      {"vertex 1 0 0\nvertex 0 1 0\nendloop\nendsolid t\n", ErrorCode::kBadValue, 8},
      {"vertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\n", ErrorCode::kTruncated, 9},
      {"vertex 1 0 0\nvertex 0 1 0\n", ErrorCode::kTruncated, 7},
      {"vertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\nendsolid t\nsolid u\nendsolid u\ngarbage\n", ErrorCode::kBadValue, 12},
      {"vertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\nfacet normal 0 0\nouter loop\n", ErrorCode::kBadValue, 9},
      {"vertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\nfacet normal 0 0 1\nloop\n", ErrorCode::kBadValue, 10},
      {"vertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\nfacets\n", ErrorCode::kBadValue, 9},
  };
  for (const BadCase& c : cases) {
    std::string text = head + c.text;
    Status s = read_memory<StlReader>(text);
    EXPECT_EQ(s.code(), c.code) << text << " -> " << s.to_string();
    if (c.code == ErrorCode::kOk) continue;
    EXPECT_EQ(s.line(), c.line) << text << " -> " << s.to_string();
    EXPECT_EQ(s.offset(), Status::kNoPlace);
  }
  Status s = read_memory<StlReader>(head + "vertex 1 0\nvertex 0 1 0\nendloop\nendfacet\nendsolid t\n");
  EXPECT_NE(s.message().find("'vertex' needs 3 numbers; found 2"), std::string::npos) << s.message();
  // Errors are sticky: next() returns the error of open().
  InputStream in;
  std::string bad = head;
  in.open_memory(bad.data(), bad.size());
  StlReader reader;
  Status o = reader.open(&in);
  EXPECT_EQ(o.code(), ErrorCode::kTruncated);
  MeshItem item;
  EXPECT_EQ(reader.next(&item).code(), ErrorCode::kTruncated);
}

TEST(Stl, TruncatedBinaryFailsAtEveryByte) {
  std::vector<std::array<float, 9>> tris = {{0, 0, 0, 1, 0, 0, 0, 1, 0}, {1, 0, 0, 1, 1, 0, 0, 1, 0}};
  const std::string full = binary_stl(tris, "two");
  ASSERT_EQ(full.size(), 184u);
  Mesh m;
  ASSERT_TRUE(read_memory<StlReader>(full, &m).ok());
  EXPECT_EQ(m.positions.size(), 4u);
  for (size_t n = 0; n < full.size(); ++n) {
    std::string prefix = full.substr(0, n);
    Status s = read_memory<StlReader>(prefix);
    EXPECT_EQ(s.code(), ErrorCode::kTruncated) << n << ": " << s.to_string();
    EXPECT_NE(s.offset(), Status::kNoPlace) << n;
    if (n >= 84) {
      EXPECT_EQ(s.offset(), 80u) << n;  // the count, found before reading
    }
    if (n % 23 == 0 || n == 183 || n == 84 || n == 133) {
      s = read_pipe<StlReader>(prefix);
      EXPECT_EQ(s.code(), ErrorCode::kTruncated) << "pipe " << n << ": " << s.to_string();
      if (n >= 84) {
        EXPECT_EQ(s.offset(), n) << "pipe " << n;  // where the input ended
      }
    }
  }
}

TEST(Stl, BinaryHostileInput) {
  std::vector<std::array<float, 9>> tris = {{0, 0, 0, 1, 0, 0, 0, 1, 0}, {1, 0, 0, 1, 1, 0, 0, 1, 0}};
  // NaN or infinity in a vertex: kBadValue at the triangle's offset.
  for (float bad : {std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity()}) {
    auto t = tris;
    t[1][4] = bad;
    Status s = read_memory<StlReader>(binary_stl(t));
    EXPECT_EQ(s.code(), ErrorCode::kBadValue) << s.to_string();
    EXPECT_EQ(s.offset(), 134u);
    EXPECT_NE(s.message().find("triangle 1"), std::string::npos);
    EXPECT_EQ(read_pipe<StlReader>(binary_stl(t)).code(), ErrorCode::kBadValue);
  }
  // A NaN normal is not an error: normals are dropped.
  std::string bytes = binary_stl(tris);
  float nan = std::numeric_limits<float>::quiet_NaN();
  std::memcpy(&bytes[84], &nan, 4);
  EXPECT_TRUE(read_memory<StlReader>(bytes).ok());
  // Bytes after the last triangle.
  Status s = read_memory<StlReader>(binary_stl(tris) + std::string(7, '\0'));
  EXPECT_EQ(s.code(), ErrorCode::kBadValue);
  EXPECT_EQ(s.offset(), 184u);
  EXPECT_NE(s.message().find("7 bytes after the last triangle"), std::string::npos) << s.message();
  s = read_pipe<StlReader>(binary_stl(tris) + std::string(7, '\0'));
  EXPECT_EQ(s.code(), ErrorCode::kBadValue);
  EXPECT_EQ(s.offset(), 184u);
  // An absurd count: found from the size, before any allocation.
  std::string absurd = binary_stl(tris);
  absurd[80] = absurd[81] = absurd[82] = absurd[83] = '\xff';
  auto start = std::chrono::steady_clock::now();
  s = read_memory<StlReader>(absurd);
  EXPECT_EQ(s.code(), ErrorCode::kTruncated);
  EXPECT_EQ(s.offset(), 80u);
  EXPECT_NE(s.message().find("4294967295 triangles"), std::string::npos) << s.message();
  EXPECT_EQ(read_pipe<StlReader>(absurd).code(), ErrorCode::kTruncated);
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(2));
  // Text that is not STL, read as STL anyway.
  EXPECT_FALSE(read_memory<StlReader>("solid but nothing else follows, and no facet").ok());
  EXPECT_FALSE(read_memory<StlReader>("").ok());
}

TEST(Stl, LooksLikeStl) {
  std::string bin = binary_stl(tetra_triangles());
  EXPECT_TRUE(looks_stl(bin));
  EXPECT_FALSE(looks_stl(bin + "x"));          // size mismatch, not ascii
  EXPECT_FALSE(looks_stl(bin.substr(0, 100)));  // truncated
  EXPECT_TRUE(looks_stl(bin.substr(0, 100), false));  // a pipe: no magic to check
  EXPECT_FALSE(looks_stl(bin.substr(0, 83), false));
  EXPECT_TRUE(looks_stl("solid x\n  facet normal 0 0 1\n"));
  EXPECT_TRUE(looks_stl("solid\r\nFACET normal 0 0 1\r\n"));
  EXPECT_TRUE(looks_stl("  solid x\nendsolid x\n"));
  EXPECT_FALSE(looks_stl("solid x\n"));
  EXPECT_FALSE(looks_stl("solidx\nfacet\n"));
  EXPECT_FALSE(looks_stl("solid x\nvertex 0 0 0\nfacet\n"));
  EXPECT_FALSE(looks_stl("OFF\n3 1 0\n"));
  EXPECT_FALSE(looks_stl("ply\nformat ascii 1.0\n"));
  EXPECT_FALSE(looks_stl(""));
  EXPECT_FALSE(looks_stl("", false));
}

TEST(Stl, SharedSpiderAsciiAndBinaryAgree) {
  const std::string a = shared("inputs/spider_ascii.stl");
  const std::string b = shared("inputs/spider_binary.stl");
  if (!test::file_exists(a) || !test::file_exists(b)) GTEST_SKIP() << "shared data not present";
  for (const std::string& p : {a, b}) {
    std::string bytes = test::read_file(p);
    EXPECT_TRUE(looks_stl(bytes.substr(0, 4096), false)) << p;
    EXPECT_TRUE(looks_like_stl(reinterpret_cast<const uint8_t*>(bytes.data()), std::min<size_t>(bytes.size(), 4096),
                               static_cast<int64_t>(bytes.size())))
        << p;
    EXPECT_FALSE(looks_off(bytes.substr(0, 4096))) << p;
  }
  Mesh ma, mb;
  SourceReport ra, rb;
  Status s = read_path<StlReader>(a, &ma, &ra);
  ASSERT_TRUE(s.ok()) << s.to_string();
  s = read_path<StlReader>(b, &mb, &rb);
  ASSERT_TRUE(s.ok()) << s.to_string();
  EXPECT_EQ(ma.triangles.size(), 1368u);
  EXPECT_EQ(mb.triangles.size(), 1368u);
  EXPECT_EQ(ma.positions.size(), mb.positions.size());
  // The ascii file has 6 decimals where the binary one has float precision:
  // the same facets in the same order weld into the same indices, with
  // positions equal to within the ascii rounding.
  EXPECT_EQ(ma.triangles, mb.triangles);
  ASSERT_EQ(ma.positions.size(), mb.positions.size());
  double worst = 0;
  for (size_t i = 0; i < ma.positions.size(); ++i) {
    for (int k = 0; k < 3; ++k) worst = std::max(worst, std::fabs(ma.positions[i][k] - mb.positions[i][k]));
  }
  EXPECT_LT(worst, 1e-5);
  // As sets of position triples (any rotation, same orientation), matched
  // to within the ascii rounding, independently of the indices.
  std::vector<bool> used(mb.triangles.size(), false);
  size_t unmatched = 0;
  for (const Tri& ta : ma.triangles) {
    bool found = false;
    for (size_t j = 0; j < mb.triangles.size() && !found; ++j) {
      if (used[j]) continue;
      for (int rot = 0; rot < 3 && !found; ++rot) {
        bool same = true;
        for (int c = 0; c < 3 && same; ++c) {
          const Pos& pa = ma.positions[ta[c]];
          const Pos& pb = mb.positions[mb.triangles[j][(c + rot) % 3]];
          for (int k = 0; k < 3; ++k) same = same && std::fabs(pa[k] - pb[k]) < 1e-5;
        }
        if (same) found = used[j] = true;
      }
    }
    unmatched += !found;
  }
  EXPECT_EQ(unmatched, 0u);
  EXPECT_EQ(position_triangles(ma).size(), position_triangles(mb).size());
  // The welded count, recomputed independently.
  std::set<Pos> distinct;
  for (const Tri& t : mb.triangles) {
    for (uint32_t i : t) distinct.insert(mb.positions[i]);
  }
  EXPECT_EQ(mb.positions.size(), distinct.size());
  EXPECT_EQ(static_cast<int64_t>(mb.positions.size()), mb.schema.vertex_count);
  // 56 triangles become index-degenerate after welding; they are kept.
  size_t degenerate = 0;
  for (const Tri& t : mb.triangles) degenerate += t[0] == t[1] || t[1] == t[2] || t[2] == t[0];
  EXPECT_EQ(degenerate, 56u);
  // Every yielded position is distinct and every triangle refers to them.
  EXPECT_EQ(std::set<Pos>(mb.positions.begin(), mb.positions.end()).size(), mb.positions.size());
  EXPECT_TRUE(has_note(ra, "facet normals not carried: psq computes none"));
}

TEST(Stl, SharedPig) {
  const std::string p = shared("inputs/pig_binary.stl");
  if (!test::file_exists(p)) GTEST_SKIP() << "shared data not present";
  Mesh m;
  Status s = read_path<StlReader>(p, &m);
  ASSERT_TRUE(s.ok()) << s.to_string();
  EXPECT_EQ(m.triangles.size(), 16848u);
  EXPECT_EQ(m.schema.triangle_count, 16848);
  // Recompute the welded count from the raw file.
  std::string bytes = test::read_file(p);
  std::set<std::array<float, 3>> distinct;
  for (size_t t = 0; t < 16848; ++t) {
    for (int c = 0; c < 3; ++c) {
      std::array<float, 3> v;
      std::memcpy(v.data(), bytes.data() + 84 + 50 * t + 12 + 12 * c, 12);
      for (float& f : v) f = f == 0.0f ? 0.0f : f;
      distinct.insert(v);
    }
  }
  EXPECT_EQ(m.positions.size(), distinct.size());
  // The file's corners, through the indices, are the file's positions.
  for (size_t t = 0; t < 16848; t += 97) {
    for (int c = 0; c < 3; ++c) {
      float v[3];
      std::memcpy(v, bytes.data() + 84 + 50 * t + 12 + 12 * c, 12);
      for (int k = 0; k < 3; ++k) EXPECT_EQ(m.positions[m.triangles[t][c]][k], v[k] == 0.0f ? 0.0 : v[k]);
    }
  }
}

}  // namespace
}  // namespace psq
