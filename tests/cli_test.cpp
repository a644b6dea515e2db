// The psq binary as a user runs it: exit codes, stdout/stderr discipline,
// atomic outputs, pipes, and the shared corpus.
#include <gtest/gtest.h>

#include <dirent.h>

#include <algorithm>
#include <regex>
#include <set>
#include <string>

#include "psq/ply.h"
#include "test_util.h"

namespace psq {
namespace {

using test::Mesh;
using test::run_psq;

std::string shared(const std::string& rel) { return std::string(PSQ_SHARED_DATA) + "/" + rel; }

// Writes a generated mesh as binary PLY and returns its path.
std::string write_sphere(const test::TempDir& dir, const std::string& name, bool with_props = false) {
  Mesh m = test::make_sphere(10, 16);
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
  EXPECT_TRUE(out.empty());
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
              {"inputs/cube_quads.obj", 8, 12},       {"inputs/cube_quads.ply", 8, 12}};
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
