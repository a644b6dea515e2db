// SPDX-License-Identifier: Apache-2.0
// Tests of the coded vertex attributes (spec/psq-format.md 8.3): normals,
// texture coordinates and colours round trip in both profiles within their
// stated error (exactly when lossless), seams and far texture coordinates
// code correctly, the names are recognized, bad values are refused, and
// damaged attribute sections are refused.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <random>
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

Property prop(const char* name, ScalarType t) {
  Property p;
  p.name = name;
  p.type = t;
  return p;
}

double as_float(double v) {
  volatile float f = static_cast<float>(v);
  return f;
}

// A torus with float positions and, per vertex, the properties of `names`
// among: nx ny nz (its normal; zero at vertex 7 when `zero_normal`), a
// texture coordinate pair (`uv` names; u runs 0..1 around the torus with a
// seam where the torus closes, v offset by `uv_offset`), red green blue
// alpha (uint8), and a float "confidence" (a column).
// Area-weighted vertex normals, not yet of unit length.
std::vector<std::array<double, 3>> ring_normals(const Mesh& m) {
  std::vector<std::array<double, 3>> n(m.positions.size(), {0, 0, 0});
  for (const auto& t : m.triangles) {
    const auto &a = m.positions[t[0]], &b = m.positions[t[1]], &c = m.positions[t[2]];
    const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, w[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    const double f[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]};
    for (uint32_t i : t)
      for (int k = 0; k < 3; ++k) n[i][k] += f[k];
  }
  return n;
}

// `m` with float normals nx ny nz: vertex i's is the unit area-weighted
// normal of vertex (i + shift) % n.
void add_normals(Mesh* m, size_t shift = 0) {
  const std::vector<std::array<double, 3>> n = ring_normals(*m);
  for (const char* name : {"nx", "ny", "nz"}) m->schema.vertex_properties.push_back(prop(name, ScalarType::kFloat32));
  m->vertex_values.assign(m->positions.size(), PropertyValues());
  for (size_t i = 0; i < m->positions.size(); ++i) {
    const auto& v = n[(i + shift) % n.size()];
    const double l = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    for (int k = 0; k < 3; ++k) m->vertex_values[i].push_back(as_float(v[k] / l));
  }
}

struct Spec {
  bool normals = false, texcoords = false, colors = false, alpha = false, confidence = false, zero_normal = false;
  const char* u = "u";
  const char* v = "v";
  const char* red = "red";
  double uv_offset = 0;
};
Mesh attributed_torus(const Spec& s) {
  Mesh m = test::make_torus(24, 12);
  for (auto& p : m.positions)
    for (double& c : p) c = as_float(c);
  auto& vp = m.schema.vertex_properties;
  if (s.normals)
    for (const char* n : {"nx", "ny", "nz"}) vp.push_back(prop(n, ScalarType::kFloat32));
  if (s.texcoords)
    for (const char* n : {s.u, s.v}) vp.push_back(prop(n, ScalarType::kFloat64));
  if (s.colors) {
    const bool full = std::string(s.red) == "red";
    for (const char* n : full ? std::vector<const char*>{"red", "green", "blue"} : std::vector<const char*>{"r", "g", "b"})
      vp.push_back(prop(n, ScalarType::kUInt8));
    if (s.alpha) vp.push_back(prop(full ? "alpha" : "a", ScalarType::kUInt8));
  }
  if (s.confidence) vp.push_back(prop("confidence", ScalarType::kFloat32));
  const std::vector<std::array<double, 3>> n = ring_normals(m);
  m.vertex_values.assign(m.positions.size(), PropertyValues());
  for (size_t i = 0; i < m.positions.size(); ++i) {
    const auto& p = m.positions[i];
    PropertyValues& v = m.vertex_values[i];
    if (s.normals) {
      const double l = std::sqrt(n[i][0] * n[i][0] + n[i][1] * n[i][1] + n[i][2] * n[i][2]);
      for (int k = 0; k < 3; ++k) v.push_back(s.zero_normal && i == 7 ? 0.0 : as_float(n[i][k] / l));
    }
    if (s.texcoords) {
      v.push_back(std::atan2(p[1], p[0]) / (2 * M_PI) + 0.5 + s.uv_offset);
      v.push_back(0.5 + 0.4 * p[2] + s.uv_offset);
    }
    if (s.colors) {
      v.push_back(std::floor(127.5 + 120 * p[0] / 1.3));
      v.push_back(std::floor(127.5 + 120 * p[1] / 1.3));
      v.push_back(static_cast<double>((i * 37) % 256));
      if (s.alpha) v.push_back(i % 5 == 0 ? 128 : 255);
    }
    if (s.confidence) v.push_back(as_float(0.001 * static_cast<double>(i)));
  }
  return m;
}

