// SPDX-License-Identifier: Apache-2.0
// The in-memory door into the codec (psq/psq_memory.h): arrays to bytes and
// back, the same mesh up to the order of vertices and triangles.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <random>

#include "psq/psq_memory.h"
#include "test_util.h"

namespace psq {
namespace {

struct Arrays {
  std::vector<float> positions;
  std::vector<uint32_t> indices;
};

Arrays arrays_of(const test::Mesh& m) {
  Arrays a;
  for (const auto& p : m.positions)
    for (double x : p) a.positions.push_back(static_cast<float>(x));
  for (const auto& t : m.triangles)
    for (uint32_t v : t) a.indices.push_back(v);
  return a;
}

using Corner = std::array<float, 3>;
using Face = std::array<Corner, 3>;

// The triangles as position triples, each rotated to start at its smallest
// corner (orientation kept), sorted: the mesh without its numbering.
// Positions are snapped to `step` (0: exact).
template <class Positions, class Indices>
std::vector<Face> faces_of(const Positions& positions, const Indices& indices, float step) {
  std::vector<Face> faces;
  for (size_t t = 0; t + 2 < indices.size(); t += 3) {
    Face f;
    for (int k = 0; k < 3; ++k)
      for (int a = 0; a < 3; ++a) {
        const float x = positions[3 * indices[t + static_cast<size_t>(k)] + static_cast<size_t>(a)];
        f[k][a] = step > 0 ? std::round(x / step) * step : x;
      }
    std::rotate(f.begin(), std::min_element(f.begin(), f.end()), f.end());
    faces.push_back(f);
  }
  std::sort(faces.begin(), faces.end());
  return faces;
}

TEST(MemoryApi, LosslessRoundTripIsTheSameMesh) {
  test::Mesh m = test::make_sphere(20, 30);
  const Arrays in = arrays_of(m);
  EncodeOptions o;
  o.lossless = true;
  std::vector<uint8_t> bytes = {0xaa};  // encode_mesh appends
  Status s = encode_mesh(in.positions.data(), in.positions.size() / 3, in.indices.data(), in.indices.size() / 3, o,
                         &bytes);
  ASSERT_TRUE(s.ok()) << s.to_string();
  ASSERT_EQ(bytes[0], 0xaa);
  MeshBuffers out;
  s = decode_mesh(bytes.data() + 1, bytes.size() - 1, &out);
  ASSERT_TRUE(s.ok()) << s.to_string();
  EXPECT_EQ(out.positions.size(), in.positions.size());
  EXPECT_EQ(out.indices.size(), in.indices.size());
  EXPECT_EQ(faces_of(out.positions, out.indices, 0), faces_of(in.positions, in.indices, 0));
}

TEST(MemoryApi, QuantizedPositionsAreWithinHalfAStep) {
  test::Mesh m = test::make_sphere(16, 24);
  const Arrays in = arrays_of(m);
  EncodeOptions o;
  o.bits = 12;
  std::vector<uint8_t> bytes;
  ASSERT_TRUE(encode_mesh(in.positions.data(), in.positions.size() / 3, in.indices.data(), in.indices.size() / 3, o,
                          &bytes)
                  .ok());
  MeshBuffers out;
  ASSERT_TRUE(decode_mesh(bytes.data(), bytes.size(), &out).ok());
  ASSERT_EQ(out.positions.size(), in.positions.size());
  // Each decoded vertex is within half a step of an input vertex: match by
  // nearest (the vertex order differs).
  const double step = 2.0 / 4095;  // the sphere spans [-1, 1]
  for (size_t v = 0; v < out.positions.size(); v += 3) {
    double best = 1e30;
    for (size_t w = 0; w < in.positions.size(); w += 3) {
      double d = 0;
      for (int a = 0; a < 3; ++a)
        d = std::max(d, std::fabs(static_cast<double>(out.positions[v + a]) - in.positions[w + a]));
      best = std::min(best, d);
    }
    ASSERT_LE(best, step / 2 + 1e-6) << "vertex " << v / 3;
  }
}

// A fin (three triangles on one edge) and a bowtie on a grid: borders, and
// vertices the converter cuts, which re-appear in the stream.
test::Mesh nonmanifold_grid(int n) {
  test::Mesh m = test::make_grid(n);
  const uint32_t a = static_cast<uint32_t>(m.positions.size());
  m.positions.push_back({0.5, -0.5, 0.7});
  m.positions.push_back({2.5, 2.5, 1.0});
  m.positions.push_back({2.5, 1.5, 1.0});
  m.triangles.push_back({0, 1, a});
  m.triangles.push_back({6, a + 1, a + 2});
  return m;
}

// decode_mesh merges the re-appearing vertices back.
TEST(MemoryApi, NonManifoldVerticesAreMergedBack) {
  const test::Mesh m = nonmanifold_grid(4);
  const Arrays in = arrays_of(m);
  EncodeOptions o;
  o.lossless = true;
  std::vector<uint8_t> bytes;
  ASSERT_TRUE(encode_mesh(in.positions.data(), in.positions.size() / 3, in.indices.data(), in.indices.size() / 3, o,
                          &bytes)
                  .ok());
  // The stream holds re-appearances.
  InputStream stream;
  stream.open_memory(bytes.data(), bytes.size(), "mem.psq");
  PsqDecoder decoder;
  ASSERT_TRUE(decoder.open(&stream).ok());
  SequenceEvent e;
  size_t reappearing = 0;
  for (;;) {
    ASSERT_TRUE(decoder.next(&e).ok());
    if (e.kind == SequenceEvent::Kind::kEnd) break;
    reappearing += e.kind == SequenceEvent::Kind::kVertex && e.vertex.reappears != kNoVertex;
  }
  EXPECT_GT(reappearing, 0u);
  MeshBuffers out;
  ASSERT_TRUE(decode_mesh(bytes.data(), bytes.size(), &out).ok());
  EXPECT_EQ(out.positions.size(), in.positions.size());
  EXPECT_EQ(faces_of(out.positions, out.indices, 0), faces_of(in.positions, in.indices, 0));
}

TEST(MemoryApi, BadArraysAreRejected) {
  const std::vector<float> p = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  const std::vector<uint32_t> bad_index = {0, 1, 3};
  std::vector<uint8_t> bytes = {1, 2, 3};
  Status s = encode_mesh(p.data(), 3, bad_index.data(), 1, EncodeOptions(), &bytes);
  EXPECT_EQ(s.code(), ErrorCode::kBadValue);
  EXPECT_NE(s.message().find("triangle 0: index 3"), std::string::npos) << s.message();
  EXPECT_EQ(bytes, (std::vector<uint8_t>{1, 2, 3}));  // untouched
  std::vector<float> nan = p;
  nan[4] = std::nanf("");
  const std::vector<uint32_t> tri = {0, 1, 2};
  s = encode_mesh(nan.data(), 3, tri.data(), 1, EncodeOptions(), &bytes);
  EXPECT_EQ(s.code(), ErrorCode::kBadValue);
  EXPECT_NE(s.message().find("vertex 1: position is not finite"), std::string::npos) << s.message();
}

TEST(MemoryApi, EmptyMeshRoundTrips) {
  std::vector<uint8_t> bytes;
  ASSERT_TRUE(encode_mesh(nullptr, 0, nullptr, 0, EncodeOptions(), &bytes).ok());
  MeshBuffers out;
  out.positions = {1, 2, 3};
  ASSERT_TRUE(decode_mesh(bytes.data(), bytes.size(), &out).ok());
  EXPECT_TRUE(out.positions.empty());
  EXPECT_TRUE(out.indices.empty());
}

TEST(MemoryApi, CorruptStreamsFailWithAnEmptyMesh) {
  test::Mesh m = test::make_sphere(8, 10);
  const Arrays in = arrays_of(m);
  std::vector<uint8_t> bytes;
  ASSERT_TRUE(encode_mesh(in.positions.data(), in.positions.size() / 3, in.indices.data(), in.indices.size() / 3,
                          EncodeOptions(), &bytes)
                  .ok());
  for (size_t n = 0; n < bytes.size(); n += 7) {
    MeshBuffers out;
    Status s = decode_mesh(bytes.data(), n, &out);
    ASSERT_FALSE(s.ok()) << "cut at " << n;
    EXPECT_TRUE(out.positions.empty() && out.indices.empty()) << "cut at " << n;
  }
}

}  // namespace
}  // namespace psq

