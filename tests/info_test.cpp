// SPDX-License-Identifier: Apache-2.0
// psq info: a .psq reports the mesh it holds as the same mesh in PLY does,
// and the boundary figures of its own sequence, counted as the decoder yields
// it; malformed streams fail in one line; no progress goes to a stderr that
// is not a terminal.
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "psq/mesh_formats.h"
#include "psq/ply.h"
#include "psq/psq_codec.h"
#include "psq/sequence_check.h"
#include "test_util.h"

namespace psq {
namespace {

using test::Mesh;
using test::run_psq;
using Tri = std::array<uint32_t, 3>;

// The value of top-level field `key` in psq info's JSON: the text after
// `"key": ` up to the end of its line, without the trailing comma.
std::string field(const std::string& json, const std::string& key) {
  const std::string tag = "\n  \"" + key + "\": ";
  const size_t at = json.find(tag);
  if (at == std::string::npos) return "<missing " + key + ">";
  const size_t from = at + tag.size();
  std::string v = json.substr(from, json.find('\n', from) - from);
  if (!v.empty() && v.back() == ',') v.pop_back();
  return v;
}

uint64_t number(const std::string& json, const std::string& key) {
  const std::string v = field(json, key);
  EXPECT_FALSE(v.empty() || v[0] == '<') << key << ": " << v;
  return std::strtoull(v.c_str(), nullptr, 10);
}

std::string info_json(const std::string& path) {
  std::string out, err;
  EXPECT_EQ(run_psq("info --json " + path, &out, &err), 0) << path << ": " << err;
  return out;
}

// The fields that are properties of the mesh, not of a sequence.
const char* const kMeshFields[] = {"vertices",          "triangles",          "unreferenced_vertices",
                                   "degenerate_triangles", "position_type",   "components",
                                   "border_edges",      "border_loops",       "nonmanifold_vertices",
                                   "nonmanifold_edges", "misoriented_edges",  "vertex_properties",
                                   "face_properties"};

void expect_same_mesh(const std::string& a, const std::string& b, const std::string& what, bool bbox) {
  for (const char* f : kMeshFields) EXPECT_EQ(field(a, f), field(b, f)) << what << ": " << f;
  if (bbox) {
    EXPECT_EQ(field(a, "bbox"), field(b, "bbox")) << what;
  }
}

void write_ply(const Mesh& m, const std::string& path) {
  OutputFile out;
  ASSERT_TRUE(out.open(path, true).ok());
  PlyWriter w(&out);
  test::MemorySource src(m);
  ASSERT_TRUE(pump(src, w).ok());
  ASSERT_TRUE(out.commit().ok());
}

// A torus of r x s quads (one handle), with a hole cut out of it.
Mesh holed_torus(int r, int s) {
  std::vector<std::array<double, 3>> p;
  std::vector<Tri> t;
  const double pi = 3.14159265358979323846;
  for (int i = 0; i < r; ++i)
    for (int j = 0; j < s; ++j) {
      double a = 2 * pi * i / r, b = 2 * pi * j / s;
      volatile float x = static_cast<float>((2 + std::cos(b)) * std::cos(a));
      volatile float y = static_cast<float>((2 + std::cos(b)) * std::sin(a));
      volatile float z = static_cast<float>(std::sin(b));
      p.push_back({x, y, z});
    }
  auto id = [&](int i, int j) { return static_cast<uint32_t>((i % r) * s + j % s); };
  for (int i = 0; i < r; ++i)
    for (int j = 0; j < s; ++j) {
      if (i == 3 && j == 2) continue;  // the hole: one quad left out
      t.push_back({id(i, j), id(i + 1, j), id(i + 1, j + 1)});
      t.push_back({id(i, j), id(i + 1, j + 1), id(i, j + 1)});
    }
  return test::make_mesh(p, t);
}

// Meshes on disk: the shipped ones and generated ones written as PLY.
std::vector<std::string> meshes(const test::TempDir& dir) {
  std::vector<std::string> files;
  for (const char* f : {"nonmanifold_wrap.ply", "max_export_nm.ply", "spider.ply", "cube_quads.obj"}) {
    files.push_back(std::string(PSQ_TEST_DATA) + "/" + f);
  }
  write_ply(test::make_sphere(30, 40), dir.file("sphere.ply"));
  write_ply(test::make_grid(25), dir.file("grid.ply"));
  write_ply(holed_torus(40, 12), dir.file("torus.ply"));
  Mesh soup = test::make_mesh({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {5, 5, 5}, {6, 5, 5}, {5, 6, 5}, {9, 9, 9}},
                              {{0, 1, 2}, {3, 4, 5}, {0, 2, 1}, {0, 1, 3}});  // a double-sided, a fin, one isolated
  write_ply(soup, dir.file("soup.ply"));
  for (const char* f : {"sphere.ply", "grid.ply", "torus.ply", "soup.ply"}) files.push_back(dir.file(f));
  return files;
}

// A .psq holds the mesh it was made from: the mesh's counts agree with the
// input's (none of these meshes has degenerate triangles, which a .psq
// drops), and a lossless .psq and its decoded PLY agree on the bounding box
// too, in either profile.
TEST(InfoPsq, MeshCountsAgreeWithThePly) {
  test::TempDir dir;
  for (const std::string& in : meshes(dir)) {
    const std::string original = info_json(in);
    ASSERT_EQ(number(original, "degenerate_triangles"), 0u) << in;
    for (const char* profile : {"compact", "fast"}) {
      for (const char* precision : {"--lossless", "--bits 14"}) {
        const std::string how = in + " " + profile + " " + precision;
        std::string out, err;
        ASSERT_EQ(run_psq(std::string("convert -f --profile ") + profile + " " + precision + " " + in + " " +
                              dir.file("m.psq"),
                          &out, &err),
                  0)
            << how << ": " << err;
        ASSERT_EQ(run_psq("convert -f " + dir.file("m.psq") + " " + dir.file("back.ply"), &out, &err), 0) << err;
        const std::string psq = info_json(dir.file("m.psq"));
        EXPECT_EQ(field(psq, "format"), "\"psq\"");
        expect_same_mesh(original, psq, how, std::string(precision) == "--lossless" && in.find(".obj") == std::string::npos);
        expect_same_mesh(info_json(dir.file("back.ply")), psq, how + ", decoded", true);
      }
    }
  }
}

// The boundary figures are those of the file's own sequence: what a
// SequenceChecker counts over the decoder's events.
TEST(InfoPsq, BoundaryIsTheFilesOwnSequence) {
  test::TempDir dir;
  for (const std::string& in : meshes(dir)) {
    for (const char* profile : {"compact", "fast"}) {
      std::string out, err;
      ASSERT_EQ(run_psq(std::string("convert -f --profile ") + profile + " " + in + " " + dir.file("m.psq"), &out, &err), 0)
          << err;
      const std::string psq = info_json(dir.file("m.psq"));
      InputStream stream;
      ASSERT_TRUE(stream.open(dir.file("m.psq")).ok());
      PsqDecoder dec;
      ASSERT_TRUE(dec.open(&stream).ok());
      SequenceChecker checker;
      Status s = dec.pump(checker);
      ASSERT_TRUE(s.ok()) << s.to_string();
      const SequenceStats& q = checker.stats();
      const std::string how = in + " " + profile;
      EXPECT_EQ(number(psq, "components"), q.components) << how;
      EXPECT_EQ(number(psq, "border_loops"), q.border_loops) << how;
      EXPECT_EQ(field(psq, "handles"), std::to_string(q.handles)) << how;
      EXPECT_EQ(number(psq, "reappearances"), q.reappearances) << how;
      EXPECT_EQ(number(psq, "nonmanifold_vertices"), q.nonmanifold_vertices) << how;
      EXPECT_EQ(number(psq, "max_boundary_vertices"), q.max_boundary_vertices) << how;
      EXPECT_EQ(number(psq, "max_boundary_edges"), q.max_boundary_edges) << how;
      EXPECT_EQ(field(psq, "ops"), "{\"start\": " + std::to_string(q.ops[0]) + ", \"add\": " + std::to_string(q.ops[1]) +
                                       ", \"join\": " + std::to_string(q.ops[2]) + ", \"fill\": " +
                                       std::to_string(q.ops[3]) + ", \"end\": " + std::to_string(q.ops[4]) + "}")
          << how;
      EXPECT_EQ(field(psq, "sequence_order"), "\"file\"") << how;
      // The converter's figures have no meaning for a file.
      EXPECT_EQ(psq.find("coherence_window"), std::string::npos) << how;
      EXPECT_EQ(psq.find("max_waiting"), std::string::npos) << how;
      ASSERT_EQ(run_psq("info " + dir.file("m.psq"), &out, &err), 0) << err;
      EXPECT_NE(out.find("sequence order         the file's own sequence\n"), std::string::npos) << out;
    }
  }
}

TEST(InfoPsq, NonManifoldCountsBothWays) {
  test::TempDir dir;
  struct Case {
    const char* file;
    uint64_t nonmanifold_edges;
  } cases[] = {{"nonmanifold_wrap.ply", 1}, {"max_export_nm.ply", 16}};
  for (const Case& c : cases) {
    const std::string ply = std::string(PSQ_TEST_DATA) + "/" + c.file;
    std::string out, err;
    ASSERT_EQ(run_psq("convert -f " + ply + " " + dir.file("nm.psq"), &out, &err), 0) << err;
    const std::string a = info_json(ply), b = info_json(dir.file("nm.psq"));
    EXPECT_EQ(number(a, "nonmanifold_edges"), c.nonmanifold_edges) << c.file;
    EXPECT_GT(number(a, "nonmanifold_vertices"), 0u) << c.file;
    for (const char* f : {"nonmanifold_vertices", "nonmanifold_edges", "misoriented_edges", "border_edges", "components"}) {
      EXPECT_EQ(field(a, f), field(b, f)) << c.file << ": " << f;
    }
    EXPECT_GT(number(b, "reappearances"), 0u) << c.file;
  }
}

TEST(InfoPsq, MalformedStreamFailsInOneLine) {
  test::TempDir dir;
  write_ply(test::make_sphere(30, 40), dir.file("s.ply"));
  std::string out, err;
  for (const char* profile : {"compact", "fast"}) {
    ASSERT_EQ(run_psq(std::string("convert -f --profile ") + profile + " " + dir.file("s.ply") + " " + dir.file("s.psq"),
                      &out, &err),
              0)
        << err;
    const std::string bytes = test::read_file(dir.file("s.psq"));
    std::vector<std::string> bad;
    for (size_t cut : {size_t{5}, size_t{40}, bytes.size() / 2, bytes.size() - 1}) bad.push_back(bytes.substr(0, cut));
    std::vector<uint8_t> garbled(bytes.begin(), bytes.end());
    test::garble_first_chunk_records(&garbled, 7, 16);
    bad.emplace_back(garbled.begin(), garbled.end());
    std::string flipped = bytes;
    flipped[flipped.size() / 2] = static_cast<char>(flipped[flipped.size() / 2] ^ 0x20);  // a checksum catches it
    bad.push_back(flipped);
    for (size_t i = 0; i < bad.size(); ++i) {
      const std::string f = dir.file("bad" + std::to_string(i) + ".psq");
      test::write_file(f, bad[i]);
      EXPECT_EQ(run_psq("info " + f, &out, &err), 1) << profile << " case " << i << ": " << out;
      EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;
      EXPECT_EQ(err.rfind("psq: error: " + f + ": ", 0), 0u) << err;
      EXPECT_TRUE(out.empty()) << out;
    }
  }
}

// Progress goes only to a terminal: run from here, stderr is a pipe, and
// verify and info of a stream that decodes for a while print nothing there.
TEST(InfoPsq, NoProgressWhenStderrIsNoTerminal) {
  test::TempDir dir;
  write_ply(test::make_sphere(300, 400), dir.file("s.ply"));
  std::string out, err;
  ASSERT_EQ(run_psq("convert " + dir.file("s.ply") + " " + dir.file("s.psq"), &out, &err), 0) << err;
  EXPECT_TRUE(err.empty()) << err;
  for (const char* cmd : {"info ", "verify ", "info --json "}) {
    EXPECT_EQ(run_psq(cmd + dir.file("s.psq"), &out, &err), 0) << err;
    EXPECT_TRUE(err.empty()) << cmd << err;
    EXPECT_FALSE(out.empty());
  }
  EXPECT_EQ(run_psq("info " + dir.file("s.ply"), &out, &err), 0) << err;
  EXPECT_TRUE(err.empty()) << err;
}

}  // namespace
}  // namespace psq
