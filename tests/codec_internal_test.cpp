// SPDX-License-Identifier: Apache-2.0
// The codec's internal helpers whose fast paths must agree with the
// definitions of spec/psq-format.md: a fast path that differed would change
// contexts in the encoder and the decoder alike, so that round trips still
// pass while the bytes no longer follow the spec.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <limits>
#include <random>
#include <vector>

#include "coding.h"
#include "crc32c.h"
#include "neighbors.h"

namespace psq {
namespace codec {
namespace {

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
}  // namespace psq