using test::attribute_options;
using test::build_events;
using test::decode_sequence;
using test::encode_sequence;

int index_of(const MeshSchema& s, const std::string& name) {
  for (size_t i = 0; i < s.vertex_properties.size(); ++i)
    if (s.vertex_properties[i].name == name) return static_cast<int>(i);
  return -1;
}

// The decoded vertices against the encoded ones, property by property:
// normals within the angle of `normal_bits` octahedral (or exact at 0),
// texture coordinates within half a step of 2^-uv_bits (or exact), every
// other value exact.
void expect_within(const Events& in, const Events& out, int normal_bits, int uv_bits) {
  ASSERT_EQ(in.events.size(), out.events.size());
  const MeshSchema& s = in.schema;
  ASSERT_EQ(s.vertex_properties, out.schema.vertex_properties);
  const int nx = index_of(s, "nx");
  // Spec 8.3: at most about 1.41 / c radians (measured over random unit
  // vectors), and the decoder's rounding to float; exact at 0 bits.
  const int c = normal_bits ? (1 << (normal_bits - 1)) - 1 : 1;
  const double angle = normal_bits ? 1.5 / c + 1e-6 : 0;
  double worst_angle = 0, worst_uv = 0;
  size_t vertices = 0;
  for (size_t i = 0; i < in.events.size(); ++i) {
    if (in.events[i].kind != SequenceEvent::Kind::kVertex) continue;
    ++vertices;
    const PropertyValues& a = in.events[i].vertex.values;
    const PropertyValues& b = out.events[i].vertex.values;
    ASSERT_EQ(a.size(), b.size());
    for (size_t k = 0; k < a.size(); ++k) {
      const std::string& name = s.vertex_properties[k].name;
      const bool is_normal = nx >= 0 && (static_cast<int>(k) - nx) >= 0 && (static_cast<int>(k) - nx) < 3;
      const bool is_uv = name == "u" || name == "v" || name == "s" || name == "t" || name.rfind("texture_", 0) == 0;
      if (is_normal && normal_bits) continue;
      if (is_uv && uv_bits) {
        const double e = std::fabs(a[k] - b[k]);
        worst_uv = std::max(worst_uv, e);
        EXPECT_LE(e, std::ldexp(0.5, -uv_bits) * (1 + 1e-9)) << name << " of event " << i;
        continue;
      }
      EXPECT_EQ(a[k], b[k]) << name << " of event " << i;
    }
    if (nx >= 0 && normal_bits) {
      const double* n = &a[static_cast<size_t>(nx)];
      const double* m = &b[static_cast<size_t>(nx)];
      const double ln = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
      const double lm = std::sqrt(m[0] * m[0] + m[1] * m[1] + m[2] * m[2]);
      EXPECT_NEAR(lm, 1.0, 1e-6) << "event " << i;
      if (ln == 0) {  // a zero normal is coded as +z
        EXPECT_NEAR(m[2], 1.0, 1e-6);
        continue;
      }
      const double dot = (n[0] * m[0] + n[1] * m[1] + n[2] * m[2]) / (ln * lm);
      const double a_err = std::acos(std::min(1.0, dot));
      worst_angle = std::max(worst_angle, a_err);
      EXPECT_LE(a_err, angle) << "normal of event " << i;
    }
  }
  EXPECT_GT(vertices, 0u);
  ::testing::Test::RecordProperty("worst_normal_angle", std::to_string(worst_angle));
  ::testing::Test::RecordProperty("worst_uv_error", std::to_string(worst_uv));
}

