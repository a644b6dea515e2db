// SPDX-License-Identifier: Apache-2.0
// codec/src/encoder_impl.h: the state of the .psq encoder (psq/psq_codec.h),
// shared by its two files: encoder.cpp (the input's checks, the container,
// properties and attributes) and record_encoder.cpp (the records of spec
// section 13 and their entropy back-ends).
#ifndef PSQ_CODEC_ENCODER_IMPL_H_
#define PSQ_CODEC_ENCODER_IMPL_H_

#include <array>
#include <memory>
#include <unordered_map>
#include <vector>

#include "boundary.h"
#include "coding.h"
#include "records.h"
#include "attributes.h"
#include "properties.h"
#include "psq/psq_codec.h"
#include "range_coder.h"
#include "rans.h"
#include "symbol_coder.h"

namespace psq {

namespace codec {

inline Status bad_sequence(const std::string& what) { return Status(ErrorCode::kBadSequence, what); }

struct PendingVertex {
  uint32_t in_index;
  uint32_t in_slot = kNoSlot;  // the input's boundary slot
  uint32_t reappears;  // input numbering, or kNoVertex
  int64_t pos[3];
  PropertyValues values;
  bool coded = false;  // already coded in the current record
};

}  // namespace codec

// An internal header of the encoder's two files, which both work in the
// codec's namespace.
using namespace codec;

struct PsqEncoder::Impl {
  ByteWriter* out;
  EncodeOptions opt;
  Status error;
  bool begun = false, finished = false;
  PsqHeader header;
  Boundary boundary{1};
  // Which active vertices an edge joins: an edge between old vertices that
  // it lists is open or dead (spec 13.6.3).
  Neighbors used;
  std::unique_ptr<PropertyPacker> props;
  // Normals, texture coordinates and colours (spec 8.3): the coder, its
  // chunk section, and the record being coded (new vertices' values, in
  // order of introduction).
  std::unique_ptr<AttributeCoder> attrs;
  std::vector<uint8_t> attr_bytes;
  std::unique_ptr<RangeEncoder> attr_rc;  // adaptive back-end
  FastAttributeWriter attr_fast;          // rANS back-end
  AttributeRecord attr_rec;
  std::vector<int32_t> attr_q;
  PropertyValues attr_columns;
  std::vector<int32_t> attr_cq, attr_face_q;  // a triangle's corner values (spec 8.5): by record corner, by input corner
  PsqStats stats;
  double cost[kCostCount] = {0, 0};

  // Active vertices by the input's boundary slot (the converter's and the
  // decoder's sequences have them: no hashing), else by input dense index.
  std::vector<uint32_t> by_inslot;
  std::unordered_map<uint32_t, uint32_t> slot_of;
  // Input index -> decoded index where they differ (spec 2.3: an isolated
  // vertex coded while others wait for their triangle).
  std::unordered_map<uint32_t, uint32_t> renumbered;
  std::vector<PendingVertex> pending;  // introduced, not used yet
  std::vector<uint32_t> expect_final;  // input indices the input must finalize now
  uint32_t next_in = 0;                // next input dense index
  uint64_t next_out = 0;               // next decoded dense index
  int64_t last_pos[3] = {0, 0, 0};
  // Quantized: half the grid step, and the highest grid index 2^bits - 1.
  double half_step = 0;
  double grid_max = 0;

  // The open chunk.
  std::vector<uint8_t> records;
  uint32_t chunk_records = 0, chunk_vertices = 0, chunk_triangles = 0;
  // Spec 4.5: the stream checksum chains the checksums of the header and
  // of every chunk (their last 4 bytes), then the end record's fields.
  uint32_t chain_crc = 0;

  Status emit(const std::vector<uint8_t>& bytes) {
    stats.total_bytes += bytes.size();
    return out->write(bytes.data(), bytes.size());
  }
  // Appends the checksum of record `rec` and chains it (spec 4.5).
  void seal(std::vector<uint8_t>* rec);

  Status fail(Status s) {
    if (error.ok()) error = s;
    return error;
  }

