// SPDX-License-Identifier: Apache-2.0
// codec/src/records.h: the symbols, contexts and tables of the record
// grammar (spec section 13), shared by its encoder and decoder and by both
// entropy back-ends (symbol_coder.h).
#ifndef PSQ_CODEC_RECORDS_H_
#define PSQ_CODEC_RECORDS_H_

#include <algorithm>
#include <cstdint>
#include <vector>

#include "boundary.h"
#include "coding.h"

namespace psq {
namespace codec {

// Record classes, the symbols of table A (spec 13.7.1).
enum FastClass : int {
  kFastGateR = 0,
  kFastGateNext = 1,
  kFastGatePrev = 2,
  kFastGateFar = 3,
  kFastStart = 4,
  kFastIsolated = 5,
  kFastEscape = 6,
  kFastClasses = 7,
};

// Third-vertex kinds t of a gate record's B symbol.
enum FastThird : int {
  kFastNew = 0,
  kFastNewReappears = 1,
  kFastLeft = 2,
  kFastRight = 3,
  kFastEnd = 4,
  kFastJoin = 5,
};

// Edge states of B and of a start's S symbol.
enum FastEdge : int { kFastEnters = 0, kFastBorder = 1, kFastCut = 2 };

// B symbol layout: new 0..8, new re-appearing 9..17, join 18..26 (edge 1
// state + 3 x edge 2 state), left 27..29 (edge 2 state), right 30..32 (edge
// 1 state), end 33.
constexpr int kFastBSymbols = 34;
inline int fast_b_symbol(int third, int e1, int e2) {
  switch (third) {
    case kFastNew: return e1 + 3 * e2;
    case kFastNewReappears: return 9 + e1 + 3 * e2;
    case kFastJoin: return 18 + e1 + 3 * e2;
    case kFastLeft: return 27 + e2;
    case kFastRight: return 30 + e1;
    default: return 33;
  }
}
constexpr int kFastBJoin = 18;  // a join whose edges 1 and 2 enter
constexpr int kFastBEnd = 33;
// The B symbols of the records that common_record() decodes: an add or a
// join whose new edges enter, a fill whose new edge enters, an end.
inline bool common_b(int b) {
  constexpr uint64_t kCommon = 1ull << 0 | 1ull << kFastBJoin | 1ull << 27 | 1ull << 30 | 1ull << kFastBEnd;
  return (kCommon >> (b & 63)) & 1;  // b < kFastBSymbols (34)
}
// Splits a B symbol (< kFastBSymbols) into its third kind and edge states
// (edge states of completed edges are left at kFastEnters).
inline void fast_b_split(int b, int* third, int* e1, int* e2) {
  *e1 = *e2 = kFastEnters;
  if (b < 27) {
    *third = b < 9 ? kFastNew : b < 18 ? kFastNewReappears : kFastJoin;
    const int v = b % 9;
    *e1 = v % 3;
    *e2 = v / 3;
  } else if (b < 30) {
    *third = kFastLeft;
    *e2 = b - 27;
  } else if (b < 33) {
    *third = kFastRight;
    *e1 = b - 30;
  } else {
    *third = kFastEnd;
  }
}

// The context of table A: the class of the record before, as g * 6 + t for
// a gate record (g = 0..3, t = FastThird), 24 start, 25 isolated, 26
// escape.
constexpr int kFastAContexts = 27;
constexpr int kFastAStartContext = 24;
inline int fast_a_context_gate(int g, int third) { return g * 6 + third; }

// A start's S symbol: its three edge states and whether corner 2 was
// introduced before corner 1 (spec 6.2.4's swap).
constexpr int kFastSSymbols = 54;

// Far gates: ranks 0..31 among the current entries of the newest 128 of
// the ring.
constexpr int kFastRanks = 32;
constexpr uint32_t kFastRing = 1024;
constexpr uint32_t kFastRingScan = 128;

// Residual symbols (spec 13.8.3).
constexpr int kFastLengthSymbols = 65;
constexpr int kFastLengthEscape = 64;

// Degree contexts of B: third_context() (coding.h, spec 13.7.3).
constexpr int kFastBContexts = (kDegreeCap + 1) * (kDegreeCap + 1);

// The fixed table list (spec 13.5.3).
enum FastTable : int {
  kFastTableA = 0,                                         // kFastAContexts
  kFastTableRank = kFastTableA + kFastAContexts,           // 2
  kFastTableB = kFastTableRank + 2,                        // kFastBContexts
  kFastTableS = kFastTableB + kFastBContexts,              // 1
  kFastTableReappear = kFastTableS + 1,                    // 1: a start's re-appearing corners
  kFastTableChoice = kFastTableReappear + 1,               // 15
  kFastTableLength = kFastTableChoice + 15,                // kPredKinds x 2 x kLengthContexts
  kFastTableDistance = kFastTableLength + kPredKinds * 2 * kLengthContexts,  // 1
  kFastTableRotation = kFastTableDistance + 1,             // 1
  kFastTables = kFastTableRotation + 1,
};

// The adaptive back-end's extra tables (spec 13.2.1, 13.7.3): the B
// symbols of gate records in shape contexts 1 to 4 (shape_context() in
// boundary.h), after the fixed list. A shape context costs the decoder a
// parallelogram per gate record, which the rANS back-end, built for
// speed, does not spend: its B symbols all take shape context 0, the
// fixed list's B tables.
constexpr int kShapeContexts = 5;
constexpr int kAdaptiveTables = kFastTables + (kShapeContexts - 1) * kFastBContexts;
inline int fast_b_table(int degree_context, int shape) {
  return shape == 0 ? kFastTableB + degree_context : kFastTables + (shape - 1) * kFastBContexts + degree_context;
}

// The alphabet size of each table.
inline int fast_table_size(int table) {
  if (table >= kFastTables) return kFastBSymbols;
  if (table < kFastTableRank) return kFastClasses;
  if (table < kFastTableB) return kFastRanks;
  if (table < kFastTableS) return kFastBSymbols;
  if (table == kFastTableS) return kFastSSymbols;
  if (table == kFastTableReappear) return 8;
  if (table < kFastTableLength) return kChoices;
  if (table < kFastTableRotation) return kFastLengthSymbols;
  return 3;
}

// Whether prediction choice `choice` (any decoded symbol) may follow the
// neighbour mask `mask` (1..3, prediction_choices()): the gate always, a
// side's choices when that neighbour exists. One table test, no branch on
// the choice itself.
inline bool fast_choice_allowed(uint32_t mask, int choice) {
  // Bit c of entry m: choice c allowed with mask m (choices 1 and 3 need
  // the edge before, 2 and 4 the one after).
  static constexpr uint32_t kAllowed[4] = {0x01, 0x0b, 0x15, 0x1f};
  return static_cast<uint32_t>(choice) < 32 && ((kAllowed[mask & 3] >> choice) & 1);
}
// What a table's symbols code, for the split of coded bits in PsqStats:
// prediction choices and residual lengths are geometry, the rest
// connectivity.
inline int fast_table_cost(int table) {
  return table >= kFastTableChoice && table < kFastTableDistance ? kCostGeometry : kCostConnectivity;
}
// The context of a residual length: the extent along the
// axis, clamped, for every axis of a predicted vertex, so that the three
// lengths decode independently; a start's or an isolated vertex's: the
// largest earlier length (spec 13.8.1).
inline int fast_length_context(int kind, int axis, int extent, int longest_so_far) {
  (void)axis;
  return std::min(kind != kPredOther ? extent : longest_so_far, kLengthContexts - 1);
}
inline int fast_length_table(int kind, int axis, int context) {
  // Axes 1 and 2 share their tables (spec 13.5.3): half as many tables take
  // less of the cache and fewer bytes.
  return kFastTableLength + (kind * 2 + (axis == 0 ? 0 : 1)) * kLengthContexts + context;
}
// Whether a stream's gate records code a prediction choice (spec
// 13.8.2): with the adaptive back-end, which is for the smallest files,
// and in a lossless stream, which they make much smaller. A quantized
// stream with the rANS back-end predicts across the gate: there the
// choices save few bytes on large meshes, but take a large share of the
// encoder's work and a symbol per vertex where decoding speed matters most.
inline bool fast_codes_choices(bool lossless, bool rans) { return lossless || !rans; }
inline int fast_choice_table(uint32_t mask, int previous) {
  return kFastTableChoice + (static_cast<int>(mask) - 1) * kChoices + previous;
}

// The ring of the newest edges that entered the boundary (spec 13.6.2):
// far gates name an edge by its rank among them.
class FastRing {
 public:
  // Edge slot `slot` of `boundary` entered it (its age tells it from a
  // later edge in the same slot).
  template <class B>
  void push(const B& boundary, uint32_t slot) {
    ring_[head_++ & (kFastRing - 1)] = Entry{slot, boundary.edge(slot).age};
  }
  // A decoder that starts at a segment (segment.h): the ring of a
  // boundary whose edges entered long ago, rebuilt from their ages. For
  // each of the last kFastRingScan ages, the open edge of that age or an
  // entry that never matches (kNone), oldest first: the ranks are those
  // of the decoder that pushed every edge (spec 13.6.2).
  template <class B>
  void rebuild(const B& boundary) {
    head_ = 0;
    const uint64_t entered = boundary.entered();
    const uint64_t from = entered > kFastRingScan ? entered - kFastRingScan : 0;
    for (uint64_t a = from; a < entered; ++a) ring_[head_++ & (kFastRing - 1)] = Entry{kNone, a};
    for (uint32_t s = 0; s < boundary.edge_capacity(); ++s)
      if (boundary.edge_live(s) && boundary.edge(s).age >= from) ring_[(boundary.edge(s).age - from) & (kFastRing - 1)].slot = s;
  }
  // The open edge of rank `rank` (the rank-th current entry, 0 the newest,
  // among the newest kFastRingScan), or kNone.
  template <class B>
  uint32_t ranked(const B& boundary, uint32_t rank) const {
    const uint32_t n = std::min<uint64_t>(head_, kFastRingScan);
    for (uint32_t i = 1; i <= n; ++i) {
      const Entry& e = ring_[(head_ - i) & (kFastRing - 1)];
      if (current(boundary, e) && rank-- == 0) return e.slot;
    }
    return kNone;
  }
  // The smallest rank among the open edges cand[0..2] (kNone entries are
  // skipped), with the k that has it in *which, or -1 when none of them is
  // among the ranked edges or below rank kFastRanks. One scan for the
  // three: the first current entry that is a candidate has the smallest rank.
  template <class B>
  int first_rank_of(const B& boundary, const uint32_t cand[3], int* which) const {
    const uint32_t n = std::min<uint64_t>(head_, kFastRingScan);
    int r = 0;
    for (uint32_t i = 1; i <= n && r < kFastRanks; ++i) {
      const Entry& e = ring_[(head_ - i) & (kFastRing - 1)];
      if (!current(boundary, e)) continue;
      for (int k = 0; k < 3; ++k)
        if (e.slot == cand[k]) {
          *which = k;
          return r;
        }
      ++r;
    }
    return -1;
  }