TEST(Attributes, RoundTripPerKindAndProfile) {
  Spec all;
  all.normals = all.texcoords = all.colors = all.alpha = all.confidence = true;
  Spec normals, texcoords, colors;
  normals.normals = true;
  texcoords.texcoords = true;
  colors.colors = true;
  for (const Spec& s : {all, normals, texcoords, colors}) {
    const Events ev = build_events(attributed_torus(s));
    for (bool fast : {false, true}) {
      for (auto [nb, ub] : {std::pair<int, int>{8, 10}, {10, 12}, {16, 20}, {3, 4}}) {
        std::vector<uint8_t> bytes;
        Status st = encode_sequence(ev, attribute_options(fast, nb, ub), &bytes);
        ASSERT_TRUE(st.ok()) << st.to_string();
        Events out;
        PsqHeader h;
        st = decode_sequence(bytes, &out, &h);
        ASSERT_TRUE(st.ok()) << st.to_string();
        EXPECT_EQ(h.fast, fast);
        const size_t kinds = (s.normals ? 1 : 0) + (s.texcoords ? 1 : 0) + (s.colors ? 1 : 0);
        ASSERT_EQ(h.attributes.size(), kinds);
        for (const CodedAttribute& a : h.attributes) {
          const int want = a.kind == CodedAttribute::Kind::kNormal ? nb : a.kind == CodedAttribute::Kind::kTexcoord ? ub : 8;
          EXPECT_EQ(a.bits, want);
        }
        expect_within(ev, out, s.normals ? nb : 0, s.texcoords ? ub : 0);
      }
    }
  }
}

// Spec 8.4: a normal is predicted from its vertex's whole ring. Normals
// that are their vertices' area-weighted normals cost far less than the
// same normals moved one step along the torus (as smooth a field, but
// not the rings' own).
TEST(Attributes, NormalsArePredictedFromTheirRing) {
  for (bool fast : {false, true}) {
    uint64_t bytes[2];
    for (size_t shift : {0, 1}) {
      Mesh m = test::make_torus(48, 24);
      add_normals(&m, shift * 24);
      std::vector<uint8_t> out;
      VectorWriter w(&out);
      PsqEncoder enc(&w, attribute_options(fast, 10, 0));
      const Events ev = build_events(m);
      const Status st = enc.begin(ev.schema);
      ASSERT_TRUE(st.ok()) << st.to_string();
      for (const SequenceEvent& e : ev.events) {
        if (e.kind == SequenceEvent::Kind::kVertex) ASSERT_TRUE(enc.vertex(e.vertex).ok());
        else if (e.kind == SequenceEvent::Kind::kTriangle) ASSERT_TRUE(enc.triangle(e.triangle).ok());
        else ASSERT_TRUE(enc.finalize(e.finalized).ok());
      }
      ASSERT_TRUE(enc.finish().ok());
      bytes[shift] = enc.stats().attribute_bytes;
      Events back;
      ASSERT_TRUE(decode_sequence(out, &back).ok());
      expect_within(ev, back, 10, 0);
    }
    EXPECT_LT(3 * bytes[0], bytes[1]) << "fast " << fast << ": " << bytes[0] << " and " << bytes[1] << " bytes";
  }
}