  uint32_t out_index_of(uint32_t in) const {
    auto it = renumbered.find(in);
    return it == renumbered.end() ? in : it->second;
  }

  Status begin(const MeshSchema& schema);
  // Codes the record's attributes (spec 8.3): a triangle's corners (vertex
  // slots) and edge slots, which corners are new and which edges enter;
  // an isolated vertex without corners.
  void code_attributes(const uint32_t* corner, const uint32_t* eslot, uint8_t fresh, uint8_t entering,
                       uint8_t final = 0, bool flush = false);
  // The coded coordinates of vertex `index` at `p` (spec 7.1, 7.2). Errors:
  // kBadValue (not finite, not a float for a float position type, outside
  // the grid), kLimit (would not decode within half a step).
  Status coded_position(const double p[3], uint32_t index, int64_t out[3]);
  // How far from `p` its decoded value `x` may be (spec 2.3 and 7.1).
  double round_trip_bound(double p, double x, double origin, bool is_float) const;
  Status introduce(const PendingVertex& v);
  // Gives a coded new vertex its boundary slot.
  Status register_vertex(const PendingVertex& v, uint32_t* slot);
  // The candidate gates of a triangle that introduces `nnew` (0 or 1)
  // vertices (pend[k] >= 0: corner k is new): per corner k, the open edge
  // that its edge k (corner k to k + 1) completes, else kNone. An error
  // when there is none.
  Status candidate_gates(const SequenceTriangle& t, const int pend[3], const uint32_t slots[3], int nnew,
                         uint32_t cand[3]) const;
  Status triangle(const SequenceTriangle& t);
  // What triangle() does after the record is coded: checks the op,
  // applies the triangle to the boundary, expects the finalized vertices.
  Status close_triangle(const SequenceTriangle& t, BTriangle& bt, int nnew);
  // What every triangle ends with (spec 6.4): the corners left with no
  // open edge (bit k of `final` for corner[k]) are finalized, in canonical
  // corner order, and the input must finalize exactly these next; then the
  // face's property values and the counts.
  Status end_triangle(const uint32_t corner[3], uint32_t final, const PropertyValues& face);
  // kLimit: more `what` than the boundary limit.
  Status boundary_full(const char* what) const;
  // The active vertex `key` by the input's boundary slot `hint`, else kNone.
  uint32_t slot_by_hint(uint32_t hint, uint32_t key) const {
    const uint32_t s = hint < by_inslot.size() ? by_inslot[hint] : kNone;
    return s != kNone && boundary.vertex_live(s) && boundary.vertex(s).key == key ? s : kNone;
  }
  Status isolated(size_t pending_at);
  Status close_chunk();
  // Segments (spec 4.6): the triangle count at which the next segment
  // begins; set when a chunk closed there and the next record must come
  // after a segment record; the records so far; per segment record, its
  // offset and the vertex and triangle counts before it (the index, 4.7).
  uint64_t segment_next = 0;
  bool segment_due = false;
  uint64_t records_so_far = 0;
  std::vector<std::array<uint64_t, 3>> segments;
  // Writes the segment record of the state now, then restarts the free
  // slots and the attribute models as a decoder does.
  Status write_segment();
  Status after_record();