namespace psq {
namespace {

// decode_mesh as PsqDecoder's events describe it: positions as floats in
// order of first appearance, re-appearances merged, triangles in order.
Status arrays_from_events(const std::vector<uint8_t>& bytes, MeshBuffers* out) {
  InputStream stream;
  stream.open_memory(bytes.data(), bytes.size(), "mem.psq");
  PsqDecoder decoder;
  PSQ_RETURN_IF_ERROR(decoder.open(&stream));
  std::vector<uint32_t> index;
  for (;;) {
    SequenceEvent e;
    PSQ_RETURN_IF_ERROR(decoder.next(&e));
    if (e.kind == SequenceEvent::Kind::kEnd) return Status();
    if (e.kind == SequenceEvent::Kind::kVertex) {
      if (e.vertex.reappears != kNoVertex) {
        index.push_back(index[e.vertex.reappears]);
      } else {
        index.push_back(static_cast<uint32_t>(out->positions.size() / 3));
        for (double x : e.vertex.position) out->positions.push_back(static_cast<float>(x));
      }
    } else if (e.kind == SequenceEvent::Kind::kTriangle) {
      for (uint32_t v : e.triangle.v) out->indices.push_back(index[v]);
    }
  }
}

std::vector<uint8_t> encode_arrays(const test::Mesh& m, const EncodeOptions& o) {
  const Arrays in = arrays_of(m);
  std::vector<uint8_t> bytes;
  const Status s = encode_mesh(in.positions.data(), in.positions.size() / 3, in.indices.data(), in.indices.size() / 3,
                               o, &bytes);
  EXPECT_TRUE(s.ok()) << s.to_string();
  return bytes;
}

class MemoryApiBackends : public ::testing::TestWithParam<bool> {
 protected:
  EncodeOptions options() const {
    EncodeOptions o;
    o.fast = GetParam();
    return o;
  }
};

// decode_mesh decodes the fast profile's common records straight into the
// arrays (record_decoder.cpp) and the others through events: the result must
// be exactly the events' mesh, in the same order.
TEST_P(MemoryApiBackends, ArraysAreTheEventsMesh) {
  struct Case {
    test::Mesh mesh;
    int bits;  // 0: lossless
    uint32_t chunk_bytes;
  };
  const std::vector<Case> cases = {
      {test::make_sphere(30, 40), 16, 1u << 20}, {test::make_sphere(30, 40), 11, 300},
      {test::make_sphere(12, 9), 0, 1u << 20},   {nonmanifold_grid(12), 14, 1u << 20},
      {nonmanifold_grid(20), 0, 200},            {test::make_grid(40), 3, 1u << 20},
  };
  for (size_t i = 0; i < cases.size(); ++i) {
    EncodeOptions o = options();
    o.lossless = cases[i].bits == 0;
    if (!o.lossless) o.bits = cases[i].bits;
    o.chunk_bytes = cases[i].chunk_bytes;
    const std::vector<uint8_t> bytes = encode_arrays(cases[i].mesh, o);
    MeshBuffers direct, events;
    ASSERT_TRUE(decode_mesh(bytes.data(), bytes.size(), &direct).ok()) << "case " << i;
    ASSERT_TRUE(arrays_from_events(bytes, &events).ok()) << "case " << i;
    EXPECT_EQ(direct.positions, events.positions) << "case " << i;
    EXPECT_EQ(direct.indices, events.indices) << "case " << i;
    EXPECT_EQ(direct.indices.size(), 3 * cases[i].mesh.triangles.size()) << "case " << i;
    // The chunks' declared counts size the arrays once (decode_into()):
    // no reallocation, so no capacity beyond them, unless the stream has
    // more than four triangles per byte (the cap on a hostile stream's
    // counts; case 5, at 3 bits). The non-manifold grids' re-appearances
    // are vertex events without a position of their own.
    if (4 * bytes.size() >= cases[i].mesh.triangles.size()) {
      EXPECT_EQ(direct.indices.capacity(), direct.indices.size()) << "case " << i;
      if (i < 3) {
        EXPECT_EQ(direct.positions.capacity(), direct.positions.size()) << "case " << i;
      }
    }
    // Into arrays that held other values: MeshBuffers' allocator does not
    // zero what resize() adds, so an element that the decoder failed to
    // write would keep a stale value here.
    // Four times the sizes: multi-chunk streams grow the arrays by
    // doubling (direct_room), which must not reach memory without them.
    MeshBuffers stale;
    stale.positions.assign(12 * cases[i].mesh.positions.size() + 100, -7.5f);
    stale.indices.assign(12 * cases[i].mesh.triangles.size() + 100, 0xdeadbeefu);
    ASSERT_TRUE(decode_mesh(bytes.data(), bytes.size(), &stale).ok()) << "case " << i;
    EXPECT_EQ(stale.positions, events.positions) << "case " << i;
    EXPECT_EQ(stale.indices, events.indices) << "case " << i;
  }
}

// Flipped bits: decode_mesh and the events agree on whether the stream is
// valid, and on its mesh when it is (the direct records check what the
// event path checks); a failed decode_mesh leaves the mesh empty.
TEST_P(MemoryApiBackends, FlippedBitsAgreeWithTheEvents) {
  EncodeOptions o = options();
  o.chunk_bytes = 400;
  const std::vector<uint8_t> good = encode_arrays(nonmanifold_grid(16), o);
  std::mt19937 rng(4);
  for (int trial = 0; trial < 600; ++trial) {
    std::vector<uint8_t> bytes = good;
    const size_t at = rng() % bytes.size();
    bytes[at] ^= static_cast<uint8_t>(1u << (rng() % 8));
    MeshBuffers direct, events;
    const Status sd = decode_mesh(bytes.data(), bytes.size(), &direct);
    const Status se = arrays_from_events(bytes, &events);
    ASSERT_EQ(sd.ok(), se.ok()) << "byte " << at << ": " << sd.to_string() << " / " << se.to_string();
    if (sd.ok()) {
      EXPECT_EQ(direct.positions, events.positions) << "byte " << at;
      EXPECT_EQ(direct.indices, events.indices) << "byte " << at;
    } else {
      EXPECT_TRUE(direct.positions.empty() && direct.indices.empty()) << "byte " << at;
    }
  }
}

// Garbled records in a re-signed chunk (a crafted file; flipped bits alone
// stop at the chunk checksum): decode_mesh's own loop and the events path
// must fail with the same error at the same place, or decode the same mesh.
TEST_P(MemoryApiBackends, CraftedRecordsFailAsTheEventsDo) {
  EncodeOptions o = options();
  const std::vector<uint8_t> good = encode_arrays(nonmanifold_grid(16), o);
  std::mt19937 rng(11);
  int failures = 0;
  for (int trial = 0; trial < 300; ++trial) {
    std::vector<uint8_t> bytes = good;
    test::garble_first_chunk_records(&bytes, rng(), 1 + trial % 3);
    MeshBuffers direct, events;
    const Status sd = decode_mesh(bytes.data(), bytes.size(), &direct);
    const Status se = arrays_from_events(bytes, &events);
    ASSERT_EQ(sd.to_string(), se.to_string()) << "trial " << trial;
    if (sd.ok()) {
      EXPECT_EQ(direct.positions, events.positions) << "trial " << trial;
      EXPECT_EQ(direct.indices, events.indices) << "trial " << trial;
    } else {
      ++failures;
    }
  }
  EXPECT_GT(failures, 250);
}

// MeshArraySink through its events gives the mesh that decode_mesh() takes
// straight from the records, and so does the direct path from a stream
// that is not in memory (no capacity hint).
TEST_P(MemoryApiBackends, ArraySinkEventsAndDirectPathAgree) {
  for (const test::Mesh& mesh : {test::make_sphere(20, 30), nonmanifold_grid(12)}) {
    EncodeOptions o = options();
    o.bits = 14;
    const std::vector<uint8_t> bytes = encode_arrays(mesh, o);
    MeshBuffers direct;
    ASSERT_TRUE(decode_mesh(bytes.data(), bytes.size(), &direct).ok());
    // Event by event: the same sink without its arrays' door.
    struct EventsOnly : MeshArraySink {
      using MeshArraySink::MeshArraySink;
      MeshBuffers* mesh_arrays() override { return nullptr; }
    };
    InputStream stream;
    stream.open_memory(bytes.data(), bytes.size(), "mem.psq");
    PsqDecoder decoder;
    ASSERT_TRUE(decoder.open(&stream).ok());
    MeshBuffers events;
    EventsOnly sink(&events);
    ASSERT_TRUE(decoder.pump(sink).ok());
    EXPECT_EQ(direct.positions, events.positions);
    EXPECT_EQ(direct.indices, events.indices);
    // The direct path from a file.
    test::TempDir dir;
    const std::string path = dir.file("array_sink.psq");
    test::write_file(path, std::string(bytes.begin(), bytes.end()));
    InputStream file;
    ASSERT_TRUE(file.open(path).ok());
    PsqDecoder from_file;
    ASSERT_TRUE(from_file.open(&file).ok());
    MeshBuffers streamed;
    MeshArraySink file_sink(&streamed);
    ASSERT_TRUE(from_file.pump(file_sink).ok());
    EXPECT_EQ(direct.positions, streamed.positions);
    EXPECT_EQ(direct.indices, streamed.indices);
  }
}

INSTANTIATE_TEST_SUITE_P(Backends, MemoryApiBackends, ::testing::Values(false, true),
                         [](const ::testing::TestParamInfo<bool>& p) { return p.param ? "Rans" : "Adaptive"; });

}  // namespace
}  // namespace psq
