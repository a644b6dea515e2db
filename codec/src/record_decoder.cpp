// SPDX-License-Identifier: Apache-2.0
// codec/src/record_decoder.cpp: the decoder's records (spec section 13).
// The boundary is a FastBoundary: every edge a triangle completes is named
// by its record (the gate, the gate's neighbours, or a slot in an escape),
// so the decoder keeps no lookups by endpoints (13.6.3). The record
// functions are templates over the symbol decoder of the stream's entropy
// back-end (symbol_coder.h, 13.2): a rANS table lookup, or a walk down an
// adaptive bit-tree with the range coder.
#include <cmath>
#include <algorithm>

#include "decoder_impl.h"
#include "geometry.h"

#if defined(__linux__) && !defined(PSQ_NO_POPULATE)
#include <errno.h>
#include <sys/mman.h>
#include <unistd.h>

#include <atomic>
#endif

namespace psq {

namespace {

// Asks the kernel to back the whole pages within the `bytes` bytes at `p`
// with memory now, writable, in one call (Linux's MADV_POPULATE_WRITE),
// instead of one page fault at each page's first write. A hint: nothing
// happens where the kernel lacks it (before Linux 5.14; after the first
// refusal it is not asked again), on other systems, or when psq is built
// with PSQ_NO_POPULATE defined (for sandboxes whose system call filter
// kills a process on an advice it does not list); the memory's contents
// are unchanged either way. Worth it only for memory about to be written
// in full: decode_mesh()'s arrays, whose pages cost far less populated in
// one call than faulted in one at a time (bench/HISTORY.md, "Arrays not
// zeroed, pages populated").
void populate_for_write(void* p, size_t bytes) {
#if defined(__linux__) && !defined(PSQ_NO_POPULATE)
#ifdef MADV_POPULATE_WRITE
  constexpr int kPopulateWrite = MADV_POPULATE_WRITE;
#else
  constexpr int kPopulateWrite = 23;  // Linux's value, for C library headers that predate it
#endif
  // After a refusal that will not change (a kernel before 5.14: EINVAL; a
  // sandbox that filters the call: ENOSYS or EPERM), no more calls.
  static std::atomic<bool> refused{false};
  if (refused.load(std::memory_order_relaxed)) return;
  static const uintptr_t page = static_cast<uintptr_t>(sysconf(_SC_PAGESIZE));
  if (page == 0 || (page & (page - 1)) != 0) return;
  const uintptr_t begin = (reinterpret_cast<uintptr_t>(p) + page - 1) & ~(page - 1);
  const uintptr_t end = (reinterpret_cast<uintptr_t>(p) + bytes) & ~(page - 1);
  if (end <= begin) return;
  if (madvise(reinterpret_cast<void*>(begin), end - begin, kPopulateWrite) != 0 &&
      (errno == EINVAL || errno == ENOSYS || errno == EPERM))
    refused.store(true, std::memory_order_relaxed);
#else
  (void)p;
  (void)bytes;
#endif
}

PSQ_INLINE uint64_t get_raw(RawReader& raw, int bits) {
  if (bits > 32) {
    const uint64_t low = raw.get(32);
    return low | static_cast<uint64_t>(raw.get(bits - 32)) << 32;
  }
  return raw.get(bits);
}

// A join's third vertex, or an escape's old one (spec 13.7.3, 13.7.5):
// the open edge J's slot, then the side (x = org(J) or dst(J)), from the
// raw bits; J into bt->join_edge. kNone when J is not an open edge.
uint32_t named_vertex(const FastBoundary& b, RawReader& bits, int sbits, BTriangle* bt) {
  const uint32_t j = bits.get(sbits);
  const bool side = bits.get(1) != 0;
  if (!b.edge_live(j)) return kNone;
  bt->join_edge = j;
  return side ? b.edge(j).dst : b.edge(j).org;
}

}  // namespace

Status PsqDecoder::Impl::open_records() {
  auto bad = [&](const std::string& what, uint64_t at) {
    return Status(ErrorCode::kBadValue, "record section: " + what, conn_offset + at);
  };
  if (!rans) {
    // Spec 13.2, adaptive back-end: the range coder's bytes, then the raw
    // block; the models start afresh.
    uint64_t range_bytes = 0;
    const int n = parse_varint(cdata, csize, &range_bytes);
    if (n <= 0) return bad("malformed range coder block length", 0);
    const size_t at = static_cast<size_t>(n);
    if (range_bytes > csize - at) return bad("block length exceeds the section", 0);
    reset_adaptive_models(&fmodels);
    fadaptive = std::make_unique<AdaptiveSymbolDecoder>(cdata + at, range_bytes, fmodels.data(), measure);
    const size_t raw_at = at + range_bytes;
    fraw = std::make_unique<RawReader>(cdata + raw_at, csize - raw_at);
    fraw_total_bits = 8 * static_cast<uint64_t>(csize - raw_at);
    fraw_geometry_bits = 0;
    return Status();
  }
  RansSection sec;
  if (const char* why = split_rans_section(cdata, csize, &sec)) return bad(why, 0);
  const size_t at = sec.tables_at;
  RawReader tables(sec.tables, sec.table_bytes);
  bool present[kFastTables];
  for (int i = 0; i < kFastTables; ++i) present[i] = tables.get(1) != 0;
  for (int i = 0; i < kFastTables; ++i) {
    if (!present[i]) {
      // Spec 13.5.2: an absent table decodes no symbol of its alphabet.
      if (!ftable_absent[i]) ftables[i].set_absent();
      ftable_absent[i] = true;
      continue;
    }
    ftable_absent[i] = false;
    const uint64_t before = tables.consumed_bits();
    if (!ftables[i].read(tables, fast_table_size(i))) return bad("table " + std::to_string(i) + " is invalid", at);
    if (measure) cost[fast_table_cost(i)] += static_cast<double>(tables.consumed_bits() - before);
  }
  if (measure) {
    cost[kCostConnectivity] += kFastTables;  // the presence bits
    fsymbol_cost.assign(size_t{kFastTables} * kFastSymbolStride, 0.0);
    for (int i = 0; i < kFastTables; ++i) {
      const RansTable& t = ftables[i];
      for (int sym = 0; sym < t.size(); ++sym) {
        if (t.freq(sym) != 0) fsymbol_cost[i * kFastSymbolStride + sym] = kRansScaleBits - std::log2(t.freq(sym));
      }
    }
  }
  if (!tables.at_clean_end()) return bad("the table block does not end with its last table", at);
  frans = std::make_unique<RansSymbolDecoder>(sec.rans, sec.rans_bytes, ftables.data());
  fraw = std::make_unique<RawReader>(sec.raw, sec.raw_bytes);
  fraw_total_bits = 8 * static_cast<uint64_t>(sec.raw_bytes);
  fraw_geometry_bits = 0;
  return Status();
}

Status PsqDecoder::Impl::close_records() {
  const bool overran = rans ? frans->overran() : fadaptive->overran();
  if (overran || fraw->overran())
    return Status(ErrorCode::kTruncated, "coded records end early", conn_offset + csize);
  if (!(rans ? frans->at_clean_end() : fadaptive->at_clean_end()))
    return Status(ErrorCode::kBadValue, "the symbol block does not end where the chunk's records do", conn_offset);
  if (!fraw->at_clean_end())
    return Status(ErrorCode::kBadValue, "the raw bits do not end where the chunk's records do", conn_offset);
  // The raw bits that no position residual read: slots, kinds, signs of
  // distances (and the last word's padding).
  if (measure) {
    cost[kCostGeometry] += fraw_geometry_bits;
    cost[kCostConnectivity] += static_cast<double>(fraw_total_bits) - fraw_geometry_bits;
  }
  return Status();
}

namespace {

// What a length symbol below the escape fixes of a residual (spec
// 13.8.3): the magnitude's leading bits, how many low bits follow raw, and how
// many raw bits to read (those and the sign, none for a zero).
struct LengthCode {
  uint32_t lead;
  uint8_t low_bits;
  uint8_t raw_bits;
  uint8_t length;
};

struct LengthCodes {
  LengthCode c[kFastLengthEscape];
  LengthCodes() {
    for (int s = 0; s < kFastLengthEscape; ++s) {
      LengthCode& e = c[s];
      const int len = s < 2 ? s : (s + 2) >> 1;
      e.length = static_cast<uint8_t>(len);
      e.low_bits = static_cast<uint8_t>(len >= 2 ? len - 2 : 0);
      e.raw_bits = static_cast<uint8_t>(len == 0 ? 0 : e.low_bits + 1);
      e.lead = len == 0 ? 0 : len == 1 ? 1 : (3u - static_cast<uint32_t>(~s & 1)) << (len - 2);
    }
  }
};
const LengthCodes kLengthCodes;

// The residual of a length code below the escape and its raw value `v`
// (the low bits, then the sign), without branches on the symbol.
PSQ_INLINE int64_t residual_of_code(const LengthCode& e, uint32_t v) {
  const uint64_t mag = e.lead | (v & ((uint32_t{1} << e.low_bits) - 1));
  const uint64_t neg = 0 - static_cast<uint64_t>((v >> e.low_bits) & 1);
  return static_cast<int64_t>((mag ^ neg) - neg);
}

}  // namespace

template <class D>
PSQ_INLINE bool PsqDecoder::Impl::fast_residual(D& d, RawReader& rawbits, int table, int64_t* r, int* k,
                                                bool measure_it) {
  const int s = d.decode(table);
  if (measure_it) {
    measure_symbol(d, table, s);
    // A position's raw bits are geometry; the rest of the raw block is
    // connectivity (close_records).
    if (table != kFastTableDistance && s <= kFastLengthEscape)
      fraw_geometry_bits += s < kFastLengthEscape ? kLengthCodes.c[s].raw_bits : 0;
    if (s == kFastLengthEscape && table != kFastTableDistance) measure_escape = true;
  }
  return residual_of_symbol(rawbits, s, r, k);
}

PSQ_INLINE bool PsqDecoder::Impl::residual_of_symbol(RawReader& rawbits, int s, int64_t* r, int* k) {
  if (s < kFastLengthEscape) {
    // Without branches on the symbol: the table gives the leading bits,
    // and the raw bits the low ones and the sign (zero reads none).
    const LengthCode& e = kLengthCodes.c[s];
    *k = e.length;
    *r = residual_of_code(e, rawbits.get(e.raw_bits));
    return true;
  }
  if (s > kFastLengthEscape) return false;
  const int len = 33 + static_cast<int>(rawbits.get(5));
  const uint64_t second = rawbits.get(1);
  *k = len;
  if (measure_escape) {
    fraw_geometry_bits += 5 + 1 + (len - 2) + 1;
    measure_escape = false;
  }
  const uint64_t mag = uint64_t{1} << (len - 1) | second << (len - 2) | get_raw(rawbits, len - 2);
  if (rawbits.get(1) == 0) {
    if (mag >= uint64_t{1} << 63) return false;  // +2^63 is not an i64 (spec 5.6)
    *r = static_cast<int64_t>(mag);
  } else {
    *r = static_cast<int64_t>(0 - mag);
  }
  return true;
}

PSQ_INLINE Status PsqDecoder::Impl::vertex_room() {
  if (seen_vertices >= chunk_vertices) return corrupt("more vertices than the chunk declares");
  if (next_out >= 0xffffffffull) return Status(ErrorCode::kLimit, "more than 4294967295 vertices", conn_offset);
  return Status();
}

Status PsqDecoder::Impl::early_end() const {
  return Status(ErrorCode::kTruncated, "record " + std::to_string(record_no) + ": coded data ends early",
                conn_offset + csize);
}

template <class D>
PSQ_INLINE Status PsqDecoder::Impl::fast_position(D& d, RawReader& bits, const int64_t pred[3], int kind,
                                                  const int extent[3], int64_t pos[3], bool measure_it) {
  if (kind != kPredOther) {
    // A predicted vertex's three length contexts are its extents (13.8.1),
    // so its three symbols decode first and its raw bits, which follow each
    // other in the raw block, come in one read when they fit (they do
    // unless a residual is long): one refill instead of three.
    int s[3];
    for (int i = 0; i < 3; ++i) {
      const int table = fast_length_table(kind, i, fast_length_context(kind, i, extent[i], 0));
      s[i] = d.decode(table);
      if (measure_it) measure_symbol(d, table, s[i]);
    }
    if (__builtin_expect((s[0] | s[1] | s[2]) < kFastLengthEscape, 1)) {
      const LengthCode* e[3] = {&kLengthCodes.c[s[0]], &kLengthCodes.c[s[1]], &kLengthCodes.c[s[2]]};
      const int total = e[0]->raw_bits + e[1]->raw_bits + e[2]->raw_bits;
      if (__builtin_expect(total <= 56, 1)) {
        if (measure_it) fraw_geometry_bits += total;
        uint64_t w = bits.get_wide(total);
        for (int i = 0; i < 3; ++i) {
          const uint32_t v = static_cast<uint32_t>(w & ((uint64_t{1} << e[i]->raw_bits) - 1));
          w >>= e[i]->raw_bits;
          pos[i] = wrap_add(pred[i], residual_of_code(*e[i], v));
        }
        return Status();
      }
    }
    for (int i = 0; i < 3; ++i) {
      int64_t r;
      int k;
      if (measure_it) {
        // As fast_residual() measures a position's residual.
        if (s[i] < kFastLengthEscape) fraw_geometry_bits += kLengthCodes.c[s[i]].raw_bits;
        else if (s[i] == kFastLengthEscape) measure_escape = true;
      }
      if (!residual_of_symbol(bits, s[i], &r, &k)) return corrupt("bad residual");
      pos[i] = wrap_add(pred[i], r);
    }
    return Status();
  }
  int lengths[3] = {0, 0, 0};
  for (int i = 0; i < 3; ++i) {
    int64_t r;
    const int c = fast_length_context(kind, i, extent[i], std::max(lengths[0], lengths[1]));
    if (!fast_residual(d, bits, fast_length_table(kind, i, c), &r, &lengths[i], measure_it)) return corrupt("bad residual");
    pos[i] = wrap_add(pred[i], r);
  }
  return Status();
}

template <class D>
Status PsqDecoder::Impl::vertex_begin(bool reappears, SequenceEvent* ev) {
  PSQ_RETURN_IF_ERROR(vertex_room());
  SequenceVertex& v = ev->vertex;
  ev->kind = SequenceEvent::Kind::kVertex;
  v.index = static_cast<uint32_t>(next_out);
  v.slot = kNoSlot;
  v.reappears = kNoVertex;
  if (reappears) {
    int64_t d;
    int length;
    if (!fast_residual(coder<D>(), *fraw, kFastTableDistance, &d, &length, measure) || d < 0 || static_cast<uint64_t>(d) >= next_out)
      return corrupt("re-appearance of a vertex that does not exist");
    v.reappears = static_cast<uint32_t>(next_out - 1 - static_cast<uint64_t>(d));
  }
  return Status();
}

template <class D>
PSQ_INLINE Status PsqDecoder::Impl::vertex_position(const int64_t pred[3], int kind, const int extent[3], int64_t pos[3],
                                              SequenceEvent* ev) {
  PSQ_RETURN_IF_ERROR(fast_position(coder<D>(), *fraw, pred, kind, extent, pos, measure));
  SequenceVertex& v = ev->vertex;
  if (const char* why = position_of(pos, v.position)) return corrupt(why);
  for (int i = 0; i < 3; ++i) last_pos[i] = pos[i];
  props->next_vertex(&v.values);
  ++seen_vertices;
  ++next_out;
  ++stats.vertices;
  return Status();
}

// The common records: an add, a fill on the gate's neighbour or a join,
// every new edge entering, or an end, no rotation (B symbols 0, 27, 30, 18
// and 33: common_b(); spec 13.7), after
// their class and B symbol. The general path (decode_record) would do
// the same in more steps. kDirect: decode_mesh's loop, which writes the
// arrays itself (a stream without properties); otherwise the record's
// events are queued.
template <bool kDirect, class D>
PSQ_INLINE Status PsqDecoder::Impl::common_record(D& d, RawReader& bits, int cls, int bsym, uint32_t gate,
                                                DirectCursor* out) {
  FastBoundary& b = fboundary;
  const BEdge& g = b.edge(gate);
  const uint32_t p = g.org, q = g.dst;
  if (bsym == 0) {
    // An add: the new vertex x, then the triangle (q, p, x).
    fast_context = fast_a_context_gate(cls, kFastNew);
    PSQ_RETURN_IF_ERROR(vertex_room());
    // Across the gate (spec 13.8.2), or by a decoded choice when the stream
    // codes choices (fast_codes_choices(): lossless or the adaptive
    // back-end; the same for the whole stream: a branch that is predicted).
    int choice = kChoiceGate;
    if (fast_choices) {
      const uint32_t mask = prediction_choices(b, gate);
      if (mask != 0) {
        const int table = fast_choice_table(mask, fast_choice);
        choice = d.decode(table);
        if (!kDirect && measure) measure_symbol(d, table, choice);
        if (!fast_choice_allowed(mask, choice)) return corrupt("prediction choice " + std::to_string(choice));
        fast_choice = choice;
      }
    }
    ++stats.predictions[choice];
    // Initialized from either call, not assigned after: an assignment
    // copies the struct through the stack, its halves stored apart and
    // loaded together, a store-forwarding stall on every add.
    const Prediction pr = fast_choices ? predict_new_vertex(b, gate, 0, last_pos, nullptr, nullptr, choice)
                                       : predict_across_gate(b, gate);
    int64_t pos[3];
    PSQ_RETURN_IF_ERROR(fast_position(d, bits, pr.pos, pr.kind, pr.extent, pos, !kDirect && measure));
    double xyz[3];
    if (kDirect) {
      if (out->vroom == 0 && !direct_grow(*out)) return direct_overflow();
      float* f = out->pos + 3 * out->verts;
      if (direct_float) {
        if (const char* why = direct_position(pos, f)) return corrupt(why);
      } else {
        if (const char* why = position_of(pos, xyz)) return corrupt(why);
        for (int i = 0; i < 3; ++i) f[i] = static_cast<float>(xyz[i]);
      }
    } else {
      if (const char* why = position_of(pos, xyz)) return corrupt(why);
    }
    const uint32_t index = static_cast<uint32_t>(next_out);
    for (int i = 0; i < 3; ++i) last_pos[i] = pos[i];
    ++seen_vertices;
    ++next_out;
    ++stats.vertices;
    // Direct: the vertex's mesh index rides in its slot's key.
    const uint32_t at = kDirect ? static_cast<uint32_t>(out->verts) : 0;
    const uint32_t s = b.new_vertex(index, at, pos);
    if (s == kNone) return Status(ErrorCode::kLimit, "more active vertices than the header's boundary limit", conn_offset);
    if (d.overran() || bits.overran()) return early_end();
    const uint32_t f1 = b.lean_add(gate, s);
    if (f1 == kNone) return Status(ErrorCode::kLimit, "more open edges than the header's boundary limit", conn_offset);
    const uint32_t f2 = b.edge(f1).next;
    ring.push(b, f1);
    ring.push(b, f2);
    fneighbors.add_vertex(s, p, q);
    ++seen_triangles;
    ++stats.triangles;
    if (kDirect) {
      // The position is written; its index, and the triangle.
      ++out->verts;
      if (!direct_identity) direct_index.push_back(at);
      uint32_t* t = out->idx + out->ni;
      t[0] = b.vertex(q).key;
      t[1] = b.vertex(p).key;
      t[2] = at;
      out->ni += 3;
      --out->vroom;
      --out->troom;
      return Status();
    }
    SequenceEvent& ev = push();
    ev.kind = SequenceEvent::Kind::kVertex;
    SequenceVertex& v = ev.vertex;
    v.index = index;
    v.slot = s;
    v.reappears = kNoVertex;
    for (int i = 0; i < 3; ++i) v.position[i] = xyz[i];
    props->next_vertex(&v.values);
    const uint32_t corner[3] = {q, p, s}, eslot[3] = {gate, f1, f2};
    push_triangle(Op::kAdd, corner, eslot, 4, 0, 1, 6);
    return Status();
  }
  if (bsym == kFastBEnd || bsym == kFastBJoin) return end_or_join_record<kDirect, D>(d, bits, cls, bsym, gate, out);
  // A fill: "left" (x starts the edge before the gate; edge 1 completes
  // it, edge 2 enters) or "right" (x ends the edge after it).
  const bool left = bsym == 27;
  fast_context = fast_a_context_gate(cls, left ? kFastLeft : kFastRight);
  const uint32_t c = left ? g.prev : g.next;
  if (c == kNone) return corrupt(left ? "no boundary edge before the gate" : "no boundary edge after the gate");
  const uint32_t x = left ? b.edge(c).org : b.edge(c).dst;
  if (x == p || x == q) return corrupt("triangle repeats a vertex");
  const uint32_t from = left ? x : p, to = left ? q : x;  // the entering edge
  if (fneighbors.contains(from, to))
    return corrupt("an entering edge is open already, completes an edge the record does not name, or is dead");
  if (d.overran() || bits.overran()) return early_end();
  uint32_t final;
  const uint32_t f = b.lean_fill(gate, left, &final);
  if (f == kNone) return Status(ErrorCode::kLimit, "more open edges than the header's boundary limit", conn_offset);
  ring.push(b, f);
  fneighbors.insert(from, to);
  ++seen_triangles;
  ++stats.triangles;
  const uint32_t corner[3] = {q, p, x};
  if (kDirect) {
    uint32_t* t = out->idx + out->ni;
    for (int k = 0; k < 3; ++k) t[k] = b.vertex(corner[k]).key;
    out->ni += 3;
    --out->troom;
    if (final) {
      for (int k = 0; k < 3; ++k)
        if (final >> k & 1) b.free_vertex(corner[k]);
    }
    return Status();
  }
  const int enters = left ? 2 : 1, completes = 3 - enters;
  uint32_t eslot[3];
  eslot[0] = gate;
  eslot[completes] = c;
  eslot[enters] = f;
  push_triangle(Op::kFill, corner, eslot, 0, static_cast<uint8_t>(final), static_cast<uint8_t>(1 | 1 << completes),
                static_cast<uint8_t>(1 << enters));
  return Status();
}

// An end (B symbol 33: the gate's neighbours meet at x, and all three
// edges complete) or a join whose two new edges enter (B symbol 18: x from
// an open edge named by slot in the raw bits), as decode_record()
// decodes them, with the same checks in the same order, and written
// straight to the arrays (kDirect) or as events. Joins and ends are rare,
// but through the general path and its events they would cost decoding
// into arrays far more than their share (bench/HISTORY.md, "The decoder's
// memory").
template <bool kDirect, class D>
__attribute__((noinline)) Status PsqDecoder::Impl::end_or_join_record(D& d, RawReader& bits, int cls, int bsym, uint32_t gate,
                                          DirectCursor* out) {
  FastBoundary& b = fboundary;
  const BEdge& g = b.edge(gate);
  const uint32_t p = g.org, q = g.dst;
  BTriangle bt;
  uint32_t x;
  Op op;
  if (bsym == kFastBEnd) {
    const uint32_t c1 = g.prev, c2 = g.next;
    if (c1 == kNone || c2 == kNone || c1 == c2 || b.edge(c1).org != b.edge(c2).dst)
      return corrupt("an end on a gate whose neighbours do not meet");
    x = b.edge(c1).org;
    bt.completes[1] = c1;
    bt.completes[2] = c2;
    bt.state[1] = bt.state[2] = EdgeState::kCompletes;
    fast_context = fast_a_context_gate(cls, kFastEnd);
    op = Op::kEnd;
  } else {
    x = named_vertex(b, bits, slot_bits(b.edge_capacity()), &bt);
    if (x == kNone) return corrupt("join names an edge that is not open");
    fast_context = fast_a_context_gate(cls, kFastJoin);
    op = Op::kJoin;
  }
  if (x == p || x == q) return corrupt("triangle repeats a vertex");
  bt.c[0] = q;
  bt.c[1] = p;
  bt.c[2] = x;
  bt.gate = gate;
  bt.completes[0] = gate;
  bt.state[0] = EdgeState::kCompletes;
  // A join's new edges p->x and x->q, between old vertices, must be new
  // (spec 13.6.3), edge 1 checked first.
  if (op == Op::kJoin)
    for (int k = 1; k < 3; ++k)
      if (fneighbors.contains(bt.c[k], bt.c[k == 2 ? 0 : k + 1]))
        return corrupt("an entering edge is open already, completes an edge the record does not name, or is dead");
  if (d.overran() || bits.overran()) return early_end();
  if (!b.apply(bt)) return Status(ErrorCode::kLimit, "more open edges than the header's boundary limit", conn_offset);
  if (op == Op::kJoin)
    for (int k = 1; k < 3; ++k) {
      ring.push(b, bt.eslot[k]);
      fneighbors.insert(bt.c[k], bt.c[k == 2 ? 0 : k + 1]);
    }
  const uint8_t final_mask = static_cast<uint8_t>(bt.final[0] | bt.final[1] << 1 | bt.final[2] << 2);
  ++seen_triangles;
  ++stats.triangles;
  if (kDirect) {
    uint32_t* t = out->idx + out->ni;
    for (int k = 0; k < 3; ++k) t[k] = b.vertex(bt.c[k]).key;
    out->ni += 3;
    --out->troom;
    // Spec 6.4: finalized slots freed in canonical corner order.
    for (int k = 0; k < 3; ++k)
      if (final_mask >> k & 1) b.free_vertex(bt.c[k]);
    return Status();
  }
  push_triangle(op, bt.c, bt.eslot, 0, final_mask, op == Op::kEnd ? 7 : 1, op == Op::kEnd ? 0 : 6);
  return Status();
}

void PsqDecoder::Impl::push_triangle(Op op, const uint32_t corner[3], const uint32_t eslot[3], uint8_t new_mask,
                                     uint8_t final_mask, uint8_t leaving, uint8_t entering) {
  FastBoundary& b = fboundary;
  SequenceEvent& ev = push();
  ev.kind = SequenceEvent::Kind::kTriangle;
  SequenceTriangle& t = ev.triangle;
  t.op = op;
  for (int k = 0; k < 3; ++k) {
    t.v[k] = b.vertex(corner[k]).index;
    t.vslot[k] = corner[k];
    t.eslot[k] = eslot[k];
  }
  t.new_mask = new_mask;
  t.final_mask = final_mask;
  t.border_mask = 0;
  t.nonmanifold_mask = 0;
  t.leaving_mask = leaving;
  t.entering_mask = entering;
  props->next_face(&t.values);
  if (final_mask) {
    // Spec 6.4: finalization events and freed slots in corner order.
    for (int k = 0; k < 3; ++k)
      if (final_mask >> k & 1) {
        SequenceEvent& fin = push();
        fin.kind = SequenceEvent::Kind::kFinalize;
        fin.finalized = t.v[k];
      }
    for (int k = 0; k < 3; ++k)
      if (final_mask >> k & 1) b.free_vertex(corner[k]);
  }
}

template <class D>
Status PsqDecoder::Impl::decode_record(int cls, uint32_t gate, int bsym) {
  D& d = coder<D>();
  RawReader& bits = *fraw;
  FastBoundary& b = fboundary;
  if (cls < 0) cls = fast_symbol(d, kFastTableA + fast_context);
  if (cls >= kFastClasses) return corrupt("record class " + std::to_string(cls));
  const uint32_t R = b.reference();
  if (cls == kFastIsolated) {
    fast_context = kFastAContexts - 2;
    ++stats.gates[3];
    SequenceEvent& ev = push();
    const bool reappears = bits.get(1) != 0;
    int64_t pos[3];
    const int64_t pred[3] = {last_pos[0], last_pos[1], last_pos[2]};
    const int no_extent[3] = {0, 0, 0};
    PSQ_RETURN_IF_ERROR(vertex_begin<D>(reappears, &ev));
    PSQ_RETURN_IF_ERROR(vertex_position<D>(pred, kPredOther, no_extent, pos, &ev));
    SequenceEvent& fin = push();
    fin.kind = SequenceEvent::Kind::kFinalize;
    fin.finalized = ev.vertex.index;
    return Status();
  }
  if (seen_triangles >= chunk_triangles) return corrupt("more triangles than the chunk declares");
  // A gate record: its gate and B symbol first, for the common path.
  if (cls <= kFastGateFar && bsym < 0) {
    if (cls == kFastGateFar) {
      const int rank = fast_symbol(d, kFastTableRank + (R == kNone ? 1 : 0));
      if (rank >= kFastRanks) return corrupt("far gate rank " + std::to_string(rank));
      gate = ring.ranked(b, static_cast<uint32_t>(rank));
      if (gate == kNone) return corrupt("far gate rank beyond the open edges of the ring");
      ++stats.gates[2];
      ++stats.far_gates[0];
    } else {
      if (R == kNone) return corrupt("gate offset without a reference edge");
      gate = cls == kFastGateR ? R : cls == kFastGateNext ? b.edge(R).next : b.edge(R).prev;
      if (gate == kNone) return corrupt("gate offset leaves the boundary");
      ++stats.gates[cls == kFastGateR ? 0 : 1];
    }
    const BEdge& g = b.edge(gate);
    bsym = fast_symbol(d, fast_b_table(third_context(b.vertex(g.org).degree, b.vertex(g.dst).degree),
                                       D::kAdaptive ? shape_context(b, gate) : 0));
    if (bsym >= kFastBSymbols) return corrupt("third-vertex symbol " + std::to_string(bsym));
    if (!header.rotation && common_b(bsym)) return common_record<false>(d, *fraw, cls, bsym, gate, nullptr);
  }
  BTriangle bt;
  uint32_t intro[3];
  int nintro = 0;
  int e[3] = {kFastEnters, kFastEnters, kFastEnters};  // states of edges that do not complete
  bool completes[3] = {false, false, false};
  uint32_t reappear_mask = 0;  // by introduction order
  bool choice_allowed = false;
  const int sbits = slot_bits(b.edge_capacity());
  if (cls == kFastStart) {
    const int s = fast_symbol(d, kFastTableS);
    if (s >= kFastSSymbols) return corrupt("start symbol " + std::to_string(s));
    const int m = fast_symbol(d, kFastTableReappear);
    if (m >= 8) return corrupt("start re-appearance symbol " + std::to_string(m));
    reappear_mask = static_cast<uint32_t>(m);
    e[0] = s % 3;
    e[1] = s / 3 % 3;
    e[2] = s / 9 % 3;
    const bool swap = s >= 27;
    intro[0] = 0;
    intro[1] = swap ? 2 : 1;
    intro[2] = swap ? 1 : 2;
    nintro = 3;
    for (int k = 0; k < 3; ++k) bt.is_new[k] = true;
    fast_context = kFastAStartContext;
    ++stats.gates[3];
  } else {
    uint32_t x = kNone;
    int xkind = 0;  // 0 new, 1 new re-appearing, 2 old
    if (cls == kFastEscape) {
      gate = bits.get(sbits);
      if (!b.edge_live(gate)) return corrupt("escaped gate is not an open edge");
      xkind = static_cast<int>(bits.get(2));
      if (xkind == 3) return corrupt("escaped third vertex kind 3");
      if (xkind == 2) {
        x = named_vertex(b, bits, sbits, &bt);
        if (x == kNone) return corrupt("escaped third vertex names an edge that is not open");
      }
      for (int k = 1; k < 3; ++k) {
        const uint32_t st = bits.get(2);
        if (st == 3) {
          if (xkind != 2) return corrupt("an edge of a new vertex completes an open edge");
          bt.completes[k] = bits.get(sbits);
          completes[k] = true;
        } else {
          e[k] = static_cast<int>(st);
        }
      }
      fast_context = kFastAContexts - 1;
      ++stats.gates[2];
      ++stats.far_gates[1];
    } else {
      const BEdge& g = b.edge(gate);
      int third;
      fast_b_split(bsym, &third, &e[1], &e[2]);
      switch (third) {
        case kFastNew: xkind = 0; break;
        case kFastNewReappears: xkind = 1; break;
        case kFastLeft:
          if (g.prev == kNone) return corrupt("no boundary edge before the gate");
          x = b.edge(g.prev).org;
          bt.completes[1] = g.prev;
          completes[1] = true;
          xkind = 2;
          break;
        case kFastRight:
          if (g.next == kNone) return corrupt("no boundary edge after the gate");
          x = b.edge(g.next).dst;
          bt.completes[2] = g.next;
          completes[2] = true;
          xkind = 2;
          break;
        case kFastEnd:
          if (g.prev == kNone || g.next == kNone || g.prev == g.next || b.edge(g.prev).org != b.edge(g.next).dst)
            return corrupt("an end on a gate whose neighbours do not meet");
          x = b.edge(g.prev).org;
          bt.completes[1] = g.prev;
          bt.completes[2] = g.next;
          completes[1] = completes[2] = true;
          xkind = 2;
          break;
        default:  // join
          x = named_vertex(b, bits, sbits, &bt);
          if (x == kNone) return corrupt("join names an edge that is not open");
          xkind = 2;
      }
      fast_context = fast_a_context_gate(cls, third);
      choice_allowed = xkind != 2;
    }
    const BEdge& g = b.edge(gate);
    const uint32_t p = g.org, q = g.dst;
    if (xkind == 2 && (x == p || x == q)) return corrupt("triangle repeats a vertex");
    bt.c[0] = q;
    bt.c[1] = p;
    bt.c[2] = x;
    bt.gate = gate;
    bt.completes[0] = gate;
    completes[0] = true;
    // An escape names its completions by slot: each must be the open twin
    // of its edge (spec 13.7.5; the fast boundary has no other check).
    for (int k = 1; k < 3; ++k)
      if (completes[k] && cls == kFastEscape) {
        const uint32_t c = bt.completes[k];
        if (!b.edge_live(c) || b.edge(c).org != bt.c[(k + 1) % 3] || b.edge(c).dst != bt.c[k] || c == gate ||
            (k == 2 && completes[1] && bt.completes[1] == c))
          return corrupt("an escaped completion is not the open twin of its edge");
      }
    if (xkind != 2) {
      bt.is_new[2] = true;
      intro[0] = 2;
      nintro = 1;
      reappear_mask = xkind == 1 ? 1u : 0u;
    }
  }
  uint32_t r = 0;
  if (header.rotation) {
    r = static_cast<uint32_t>(fast_symbol(d, kFastTableRotation));
    if (r > 2) return corrupt("rotation above 2");
  }
  // New vertices in the order of introduction (spec 6.3).
  int64_t first[3] = {0, 0, 0}, second[3] = {0, 0, 0};
  for (int i = 0; i < nintro; ++i) {
    const int k = static_cast<int>(intro[i]);
    SequenceEvent& ev = push();
    // The distance, the choice, the residuals: the encoder's order.
    PSQ_RETURN_IF_ERROR(vertex_begin<D>((reappear_mask >> i) & 1, &ev));
    int choice = kChoiceGate;
    Prediction pr;
    int64_t pos[3];
    if (nintro == 1) {
      const uint32_t mask = choice_allowed && fast_choices ? prediction_choices(b, gate) : 0;
      if (mask != 0) {
        choice = fast_symbol(d, fast_choice_table(mask, fast_choice));
        if (!fast_choice_allowed(mask, choice))
          return corrupt("prediction choice " + std::to_string(choice));
        fast_choice = choice;
      }
      ++stats.predictions[choice];
      pr = predict_new_vertex(b, gate, 0, last_pos, first, second, choice);
    } else {
      pr = predict_new_vertex(b, kNone, i, last_pos, first, second);
    }
    PSQ_RETURN_IF_ERROR(vertex_position<D>(pr.pos, pr.kind, pr.extent, pos, &ev));
    for (int a = 0; a < 3; ++a) (i == 0 ? first : second)[a] = pos[a];
    const uint32_t s = b.new_vertex(ev.vertex.index, 0, pos);
    if (s == kNone) return Status(ErrorCode::kLimit, "more active vertices than the header's boundary limit", conn_offset);
    fneighbors.vertex_begins(s);
    ev.vertex.slot = s;
    bt.c[k] = s;
  }
  // Edge states (spec 13.7.8): named completions, else entering or a
  // border, a cut border setting the non-manifold flag.
  uint8_t cut = 0;
  int completed = 0;
  for (int k = 0; k < 3; ++k) {
    if (completes[k]) {
      bt.state[k] = EdgeState::kCompletes;
      ++completed;
      continue;
    }
    bt.completes[k] = kNone;
    bt.border[k] = e[k] != kFastEnters;
    bt.state[k] = bt.border[k] ? EdgeState::kBorder : EdgeState::kEnters;
    if (e[k] == kFastCut) cut |= static_cast<uint8_t>(1u << k);
  }
  // Entering edges and borders between old vertices must be new to the
  // mesh (spec 13.6.3): the fast boundary is told which edges complete,
  // and Neighbors checks the others.
  for (int k = 0; k < 3; ++k)
    if (!completes[k] && !bt.is_new[k] && !bt.is_new[(k + 1) % 3] && fneighbors.contains(bt.c[k], bt.c[(k + 1) % 3]))
      return corrupt("an entering edge is open already, completes an edge the record does not name, or is dead");
  const int nnew = bt.is_new[0] + bt.is_new[1] + bt.is_new[2];
  const Op op = nnew == 3 ? Op::kStart
                : completed == 1 ? (nnew == 1 ? Op::kAdd : Op::kJoin)
                : completed == 2 ? Op::kFill
                                 : Op::kEnd;
  if (d.overran() || bits.overran()) return early_end();
  if (!b.apply(bt)) return Status(ErrorCode::kLimit, "more open edges than the header's boundary limit", conn_offset);
  for (int k = 0; k < 3; ++k) {
    if (bt.state[k] == EdgeState::kEnters) ring.push(b, bt.eslot[k]);
    if (bt.state[k] != EdgeState::kCompletes) fneighbors.insert(bt.c[k], bt.c[(k + 1) % 3]);
  }
  emit_triangle(b, bt, op, r, cut);
  return Status();
}

template <class D>
Status PsqDecoder::Impl::direct_records() {
  FastBoundary& b = fboundary;
  // The coders' states live in locals for the loop, so that the compiler
  // can keep them in registers: as members they would be reloaded after
  // every store to the output arrays, which might alias them. They go back
  // to the members around every call that decodes through the members.
  D d = coder<D>();
  RawReader bits = *fraw;
  MeshBuffers& mesh = *direct;
  // Room for the chunk's declared counts, but for no more than four
  // vertices or triangles per coded byte and 2^21 in all, so that a hostile
  // count allocates at most a bounded multiple of the bytes actually read
  // (a symbol can cost far less than a bit) and never more than 48 MiB: a
  // chunk that holds more grows the arrays geometrically (direct_room).
  // Real chunks take 1 to 8 bytes per triangle, and a chunk of the default
  // size (2^20 coded bytes) about half a million triangles (a cap of half
  // a triangle per byte would make the arrays of most meshes grow once:
  // a copy and twice the pages).
  // The room is populated at once (populate_for_write()): honest records
  // write all of it.
  const uint64_t cap = std::min<uint64_t>(4 * static_cast<uint64_t>(csize) + 64, uint64_t{1} << 21);
  const size_t ni = 3 * static_cast<size_t>(std::min<uint64_t>(chunk_triangles, cap));
  const size_t np = 3 * static_cast<size_t>(std::min<uint64_t>(chunk_vertices, cap));
  if (!direct_fixed) {
    populate_for_write(direct_room(mesh.indices, direct_ni, ni), ni * sizeof(uint32_t));
    populate_for_write(direct_room(mesh.positions, direct_np, np), np * sizeof(float));
  }
  direct_float = !header.lossless && header.schema.position_type == ScalarType::kFloat32;
  DirectCursor out = direct_cursor();
  const bool rotation = header.rotation;
  while (records_left > 0) {
    // Without room for a triangle (fixed arrays: the segment's part is
    // full), the record takes the general path, whose events are checked.
    const bool room = out.troom != 0 || direct_grow(out);
    const int cls = d.decode(kFastTableA + fast_context);
    const uint32_t R = b.reference();
    int done = 0;  // 1: an add decoded below, 2: a fill
    if (((cls <= kFastGatePrev && R != kNone) || cls == kFastGateFar) && seen_triangles < chunk_triangles) {
      // The gate (spec 13.7.1): an offset from R, or a far gate's rank
      // among the ring's open edges (13.7.4), as decode_record()
      // finds it. Repeated, not shared: one inline helper for both costs
      // this loop more instructions.
      uint32_t gate;
      if (cls == kFastGateFar) {
        const int rank = d.decode(kFastTableRank + (R == kNone ? 1 : 0));
        if (rank >= kFastRanks) return corrupt("far gate rank " + std::to_string(rank));
        gate = ring.ranked(b, static_cast<uint32_t>(rank));
        if (gate == kNone) return corrupt("far gate rank beyond the open edges of the ring");
        ++stats.gates[2];
        ++stats.far_gates[0];
      } else {
        gate = cls == kFastGateR ? R : cls == kFastGateNext ? b.edge(R).next : b.edge(R).prev;
        if (gate == kNone) return corrupt("gate offset leaves the boundary");
        ++stats.gates[cls == kFastGateR ? 0 : 1];
      }
      const BEdge& g = b.edge(gate);
      const uint32_t p = g.org, q = g.dst;
      const int bsym = d.decode(fast_b_table(third_context(b.vertex(p).degree, b.vertex(q).degree),
                                             D::kAdaptive ? shape_context(b, gate) : 0));
      if (bsym >= kFastBSymbols) return corrupt("third-vertex symbol " + std::to_string(bsym));
      if (room && !rotation && common_b(bsym)) {
        PSQ_RETURN_IF_ERROR(common_record<true>(d, bits, cls, bsym, gate, &out));
        // A join adds open edges; a fill or an end does not, nor vertices.
        done = bsym == 0 || bsym == kFastBJoin ? 1 : 2;
      } else {
        qhead = qcount = 0;
        coder<D>() = d;
        *fraw = bits;
        PSQ_RETURN_IF_ERROR(decode_record<D>(cls, gate, bsym));
        d = coder<D>();
        bits = *fraw;
      }
    } else {
      qhead = qcount = 0;
      coder<D>() = d;
      *fraw = bits;
      PSQ_RETURN_IF_ERROR(decode_record<D>(cls));
      d = coder<D>();
      bits = *fraw;
    }
    if (!done) {
      direct_sync(out);
      for (size_t i = 0; i < qcount; ++i) {
        const SequenceEvent& e = queue[i];
        if (direct_fixed) PSQ_RETURN_IF_ERROR(direct_fixed_check(e));
        if (e.kind == SequenceEvent::Kind::kVertex) {
          const uint32_t at = direct_vertex(e.vertex);
          if (e.vertex.slot != kNoSlot) b.vertex(e.vertex.slot).key = at;
        } else if (e.kind == SequenceEvent::Kind::kTriangle) {
          direct_triangle(e.triangle.v);
        }
      }
      qhead = qcount = 0;
      out = direct_cursor();
    }
    // advance()'s bookkeeping. A fill adds no vertex and closes two open
    // edges for one, so neither maximum can move.
    ++record_no;
    if (done != 2) {
      stats.max_active_vertices = std::max(stats.max_active_vertices, b.active_vertices());
      stats.max_open_edges = std::max(stats.max_open_edges, b.open_edges());
    }
    if (--records_left == 0) {
      coder<D>() = d;
      *fraw = bits;
      direct_sync(out);
      PSQ_RETURN_IF_ERROR(close_records());
      if (seen_vertices != chunk_vertices || seen_triangles != chunk_triangles)
        return Status(ErrorCode::kBadHeader, "chunk declares other vertex or triangle counts than it holds", chunk_offset);
    }
  }
  return Status();
}

template Status PsqDecoder::Impl::decode_record<RansSymbolDecoder>(int, uint32_t, int);
template Status PsqDecoder::Impl::decode_record<AdaptiveSymbolDecoder>(int, uint32_t, int);
template Status PsqDecoder::Impl::direct_records<RansSymbolDecoder>();
template Status PsqDecoder::Impl::direct_records<AdaptiveSymbolDecoder>();

}  // namespace psq