  // The records (record_encoder.cpp, spec section 13).
  bool rans = false;  // the back-end (spec 13.2): rANS, else adaptive
  RansSymbols fast_symbols;              // the open chunk's symbols, in order
  RawWriter fast_raw;                    // and its raw bits
  uint64_t fast_raw_geometry = 0;        // of those, position residuals' (measure_costs)
  FastRing ring;
  int fast_context = kFastAStartContext;  // the previous record's class (table A)
  bool fast_choices = false;  // gate records code a prediction choice (fast_codes_choices())
  int fast_choice = 0;                    // the previous prediction choice
  // Running symbol counts, per table and symbol (the chunk's tables are
  // built from their growth since the chunk began, record_section()); with
  // choices, for pricing them (fast_cost()): per table, twice its total
  // plus its alphabet size (counts doubled, half a count for every symbol)
  // and that number's log2 in 1/65536 bits, set up by begin_records().
  std::vector<uint32_t> fast_count = std::vector<uint32_t>(size_t{kAdaptiveTables} * 128, 0);
  std::vector<uint32_t> fast_chunk_base;  // fast_count when the open chunk began (record_section())
  std::vector<uint64_t> fast_denominator;
  std::vector<int32_t> fast_log_denominator;
  // For the priced tables, the log2 of each symbol's doubled count plus
  // one (fast_cost()'s numerator), kept by fast_put(): a price then takes
  // no logarithm (choosing a prediction prices up to 20 symbols a vertex).
  // (int32: a log2 below 64 in 1/65536 bits fits, and the tables take
  // half the cache.)
  std::vector<int32_t> fast_log_count;
  void begin_records();
  Status code_triangle(const SequenceTriangle& t, const int pend[3], const uint32_t slots[3], int nnew);
  // Spec 13.7.1: the class of a gate record among the candidate gates
  // cand (per input corner k, as candidate_gates() gives them): R, its
  // next or prev, else the lowest recency rank (kFastGateFar, *rank set),
  // else kFastEscape. Sets *rot to the input corner of the chosen gate's
  // canonical corner 0 (the first candidate for an escape). *rank must be
  // -1 on entry.
  int gate_class(const uint32_t cand[3], int* rot, int* rank) const;
  // A gate record's symbols after its class (spec 13.7.3): a far gate's
  // rank and the B symbol; then the next record's context.
  void put_gate(int cls, int rank, uint32_t gate, int third, int e1, int e2);
  void count_gate(int cls) {
    ++stats.gates[cls == kFastStart ? 3 : cls == kFastGateR ? 0 : cls == kFastEscape || cls == kFastGateFar ? 2 : 1];
    if (cls == kFastGateFar || cls == kFastEscape) ++stats.far_gates[cls == kFastGateFar ? 0 : 1];
  }
  // The direct path for the common triangle of an input
  // that gives boundary slots (the converter's and the decoders'): an add
  // or a fill on a gate of class 0 to 3, without borders, re-appearances
  // or face properties. It finds the gate and the completed neighbour
  // from the input's edge slots (checked against the boundary: an open
  // edge between two vertices in one direction is unique), codes the
  // record as code_triangle() would, with the same bytes, and applies it
  // with lean_add() or lean_fill(). Returns false, having changed nothing,
  // for any other triangle or any check that fails: the general path then
  // codes it, or reports the error. Otherwise sets *status.
  bool fast_direct(const SequenceTriangle& t, Status* status);
  // Input edge slot -> edge slot of the open edge it named when it
  // entered (fast_direct()'s lookups; a stale entry fails its check).
  std::vector<uint32_t> by_ineslot;
  // Remembers that input edge slot `in` (kNoSlot: none) names edge slot
  // `slot`.
  void note_input_edge(uint32_t in, uint32_t slot) {
    if (in < by_ineslot.size()) by_ineslot[in] = slot;
    else note_input_edge_grow(in, slot);
  }
  PSQ_NOINLINE void note_input_edge_grow(uint32_t in, uint32_t slot);
  void code_isolated(PendingVertex& v);
  void fast_put(int table, int symbol);
  // Codes residual r with length table `table`; returns its bit length.
  int fast_residual(int table, int64_t r);
  void fast_vertex(const PendingVertex& v, const int64_t pred[3], int kind, const int extent[3]);
  int64_t fast_cost(int table, int symbol) const;  // in 1/65536 bits
  int choose_prediction(uint32_t gate, uint32_t mask, const int64_t pos[3], Prediction* pred);
  // Codes the new vertex v of a triangle on `gate` (spec 13.8): the
  // prediction choice among the gate's neighbours, if the stream codes
  // choices (fast_choices), `choices` is set (not for an escape, 13.7.5)
  // and there are any; then its residuals.
  void gate_vertex(const PendingVertex& v, uint32_t gate, bool choices);
  // The record section of the open chunk in the stream's back-end (spec
  // 13.2).
  void record_section(std::vector<uint8_t>* section);
  Status finish();
};

}  // namespace psq

#endif  // PSQ_CODEC_ENCODER_IMPL_H_
