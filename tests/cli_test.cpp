// SPDX-License-Identifier: Apache-2.0
// The psq binary as a user runs it: exit codes, stdout/stderr discipline,
// atomic outputs, pipes, and the shared corpus.
#include <gtest/gtest.h>

#include <cstdlib>

#include <dirent.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <regex>
#include <set>
#include <sstream>
#include <string>

#include "psq/ply.h"
#include "psq/sequence_check.h"
#include "test_util.h"

namespace psq {
namespace {

using test::Mesh;
using test::run_psq;

std::string shared(const std::string& rel) { return std::string(PSQ_SHARED_DATA) + "/" + rel; }

// Writes a generated mesh as binary PLY and returns its path.
std::string write_sphere(const test::TempDir& dir, const std::string& name, bool with_props = false, int rings = 10,
                         int segments = 16) {
  Mesh m = test::make_sphere(rings, segments);
  if (with_props) {
    m.schema.vertex_properties.push_back({"confidence", ScalarType::kFloat32});
    m.schema.vertex_properties.push_back({"label", ScalarType::kUInt16});
    m.schema.face_properties.push_back({"segment", ScalarType::kInt32});
    for (size_t i = 0; i < m.positions.size(); ++i) m.vertex_values[i] = {0.5f + i * 0.25f, static_cast<double>(i % 7)};
    for (size_t t = 0; t < m.triangles.size(); ++t) m.face_values[t] = {-static_cast<double>(t)};
  }
  OutputFile out;
  EXPECT_TRUE(out.open(dir.file(name), false).ok());
  PlyWriter w(&out);
  test::MemorySource src(m);
  EXPECT_TRUE(pump(src, w).ok());
  EXPECT_TRUE(out.commit().ok());
  return dir.file(name);
}

int count_lines(const std::string& s) { return static_cast<int>(std::count(s.begin(), s.end(), '\n')); }

TEST(Cli, HelpAndVersion) {
  std::string out, err;
  EXPECT_EQ(run_psq("--help", &out, &err), 0);
  EXPECT_NE(out.find("Usage: psq"), std::string::npos);
  EXPECT_EQ(run_psq("--version", &out, &err), 0);
  EXPECT_TRUE(std::regex_search(out, std::regex("^psq [0-9]+\\.[0-9]+\\.[0-9]+\n$")));
  for (const char* cmd : {"info", "convert"}) {
    EXPECT_EQ(run_psq(std::string(cmd) + " --help", &out, &err), 0) << cmd;
    EXPECT_NE(out.find(std::string("Usage: psq ") + cmd), std::string::npos);
    EXPECT_TRUE(err.empty());
  }
}

TEST(Cli, UsageErrorsExitTwoWithHint) {
  std::string out, err;
  EXPECT_EQ(run_psq("", &out, &err), 2);
  EXPECT_EQ(run_psq("frobnicate", &out, &err), 2);
  EXPECT_NE(err.find("psq: error: unknown command"), std::string::npos);
  EXPECT_EQ(run_psq("info", &out, &err), 2);
  EXPECT_NE(err.find("Try 'psq info --help'"), std::string::npos);
  EXPECT_EQ(run_psq("info --bogus x.ply", &out, &err), 2);
  EXPECT_EQ(run_psq("convert a.ply", &out, &err), 2);
  EXPECT_EQ(run_psq("convert a.ply b.xyz", &out, &err), 2);
  EXPECT_EQ(run_psq("convert -o b.ply", &out, &err), 2);
  EXPECT_EQ(run_psq("convert a.ply b.ply -o c.ply", &out, &err), 2);
  EXPECT_TRUE(out.empty());
}

TEST(Cli, HelpCommandAndSuggestions) {
  std::string out, err, direct;
  for (const char* cmd : {"info", "convert", "dump", "verify"}) {
    EXPECT_EQ(run_psq(std::string("help ") + cmd, &out, &err), 0) << cmd;
    EXPECT_EQ(run_psq(std::string(cmd) + " --help", &direct, &err), 0) << cmd;
    EXPECT_EQ(out, direct) << cmd;
  }
  // The simplification benchmark finds the methods in this list.
  EXPECT_EQ(run_psq("simplify --help", &out, &err), 0);
  EXPECT_TRUE(std::regex_search(out, std::regex("Methods \\(--method\\):\n  clustering [^]*\n  qem  ")));
  EXPECT_EQ(run_psq("help frobnicate", &out, &err), 2);
  EXPECT_NE(err.find("unknown command 'frobnicate'"), std::string::npos);
  // A typo or a prefix names the nearest command; a word far from every
  // command names none.
  EXPECT_EQ(run_psq("convrt a.ply b.psq", &out, &err), 2);
  EXPECT_NE(err.find("did you mean 'convert'?"), std::string::npos) << err;
  EXPECT_EQ(run_psq("inf x.ply", &out, &err), 2);
  EXPECT_NE(err.find("did you mean 'info'?"), std::string::npos) << err;
  EXPECT_EQ(run_psq("verfiy x.psq", &out, &err), 2);
  EXPECT_NE(err.find("did you mean 'verify'?"), std::string::npos) << err;
  EXPECT_EQ(run_psq("frobnicate", &out, &err), 2);
  EXPECT_EQ(err.find("did you mean"), std::string::npos) << err;
}

TEST(Cli, VerifyJson) {
  test::TempDir dir;
  std::string ply = write_sphere(dir, "s.ply");
  std::string out, err;
  ASSERT_EQ(run_psq("convert -q " + ply + " " + dir.file("s.psq"), &out, &err), 0) << err;
  ASSERT_EQ(run_psq("verify --json " + dir.file("s.psq"), &out, &err), 0) << err;
  EXPECT_TRUE(std::regex_search(out, std::regex("^\\{\"file\": \".*s\\.psq\", \"ok\": true, \"version\": \"[0-9]+\\.[0-9]+\", "
                                                "\"profile\": \"compact\", \"vertices\": [0-9]+, \"triangles\": 288, "
                                                "\"chunks\": 1, \"bytes\": [0-9]+, \"max_boundary_vertices\": [0-9]+\\}\n$")))
      << out;
  EXPECT_TRUE(err.empty()) << err;
}

TEST(Cli, ConvertTakesOutputFromDashO) {
  test::TempDir dir;
  std::string ply = write_sphere(dir, "s.ply");
  std::string out, err;
  ASSERT_EQ(run_psq("convert -o " + dir.file("a.psq") + " " + ply, &out, &err), 0) << err;
  ASSERT_EQ(run_psq("convert " + ply + " --output=" + dir.file("b.psq"), &out, &err), 0) << err;
  ASSERT_EQ(run_psq("convert " + ply + " " + dir.file("c.psq"), &out, &err), 0) << err;
  EXPECT_EQ(test::read_file(dir.file("a.psq")), test::read_file(dir.file("c.psq")));
  EXPECT_EQ(test::read_file(dir.file("b.psq")), test::read_file(dir.file("c.psq")));
  // -o refuses to overwrite without -f, as OUT does (a usage error).
  EXPECT_EQ(run_psq("convert -o " + dir.file("a.psq") + " " + ply, &out, &err), 2);
  EXPECT_EQ(run_psq("convert -f -o " + dir.file("a.psq") + " " + ply, &out, &err), 0) << err;
}

// Normals and texture coordinates quantized at the bits asked for (spec
// 8.3), named by psq info; --lossless keeps them exact; bad bits are usage
// errors.
TEST(Cli, ConvertQuantizesAttributesAndInfoSaysSo) {
  test::TempDir dir;
  const std::string in = std::string(PSQ_TEST_DATA) + "/attributes.ply";
  std::string out, err;
  ASSERT_EQ(run_psq("convert -q --normal-bits 8 --uv-bits 10 " + in + " " + dir.file("a.psq"), &out, &err), 0) << err;
  ASSERT_EQ(run_psq("info " + dir.file("a.psq"), &out, &err), 0) << err;
  EXPECT_NE(out.find("coded attributes       normals (nx ny nz) quantized, 8-bit octahedral; texture coordinates "
                     "(s t) quantized to steps of 2^-10; colours (red green blue alpha) exact"),
            std::string::npos)
      << out;
  ASSERT_EQ(run_psq("info --json " + dir.file("a.psq"), &out, &err), 0) << err;
  EXPECT_NE(out.find("\"attributes\": [{\"kind\": \"normal\", \"bits\": 8, \"properties\": [\"nx\", \"ny\", \"nz\"]}"),
            std::string::npos)
      << out;
  // The defaults: 10 and 12 bits.
  ASSERT_EQ(run_psq("convert -q " + in + " " + dir.file("d.psq"), &out, &err), 0) << err;
  ASSERT_EQ(run_psq("info " + dir.file("d.psq"), &out, &err), 0) << err;
  EXPECT_NE(out.find("10-bit octahedral; texture coordinates (s t) quantized to steps of 2^-12"), std::string::npos) << out;
  ASSERT_EQ(run_psq("convert -q --lossless " + in + " " + dir.file("l.psq"), &out, &err), 0) << err;
  ASSERT_EQ(run_psq("info " + dir.file("l.psq"), &out, &err), 0) << err;
  EXPECT_NE(out.find("coded attributes       colours (red green blue alpha) exact\n"), std::string::npos) << out;
  // Draco output keeps s t as texture coordinates (read back as u v).
  ASSERT_EQ(run_psq("convert -q " + in + " " + dir.file("a.drc"), &out, &err), 0) << err;
  ASSERT_EQ(run_psq("info " + dir.file("a.drc"), &out, &err), 0) << err;
  EXPECT_NE(out.find("alpha:uchar u:float v:float"), std::string::npos) << out;
  for (const char* bad : {"--normal-bits 1", "--normal-bits 17", "--normal-bits x", "--uv-bits 25", "--uv-bits -1"}) {
    EXPECT_EQ(run_psq("convert -q " + std::string(bad) + " " + in + " " + dir.file("b.psq"), &out, &err), 2) << bad;
    EXPECT_FALSE(test::file_exists(dir.file("b.psq"))) << bad;
  }
}

// A filter's .psq output keeps a .psq input's attribute quantization (and
// codes per-corner values per corner); from another input it quantizes as
// convert does.
TEST(Cli, FiltersKeepTheAttributesQuantization) {
  test::TempDir dir;
  const std::string in = std::string(PSQ_TEST_DATA) + "/attributes.ply";
  const std::string obj = std::string(PSQ_TEST_DATA) + "/spider.obj";
  std::string out, err;
  ASSERT_EQ(run_psq("convert -q --normal-bits 8 --uv-bits 10 " + in + " " + dir.file("a.psq"), &out, &err), 0) << err;
  ASSERT_EQ(run_psq("convert -q --normal-bits 9 --uv-bits 11 " + obj + " " + dir.file("c.psq"), &out, &err), 0) << err;
  for (const std::string& cmd :
       {"smooth -q " + dir.file("a.psq") + " " + dir.file("s.psq"),
        "simplify -q --method qem --ratio 50% " + dir.file("a.psq") + " " + dir.file("s.psq"),
        "simplify -q --grid 4 " + dir.file("a.psq") + " " + dir.file("s.psq")}) {
    ASSERT_EQ(run_psq(cmd + " -f", &out, &err), 0) << cmd << ": " << err;
    ASSERT_EQ(run_psq("info " + dir.file("s.psq"), &out, &err), 0) << err;
    EXPECT_NE(out.find("normals (nx ny nz) quantized, 8-bit octahedral; texture coordinates (s t) quantized to "
                       "steps of 2^-10"),
              std::string::npos)
        << cmd << ": " << out;
  }
  ASSERT_EQ(run_psq("smooth -q -f " + dir.file("c.psq") + " " + dir.file("s.psq"), &out, &err), 0) << err;
  ASSERT_EQ(run_psq("info " + dir.file("s.psq"), &out, &err), 0) << err;
  EXPECT_NE(out.find("per-corner normals (corner_normals) quantized, 9-bit octahedral; per-corner texture "
                     "coordinates (corner_uv) quantized to steps of 2^-11"),
            std::string::npos)
      << out;
  ASSERT_EQ(run_psq("smooth -q -f " + in + " " + dir.file("s.psq"), &out, &err), 0) << err;
  ASSERT_EQ(run_psq("info " + dir.file("s.psq"), &out, &err), 0) << err;
  EXPECT_NE(out.find("10-bit octahedral; texture coordinates (s t) quantized to steps of 2^-12"), std::string::npos)
      << out;
}

TEST(Cli, InfoTextAndJson) {
  test::TempDir dir;
  std::string ply = write_sphere(dir, "s.ply", true);
  std::string out, err;
  ASSERT_EQ(run_psq("info " + ply, &out, &err), 0) << err;
  EXPECT_NE(out.find("vertices               146"), std::string::npos) << out;
  EXPECT_NE(out.find("triangles              288"), std::string::npos) << out;
  ASSERT_EQ(run_psq("info --json " + ply, &out, &err), 0) << err;
  EXPECT_NE(out.find("\"vertices\": 146,"), std::string::npos) << out;
  EXPECT_NE(out.find("\"unreferenced_vertices\": 0,"), std::string::npos);
  EXPECT_NE(out.find("{\"name\": \"label\", \"type\": \"ushort\"}"), std::string::npos);
  EXPECT_NE(out.find("{\"name\": \"segment\", \"type\": \"int\"}"), std::string::npos);
  EXPECT_TRUE(err.empty()) << err;
}

TEST(Cli, InfoCountsUnreferencedAndDegenerate) {
  test::TempDir dir;
  test::write_file(dir.file("m.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 5 5 5\nf 1 2 3\nf 1 1 2\n");
  std::string out, err;
  ASSERT_EQ(run_psq("info --json " + dir.file("m.obj"), &out, &err), 0) << err;
  EXPECT_NE(out.find("\"unreferenced_vertices\": 1,"), std::string::npos) << out;
  EXPECT_NE(out.find("\"degenerate_triangles\": 1,"), std::string::npos) << out;
  EXPECT_NE(err.find("psq: warning: "), std::string::npos);
}

TEST(Cli, ConvertPlyObjPlyKeepsTrianglesAndPositions) {
  test::TempDir dir;
  std::string ply = write_sphere(dir, "s.ply");
  std::string out, err;
  ASSERT_EQ(run_psq("convert " + ply + " " + dir.file("s.obj"), &out, &err), 0) << err;
  ASSERT_EQ(run_psq("convert " + dir.file("s.obj") + " " + dir.file("back.ply"), &out, &err), 0) << err;
  Mesh a, b;
  ASSERT_TRUE(test::load_mesh(ply, &a).ok());
  ASSERT_TRUE(test::load_mesh(dir.file("back.ply"), &b).ok());
  EXPECT_EQ(a.positions, b.positions);
  EXPECT_EQ(a.triangles, b.triangles);
}

TEST(Cli, ConvertPlyToPlyKeepsUnknownProperties) {
  test::TempDir dir;
  std::string ply = write_sphere(dir, "s.ply", true);
  std::string out, err;
  ASSERT_EQ(run_psq("convert --ascii " + ply + " " + dir.file("a.ply"), &out, &err), 0) << err;
  ASSERT_EQ(run_psq("convert " + dir.file("a.ply") + " " + dir.file("b.ply"), &out, &err), 0) << err;
  Mesh a, b;
  ASSERT_TRUE(test::load_mesh(ply, &a).ok());
  ASSERT_TRUE(test::load_mesh(dir.file("b.ply"), &b).ok());
  EXPECT_EQ(a.schema.vertex_properties, b.schema.vertex_properties);
  EXPECT_EQ(a.schema.face_properties, b.schema.face_properties);
  EXPECT_EQ(a.vertex_values, b.vertex_values);
  EXPECT_EQ(a.face_values, b.face_values);
  EXPECT_EQ(a.positions, b.positions);
}

TEST(Cli, ConvertThroughPipes) {
  test::TempDir dir;
  std::string ply = write_sphere(dir, "s.ply", true);
  std::string cmd = std::string(PSQ_BINARY) + " convert " + ply + " - --to ply | " + PSQ_BINARY +
                    " convert - --to obj - | " + PSQ_BINARY + " convert - " + dir.file("p.ply");
  ASSERT_EQ(std::system(cmd.c_str()), 0);
  Mesh a, b;
  ASSERT_TRUE(test::load_mesh(ply, &a).ok());
  ASSERT_TRUE(test::load_mesh(dir.file("p.ply"), &b).ok());
  EXPECT_EQ(a.positions, b.positions);
  EXPECT_EQ(a.triangles, b.triangles);
}

TEST(Cli, ConvertWritesTheSameBytesOnOneOrTwoThreads) {
  test::TempDir dir;
  // 19,000 triangles: many batches go to the encoder's thread while the
  // converter runs.
  std::string ply = write_sphere(dir, "s.ply", true, 80, 120);
  std::string out, err;
  // From a mesh (the converter feeds the encoder) and from a .psq (the
  // decoder does).
  for (const char* t : {"1", "2"}) {
    ASSERT_EQ(run_psq("convert --threads " + std::string(t) + " " + ply + " " + dir.file(std::string("s") + t + ".psq"),
                      &out, &err), 0) << err;
    ASSERT_EQ(run_psq("convert --bits 12 --threads " + std::string(t) + " " + dir.file("s1.psq") + " " +
                          dir.file(std::string("r") + t + ".psq"), &out, &err), 0) << err;
  }
  EXPECT_EQ(test::read_file(dir.file("s1.psq")), test::read_file(dir.file("s2.psq")));
  EXPECT_EQ(test::read_file(dir.file("r1.psq")), test::read_file(dir.file("r2.psq")));
  EXPECT_NE(test::read_file(dir.file("r1.psq")), test::read_file(dir.file("s1.psq")));
  EXPECT_EQ(run_psq("convert --threads 0 " + ply + " " + dir.file("s3.psq"), &out, &err), 2);
  EXPECT_NE(err.find("bad --threads '0'"), std::string::npos) << err;
  // A truncated input fails while the encoder's thread runs: one line, exit
  // 1, no output left behind.
  const std::string bytes = test::read_file(ply);
  test::write_file(dir.file("cut.ply"), bytes.substr(0, bytes.size() * 3 / 4));
  EXPECT_EQ(run_psq("convert --threads 2 " + dir.file("cut.ply") + " " + dir.file("cut.psq"), &out, &err), 1);
  EXPECT_EQ(count_lines(err), 1) << err;
  EXPECT_NE(err.find("psq: error: " + dir.file("cut.ply") + ": byte "), std::string::npos) << err;
  EXPECT_FALSE(test::file_exists(dir.file("cut.psq")));
  EXPECT_EQ(dir.entries(), (std::vector<std::string>{"cut.ply", "r1.psq", "r2.psq", "s.ply", "s1.psq", "s2.psq"}));
}

// .psq to binary PLY in a file: the segments decode at once and write
// their parts in place (spec 4.6); the bytes are those of the streaming
// writer, which a pipe gets.
TEST(Cli, PsqToPlyBySegmentsWritesTheStreamingWritersBytes) {
  test::TempDir dir;
  std::string ply = write_sphere(dir, "s.ply", true, 80, 120);
  std::string out, err;
  ASSERT_EQ(run_psq("convert --segment 4000 " + ply + " " + dir.file("s.psq"), &out, &err), 0) << err;
  ASSERT_EQ(run_psq("info " + dir.file("s.psq"), &out, &err), 0) << err;
  EXPECT_NE(out.find("segments               5 of 4000 triangles"), std::string::npos) << out;
  std::string piped;
  ASSERT_EQ(run_psq("convert " + dir.file("s.psq") + " - --to ply", &piped, &err), 0) << err;
  for (const char* t : {"1", "2", "3"}) {
    const std::string target = dir.file(std::string("o") + t + ".ply");
    ASSERT_EQ(run_psq("convert -q --threads " + std::string(t) + " " + dir.file("s.psq") + " " + target, &out, &err), 0)
        << err;
    EXPECT_EQ(test::read_file(target), piped) << t;
  }
  // A damaged stream: one error line, no output left behind.
  std::string bytes = test::read_file(dir.file("s.psq"));
  bytes[bytes.size() / 2] ^= 0x40;
  test::write_file(dir.file("bad.psq"), bytes);
  EXPECT_EQ(run_psq("convert " + dir.file("bad.psq") + " " + dir.file("bad.ply"), &out, &err), 1);
  EXPECT_EQ(count_lines(err), 1) << err;
  EXPECT_FALSE(test::file_exists(dir.file("bad.ply")));
}

// --profile auto (the default) picks the fast profile for large inputs,
// also for a PLY, which declares its vertices but not its triangles; the
// header's flag bit 2 (spec 4.2) tells.
TEST(Cli, ConvertPicksTheFastProfileForLargeInputs) {
  test::TempDir dir;
  const std::string small = write_sphere(dir, "small.ply", true);
  const std::string large = write_sphere(dir, "large.ply", true, 200, 330);  // 66,002 vertices
  std::string out, err;
  auto fast_flag = [&](const std::string& psq) {
    const std::string bytes = test::read_file(psq);
    return bytes.size() > 11 && (static_cast<uint8_t>(bytes[10]) & 4) != 0;
  };
  ASSERT_EQ(run_psq("convert " + small + " " + dir.file("small.psq"), &out, &err), 0) << err;
  EXPECT_FALSE(fast_flag(dir.file("small.psq")));
  ASSERT_EQ(run_psq("convert " + large + " " + dir.file("large.psq"), &out, &err), 0) << err;
  EXPECT_TRUE(fast_flag(dir.file("large.psq")));
  ASSERT_EQ(run_psq("convert --profile compact " + large + " " + dir.file("c.psq"), &out, &err), 0) << err;
  EXPECT_FALSE(fast_flag(dir.file("c.psq")));
  // A .psq input keeps its profile under auto.
  ASSERT_EQ(run_psq("convert --bits 12 " + dir.file("large.psq") + " " + dir.file("r.psq"), &out, &err), 0) << err;
  EXPECT_TRUE(fast_flag(dir.file("r.psq")));
  ASSERT_EQ(run_psq("convert --profile fast " + small + " " + dir.file("f.psq"), &out, &err), 0) << err;
  EXPECT_TRUE(fast_flag(dir.file("f.psq")));
  ASSERT_EQ(run_psq("info " + dir.file("f.psq"), &out, &err), 0) << err;
  EXPECT_NE(out.find("1.0, fast profile"), std::string::npos) << out;
  // The JSON summary measures the split of the coded bits, in both profiles.
  for (const char* p : {"fast", "compact"}) {
    ASSERT_EQ(run_psq("convert -f --json --profile " + std::string(p) + " " + small + " " + dir.file("j.psq"), &out, &err),
              0) << err;
    const size_t at = out.find("\"connectivity_bits_per_vertex\": ");
    ASSERT_NE(at, std::string::npos) << out;
    EXPECT_GT(std::atof(out.c_str() + at + 32), 0.5) << p << ": " << out;
  }
  EXPECT_EQ(run_psq("convert --profile quick " + small + " " + dir.file("q.psq"), &out, &err), 2);
}

// --weld: a triangle soup (each triangle with its own three vertices)
// becomes the indexed mesh; without it a note suggests welding.
TEST(Cli, ConvertWeldsASoup) {
  test::TempDir dir;
  const Mesh sphere = test::make_sphere(60, 90);
  Mesh soup;
  soup.schema = sphere.schema;
  for (const auto& t : sphere.triangles) {
    const uint32_t first = static_cast<uint32_t>(soup.positions.size());
    for (int k = 0; k < 3; ++k) soup.positions.push_back(sphere.positions[t[k]]);
    soup.triangles.push_back({first, first + 1, first + 2});
  }
  test::reset_values(&soup);
  {
    OutputFile out;
    ASSERT_TRUE(out.open(dir.file("soup.ply"), false).ok());
    PlyWriter w(&out);
    test::MemorySource src(soup);
    ASSERT_TRUE(pump(src, w).ok());
    ASSERT_TRUE(out.commit().ok());
  }
  const std::string in = dir.file("soup.ply");
  std::string out, err;
  ASSERT_EQ(run_psq("convert " + in + " " + dir.file("plain.psq"), &out, &err), 0) << err;
  EXPECT_NE(err.find("--weld would merge them"), std::string::npos) << err;
  ASSERT_EQ(run_psq("convert -q " + in + " " + dir.file("quiet.psq"), &out, &err), 0) << err;
  EXPECT_EQ(err, "");
  const std::string merged = std::to_string(soup.positions.size() - sphere.positions.size());
  for (const char* mode : {"--weld", "--weld=positions"}) {
    ASSERT_EQ(run_psq("convert -f --json --memory 1M " + std::string(mode) + " " + in + " " + dir.file("w.psq"), &out,
                      &err), 0) << err;
    EXPECT_NE(out.find("\"welded_vertices\": " + merged + ","), std::string::npos) << out;
    EXPECT_NE(out.find("\"weld_dropped_triangles\": 0,"), std::string::npos) << out;
    EXPECT_NE(out.find("\"vertices\": " + std::to_string(sphere.positions.size()) + ","), std::string::npos) << out;
    EXPECT_NE(err.find("--weld merged " + merged + " of"), std::string::npos) << err;
    ASSERT_EQ(run_psq("convert -f " + dir.file("w.psq") + " " + dir.file("w.ply"), &out, &err), 0) << err;
    Mesh back;
    ASSERT_TRUE(test::load_mesh(dir.file("w.ply"), &back).ok());
    EXPECT_EQ(back.positions.size(), sphere.positions.size());
    EXPECT_EQ(back.triangles.size(), sphere.triangles.size());
  }
  EXPECT_LT(test::read_file(dir.file("w.psq")).size() * 3, test::read_file(dir.file("plain.psq")).size());
  EXPECT_EQ(run_psq("convert --weld=normals " + in + " " + dir.file("x.psq"), &out, &err), 2);
  EXPECT_NE(err.find("bad --weld 'normals'"), std::string::npos) << err;
  EXPECT_EQ(run_psq("convert --weld " + in + " " + dir.file("x.ply"), &out, &err), 2);
  EXPECT_EQ(run_psq("convert --weld " + dir.file("plain.psq") + " " + dir.file("x.psq"), &out, &err), 2);
  EXPECT_FALSE(test::file_exists(dir.file("x.psq")));
  EXPECT_FALSE(test::file_exists(dir.file("x.ply")));
}

// --weld=corners: a mesh split at its seams (one vertex per distinct
// position, normal and texture coordinate) becomes one vertex per
// position with its normals and texture coordinates per corner, each
// corner keeping its own.
TEST(Cli, ConvertWeldsCorners) {
  test::TempDir dir;
  const std::string in = std::string(PSQ_TEST_DATA) + "/spider_attributes.ply";
  std::string out, err;
  ASSERT_EQ(run_psq("convert -q " + in + " " + dir.file("split.psq"), &out, &err), 0) << err;
  ASSERT_EQ(run_psq("convert --weld=corners " + in + " " + dir.file("w.psq"), &out, &err), 0) << err;
  EXPECT_NE(err.find("--weld=corners merged 252 of 974 vertices"), std::string::npos) << err;
  ASSERT_EQ(run_psq("convert -f --json --weld=corners " + in + " " + dir.file("j.psq"), &out, &err), 0) << err;
  EXPECT_NE(out.find("\"weld\": \"corners\", \"input_vertices\": 974, \"input_triangles\": 1368, "
                     "\"welded_vertices\": 252, \"weld_dropped_triangles\": 56"),
            std::string::npos)
      << out;
  EXPECT_NE(err.find("56 triangle(s) degenerate after the merge dropped"), std::string::npos) << err;
  ASSERT_EQ(run_psq("info " + dir.file("w.psq"), &out, &err), 0) << err;
  EXPECT_NE(out.find("per-corner normals (corner_normals) quantized, 10-bit octahedral; per-corner texture "
                     "coordinates (corner_uv)"),
            std::string::npos)
      << out;
  EXPECT_LT(test::read_file(dir.file("w.psq")).size() * 10, test::read_file(dir.file("split.psq")).size() * 9);
  ASSERT_EQ(run_psq("convert " + dir.file("w.psq") + " " + dir.file("w.ply"), &out, &err), 0) << err;
  Mesh split, back;
  ASSERT_TRUE(test::load_mesh(in, &split).ok());
  ASSERT_TRUE(test::load_mesh(dir.file("w.ply"), &back).ok());
  EXPECT_EQ(back.positions.size(), 722u);
  ASSERT_EQ(back.triangles.size(), 1312u);
  ASSERT_EQ(back.schema.face_properties.size(), 2u);
  // Every decoded corner is a corner of the split mesh: a vertex there at
  // its position (within the 16-bit grid) with its texture coordinate
  // (within 2^-13).
  double extent = 0;
  for (const auto& p : split.positions)
    for (double c : p) extent = std::max(extent, std::fabs(c));
  const double tol = 2 * extent / 65535;
  for (size_t f = 0; f < back.triangles.size(); ++f) {
    const PropertyValues& v = back.face_values[f];
    ASSERT_EQ(v.size(), 17u);
    for (int k = 0; k < 3; ++k) {
      const auto& p = back.positions[back.triangles[f][k]];
      bool found = false;
      for (size_t i = 0; i < split.positions.size() && !found; ++i) {
        const auto& q = split.positions[i];
        const PropertyValues& w = split.vertex_values[i];  // nx ny nz u v
        found = std::fabs(p[0] - q[0]) <= tol && std::fabs(p[1] - q[1]) <= tol && std::fabs(p[2] - q[2]) <= tol &&
                std::fabs(v[11 + 2 * k] - w[3]) <= 0x1p-13 && std::fabs(v[12 + 2 * k] - w[4]) <= 0x1p-13;
      }
      EXPECT_TRUE(found) << "triangle " << f << " corner " << k;
    }
  }
  EXPECT_EQ(run_psq("convert --weld=corners " + in + " " + dir.file("x.ply"), &out, &err), 2);
  EXPECT_EQ(run_psq("convert --weld=corners " + dir.file("w.psq") + " " + dir.file("x.psq"), &out, &err), 2);
  EXPECT_EQ(run_psq("convert --weld=corners --memory 64K " + in + " " + dir.file("x.psq"), &out, &err), 1);
  EXPECT_NE(err.find("exceeds the memory budget"), std::string::npos) << err;
  EXPECT_FALSE(test::file_exists(dir.file("x.psq")));
  EXPECT_FALSE(test::file_exists(dir.file("x.ply")));
}

// A mesh split at seams every fourth column (its copies' u 0.5 larger):
// the converter suggests --weld=corners, and with it repeats no position.
TEST(Cli, ConvertSuggestsWeldingCorners) {
  test::TempDir dir;
  const int n = 80;
  Mesh grid = test::make_grid(n);
  Mesh m = grid;
  m.schema.vertex_properties = {{"u", ScalarType::kFloat32}, {"v", ScalarType::kFloat32}};
  for (size_t i = 0; i < grid.positions.size(); ++i)
    m.vertex_values[i] = {grid.positions[i][0] / 128, grid.positions[i][1] / 128};
  std::vector<uint32_t> copy(grid.positions.size(), UINT32_MAX);
  for (auto& t : m.triangles) {
    const double x = (grid.positions[t[0]][0] + grid.positions[t[1]][0] + grid.positions[t[2]][0]) / 3;
    if (static_cast<int>(x) % 8 < 4) continue;  // the other side of a seam at columns 4, 8, ...
    for (uint32_t& v : t) {
      const int col = static_cast<int>(grid.positions[v][0]);
      if (col % 4 != 0) continue;
      if (copy[v] == UINT32_MAX) {
        copy[v] = static_cast<uint32_t>(m.positions.size());
        m.positions.push_back(grid.positions[v]);
        m.vertex_values.push_back({grid.positions[v][0] / 128 + 0.5, grid.positions[v][1] / 128});
      }
      v = copy[v];
    }
  }
  m.schema.vertex_count = static_cast<int64_t>(m.positions.size());
  {
    OutputFile out;
    ASSERT_TRUE(out.open(dir.file("split.ply"), false).ok());
    PlyWriter w(&out);
    test::MemorySource src(m);
    ASSERT_TRUE(pump(src, w).ok());
    ASSERT_TRUE(out.commit().ok());
  }
  std::string out, err;
  ASSERT_EQ(run_psq("convert " + dir.file("split.ply") + " " + dir.file("a.psq"), &out, &err), 0) << err;
  EXPECT_NE(err.find("--weld=corners those that differ in normals or texture coordinates only"), std::string::npos)
      << err;
  ASSERT_EQ(run_psq("convert --weld=corners " + dir.file("split.ply") + " " + dir.file("b.psq"), &out, &err), 0)
      << err;
  EXPECT_EQ(err.find("repeat another vertex's position"), std::string::npos) << err;
  EXPECT_NE(err.find("merged " + std::to_string(m.positions.size() - grid.positions.size()) + " of"),
            std::string::npos)
      << err;
}

TEST(Cli, ConvertSafety) {
  test::TempDir dir;
  std::string ply = write_sphere(dir, "s.ply");
  std::string out, err;
  EXPECT_EQ(run_psq("convert " + ply + " " + ply, &out, &err), 2);
  EXPECT_NE(err.find("same file"), std::string::npos);
  test::write_file(dir.file("exists.obj"), "keep");
  EXPECT_EQ(run_psq("convert " + ply + " " + dir.file("exists.obj"), &out, &err), 2);
  EXPECT_EQ(test::read_file(dir.file("exists.obj")), "keep");
  EXPECT_EQ(run_psq("convert -f " + ply + " " + dir.file("exists.obj"), &out, &err), 0) << err;
  EXPECT_NE(test::read_file(dir.file("exists.obj")), "keep");
}

TEST(Cli, FailedConvertLeavesNoFile) {
  test::TempDir dir;
  std::string ply = write_sphere(dir, "s.ply");
  std::string bytes = test::read_file(ply);
  test::write_file(dir.file("cut.ply"), bytes.substr(0, bytes.size() - 20));
  std::string out, err;
  EXPECT_EQ(run_psq("convert " + dir.file("cut.ply") + " " + dir.file("o.obj"), &out, &err), 1);
  EXPECT_EQ(count_lines(err), 1) << err;
  EXPECT_NE(err.find("psq: error: " + dir.file("cut.ply") + ": byte "), std::string::npos) << err;
  EXPECT_EQ(dir.entries(), (std::vector<std::string>{"cut.ply", "s.ply"}));
}

TEST(Cli, SharedMeshesInfoAgreesWithReadme) {
  if (!test::file_exists(shared("meshes/bunny.ply"))) GTEST_SKIP() << "../shared/data not present";
  struct Row {
    const char* file;
    int v, f;
  } rows[] = {{"meshes/bunny.ply", 35947, 69451},     {"meshes/fandisk.ply", 6475, 12946},
              {"meshes/boeing.ply", 2741, 2564},      {"meshes/nonmanifold_wrap.ply", 10, 12},
              {"inputs/fandisk.obj", 6475, 12946},    {"inputs/bun_zipper_ascii.ply", 35947, 69451},
              {"inputs/cube_quads.obj", 8, 12},       {"inputs/cube_quads.ply", 8, 12},
              {"inputs/fandisk.off", 6475, 12946},    {"inputs/pig_binary.stl", 8642, 16848},
              {"inputs/spider_ascii.stl", 722, 1368}, {"inputs/spider_binary.stl", 722, 1368}};
  for (const Row& r : rows) {
    std::string out, err;
    ASSERT_EQ(run_psq("info --json " + shared(r.file), &out, &err), 0) << r.file << ": " << err;
    EXPECT_NE(out.find("\"vertices\": " + std::to_string(r.v) + ","), std::string::npos) << r.file << out;
    EXPECT_NE(out.find("\"triangles\": " + std::to_string(r.f) + ","), std::string::npos) << r.file << out;
  }
  std::string out, err;
  ASSERT_EQ(run_psq("info --json " + shared("meshes/bunny.ply"), &out, &err), 0);
  EXPECT_NE(out.find("\"unreferenced_vertices\": 1113,"), std::string::npos) << out;
}

TEST(Cli, EveryBadFileFailsWithOneLine) {
  std::string dir_path = shared("bad");
  DIR* d = ::opendir(dir_path.c_str());
  if (d == nullptr) GTEST_SKIP() << "../shared/data not present";
  std::vector<std::string> files;
  while (dirent* e = ::readdir(d)) {
    std::string n = e->d_name;
    if (n != "." && n != "..") files.push_back(n);
  }
  ::closedir(d);
  // Degenerate triangles are legal meshes: info reports them with a warning.
  const std::set<std::string> legal = {"draco_deg_faces.obj", "draco_degenerate_mesh.obj"};
  for (const std::string& f : files) {
    std::string out, err;
    int rc = run_psq("info " + dir_path + "/" + f, &out, &err);
    if (legal.count(f)) {
      EXPECT_EQ(rc, 0) << f << ": " << err;
      continue;
    }
    EXPECT_EQ(rc, 1) << f << ": " << out;
    EXPECT_EQ(count_lines(err), 1) << f << ": " << err;
    EXPECT_EQ(err.rfind("psq: error: " + dir_path + "/" + f + ": ", 0), 0u) << err;
    EXPECT_TRUE(out.empty()) << f;
    test::TempDir tmp;
    rc = run_psq("convert " + dir_path + "/" + f + " " + tmp.file("o.ply"), &out, &err);
    EXPECT_EQ(rc, 1) << f;
    EXPECT_TRUE(tmp.entries().empty()) << f;
  }
}

}  // namespace
}  // namespace psq

namespace psq {
namespace {

// Parses a psq-dump text into the checker; fills triangles as position
// triples (rotated so the smallest comes first) for comparison with input.
using PosTri = std::array<std::array<double, 3>, 3>;

Status check_dump(const std::string& text, SequenceChecker* checker, std::vector<PosTri>* tris) {
  std::istringstream in(text);
  std::string line;
  if (!std::getline(in, line) || line != "psq-dump 1") return Status(ErrorCode::kBadSequence, "bad first line");
  PSQ_RETURN_IF_ERROR(checker->begin(MeshSchema()));
  std::vector<std::array<double, 3>> pos;
  std::vector<int> uses;
  bool fresh_since_triangle = false;
  std::vector<char> fresh;
  while (std::getline(in, line)) {
    std::istringstream ls(line);
    std::string kind;
    ls >> kind;
    if (kind == "v") {
      SequenceVertex v;
      v.index = static_cast<uint32_t>(pos.size());
      // %.9g of a float reads back exactly as a float (the meshes here are float).
      for (int k = 0; k < 3; ++k) {
        std::string num;
        ls >> num;
        v.position[k] = std::strtof(num.c_str(), nullptr);
      }
      std::string tok;
      if (ls >> tok && tok[0] == '~') v.reappears = static_cast<uint32_t>(std::stoul(tok.substr(1)));
      pos.push_back({v.position[0], v.position[1], v.position[2]});
      fresh.push_back(1);
      fresh_since_triangle = true;
      PSQ_RETURN_IF_ERROR(checker->vertex(v));
    } else if (kind == "t") {
      SequenceTriangle t;
      std::string op;
      unsigned mask;
      ls >> t.v[0] >> t.v[1] >> t.v[2] >> op >> mask;
      const char* names[] = {"start", "add", "join", "fill", "end"};
      int o = static_cast<int>(std::find(names, names + 5, op) - names);
      if (o == 5) return Status(ErrorCode::kBadSequence, "bad op " + op);
      t.op = static_cast<Op>(o);
      t.border_mask = static_cast<uint8_t>(mask);
      for (int k = 0; k < 3; ++k) {
        if (t.v[k] >= pos.size()) return Status(ErrorCode::kBadSequence, "index out of range");
        if (fresh[t.v[k]]) t.new_mask |= static_cast<uint8_t>(1 << k);
      }
      for (int k = 0; k < 3; ++k) fresh[t.v[k]] = 0;
      fresh_since_triangle = false;
      PSQ_RETURN_IF_ERROR(checker->triangle(t));
      PosTri pt = {pos[t.v[0]], pos[t.v[1]], pos[t.v[2]]};
      while (pt[0] > pt[1] || pt[0] > pt[2]) std::rotate(pt.begin(), pt.begin() + 1, pt.end());
      tris->push_back(pt);
    } else if (kind == "x") {
      uint32_t a;
      ls >> a;
      PSQ_RETURN_IF_ERROR(checker->finalize(a));
    } else {
      return Status(ErrorCode::kBadSequence, "bad line: " + line);
    }
  }
  (void)fresh_since_triangle;
  return checker->finish();
}

std::vector<PosTri> input_triangles(const test::Mesh& m) {
  std::vector<PosTri> out;
  for (const auto& t : m.triangles) {
    if (t[0] == t[1] || t[1] == t[2] || t[2] == t[0]) continue;
    PosTri pt = {m.positions[t[0]], m.positions[t[1]], m.positions[t[2]]};
    while (pt[0] > pt[1] || pt[0] > pt[2]) std::rotate(pt.begin(), pt.begin() + 1, pt.end());
    out.push_back(pt);
  }
  std::sort(out.begin(), out.end());
  return out;
}

TEST(CliDump, ShippedAndSharedMeshesDumpValidSequences) {
  std::vector<std::string> files = {std::string(PSQ_TEST_DATA) + "/max_export_nm.ply",
                                    std::string(PSQ_TEST_DATA) + "/spider.ply",
                                    std::string(PSQ_TEST_DATA) + "/nonmanifold_wrap.ply",
                                    std::string(PSQ_TEST_DATA) + "/cube_quads.obj"};
  for (const char* f : {"meshes/bunny.ply", "meshes/boeing.ply", "meshes/blobby_shuffled.ply", "meshes/b9_mesh.ply",
                        "meshes/iso_labyrinth_200k.ply"}) {
    if (test::file_exists(shared(f))) files.push_back(shared(f));
  }
  for (const std::string& f : files) {
    std::string out, err;
    ASSERT_EQ(run_psq("dump " + f, &out, &err), 0) << f << ": " << err;
    SequenceChecker checker;
    std::vector<PosTri> tris;
    Status s = check_dump(out, &checker, &tris);
    ASSERT_TRUE(s.ok()) << f << ": " << s.to_string();
    std::sort(tris.begin(), tris.end());
    Mesh m;
    ASSERT_TRUE(test::load_mesh(f, &m).ok());
    EXPECT_EQ(tris, input_triangles(m)) << f;
  }
}

TEST(CliDump, SortPathUnderSmallMemoryAndPipes) {
  test::TempDir dir;
  std::string ply = write_sphere(dir, "s.ply");
  std::string a, b, err;
  ASSERT_EQ(run_psq("dump " + ply, &a, &err), 0) << err;
  ASSERT_EQ(run_psq("dump --sort --memory 1M --tmpdir " + dir.path() + " -", &b, &err, ply), 0) << err;
  for (const std::string* text : {&a, &b}) {
    SequenceChecker checker;
    std::vector<PosTri> tris;
    ASSERT_TRUE(check_dump(*text, &checker, &tris).ok());
    EXPECT_EQ(checker.stats().components, 1u);
  }
  EXPECT_EQ(dir.entries(), (std::vector<std::string>{"s.ply"}));  // temporary files are gone
  EXPECT_EQ(run_psq("dump --memory 12Q " + ply, &a, &err), 2);
}

TEST(CliInfo, SequenceStatisticsOfSharedMeshes) {
  if (!test::file_exists(shared("meshes/cheese.ply"))) GTEST_SKIP() << "../shared/data not present";
  struct Row {
    const char* file;
    const char* expect[4];
  } rows[] = {
      {"meshes/cheese.ply", {"\"components\": 1,", "\"handles\": 133,", "\"border_edges\": 0,", "\"nonmanifold_edges\": 0,"}},
      {"meshes/bunny.ply", {"\"components\": 1,", "\"border_edges\": 223,", "\"border_loops\": 5,", "\"handles\": 0,"}},
      {"meshes/bones.ply", {"\"components\": 26,", "\"border_edges\": 0,", "\"handles\": 0,", "\"nonmanifold_edges\": 0,"}},
      {"meshes/max_export_nm.ply", {"\"components\": 24,", "\"nonmanifold_edges\": 16,", "\"border_edges\": 0,", "\"misoriented_edges\": 0,"}},
      {"meshes/blobby_shuffled.ply", {"\"components\": 1,", "\"misoriented_edges\": 3069,", "\"border_edges\": 0,", "\"nonmanifold_edges\": 0,"}},
  };
  for (const Row& r : rows) {
    std::string out, err;
    ASSERT_EQ(run_psq("info --json " + shared(r.file), &out, &err), 0) << err;
    for (const char* e : r.expect) EXPECT_NE(out.find(e), std::string::npos) << r.file << " lacks " << e << "\n" << out;
  }
}


// ----------------------------------------------- data safety (issue 32)

namespace safety {

// Runs `command` with /bin/sh; returns its exit status.
int shell(const std::string& command) {
  int rc = std::system(command.c_str());
  return WIFEXITED(rc) ? WEXITSTATUS(rc) : 128;
}

std::string psq_binary() { return PSQ_BINARY; }

// How many entries the directory `path` holds.
size_t entry_count(const std::string& path) {
  size_t n = 0;
  DIR* d = ::opendir(path.c_str());
  if (d == nullptr) return 0;
  while (dirent* e = ::readdir(d)) n += std::string(e->d_name) != "." && std::string(e->d_name) != "..";
  ::closedir(d);
  return n;
}

// A reader that stops early ("| head -c 100") makes psq exit quietly with
// 141, whatever it writes, and leaves no temporary file behind.
TEST(CliSafety, ClosedOutputPipeExitsQuietlyWith141) {
  test::TempDir dir;
  std::string ply = write_sphere(dir, "big.ply", true, 200, 300);
  ASSERT_EQ(::mkdir(dir.file("tmp").c_str(), 0700), 0);
  for (const char* to : {"ply", "obj", "psq"}) {
    SCOPED_TRACE(to);
    std::string cmd = "{ " + psq_binary() + " convert " + ply + " - --to " + to + " --tmpdir " + dir.file("tmp") +
                      " 2>" + dir.file("err") + "; echo $? >" + dir.file("rc") + "; } | head -c 100 >" +
                      dir.file("out");
    ASSERT_EQ(shell(cmd), 0);
    EXPECT_EQ(test::read_file(dir.file("rc")), "141\n");
    EXPECT_EQ(test::read_file(dir.file("err")), "");
    EXPECT_EQ(test::read_file(dir.file("out")).size(), 100u);
    EXPECT_EQ(entry_count(dir.file("tmp")), 0u);
  }
  // A dump too.
  std::string cmd = "{ " + psq_binary() + " dump " + ply + " 2>" + dir.file("err") + "; echo $? >" + dir.file("rc") +
                    "; } | head -c 10 >/dev/null";
  ASSERT_EQ(shell(cmd), 0);
  EXPECT_EQ(test::read_file(dir.file("rc")), "141\n");
  EXPECT_EQ(test::read_file(dir.file("err")), "");
  std::string out, err;
  EXPECT_NE(run_psq("convert --help", &out, &err), 1);
  EXPECT_NE(out.find("cannot be taken back"), std::string::npos);
}

// The PLY: double coordinates whose range overflows the
// quantization arithmetic. Refused (no output), kept exactly when lossless.
TEST(CliSafety, UnrepresentablePositionsAreRefusedNotGarbled) {
  test::TempDir dir;
  test::write_file(dir.file("big.ply"),
                   "ply\nformat ascii 1.0\nelement vertex 3\nproperty double x\nproperty double y\nproperty double z\n"
                   "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
                   "9e307 0 0\n-9e307 0 0\n0 9e307 0\n3 0 1 2\n");
  std::string out, err;
  for (const char* target : {"q.psq", "q.drc"}) {
    EXPECT_EQ(run_psq("convert " + dir.file("big.ply") + " " + dir.file(target), &out, &err), 1) << target;
    EXPECT_EQ(count_lines(err), 1) << err;
    EXPECT_FALSE(test::file_exists(dir.file(target))) << target;
  }
  EXPECT_EQ(run_psq("convert --lossless " + dir.file("big.ply") + " " + dir.file("l.psq"), &out, &err), 0) << err;
  EXPECT_EQ(run_psq("verify " + dir.file("l.psq"), &out, &err), 0) << err;
  EXPECT_EQ(run_psq("convert " + dir.file("l.psq") + " - --to obj", &out, &err), 0) << err;
  EXPECT_NE(out.find("v 9e+307 0 0\nv -9e+307 0 0\nv 0 9e+307 0\n"), std::string::npos) << out;
}

// Header leniency as a user sees it: a note, not an error.
TEST(CliSafety, BareHeaderLineGivesANoteAndMissingEndHeaderSaysSo) {
  test::TempDir dir;
  const std::string body = "element vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                           "element face 1\nproperty list uchar int vertex_indices\n";
  test::write_file(dir.file("b.ply"), "ply\nformat ascii 1.0\nCreated by Blender3D 247 - www.blender.org, source "
                                      "file: ''\n" + body + "end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
  std::string out, err;
  EXPECT_EQ(run_psq("convert " + dir.file("b.ply") + " " + dir.file("b.psq"), &out, &err), 0) << err;
  EXPECT_NE(err.find("psq: note: " + dir.file("b.ply") + ": header line 3 is not PLY"), std::string::npos) << err;
  test::write_file(dir.file("n.ply"), "ply\nformat ascii 1.0\n" + body);
  EXPECT_EQ(run_psq("convert " + dir.file("n.ply") + " " + dir.file("n.psq"), &out, &err), 1);
  EXPECT_NE(err.find("line 9: missing end_header"), std::string::npos) << err;
}

// -f keeps the replaced file's mode; pipes and devices are written in
// place; a directory is refused; a symbolic link is written through.
TEST(CliSafety, OutputTargetsOfEveryKind) {
  test::TempDir dir;
  std::string ply = write_sphere(dir, "s.ply");
  std::string out, err;
  const std::string kept = dir.file("kept.ply");
  test::write_file(kept, "old");
  ASSERT_EQ(::chmod(kept.c_str(), 0600), 0);
  EXPECT_EQ(run_psq("convert -f " + ply + " " + kept, &out, &err), 0) << err;
  struct stat st;
  ASSERT_EQ(::stat(kept.c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 07777, 0600u);
  EXPECT_GT(st.st_size, 100);
  // /dev/null, with or without -f: still the device.
  EXPECT_EQ(run_psq("convert " + ply + " /dev/null --to ply", &out, &err), 0) << err;
  EXPECT_EQ(run_psq("convert -f " + ply + " /dev/null --to psq", &out, &err), 0) << err;
  ASSERT_EQ(::stat("/dev/null", &st), 0);
  EXPECT_TRUE(S_ISCHR(st.st_mode));
  // A FIFO with a reader.
  const std::string fifo = dir.file("pipe.ply");
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  ASSERT_EQ(shell("cat " + fifo + " >" + dir.file("from_pipe.ply") + " & " + psq_binary() + " convert " + ply + " " +
                  fifo + " 2>" + dir.file("err") + "; rc=$?; wait; exit $rc"),
            0)
      << test::read_file(dir.file("err"));
  ASSERT_EQ(::lstat(fifo.c_str(), &st), 0);
  EXPECT_TRUE(S_ISFIFO(st.st_mode));
  Mesh a, b;
  ASSERT_TRUE(test::load_mesh(ply, &a).ok());
  ASSERT_TRUE(test::load_mesh(dir.file("from_pipe.ply"), &b).ok());
  EXPECT_EQ(a.positions, b.positions);
  // A directory.
  ASSERT_EQ(::mkdir(dir.file("d.ply").c_str(), 0700), 0);
  EXPECT_EQ(run_psq("convert -f " + ply + " " + dir.file("d.ply"), &out, &err), 2);
  EXPECT_NE(err.find("is a directory"), std::string::npos) << err;
  // A symbolic link: the link stays, its target gets the mesh.
  ASSERT_EQ(::symlink("kept.ply", dir.file("link.ply").c_str()), 0);
  EXPECT_EQ(run_psq("convert " + ply + " " + dir.file("link.ply"), &out, &err), 2);  // kept.ply exists
  EXPECT_EQ(run_psq("convert -f --ascii " + ply + " " + dir.file("link.ply"), &out, &err), 0) << err;
  ASSERT_EQ(::lstat(dir.file("link.ply").c_str(), &st), 0);
  EXPECT_TRUE(S_ISLNK(st.st_mode));
  EXPECT_NE(test::read_file(kept).find("format ascii"), std::string::npos);
}

}  // namespace safety
}  // namespace
}  // namespace psq
