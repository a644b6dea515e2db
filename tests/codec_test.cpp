// SPDX-License-Identifier: Apache-2.0
// Tests of the .psq codec (codec/, spec/psq-format.md): exact round trips of
// processing sequences, quantization error bounds, determinism, chunking,
// and hostile input (every truncation, random bit flips, bad fields).
#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>

#include <unistd.h>

#include "psq/psq_codec.h"
#include "psq/psq_memory.h"
#include "psq/sequence_builder.h"
#include "psq/sequence_check.h"
#include "test_util.h"

namespace psq {
namespace {

using test::Mesh;
using Tri = std::array<uint32_t, 3>;

using Events = test::EventLog;

// Positions of a float mesh must be floats.
Mesh as_float(Mesh m) {
  if (m.schema.position_type == ScalarType::kFloat32)
    for (auto& p : m.positions)
      for (double& c : p) {
        volatile float f = static_cast<float>(c);
        c = f;
      }
  return m;
}

Events sequence_of(const Mesh& mesh, bool force_sort = false) {
  test::MemorySource src(as_float(mesh));
  Events ev;
  BuildOptions o;
  o.force_sort = force_sort;
  BuildReport report;
  Status s = build_sequence(src, ev, o, &report);
  EXPECT_TRUE(s.ok()) << s.to_string();
  return ev;
}

Status replay(const Events& ev, SequenceSink& sink) {
  PSQ_RETURN_IF_ERROR(sink.begin(ev.schema));
  for (const SequenceEvent& e : ev.events) {
    if (e.kind == SequenceEvent::Kind::kVertex) {
      PSQ_RETURN_IF_ERROR(sink.vertex(e.vertex));
    } else if (e.kind == SequenceEvent::Kind::kTriangle) {
      PSQ_RETURN_IF_ERROR(sink.triangle(e.triangle));
    } else {
      PSQ_RETURN_IF_ERROR(sink.finalize(e.finalized));
    }
  }
  return sink.finish();
}

std::vector<uint8_t> encode(const Events& ev, const EncodeOptions& o, PsqStats* stats = nullptr) {
  std::vector<uint8_t> bytes;
  VectorWriter w(&bytes);
  PsqEncoder enc(&w, o);
  Status s = replay(ev, enc);
  EXPECT_TRUE(s.ok()) << s.to_string();
  if (stats) *stats = enc.stats();
  return bytes;
}

Status decode(const std::vector<uint8_t>& bytes, Events* out, PsqStats* stats = nullptr) {
  InputStream in;
  in.open_memory(bytes.data(), bytes.size(), "mem.psq");
  PsqDecoder dec;
  PSQ_RETURN_IF_ERROR(dec.open(&in));
  out->schema = dec.schema();
  SequenceEvent e;
  for (;;) {
    PSQ_RETURN_IF_ERROR(dec.next(&e));
    if (e.kind == SequenceEvent::Kind::kEnd) break;
    out->events.push_back(e);
  }
  if (stats) *stats = dec.stats();
  return Status();
}

// Opens a decoder on `bytes`: reads and checks the header only.
Status decode_header_only(const std::vector<uint8_t>& bytes) {
  InputStream in;
  in.open_memory(bytes.data(), bytes.size(), "mem.psq");
  PsqDecoder dec;
  return dec.open(&in);
}

// A triangle rotated so that its smallest index is first, with its border
// and cut masks rotated alike.
struct CanonTri {
  Tri v;
  Op op;
  uint8_t border, cut;
  PropertyValues values;
  bool operator==(const CanonTri& o) const {
    return v == o.v && op == o.op && border == o.border && cut == o.cut && values == o.values;
  }
};
CanonTri canon(const SequenceTriangle& t, bool keep_rotation) {
  CanonTri c{{t.v[0], t.v[1], t.v[2]}, t.op, t.border_mask, t.nonmanifold_mask, t.values};
  if (keep_rotation) return c;
  auto rot = [](uint8_t m) { return static_cast<uint8_t>(((m >> 1) | (m << 2)) & 7); };
  while (c.v[0] > c.v[1] || c.v[0] > c.v[2]) {
    std::rotate(c.v.begin(), c.v.begin() + 1, c.v.end());
    c.border = rot(c.border);
    c.cut = rot(c.cut);
  }
  return c;
}

// The decoded sequence equals the encoded one (spec 2.3): the same events in
// the same order, triangles up to rotation (kept when there are face
// properties), finalize events of one triangle as a set, positions within
// `tolerance` (0: bit-exact).
void expect_same(const Events& a, const Events& b, double tolerance) {
  ASSERT_EQ(a.events.size(), b.events.size());
  const bool keep_rotation = !a.schema.face_properties.empty();
  size_t i = 0;
  double worst = 0;
  while (i < a.events.size()) {
    const SequenceEvent& x = a.events[i];
    const SequenceEvent& y = b.events[i];
    ASSERT_EQ(x.kind, y.kind) << "event " << i;
    if (x.kind == SequenceEvent::Kind::kVertex) {
      ASSERT_EQ(x.vertex.index, y.vertex.index) << "event " << i;
      ASSERT_EQ(x.vertex.reappears, y.vertex.reappears) << "event " << i;
      ASSERT_EQ(x.vertex.values, y.vertex.values) << "event " << i;
      for (int k = 0; k < 3; ++k) {
        double d = std::fabs(x.vertex.position[k] - y.vertex.position[k]);
        worst = std::max(worst, d);
        if (tolerance == 0) {
          ASSERT_EQ(x.vertex.position[k], y.vertex.position[k]) << "event " << i;
        }
      }
      ++i;
    } else if (x.kind == SequenceEvent::Kind::kTriangle) {
      ASSERT_TRUE(canon(x.triangle, keep_rotation) == canon(y.triangle, keep_rotation)) << "event " << i;
      ++i;
    } else {
      std::vector<uint32_t> fa, fb;
      while (i < a.events.size() && a.events[i].kind == SequenceEvent::Kind::kFinalize) {
        ASSERT_EQ(b.events[i].kind, SequenceEvent::Kind::kFinalize) << "event " << i;
        fa.push_back(a.events[i].finalized);
        fb.push_back(b.events[i].finalized);
        ++i;
      }
      std::sort(fa.begin(), fa.end());
      std::sort(fb.begin(), fb.end());
      ASSERT_EQ(fa, fb) << "event " << i;
    }
  }
  EXPECT_LE(worst, tolerance);
}

double half_step(const Events& ev, int bits) {
  double extent = 0;
  for (int k = 0; k < 3; ++k) extent = std::max(extent, ev.schema.bounds_max[k] - ev.schema.bounds_min[k]);
  // Half a step, plus the float rounding of the dequantized value.
  return extent / ((std::pow(2.0, bits) - 1) * 2) + 1e-6 * (1 + extent);
}

Events round_trip(const Events& ev, const EncodeOptions& o, PsqStats* stats = nullptr) {
  std::vector<uint8_t> bytes = encode(ev, o, stats);
  Events back;
  Status s = decode(bytes, &back);
  EXPECT_TRUE(s.ok()) << s.to_string();
  // The decoded sequence is valid on its own.
  SequenceChecker checker;
  Status c = replay(back, checker);
  EXPECT_TRUE(c.ok()) << c.to_string();
  if (!o.fast) {
    // The rANS back-end (spec/psq-format.md, 13.2) decodes to the same
    // sequence as the adaptive one: the same positions, triangles up to
    // rotation.
    EncodeOptions f = o;
    f.fast = true;
    Events fast_back;
    Status fs = decode(encode(ev, f), &fast_back);
    EXPECT_TRUE(fs.ok()) << "rANS back-end: " << fs.to_string();
    SequenceChecker fast_checker;
    Status fc = replay(fast_back, fast_checker);
    EXPECT_TRUE(fc.ok()) << "rANS back-end: " << fc.to_string();
    expect_same(back, fast_back, 0);
  }
  return back;
}

// Several components, a non-manifold edge and vertex, isolated vertices.
Mesh messy_mesh() {
  Mesh m = test::make_grid(12);
  Mesh s = test::make_sphere(8, 10);
  uint32_t base = static_cast<uint32_t>(m.positions.size());
  for (auto p : s.positions) m.positions.push_back({p[0] + 3, p[1], p[2]});
  for (auto t : s.triangles) m.triangles.push_back({t[0] + base, t[1] + base, t[2] + base});
  // A fin on a grid edge (three triangles on edge 0-1) and a bowtie at 5.
  uint32_t a = static_cast<uint32_t>(m.positions.size());
  m.positions.push_back({0.05, -0.2, 0.3});
  m.positions.push_back({0.4, -0.3, 0.2});
  m.positions.push_back({0.5, -0.3, -0.2});
  m.positions.push_back({9, 9, 9});  // isolated
  m.triangles.push_back({0, 1, a});
  m.triangles.push_back({5, a + 1, a + 2});
  test::reset_values(&m);
  return m;
}

TEST(Codec, SphereQuantizedRoundTrip) {
  Events ev = sequence_of(test::make_sphere(30, 40));
  for (int bits : {1, 8, 11, 16, 24, 31}) {
    EncodeOptions o;
    o.bits = bits;
    Events back = round_trip(ev, o);
    expect_same(ev, back, half_step(ev, bits));
  }
}

TEST(Codec, LosslessFloatAndDoubleAreBitExact) {
  Events ev = sequence_of(messy_mesh());
  EncodeOptions o;
  o.lossless = true;
  expect_same(ev, round_trip(ev, o), 0);
  Mesh d = messy_mesh();
  d.schema.position_type = ScalarType::kFloat64;
  std::mt19937_64 rng(7);
  for (auto& p : d.positions) {
    for (double& c : p) c += std::uniform_real_distribution<double>(-1e-9, 1e-9)(rng);
  }
  Events evd = sequence_of(d);
  expect_same(evd, round_trip(evd, o), 0);
}

TEST(Codec, NonManifoldSoupAndShuffledInput) {
  Mesh m = messy_mesh();
  Events ev = sequence_of(m, /*force_sort=*/true);
  EncodeOptions o;
  o.bits = 14;
  expect_same(ev, round_trip(ev, o), half_step(ev, 14));
  // Many components: a soup of separate triangles.
  std::vector<std::array<double, 3>> p;
  std::vector<Tri> t;
  std::mt19937 rng(3);
  for (uint32_t i = 0; i < 500; ++i) {
    for (int k = 0; k < 3; ++k)
      p.push_back({std::uniform_real_distribution<double>(0, 1)(rng), std::uniform_real_distribution<double>(0, 1)(rng),
                   std::uniform_real_distribution<double>(0, 1)(rng)});
    t.push_back({3 * i, 3 * i + 1, 3 * i + 2});
  }
  Events soup = sequence_of(test::make_mesh(p, t));
  expect_same(soup, round_trip(soup, o), half_step(soup, 14));
}

TEST(Codec, PropertiesOfEveryTypeSurvive) {
  Mesh m = messy_mesh();
  m.schema.vertex_properties = {{"nx", ScalarType::kFloat32}, {"red", ScalarType::kUInt8},
                                {"q", ScalarType::kInt16},     {"conf", ScalarType::kFloat64},
                                {"w", ScalarType::kUInt32},    {"s", ScalarType::kInt8},
                                {"u", ScalarType::kUInt16},    {"i", ScalarType::kInt32}};
  m.schema.face_properties = {{"corner_uv", ScalarType::kFloat32, true, ScalarType::kUInt8},
                              {"material", ScalarType::kInt32}};
  std::mt19937 rng(11);
  for (size_t i = 0; i < m.positions.size(); ++i) {
    m.vertex_values[i] = {static_cast<double>(static_cast<float>(std::sin(i * 0.1))),
                          static_cast<double>(i % 256),
                          static_cast<double>(static_cast<int>(i % 700) - 350),
                          std::cos(i * 0.37),
                          static_cast<double>(rng()),
                          -static_cast<double>(i % 128),
                          static_cast<double>(i * 7 % 65536),
                          -static_cast<double>(i * 1000)};
  }
  for (size_t i = 0; i < m.triangles.size(); ++i) {
    size_t n = i % 4;  // lists of 0..3 pairs
    PropertyValues v = {static_cast<double>(2 * n)};
    for (size_t k = 0; k < 2 * n; ++k) v.push_back(static_cast<double>(static_cast<float>(k * 0.25 + i)));
    v.push_back(static_cast<double>(i % 5) - 2);
    m.face_values[i] = v;
  }
  Events ev = sequence_of(m);
  EncodeOptions o;
  o.lossless = true;
  o.chunk_bytes = 64;  // many chunks
  PsqStats stats;
  Events back = round_trip(ev, o, &stats);
  EXPECT_GT(stats.chunks, 5u);
  expect_same(ev, back, 0);
  // With face properties the rotation is kept: the events are identical.
  for (size_t i = 0; i < ev.events.size(); ++i) {
    if (ev.events[i].kind != SequenceEvent::Kind::kTriangle) continue;
    for (int k = 0; k < 3; ++k) {
      ASSERT_EQ(ev.events[i].triangle.v[k], back.events[i].triangle.v[k]);
    }
  }
}

TEST(Codec, EncoderIsDeterministicAndChunkingIsTransparent) {
  Events ev = sequence_of(test::make_sphere(40, 50));
  EncodeOptions o;
  EXPECT_EQ(encode(ev, o), encode(ev, o));
  EncodeOptions small = o;
  small.chunk_bytes = 100;
  PsqStats stats;
  Events back = round_trip(ev, small, &stats);
  EXPECT_GT(stats.chunks, 10u);
  expect_same(ev, back, half_step(ev, 16));
}

// Gates away from R named both ways of spec 13.7 (a recency rank, 13.7.4;
// a slot in an escape, 13.7.5): the sequences of 40 spheres,
// interleaved a few records at a time in a random order, as a converter
// hopping between the regions of an iso-surface's sweep would emit them.
// Each record keeps its vertex and finalize events; indices are renumbered
// in order of introduction and the slot hints dropped.
TEST(Codec, FarGatesOfEveryKindRoundTrip) {
  const int kSpheres = 40;
  std::vector<std::vector<std::vector<SequenceEvent>>> records(kSpheres);  // [sphere][record]
  Events ev;
  for (int s = 0; s < kSpheres; ++s) {
    test::Mesh m = test::make_sphere(6, 8);
    for (auto& p : m.positions) p = {p[0] + 3.0 * (s % 8), p[1] + 3.0 * (s / 8), p[2]};
    Events one = sequence_of(m);
    if (s == 0) ev.schema = one.schema;
    // A record: the vertex events of a triangle, the triangle, and the
    // finalize events after it.
    std::vector<SequenceEvent> record;
    bool has_triangle = false;
    for (const SequenceEvent& e : one.events) {
      if (e.kind != SequenceEvent::Kind::kFinalize && has_triangle) {
        records[s].push_back(std::move(record));
        record.clear();
        has_triangle = false;
      }
      record.push_back(e);
      has_triangle = has_triangle || e.kind == SequenceEvent::Kind::kTriangle;
    }
    if (!record.empty()) records[s].push_back(std::move(record));
  }
  ev.schema.vertex_count = ev.schema.triangle_count = -1;
  ev.schema.bounds_max[0] += 3.0 * 7;
  ev.schema.bounds_max[1] += 3.0 * 4;
  std::mt19937 rng(5);
  std::vector<size_t> next(kSpheres, 0);
  std::map<std::pair<int, uint32_t>, uint32_t> index;  // (sphere, its index) -> new index
  for (;;) {
    std::vector<int> open;
    for (int s = 0; s < kSpheres; ++s)
      if (next[s] < records[s].size()) open.push_back(s);
    if (open.empty()) break;
    const int s = open[rng() % open.size()];
    for (int run = 1 + static_cast<int>(rng() % 6); run > 0 && next[s] < records[s].size(); --run) {
      for (SequenceEvent e : records[s][next[s]++]) {
        if (e.kind == SequenceEvent::Kind::kVertex) {
          const uint32_t n = static_cast<uint32_t>(index.size());
          index[{s, e.vertex.index}] = n;
          e.vertex.index = n;
          e.vertex.slot = kNoSlot;
        } else if (e.kind == SequenceEvent::Kind::kTriangle) {
          for (int k = 0; k < 3; ++k) {
            e.triangle.v[k] = index.at({s, e.triangle.v[k]});
            e.triangle.vslot[k] = e.triangle.eslot[k] = kNoSlot;
          }
        } else {
          e.finalized = index.at({s, e.finalized});
        }
        ev.events.push_back(e);
      }
    }
  }
  SequenceChecker checker;
  ASSERT_TRUE(replay(ev, checker).ok());
  EncodeOptions o;
  o.bits = 14;
  PsqStats stats;
  Events back = round_trip(ev, o, &stats);
  EXPECT_GT(stats.far_gates[0], 0u) << "recency ranks";
  EXPECT_GT(stats.far_gates[1], 0u) << "slots (escapes)";
  expect_same(ev, back, half_step(ev, 14));
}

// The encoder codes most triangles of an input that gives boundary
// slots (the converter's, the decoders') on a direct path that finds the
// gate by the input's edge slots (PsqEncoder::Impl::fast_direct()). It must
// give exactly the bytes of its general path, which finds every edge by
// its endpoints and is the only one an input without slots takes. An input
// whose edge slots lie (each names another edge) must give them too: the
// direct path checks what a slot names and leaves a triangle that fails a
// check to the general path. So must an input with absurdly large slots,
// without growing the encoder's slot arrays to them.
TEST(Codec, FastDirectPathCodesAsTheGeneralPath) {
  std::vector<std::pair<const char*, Events>> inputs;
  inputs.emplace_back("sphere", sequence_of(test::make_sphere(24, 48)));
  inputs.emplace_back("grid (borders)", sequence_of(test::make_grid(14)));
  inputs.emplace_back("messy (non-manifold, sorted)", sequence_of(messy_mesh(), /*force_sort=*/true));
  for (const auto& [name, ev] : inputs) {
    Events bare = ev, lying = ev;
    size_t edges_named = 0;
    for (SequenceEvent& e : bare.events) {
      if (e.kind == SequenceEvent::Kind::kVertex) e.vertex.slot = kNoSlot;
      if (e.kind != SequenceEvent::Kind::kTriangle) continue;
      for (int k = 0; k < 3; ++k) e.triangle.vslot[k] = e.triangle.eslot[k] = kNoSlot;
    }
    uint32_t n = 0;
    for (SequenceEvent& e : lying.events) {
      if (e.kind != SequenceEvent::Kind::kTriangle) continue;
      uint32_t* es = e.triangle.eslot;
      for (int k = 0; k < 3; ++k) edges_named += es[k] != kNoSlot;
      // Every third triangle names its edges in the wrong order, every
      // other third names other slots.
      if (++n % 3 == 1) std::rotate(es, es + 1, es + 3);
      else if (n % 3 == 2)
        for (int k = 0; k < 3; ++k) es[k] = es[k] == kNoSlot ? 0 : es[k] ^ 1;
    }
    ASSERT_GT(edges_named, 0u) << name;
    // Slots far beyond what the input could have handed out must not size
    // the encoder's arrays (they would take 8 GiB each): such vertices and
    // edges are found by the general path's lookups.
    Events huge = ev;
    for (SequenceEvent& e : huge.events) {
      if (e.kind == SequenceEvent::Kind::kVertex && e.vertex.slot != kNoSlot) e.vertex.slot |= 0x80000000u;
      if (e.kind != SequenceEvent::Kind::kTriangle) continue;
      for (int k = 0; k < 3; ++k) {
        if (e.triangle.vslot[k] != kNoSlot) e.triangle.vslot[k] |= 0x80000000u;
        if (e.triangle.eslot[k] != kNoSlot) e.triangle.eslot[k] |= 0x80000000u;
      }
    }
    // Quantized, and lossless, whose gate records code prediction
    // choices (spec 13.8.2).
    for (const bool lossless : {false, true}) {
      EncodeOptions o;
      o.bits = 14;
      o.lossless = lossless;
      o.fast = true;
      const std::vector<uint8_t> direct = encode(ev, o);
      EXPECT_EQ(direct, encode(bare, o)) << name << (lossless ? ", lossless" : "");
      EXPECT_EQ(direct, encode(lying, o)) << name << (lossless ? ", lossless" : "");
      EXPECT_EQ(direct, encode(huge, o)) << name << (lossless ? ", lossless" : "");
      Events back;
      Status s = decode(direct, &back);
      ASSERT_TRUE(s.ok()) << name << ": " << s.to_string();
      expect_same(ev, back, lossless ? 0 : half_step(ev, 14));
    }
  }
}

// Spec 7.3: with the adaptive back-end, the encoder predicts some adds
// across the open edge before or after the gate instead of across the
// gate, or by a mean of two of these parallelograms, and the decoder
// follows.
TEST(Codec, AddsArePredictedAcrossTheGateOrANeighbour) {
  Events ev = sequence_of(test::make_sphere(30, 60));
  EncodeOptions o;
  o.bits = 14;
  PsqStats enc_stats, dec_stats;
  std::vector<uint8_t> bytes = encode(ev, o, &enc_stats);
  Events back;
  Status s = decode(bytes, &back, &dec_stats);
  ASSERT_TRUE(s.ok()) << s.to_string();
  expect_same(ev, back, half_step(ev, 14));
  EXPECT_GT(enc_stats.predictions[0], 0u) << "across the gate";
  EXPECT_GT(enc_stats.predictions[1], 0u) << "across the edge before";
  EXPECT_GT(enc_stats.predictions[2], 0u) << "across the edge after";
  EXPECT_GT(enc_stats.predictions[3] + enc_stats.predictions[4], 0u) << "means";
  for (int k = 0; k < 5; ++k) EXPECT_EQ(enc_stats.predictions[k], dec_stats.predictions[k]) << k;
}

// Spec 13.8.2: with the rANS back-end, the adds of a quantized stream are
// predicted across the gate only, and those of a lossless one by all five
// choices; the decoder follows either way.
TEST(Codec, FastProfilePredictsByChoicesWhenLossless) {
  Events ev = sequence_of(test::make_sphere(30, 60));
  for (const bool lossless : {false, true}) {
    EncodeOptions o;
    o.bits = 14;
    o.lossless = lossless;
    o.fast = true;
    PsqStats enc_stats, dec_stats;
    std::vector<uint8_t> bytes = encode(ev, o, &enc_stats);
    Events back;
    Status s = decode(bytes, &back, &dec_stats);
    ASSERT_TRUE(s.ok()) << s.to_string();
    expect_same(ev, back, lossless ? 0 : half_step(ev, 14));
    EXPECT_GT(enc_stats.predictions[0], 0u) << "across the gate";
    for (int k = 1; k < 5; ++k) {
      if (lossless) EXPECT_GT(enc_stats.predictions[k], 0u) << "choice " << k;
      else EXPECT_EQ(enc_stats.predictions[k], 0u) << "choice " << k;
    }
    for (int k = 0; k < 5; ++k) EXPECT_EQ(enc_stats.predictions[k], dec_stats.predictions[k]) << k;
  }
}

TEST(Codec, CompressesASmoothSphereWell) {
  Events ev = sequence_of(test::make_sphere(100, 200));
  EncodeOptions o;
  o.bits = 12;
  o.measure_costs = true;
  PsqStats stats;
  std::vector<uint8_t> bytes = encode(ev, o, &stats);
  const double bpv_conn = stats.connectivity_bits / stats.vertices;
  // A regular mesh: connectivity far below the 32+ bits of an index list.
  EXPECT_LT(bpv_conn, 4.5) << "gates " << stats.gates[0] << " " << stats.gates[1] << " " << stats.gates[2] << " "
                           << stats.gates[3];
  EXPECT_EQ(stats.total_bytes, bytes.size());
}

// PsqStats splits the coded bits into connectivity and geometry with both
// back-ends (psq info, psq convert --json): the parts add up to about the
// record bytes, and the decoder measures what the encoder did.
TEST(Codec, MeasuredCostsAddUpInBothBackends) {
  Events ev = sequence_of(test::make_sphere(40, 80));
  for (bool fast : {false, true}) {
    SCOPED_TRACE(fast ? "rANS back-end" : "adaptive back-end");
    EncodeOptions o;
    o.bits = 14;
    o.fast = fast;
    o.chunk_bytes = 1024;  // several chunks
    o.measure_costs = true;
    PsqStats enc;
    std::vector<uint8_t> bytes = encode(ev, o, &enc);
    ASSERT_GT(enc.chunks, 2u);
    EXPECT_GT(enc.connectivity_bits, 0.5 * enc.vertices);
    EXPECT_GT(enc.geometry_bits, 10.0 * enc.vertices);
    const double coded = enc.connectivity_bits + enc.geometry_bits;
    // Not counted: the block lengths, the rANS states' last bytes and the
    // padding of each chunk, or the range coder's flush.
    EXPECT_LE(coded, 8.0 * enc.record_bytes);
    EXPECT_GE(coded, 0.99 * 8.0 * enc.record_bytes - 128.0 * enc.chunks);
    InputStream in;
    in.open_memory(bytes.data(), bytes.size(), "mem.psq");
    PsqDecoder dec;
    dec.measure_costs(true);
    ASSERT_TRUE(dec.open(&in).ok());
    SequenceEvent e;
    do {
      ASSERT_TRUE(dec.next(&e).ok());
    } while (e.kind != SequenceEvent::Kind::kEnd);
    EXPECT_NEAR(dec.stats().geometry_bits, enc.geometry_bits, 0.01 * enc.geometry_bits);
    EXPECT_NEAR(dec.stats().connectivity_bits, enc.connectivity_bits, 0.05 * enc.connectivity_bits + 32.0 * enc.chunks);
  }
}

TEST(Codec, EncoderRejectsInvalidSequences) {
  Events ev = sequence_of(test::make_grid(3));
  // Drop one finalize event: the encoder must notice.
  Events bad = ev;
  for (size_t i = 0; i < bad.events.size(); ++i)
    if (bad.events[i].kind == SequenceEvent::Kind::kFinalize) {
      bad.events.erase(bad.events.begin() + static_cast<std::ptrdiff_t>(i));
      break;
    }
  std::vector<uint8_t> bytes;
  VectorWriter w(&bytes);
  EncodeOptions o;
  PsqEncoder enc(&w, o);
  Status s = replay(bad, enc);
  EXPECT_EQ(s.code(), ErrorCode::kBadSequence) << s.to_string();
  // A wrong op claim.
  Events wrong = ev;
  for (auto& e : wrong.events)
    if (e.kind == SequenceEvent::Kind::kTriangle && e.triangle.op == Op::kAdd) {
      e.triangle.op = Op::kFill;
      break;
    }
  PsqEncoder enc2(&w, o);
  EXPECT_EQ(replay(wrong, enc2).code(), ErrorCode::kBadSequence);
  // Quantization needs bounds.
  Events nob = ev;
  nob.schema.has_bounds = false;
  PsqEncoder enc3(&w, o);
  EXPECT_EQ(replay(nob, enc3).code(), ErrorCode::kUsage);
}

// The encoder writes nothing its decoder would refuse: names the header
// cannot hold, and a re-appearance of a vertex not yet coded, are errors.
TEST(Codec, EncoderRefusesWhatTheDecoderWouldReject) {
  Events ev = sequence_of(test::make_grid(2));
  for (const char* name : {"a=b", "x", "has space", ""}) {
    Events named = ev;
    named.schema.vertex_properties = {{name, ScalarType::kUInt8}};
    for (auto& e : named.events)
      if (e.kind == SequenceEvent::Kind::kVertex) e.vertex.values = {1};
    std::vector<uint8_t> bytes;
    VectorWriter w(&bytes);
    EncodeOptions o;
    PsqEncoder enc(&w, o);
    EXPECT_FALSE(replay(named, enc).ok()) << name;
  }
  // Vertex 1 introduced while vertex 0 waits, isolated, re-appearing 0.
  std::vector<uint8_t> bytes;
  VectorWriter w(&bytes);
  EncodeOptions o;
  o.lossless = true;
  PsqEncoder enc(&w, o);
  ASSERT_TRUE(enc.begin(MeshSchema()).ok());
  SequenceVertex v0, v1;
  v0.index = 0;
  v1.index = 1;
  v1.reappears = 0;
  ASSERT_TRUE(enc.vertex(v0).ok());
  ASSERT_TRUE(enc.vertex(v1).ok());
  EXPECT_EQ(enc.finalize(1).code(), ErrorCode::kBadSequence);
}

// Encodes `ev` and returns the status (the bytes are dropped).
Status try_encode(const Events& ev, const EncodeOptions& o) {
  std::vector<uint8_t> bytes;
  VectorWriter w(&bytes);
  PsqEncoder enc(&w, o);
  return replay(ev, enc);
}

// The largest distance of a decoded position from the encoded one, in
// units of the grid's step.
double worst_in_steps(const Events& a, const Events& b, double step) {
  double worst = 0;
  for (size_t i = 0; i < a.events.size(); ++i) {
    if (a.events[i].kind != SequenceEvent::Kind::kVertex) continue;
    for (int k = 0; k < 3; ++k)
      worst = std::max(worst, std::fabs(a.events[i].vertex.position[k] - b.events[i].vertex.position[k]) / step);
  }
  return worst;
}

Mesh double_triangle(std::array<double, 3> a, std::array<double, 3> b, std::array<double, 3> c) {
  Mesh m = test::make_mesh({a, b, c}, {{0, 1, 2}});
  m.schema.position_type = ScalarType::kFloat64;
  return m;
}

// Positions no grid can hold at the requested precision are refused, never
// clamped: the range overflows, the step underflows, a position lies
// outside the box the encoder was given. Lossless keeps them exactly.
TEST(Codec, QuantizationRefusesWhatItCannotRepresent) {
  struct Case {
    const char* name;
    Mesh mesh;
    const char* says;
  } cases[] = {
      {"x range overflows", double_triangle({9e307, 0, 0}, {-9e307, 0, 0}, {0, 9e307, 0}), "overflows a double"},
      {"y range overflows", double_triangle({0, -1.7e308, 0}, {0, 1.7e308, 0}, {1, 0, 0}), "overflows a double"},
      {"z range overflows", double_triangle({0, 0, -1e308}, {1, 0, 1e308}, {0, 1, 0}), "overflows a double"},
      {"step underflows", double_triangle({0, 0, 0}, {4.9e-324, 0, 0}, {0, 0, 0}), "underflow"},
  };
  for (Case& c : cases) {
    Events ev = sequence_of(c.mesh);
    for (bool fast : {false, true}) {
      EncodeOptions o;
      o.fast = fast;
      o.bits = 31;
      Status s = try_encode(ev, o);
      EXPECT_EQ(s.code(), ErrorCode::kLimit) << c.name << ": " << s.to_string();
      EXPECT_NE(s.message().find(c.says), std::string::npos) << c.name << ": " << s.to_string();
      o.lossless = true;
      Events back = round_trip(ev, o);
      expect_same(ev, back, 0);
    }
  }
  // A box that does not hold every position: the vertex is named.
  Events ev = sequence_of(test::make_grid(3));
  for (double& hi : ev.schema.bounds_max) hi = 0.5;  // the grid is a cube of the largest extent
  EncodeOptions o;
  Status s = try_encode(ev, o);
  EXPECT_EQ(s.code(), ErrorCode::kBadValue) << s.to_string();
  EXPECT_NE(s.message().find("outside the quantization grid"), std::string::npos) << s.to_string();
  EXPECT_EQ(s.message().rfind("vertex ", 0), 0u) << s.to_string();
  ev = sequence_of(test::make_grid(3));
  ev.schema.bounds_min[1] = 0.25;
  EXPECT_EQ(try_encode(ev, o).code(), ErrorCode::kBadValue);
  ev.schema.bounds_min[1] = 1e6;  // above the maximum
  EXPECT_EQ(try_encode(ev, o).code(), ErrorCode::kUsage);
  // A double that is not a float, with the float position type.
  ev = sequence_of(test::make_grid(2));
  for (auto& e : ev.events)
    if (e.kind == SequenceEvent::Kind::kVertex && e.vertex.index == 4) e.vertex.position[2] = 0.1;
  for (bool lossless : {false, true}) {
    o.lossless = lossless;
    s = try_encode(ev, o);
    EXPECT_EQ(s.code(), ErrorCode::kBadValue) << s.to_string();
    EXPECT_NE(s.message().find("vertex 4: z = 0.1 is not a float"), std::string::npos) << s.to_string();
  }
}

// Extreme but representable ranges quantize within half a step (with the
// decoder's roundings) at every precision.
TEST(Codec, ExtremeRangesQuantizeWithinHalfAStep) {
  std::mt19937_64 rng(11);
  const double kRanges[][2] = {{-8e307, 8e307}, {1e300, 1e300 + 1e290}, {-1e-300, 1e-300},
                               {1e15, 1e15 + 3}, {-5e-310, 5e-310}};
  for (const auto& r : kRanges) {
    std::vector<std::array<double, 3>> p;
    std::vector<Tri> t;
    for (uint32_t i = 0; i < 60; ++i) {
      std::array<double, 3> q;
      for (double& c : q) c = r[0] + (r[1] / 2 - r[0] / 2) * 2 * std::uniform_real_distribution<double>(0, 1)(rng);
      p.push_back(q);
      if (i % 3 == 2) t.push_back({i - 2, i - 1, i});
    }
    p[0] = {r[0], r[0], r[0]};
    p[1] = {r[1], r[1], r[1]};
    Mesh m = test::make_mesh(p, t);
    m.schema.position_type = ScalarType::kFloat64;
    Events ev = sequence_of(m);
    for (int bits : {1, 16, 31}) {
      EncodeOptions o;
      o.bits = bits;
      std::vector<uint8_t> bytes;
      VectorWriter w(&bytes);
      PsqEncoder enc(&w, o);
      Status s = replay(ev, enc);
      ASSERT_TRUE(s.ok()) << r[0] << " " << bits << ": " << s.to_string();
      Events back;
      InputStream in;
      in.open_memory(bytes.data(), bytes.size());
      PsqDecoder dec;
      ASSERT_TRUE(dec.open(&in).ok());
      const double step = (dec.schema().bounds_max[0] - dec.schema().bounds_min[0]) / (std::pow(2.0, bits) - 1);
      ASSERT_TRUE(decode(bytes, &back).ok());
      ASSERT_EQ(back.events.size(), ev.events.size());
      EXPECT_LE(worst_in_steps(ev, back, step), 0.5 + 1e-5) << r[0] << " " << bits;
    }
  }
}

// Writes the header checksum of `b` (spec 4.2: the CRC-32C of the fixed
// part and the payload, whose length is one byte here) after a patch.
void resign_header(std::vector<uint8_t>* b) {
  ASSERT_LT((*b)[12], 0x80);
  const size_t crc_at = 13 + (*b)[12];
  uint32_t c = 0xffffffffu;
  for (size_t i = 0; i < crc_at; ++i) {
    c ^= (*b)[i];
    for (int k = 0; k < 8; ++k) c = (c >> 1) ^ (0x82f63b78u & (0u - (c & 1u)));
  }
  c = ~c;
  for (int k = 0; k < 4; ++k) (*b)[crc_at + k] = static_cast<uint8_t>(c >> (8 * k));
}

// Spec 4.2, 11: a newer minor version of major version 1 is read, and
// the header reports it.
TEST(Codec, NewerMinorVersionsAreRead) {
  std::vector<uint8_t> b = encode(sequence_of(test::make_grid(2)), EncodeOptions());
  ASSERT_EQ(b[8], 1);
  ASSERT_EQ(b[9], 0);
  b[9] = 7;
  resign_header(&b);
  InputStream in;
  in.open_memory(b.data(), b.size(), "mem.psq");
  PsqDecoder dec;
  ASSERT_TRUE(dec.open(&in).ok());
  EXPECT_EQ(dec.header().version_major, 1);
  EXPECT_EQ(dec.header().version_minor, 7);
}

// The decoder refuses a grid that would give positions that are not finite
// (spec 4.2), so that verify cannot call such a stream valid: a quantized
// stream's step patched and its header re-signed.
TEST(Codec, GridBeyondTheRangeOfDoublesIsRefused) {
  Events ev = sequence_of(test::make_grid(2));
  for (ScalarType type : {ScalarType::kFloat32, ScalarType::kFloat64}) {
    ev.schema.position_type = type;
    std::vector<uint8_t> bytes = encode(ev, EncodeOptions());
    ASSERT_TRUE(decode_header_only(bytes).ok());
    for (double step : {1e304, 1e300, std::numeric_limits<double>::infinity(), 0.0, -1.0}) {
      std::vector<uint8_t> b = bytes;
      // Spec 4.2: step at payload offset 26, after the 12 fixed bytes and a
      // one-byte payload length; the header's CRC-32C follows the payload.
      ASSERT_LT(b[12], 0x80);
      std::memcpy(&b[13 + 26], &step, 8);
      resign_header(&b);
      Status s = decode_header_only(b);
      if (step == 1e300 && type == ScalarType::kFloat64) {
        // The grid's corner, 1e300 * 65535, is finite: a valid header.
        EXPECT_TRUE(s.ok()) << s.to_string();
        continue;
      }
      EXPECT_EQ(s.code(), ErrorCode::kBadHeader) << step << ": " << s.to_string();
    }
  }
}

std::vector<uint8_t> small_file(bool fast = false) {
  Mesh m = messy_mesh();
  m.schema.vertex_properties = {{"red", ScalarType::kUInt8}};
  for (size_t i = 0; i < m.positions.size(); ++i) m.vertex_values[i] = {static_cast<double>(i % 200)};
  Events ev = sequence_of(m);
  EncodeOptions o;
  o.bits = 10;
  o.chunk_bytes = 200;
  o.fast = fast;
  return encode(ev, o);
}

Status decode_all(const std::vector<uint8_t>& bytes) {
  Events out;
  return decode(bytes, &out);
}

class CodecHostile : public ::testing::TestWithParam<bool> {};  // the parameter: the rANS back-end, else adaptive
INSTANTIATE_TEST_SUITE_P(Backends, CodecHostile, ::testing::Values(false, true),
                         [](const ::testing::TestParamInfo<bool>& i) { return i.param ? "Rans" : "Adaptive"; });

TEST_P(CodecHostile, EveryTruncationFailsCleanly) {
  std::vector<uint8_t> bytes = small_file(GetParam());
  ASSERT_TRUE(decode_all(bytes).ok());
  for (size_t n = 0; n < bytes.size(); ++n) {
    std::vector<uint8_t> cut(bytes.begin(), bytes.begin() + static_cast<std::ptrdiff_t>(n));
    Status s = decode_all(cut);
    ASSERT_FALSE(s.ok()) << "cut at " << n;
    if (n >= 8) {
      ASSERT_EQ(s.code(), ErrorCode::kTruncated) << "cut at " << n << ": " << s.to_string();
      ASSERT_NE(s.offset(), Status::kNoPlace);
      ASSERT_LE(s.offset(), n);
    }
  }
}

TEST_P(CodecHostile, BitFlipsAreDetected) {
  std::vector<uint8_t> bytes = small_file(GetParam());
  std::mt19937 rng(5);
  for (int trial = 0; trial < 2000; ++trial) {
    std::vector<uint8_t> b = bytes;
    size_t at = rng() % b.size();
    b[at] ^= static_cast<uint8_t>(1u << (rng() % 8));
    Status s = decode_all(b);
    // CRC-32C detects every single-bit error.
    ASSERT_FALSE(s.ok()) << "flip at " << at;
  }
}

// A chunk with a valid checksum but garbage records (a crafted file) must
// still fail cleanly: re-sign random record bytes.
TEST_P(CodecHostile, CraftedRecordsWithValidChecksums) {
  std::vector<uint8_t> bytes = small_file(GetParam());
  std::mt19937 rng(9);
  int failures = 0;
  for (int trial = 0; trial < 300; ++trial) {
    std::vector<uint8_t> b = bytes;
    test::garble_first_chunk_records(&b, rng(), 3);
    Status s = decode_all(b);
    if (!s.ok()) ++failures;  // garbage is rejected, or (rarely) decodes to another valid prefix
  }
  EXPECT_GT(failures, 250);
}

TEST(CodecHostile, BadHeaders) {
  std::vector<uint8_t> bytes = small_file();
  std::vector<uint8_t> b = bytes;
  b[0] = 'X';
  EXPECT_EQ(decode_all(b).code(), ErrorCode::kUnknownFormat);
  b = bytes;
  // Spec 4.2, 11: every major version but 1 is unsupported, at the
  // version byte, and the message names the version found and the one
  // this psq reads.
  ASSERT_EQ(bytes[8], 1);
  for (int major : {0, 2, 7, 10, 11, 12, 255}) {
    b[8] = static_cast<uint8_t>(major);
    const Status s = decode_all(b);
    EXPECT_EQ(s.code(), ErrorCode::kUnsupported) << major;
    EXPECT_EQ(s.offset(), 8u) << major;
    EXPECT_NE(s.message().find("format version " + std::to_string(major) + ".0; this psq reads 1.x"),
              std::string::npos)
        << s.message();
  }
  b = bytes;
  b[10] |= 0x80;  // unknown flag
  EXPECT_EQ(decode_all(b).code(), ErrorCode::kUnsupported);
  b = bytes;
  b[12] = 0xff;  // absurd header length: 2^21 - 1
  b[13] = 0xff;
  b[14] = 0x7f;
  EXPECT_EQ(decode_all(b).code(), ErrorCode::kLimit);
  b = bytes;
  for (int i = 12; i < 23; ++i) b[i] = 0x80;  // a varint of more than 10 bytes
  EXPECT_EQ(decode_all(b).code(), ErrorCode::kBadHeader);
  b = bytes;
  ASSERT_LT(b[12], 0x80);  // a one-byte payload length
  b[12] |= 0x80;  // the same length in a longer form than needed
  b.insert(b.begin() + 13, 0x00);
  EXPECT_EQ(decode_all(b).code(), ErrorCode::kBadHeader);
  b = bytes;
  b[20] ^= 1;  // a payload byte: checksum
  EXPECT_EQ(decode_all(b).code(), ErrorCode::kChecksum);
  b = bytes;
  b.push_back(0);  // trailing data
  EXPECT_EQ(decode_all(b).code(), ErrorCode::kBadHeader);
}


// Independent segments (spec 4.6, 4.7): a stream cut into segments decodes
// to the same sequence whether one decoder reads it from the start, each
// segment is decoded alone, or all of them at once on several threads.
struct SegmentCase {
  const char* name;
  Mesh mesh;
  EncodeOptions options;
};

std::vector<SegmentCase> segment_cases() {
  std::vector<SegmentCase> cases;
  for (bool fast : {false, true})
    for (bool lossless : {false, true}) {
      EncodeOptions o;
      o.fast = fast;
      o.lossless = lossless;
      o.segment_triangles = 97;
      o.chunk_bytes = 700;  // chunks inside segments too
      cases.push_back({"torus", test::make_torus(40, 24), o});
      o.segment_triangles = 31;
      cases.push_back({"messy", messy_mesh(), o});  // re-appearances, isolated vertices
    }
  return cases;
}

// Every segment of `bytes` decoded on `threads` threads, their events in
// order.
Status decode_by_segments(const std::vector<uint8_t>& bytes, int threads, test::EventLog* all, PsqStats* stats) {
  std::vector<test::EventLog> logs(64);
  auto open = [&](InputStream* in) {
    in->open_memory(bytes.data(), bytes.size(), "mem.psq");
    return Status();
  };
  auto work = [&](PsqDecoder& d, size_t k) {
    if (k >= logs.size()) return Status(ErrorCode::kUsage, "more segments than the test expects");
    return d.pump(logs[k]);
  };
  PSQ_RETURN_IF_ERROR(decode_segments(open, threads, work, stats));
  for (const test::EventLog& l : logs) all->events.insert(all->events.end(), l.events.begin(), l.events.end());
  return Status();
}

TEST(Segments, EverySegmentDecoderYieldsTheSameSequence) {
  for (const SegmentCase& c : segment_cases()) {
    SCOPED_TRACE(std::string(c.name) + (c.options.fast ? " rANS" : " adaptive") + (c.options.lossless ? " lossless" : ""));
    const Events ev = sequence_of(c.mesh);
    PsqStats enc_stats;
    const std::vector<uint8_t> bytes = encode(ev, c.options, &enc_stats);
    ASSERT_GE(enc_stats.segments, 3u);
    // From the start: the encoded sequence (spec 2.3), as without segments.
    test::EventLog seq;
    {
      InputStream in;
      in.open_memory(bytes.data(), bytes.size(), "mem.psq");
      PsqDecoder dec;
      ASSERT_TRUE(dec.open(&in).ok());
      EXPECT_EQ(dec.header().segment_triangles, c.options.segment_triangles);
      Status s = dec.pump(seq);
      ASSERT_TRUE(s.ok()) << s.to_string();
      EXPECT_EQ(dec.stats().segments, enc_stats.segments);
      EXPECT_EQ(dec.stats().total_bytes, bytes.size());
      // A valid sequence: slots keep their vertices and edges across the
      // segment records (consumers index their data by slot).
      SequenceChecker checker;
      Status checked = replay(seq, checker);
      EXPECT_TRUE(checked.ok()) << checked.to_string();
      EncodeOptions one = c.options;
      one.segment_triangles = 0;
      Events plain;
      ASSERT_TRUE(decode(encode(ev, one), &plain).ok());
      Events back;
      back.schema = seq.schema;
      back.events = seq.events;
      expect_same(back, plain, 0);
    }
    // By segments, on one thread and on two: every field of every event
    // (slots included: each decoder restarts in the same canonical state).
    for (int threads : {1, 2}) {
      test::EventLog par;
      PsqStats st;
      Status s = decode_by_segments(bytes, threads, &par, &st);
      ASSERT_TRUE(s.ok()) << s.to_string();
      EXPECT_EQ(par.text(), seq.text());
      EXPECT_EQ(st.vertices, enc_stats.vertices);
      EXPECT_EQ(st.triangles, enc_stats.triangles);
      EXPECT_EQ(st.chunks, enc_stats.chunks);
      EXPECT_EQ(st.max_active_vertices, enc_stats.max_active_vertices);
      EXPECT_EQ(st.total_bytes, bytes.size());
    }
    // decode_mesh on two threads: the arrays of one thread.
    MeshBuffers one, two;
    ASSERT_TRUE(decode_mesh(bytes.data(), bytes.size(), &one, 1).ok());
    Status s = decode_mesh(bytes.data(), bytes.size(), &two, 2);
    ASSERT_TRUE(s.ok()) << s.to_string();
    EXPECT_EQ(one.positions, two.positions);
    EXPECT_EQ(one.indices, two.indices);
  }
}

TEST(Segments, ASegmentDecodesAloneFromItsIndexEntry) {
  const Events ev = sequence_of(test::make_torus(40, 24));
  EncodeOptions o;
  o.segment_triangles = 500;
  const std::vector<uint8_t> bytes = encode(ev, o);
  Events all;
  ASSERT_TRUE(decode(bytes, &all).ok());
  InputStream in;
  in.open_memory(bytes.data(), bytes.size(), "mem.psq");
  PsqDecoder index;
  ASSERT_TRUE(index.open(&in).ok());
  std::vector<PsqSegment> segs;
  ASSERT_TRUE(index.segments(&segs).ok());
  ASSERT_EQ(segs.size(), 4u);  // 1,920 triangles
  // Segment 2 alone: the events between its index entry's counts.
  const PsqSegment& seg = segs[2];
  EXPECT_EQ(seg.triangles, 1000u);
  InputStream in2;
  in2.open_memory(bytes.data(), bytes.size(), "mem.psq");
  PsqDecoder d;
  ASSERT_TRUE(d.open(&in2).ok());
  ASSERT_TRUE(d.start_segment(seg).ok());
  Events part;
  SequenceEvent e;
  for (;;) {
    Status s = d.next(&e);
    ASSERT_TRUE(s.ok()) << s.to_string();
    if (e.kind == SequenceEvent::Kind::kEnd) break;
    part.events.push_back(e);
  }
  uint64_t triangles = 0;
  size_t first = 0;
  while (triangles < seg.triangles || all.events[first].kind == SequenceEvent::Kind::kFinalize) {
    if (all.events[first].kind == SequenceEvent::Kind::kTriangle) ++triangles;
    ++first;
  }
  ASSERT_FALSE(part.events.empty());
  ASSERT_EQ(part.events[0].kind, SequenceEvent::Kind::kVertex);
  EXPECT_EQ(part.events[0].vertex.index, seg.vertices);
  size_t t = 0;
  for (const SequenceEvent& x : part.events) t += x.kind == SequenceEvent::Kind::kTriangle;
  EXPECT_EQ(t, 500u);
  for (size_t i = 0; i < part.events.size(); ++i) {
    const SequenceEvent& x = part.events[i];
    const SequenceEvent& y = all.events[first + i];
    ASSERT_EQ(x.kind, y.kind) << i;
    if (x.kind == SequenceEvent::Kind::kVertex) {
      EXPECT_EQ(x.vertex.index, y.vertex.index);
      EXPECT_EQ(x.vertex.position[0], y.vertex.position[0]);
    } else if (x.kind == SequenceEvent::Kind::kTriangle) {
      EXPECT_EQ(x.triangle.v[0], y.triangle.v[0]);
      EXPECT_EQ(x.triangle.v[1], y.triangle.v[1]);
      EXPECT_EQ(x.triangle.v[2], y.triangle.v[2]);
    } else {
      EXPECT_EQ(x.finalized, y.finalized);
    }
  }
  // A pipe cannot find its segments (it decodes from the start).
  ASSERT_LT(bytes.size(), 60000u);  // fits a pipe's buffer
  int fds[2];
  ASSERT_EQ(::pipe(fds), 0);
  ASSERT_EQ(::write(fds[1], bytes.data(), bytes.size()), static_cast<ssize_t>(bytes.size()));
  ::close(fds[1]);
  InputStream pipe;
  ASSERT_TRUE(pipe.open_fd(fds[0], true, "pipe").ok());
  PsqDecoder p;
  ASSERT_TRUE(p.open(&pipe).ok());
  EXPECT_EQ(p.segments(&segs).code(), ErrorCode::kIo);
  Events piped;
  SequenceEvent pe;
  do {
    ASSERT_TRUE(p.next(&pe).ok());
  } while (pe.kind != SequenceEvent::Kind::kEnd);
}

// Damage to a segmented stream: every decoder refuses exactly the streams
// that one decoder reading from the start refuses.
TEST(Segments, DamagedStreamsFailOnEveryDecoder) {
  const Events ev = sequence_of(test::make_torus(30, 20));
  EncodeOptions o;
  o.segment_triangles = 150;
  const std::vector<uint8_t> bytes = encode(ev, o);
  std::mt19937 rng(7);
  int refused = 0;
  for (int trial = 0; trial < 300; ++trial) {
    std::vector<uint8_t> b = bytes;
    if (trial % 3 == 0) {
      b.resize(std::uniform_int_distribution<size_t>(0, b.size() - 1)(rng));
    } else {
      const size_t at = std::uniform_int_distribution<size_t>(0, b.size() - 1)(rng);
      b[at] = static_cast<uint8_t>(b[at] ^ (1u << (trial % 8)));
    }
    Events seq;
    const bool ok = decode(b, &seq).ok();
    test::EventLog par;
    const bool par_ok = decode_by_segments(b, 2, &par, nullptr).ok();
    EXPECT_EQ(ok, par_ok) << "trial " << trial;
    MeshBuffers m;
    EXPECT_EQ(decode_mesh(b.data(), b.size(), &m, 2).ok(), ok) << "trial " << trial;
    refused += !ok;
  }
  EXPECT_EQ(refused, 300);
}

}  // namespace
}  // namespace psq
