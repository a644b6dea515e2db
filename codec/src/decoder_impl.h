// SPDX-License-Identifier: Apache-2.0
// codec/src/decoder_impl.h: the state of the .psq decoder
// (psq/psq_codec.h), shared by its two files: decoder.cpp (the container,
// properties, attributes and the output of events) and record_decoder.cpp
// (the records of spec section 13, templates over the symbol decoder of
// either entropy back-end, symbol_coder.h).
#ifndef PSQ_CODEC_DECODER_IMPL_H_
#define PSQ_CODEC_DECODER_IMPL_H_

#include <algorithm>
#include <cmath>
#include <deque>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "boundary.h"
#include "coding.h"
#include "container.h"
#include "crc32c.h"
#include "neighbors.h"
#include "records.h"
#include "attributes.h"
#include "properties.h"
#include "psq/io.h"
#include "psq/psq_codec.h"
#include "psq/psq_memory.h"
#include "range_coder.h"
#include "rans.h"
#include "segment.h"
#include "symbol_coder.h"

namespace psq {

// An internal header of the decoder's two files, which both work in the
// codec's namespace.
using namespace codec;

namespace codec {
// Fuzzing builds accept any checksum, so that the fuzzer reaches the record
// decoder behind them (as zstd does); every other check still runs.
inline bool checksum_ok(uint32_t stored, uint32_t computed) {
#ifdef FUZZING_BUILD_MODE_UNSAFE_FOR_PRODUCTION
  (void)stored;
  (void)computed;
  return true;
#else
  return stored == computed;
#endif
}

// What a segment decoded alone (PsqDecoder::start_segment()) leaves for a
// caller that decodes every segment to check them together (parallel.cpp):
// the state block it started from and the one its state serializes to at
// its end, its checksum fields in order (4.5), and the end record's fields.
struct AloneResult {
  std::vector<uint8_t> start_state, end_state;
  uint32_t header_chain = 0;          // the stream checksum's chain after the header
  std::vector<uint8_t> chain_fields;  // the checksum fields it read (4 bytes each)
  std::vector<uint8_t> end_bytes;     // the end record before its checksum
  uint32_t end_checksum = 0;
  uint64_t end_fields[5] = {0, 0, 0, 0, 0};
  uint64_t end_index_at = 0;
  bool reached_end = false;  // this segment is the last
  uint64_t stopped_at = 0;   // the offset of the segment record it stopped at
};

// Spec 4.5: the end record's fields (vertices, triangles, chunks, the two
// boundary maxima) and index offset against the stream's, which put its
// index at `index_at`; kBadHeader at the end record's offset `at`.
Status check_end(const uint64_t fields[5], uint64_t index_field, uint64_t index_at, const PsqStats& stats,
                 uint64_t at);
// kLimit when a position of a double stream became an infinity in the
// arrays (decode_into(), decode_mesh_segments()).
Status check_float_range(const PsqHeader& header, const MeshBuffers& mesh);
}  // namespace codec

struct PsqDecoder::Impl {
  InputStream* in = nullptr;
  PsqHeader header;
  Status error;
  bool opened = false, ended = false, measure = false;
  std::unique_ptr<PropertyUnpacker> props;
  // Normals, texture coordinates and colours (spec 8.3): the coder and
  // the chunk's attribute section with its range decoder.
  std::unique_ptr<AttributeCoder> attrs;
  std::vector<uint8_t> attr_bytes;
  std::unique_ptr<RangeDecoder> attr_rc;  // adaptive back-end
  FastAttributeReader attr_fast;          // rANS back-end
  uint64_t attr_offset = 0;
  std::vector<int32_t> attr_q;
  PropertyValues attr_columns;
  std::vector<int32_t> attr_cq;  // a triangle's corner values (spec 8.5)
  PsqStats stats;
  double cost[kCostCount] = {0, 0};
  uint32_t file_crc = 0;     // of the header's bytes (spec 4.2)
  bool in_header = true;
  uint32_t chain_crc = 0;    // spec 4.5: the block checksums, in order