// Spec 8.4: a normal waits for its vertex at most kMaxNormalWait records,
// and none past its chunk. The centre of a fan of more triangles than
// that is coded before its last triangle comes; the events, the arrays
// and the segments decoded on two threads agree.
TEST(Attributes, ANormalWaitsAtMostItsBound) {
  const uint32_t n = 6000;
  Mesh m = test::make_wavy_fan(n);
  add_normals(&m);
  const Events ev = build_events(m);
  for (bool fast : {false, true})
    for (uint64_t segment : {uint64_t{0}, uint64_t{1000}}) {
      EncodeOptions o = attribute_options(fast, 12, 0);
      o.segment_triangles = segment;
      o.chunk_bytes = 4096;  // chunks end while normals wait
      std::vector<uint8_t> bytes;
      const Status st = encode_sequence(ev, o, &bytes);
      ASSERT_TRUE(st.ok()) << st.to_string();
      Events back;
      const Status ds = decode_sequence(bytes, &back);
      ASSERT_TRUE(ds.ok()) << "fast " << fast << " segments of " << segment << ": " << ds.to_string();
      expect_within(ev, back, 12, 0);
      MeshBuffers one, two, events;
      ASSERT_TRUE(decode_mesh(bytes.data(), bytes.size(), &one, 1).ok());
      ASSERT_TRUE(decode_mesh(bytes.data(), bytes.size(), &two, 2).ok());
      MeshArraySink sink(&events);
      ASSERT_TRUE(sink.begin(back.schema).ok());
      for (const SequenceEvent& e : back.events)
        ASSERT_TRUE(e.kind == SequenceEvent::Kind::kVertex ? sink.vertex(e.vertex).ok()
                    : e.kind == SequenceEvent::Kind::kTriangle ? sink.triangle(e.triangle).ok()
                                                                : true);
      EXPECT_EQ(one.positions, events.positions);
      EXPECT_EQ(one.indices, events.indices);
      EXPECT_EQ(two.positions, events.positions);
      EXPECT_EQ(two.indices, events.indices);
      EXPECT_EQ(events.indices.size(), size_t{3} * n);
    }
}

// Both profiles decode to the same values: the attribute coder is shared.
TEST(Attributes, BackendsAgree) {
  Spec all;
  all.normals = all.texcoords = all.colors = true;
  const Events ev = build_events(attributed_torus(all));
  std::vector<uint8_t> c, f;
  ASSERT_TRUE(encode_sequence(ev, attribute_options(false, 9, 11), &c).ok());
  ASSERT_TRUE(encode_sequence(ev, attribute_options(true, 9, 11), &f).ok());
  Events a, b;
  ASSERT_TRUE(decode_sequence(c, &a).ok());
  ASSERT_TRUE(decode_sequence(f, &b).ok());
  ASSERT_EQ(a.events.size(), b.events.size());
  for (size_t i = 0; i < a.events.size(); ++i) {
    if (a.events[i].kind == SequenceEvent::Kind::kVertex) {
      EXPECT_EQ(a.events[i].vertex.values, b.events[i].vertex.values) << "event " << i;
    }
  }
}

// The texture's seam (u jumps from 1 back to 0 where the torus closes, on
// split vertices), coordinates far from the unit square and negative ones
// code within half a step, and a zero normal decodes as +z.
TEST(Attributes, SeamsFarCoordinatesAndZeroNormals) {
  for (double offset : {0.0, 1000.25, -37.5}) {
    Spec s;
    s.normals = s.texcoords = true;
    s.zero_normal = true;
    s.uv_offset = offset;
    const Events ev = build_events(attributed_torus(s));
    for (bool fast : {false, true}) {
      std::vector<uint8_t> bytes;
      ASSERT_TRUE(encode_sequence(ev, attribute_options(fast, 10, 12), &bytes).ok());
      Events out;
      ASSERT_TRUE(decode_sequence(bytes, &out).ok());
      expect_within(ev, out, 10, 12);
    }
  }
}

// Lossless streams, and quantized ones with normal and uv bits 0, keep every
// attribute bit-exact; colours are still coded by prediction.
TEST(Attributes, LosslessKeepsEveryBit) {
  Spec all;
  all.normals = all.texcoords = all.colors = all.alpha = all.confidence = true;
  const Events ev = build_events(attributed_torus(all));
  for (bool fast : {false, true}) {
    for (bool lossless : {true, false}) {
      EncodeOptions o = attribute_options(fast, lossless ? 8 : 0, lossless ? 10 : 0);
      o.lossless = lossless;
      std::vector<uint8_t> bytes;
      ASSERT_TRUE(encode_sequence(ev, o, &bytes).ok());
      Events out;
      PsqHeader h;
      ASSERT_TRUE(decode_sequence(bytes, &out, &h).ok());
      ASSERT_EQ(h.attributes.size(), 1u);
      EXPECT_EQ(h.attributes[0].kind, CodedAttribute::Kind::kColor);
      EXPECT_EQ(h.attributes[0].properties.size(), 4u);
      expect_within(ev, out, 0, 0);
    }
  }
}

