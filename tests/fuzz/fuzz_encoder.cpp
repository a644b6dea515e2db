// SPDX-License-Identifier: Apache-2.0
// libFuzzer target: the .psq encoder (PsqEncoder) on hostile event sequences.
//
// An application that links psq feeds the encoder processing-sequence events
// itself, so the encoder treats them as untrusted: a wrong event must give
// an error, never a crash, a runaway allocation or a stream that does not
// decode. The boundary slots that come with the events (SequenceVertex::
// slot, SequenceTriangle::vslot and eslot) speed it up: the fast profile's
// direct path (PsqEncoder::Impl::fast_direct) takes a triangle's gate from
// them when they hold, and leaves the triangle to the general path, which
// finds edges by their endpoints, when they do not. They must never change
// the bytes.
//
// The bytes describe an index soup, as fuzz_sequence's do, then options and
// mutations of the sequence that build_sequence makes of it:
//   byte 0: bits 0-5: vertex count n - 1 (n in [1, 64]); bit 6: the soup
//           lists its triangles before its vertices; bit 7: vertices carry
//           a uchar property, a normal, a texture coordinate and a colour
//           (attributes, spec 8.3), and triangles corner normals and
//           texture coordinates (8.5) and, for an even n, an int property;
//   byte 1: bits 0-1: chunk size (2^14, 64, 256 or 4096 bytes); bits 2-3:
//           positions (14 bits, 4 bits, 21 bits, lossless); bits 4-7: the
//           boundary limit (0: the default, else 2 * value + 1);
//   byte 2: the triangle count t (at most kMaxTriangles);
//   then 3 bytes a triangle (each index = byte mod n), then 3 bytes a
//   mutation (kind, event, value; see mutate()), at most kMaxMutations.
// Vertex i is at (i, i*i mod 7, i mod 3).
//
// The oracle compares the sequence as mutated with the same sequence with
// every slot hint removed (kNoSlot), in the fast profile and, for one input
// in four, in the compact one:
// - Edge slots are hints only (the fast profile's direct path checks what
//   one names and leaves the triangle to the general path when it lies).
//   While the mutations only made edge slots lie or rotated triangles whole,
//   both must fail with the same error or give the same bytes.
// - A vertex slot that lies may be refused (an encoder given slots finds
//   vertices by them), so after other mutations: when the sequence with its
//   hints is accepted, the one without must be too, with the same bytes.
// A stream the encoder accepted must decode, through PsqDecoder and
// through decode_mesh(), to as many vertices and triangles as it was given.
#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <utility>
#include <vector>

#include "common.h"
#include "psq/indexed_mesh.h"
#include "psq/psq_codec.h"
#include "psq/psq_memory.h"
#include "psq/sequence_builder.h"

