// SPDX-License-Identifier: Apache-2.0
// The codec's internal helpers whose fast paths must agree with the
// definitions of spec/psq-format.md: a fast path that differed would change
// contexts in the encoder and the decoder alike, so that round trips still
// pass while the bytes no longer follow the spec.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <vector>

#include "attributes.h"
#include "coding.h"
#include "container.h"
#include "crc32c.h"
#include "neighbors.h"
#include "properties.h"
#include "psq/psq_memory.h"
#include "records.h"
#include "segment.h"

namespace psq {
namespace codec {
namespace {

// A segmented stream of a small torus (spec 4.6), and where its first
// segment record is: the offset of its tag, of its zstd frame, its sizes.
struct SegmentedStream {
  std::vector<uint8_t> bytes;
  size_t record = 0, frame = 0, packed = 0, raw = 0;
};

SegmentedStream segmented_torus(bool fast) {
  SegmentedStream t;
  std::vector<float> pos;
  std::vector<uint32_t> idx;
  const int n = 24, m = 16;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < m; ++j) {
      const double a = 6.283185307179586 * i / n, b = 6.283185307179586 * j / m;
      pos.push_back(static_cast<float>((1 + 0.3 * std::cos(b)) * std::cos(a)));
      pos.push_back(static_cast<float>((1 + 0.3 * std::cos(b)) * std::sin(a)));
      pos.push_back(static_cast<float>(0.3 * std::sin(b)));
    }
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < m; ++j) {
      const uint32_t a = static_cast<uint32_t>(i * m + j), b = static_cast<uint32_t>(((i + 1) % n) * m + j);
      const uint32_t c = static_cast<uint32_t>(((i + 1) % n) * m + (j + 1) % m), d = static_cast<uint32_t>(i * m + (j + 1) % m);
      idx.insert(idx.end(), {a, b, c, a, c, d});
    }
  EncodeOptions o;
  o.fast = fast;
  o.segment_triangles = 200;
  EXPECT_TRUE(encode_mesh(pos.data(), pos.size() / 3, idx.data(), idx.size() / 3, o, &t.bytes).ok());
  // Walk the chunks (spec 4.3) to the first segment record.
  uint64_t hlen = 0;
  size_t at = 12 + static_cast<size_t>(parse_varint(t.bytes.data() + 12, 10, &hlen));
  at += static_cast<size_t>(hlen) + 4;
  while (at < t.bytes.size() && t.bytes[at] == kChunkTag) {
    ++at;
    uint64_t f[7];
    for (uint64_t& x : f) at += static_cast<size_t>(parse_varint(t.bytes.data() + at, 10, &x));
    at += static_cast<size_t>(f[3] + f[4] + f[6] + 4);
  }
  EXPECT_EQ(t.bytes[at], kSegmentTag);
  t.record = at;
  uint64_t packed = 0, raw = 0;
  at += 1;
  at += static_cast<size_t>(parse_varint(t.bytes.data() + at, 10, &packed));
  at += static_cast<size_t>(parse_varint(t.bytes.data() + at, 10, &raw));
  t.frame = at;
  t.packed = static_cast<size_t>(packed);
  t.raw = static_cast<size_t>(raw);
  return t;
}

// `t` with its first segment record's state replaced by `state`, the
// record's sizes and checksum made right, and the index's offsets moved
// (their checksum and the stream checksum are left: start_segment() does
// not read them).
std::vector<uint8_t> with_state(const SegmentedStream& t, const std::vector<uint8_t>& state) {
  std::vector<uint8_t> packed, rec;
  zstd_compress(state, 3, &packed);
  Put put(&rec);
  put.u8(kSegmentTag);
  put.varint(packed.size());
  put.varint(state.size());
  put.bytes(packed.data(), packed.size());
  put.u32(crc32c_update(0, rec.data(), rec.size()));
  std::vector<uint8_t> out(t.bytes.begin(), t.bytes.begin() + static_cast<std::ptrdiff_t>(t.record));
  out.insert(out.end(), rec.begin(), rec.end());
  out.insert(out.end(), t.bytes.begin() + static_cast<std::ptrdiff_t>(t.frame + t.packed + 4), t.bytes.end());
  return out;
}

// A hostile state block: whatever parse_state() accepts, a decoder that
// starts from it decodes the segment's records or refuses them, with no
// crash (the sanitizer build runs this), and nothing parse_state() refuses
// reaches load_state().
TEST(SegmentState, HostileBlocksAreRefusedOrDecodeSafely) {
  for (bool fast : {false, true}) {
    const SegmentedStream t = segmented_torus(fast);
    std::vector<uint8_t> state;
    ASSERT_TRUE(zstd_decompress(t.bytes.data() + t.frame, t.packed, t.raw, &state));
    // The block as written parses, and serializes back to itself.
    SegmentState s;
    ASSERT_EQ(parse_state(state.data(), state.size(), 1u << 24, 0, 0, (1 << 16) - 1, nullptr, &s), nullptr);
    std::vector<uint8_t> again;
    serialize_state(s, 0, &again);
    EXPECT_EQ(again, state);
    std::mt19937 rng(fast ? 3 : 4);
    int accepted = 0;
    for (int trial = 0; trial < 400; ++trial) {
      std::vector<uint8_t> b = state;
      const int flips = 1 + trial % 3;
      for (int f = 0; f < flips; ++f) {
        const size_t at = std::uniform_int_distribution<size_t>(0, b.size() - 1)(rng);
        b[at] = static_cast<uint8_t>(std::uniform_int_distribution<int>(0, 255)(rng));
      }
      if (trial % 50 == 49) b.resize(b.size() / 2);
      SegmentState h;
      if (parse_state(b.data(), b.size(), 1u << 24, 0, 0, (1 << 16) - 1, nullptr, &h) != nullptr) continue;
      ++accepted;
      FastBoundary boundary(1u << 24);
      Neighbors neighbors;
      FastRing ring;
      load_state(h, &boundary, &neighbors, &ring, static_cast<AttributeCoder*>(nullptr));
      // The whole stream with this block: decoded alone from the record.
      const std::vector<uint8_t> stream = with_state(t, b);
      InputStream in;
      in.open_memory(stream.data(), stream.size(), "mem.psq");
      PsqDecoder d;
      ASSERT_TRUE(d.open(&in).ok());
      PsqSegment seg{t.record, h.vertices, h.triangles};
      if (!d.start_segment(seg).ok()) continue;
      SequenceEvent e;
      for (int guard = 0; guard < 100000; ++guard)
        if (!d.next(&e).ok() || e.kind == SequenceEvent::Kind::kEnd) break;
    }
    EXPECT_GT(accepted, 0);
  }
}


// The CRC-32C check value, and the processor's instruction (where
// crc32c_update() uses it) against the tables: every length from 0 to 88
// at every alignment within 8 bytes, then in pieces.
TEST(Crc32c, HardwareAndTablesAgree) {
  EXPECT_EQ(crc32c_update(0, "123456789", 9), 0xe3069283u);
  EXPECT_EQ(crc32c_update_portable(0, "123456789", 9), 0xe3069283u);
  std::mt19937 rng(7);
  std::vector<uint8_t> bytes(100);
  for (uint8_t& b : bytes) b = static_cast<uint8_t>(rng());
  for (size_t at = 0; at < 8; ++at)
    for (size_t n = 0; at + n <= 88; ++n)
      ASSERT_EQ(crc32c_update(0x1234u, bytes.data() + at, n), crc32c_update_portable(0x1234u, bytes.data() + at, n))
          << "at " << at << ", " << n << " bytes";
  const uint32_t whole = crc32c_update(0, bytes.data(), bytes.size());
  EXPECT_EQ(crc32c_update(crc32c_update(0, bytes.data(), 13), bytes.data() + 13, bytes.size() - 13), whole);
}

// Spec 7.4: the bit length of the largest of the three pairwise coordinate
// distances, each taken modulo 2^64.
int extent_by_definition(int64_t a, int64_t b, int64_t c) {
  return bit_length64(std::max(coord_distance(a, b), std::max(coord_distance(a, c), coord_distance(b, c))));
}

TEST(CodecInternal, TriangleExtentMatchesItsDefinition) {
  std::mt19937_64 rng(7);
  const int64_t kMin = std::numeric_limits<int64_t>::min(), kMax = std::numeric_limits<int64_t>::max();
  const int64_t special[] = {0, 1, -1, kMin, kMax, kMin + 1, kMax - 1, int64_t{1} << 62, -(int64_t{1} << 62),
                             (int64_t{1} << 31) - 1, int64_t{1} << 31};
  auto pick = [&]() -> int64_t {
    switch (rng() % 4) {
      case 0: return special[rng() % (sizeof(special) / sizeof(special[0]))];
      case 1: return static_cast<int64_t>(rng());                      // anywhere (lossless doubles)
      case 2: return static_cast<int64_t>(rng() % (uint64_t{1} << 31));  // quantized
      default: return static_cast<int64_t>(rng() % 64) - 32;            // near each other
    }
  };
  int wrapped = 0;
  for (int i = 0; i < 200000; ++i) {
    const int64_t v[3] = {pick(), pick(), pick()};
    const int64_t p[3] = {v[0], 0, 0}, q[3] = {v[1], 0, 0}, r[3] = {v[2], 0, 0};
    ASSERT_EQ(triangle_extent(p, q, r, 0), extent_by_definition(v[0], v[1], v[2]))
        << v[0] << " " << v[1] << " " << v[2];
    const int64_t hi = std::max(v[0], std::max(v[1], v[2])), lo = std::min(v[0], std::min(v[1], v[2]));
    wrapped += static_cast<int64_t>(static_cast<uint64_t>(hi) - static_cast<uint64_t>(lo)) < 0;
  }
  EXPECT_GT(wrapped, 1000);  // the slow path ran too
}

}  // namespace
// The centre of a fan stays active while 100,000 neighbours come and go
// through a few slots: its list keeps only the neighbours that are still
// active (plus the inline entries and the growth slack), and answers
// like a set of the live edges.
TEST(Neighbors, ListsOfLongLivedVerticesDropFinalizedNeighbours) {
  codec::Neighbors n;
  n.vertex_begins(0);
  for (uint32_t s = 1; s <= 8; ++s) n.vertex_begins(s);
  for (uint32_t k = 0; k < 100000; ++k) {
    const uint32_t s = 1 + k % 8;  // the slot of the k-th neighbour
    n.vertex_begins(s);             // the slot's previous vertex was finalized
    EXPECT_FALSE(n.contains(0, s));
    n.insert(0, s);
    ASSERT_TRUE(n.contains(0, s));
    ASSERT_TRUE(n.contains(s, 0));
  }
  EXPECT_LE(n.listed(0), 10u + 2 * 16u + 8u);
  // contains() scans the shorter list: give the neighbours longer ones,
  // so that slot 0's compacted list is the one searched.
  for (uint32_t s = 1; s <= 8; ++s)
    for (uint32_t j = 0; j < 60; ++j) {
      const uint32_t other = 100 + 60 * s + j;
      n.vertex_begins(other);
      n.insert(s, other);
    }
  for (uint32_t s = 1; s <= 8; ++s) ASSERT_GT(n.listed(s), n.listed(0));
  // A vertex new in a slot has no edges, whatever its slot's past.
  n.vertex_begins(3);
  EXPECT_FALSE(n.contains(0, 3));
  EXPECT_FALSE(n.contains(3, 0));
  for (uint32_t s = 1; s <= 8; ++s) EXPECT_EQ(n.contains(0, s), s != 3) << s;
}