// The names of spec 8.3: every texture coordinate pair and both colour
// spellings; a normal of an integer type is no normal and stays exact.
TEST(Attributes, RecognizesTheCommonNames) {
  for (auto [u, v] : {std::pair<const char*, const char*>{"u", "v"}, {"s", "t"}, {"texture_u", "texture_v"},
                      {"texture_s", "texture_t"}}) {
    Spec s;
    s.texcoords = s.colors = s.alpha = true;
    s.u = u;
    s.v = v;
    s.red = std::string(u) == "s" ? "r" : "red";
    std::vector<uint8_t> bytes;
    const Events ev = build_events(attributed_torus(s));
    ASSERT_TRUE(encode_sequence(ev, attribute_options(false, 8, 10), &bytes).ok());
    Events out;
    PsqHeader h;
    ASSERT_TRUE(decode_sequence(bytes, &out, &h).ok());
    ASSERT_EQ(h.attributes.size(), 2u) << u;
    EXPECT_EQ(h.attributes[0].kind, CodedAttribute::Kind::kTexcoord);
    EXPECT_EQ(h.schema.vertex_properties[h.attributes[0].properties[1]].name, v);
    EXPECT_EQ(h.attributes[1].kind, CodedAttribute::Kind::kColor);
    EXPECT_EQ(h.attributes[1].properties.size(), 4u);
    expect_within(ev, out, 0, 10);
  }
  Mesh m = test::make_grid(4);
  for (const char* n : {"nx", "ny", "nz"}) m.schema.vertex_properties.push_back(prop(n, ScalarType::kInt8));
  for (auto& v : m.vertex_values) v = {1, -1, 0};
  const Events ev = build_events(m);
  std::vector<uint8_t> bytes;
  ASSERT_TRUE(encode_sequence(ev, attribute_options(false, 8, 10), &bytes).ok());
  Events out;
  PsqHeader h;
  ASSERT_TRUE(decode_sequence(bytes, &out, &h).ok());
  EXPECT_TRUE(h.attributes.empty());
  expect_within(ev, out, 0, 0);
}

TEST(Attributes, EncoderRefusesBadValuesAndOptions) {
  Spec s;
  s.normals = s.texcoords = true;
  Mesh m = attributed_torus(s);
  {
    Mesh bad = m;
    bad.vertex_values[3][0] = std::nan("");
    std::vector<uint8_t> bytes;
    Status st = encode_sequence(build_events(bad), attribute_options(false, 8, 10), &bytes);
    EXPECT_EQ(st.code(), ErrorCode::kBadValue) << st.to_string();
    EXPECT_NE(st.message().find("normal"), std::string::npos) << st.message();
    // Kept exact, the same value is carried.
    bytes.clear();
    EXPECT_TRUE(encode_sequence(build_events(bad), attribute_options(false, 0, 10), &bytes).ok());
  }
  {
    Mesh bad = m;
    bad.vertex_values[3][3] = 3e6;  // beyond 2^31 steps of 2^-10
    std::vector<uint8_t> bytes;
    Status st = encode_sequence(build_events(bad), attribute_options(true, 8, 10), &bytes);
    EXPECT_EQ(st.code(), ErrorCode::kBadValue) << st.to_string();
  }
  {
    Spec c;
    c.colors = true;
    for (double v : {256.0, -1.0, 1.5, std::nan("")}) {
      Mesh bad = attributed_torus(c);
      bad.vertex_values[5][1] = v;
      std::vector<uint8_t> bytes;
      Status st = encode_sequence(build_events(bad), attribute_options(false, 8, 10), &bytes);
      EXPECT_EQ(st.code(), ErrorCode::kBadValue) << v << ": " << st.to_string();
    }
  }
  for (auto [nb, ub] : {std::pair<int, int>{1, 10}, {17, 10}, {-1, 10}, {8, 25}, {8, -2}}) {
    std::vector<uint8_t> bytes;
    EXPECT_EQ(encode_sequence(build_events(m), attribute_options(false, nb, ub), &bytes).code(), ErrorCode::kUsage) << nb << " " << ub;
  }
}