namespace {

constexpr size_t kMaxTriangles = 120;
constexpr size_t kMaxMutations = 48;
using psq::fuzz::Soup;
using psq::fuzz::SoupSource;

// Mutation `kind` of event `at` (mod the count) with `value`. Kinds 0 to 4
// only change slot hints (the sequence stays what it was); 5 to 9 change
// the sequence itself, which the encoder must then check. Returns whether
// the mutation left every vertex slot as it was (kinds 0, 3 and 4).
bool mutate(std::vector<psq::SequenceEvent>& ev, uint8_t kind, uint8_t at, uint8_t value) {
  if (ev.empty()) return true;
  const size_t i = at % ev.size();
  psq::SequenceEvent& e = ev[i];
  const bool tri = e.kind == psq::SequenceEvent::Kind::kTriangle;
  const int k = value % 3;
  // Small slots name other boundary edges and vertices; a high bit names
  // slots the input could never have handed out.
  const uint32_t slot = value & 0x80 ? 0x80000000u | value : value & 0x3f;
  switch (kind % 10) {
    case 0:  // an edge slot names another edge: one named by a triangle shortly before, or any
      if (tri && (value & 0x40)) {
        for (size_t j = i, back = 1 + (value >> 3 & 7); j-- > 0;)
          if (ev[j].kind == psq::SequenceEvent::Kind::kTriangle && --back == 0) {
            e.triangle.eslot[k] = ev[j].triangle.eslot[(k + (value >> 2 & 1)) % 3];
            break;
          }
      } else if (tri) {
        e.triangle.eslot[k] = slot;
      }
      break;
    case 1:  // a vertex slot names another vertex
      if (tri) e.triangle.vslot[k] = slot;
      break;
    case 2:  // a vertex's own slot
      if (e.kind == psq::SequenceEvent::Kind::kVertex) e.vertex.slot = slot;
      break;
    case 3:  // the edge slots in the wrong order
      if (tri) {
        uint32_t* s = e.triangle.eslot;
        const uint32_t first = s[0];
        s[0] = s[1];
        s[1] = s[2];
        s[2] = first;
      }
      break;
    case 4:  // the corners rotated with everything that goes with them: the same triangle
      if (tri) {
        psq::SequenceTriangle& t = e.triangle;
        psq::SequenceTriangle r = t;
        auto rot3 = [](uint8_t m) { return static_cast<uint8_t>(((m >> 1) | (m << 2)) & 7); };
        for (int c = 0; c < 3; ++c) {
          r.v[c] = t.v[(c + 1) % 3];
          r.vslot[c] = t.vslot[(c + 1) % 3];
          r.eslot[c] = t.eslot[(c + 1) % 3];
        }
        r.new_mask = rot3(t.new_mask);
        r.final_mask = rot3(t.final_mask);
        r.border_mask = rot3(t.border_mask);
        r.nonmanifold_mask = rot3(t.nonmanifold_mask);
        r.leaving_mask = rot3(t.leaving_mask);
        r.entering_mask = rot3(t.entering_mask);
        t = r;
      }
      break;
    case 5:  // two neighbouring events swapped
      if (i + 1 < ev.size()) std::swap(ev[i], ev[i + 1]);
      break;
    case 6:  // an event dropped
      ev.erase(ev.begin() + static_cast<std::ptrdiff_t>(i));
      break;
    case 7:  // an event repeated
      if (ev.size() < 4 * (kMaxTriangles + 64)) ev.insert(ev.begin() + static_cast<std::ptrdiff_t>(i), ev[i]);
      break;
    case 8:  // a corner names another vertex
      if (tri) e.triangle.v[k] = value % 64;
      else if (e.kind == psq::SequenceEvent::Kind::kFinalize) e.finalized = value % 64;
      break;
    case 9:  // a flag of the triangle flipped (op, masks)
      if (tri) {
        psq::SequenceTriangle& t = e.triangle;
        switch ((value >> 2) % 7) {
          case 0: t.op = static_cast<psq::Op>(value % 5); break;
          case 1: t.new_mask ^= 1u << k; break;
          case 2: t.final_mask ^= 1u << k; break;
          case 3: t.border_mask ^= 1u << k; break;
          case 4: t.nonmanifold_mask ^= 1u << k; break;
          case 5: t.leaving_mask ^= 1u << k; break;
          default: t.entering_mask ^= 1u << k; break;
        }
      }
      break;
  }
  return kind % 10 == 0 || kind % 10 == 3 || kind % 10 == 4;
}

struct Result {
  psq::Status status;
  std::vector<uint8_t> bytes;
};

Result encode(const psq::MeshSchema& schema, const std::vector<psq::SequenceEvent>& ev, const psq::EncodeOptions& o) {
  Result r;
  psq::VectorWriter w(&r.bytes);
  psq::PsqEncoder enc(&w, o);
  r.status = enc.begin(schema);
  for (size_t i = 0; i < ev.size() && r.status.ok(); ++i) {
    const psq::SequenceEvent& e = ev[i];
    if (e.kind == psq::SequenceEvent::Kind::kVertex) r.status = enc.vertex(e.vertex);
    else if (e.kind == psq::SequenceEvent::Kind::kTriangle) r.status = enc.triangle(e.triangle);
    else r.status = enc.finalize(e.finalized);
  }
  if (r.status.ok()) r.status = enc.finish();
  return r;
}

[[noreturn]] void fail(const char* what, const std::string& a, const std::string& b) {
  std::fprintf(stderr, "%s\n  with slot hints: %s\n  without:         %s\n", what, a.c_str(), b.c_str());
  std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 3) return 0;
  Soup soup;
  soup.n = (data[0] & 0x3f) + 1u;
  soup.faces_first = (data[0] & 0x40) != 0;
  soup.with_values = (data[0] & 0x80) != 0;
  const uint8_t opt = data[1];
  const size_t nt = std::min<size_t>(data[2], kMaxTriangles);
  size_t at = 3;
  for (size_t t = 0; t < nt && at + 3 <= size; ++t, at += 3)
    soup.triangles.push_back({data[at] % soup.n, data[at + 1] % soup.n, data[at + 2] % soup.n});