// A fan centre with at most seven neighbours active at a time keeps its
// list in its slot: a full slot drops its finalized neighbours before
// anything spills (the lists of iso-surfaces, whose vertices have eight
// to twelve neighbours over their lives, spilled often).
TEST(Neighbors, FullSlotsDropFinalizedNeighboursBeforeSpilling) {
  codec::Neighbors n;
  for (uint32_t s = 0; s <= 5; ++s) n.vertex_begins(s);
  for (uint32_t k = 0; k < 1000; ++k) {
    const uint32_t s = 1 + k % 5;
    n.vertex_begins(s);
    n.insert(0, s);
    ASSERT_LE(n.listed(0), 7u) << k;
    for (uint32_t t = 1; t <= 5; ++t) ASSERT_EQ(n.contains(0, t), k >= 4 || t <= s) << k << " " << t;
  }
}

// add_vertex(s, p, q) is vertex_begins(s), insert(p, s), insert(s, q):
// run both ways on the same random adds (slots reused, lists spilling past
// their inline entries), every pair of slots answers alike.
TEST(Neighbors, AddVertexIsBeginAndTwoInserts) {
  codec::Neighbors one, three;
  uint64_t x = 12345;
  auto next = [&x](uint32_t n) {
    x = x * 6364136223846793005ull + 1442695040888963407ull;
    return static_cast<uint32_t>((x >> 33) % n);
  };
  constexpr uint32_t kSlots = 24;
  for (uint32_t s = 0; s < kSlots; ++s) {
    one.vertex_begins(s);
    three.vertex_begins(s);
  }
  for (int k = 0; k < 20000; ++k) {
    const uint32_t s = next(kSlots), p = next(kSlots), q = next(kSlots);
    if (s == p || s == q || p == q) continue;
    one.add_vertex(s, p, q);
    three.vertex_begins(s);
    three.insert(p, s);
    three.insert(s, q);
    if (k % 97 == 0) {
      for (uint32_t a = 0; a < kSlots; ++a)
        for (uint32_t b = 0; b < kSlots; ++b) ASSERT_EQ(one.contains(a, b), three.contains(a, b)) << k;
    }
    ASSERT_TRUE(one.contains(p, s));
    ASSERT_TRUE(one.contains(q, s));
  }
}

}  // namespace codec