  // The current chunk.
  std::vector<uint8_t> conn, packed, raw;
  // The chunk's record section: in place for memory input
  // (InputStream::view), else read into `conn`.
  const uint8_t* cdata = nullptr;
  size_t csize = 0;
  uint64_t conn_offset = 0, chunk_offset = 0;
  uint32_t records_left = 0, chunk_vertices = 0, chunk_triangles = 0;
  uint32_t seen_vertices = 0, seen_triangles = 0;

  uint64_t next_out = 0;
  uint64_t record_no = 0;
  int64_t last_pos[3] = {0, 0, 0};
  int64_t grid_max = 0;

  // Decoded events waiting for next(): event(qhead) to event(qcount - 1).
  SequenceEvent queue[7];
  size_t qhead = 0, qcount = 0;
  // Normals wait for their vertices to settle (spec 8.4): the events from
  // the first vertex whose normal is still to come are held back, in a
  // ring by their position among all held events, reported (report()) as
  // they are decoded and released in order once that normal has come:
  // [held_begin, held_ready) released, [held_ready, held_end) held.
  bool late = false;
  // Asked once: whether vertices wait for their normals (8.4) and
  // whether triangles have corner values (8.5); without, their steps
  // are skipped.
  bool late_vertices = false, corners = false;
  std::vector<SequenceEvent> held;
  std::vector<uint8_t> held_waiting;  // a vertex event whose normal is still to come
  uint64_t held_begin = 0, held_ready = 0, held_end = 0;
  std::deque<uint64_t> held_vertex;  // the held vertex events' positions, by dense index
  uint32_t held_first_vertex = 0;    // held_vertex.front()'s dense index
  SequenceEvent& event(size_t i) {
    return late ? held[(held_begin + i) & (held.size() - 1)] : queue[i];
  }
  // Appends a record's event to the ring.
  void hold(SequenceEvent& e);

  Status fail(Status s) {
    if (error.ok()) error = s;
    return error;
  }
  // The error that stopped the decoder, or kUsage before open().
  Status ready() {
    if (!error.ok()) return error;
    return opened ? Status() : fail(Status(ErrorCode::kUsage, "decoder not opened"));
  }
  Status read(void* dst, size_t n) {
    Status s = in->read_exact(dst, n);
    if (!s.ok()) {
      if (s.code() == ErrorCode::kTruncated)
        return Status(ErrorCode::kTruncated, "the stream ends inside a chunk or before its end record", in->offset());
      return s;
    }
    if (in_header) file_crc = crc32c_update(file_crc, dst, n);
    return Status();
  }
  // Reads n bytes in steps, so that a huge declared size allocates only as
  // the bytes actually arrive.
  Status read_block(size_t n, std::vector<uint8_t>* out) {
    out->clear();
    while (out->size() < n) {
      size_t k = std::min<size_t>(n - out->size(), size_t{1} << 20);
      size_t at = out->size();
      out->resize(at + k);
      PSQ_RETURN_IF_ERROR(read(out->data() + at, k));
    }
    return Status();
  }
  // Reads a varint field (spec 3.1) a byte at a time, appending its bytes
  // to `bytes` when given. A malformed varint is *bad_header* at its start.
  Status read_varint(uint64_t* v, std::vector<uint8_t>* bytes) {
    const uint64_t at = in->offset();
    uint8_t b[kMaxVarintBytes];
    for (size_t i = 0; i < kMaxVarintBytes; ++i) {
      PSQ_RETURN_IF_ERROR(read(&b[i], 1));
      if (bytes) bytes->push_back(b[i]);
      if (!(b[i] & 0x80)) {
        if (parse_varint(b, i + 1, v) > 0) return Status();
        break;
      }
    }
    return Status(ErrorCode::kBadHeader, "malformed varint", at);
  }
  // Reads a checksum field (spec 4.5) and checks it against `crc`: "<what>
  // checksum mismatch" at the field. `chain`: the field joins the stream
  // checksum's chain (and, alone, the fields its caller chains).
  Status read_checksum(uint32_t crc, const char* what, bool chain = true) {
    uint8_t c[4];
    const uint64_t at = in->offset();
    PSQ_RETURN_IF_ERROR(read(c, 4));
    if (!checksum_ok(Get(c, 4).u32(), crc)) return Status(ErrorCode::kChecksum, std::string(what) + " checksum mismatch", at);
    if (!chain) return Status();
    chain_crc = crc32c_update(chain_crc, c, 4);
    if (alone) alone_result.chain_fields.insert(alone_result.chain_fields.end(), c, c + 4);
    return Status();
  }
  Status corrupt(const std::string& what) {
    const uint64_t at = conn_offset;
    return Status(ErrorCode::kBadValue, "record " + std::to_string(record_no) + ": " + what, at);
  }

