// SPDX-License-Identifier: Apache-2.0
// codec/src/record_encoder.cpp: the encoder's records (spec section 13):
// symbols and raw bits, gathered for the open chunk and coded at its end
// by the stream's entropy back-end (13.2): static rANS tables, or
// adaptive bit-trees with the range coder.
//
// The encoder keeps a Boundary with lookups by endpoints: it must check
// its input and find which open edges a triangle completes. The decoder
// keeps the same slots and links without the lookups (FastBoundary),
// because every completion is named in the record (13.6.3).
#include <algorithm>
#include <cassert>
#include <cmath>
#include <type_traits>

#include "container.h"
#include "encoder_impl.h"
#include "geometry.h"

namespace psq {

namespace {

// Raw values of up to 64 bits, in pieces of at most 32.
void put_raw(RawWriter& raw, uint64_t value, int bits) {
  if (bits > 32) {
    raw.put(static_cast<uint32_t>(value), 32);
    raw.put(static_cast<uint32_t>(value >> 32), bits - 32);
  } else {
    raw.put(static_cast<uint32_t>(value), bits);
  }
}

int edge_state(const BTriangle& bt, const SequenceTriangle& t, int k, int rot) {
  if (bt.state[k] != EdgeState::kBorder) return kFastEnters;
  return (t.nonmanifold_mask >> ((rot + k) % 3)) & 1 ? kFastCut : kFastBorder;
}

}  // namespace

PSQ_INLINE int PsqEncoder::Impl::fast_residual(int table, int64_t r) {
  const uint64_t raw_before = opt.measure_costs ? fast_raw.bits() : 0;
  const uint64_t mag = r < 0 ? 0 - static_cast<uint64_t>(r) : static_cast<uint64_t>(r);
  const int k = bit_length64(mag);
  const int sym = fast_length_symbol(k, mag);
  fast_put(table, sym);
  if (sym == kFastLengthEscape) {
    fast_raw.put(static_cast<uint32_t>(k - 33), 5);
    fast_raw.put(static_cast<uint32_t>((mag >> (k - 2)) & 1), 1);
  }
  // The sign and the bits below the leading two (spec 13.8.3), none for
  // a zero.
  const int nbits = fast_raw_bit_count(k);
  const int low_bits = nbits - static_cast<int>(k != 0);
  const uint64_t low = mag & ((uint64_t{1} << low_bits) - 1);
  put_raw(fast_raw, (static_cast<uint64_t>(r < 0) << low_bits) | low, nbits);
  if (opt.measure_costs && table != kFastTableDistance) fast_raw_geometry += fast_raw.bits() - raw_before;
  return k;
}

void PsqEncoder::Impl::fast_vertex(const PendingVertex& v, const int64_t pred[3], int kind, const int extent[3]) {
  int lengths[3] = {0, 0, 0};
  for (int i = 0; i < 3; ++i) {
    const int c = fast_length_context(kind, i, extent[i], std::max(lengths[0], lengths[1]));
    lengths[i] = fast_residual(fast_length_table(kind, i, c), wrap_sub(v.pos[i], pred[i]));
  }
  for (int i = 0; i < 3; ++i) last_pos[i] = v.pos[i];
}

namespace {

// log2 in 1/65536 bits by integer arithmetic only, so that the encoder's
// choices, and so its bytes, are the same on every machine (a libm's
// log2 may round differently). The fraction comes from the top 8 bits
// below the leading one: within 0.006 bits, enough to rank predictions.
struct Log2Table {
  uint32_t frac[256];
  Log2Table() {
    for (uint32_t i = 0; i < 256; ++i) {
      // m = (256 + i) / 256 in Q31; square it 16 times, taking a bit of
      // the logarithm each time the square reaches 2.
      uint64_t m = uint64_t{256 + i} << 23;
      uint32_t f = 0;
      for (int b = 15; b >= 0; --b) {
        m = (m * m) >> 31;
        if (m >= uint64_t{1} << 32) {
          m >>= 1;
          f |= 1u << b;
        }
      }
      frac[i] = f;
    }
  }
};
const Log2Table kLog2;

int64_t fixed_log2(uint64_t x) {  // x >= 1
  const int msb = 63 - __builtin_clzll(x);
  // The 8 bits below the leading one: one shift each way while x << 8
  // fits (counts and denominators stay far below 2^56).
  const uint32_t top =
      static_cast<uint32_t>(__builtin_expect(msb < 56, 1) ? (x << 8) >> msb : x >> (msb - 8)) & 255u;
  return int64_t{msb} * 65536 + kLog2.frac[top];
}

}  // namespace

void PsqEncoder::Impl::begin_records() {
  fast_choices = fast_codes_choices(header.lossless, rans);
  fast_denominator.resize(kAdaptiveTables);
  fast_log_denominator.resize(kAdaptiveTables);
  for (int i = 0; i < kAdaptiveTables; ++i) {
    fast_denominator[i] = static_cast<uint64_t>(fast_table_size(i));
    fast_log_denominator[i] = static_cast<int32_t>(fixed_log2(fast_denominator[i]));
  }
  fast_log_count.assign(size_t{kAdaptiveTables} * 128, static_cast<int32_t>(fixed_log2(1)));
  // after_record() closes a chunk before it holds 2 * chunk_bytes
  // symbols: reserved, the array never moves, and no symbol is copied as
  // it grows.
  // (At most 2^22 symbols, 16 MiB of address space, for large --chunk
  // sizes; beyond, the array doubles.)
  fast_symbols.reserve(std::min<size_t>(2 * size_t{opt.chunk_bytes} + 4096, size_t{1} << 22));
}

PSQ_INLINE void PsqEncoder::Impl::fast_put(int table, int symbol) {
  fast_symbols.push(RansSymbol{static_cast<uint16_t>(table), static_cast<uint8_t>(symbol)});
  const size_t at = static_cast<size_t>(table) * 128 + static_cast<size_t>(symbol);
  ++fast_count[at];
  if (!fast_choices) return;  // nothing to price (spec 13.8.2)
  fast_denominator[table] += 2;
  if (table >= kFastTableChoice && table < kFastTableDistance) {
    fast_log_denominator[table] = static_cast<int32_t>(fixed_log2(fast_denominator[table]));
    fast_log_count[at] = static_cast<int32_t>(fixed_log2(2 * uint64_t{fast_count[at]} + 1));
  }
}

PSQ_INLINE int64_t PsqEncoder::Impl::fast_cost(int table, int symbol) const {
  // Half a count for every symbol of the alphabet (encoder_impl.h), so
  // that unseen symbols cost finitely.
  assert(table >= kFastTableChoice && table < kFastTableDistance);
  return int64_t{fast_log_denominator[table]} -
         fast_log_count[static_cast<size_t>(table) * 128 + static_cast<size_t>(symbol)];
}

// Spec 7.3 leaves the choice to the encoder; this one takes the cheapest
// under the running counts of the tables (the choice symbol, the length
// symbols and the raw bits), among the candidates whose residuals have no
// more bits than the gate's. The counts price a symbol in either back-end:
// the adaptive models follow the same statistics. Ties go to the lower
// choice.
int PsqEncoder::Impl::choose_prediction(uint32_t gate, uint32_t mask, const int64_t pos[3], Prediction* pred) {
  // The five choices combine three parallelograms and the extents of
  // three triangles as predict_new_vertex() does (spec 7.3): each is
  // computed once here instead of once per choice. The rule is repeated,
  // not shared: a helper that both call costs the decoder and this loop
  // more instructions. A divergence
  // would code residuals against another prediction than the decoder's,
  // which every round-trip test would catch.
  const BEdge& g = boundary.edge(gate);
  const uint32_t edge[3] = {gate, g.prev, g.next};  // by side
  int64_t para[3][3];
  int extent[3][3];
  // A neighbour's extents only when a choice that uses them passes the
  // rough test below (most do not).
  bool have_extent[3] = {true, false, false};
  triangle_extents(boundary, gate, extent[kChoiceGate]);
  for (int side = 0; side < 3; ++side) {
    if (side != 0 && !(mask & (1u << (side - 1)))) continue;
    parallelogram(boundary, edge[side], para[side]);
  }
  const int choice_table = fast_choice_table(mask, fast_choice);
  int best = kChoiceGate;
  int64_t best_cost = 0;
  int rough_gate = 0;
  // One candidate, its choice a constant: the side, the predicting side and
  // the kind fold away (in a loop over the choices they would not, and the
  // encoder would run more instructions).
  auto price = [&](auto choice) PSQ_LAMBDA_INLINE {
    constexpr int ch = decltype(choice)::value;
    constexpr int side = choice_side(ch), ps = predicting_side(ch), kind = prediction_kind(ch);
    // The residuals' magnitudes and bit lengths, for the rough test and
    // then the price.
    uint64_t mag[3];
    int len[3];
    int rough = 0;
    for (int a = 0; a < 3; ++a) {
      const int64_t pa = ch >= kChoiceMeanBefore ? midpoint(para[kChoiceGate][a], para[side][a]) : para[side][a];
      mag[a] = coord_distance(pos[a], pa);
      // (bit_length63(): only a distance of exactly 2^63 reads 0, which
      // could only make this a worse choice, not a wrong stream.)
      len[a] = bit_length63(mag[a]);
      rough += len[a];
    }
    if (ch == kChoiceGate) rough_gate = rough;
    else if (rough > rough_gate) return;
    if (ps != kChoiceGate && !have_extent[ps]) {
      triangle_extents(boundary, edge[ps], extent[ps]);
      have_extent[ps] = true;
    }
    // fast_vertex()'s tables for these residuals: a prediction that is not
    // kPredOther takes its length context from the extent alone.
    int64_t c = fast_cost(choice_table, ch);
    for (int a = 0; a < 3; ++a) {
      const int table = fast_length_table(kind, a, std::min(extent[ps][a], kLengthContexts - 1));
      const int k = len[a];
      c += fast_cost(table, fast_length_symbol(k, mag[a])) + int64_t{fast_raw_bit_count(k)} * 65536;
    }
    if (ch == kChoiceGate || c < best_cost) {
      best = ch;
      best_cost = c;
    }
  };
  price(std::integral_constant<int, kChoiceGate>());
  if (mask & 1u) price(std::integral_constant<int, kChoiceBefore>());
  if (mask & 2u) price(std::integral_constant<int, kChoiceAfter>());
  if (mask & 1u) price(std::integral_constant<int, kChoiceMeanBefore>());
  if (mask & 2u) price(std::integral_constant<int, kChoiceMeanAfter>());
  const int side = choice_side(best), ps = predicting_side(best);
  for (int a = 0; a < 3; ++a) {
    pred->pos[a] = best >= kChoiceMeanBefore ? midpoint(para[kChoiceGate][a], para[side][a]) : para[side][a];
    pred->extent[a] = extent[ps][a];
  }
  pred->kind = prediction_kind(best);
  return best;
}

PSQ_INLINE int PsqEncoder::Impl::gate_class(const uint32_t cand[3], int* rot, int* rank) const {
  // Spec 13.7.1: R, R's next, R's prev, else a recency rank (13.7.4),
  // else the escape (13.7.5) with the first candidate.
  const uint32_t R = boundary.reference();
  if (R != kNone) {
    const uint32_t near[3] = {R, boundary.edge(R).next, boundary.edge(R).prev};
    for (int g = 0; g < 3; ++g)
      for (int k = 0; k < 3; ++k)
        if (near[g] != kNone && cand[k] == near[g]) {
          *rot = k;
          return g;
        }
  }
  // The ring holds edge slots only (never kNone), so a kNone candidate
  // matches no entry.
  int k = 0;
  const int r = ring.first_rank_of(boundary, cand, &k);
  if (r >= 0) {
    *rank = r;
    *rot = k;
    return kFastGateFar;
  }
  *rot = cand[0] != kNone ? 0 : cand[1] != kNone ? 1 : 2;
  return kFastEscape;
}

void PsqEncoder::Impl::note_input_edge_grow(uint32_t in, uint32_t slot) {
  // The input's edge slots stay below the size of its working set
  // (psq/sequence.h): the converter's waiting area, ahead of the
  // triangles it has sent, or the boundary. One beyond three slots a
  // triangle sent plus 2^20 (or kNoSlot) is not remembered, so that no
  // input can make the array much larger than the stream: its edge takes
  // the general path.
  if (in >= 3 * stats.triangles + (uint64_t{1} << 20)) return;
  by_ineslot.resize(std::max<size_t>(size_t{in} + 1, 2 * by_ineslot.size()), kNone);
  by_ineslot[in] = slot;
}

PSQ_INLINE void PsqEncoder::Impl::put_gate(int cls, int rank, uint32_t gate, int third, int e1, int e2) {
  if (cls == kFastGateFar) fast_put(kFastTableRank + (boundary.reference() == kNone ? 1 : 0), rank);
  const BEdge& g = boundary.edge(gate);
  fast_put(fast_b_table(third_context(boundary.vertex(g.org).degree, boundary.vertex(g.dst).degree),
                        rans ? 0 : shape_context(boundary, gate)),
           fast_b_symbol(third, e1, e2));
  fast_context = fast_a_context_gate(cls, third);
}

void PsqEncoder::Impl::gate_vertex(const PendingVertex& v, uint32_t gate, bool choices) {
  Prediction pr;
  const uint32_t mask = choices && fast_choices ? prediction_choices(boundary, gate) : 0;
  if (mask != 0) {
    const int choice = choose_prediction(gate, mask, v.pos, &pr);
    fast_put(fast_choice_table(mask, fast_choice), choice);
    fast_choice = choice;
    ++stats.predictions[choice];
  } else {
    pr = predict_across_gate(boundary, gate);
    ++stats.predictions[kChoiceGate];
  }
  fast_vertex(v, pr.pos, pr.kind, pr.extent);
}

PSQ_INLINE Status PsqEncoder::Impl::end_triangle(const uint32_t corner[3], uint32_t final, const PropertyValues& face) {
  pending.clear();
  for (int k = 0; k < 3; ++k)
    if (final >> k & 1) {
      const BVertex& v = boundary.vertex(corner[k]);
      expect_final.push_back(v.key);
      if (!slot_of.empty()) slot_of.erase(v.key);
      boundary.free_vertex(corner[k]);
    }
  if (!props->add_face(face))
    return Status(ErrorCode::kBadValue, "face property values do not match the schema or their types");
  ++stats.triangles;
  ++chunk_triangles;
  return after_record();
}

Status PsqEncoder::Impl::close_triangle(const SequenceTriangle& t, BTriangle& bt, int nnew) {
  int completed = 0;
  for (int k = 0; k < 3; ++k) completed += bt.state[k] == EdgeState::kCompletes;
  Op op = nnew == 3 ? Op::kStart
          : completed == 1 ? (nnew == 1 ? Op::kAdd : Op::kJoin)
          : completed == 2 ? Op::kFill
                           : Op::kEnd;
  if ((nnew == 1 && completed != 1) || (nnew == 3 && completed != 0))
    return bad_sequence("triangle is no valid op");
  if (op != t.op)
    return bad_sequence(std::string("triangle claims op ") + op_name(t.op) + " but is " + op_name(op));
  if (!boundary.apply(bt)) return boundary_full("open edges");
  // Spec 13.6.2: entering edges join the ring, in edge order; every edge
  // that completes none is new to `used`.
  uint8_t fresh = 0, entering = 0, final = 0;
  for (int k = 0; k < 3; ++k) {
    if (bt.state[k] == EdgeState::kEnters) ring.push(boundary, bt.eslot[k]);
    if (bt.state[k] != EdgeState::kCompletes) used.insert(bt.c[k], bt.c[k == 2 ? 0 : k + 1]);
    fresh |= static_cast<uint8_t>(bt.is_new[k] << k);
    entering |= static_cast<uint8_t>((bt.state[k] == EdgeState::kEnters) << k);
    final |= static_cast<uint8_t>(bt.final[k] << k);
  }
  if (!attrs->empty()) {
    if (attrs->corner_dims() > 0) {
      // Spec 8.5: the corners' values, in the record's corner order.
      PSQ_RETURN_IF_ERROR(attrs->split_face(t.values, stats.triangles, &attr_columns, attr_face_q.data()));
      const size_t cd = static_cast<size_t>(attrs->corner_dims());
      for (int k = 0; k < 3; ++k)
        for (int j = 0; j < 3; ++j)
          if (out_index_of(t.v[j]) == boundary.vertex(bt.c[k]).index)
            std::copy(&attr_face_q[j * cd], &attr_face_q[j * cd] + cd, &attr_cq[k * cd]);
      attr_rec.corners = attr_cq.data();
    }
    code_attributes(bt.c, bt.eslot, fresh, entering, final);
  }
  return end_triangle(bt.c, final, attrs->corner_dims() > 0 ? attr_columns : t.values);
}

Status PsqEncoder::Impl::code_triangle(const SequenceTriangle& t, const int pend[3], const uint32_t slots_in[3],
                                       int nnew) {
  uint32_t slots[3] = {slots_in[0], slots_in[1], slots_in[2]};
  int rot = 0;  // canonical corner k is input corner (rot + k) % 3
  int cls = kFastStart;
  int rank = -1;
  uint32_t gate = kNone;
  if (nnew == 3) {
    rot = pend[0] == 0 ? 0 : pend[1] == 0 ? 1 : 2;  // spec 6.2.4
  } else {
    uint32_t cand[3];
    PSQ_RETURN_IF_ERROR(candidate_gates(t, pend, slots, nnew, cand));
    cls = gate_class(cand, &rot, &rank);
    gate = cand[rot];
  }
  BTriangle bt;
  int cp[3];  // pending position of canonical corner k, or -1
  for (int k = 0; k < 3; ++k) {
    const int ik = (rot + k) % 3;
    bt.c[k] = slots[ik];
    bt.is_new[k] = pend[ik] >= 0;
    cp[k] = pend[ik];
    bt.border[k] = (t.border_mask >> ik) & 1;
  }
  bt.gate = gate;
  const int r = (3 - rot) % 3;  // spec 6.2.3
  if (!boundary.find_completions(bt, used))
    return bad_sequence("triangle " + std::to_string(t.v[0]) + " " + std::to_string(t.v[1]) + " " +
                        std::to_string(t.v[2]) + " uses a directed edge already on the boundary, or a border edge");
  for (int k = 0; k < 3; ++k)
    if (bt.state[k] == EdgeState::kCompletes && bt.border[k])
      return bad_sequence("a border edge completes a boundary edge");
  const int e[3] = {edge_state(bt, t, 0, rot), edge_state(bt, t, 1, rot), edge_state(bt, t, 2, rot)};

  // The third vertex (spec 13.7.3).
  int third = kFastNew;
  uint32_t join = kNone;
  int join_side = 0;
  if (nnew == 1) {
    third = pending[cp[2]].reappears != kNoVertex ? kFastNewReappears : kFastNew;
  } else if (nnew == 0) {
    const BEdge& g = boundary.edge(gate);
    const uint32_t x = bt.c[2];
    const bool left = g.prev != kNone && boundary.edge(g.prev).org == x;
    const bool right = g.next != kNone && boundary.edge(g.next).dst == x;
    const bool c1 = bt.state[1] == EdgeState::kCompletes, c2 = bt.state[2] == EdgeState::kCompletes;
    if (left && right && c1 && c2 && bt.completes[1] == g.prev && bt.completes[2] == g.next) third = kFastEnd;
    else if (left && c1 && bt.completes[1] == g.prev && !c2) third = kFastLeft;
    else if (right && c2 && bt.completes[2] == g.next && !c1) third = kFastRight;
    else if (!left && !right && !c1 && !c2) third = kFastJoin;
    else cls = kFastEscape;  // a completion that is not the gate's neighbour
    if (third == kFastJoin || cls == kFastEscape) {
      // Spec 13.11: an open edge at x names it and the gap the triangle
      // goes into: its first edge leaving x, else its first entering x.
      const BLinks& vx = boundary.links(x);
      join = vx.first_out != kNone ? vx.first_out : vx.first_in;
      if (join == kNone)
        return bad_sequence("join over vertex " + std::to_string(t.v[(rot + 2) % 3]) +
                            ", which is not on the boundary");
      join_side = join == vx.first_out ? 0 : 1;
      bt.join_edge = join;
    }
  }

  // The record's symbols and raw fields.
  fast_put(kFastTableA + fast_context, cls);
  uint32_t intro[3];  // canonical corners in the order their vertices are introduced
  int nintro = 0;
  const int sbits = slot_bits(boundary.edge_capacity());
  if (cls == kFastStart) {
    const bool swap = cp[2] == 1;  // corner 2 was introduced second
    fast_put(kFastTableS, e[0] + 3 * e[1] + 9 * e[2] + (swap ? 27 : 0));
    intro[0] = 0;
    intro[1] = swap ? 2 : 1;
    intro[2] = swap ? 1 : 2;
    nintro = 3;
    int mask = 0;
    for (int i = 0; i < 3; ++i) mask |= (pending[cp[intro[i]]].reappears != kNoVertex) << i;
    fast_put(kFastTableReappear, mask);
    fast_context = kFastAStartContext;
  } else if (cls == kFastEscape) {
    fast_raw.put(gate, sbits);
    const int xkind = nnew == 1 ? (third == kFastNewReappears ? 1 : 0) : 2;
    fast_raw.put(static_cast<uint32_t>(xkind), 2);
    if (xkind == 2) {
      fast_raw.put(join, sbits);
      fast_raw.put(static_cast<uint32_t>(join_side), 1);
    }
    for (int k = 1; k < 3; ++k) {
      if (bt.state[k] == EdgeState::kCompletes) {
        fast_raw.put(3, 2);
        fast_raw.put(bt.completes[k], sbits);
      } else {
        fast_raw.put(static_cast<uint32_t>(e[k]), 2);
      }
    }
    fast_context = kFastAContexts - 1;
  } else {
    put_gate(cls, rank, gate, third, e[1], e[2]);
    if (third == kFastJoin) {
      fast_raw.put(join, sbits);
      fast_raw.put(static_cast<uint32_t>(join_side), 1);
    }
  }
  if (nnew == 1) intro[nintro++] = 2;
  if (header.rotation) fast_put(kFastTableRotation, r);

  // New vertices in the order of introduction, with their predictions.
  for (int i = 0; i < nintro; ++i) {
    const int k = static_cast<int>(intro[i]);
    PendingVertex& v = pending[cp[k]];
    PSQ_RETURN_IF_ERROR(introduce(v));
    v.coded = true;
    if (v.reappears != kNoVertex)
      (void)fast_residual(kFastTableDistance,
                          static_cast<int64_t>(out_index_of(v.in_index) - out_index_of(v.reappears)) - 1);
    if (nnew == 1) {
      gate_vertex(v, gate, cls != kFastEscape);
    } else {
      const int64_t* first = i >= 1 ? pending[cp[intro[0]]].pos : nullptr;
      const int64_t* second = i >= 2 ? pending[cp[intro[1]]].pos : nullptr;
      const Prediction pr = predict_new_vertex(boundary, kNone, i, last_pos, first, second);
      fast_vertex(v, pr.pos, pr.kind, pr.extent);
    }
    PSQ_RETURN_IF_ERROR(register_vertex(v, &bt.c[k]));
  }
  count_gate(cls);
  PSQ_RETURN_IF_ERROR(close_triangle(t, bt, nnew));
  for (int k = 0; k < 3; ++k)
    if (bt.state[k] == EdgeState::kEnters) note_input_edge(t.eslot[(rot + k) % 3], bt.eslot[k]);
  return Status();
}

bool PsqEncoder::Impl::fast_direct(const SequenceTriangle& t, Status* status) {
  const size_t np = pending.size();
  if (np > 1 || !expect_final.empty() || header.rotation || attrs->corner_dims() > 0 || t.border_mask != 0 ||
      t.op != (np == 1 ? Op::kAdd : Op::kFill) || t.v[0] == t.v[1] || t.v[1] == t.v[2] || t.v[0] == t.v[2])
    return false;
  // The corners: the pending vertex (an add's new one, input corner j), and
  // active vertices by the input's vertex slots, as triangle() finds them.
  int j = -1;
  uint32_t slots[3];
  for (int k = 0; k < 3; ++k) {
    if (np == 1 && pending[0].in_index == t.v[k]) {
      j = k;
      slots[k] = kNone;
      continue;
    }
    slots[k] = slot_by_hint(t.vslot[k], t.v[k]);
    if (slots[k] == kNone) return false;
  }
  if (np == 1 && (j < 0 || pending[0].reappears != kNoVertex)) return false;
  // The open edge that input edge k (corner k to k + 1) completes, by the
  // input's slot for it: the edge it maps to, if that is open and runs
  // the other way. There is at most one such open edge, so this is what
  // candidate_gates() finds by the endpoints; else kNone.
  auto completed = [&](int k) PSQ_LAMBDA_INLINE {
    const uint32_t in = t.eslot[k];
    if (in >= by_ineslot.size()) return kNone;
    const uint32_t e = by_ineslot[in];
    if (e == kNone || !boundary.edge_live(e)) return kNone;
    const BEdge& E = boundary.edge(e);
    return E.org == slots[k == 2 ? 0 : k + 1] && E.dst == slots[k] ? e : kNone;
  };
  uint32_t cand[3] = {kNone, kNone, kNone};
  int open_k = -1;  // a fill's edge between old vertices that must enter
  if (np == 1) {
    const int k = j == 2 ? 0 : j + 1;  // the edge between the old corners
    cand[k] = completed(k);
    if (cand[k] == kNone) return false;
  } else {
    for (int k = 0; k < 3; ++k) {
      cand[k] = (t.leaving_mask >> k) & 1 ? completed(k) : kNone;
      if (cand[k] == kNone) {
        if (open_k >= 0) return false;
        open_k = k;
      }
    }
    if (open_k < 0) return false;
    const uint32_t a = slots[open_k], b = slots[open_k == 2 ? 0 : open_k + 1];
    if (used.contains(a, b)) return false;  // not new: open or dead
  }
  int rot = 0, rank = -1;
  const int cls = gate_class(cand, &rot, &rank);
  if (cls == kFastEscape) return false;
  const uint32_t gate = cand[rot];
  const BEdge& g = boundary.edge(gate);
  const uint32_t p = g.org, q = g.dst;
  // Canonical corners q, p, x are input corners rot, rot + 1, rot + 2; a
  // fill's other completion is canonical edge 1 or 2.
  const int in1 = rot == 2 ? 0 : rot + 1, in2 = rot == 0 ? 2 : rot - 1;
  int third = kFastNew;
  if (np == 0) {
    if (cand[in1] != kNone && cand[in1] == g.prev) third = kFastLeft;
    else if (cand[in2] != kNone && cand[in2] == g.next) third = kFastRight;
    else return false;  // named by an escape (13.7.5)
  }

  // The record (spec 13.7.3), as code_triangle() codes it.
  fast_put(kFastTableA + fast_context, cls);
  put_gate(cls, rank, gate, third, kFastEnters, kFastEnters);
  count_gate(cls);
  uint32_t corner[3] = {q, p, slots[in2]};  // an add's x: once registered
  uint32_t final = 0;
  if (np == 1) {
    PendingVertex& v = pending[0];
    Status s = introduce(v);
    if (!s.ok()) return *status = std::move(s), true;
    v.coded = true;
    gate_vertex(v, gate, true);
    Status r = register_vertex(v, &corner[2]);
    if (!r.ok()) return *status = std::move(r), true;
    const uint32_t x = corner[2];
    const uint32_t f1 = boundary.lean_add(gate, x);
    if (f1 == kNone) return *status = boundary_full("open edges"), true;
    const uint32_t f2 = boundary.edge(f1).next;
    used.insert(p, x);
    used.insert(x, q);
    ring.push(boundary, f1);
    ring.push(boundary, f2);
    note_input_edge(t.eslot[in1], f1);
    note_input_edge(t.eslot[in2], f2);
    const uint32_t eslot[3] = {gate, f1, f2};
    code_attributes(corner, eslot, 4, 6);
  } else {
    const bool left = third == kFastLeft;
    const uint32_t f = boundary.lean_fill(gate, left, &final);
    if (f == kNone) return *status = boundary_full("open edges"), true;
    ring.push(boundary, f);
    used.insert(boundary.edge(f).org, boundary.edge(f).dst);
    note_input_edge(t.eslot[left ? in2 : in1], f);
    if (!attrs->empty()) {
      const int enters = left ? 2 : 1;
      uint32_t eslot[3] = {gate, gate, gate};  // only the entering edge's slot is used
      eslot[enters] = f;
      code_attributes(corner, eslot, 0, static_cast<uint8_t>(1 << enters), static_cast<uint8_t>(final));
    }
  }
  Status s = end_triangle(corner, final, t.values);
  if (!s.ok()) *status = std::move(s);
  return true;
}

void PsqEncoder::Impl::code_isolated(PendingVertex& v) {
  fast_put(kFastTableA + fast_context, kFastIsolated);
  fast_context = kFastAContexts - 2;
  // An isolated vertex re-appears only in sequences not written by psq's
  // converter: one raw bit, then the distance.
  fast_raw.put(v.reappears != kNoVertex, 1);
  if (v.reappears != kNoVertex)
    (void)fast_residual(kFastTableDistance,
                        static_cast<int64_t>(out_index_of(v.in_index) - out_index_of(v.reappears)) - 1);
  const int no_extent[3] = {0, 0, 0};
  fast_vertex(v, last_pos, kPredOther, no_extent);
  ++stats.gates[3];
}

void PsqEncoder::Impl::record_section(std::vector<uint8_t>* section) {
  // Spec 13.2: the chunk's symbols in the stream's back-end (the range
  // coder's bytes; or the tables of this chunk's symbols and the rANS
  // block), then the raw bits.
  // The chunk's counts are the running counts (fast_put()) less those at
  // the chunk's start: no pass over its symbols.
  std::vector<std::vector<uint64_t>> counts(kFastTables);
  fast_chunk_base.resize(fast_count.size(), 0);
  for (int i = 0; i < kFastTables; ++i) {
    counts[i].resize(fast_table_size(i));
    for (int sym = 0; sym < fast_table_size(i); ++sym) {
      const size_t at = static_cast<size_t>(i) * 128 + static_cast<size_t>(sym);
      counts[i][sym] = fast_count[at] - fast_chunk_base[at];
      fast_chunk_base[at] = fast_count[at];
    }
  }
  std::vector<uint8_t> coded, table_bytes;  // the range coder's bytes, or the rANS block and its tables
  if (!rans) {
    // The adaptive back-end: the symbols in order, each through its
    // table's bit-tree, the models fresh for the chunk.
    std::vector<SymbolModel> models;
    reset_adaptive_models(&models);
    RangeEncoder enc(&coded);
    for (const RansSymbol& sym : fast_symbols) {
      SymbolModel& m = models[sym.table];
      if (opt.measure_costs) {
        // The symbol's information content, bit by bit of its tree.
        uint32_t node = 1;
        for (int i = m.bits() - 1; i >= 0; --i) {
          const int bit = (sym.symbol >> i) & 1;
          const double p0 = m.tree()[node].p0 / 65536.0;
          cost[fast_table_cost(sym.table)] -= std::log2(bit ? 1 - p0 : p0);
          enc.encode_bit(m.tree()[node], bit);
          node = (node << 1) | static_cast<uint32_t>(bit);
        }
      } else {
        enc.encode_symbol(m, sym.symbol);
      }
    }
    enc.finish();
  } else {
    std::vector<RansTable> tables(kFastTables);
    RawWriter tw;
    for (int i = 0; i < kFastTables; ++i) {
      bool present = false;
      for (uint64_t c : counts[i]) present = present || c != 0;
      tw.put(present, 1);
      if (present) tables[i].build(counts[i].data(), fast_table_size(i));
    }
    if (opt.measure_costs) cost[kCostConnectivity] += kFastTables;  // the presence bits
    for (int i = 0; i < kFastTables; ++i) {
      if (tables[i].empty()) continue;
      const uint64_t before = tw.bits();
      tables[i].write(tw);
      if (opt.measure_costs) cost[fast_table_cost(i)] += static_cast<double>(tw.bits() - before);
    }
    if (opt.measure_costs) {
      // Each symbol's information content under its table.
      for (const RansSymbol& s : fast_symbols)
        cost[fast_table_cost(s.table)] += kRansScaleBits - std::log2(tables[s.table].freq(s.symbol));
    }
    table_bytes = tw.finish();
    rans_encode(fast_symbols.data(), fast_symbols.size(), tables.data(), tables.size(), &coded);
  }
  fast_symbols.clear();
  if (opt.measure_costs) {
    // The raw bits of positions are geometry, the other raw bits connectivity.
    cost[kCostGeometry] += static_cast<double>(fast_raw_geometry);
    cost[kCostConnectivity] += static_cast<double>(fast_raw.bits() - fast_raw_geometry);
  }
  fast_raw_geometry = 0;
  // (finish() starts fast_raw over, keeping its array.)
  const std::vector<uint8_t> raw_bytes = fast_raw.finish();
  if (rans) {
    put_rans_section(table_bytes, coded, raw_bytes, section);
    return;
  }
  Put put(section);
  put.varint(coded.size());
  put.bytes(coded.data(), coded.size());
  put.bytes(raw_bytes.data(), raw_bytes.size());
}

}  // namespace psq