// A header of a 12-bit stream, its tables empty.
static PsqHeader table_header() {
  PsqHeader h;
  h.version_major = codec::kVersionMajor;
  h.bits = 12;
  h.step = 1;
  h.boundary_limit = 64;
  h.schema.position_type = ScalarType::kFloat32;
  return h;
}

static CodedAttribute attr(CodedAttribute::Kind kind, int bits, std::vector<uint32_t> props) {
  CodedAttribute a;
  a.kind = kind;
  a.bits = bits;
  a.properties = std::move(props);
  return a;
}

// Writes `h` with `table` and the rotation flag, and parses the payload back.
static Status parse_with_table(PsqHeader h, const std::vector<CodedAttribute>& table, bool rotation) {
  h.attributes = table;
  h.rotation = rotation;
  const std::vector<uint8_t> bytes = codec::write_header(h);
  uint64_t n = 0;
  const int len = codec::parse_varint(bytes.data() + 12, bytes.size() - 12, &n);
  PsqHeader out;
  out.version_major = codec::kVersionMajor;
  out.rotation = rotation;  // the flags precede the payload
  return codec::parse_header_payload(bytes.data() + 12 + len, static_cast<size_t>(n), 0, &out);
}

// Spec 4.2: a header's attribute table is checked against its vertex
// properties; every bad entry is refused as bad_header.
TEST(AttributeTable, BadEntriesAreRefused) {
  PsqHeader h = table_header();
  for (const char* n : {"nx", "ny", "nz", "u", "v", "red", "green", "blue", "i"}) {
    Property p;
    p.name = n;
    p.type = n[0] == 'n' || n[1] == 0 ? ScalarType::kFloat32 : ScalarType::kUInt8;
    if (std::string(n) == "i") p.type = ScalarType::kInt32;
    h.schema.vertex_properties.push_back(p);
  }
  using K = CodedAttribute::Kind;
  auto parse = [&](const std::vector<CodedAttribute>& table) { return parse_with_table(h, table, false); };
  const CodedAttribute normal = attr(K::kNormal, 8, {0, 1, 2});
  const CodedAttribute uv = attr(K::kTexcoord, 10, {3, 4});
  const CodedAttribute color = attr(K::kColor, 8, {5, 6, 7});
  EXPECT_TRUE(parse({normal, uv, color}).ok());
  EXPECT_TRUE(parse({}).ok());
  const std::vector<std::vector<CodedAttribute>> bad = {
      {attr(static_cast<K>(6), 8, {0, 1, 2})},                  // unknown kind
      {attr(static_cast<K>(0), 8, {0, 1, 2})},
      {normal, attr(K::kNormal, 8, {3, 4, 8})},                  // a kind twice
      {attr(K::kNormal, 1, {0, 1, 2})},                          // bits out of range
      {attr(K::kNormal, 17, {0, 1, 2})},
      {attr(K::kTexcoord, 0, {3, 4})},
      {attr(K::kTexcoord, 25, {3, 4})},
      {attr(K::kColor, 7, {5, 6, 7})},
      {attr(K::kNormal, 8, {0, 1})},                             // component counts
      {attr(K::kTexcoord, 10, {3, 4, 0})},
      {attr(K::kColor, 8, {5, 6})},
      {attr(K::kNormal, 8, {0, 1, 9})},                          // not a property
      {attr(K::kNormal, 8, {0, 1, 0xffffffffu})},
      {normal, attr(K::kTexcoord, 10, {2, 3})},                  // a property twice
      {attr(K::kNormal, 8, {0, 1, 8})},                          // wrong types
      {attr(K::kTexcoord, 10, {3, 5})},
      {attr(K::kColor, 8, {5, 6, 0})},
      {normal, uv, color, attr(K::kColor, 8, {5, 6, 7})},        // a kind twice, 4 entries
      {attr(K::kCornerNormal, 8, {0})},                          // no face property
  };
  for (size_t i = 0; i < bad.size(); ++i) {
    const Status s = parse(bad[i]);
    EXPECT_EQ(s.code(), ErrorCode::kBadHeader) << "case " << i << ": " << s.to_string();
  }
}

