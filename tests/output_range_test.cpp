// SPDX-License-Identifier: Apache-2.0
// Values that an output cannot hold at the precision asked for are refused
// with the vertex named, never written as something else: doubles beyond
// float range in OBJ, Draco and decode_mesh()'s float arrays, and double
// positions that Draco's float quantization would move by more than half a
// step. (The PLY writer's and the .psq encoder's are in ply_test and
// codec_test.)
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "psq/draco.h"
#include "psq/obj.h"
#include "psq/psq_codec.h"
#include "psq/psq_memory.h"
#include "psq/sequence_builder.h"
#include "test_util.h"

namespace psq {
namespace {

using test::Mesh;

// One triangle with double positions.
Mesh double_triangle(std::array<double, 3> a, std::array<double, 3> b, std::array<double, 3> c) {
  Mesh m = test::make_mesh({a, b, c}, {{0, 1, 2}});
  m.schema.position_type = ScalarType::kFloat64;
  return m;
}

Status write_obj(const Mesh& mesh, std::string* text) {
  test::TempDir dir;
  OutputFile out;
  PSQ_RETURN_IF_ERROR(out.open(dir.file("m.obj"), false));
  ObjWriter writer(&out);
  test::MemorySource source(mesh);
  PSQ_RETURN_IF_ERROR(pump(source, writer));
  PSQ_RETURN_IF_ERROR(out.commit());
  *text = test::read_file(dir.file("m.obj"));
  return Status();
}

Status write_draco(const Mesh& mesh, const DracoWriteOptions& options) {
  test::TempDir dir;
  OutputFile out;
  PSQ_RETURN_IF_ERROR(out.open(dir.file("m.drc"), false));
  DracoWriter writer(&out, options);
  test::MemorySource source(mesh);
  PSQ_RETURN_IF_ERROR(pump(source, writer));
  return out.commit();
}

TEST(OutputRange, ObjFloatValuesBeyondFloatRangeAreRefused) {
  // A float position type with a value no float holds (a source that
  // breaks its schema's promise): refused, not written as "inf".
  Mesh m = double_triangle({0, 0, 0}, {1e39, 0, 0}, {0, 1, 0});
  m.schema.position_type = ScalarType::kFloat32;
  std::string text;
  Status s = write_obj(m, &text);
  EXPECT_EQ(s.code(), ErrorCode::kBadValue) << s.to_string();
  EXPECT_NE(s.message().find("vertex 1: 1e+39 is beyond float range"), std::string::npos) << s.to_string();
  // A float normal.
  m = test::make_grid(1);
  for (const char* n : {"nx", "ny", "nz"}) m.schema.vertex_properties.push_back({n, ScalarType::kFloat32});
  for (auto& v : m.vertex_values) v = {0, 0, 1};
  m.vertex_values[2] = {0, -4e38, 1};
  s = write_obj(m, &text);
  EXPECT_EQ(s.code(), ErrorCode::kBadValue) << s.to_string();
  EXPECT_NE(s.message().find("vertex 2"), std::string::npos) << s.to_string();
  // Doubles are written as doubles; infinities and NaN normals as they are.
  m = double_triangle({0, 0, 0}, {1e300, 0, 0}, {0, 1, 0});
  s = write_obj(m, &text);
  ASSERT_TRUE(s.ok()) << s.to_string();
  EXPECT_NE(text.find("v 1e+300 0 0"), std::string::npos) << text;
}

TEST(OutputRange, DracoRefusesPositionsItsFloatsCannotHold) {
  DracoWriteOptions lossy, lossless;
  lossless.lossless = true;
  struct Case {
    const char* name;
    Mesh mesh;
    bool lossy_ok, lossless_ok;
    const char* says;  // in the lossy error
  } cases[] = {
      // Beyond float range: the float would be an infinity.
      {"1e300", double_triangle({1e300, 0, 0}, {1e300, 1, 0}, {1e300, 0, 1}), false, true, "beyond float range"},
      {"9e307", double_triangle({9e307, 0, 0}, {-9e307, 0, 0}, {0, 9e307, 0}), false, true, "beyond float range"},
      // Floats, but their range overflows Draco's float arithmetic (once
      // made libdraco crash).
      {"3e38", double_triangle({3e38, 0, 0}, {-3e38, 1, 0}, {0, 0, 1}), false, true, "range overflows"},
      // Coordinates far from the origin: as floats they move by up to 0.25,
      // far more than the 16-bit step of a box of side 1.
      {"utm", double_triangle({4000000.123, 500000.5, 10}, {4000001.123, 500000.5, 10}, {4000000.123, 500001.5, 10}),
       false, true, "more than half a quantization step"},
      // Doubles that are floats, or close to them: written.
      {"near floats", double_triangle({0.1, 0.2, 0.3}, {1.1, 0.2, 0.3}, {0.1, 1.2, 0.3}), true, true, ""},
  };
  for (const Case& c : cases) {
    Status s = write_draco(c.mesh, lossy);
    EXPECT_EQ(s.ok(), c.lossy_ok) << c.name << ": " << s.to_string();
    if (!c.lossy_ok) {
      EXPECT_NE(s.message().find(c.says), std::string::npos) << c.name << ": " << s.to_string();
      EXPECT_EQ(s.message().find('\n'), std::string::npos) << c.name;
    }
    s = write_draco(c.mesh, lossless);
    EXPECT_EQ(s.ok(), c.lossless_ok) << c.name << ": " << s.to_string();
  }
  // With float positions, lossless Draco stores floats: beyond their range
  // is refused too.
  Mesh m = double_triangle({1e39, 0, 0}, {0, 1, 0}, {0, 0, 1});
  m.schema.position_type = ScalarType::kFloat32;
  Status s = write_draco(m, lossless);
  EXPECT_EQ(s.code(), ErrorCode::kBadValue) << s.to_string();
  EXPECT_NE(s.message().find("vertex 0: x = 1e+39"), std::string::npos) << s.to_string();
}

// A double .psq whose positions are beyond float range: decode_mesh(),
// which returns floats, refuses it; PsqDecoder reads it.
TEST(OutputRange, DecodeMeshRefusesDoublesBeyondFloatRange) {
  for (bool fast : {false, true}) {
    for (bool lossless : {false, true}) {
      test::MemorySource source(double_triangle({1e300, 0, 0}, {-1e300, 1, 0}, {0, 0, 1e300}));
      std::vector<uint8_t> bytes;
      VectorWriter w(&bytes);
      EncodeOptions o;
      o.fast = fast;
      o.lossless = lossless;
      PsqEncoder enc(&w, o);
      BuildReport report;
      Status s = build_sequence(source, enc, BuildOptions(), &report);
      ASSERT_TRUE(s.ok()) << s.to_string();
      MeshBuffers mesh;
      s = decode_mesh(bytes.data(), bytes.size(), &mesh);
      EXPECT_EQ(s.code(), ErrorCode::kLimit) << s.to_string();
      EXPECT_NE(s.message().find("beyond float range"), std::string::npos) << s.to_string();
      EXPECT_TRUE(mesh.positions.empty());
    }
  }
}

}  // namespace
}  // namespace psq