  // Segments (spec 4.6, 4.7). A decoder that starts at a segment record
  // (start_segment()) takes its counts from the state block: the records
  // (record_no), vertex events (next_out) and triangle events before it
  // (base_triangles); its stats count its own.
  uint64_t base_triangles = 0;
  uint64_t segment_next = 0;  // the triangle count where the next segment begins; 0: none
  // The segment records seen, as the index lists them.
  std::vector<PsqSegment> seen_segments;
  uint64_t index_at = 0;  // the index record's offset, once read
  // Decoding one segment alone (start_segment()): it ends at the next
  // segment record or at the end record.
  bool alone = false;
  AloneResult alone_result;
  uint64_t triangles_so_far() const { return base_triangles + stats.triangles; }
  // The state now (segment.h), and serialized into `out`.
  void capture_state(SegmentState* st, std::vector<uint8_t>* out);
  // The slots the events report (spec 4.6): a decoder that reads the
  // stream from its start restarts its boundary in the state's slots at a
  // segment record, but keeps reporting each element in the slot it was
  // reported with, and gives new elements free reported slots (the lowest
  // first after a segment record, then as they come free, last freed
  // first). Off until the first segment record (the slots are the
  // boundary's own) and for a decoder that starts at a segment (it
  // reports the state's slots). The maps are by the boundary's slots.
  bool report_slots = false;
  std::vector<uint32_t> report_vertex, report_edge;
  SlotStack report_vertex_free, report_edge_free;
  uint32_t report_vertex_top = 0, report_edge_top = 0;  // reported slots ever used
  // At a segment record, before restart(): the maps of the state's order.
  void keep_reported_slots(const SegmentState& st);
  // An event's slots as reported, as next() and pump() hand it out.
  void report(SequenceEvent& e);
  // A segment record (its tag read): decompressed into state_raw, and
  // checked against the decoder's state, or loaded by a decoder that
  // starts here (`load`).
  Status read_segment(bool load);
  Status read_index();
  // Spec 4.7: an index's n entries after its tag and count, whose bytes `f`
  // holds (tag first): three varint deltas each, summed into `out`; then
  // its checksum (read_checksum()).
  Status read_index_entries(uint64_t n, std::vector<uint8_t>* f, std::vector<PsqSegment>* out, bool chain);

  Status open(InputStream* stream);
  Status next_chunk();
  // The attributes of the record in the queue (spec 8.3), into its vertex
  // events' values, with the normals that settle (8.4), or at the end of a
  // chunk (`flush`) the normals still waiting.
  Status decode_attributes(bool flush = false);
  Status read_end();
  // The events of one record, in order (at most 3 vertices, a triangle and
  // 3 finalizations); the queue is empty before each record is decoded.
  SequenceEvent& push() { return queue[qcount++]; }
  // Decodes the next record (or chunk, or the end) into the queue.
  Status advance();

  // The position of coded coordinates `pos` (spec 7.1, 7.2), or the reason
  // they are not one.
  const char* position_of(const int64_t pos[3], double x[3]) const;
  // The triangle event of a record (spec 6.2.3, 6.4) and the
  // finalizations, from a BTriangle that `b` applied.
  void emit_triangle(FastBoundary& b, const BTriangle& bt, Op op, uint32_t r, uint8_t cut);
  // The triangle event of a common record (common_record), and the
  // finalizations of the corners in final_mask, whose slots it frees.
  void push_triangle(Op op, const uint32_t corner[3], const uint32_t eslot[3], uint8_t new_mask, uint8_t final_mask,
                     uint8_t leaving, uint8_t entering);