 private:
  struct Entry {
    uint32_t slot = 0;
    uint64_t age = 0;
  };
  template <class B>
  bool current(const B& boundary, const Entry& e) const {
    return boundary.edge_live(e.slot) && boundary.edge(e.slot).age == e.age;
  }
  Entry ring_[kFastRing];
  uint64_t head_ = 0;
};

// A residual's length symbol (spec 13.8.3): k for k < 2, 2k - 2 + the
// bit below the leading one for 2 <= k <= 32, else the escape. Without a
// branch on k < 2, which is data (for k < 2, mag >> 62 or 63 is 0).
inline int fast_length_symbol(int k, uint64_t mag) {
  if (__builtin_expect(k > 32, 0)) return kFastLengthEscape;
  const int below = static_cast<int>((mag >> ((k - 2) & 63)) & 1);
  return k + static_cast<int>(k >= 2) * (k - 2 + below);
}

// The bit length that length symbol `s` stands for (spec 13.8.3): 33 for
// the escape.
inline int length_of_symbol(int s) {
  if (s < 2) return s;
  return s < kFastLengthEscape ? (s + 2) >> 1 : 33;
}

// The raw bits of a residual of bit length k (spec 13.8.3): the sign and
// the bits below the leading two, k - 1 for k >= 2, k for k < 2 (none for
// a zero). A comparison as a number, not a ternary, which the compiler made
// into a branch on k.
inline int fast_raw_bit_count(int k) { return k - static_cast<int>(k >= 2); }

}  // namespace codec
}  // namespace psq

#endif  // PSQ_CODEC_RECORDS_H_
