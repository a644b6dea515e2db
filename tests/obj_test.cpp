// SPDX-License-Identifier: Apache-2.0
// Tests of the OBJ reader and writer (psq/obj.h).

#include <unistd.h>

#include <array>
#include <cmath>
#include <cstring>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "psq/obj.h"
#include "test_util.h"

namespace psq {
namespace {

using test::Mesh;
using test::MemorySink;
using test::TempDir;

const std::string kShared = PSQ_SHARED_DATA;

// Reads OBJ text through a file, the way the tools do.
Status read_obj(const std::string& text, Mesh* mesh, SourceReport* report = nullptr) {
  TempDir dir;
  test::write_file(dir.file("in.obj"), text);
  InputStream in;
  PSQ_RETURN_IF_ERROR(in.open(dir.file("in.obj")));
  ObjReader reader;
  PSQ_RETURN_IF_ERROR(reader.open(&in, dir.path()));
  MemorySink sink;
  Status s = pump(reader, sink);
  if (report != nullptr) *report = reader.report();
  PSQ_RETURN_IF_ERROR(s);
  *mesh = std::move(sink.mesh);
  return Status();
}

Status read_obj_file(const std::string& path, Mesh* mesh, SourceReport* report = nullptr) {
  InputStream in;
  PSQ_RETURN_IF_ERROR(in.open(path));
  ObjReader reader;
  PSQ_RETURN_IF_ERROR(reader.open(&in));
  MemorySink sink;
  PSQ_RETURN_IF_ERROR(pump(reader, sink));
  if (report != nullptr) *report = reader.report();
  *mesh = std::move(sink.mesh);
  return Status();
}

using Tri = std::array<uint32_t, 3>;
using Pos = std::array<double, 3>;

std::vector<std::string> property_names(const std::vector<Property>& props) {
  std::vector<std::string> names;
  for (const Property& p : props) names.push_back(p.name);
  return names;
}

bool looks(const std::string& s) { return looks_like_obj(reinterpret_cast<const uint8_t*>(s.data()), s.size()); }

TEST(Obj, LooksLikeObj) {
  EXPECT_TRUE(looks("v 1 2 3\n"));
  EXPECT_TRUE(looks("# comment\n\n  # another\r\nv 1 2 3"));
  EXPECT_TRUE(looks("\tf 1 2 3"));
  EXPECT_TRUE(looks("mtllib a.mtl\n"));
  EXPECT_TRUE(looks("o cube"));
  EXPECT_TRUE(looks("vn 0 0 1"));
  EXPECT_FALSE(looks(""));
  EXPECT_FALSE(looks("   \n\n"));
  EXPECT_FALSE(looks("# only a comment\n"));
  EXPECT_FALSE(looks("ply\nformat ascii 1.0\n"));
  EXPECT_FALSE(looks("OFF\n3 1 0\n"));
  EXPECT_FALSE(looks("solid cube\n"));
  EXPECT_FALSE(looks("vertex 1 2 3"));
  EXPECT_FALSE(looks(std::string("v \x01\x02\x03\x00\xff", 7)));
  EXPECT_FALSE(looks(std::string("\x00\x01\x02v 1 2 3", 10)));
}

TEST(Obj, PlainTriangles) {
  Mesh m;
  SourceReport report;
  ASSERT_TRUE(read_obj("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 2 4 3\n", &m, &report).ok());
  EXPECT_EQ(m.schema.position_type, ScalarType::kFloat32);
  EXPECT_TRUE(m.schema.vertex_properties.empty());
  EXPECT_EQ(m.schema.vertex_count, 4);
  EXPECT_EQ(m.schema.triangle_count, 2);
  EXPECT_EQ(m.positions, (std::vector<Pos>{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0}}));
  EXPECT_EQ(m.triangles, (std::vector<Tri>{{0, 1, 2}, {1, 3, 2}}));
  EXPECT_EQ(report.polygons_triangulated, 0u);
  EXPECT_TRUE(report.notes.empty());
  for (const auto& v : m.vertex_values) EXPECT_TRUE(v.empty());
}

TEST(Obj, SlashFormsWithoutAttributes) {
  // v/t and v//n need vt and vn; with them the same triangles come out.
  const std::string verts = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nvn 0 0 1\n";
  for (const std::string face : {"f 1/1 2/2 3/3\n", "f 1//1 2//1 3//1\n", "f 1/1/1 2/2/1 3/3/1\n", "f 1 2 3\n"}) {
    Mesh m;
    ASSERT_TRUE(read_obj(verts + face, &m).ok()) << face;
    EXPECT_EQ(m.positions.size(), 3u) << face;
    EXPECT_EQ(m.triangles, (std::vector<Tri>{{0, 1, 2}})) << face;
  }
}

TEST(Obj, AttributeIndicesWithoutAttributesAreIgnored) {
  // Some writers emit f a//a with no vn line at all: nothing to refer to.
  Mesh m;
  SourceReport report;
  ASSERT_TRUE(read_obj("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1//1 2//2 3//3\nf 1/7 2/8 3/-9\n", &m, &report).ok());
  EXPECT_TRUE(m.schema.vertex_properties.empty());
  EXPECT_EQ(m.triangles, (std::vector<Tri>{{0, 1, 2}, {0, 1, 2}}));
  EXPECT_EQ(report.notes, (std::vector<std::string>{"3 texture coordinate indices ignored: the file has no vt lines",
                                                    "3 normal indices ignored: the file has no vn lines"}));
}

TEST(Obj, TexcoordsOnly) {
  Mesh m;
  ASSERT_TRUE(read_obj("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0.25 0.5\nvt 1 0 0\nvt 0 1\nf 1/1 2/2 3/3\n", &m).ok());
  EXPECT_EQ(property_names(m.schema.vertex_properties), (std::vector<std::string>{"u", "v"}));
  EXPECT_EQ(m.schema.vertex_properties[0].type, ScalarType::kFloat32);
  ASSERT_EQ(m.vertex_values.size(), 3u);
  EXPECT_EQ(m.vertex_values[0], (PropertyValues{0.25, 0.5}));
  EXPECT_EQ(m.vertex_values[1], (PropertyValues{1, 0}));
  EXPECT_EQ(m.vertex_values[2], (PropertyValues{0, 1}));
}

TEST(Obj, NormalsOnly) {
  Mesh m;
  ASSERT_TRUE(read_obj("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 5 5 5\nvn 0 0 1\nvn 0 1 0\nf 1//1 2//1 3//2\n", &m).ok());
  EXPECT_EQ(property_names(m.schema.vertex_properties), (std::vector<std::string>{"nx", "ny", "nz"}));
  EXPECT_EQ(m.schema.vertex_count, 4);
  EXPECT_EQ(m.schema.triangle_count, 1);
  ASSERT_EQ(m.vertex_values.size(), 4u);
  EXPECT_EQ(m.vertex_values[0], (PropertyValues{0, 0, 1}));
  EXPECT_EQ(m.vertex_values[2], (PropertyValues{0, 1, 0}));
  EXPECT_EQ(m.vertex_values[3], (PropertyValues{0, 0, 0}));  // unreferenced
}

TEST(Obj, NormalsAndTexcoordsWithoutSplit) {
  Mesh m;
  SourceReport report;
  const std::string text =
      "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\n"
      "vt 0 0\nvt 1 0\nvt 0 1\nvt 1 1\n"
      "vn 0 0 1\n"
      "f 1/1/1 2/2/1 3/3/1\nf 2/2/1 4/4/1 3/3/1\n";
  ASSERT_TRUE(read_obj(text, &m, &report).ok());
  EXPECT_EQ(property_names(m.schema.vertex_properties),
            (std::vector<std::string>{"nx", "ny", "nz", "u", "v"}));
  EXPECT_EQ(m.positions.size(), 4u);
  EXPECT_EQ(m.schema.vertex_count, 4);
  EXPECT_EQ(m.triangles, (std::vector<Tri>{{0, 1, 2}, {1, 3, 2}}));
  EXPECT_EQ(m.vertex_values[3], (PropertyValues{0, 0, 1, 1, 1}));
  EXPECT_TRUE(report.notes.empty());
}

TEST(Obj, CornerWithoutAttributesIsCompatible) {
  Mesh m;
  SourceReport report;
  ASSERT_TRUE(read_obj("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0.5 0.5\nf 1/1 2/1 3/1\nf 1 2 3\n", &m, &report).ok());
  EXPECT_EQ(property_names(m.schema.vertex_properties), (std::vector<std::string>{"u", "v"}));
  EXPECT_TRUE(m.schema.face_properties.empty());
  EXPECT_EQ(m.positions.size(), 3u);
  EXPECT_EQ(m.vertex_values[2], (PropertyValues{0.5, 0.5}));
  EXPECT_EQ(m.triangles, (std::vector<Tri>{{0, 1, 2}, {0, 1, 2}}));
  EXPECT_TRUE(report.notes.empty());
}

// As cube_quads.obj: every corner of the cube is on three faces, with three
// normals and several texture coordinates.
const char kFlatCube[] =
    "v 0 0 0\nv 0 0 1\nv 0 1 0\nv 0 1 1\nv 1 0 0\nv 1 0 1\nv 1 1 0\nv 1 1 1\n"
    "vn 0 0 1\nvn 0 0 -1\nvn 0 1 0\nvn 0 -1 0\nvn 1 0 0\nvn -1 0 0\n"
    "vt 0 0\nvt 0 1\nvt 1 0\nvt 1 1\n"
    "f 1/4/2 3/3/2 7/1/2 5/2/2\n"
    "f 1/2/6 2/4/6 4/3/6 3/1/6\n"
    "f 3/1/3 4/2/3 8/4/3 7/3/3\n"
    "f 5/4/5 7/3/5 8/1/5 6/2/5\n"
    "f 1/2/4 5/4/4 6/3/4 2/1/4\n"
    "f 2/2/1 6/4/1 8/3/1 4/1/1\n";

TEST(Obj, FlatShadedCubeKeepsConnectivity) {
  Mesh m;
  SourceReport report;
  ASSERT_TRUE(read_obj(kFlatCube, &m, &report).ok());
  EXPECT_EQ(m.schema.vertex_count, 8);
  EXPECT_EQ(m.schema.triangle_count, 12);
  ASSERT_EQ(m.positions.size(), 8u);
  EXPECT_EQ(m.positions[7], (Pos{1, 1, 1}));
  ASSERT_EQ(m.triangles.size(), 12u);
  EXPECT_EQ(m.triangles[0], (Tri{0, 2, 6}));
  EXPECT_EQ(m.triangles[1], (Tri{0, 6, 4}));
  EXPECT_TRUE(m.schema.vertex_properties.empty());
  ASSERT_EQ(property_names(m.schema.face_properties), (std::vector<std::string>{"corner_normals", "corner_uv"}));
  for (const Property& p : m.schema.face_properties) {
    EXPECT_TRUE(p.is_list);
    EXPECT_EQ(p.type, ScalarType::kFloat32);
    EXPECT_EQ(p.count_type, ScalarType::kUInt8);
  }
  ASSERT_EQ(m.face_values.size(), 12u);
  // Triangle 3 is the second of `f 1/2/6 2/4/6 4/3/6 3/1/6`: corners 1, 4, 3.
  EXPECT_EQ(m.triangles[3], (Tri{0, 3, 2}));
  EXPECT_EQ(m.face_values[3], (PropertyValues{9, -1, 0, 0, -1, 0, 0, -1, 0, 0, 6, 0, 1, 1, 0, 0, 0}));
  EXPECT_EQ(report.polygons_triangulated, 6u);
  EXPECT_EQ(report.notes,
            (std::vector<std::string>{"normals vary per corner at 8 vertices: kept as per-corner face property corner_normals",
                                      "texture coordinates vary per corner at 8 vertices: kept as per-corner face property corner_uv"}));
}

TEST(Obj, PerCornerAttributesFollowTheFan) {
  // Normals vary (position 1 has two), texture coordinates do not; a corner
  // without a normal gets 0s.
  Mesh m;
  SourceReport report;
  const std::string text =
      "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
      "vn 0 0 1\nvn 0 1 0\nvt 0.25 0.75\n"
      "f 1/1/1 2/1/2 3/1/1 4/1\n"
      "f 1//2 3 2\n";
  ASSERT_TRUE(read_obj(text, &m, &report).ok());
  EXPECT_EQ(m.positions.size(), 4u);
  EXPECT_EQ(property_names(m.schema.vertex_properties), (std::vector<std::string>{"u", "v"}));
  EXPECT_EQ(m.vertex_values[3], (PropertyValues{0.25, 0.75}));
  EXPECT_EQ(property_names(m.schema.face_properties), (std::vector<std::string>{"corner_normals"}));
  EXPECT_EQ(m.triangles, (std::vector<Tri>{{0, 1, 2}, {0, 2, 3}, {0, 2, 1}}));
  ASSERT_EQ(m.face_values.size(), 3u);
  EXPECT_EQ(m.face_values[0], (PropertyValues{9, 0, 0, 1, 0, 1, 0, 0, 0, 1}));
  EXPECT_EQ(m.face_values[1], (PropertyValues{9, 0, 0, 1, 0, 0, 1, 0, 0, 0}));
  EXPECT_EQ(m.face_values[2], (PropertyValues{9, 0, 1, 0, 0, 0, 0, 0, 0, 0}));
  EXPECT_EQ(report.notes,
            (std::vector<std::string>{"normals vary per corner at 1 vertices: kept as per-corner face property corner_normals"}));
}

TEST(Obj, NegativeIndices) {
  Mesh m;
  const std::string text =
      "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\n"
      "v 1 1 0\nf -3 -1 -2\n";
  ASSERT_TRUE(read_obj(text, &m).ok());
  EXPECT_EQ(m.triangles, (std::vector<Tri>{{0, 1, 2}, {1, 3, 2}}));

  Mesh n;
  ASSERT_TRUE(read_obj("v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nvt 1 1\nf -3/-1/-1 -2//-1 +3/1/1\n", &n).ok());
  EXPECT_EQ(n.triangles.size(), 1u);
}

TEST(Obj, PolygonsBecomeFans) {
  Mesh m;
  SourceReport report;
  const std::string text =
      "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv -1 0.5 0\n"
      "f 1 2 3 4\n"
      "f 1 4 5 2 3\n"
      "f 1 2 3\n";
  ASSERT_TRUE(read_obj(text, &m, &report).ok());
  EXPECT_EQ(m.schema.triangle_count, 6);
  EXPECT_EQ(m.triangles, (std::vector<Tri>{{0, 1, 2}, {0, 2, 3}, {0, 3, 4}, {0, 4, 1}, {0, 1, 2}, {0, 1, 2}}));
  EXPECT_EQ(report.polygons_triangulated, 2u);
}

TEST(Obj, CommentsBlankLinesCrlfAndWhitespace) {
  Mesh m;
  SourceReport report;
  const std::string text =
      "# header comment\r\n"
      "#second\r\n"
      "\r\n"
      "o thing\r\n"
      "g group\r\n"
      "s 1\r\n"
      "mtllib x.mtl\r\n"
      "usemtl red\r\n"
      "v\t0  0\t 0   # trailing comment\r\n"
      "   v 1 0 0\r"
      "v +1 1 0\n"
      "\t\n"
      "v 0 1.0e0 -0\r\n"
      "vp 0.5 0.5\r\n"
      "l 1 2\r\n"
      "p 3\r\n"
      "f 1 2 3 4 # quad\r\n"
      "f 1 \\\r\n"
      "  2 \\\r\n"
      "  3\r\n"
      "unknownstatement 1 2 3\r\n"
      "f 1 2 3";  // no final line end
  ASSERT_TRUE(read_obj(text, &m, &report).ok());
  EXPECT_EQ(m.positions, (std::vector<Pos>{{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}}));
  EXPECT_TRUE(std::signbit(m.positions[3][2]));
  EXPECT_EQ(m.triangles, (std::vector<Tri>{{0, 1, 2}, {0, 2, 3}, {0, 1, 2}, {0, 1, 2}}));
  EXPECT_EQ(m.schema.comments, (std::vector<std::string>{"header comment", "second"}));
  EXPECT_EQ(report.polygons_triangulated, 1u);
  // Statements of the OBJ specification psq does not use pass quietly; one
  // with no OBJ keyword is named in a note.
  EXPECT_EQ(report.notes,
            (std::vector<std::string>{"2 line/point elements ignored",
                                      "1 statement(s) with no OBJ keyword ignored (the first, line 21: "
                                      "'unknownstatement 1 2 3')"}));
}

TEST(Obj, Colours) {
  Mesh m;
  ASSERT_TRUE(read_obj("v 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 0 1 0 0 0 0.5\nf 1 2 3\n", &m).ok());
  EXPECT_EQ(property_names(m.schema.vertex_properties), (std::vector<std::string>{"red", "green", "blue"}));
  EXPECT_EQ(m.schema.vertex_properties[0].type, ScalarType::kFloat32);
  EXPECT_EQ(m.vertex_values[0], (PropertyValues{1, 0, 0}));
  EXPECT_EQ(m.vertex_values[2], (PropertyValues{0, 0, 0.5}));

  Mesh w;  // a fourth coordinate (OBJ's rational weight) is ignored
  ASSERT_TRUE(read_obj("v 0 0 0 1\nv 1 0 0 1\nv 0 1 0 1\nf 1 2 3\n", &w).ok());
  EXPECT_TRUE(w.schema.vertex_properties.empty());
  EXPECT_EQ(w.positions[1], (Pos{1, 0, 0}));

  Mesh n;  // colours on later vertices only are noted, not carried
  SourceReport report;
  ASSERT_TRUE(read_obj("v 0 0 0\nv 1 0 0 1 1 1\nv 0 1 0 1 1 1\nf 1 2 3\n", &n, &report).ok());
  EXPECT_TRUE(n.schema.vertex_properties.empty());
  EXPECT_EQ(report.notes, (std::vector<std::string>{"colours of 2 vertices ignored: the first vertex has none"}));

  Mesh c;  // colours with normals (read in memory)
  ASSERT_TRUE(read_obj("v 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 0 1 0 0 0 1\nvn 0 0 1\nf 1//1 2//1 3//1\n", &c).ok());
  EXPECT_EQ(property_names(c.schema.vertex_properties),
            (std::vector<std::string>{"nx", "ny", "nz", "red", "green", "blue"}));
  EXPECT_EQ(c.vertex_values[1], (PropertyValues{0, 0, 1, 0, 1, 0}));
}

TEST(Obj, PositionsAreRoundedToFloat) {
  Mesh m;
  ASSERT_TRUE(read_obj("v 0.1 0.2 1e-50\nv 1e-40 0 0\nv 0 0 0\nf 1 2 3\n", &m).ok());
  EXPECT_EQ(m.positions[0][0], static_cast<double>(0.1f));
  EXPECT_EQ(m.positions[0][1], static_cast<double>(0.2f));
  EXPECT_EQ(m.positions[0][2], 0.0);
  EXPECT_EQ(m.positions[1][0], static_cast<double>(1e-40f));
}

TEST(Obj, VerticesComeBeforeTrianglesWhenInterleaved) {
  Mesh m;
  const std::string text =
      "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"
      "v 1 1 0\nf 2 4 3\nf -1 -3 -2\n";
  ASSERT_TRUE(read_obj(text, &m).ok());
  EXPECT_EQ(m.positions.size(), 4u);
  EXPECT_EQ(m.triangles, (std::vector<Tri>{{0, 1, 2}, {1, 3, 2}, {3, 1, 2}}));

  // The order is visible at the source: all four vertices, then triangles.
  InputStream in;
  in.open_memory(text.data(), text.size());
  ObjReader reader;
  ASSERT_TRUE(reader.open(&in).ok());
  std::vector<MeshItem::Kind> kinds;
  MeshItem item;
  do {
    ASSERT_TRUE(reader.next(&item).ok());
    kinds.push_back(item.kind);
  } while (item.kind != MeshItem::Kind::kEnd);
  using K = MeshItem::Kind;
  EXPECT_EQ(kinds, (std::vector<K>{K::kVertex, K::kVertex, K::kVertex, K::kVertex, K::kTriangle, K::kTriangle,
                                   K::kTriangle, K::kEnd}));

  // A face may not use a vertex defined after it, even though it is read later.
  Status s = read_obj("v 0 0 0\nv 1 0 0\nf 1 2 3\nv 0 1 0\n", &m);
  EXPECT_EQ(s.code(), ErrorCode::kBadIndex);
  EXPECT_EQ(s.line(), 3u);
}

TEST(Obj, EmptyAndGeometryFreeFilesAreEmptyMeshes) {
  for (const std::string text : {"", "# nothing\n", "o empty\ng g\n"}) {
    Mesh m;
    ASSERT_TRUE(read_obj(text, &m).ok()) << text;
    EXPECT_EQ(m.schema.vertex_count, 0);
    EXPECT_EQ(m.schema.triangle_count, 0);
    EXPECT_TRUE(m.positions.empty());
    EXPECT_TRUE(m.triangles.empty());
  }
}

struct BadCase {
  const char* text;
  ErrorCode code;
  uint64_t line;
  const char* message_part;
};

TEST(Obj, ErrorsNameTheLine) {
  const std::string tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";  // lines 1-3
  const BadCase cases[] = {
      {"f 1 2 0\n", ErrorCode::kBadIndex, 4, "index 0 is not valid"},
      {"f 1 2 4\n", ErrorCode::kBadIndex, 4, "vertex index 4 refers to an undefined vertex (3 defined so far)"},
      {"f -4 1 2\n", ErrorCode::kBadIndex, 4, "vertex index -4"},
      {"f 1 2 99999999999999999999\n", ErrorCode::kBadIndex, 4, "out of range"},
      {"\nv nan 0 0\n", ErrorCode::kBadValue, 5, "position is not finite"},
      {"v 0 inf 0\n", ErrorCode::kBadValue, 4, "position is not finite"},
      {"v 0 0 1e39\n", ErrorCode::kBadValue, 4, "out of range for float"},
      {"f 1 2\n", ErrorCode::kBadValue, 4, "face has 2 corners; a face needs at least 3"},
      {"f\n", ErrorCode::kBadValue, 4, "face has 0 corners"},
      {"v 1 2 x\n", ErrorCode::kBadValue, 4, "malformed number 'x'"},
      {"v 1 2 3.0.0\n", ErrorCode::kBadValue, 4, "malformed number"},
      {"v 1 2 +-3\n", ErrorCode::kBadValue, 4, "malformed number"},
      {"v 1 2\n", ErrorCode::kBadValue, 4, "vertex has 2 coordinates"},
      {"v 1 2 3 4 5\n", ErrorCode::kBadValue, 4, "vertex has 5 coordinates"},
      {"f 1 2 3x\n", ErrorCode::kBadValue, 4, "malformed vertex index '3x'"},
      {"f 1 2 /1\n", ErrorCode::kBadValue, 4, "has no vertex index"},
      {"f 1 2 3/1/1/1\n", ErrorCode::kBadValue, 4, "malformed face corner"},
      {"vt 0 0\nf 1 2 3/2\n", ErrorCode::kBadIndex, 5,
       "texture coordinate index 2 refers to an undefined texture coordinate (1 defined so far)"},
      {"f 1 2 3/0\n", ErrorCode::kBadIndex, 4, "index 0"},
      {"f 1 2 3//x\n", ErrorCode::kBadValue, 4, "malformed normal index 'x'"},
      {"vn 0 0 1\nf 1 2 3//2\n", ErrorCode::kBadIndex, 5, "normal index 2"},
      {"vn 0 0\nf 1 2 3\n", ErrorCode::kBadValue, 4, "normal has 2 values"},
      {"vt 0 x\nf 1 2 3\n", ErrorCode::kBadValue, 4, "malformed number 'x' in texture coordinate"},
      {"# c\n\nf 1 2 \\\n 3 0\n", ErrorCode::kBadIndex, 6, "index 0"},
  };
  for (const BadCase& c : cases) {
    Mesh m;
    Status s = read_obj(tri + c.text, &m);
    EXPECT_EQ(s.code(), c.code) << c.text << " -> " << s.to_string();
    EXPECT_EQ(s.line(), c.line) << c.text << " -> " << s.to_string();
    EXPECT_NE(s.message().find(c.message_part), std::string::npos) << c.text << " -> " << s.to_string();
    EXPECT_EQ(s.message().find('\n'), std::string::npos);
  }
  // Colour consistency is decided by the first vertex.
  Mesh m;
  Status s = read_obj("v 0 0 0 1 1 1\nv 1 0 0\n", &m);
  EXPECT_EQ(s.code(), ErrorCode::kBadValue);
  EXPECT_EQ(s.line(), 2u);
  EXPECT_EQ(s.message(), "vertex has 3 coordinates but earlier vertices have colours");
}

TEST(Obj, OverlongLineIsALimitError) {
  Mesh m;
  Status s = read_obj("v 0 0 0\n# " + std::string(InputStream::kMaxLine + 10, 'x') + "\nv 1 1 1\n", &m);
  EXPECT_EQ(s.code(), ErrorCode::kLimit) << s.to_string();
  EXPECT_EQ(s.line(), 2u);
}

TEST(Obj, ErrorsAreSticky) {
  const std::string text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 5\nf 1 2 3\n";
  InputStream in;
  in.open_memory(text.data(), text.size());
  ObjReader reader;
  ASSERT_TRUE(reader.open(&in).ok());
  MeshItem item;
  Status s;
  int items = 0;
  while ((s = reader.next(&item)).ok() && item.kind != MeshItem::Kind::kEnd) ++items;
  EXPECT_EQ(items, 3);
  EXPECT_EQ(s.code(), ErrorCode::kBadIndex);
  Status again = reader.next(&item);
  EXPECT_EQ(again.code(), s.code());
  EXPECT_EQ(again.message(), s.message());
  EXPECT_EQ(again.line(), 4u);
}

TEST(Obj, InMemoryErrorsComeFromOpen) {
  const std::string text = "v 0 0 0\nvn 0 0 1\nf 1//1 1//1 2//1\n";
  InputStream in;
  in.open_memory(text.data(), text.size());
  ObjReader reader;
  Status s = reader.open(&in);
  EXPECT_EQ(s.code(), ErrorCode::kBadIndex);
  EXPECT_EQ(s.line(), 3u);
  MeshItem item;
  EXPECT_EQ(reader.next(&item).code(), ErrorCode::kBadIndex);
}

TEST(Obj, RepeatedIndicesAreDegenerateNotErrors) {
  Mesh m;
  ASSERT_TRUE(read_obj("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 1 3\n", &m).ok());
  EXPECT_EQ(m.triangles, (std::vector<Tri>{{0, 0, 2}}));
}

Status write_obj(const Mesh& mesh, const std::string& path, std::vector<std::string>* dropped = nullptr) {
  OutputFile out;
  PSQ_RETURN_IF_ERROR(out.open(path, true));
  test::MemorySource source(mesh);
  ObjWriter writer(&out);
  PSQ_RETURN_IF_ERROR(pump(source, writer));
  if (dropped != nullptr) *dropped = writer.dropped();
  return out.commit();
}

TEST(Obj, WriterRoundTripIsBitExact) {
  TempDir dir;
  Mesh sphere = test::make_sphere(8, 12);
  ASSERT_TRUE(write_obj(sphere, dir.file("s.obj")).ok());
  std::string text = test::read_file(dir.file("s.obj"));
  EXPECT_EQ(text.rfind("# psq\nv ", 0), 0u);
  Mesh back;
  ASSERT_TRUE(read_obj_file(dir.file("s.obj"), &back).ok());
  EXPECT_EQ(back.schema.vertex_count, static_cast<int64_t>(sphere.positions.size()));
  EXPECT_EQ(back.schema.triangle_count, static_cast<int64_t>(sphere.triangles.size()));
  ASSERT_EQ(back.positions.size(), sphere.positions.size());
  for (size_t i = 0; i < sphere.positions.size(); ++i) {
    for (int k = 0; k < 3; ++k) {
      EXPECT_EQ(std::memcmp(&back.positions[i][k], &sphere.positions[i][k], sizeof(double)), 0) << i;
    }
  }
  EXPECT_EQ(back.triangles, sphere.triangles);
  // Read again, the comment the writer added is not repeated.
  ASSERT_TRUE(write_obj(back, dir.file("t.obj")).ok());
  EXPECT_EQ(test::read_file(dir.file("t.obj")), text);
}

TEST(Obj, WriterRoundTripWithNormalsAndTexcoords) {
  TempDir dir;
  Mesh mesh = test::make_sphere(6, 8);
  for (const char* name : {"nx", "ny", "nz", "u", "v"}) {
    Property p;
    p.name = name;
    mesh.schema.vertex_properties.push_back(p);
  }
  for (size_t i = 0; i < mesh.positions.size(); ++i) {
    const auto& p = mesh.positions[i];
    mesh.vertex_values[i] = {p[0], p[1], p[2], static_cast<float>(i / 100.0), 0.5};
  }
  ASSERT_TRUE(write_obj(mesh, dir.file("n.obj")).ok());
  std::string text = test::read_file(dir.file("n.obj"));
  EXPECT_NE(text.find("\nvn "), std::string::npos);
  EXPECT_NE(text.find("\nvt "), std::string::npos);
  EXPECT_NE(text.find("\nf 1/1/1 2/2/2 3/3/3\n"), std::string::npos);
  Mesh back;
  SourceReport report;
  ASSERT_TRUE(read_obj_file(dir.file("n.obj"), &back, &report).ok());
  EXPECT_EQ(property_names(back.schema.vertex_properties), (std::vector<std::string>{"nx", "ny", "nz", "u", "v"}));
  EXPECT_EQ(back.positions, mesh.positions);
  EXPECT_EQ(back.triangles, mesh.triangles);
  EXPECT_EQ(back.vertex_values, mesh.vertex_values);
  EXPECT_TRUE(report.notes.empty());

  // Normals only: f a//a.
  mesh.schema.vertex_properties.resize(3);
  for (auto& v : mesh.vertex_values) v.resize(3);
  ASSERT_TRUE(write_obj(mesh, dir.file("n2.obj")).ok());
  EXPECT_NE(test::read_file(dir.file("n2.obj")).find("\nf 1//1 2//2 3//3\n"), std::string::npos);
  ASSERT_TRUE(read_obj_file(dir.file("n2.obj"), &back).ok());
  EXPECT_EQ(back.vertex_values, mesh.vertex_values);
  EXPECT_EQ(back.triangles, mesh.triangles);
}

TEST(Obj, WriterColoursListsAndDropped) {
  TempDir dir;
  Mesh mesh;
  auto prop = [](const char* name, ScalarType t, bool list = false) {
    Property p;
    p.name = name;
    p.type = t;
    p.is_list = list;
    return p;
  };
  mesh.schema.vertex_properties = {prop("confidence", ScalarType::kFloat32), prop("tags", ScalarType::kInt32, true),
                                   prop("red", ScalarType::kUInt8), prop("green", ScalarType::kUInt8),
                                   prop("blue", ScalarType::kUInt8), prop("nx", ScalarType::kInt8),
                                   prop("ny", ScalarType::kInt8), prop("nz", ScalarType::kInt8)};
  mesh.schema.face_properties = {prop("flags", ScalarType::kUInt8)};
  mesh.schema.comments = {"made by a test"};
  mesh.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  mesh.vertex_values = {{0.5, 2, 7, 8, 255, 0, 51, 1, 0, 0},
                        {0.5, 0, 0, 255, 0, 1, 0, 0},
                        {0.5, 1, 9, 0, 0, 255, 0, 0, 1}};
  mesh.triangles = {{0, 1, 2}};
  mesh.face_values = {{3}};
  std::vector<std::string> dropped;
  ASSERT_TRUE(write_obj(mesh, dir.file("c.obj"), &dropped).ok());
  EXPECT_EQ(dropped, (std::vector<std::string>{"confidence", "tags", "nx", "ny", "nz", "flags"}));
  EXPECT_EQ(test::read_file(dir.file("c.obj")),
            "# psq\n# made by a test\nv 0 0 0 1 0 0.2\nv 1 0 0 0 1 0\nv 0 1 0 0 0 1\nf 1 2 3\n");
  Mesh back;
  ASSERT_TRUE(read_obj_file(dir.file("c.obj"), &back).ok());
  EXPECT_EQ(back.vertex_values[0], (PropertyValues{1, 0, static_cast<float>(0.2)}));
  EXPECT_EQ(back.schema.comments, (std::vector<std::string>{"psq", "made by a test"}));

  // Double positions keep every bit.
  Mesh d = test::make_grid(2);
  d.schema.position_type = ScalarType::kFloat64;
  d.positions[1][0] = 0.123456789012345;
  ASSERT_TRUE(write_obj(d, dir.file("d.obj")).ok());
  EXPECT_NE(test::read_file(dir.file("d.obj")).find("\nv 0.123456789012345 0 0\n"), std::string::npos);
}

TEST(Obj, WriterRoundTripOfCornerAttributes) {
  TempDir dir;
  Mesh cube;
  ASSERT_TRUE(read_obj(kFlatCube, &cube).ok());
  std::vector<std::string> dropped;
  ASSERT_TRUE(write_obj(cube, dir.file("c.obj"), &dropped).ok());
  EXPECT_TRUE(dropped.empty());
  std::string text = test::read_file(dir.file("c.obj"));
  // A flat face's corners share one vn line; each triangle has its own vt.
  EXPECT_NE(text.find("\nvn 0 0 -1\nvt 1 1\nvt 1 0\nvt 0 0\nf 1/1/1 3/2/1 7/3/1\n"
                      "vt 1 1\nvt 0 0\nvt 0 1\nf 1/4/1 7/5/1 5/6/1\n"),
            std::string::npos)
      << text;
  Mesh back;
  SourceReport report;
  ASSERT_TRUE(read_obj_file(dir.file("c.obj"), &back, &report).ok());
  EXPECT_EQ(back.schema.vertex_count, 8);
  EXPECT_EQ(back.schema.vertex_properties, cube.schema.vertex_properties);
  EXPECT_EQ(back.schema.face_properties, cube.schema.face_properties);
  EXPECT_EQ(back.positions, cube.positions);
  EXPECT_EQ(back.triangles, cube.triangles);
  EXPECT_EQ(back.face_values, cube.face_values);
  EXPECT_EQ(report.notes.size(), 2u);

  // Normals only, in double: f a//n.
  cube.schema.face_properties.resize(1);
  cube.schema.face_properties[0].type = ScalarType::kFloat64;
  for (PropertyValues& v : cube.face_values) v.resize(10);
  cube.face_values[0][1] = 0.1;
  ASSERT_TRUE(write_obj(cube, dir.file("n.obj")).ok());
  text = test::read_file(dir.file("n.obj"));
  EXPECT_NE(text.find("\nvn 0.1 0 -1\nvn 0 0 -1\nf 1//1 3//2 7//2\nf 1//2 7//2 5//2\n"), std::string::npos) << text;
  ASSERT_TRUE(read_obj_file(dir.file("n.obj"), &back).ok());
  EXPECT_EQ(property_names(back.schema.face_properties), (std::vector<std::string>{"corner_normals"}));
  EXPECT_EQ(back.triangles, cube.triangles);
  EXPECT_EQ(back.face_values[0][1], static_cast<double>(0.1f));
  EXPECT_EQ(back.face_values[5], cube.face_values[5]);
}

TEST(Obj, WriterCornerAttributeErrorsAndPrecedence) {
  TempDir dir;
  Mesh mesh = test::make_grid(1);
  auto prop = [](const char* name, ScalarType t, bool list = false) {
    Property p;
    p.name = name;
    p.type = t;
    p.is_list = list;
    return p;
  };
  mesh.schema.face_properties = {prop("flags", ScalarType::kUInt8), prop("corner_normals", ScalarType::kFloat32, true)};
  mesh.face_values.assign(mesh.triangles.size(), PropertyValues{1, 9, 0, 0, 1, 0, 0, 1, 0, 0, 1});
  std::vector<std::string> dropped;
  ASSERT_TRUE(write_obj(mesh, dir.file("a.obj"), &dropped).ok());
  EXPECT_EQ(dropped, (std::vector<std::string>{"flags"}));
  EXPECT_NE(test::read_file(dir.file("a.obj")).find("\nvn 0 0 1\nf 1//1 2//1 "), std::string::npos);

  // A triangle whose list has the wrong length.
  mesh.face_values.back() = {1, 3, 0, 0, 1};
  Status s = write_obj(mesh, dir.file("b.obj"));
  EXPECT_EQ(s.code(), ErrorCode::kInternal) << s.to_string();

  // Per-vertex normals win; corner_normals is then dropped.
  for (const char* name : {"nx", "ny", "nz"}) mesh.schema.vertex_properties.push_back(prop(name, ScalarType::kFloat32));
  for (PropertyValues& v : mesh.vertex_values) v = {0, 0, 1};
  ASSERT_TRUE(write_obj(mesh, dir.file("c.obj"), &dropped).ok());
  EXPECT_EQ(dropped, (std::vector<std::string>{"flags", "corner_normals"}));
}

// A pipe cannot rewind: the reader spools it.
Status read_through_pipe(const std::string& text, const std::string& spool_dir, Mesh* mesh) {
  int fds[2];
  if (::pipe(fds) != 0) return Status(ErrorCode::kIo, "pipe failed");
  std::thread writer([&] {
    size_t done = 0;
    while (done < text.size()) {
      ssize_t w = ::write(fds[1], text.data() + done, text.size() - done);
      if (w <= 0) break;
      done += static_cast<size_t>(w);
    }
    ::close(fds[1]);
  });
  InputStream in;
  Status s = in.open_fd(fds[0], true, "pipe");
  if (s.ok() && in.can_rewind()) s = Status(ErrorCode::kInternal, "a pipe should not rewind");
  ObjReader reader;
  if (s.ok()) s = reader.open(&in, spool_dir);
  MemorySink sink;
  if (s.ok()) s = pump(reader, sink);
  writer.join();
  *mesh = std::move(sink.mesh);
  return s;
}

TEST(Obj, ReadsFromAPipe) {
  TempDir dir;
  Mesh m;
  ASSERT_TRUE(read_through_pipe("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 1\nf 1 2 3 4\n", dir.path(), &m).ok());
  EXPECT_EQ(m.schema.vertex_count, 4);
  EXPECT_EQ(m.triangles, (std::vector<Tri>{{0, 1, 2}, {0, 2, 3}}));
  EXPECT_TRUE(dir.entries().empty());  // the spool file is unlinked

  // Bigger than a pipe's buffer, interleaved, with normals.
  Mesh grid = test::make_grid(120);
  ASSERT_TRUE(write_obj(grid, dir.file("g.obj")).ok());
  std::string text = test::read_file(dir.file("g.obj"));
  ASSERT_GT(text.size(), size_t{1} << 17);
  ASSERT_TRUE(read_through_pipe(text, "", &m).ok());
  EXPECT_EQ(m.positions, grid.positions);
  EXPECT_EQ(m.triangles, grid.triangles);

  text += "vn 0 0 1\nf -1//1 -2//1 -3//1\n";
  ASSERT_TRUE(read_through_pipe(text, "", &m).ok());
  EXPECT_EQ(m.positions, grid.positions);
  EXPECT_EQ(m.triangles.size(), grid.triangles.size() + 1);
  EXPECT_EQ(m.vertex_values.back(), (PropertyValues{0, 0, 1}));
}

TEST(Obj, SharedFandisk) {
  const std::string path = kShared + "/inputs/fandisk.obj";
  if (!test::file_exists(path)) GTEST_SKIP() << "shared data not present";
  Mesh m;
  SourceReport report;
  ASSERT_TRUE(read_obj_file(path, &m, &report).ok());
  EXPECT_EQ(m.positions.size(), 6475u);
  EXPECT_EQ(m.triangles.size(), 12946u);
  EXPECT_EQ(m.schema.vertex_count, 6475);
  EXPECT_EQ(m.schema.triangle_count, 12946);
  // Its faces are written f a//a without vn lines.
  EXPECT_EQ(report.notes, (std::vector<std::string>{"38838 normal indices ignored: the file has no vn lines"}));
}

TEST(Obj, SharedCubeQuads) {
  const std::string path = kShared + "/inputs/cube_quads.obj";
  if (!test::file_exists(path)) GTEST_SKIP() << "shared data not present";
  Mesh m;
  SourceReport report;
  ASSERT_TRUE(read_obj_file(path, &m, &report).ok());
  // 8 corners, each on 3 faces with 3 normals: still 8 vertices.
  EXPECT_EQ(m.positions.size(), 8u);
  EXPECT_EQ(m.triangles.size(), 12u);
  EXPECT_EQ(report.polygons_triangulated, 6u);
  EXPECT_EQ(property_names(m.schema.face_properties), (std::vector<std::string>{"corner_normals", "corner_uv"}));
  EXPECT_EQ(report.notes,
            (std::vector<std::string>{"normals vary per corner at 8 vertices: kept as per-corner face property corner_normals",
                                      "texture coordinates vary per corner at 8 vertices: kept as per-corner face property corner_uv"}));
}

TEST(Obj, SharedBadFiles) {
  const std::string bad = kShared + "/bad/";
  if (!test::file_exists(bad + "assimp_malformed.obj")) GTEST_SKIP() << "shared data not present";
  Mesh m;
  Status s = read_obj_file(bad + "assimp_malformed.obj", &m);
  EXPECT_EQ(s.code(), ErrorCode::kBadIndex) << s.to_string();
  EXPECT_NE(s.line(), Status::kNoPlace);
  s = read_obj_file(bad + "assimp_malformed2.obj", &m);
  EXPECT_EQ(s.code(), ErrorCode::kBadValue) << s.to_string();
  EXPECT_NE(s.line(), Status::kNoPlace);
  s = read_obj_file(bad + "draco_inf_nan.obj", &m);
  EXPECT_EQ(s.code(), ErrorCode::kBadValue) << s.to_string();
  EXPECT_EQ(s.line(), 1u);
  s = read_obj_file(bad + "fandisk.bad_index_range.obj", &m);
  EXPECT_EQ(s.code(), ErrorCode::kBadIndex) << s.to_string();
  ASSERT_TRUE(read_obj_file(bad + "draco_deg_faces.obj", &m).ok());
  EXPECT_EQ(m.triangles.size(), 4u);
  ASSERT_TRUE(read_obj_file(bad + "assimp_empty.obj", &m).ok());
  EXPECT_TRUE(m.positions.empty());
}

}  // namespace
}  // namespace psq