  // Direct output (decode_mesh): the common records (common_record()) write
  // their vertex and triangle here instead of queueing events; the other
  // records' events are drained into it by decode_into().
  MeshBuffers* direct = nullptr;
  // The mesh index of each vertex of the sequence (by dense index). Until
  // a vertex re-appears, every vertex is a new mesh vertex and the map is
  // the identity: it is not kept (direct_identity), which spares a store
  // per vertex and the array's pages. The first re-appearance writes it out.
  bool direct_identity = true;
  std::vector<uint32_t> direct_index;
  // The arrays are sized ahead and written through pointers; these are the
  // lengths in use (decode_into() trims the arrays to them at the end).
  size_t direct_np = 0, direct_ni = 0;  // positions, indices
  // Room for n more elements after the `used` ones of v: v's size grows
  // to twice its size, within the capacity (decode_into() reserves it), or
  // to used + n when that is more, which reallocates geometrically.
  template <class Vector>
  static typename Vector::value_type* direct_room(Vector& v, size_t used, size_t n) {
    if (used + n > v.size()) v.resize(std::max(used + n, std::min(2 * v.size(), v.capacity())));
    return v.data() + used;
  }
  // Whether positions are quantized floats (direct_position() applies).
  bool direct_float = false;
  // direct_records()'s view of the arrays, kept in locals so that
  // the compiler holds it in registers: the lengths in use, the data, and
  // how many more vertices and triangles fit before an array must grow
  // (a common record writes at most one of each). Its records take the
  // corners' mesh indices from the boundary's vertices (BVertex::key).
  struct DirectCursor {
    float* pos;
    uint32_t* idx;
    size_t verts, ni;  // positions written (direct_np / 3: no division per vertex), indices
    size_t vroom, troom;
  };
  // The cursor of the members' arrays and lengths; back into the members.
  DirectCursor direct_cursor() {
    const size_t np_end = std::min(direct->positions.size(), direct_np_end);
    const size_t ni_end = std::min(direct->indices.size(), direct_ni_end);
    return DirectCursor{direct->positions.data(), direct->indices.data(), direct_np / 3, direct_ni,
                        (np_end - direct_np) / 3, (ni_end - direct_ni) / 3};
  }
  // A segment decoded into its part of arrays that every segment shares
  // (decode_range()): the arrays never grow, and the segment writes
  // nothing beyond the ends of its part.
  bool direct_fixed = false;
  size_t direct_np_end = SIZE_MAX, direct_ni_end = SIZE_MAX;
  // Called between chunks with the ranges of the arrays written since the
  // last call (decode_mesh_segments()'s flush).
  std::function<Status(size_t, size_t, size_t, size_t)> direct_flush;
  size_t flushed_np = 0, flushed_ni = 0;
  Status flush_direct() {
    if (!direct_flush || (direct_np == flushed_np && direct_ni == flushed_ni)) return Status();
    PSQ_RETURN_IF_ERROR(direct_flush(flushed_np, direct_np, flushed_ni, direct_ni));
    flushed_np = direct_np;
    flushed_ni = direct_ni;
    return Status();
  }
  // The event path's check of fixed arrays: room for event e, and no
  // re-appearing vertex (whose mesh index another segment knows).
  Status direct_fixed_check(const SequenceEvent& e) const {
    if (e.kind == SequenceEvent::Kind::kVertex) {
      if (e.vertex.reappears != kNoVertex)
        return Status(ErrorCode::kUnsupported, "a re-appearing vertex in a segment decoded alone into arrays");
      if (direct_np + 3 > direct_np_end) return direct_overflow();
    } else if (e.kind == SequenceEvent::Kind::kTriangle) {
      if (direct_ni + 3 > direct_ni_end) return direct_overflow();
    }
    return Status();
  }
  Status direct_overflow() const {
    return Status(ErrorCode::kBadHeader, "the segment holds more vertex or triangle events than the index declares",
                  conn_offset);
  }
  void direct_sync(const DirectCursor& c) {
    direct_np = 3 * c.verts;
    direct_ni = c.ni;
  }
  // Grows the array that has no room left for one more vertex or triangle
  // (geometrically, or up to the capacity decode_into() reserved). Each
  // grows only when a record needs it: a chunk's room for vertices is its
  // declared count, which fills before its last fills come.
  // False, with fixed arrays (direct_fixed), when there is no room left.
  bool direct_grow(DirectCursor& c) {
    if (direct_fixed) return false;
    direct_sync(c);
    if (c.vroom == 0) direct_room(direct->positions, direct_np, 3);
    if (c.troom == 0) direct_room(direct->indices, direct_ni, 3);
    c = direct_cursor();
    return true;
  }
  // The float position of quantized float coordinates (spec 7.1) straight
  // into `out`: position_of() and the cast in one rounding; the same
  // checks. The caller knows the stream is quantized with float positions.
  const char* direct_position(const int64_t pos[3], float out[3]) const {
    for (int i = 0; i < 3; ++i) {
      if (static_cast<uint64_t>(pos[i]) > static_cast<uint64_t>(grid_max)) return "position outside the quantization grid";
      const float f = static_cast<float>(header.origin[i] + static_cast<double>(pos[i]) * header.step);
      if (!std::isfinite(f)) return "position is not finite";
      out[i] = f;
    }
    return nullptr;
  }
  // A vertex event into the arrays; returns its mesh index (a new position,
  // or the one of the vertex it re-appears as).
  uint32_t direct_vertex(const SequenceVertex& v) {
    if (v.reappears != kNoVertex) {
      if (direct_identity) {
        // The map stops being the identity here: write it out.
        direct_index.resize(v.index);
        for (uint32_t i = 0; i < v.index; ++i) direct_index[i] = i;
        direct_identity = false;
      }
      const uint32_t at = direct_index[v.reappears];
      direct_index.push_back(at);
      return at;
    }
    const uint32_t at = static_cast<uint32_t>(direct_np / 3);
    if (!direct_identity) direct_index.push_back(at);
    float* p = direct_room(direct->positions, direct_np, 3);
    for (int i = 0; i < 3; ++i) p[i] = static_cast<float>(v.position[i]);
    direct_np += 3;
    return at;
  }
  void direct_triangle(const uint32_t v[3]) {
    uint32_t* t = direct_room(direct->indices, direct_ni, 3);
    for (int k = 0; k < 3; ++k) t[k] = direct_identity ? v[k] : direct_index[v[k]];
    direct_ni += 3;
  }
  // Decodes the rest of the stream into `mesh` (PsqDecoder::pump() into a
  // sink that gives its arrays, psq/sequence.h).
  Status decode_into(MeshBuffers* mesh);
  // A segment decoded alone (start_segment()) into its part of `mesh`,
  // whose arrays are sized for the whole stream: positions [np_begin,
  // np_end) and indices [ni_begin, ni_end) (parallel.cpp).
  Status decode_range(MeshBuffers* mesh, size_t np_begin, size_t np_end, size_t ni_begin, size_t ni_end);
  // decode_into()'s and decode_range()'s loop.
  Status decode_loop();