// Where the attribute section of the first chunk starts and ends, and its
// checksum (spec 4.3): the seven varints after the tag give the sections'
// sizes.
struct ChunkLayout {
  size_t chunk = 0, attr = 0, attr_size = 0, crc = 0;
};
ChunkLayout first_chunk(const std::vector<uint8_t>& b) {
  size_t at = 12;
  auto varint = [&](size_t& p) {
    uint64_t v = 0;
    for (int shift = 0;; shift += 7) {
      v |= static_cast<uint64_t>(b[p] & 0x7f) << shift;
      if (!(b[p++] & 0x80)) return v;
    }
  };
  const uint64_t payload = varint(at);
  ChunkLayout l;
  l.chunk = at + payload + 4;
  at = l.chunk + 1;
  uint64_t f[7];
  for (uint64_t& v : f) v = varint(at);
  l.attr = at + f[3] + f[4];
  l.attr_size = f[6];
  l.crc = l.attr + f[6];
  return l;
}
uint32_t crc32c(const uint8_t* p, size_t n) {
  uint32_t c = 0xffffffffu;
  for (size_t i = 0; i < n; ++i) {
    c ^= p[i];
    for (int k = 0; k < 8; ++k) c = (c >> 1) ^ (0x82f63b78u & (0u - (c & 1u)));
  }
  return ~c;
}

TEST(Attributes, DamagedStreamsAreRefused) {
  Spec all;
  all.normals = all.texcoords = all.colors = true;
  const Events ev = build_events(attributed_torus(all));
  for (bool fast : {false, true}) {
    std::vector<uint8_t> bytes;
    ASSERT_TRUE(encode_sequence(ev, attribute_options(fast, 8, 10), &bytes).ok());
    // Every truncation.
    for (size_t n = 0; n < bytes.size(); ++n) {
      std::vector<uint8_t> cut(bytes.begin(), bytes.begin() + static_cast<std::ptrdiff_t>(n));
      Events out;
      EXPECT_FALSE(decode_sequence(cut, &out).ok()) << "cut at " << n;
    }
    // Bit flips anywhere: the checksums refuse them.
    std::mt19937 rng(7);
    for (int k = 0; k < 200; ++k) {
      std::vector<uint8_t> b = bytes;
      b[rng() % b.size()] ^= static_cast<uint8_t>(1u << (rng() % 8));
      Events out;
      EXPECT_FALSE(decode_sequence(b, &out).ok());
    }
    // Garbled attribute bytes behind a valid chunk checksum reach the
    // attribute decoder: each is refused, as a corrupt section or, when its
    // values happen to be valid, by the stream checksum (spec 4.5).
    const ChunkLayout l = first_chunk(bytes);
    ASSERT_GT(l.attr_size, 0u);
    int early = 0;
    for (int k = 0; k < 300; ++k) {
      std::vector<uint8_t> b = bytes;
      for (int j = 0; j < 1 + k % 4; ++j) b[l.attr + rng() % l.attr_size] = static_cast<uint8_t>(rng());
      if (b == bytes) continue;  // the same bytes drawn again
      const uint32_t c = crc32c(b.data() + l.chunk, l.crc - l.chunk);
      for (int j = 0; j < 4; ++j) b[l.crc + static_cast<size_t>(j)] = static_cast<uint8_t>(c >> (8 * j));
      Events out;
      Status st = decode_sequence(b, &out);
      EXPECT_TRUE(st.code() == ErrorCode::kBadValue || st.code() == ErrorCode::kTruncated ||
                  st.code() == ErrorCode::kChecksum)
          << st.to_string();
      early += st.code() != ErrorCode::kChecksum;
    }
    EXPECT_GT(early, 150);
  }
}

}  // namespace
}  // namespace psq
