// SPDX-License-Identifier: Apache-2.0
// Tests of corner attributes (spec/psq-format.md 8.5): normals and texture
// coordinates that differ between the corners at one vertex round trip
// within their stated error with both back-ends, in chunks and segments; a
// corner that repeats its vertex's value costs little, and a normal waits
// for its fan; values the coder cannot hold are refused.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <string>
#include <vector>

#include "psq/mesh_arrays.h"
#include "psq/psq_codec.h"
#include "psq/psq_memory.h"
#include "psq/sequence_builder.h"
#include "test_util.h"

namespace psq {
namespace {

using test::Mesh;
using Events = test::EventLog;

double as_float(double v) {
  volatile float f = static_cast<float>(v);
  return f;
}

Property list_prop(const char* name) {
  Property p;
  p.name = name;
  p.type = ScalarType::kFloat32;
  p.is_list = true;
  p.count_type = ScalarType::kUInt8;
  return p;
}

// A torus whose corners carry what an artist's OBJ gives: corner_uv, the
// texture coordinates, u running around the torus with a seam where it
// closes (u 1 on one side, 0 on the other) and, when `islands`, each
// quarter of the torus in a chart of its own; corner_normals, smooth
// (each vertex's area-weighted normal) or, when `flat`, each triangle's
// own (a crease at every edge); then a uint8 "material" column.
Mesh corner_torus(bool flat, bool islands, int seg = 48, int ring = 24) {
  Mesh m = test::make_torus(seg, ring);
  for (auto& p : m.positions)
    for (double& c : p) c = as_float(c);
  m.schema.face_properties = {list_prop("corner_normals"), list_prop("corner_uv"), {"material", ScalarType::kUInt8}};
  std::vector<std::array<double, 3>> vn(m.positions.size(), {0, 0, 0});
  std::vector<std::array<double, 3>> fn;
  for (const auto& t : m.triangles) {
    const auto &a = m.positions[t[0]], &b = m.positions[t[1]], &c = m.positions[t[2]];
    const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, w[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    fn.push_back({u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]});
    for (uint32_t i : t)
      for (int k = 0; k < 3; ++k) vn[i][k] += fn.back()[k];
  }
  m.face_values.assign(m.triangles.size(), PropertyValues());
  for (size_t f = 0; f < m.triangles.size(); ++f) {
    const auto& t = m.triangles[f];
    PropertyValues& v = m.face_values[f];
    v.push_back(9);
    for (uint32_t i : t) {
      const auto& n = flat ? fn[f] : vn[i];
      const double l = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
      for (int k = 0; k < 3; ++k) v.push_back(as_float(n[k] / l));
    }
    // The angle around the axis of the triangle's centre decides the side
    // of the seam (and the chart) for all three corners.
    double cx = 0, cy = 0;
    for (uint32_t i : t) {
      cx += m.positions[i][0];
      cy += m.positions[i][1];
    }
    const double centre = std::atan2(cy, cx);
    v.push_back(6);
    for (uint32_t i : t) {
      const auto& p = m.positions[i];
      double a = std::atan2(p[1], p[0]);
      if (a - centre > M_PI) a -= 2 * M_PI;
      if (centre - a > M_PI) a += 2 * M_PI;
      double u = a / (2 * M_PI) + 0.5, w = 0.5 + 0.4 * p[2];
      if (islands) {
        const int chart = static_cast<int>(std::floor((centre / (2 * M_PI) + 0.5) * 4)) & 3;
        u = 0.25 * chart + 0.9 * (u - 0.25 * chart);
        w = w * 0.5 + 0.5 * (chart & 1);
      }
      v.push_back(as_float(u));
      v.push_back(as_float(w));
    }
    v.push_back(static_cast<double>(f % 3));
  }
  return m;
}

using test::attribute_options;
using test::build_events;
using test::decode_sequence;
using test::encode_sequence;

// The rotation r that takes triangle a's corner k to b's corner (k + r) % 3,
// else -1.
int rotation_of(const SequenceTriangle& a, const SequenceTriangle& b) {
  for (int r = 0; r < 3; ++r)
    if (a.v[0] == b.v[r] && a.v[1] == b.v[(r + 1) % 3] && a.v[2] == b.v[(r + 2) % 3]) return r;
  return -1;
}

// The decoded triangles against the encoded ones: corner normals within
// the angle of `normal_bits` octahedral, texture coordinates within half a
// step of 2^-uv_bits, the material exact; the vertices exact but for the
// positions' quantization (checked elsewhere).
void expect_within(const Events& in, const Events& out, int normal_bits, int uv_bits) {
  ASSERT_EQ(in.events.size(), out.events.size());
  ASSERT_EQ(in.schema.face_properties, out.schema.face_properties);
  const int c = (1 << (normal_bits - 1)) - 1;
  const double angle = 1.5 / c + 1e-6;
  size_t triangles = 0;
  for (size_t i = 0; i < in.events.size(); ++i) {
    ASSERT_EQ(in.events[i].kind, out.events[i].kind) << "event " << i;
    if (in.events[i].kind != SequenceEvent::Kind::kTriangle) continue;
    ++triangles;
    const PropertyValues& a = in.events[i].triangle.values;
    const PropertyValues& b = out.events[i].triangle.values;
    ASSERT_EQ(a.size(), b.size()) << "event " << i;
    ASSERT_EQ(a[0], b[0]);
    // Without other face properties the stream keeps only the cyclic
    // order (spec 4.2): corner k of the input is corner (k + r) % 3.
    const int r = rotation_of(in.events[i].triangle, out.events[i].triangle);
    ASSERT_GE(r, 0) << "event " << i;
    for (int k = 0; k < 3; ++k) {
      const double* n = &a[1 + 3 * k];
      const double* m = &b[1 + 3 * ((k + r) % 3)];
      const double lm = std::sqrt(m[0] * m[0] + m[1] * m[1] + m[2] * m[2]);
      EXPECT_NEAR(lm, 1.0, 1e-6) << "event " << i;
      const double dot = (n[0] * m[0] + n[1] * m[1] + n[2] * m[2]) / lm;
      EXPECT_LE(std::acos(std::min(1.0, dot)), angle) << "corner " << k << " normal of event " << i;
    }
    ASSERT_EQ(a[10], b[10]);
    for (int k = 0; k < 3; ++k)
      for (int d = 0; d < 2; ++d)
        EXPECT_LE(std::fabs(a[11 + 2 * k + d] - b[11 + 2 * ((k + r) % 3) + d]), std::ldexp(0.5, -uv_bits) * (1 + 1e-9))
            << "texture coordinate " << k << " of event " << i;
    EXPECT_EQ(a[17], b[17]) << "material of event " << i;
  }
  EXPECT_GT(triangles, 0u);
}

TEST(Corners, RoundTripWithinTheirError) {
  for (bool flat : {false, true})
    for (bool islands : {false, true}) {
      const Events ev = build_events(corner_torus(flat, islands));
      for (bool fast : {false, true})
        for (uint64_t segment : {uint64_t{0}, uint64_t{500}}) {
          EncodeOptions o = attribute_options(fast, 10, 12);
          o.segment_triangles = segment;
          o.chunk_bytes = 2048;  // chunks end while corner normals wait
          std::vector<uint8_t> bytes;
          const Status st = encode_sequence(ev, o, &bytes);
          ASSERT_TRUE(st.ok()) << st.to_string();
          PsqHeader h;
          Events back;
          const Status ds = decode_sequence(bytes, &back, &h);
          ASSERT_TRUE(ds.ok()) << "flat " << flat << " islands " << islands << " fast " << fast << " segments of "
                               << segment << ": " << ds.to_string();
          ASSERT_EQ(h.attributes.size(), 2u);
          EXPECT_EQ(h.attributes[0].kind, CodedAttribute::Kind::kCornerNormal);
          EXPECT_EQ(h.attributes[1].kind, CodedAttribute::Kind::kCornerTexcoord);
          expect_within(ev, back, 10, 12);
          MeshBuffers one, two;
          ASSERT_TRUE(decode_mesh(bytes.data(), bytes.size(), &one, 1).ok());
          ASSERT_TRUE(decode_mesh(bytes.data(), bytes.size(), &two, 2).ok());
          EXPECT_EQ(one.indices, two.indices);
          size_t triangles = 0;
          for (const SequenceEvent& e : back.events) triangles += e.kind == SequenceEvent::Kind::kTriangle;
          EXPECT_EQ(one.indices.size(), 3 * triangles);
        }
    }
}

// Corner normals beside vertex attributes (8.3): texture coordinates and
// colours per vertex, normals per corner (flat), with and without the
// rotation (a material column keeps it).
TEST(Corners, BesideVertexAttributes) {
  for (bool material : {false, true}) {
    Mesh m = corner_torus(true, false, 24, 12);
    for (PropertyValues& v : m.face_values) {
      const double mat = v[17];
      v.resize(10);
      if (material) v.push_back(mat);
    }
    m.schema.face_properties.erase(m.schema.face_properties.begin() + 1, m.schema.face_properties.end());
    if (material) m.schema.face_properties.push_back({"material", ScalarType::kUInt8});
    for (const char* n : {"u", "v"}) m.schema.vertex_properties.push_back({n, ScalarType::kFloat64});
    for (const char* n : {"red", "green", "blue"}) m.schema.vertex_properties.push_back({n, ScalarType::kUInt8});
    m.vertex_values.assign(m.positions.size(), PropertyValues());
    for (size_t i = 0; i < m.positions.size(); ++i)
      m.vertex_values[i] = {0.25 + 0.001 * static_cast<double>(i), 0.5, static_cast<double>(i % 256), 7, 200};
    const Events ev = build_events(m);
    for (bool fast : {false, true}) {
      std::vector<uint8_t> bytes;
      ASSERT_TRUE(encode_sequence(ev, attribute_options(fast, 10, 12), &bytes).ok());
      PsqHeader h;
      Events back;
      const Status ds = decode_sequence(bytes, &back, &h);
      ASSERT_TRUE(ds.ok()) << "material " << material << " fast " << fast << ": " << ds.to_string();
      ASSERT_EQ(h.attributes.size(), 3u);
      EXPECT_EQ(h.rotation, material);
      ASSERT_EQ(back.events.size(), ev.events.size());
      const int c = (1 << 9) - 1;
      for (size_t i = 0; i < ev.events.size(); ++i) {
        const SequenceEvent& a = ev.events[i];
        const SequenceEvent& b = back.events[i];
        if (a.kind == SequenceEvent::Kind::kVertex) {
          ASSERT_EQ(b.vertex.values.size(), 5u) << "event " << i;
          EXPECT_LE(std::fabs(a.vertex.values[0] - b.vertex.values[0]), std::ldexp(0.5, -12)) << "event " << i;
          for (int k = 2; k < 5; ++k) EXPECT_EQ(a.vertex.values[k], b.vertex.values[k]) << "event " << i;
        } else if (a.kind == SequenceEvent::Kind::kTriangle) {
          ASSERT_EQ(b.triangle.values.size(), a.triangle.values.size()) << "event " << i;
          const int r = rotation_of(a.triangle, b.triangle);
          ASSERT_GE(r, 0);
          for (int k = 0; k < 3; ++k) {
            const double* n = &a.triangle.values[1 + 3 * k];
            const double* q = &b.triangle.values[1 + 3 * ((k + r) % 3)];
            EXPECT_LE(std::acos(std::min(1.0, n[0] * q[0] + n[1] * q[1] + n[2] * q[2])), 1.5 / c + 1e-6)
                << "event " << i;
          }
          if (material) {
            EXPECT_EQ(a.triangle.values[10], b.triangle.values[10]);
          }
        }
      }
    }
  }
}

// A corner that takes a value its vertex already has costs a symbol, not
// a value: texture coordinates the same at every corner of a vertex but
// on the seam cost about what the same coordinates do per vertex, and a
// mesh with the values per corner costs far less than one whose corners'
// values are all different.
TEST(Corners, RepeatedValuesCostASymbol) {
  const Events ev = build_events(corner_torus(false, false));
  Events split = ev;
  // Every corner a value of its own: each triangle's texture coordinates
  // moved by its index (the charts of a triangle soup).
  int f = 0;
  for (SequenceEvent& e : split.events) {
    if (e.kind != SequenceEvent::Kind::kTriangle) continue;
    for (int k = 0; k < 6; k += 2) e.triangle.values[11 + k] = as_float(e.triangle.values[11 + k] + (f % 7) * 0.001);
    ++f;
  }
  for (bool fast : {false, true}) {
    std::vector<uint8_t> welded, soup, none;
    EncodeOptions o = attribute_options(fast, 10, 12);
    ASSERT_TRUE(encode_sequence(ev, o, &welded).ok());
    ASSERT_TRUE(encode_sequence(split, o, &soup).ok());
    o.normal_bits = o.uv_bits = 0;  // as columns
    ASSERT_TRUE(encode_sequence(ev, o, &none).ok());
    EXPECT_LT(welded.size() * 3, none.size()) << "fast " << fast;
    EXPECT_LT(welded.size() * 5, soup.size() * 4) << "fast " << fast;
  }
}

// Spec 8.5: a corner normal waits for the triangles of its fan, as a
// vertex's normal waits for its ring (8.4): smooth normals cost about the
// same either way (predicted from the first triangle alone they cost half
// as much again). On a fan of 6000 triangles the normal at the centre
// settles by its bound, those at the rim when their vertices are
// finalized.
TEST(Corners, NormalsWaitForTheirFan) {
  const uint32_t n = 6000;
  Mesh m = test::make_wavy_fan(n);
  const auto& p = m.positions;
  const auto& t = m.triangles;
  m.schema.face_properties = {list_prop("corner_normals")};
  std::vector<std::array<double, 3>> vn(p.size(), {0, 0, 0});
  for (const auto& f : t) {
    const auto &a = p[f[0]], &b = p[f[1]], &c = p[f[2]];
    const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, w[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    const double x[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]};
    for (uint32_t i : f)
      for (int k = 0; k < 3; ++k) vn[i][k] += x[k];
  }
  m.face_values.clear();
  for (const auto& f : t) {
    PropertyValues v{9};
    for (uint32_t i : f) {
      const double l = std::sqrt(vn[i][0] * vn[i][0] + vn[i][1] * vn[i][1] + vn[i][2] * vn[i][2]);
      for (int k = 0; k < 3; ++k) v.push_back(as_float(vn[i][k] / l));
    }
    m.face_values.push_back(v);
  }
  {
    Mesh torus = corner_torus(false, false);
    for (PropertyValues& v : torus.face_values) v.resize(10);
    torus.schema.face_properties.resize(1);
    Mesh per_vertex = torus;
    per_vertex.schema.face_properties.clear();
    per_vertex.schema.vertex_properties = {{"nx", ScalarType::kFloat32}, {"ny", ScalarType::kFloat32},
                                           {"nz", ScalarType::kFloat32}};
    per_vertex.vertex_values.assign(torus.positions.size(), PropertyValues(3));
    for (size_t f = 0; f < torus.triangles.size(); ++f) {
      for (int k = 0; k < 3; ++k)
        for (int d = 0; d < 3; ++d)
          per_vertex.vertex_values[torus.triangles[f][k]][d] = torus.face_values[f][1 + 3 * k + d];
      per_vertex.face_values[f].clear();
    }
    for (bool fast : {false, true}) {
      std::vector<uint8_t> corners, vertices;
      ASSERT_TRUE(encode_sequence(build_events(torus), attribute_options(fast, 10, 0), &corners).ok());
      ASSERT_TRUE(encode_sequence(build_events(per_vertex), attribute_options(fast, 10, 0), &vertices).ok());
      EXPECT_LT(corners.size(), vertices.size() * 11 / 10 + 64) << "fast " << fast;
    }
  }
  const Events ev = build_events(m);
  Mesh bare = m;
  bare.schema.face_properties.clear();
  bare.face_values.assign(t.size(), PropertyValues());
  const Events positions = build_events(bare);
  for (bool fast : {false, true}) {
    EncodeOptions o = attribute_options(fast, 8, 0);
    o.bits = 20;  // the fans' triangles keep their shape
    o.chunk_bytes = 1 << 20;
    std::vector<uint8_t> bytes, alone;
    ASSERT_TRUE(encode_sequence(ev, o, &bytes).ok());
    ASSERT_TRUE(encode_sequence(positions, o, &alone).ok());
    // Under two bits a normal beyond the positions and connectivity.
    EXPECT_LT(bytes.size(), alone.size() + n / 4) << "fast " << fast;
    PsqDecoder dec;
    InputStream in;
    in.open_memory(bytes.data(), bytes.size(), "fan.psq");
    ASSERT_TRUE(dec.open(&in).ok());
    SequenceEvent e;
    size_t i = 0;
    for (;; ++i) {
      ASSERT_TRUE(dec.next(&e).ok());
      if (e.kind == SequenceEvent::Kind::kEnd) break;
      if (e.kind != SequenceEvent::Kind::kTriangle) continue;
      const PropertyValues& a = ev.events[i].triangle.values;
      const int r = rotation_of(ev.events[i].triangle, e.triangle);
      ASSERT_GE(r, 0) << "event " << i;
      for (int k = 0; k < 3; ++k)
        for (int d = 0; d < 3; ++d)
          EXPECT_NEAR(a[1 + 3 * k + d], e.triangle.values[1 + 3 * ((k + r) % 3) + d], 0.02) << "event " << i;
    }
  }
}

TEST(Corners, EncoderRefusesWhatItCannotHold) {
  Events ev = build_events(corner_torus(false, false, 12, 6));
  {
    Events bad = ev;
    for (SequenceEvent& e : bad.events)
      if (e.kind == SequenceEvent::Kind::kTriangle) {
        PropertyValues& v = e.triangle.values;
        v.erase(v.begin() + 10, v.begin() + 17);
        v.insert(v.begin() + 10, {4, 0.5, 0.25, 0.125, 0.75});  // two corners' texture coordinates
        break;
      }
    std::vector<uint8_t> bytes;
    const Status st = encode_sequence(bad, attribute_options(false, 10, 12), &bytes);
    EXPECT_EQ(st.code(), ErrorCode::kBadValue);
    EXPECT_NE(st.message().find("corner_uv holds 4 values, not 6"), std::string::npos) << st.message();
    // Kept as a column when not quantized.
    const Status kept = encode_sequence(bad, attribute_options(false, 10, 0), &bytes);
    EXPECT_TRUE(kept.ok()) << kept.to_string();
  }
  {
    Events bad = ev;
    for (SequenceEvent& e : bad.events)
      if (e.kind == SequenceEvent::Kind::kTriangle) {
        e.triangle.values[12] = 1e12;
        break;
      }
    std::vector<uint8_t> bytes;
    const Status st = encode_sequence(bad, attribute_options(true, 10, 12), &bytes);
    EXPECT_EQ(st.code(), ErrorCode::kBadValue);
    EXPECT_NE(st.message().find("beyond the grid"), std::string::npos) << st.message();
  }
  {
    Events bad = ev;
    for (SequenceEvent& e : bad.events)
      if (e.kind == SequenceEvent::Kind::kTriangle) {
        e.triangle.values[2] = std::nan("");
        break;
      }
    std::vector<uint8_t> bytes;
    const Status st = encode_sequence(bad, attribute_options(false, 10, 12), &bytes);
    EXPECT_EQ(st.code(), ErrorCode::kBadValue);
    EXPECT_NE(st.message().find("not finite"), std::string::npos) << st.message();
  }
}

}  // namespace
}  // namespace psq