// Spec 4.2 and 8.5: a corner attribute names one float or double list
// face property; the rotation flag is set exactly when a face property
// is not a corner attribute.
TEST(AttributeTable, CornerEntries) {
  PsqHeader h = table_header();
  auto list = [](const char* name, ScalarType t) {
    Property p;
    p.name = name;
    p.type = t;
    p.is_list = true;
    p.count_type = ScalarType::kUInt8;
    return p;
  };
  h.schema.face_properties = {list("corner_normals", ScalarType::kFloat32), list("corner_uv", ScalarType::kFloat64),
                              list("ints", ScalarType::kInt32), {"flags", ScalarType::kUInt8}};
  using K = CodedAttribute::Kind;
  auto parse = [&](const std::vector<CodedAttribute>& table, bool rotation) {
    return parse_with_table(h, table, rotation);
  };
  const CodedAttribute normals = attr(K::kCornerNormal, 8, {0});
  const CodedAttribute uv = attr(K::kCornerTexcoord, 10, {1});
  EXPECT_TRUE(parse({normals, uv}, true).ok());
  EXPECT_EQ(parse({normals, uv}, false).code(), ErrorCode::kBadHeader);  // two face properties remain
  h.schema.face_properties.resize(2);
  EXPECT_TRUE(parse({normals, uv}, false).ok());
  EXPECT_EQ(parse({normals, uv}, true).code(), ErrorCode::kBadHeader);
  EXPECT_EQ(parse({normals}, false).code(), ErrorCode::kBadHeader);  // corner_uv is a column
  EXPECT_TRUE(parse({normals}, true).ok());
  h.schema.face_properties = {list("corner_normals", ScalarType::kFloat32), list("corner_uv", ScalarType::kFloat64),
                              list("ints", ScalarType::kInt32), {"flags", ScalarType::kUInt8}};
  const std::vector<std::vector<CodedAttribute>> bad = {
      {attr(K::kCornerNormal, 8, {2})},       // a list of integers
      {attr(K::kCornerNormal, 8, {3})},       // not a list
      {attr(K::kCornerNormal, 8, {4})},       // not a face property
      {attr(K::kCornerNormal, 8, {0, 1})},    // two components
      {attr(K::kCornerNormal, 1, {0})},       // bits out of range
      {attr(K::kCornerTexcoord, 25, {1})},
      {normals, attr(K::kCornerTexcoord, 10, {0})},  // a property twice
      {normals, attr(K::kCornerNormal, 8, {1})},     // a kind twice
  };
  for (size_t i = 0; i < bad.size(); ++i) {
    const Status s = parse(bad[i], true);
    EXPECT_EQ(s.code(), ErrorCode::kBadHeader) << "case " << i << ": " << s.to_string();
  }
}

// Spec 8.3: the octahedral grid's points decode to unit vectors, and
// encoding a decoded point gives it back.
TEST(AttributeTable, OctahedralPointsRoundTrip) {
  for (int bits : {2, 5, 8}) {
    const int32_t c = (1 << (bits - 1)) - 1;
    for (int32_t s = 0; s <= 2 * c; ++s)
      for (int32_t t = 0; t <= 2 * c; ++t) {
        double n[3];
        codec::octahedral_decode(s, t, c, n);
        EXPECT_NEAR(n[0] * n[0] + n[1] * n[1] + n[2] * n[2], 1.0, 1e-12);
        int32_t s2, t2;
        ASSERT_TRUE(codec::octahedral_encode(n, c, &s2, &t2));
        double m[3];
        codec::octahedral_decode(s2, t2, c, m);
        // Points on the square's rim that fold onto the same normal may
        // come back as their twin.
        EXPECT_NEAR(n[0], m[0], 1e-12) << s << " " << t;
        EXPECT_NEAR(n[1], m[1], 1e-12) << s << " " << t;
        EXPECT_NEAR(n[2], m[2], 1e-12) << s << " " << t;
      }
  }
}

}  // namespace psq