  // The records (record_decoder.cpp, spec section 13).
  bool fast_choices = false;  // gate records code a prediction choice (fast_codes_choices())
  FastBoundary fboundary{1};
  Neighbors fneighbors;  // which active vertices an edge joins (the new-edge check, spec 13.6.3)
  std::vector<RansTable> ftables;  // kFastTables of them with the rANS back-end
  // A chunk's tables by index, the absent ones set_absent() (indexed
  // directly, so that finding a table is no load of its own).
  bool ftable_absent[kFastTables] = {};
  // The open chunk's symbol decoder: one of the two back-ends (spec
  // 13.2), chosen by the header's flag; the adaptive one's models.
  bool rans = false;
  std::unique_ptr<RansSymbolDecoder> frans;
  std::unique_ptr<AdaptiveSymbolDecoder> fadaptive;
  std::vector<SymbolModel> fmodels;
  RansSymbolDecoder& coder(RansSymbolDecoder*) { return *frans; }
  AdaptiveSymbolDecoder& coder(AdaptiveSymbolDecoder*) { return *fadaptive; }
  template <class D>
  D& coder() { return coder(static_cast<D*>(nullptr)); }
  std::unique_ptr<RawReader> fraw;
  FastRing ring;
  int fast_context = kFastAStartContext;
  int fast_choice = 0;
  // Reads the record section `conn` of a chunk (spec 13.2).
  Status open_records();
  // At the chunk's end: every byte of the symbol block and the raw block
  // used, and with the rANS back-end both states back at 2^16 (spec 13.9).
  Status close_records();
  // The next record; with `cls` >= 0 its class is decoded already, and
  // with `bsym` >= 0 also its gate and B symbol (a gate record).
  template <class D>
  Status decode_record(int cls = -1, uint32_t gate = kNone, int bsym = -1);
  // kDirect: the record goes into the arrays at `out` (direct_records).
  template <bool kDirect, class D>
  Status common_record(D& d, RawReader& bits, int cls, int bsym, uint32_t gate, DirectCursor* out);
  // common_record()'s ends and joins (B symbols kFastBEnd and kFastBJoin).
  template <bool kDirect, class D>
  Status end_or_join_record(D& d, RawReader& bits, int cls, int bsym, uint32_t gate, DirectCursor* out);
  // decode_mesh's loop over the rest of a fast chunk's records, when the
  // stream has no properties: adds and fills write the arrays directly,
  // other records go through decode_record() and their events are
  // drained into the arrays.
  template <class D>
  Status direct_records();
  // measure_it: add the symbol's and raw bits' cost to `cost` (measure on).
  template <class D>
  bool fast_residual(D& d, RawReader& raw, int table, int64_t* r, int* k, bool measure_it);
  // The residual of length symbol `s` (spec 13.8.3) from its raw bits;
  // false for a symbol beyond the escape or +2^63.
  bool residual_of_symbol(RawReader& raw, int s, int64_t* r, int* k);
  bool measure_escape = false;  // measuring: the next escape's raw bits are geometry
  // The decoded symbol s of `table`, its information content added to
  // `cost` when measuring (PsqDecoder::measure_costs).
  template <class D>
  int fast_symbol(D& d, int table) {
    const int s = d.decode(table);
    if (measure) measure_symbol(d, table, s);
    return s;
  }
  void measure_symbol(const RansSymbolDecoder&, int table, int s) {
    if (static_cast<unsigned>(s) < kFastSymbolStride) cost[fast_table_cost(table)] += fsymbol_cost[table * kFastSymbolStride + s];
  }
  void measure_symbol(const AdaptiveSymbolDecoder& d, int table, int) { cost[fast_table_cost(table)] += d.last_bits(); }
  // Measuring: the information content of each symbol of the chunk's
  // tables, kRansScaleBits - log2(frequency), 0 for a symbol the table
  // cannot code; per table, kFastSymbolStride entries (every symbol a
  // table decodes, kRansAbsent included). A lookup per symbol instead of a
  // logarithm.
  static constexpr int kFastSymbolStride = kRansAbsent + 1;
  std::vector<double> fsymbol_cost;
  double fraw_geometry_bits = 0;  // raw bits of position residuals in the chunk, when measuring
  uint64_t fraw_total_bits = 0;   // the chunk's raw block
  // A new vertex fits the chunk's count and the 2^32 - 1 vertices (spec 13.10).
  Status vertex_room();
  // "Coded data ends early" for the current record (truncated).
  Status early_end() const;
  // The three residuals of a new vertex predicted at `pred` (spec 13.8.1):
  // its coded position in `pos`.
  template <class D>
  Status fast_position(D& d, RawReader& bits, const int64_t pred[3], int kind, const int extent[3],
                       int64_t pos[3], bool measure_it);
  // A new vertex's event: its index and, when it re-appears, the distance;
  template <class D>
  Status vertex_begin(bool reappears, SequenceEvent* ev);
  // then its residuals against `pred`, its position with its checks (spec
  // 7.1, 7.2), its properties and the counts.
  template <class D>
  Status vertex_position(const int64_t pred[3], int kind, const int extent[3], int64_t pos[3],
                              SequenceEvent* ev);
};

}  // namespace psq

#endif  // PSQ_CODEC_DECODER_IMPL_H_