  SoupSource source(soup);
  psq::fuzz::SequenceRecorder seq;
  psq::BuildOptions bo;
  psq::BuildReport report;
  if (!psq::build_sequence(source, seq, bo, &report).ok()) return 0;  // fuzz_sequence's concern
  bool edge_hints_only = true;  // no mutation but lying edge slots and whole rotations
  for (size_t m = 0; m < kMaxMutations && at + 3 <= size; ++m, at += 3)
    edge_hints_only = mutate(seq.events, data[at], data[at + 1], data[at + 2]) && edge_hints_only;
  std::vector<psq::SequenceEvent> bare = seq.events;
  for (psq::SequenceEvent& e : bare) {
    e.vertex.slot = psq::kNoSlot;
    for (int k = 0; k < 3; ++k) e.triangle.vslot[k] = e.triangle.eslot[k] = psq::kNoSlot;
  }
  uint64_t vertices = 0, triangles = 0;
  for (const psq::SequenceEvent& e : seq.events) {
    vertices += e.kind == psq::SequenceEvent::Kind::kVertex;
    triangles += e.kind == psq::SequenceEvent::Kind::kTriangle;
  }

  psq::EncodeOptions o;
  // 2^14 bytes holds any of these meshes in one chunk, as the default 2^20
  // would, without the default's reservation of 2^22 symbols per encoder
  // (poisoned by ASan at each allocation, it made the fuzzer 3 times slower).
  static const uint32_t kChunk[4] = {1u << 14, 64, 256, 4096};
  static const int kBits[4] = {14, 4, 21, 0};
  o.chunk_bytes = kChunk[opt & 3];
  o.bits = kBits[(opt >> 2) & 3];
  o.lossless = o.bits == 0;
  if (o.lossless) o.bits = 16;
  if (opt >> 4) o.boundary_limit = 2u * (opt >> 4) + 1;
  // Normals and texture coordinates quantized (spec 8.3; colours always).
  o.normal_bits = 8;
  o.uv_bits = 10;
  // The compact profile shares the code that reads the hints, and its
  // encoder and decoder build their adaptive models first (most of a run
  // here, under coverage instrumentation): it is checked on one input in
  // four (by length), the fast profile on all.
  for (bool fast : {true, false}) {
    if (!fast && size % 4 != 0) continue;
    o.fast = fast;
    const Result hinted = encode(seq.schema, seq.events, o);
    const Result plain = encode(seq.schema, bare, o);
    if (hinted.status.to_string() != plain.status.to_string() && (edge_hints_only || hinted.status.ok()))
      fail(fast ? "fast: the slot hints changed the outcome" : "compact: the slot hints changed the outcome",
           hinted.status.to_string(), plain.status.to_string());
    if (!hinted.status.ok()) continue;
    if (hinted.bytes != plain.bytes)
      fail(fast ? "fast: the slot hints changed the bytes" : "compact: the slot hints changed the bytes",
           std::to_string(hinted.bytes.size()) + " bytes", std::to_string(plain.bytes.size()) + " bytes");
    // What the encoder accepted decodes, through both decoders.
    psq::InputStream in;
    in.open_memory(hinted.bytes.data(), hinted.bytes.size(), "<encoded>");
    psq::PsqDecoder dec;
    psq::Status s = dec.open(&in);
    uint64_t dv = 0, dt = 0;
    psq::SequenceEvent e;
    while (s.ok()) {
      s = dec.next(&e);
      if (!s.ok() || e.kind == psq::SequenceEvent::Kind::kEnd) break;
      dv += e.kind == psq::SequenceEvent::Kind::kVertex;
      dt += e.kind == psq::SequenceEvent::Kind::kTriangle;
    }
    if (!s.ok()) psq::fuzz::die("an accepted sequence does not decode", s);
    if (dv != vertices || dt != triangles)
      fail("the decoded counts differ from the encoded ones",
           std::to_string(vertices) + " vertices, " + std::to_string(triangles) + " triangles",
           std::to_string(dv) + " vertices, " + std::to_string(dt) + " triangles decoded");
    psq::MeshBuffers mesh;
    s = psq::decode_mesh(hinted.bytes.data(), hinted.bytes.size(), &mesh);
    if (!s.ok()) psq::fuzz::die("decode_mesh rejects an accepted sequence", s);
  }
  return 0;
}
