// SPDX-License-Identifier: Apache-2.0
// codec/src/encoder.cpp: the .psq encoder (psq/psq_codec.h). Section
// numbers refer to spec/psq-format.md.
#include <algorithm>
#include <charconv>
#include <cmath>
#include <unordered_map>

#include "encoder_impl.h"
#include "container.h"
#include "crc32c.h"
#include "geometry.h"
#include "segment.h"

namespace psq {

using namespace codec;

namespace {

const char* const kAxisName[3] = {"x", "y", "z"};

// A double for a message: the shortest text that reads back to it.
std::string number_text(double v) {
  char buf[32];
  auto r = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, r.ptr);
}

}  // namespace

Status PsqEncoder::Impl::begin(const MeshSchema& schema) {
  if (begun) return bad_sequence("begin() called twice");
  begun = true;
  if (schema.position_type != ScalarType::kFloat32 && schema.position_type != ScalarType::kFloat64)
    return Status(ErrorCode::kUsage, "position type must be float or double");
  if (schema.vertex_properties.size() > kMaxProperties || schema.face_properties.size() > kMaxProperties)
    return Status(ErrorCode::kLimit, "more than " + std::to_string(kMaxProperties) + " properties");
  for (const auto* list : {&schema.vertex_properties, &schema.face_properties})
    for (const Property& p : *list)
      if (p.name.empty() || p.name.size() > 255)
        return Status(ErrorCode::kLimit, "property name empty or longer than 255 bytes");
  if (opt.boundary_limit < 1 || opt.boundary_limit > kMaxBoundaryLimit)
    return Status(ErrorCode::kUsage, "boundary limit must be 1.." + std::to_string(kMaxBoundaryLimit));
  if (opt.zstd_level < 1 || opt.zstd_level > 22) return Status(ErrorCode::kUsage, "zstd level must be 1..22");
  header.schema = schema;
  header.schema.has_bounds = false;
  header.lossless = opt.lossless;
  header.fast = rans = opt.fast;
  header.boundary_limit = opt.boundary_limit;
  if (opt.segment_triangles == EncodeOptions::kAutoSegments)
    opt.segment_triangles = EncodeOptions::auto_segment_triangles(schema);
  header.segment_triangles = opt.segment_triangles;
  segment_next = opt.segment_triangles;
  if (!opt.lossless) {
    if (opt.bits < 1 || opt.bits > 31) return Status(ErrorCode::kUsage, "quantization bits must be 1..31");
    if (!schema.has_bounds)
      return Status(ErrorCode::kUsage,
                    "quantization needs the bounding box before the first vertex (encode from the sequence "
                    "builder, or use lossless)");
    // Spec 7.1: the grid is the cube of the largest extent from the box's
    // minimum corner, divided into 2^bits - 1 steps, as Draco quantizes. A
    // box no grid of binary64 steps can cover is refused here, before any
    // output: quantizing it anyway would clamp positions to garbage (2.3).
    double extent = 0;
    for (int i = 0; i < 3; ++i) {
      const double lo = schema.bounds_min[i], hi = schema.bounds_max[i];
      if (!std::isfinite(lo) || !std::isfinite(hi))
        return Status(ErrorCode::kBadValue, "bounding box is not finite");
      if (lo > hi)
        return Status(ErrorCode::kUsage, std::string("bounding box minimum above its maximum on ") + kAxisName[i]);
      const double e = hi - lo;
      if (!std::isfinite(e))
        return Status(ErrorCode::kLimit, std::string("positions span ") + number_text(lo) + " to " + number_text(hi) +
                                             " on " + kAxisName[i] +
                                             ": the extent overflows a double, so no quantization grid holds "
                                             "them (encode lossless)");
      extent = std::max(extent, e);
      header.origin[i] = lo;
    }
    const double steps = static_cast<double>((uint64_t{1} << opt.bits) - 1);
    header.bits = opt.bits;
    // A flat or single-point box: any step keeps every position exactly.
    header.step = extent > 0 ? extent / steps : 1.0;
    if (!(header.step > 0))
      return Status(ErrorCode::kLimit, "positions span " + number_text(extent) + " at most: " +
                                           std::to_string(opt.bits) +
                                           "-bit quantization steps of it underflow to zero (encode lossless)");
    half_step = 0.5 * header.step;
    grid_max = steps;
    for (int i = 0; i < 3; ++i) last_pos[i] = static_cast<int64_t>(((uint64_t{1} << opt.bits) - 1) / 2);
  }
  boundary = Boundary(opt.boundary_limit);
  // Spec 8.3: normals and texture coordinates quantized only when asked
  // (and never in a lossless stream), colours always (they stay exact).
  if (!opt.lossless && (opt.normal_bits < 0 || opt.normal_bits == 1 || opt.normal_bits > 16))
    return Status(ErrorCode::kUsage, "normal bits must be 0 (exact) or 2..16");
  if (!opt.lossless && (opt.uv_bits < 0 || opt.uv_bits > 24))
    return Status(ErrorCode::kUsage, "texture coordinate bits must be 0 (exact) or 1..24");
  header.attributes =
      recognize_attributes(schema, opt.lossless ? 0 : opt.normal_bits, opt.lossless ? 0 : opt.uv_bits);
  attrs = std::make_unique<AttributeCoder>(schema, header.attributes);
  header.rotation = rotation_kept(schema, header.attributes);
  props = std::make_unique<PropertyPacker>(attrs->column_properties(), attrs->face_column_properties());
  if (!attrs->empty()) {
    if (!opt.fast) attr_rc = std::make_unique<RangeEncoder>(&attr_bytes);
    attr_q.resize(3 * static_cast<size_t>(attrs->dims()));
    attr_cq.resize(3 * static_cast<size_t>(attrs->corner_dims()));
    attr_face_q.resize(attr_cq.size());
  }
  if (opt.chunk_bytes < 1 || opt.chunk_bytes > kMaxRecordBytes / 2)
    return Status(ErrorCode::kUsage, "chunk size must be 1.." + std::to_string(kMaxRecordBytes / 2) + " bytes");
  std::vector<uint8_t> h = write_header(header);
  // The encoder writes only what its decoder accepts: the header is checked
  // by the decoder's own parser (names, limits, the float grid's range).
  uint64_t payload_size = 0;
  const int length_bytes = parse_varint(h.data() + kFixedHeaderBytes, h.size() - kFixedHeaderBytes, &payload_size);
  if (length_bytes <= 0 || payload_size > kMaxHeaderPayload)
    return Status(ErrorCode::kLimit, "header larger than " + std::to_string(kMaxHeaderPayload) + " bytes");
  PsqHeader check;
  check.version_major = kVersionMajor;
  check.lossless = header.lossless;
  check.rotation = header.rotation;
  Status hs = parse_header_payload(h.data() + kFixedHeaderBytes + length_bytes, payload_size, 0, &check);
  if (!hs.ok()) return Status(hs.code() == ErrorCode::kLimit ? ErrorCode::kLimit : ErrorCode::kBadValue,
                              "cannot encode this mesh: " + hs.message());
  stats.header_bytes = h.size();
  begin_records();
  chain_crc = crc32c_update(chain_crc, h.data() + h.size() - 4, 4);
  return emit(h);
}

Status PsqEncoder::Impl::coded_position(const double p[3], uint32_t index, int64_t q[3]) {
  const bool is_float = header.schema.position_type == ScalarType::kFloat32;
  for (int i = 0; i < 3; ++i) {
    if (!std::isfinite(p[i]))
      return Status(ErrorCode::kBadValue, "vertex " + std::to_string(index) + ": position is not finite");
    if (is_float && round_to_float(p[i]) != p[i])
      return Status(ErrorCode::kBadValue, "vertex " + std::to_string(index) + ": " + kAxisName[i] + " = " +
                                              number_text(p[i]) + " is not a float although the position type is");
    if (opt.lossless) {
      q[i] = is_float ? ordered_from_float(static_cast<float>(p[i])) : ordered_from_double(p[i]);
      continue;
    }
    // floor(v) for v in [0, max + 1) is v truncated. Outside it the nearest
    // grid point is more than half a step away: the box given to begin()
    // does not hold the position, and clamping would move it silently.
    const double v = (p[i] - header.origin[i]) / header.step + 0.5;
    if (!(v >= 0.0 && v < grid_max + 1.0))
      return Status(ErrorCode::kBadValue, "vertex " + std::to_string(index) + ": " + kAxisName[i] + " = " +
                                              number_text(p[i]) + " lies outside the quantization grid (" +
                                              number_text(header.origin[i]) + " to " +
                                              number_text(header.origin[i] + grid_max * header.step) +
                                              ", the bounding box given before the first vertex)");
    q[i] = static_cast<int64_t>(v);
    // The position as the decoder computes it (spec 7.1) must be within
    // half a step of the input, as 2.3 promises. Nearly always it is at
    // once; else the bound allows for the roundings of that computation.
    double x = header.origin[i] + static_cast<double>(q[i]) * header.step;
    if (is_float) x = round_to_float(x);
    const double off = std::fabs(x - p[i]);
    if (!(off <= half_step) && !(off <= round_trip_bound(p[i], x, header.origin[i], is_float)))
      return Status(ErrorCode::kLimit, "vertex " + std::to_string(index) + ": " + kAxisName[i] + " = " +
                                           number_text(p[i]) + " would decode as " + number_text(x) +
                                           ", more than half a quantization step (" + number_text(header.step) +
                                           ") away (encode lossless)");
  }
  return Status();
}

double PsqEncoder::Impl::round_trip_bound(double p, double x, double origin, bool is_float) const {
  // Half a step, plus the decoder's roundings (spec 7.1): the product
  // q * step (at most 2^31 * step * 2^-53), the sum and the rounding to the
  // position type (an ulp of the result, or of the origin when it is the
  // larger term), and the encoder's own rounding of (p - origin) / step
  // (under 2^-21 steps).
  const double a = std::max(std::fabs(p), std::fabs(x));
  const double ulp = is_float ? static_cast<double>(std::nextafter(static_cast<float>(a), HUGE_VALF) -
                                                    static_cast<float>(a))
                              : std::nextafter(a, HUGE_VAL) - a;
  const double o = std::fabs(origin);
  return half_step + header.step * 0x1p-19 + ulp + (std::nextafter(o, HUGE_VAL) - o);
}

// Gives the next decoded index to `v`, remembering it when it differs from
// the input's (spec 2.3).
Status PsqEncoder::Impl::introduce(const PendingVertex& v) {
  if (!attrs->empty()) {
    if (attr_rec.nnew == 3) return bad_sequence("more than three new vertices in one record");
    PSQ_RETURN_IF_ERROR(attrs->split(v.values, v.in_index, &attr_columns,
                                     attr_q.data() + attr_rec.nnew * attrs->dims()));
    attr_rec.index[attr_rec.nnew++] = static_cast<uint32_t>(next_out);
  }
  if (!props->add_vertex(attrs->empty() ? v.values : attr_columns))
    return Status(ErrorCode::kBadValue, "vertex " + std::to_string(v.in_index) +
                                            ": a property value does not fit its type");
  uint32_t out_index = static_cast<uint32_t>(next_out++);
  if (out_index != v.in_index) renumbered[v.in_index] = out_index;
  if (v.reappears != kNoVertex) {
    // The re-appeared vertex must be coded before this one (spec 6.3); it
    // is not when it still waits for its triangle while this one is coded.
    bool waiting = false;
    for (const PendingVertex& p : pending) waiting = waiting || (p.in_index == v.reappears && !p.coded);
    if (waiting || out_index_of(v.reappears) >= out_index)
      return bad_sequence("vertex " + std::to_string(v.in_index) + " re-appears vertex " +
                          std::to_string(v.reappears) + ", which is not yet used");
  }
  ++stats.vertices;
  ++chunk_vertices;
  return Status();
}

// Spec 2.4: a gate is an open edge that the triangle completes; every
// gate record and escape names one of these (13.7.3, 13.7.5).
Status PsqEncoder::Impl::candidate_gates(const SequenceTriangle& t, const int pend[3], const uint32_t slots[3],
                                         int nnew, uint32_t cand[3]) const {
  for (int k = 0; k < 3; ++k) {
    cand[k] = kNone;
    if (pend[k] < 0 && pend[(k + 1) % 3] < 0) cand[k] = boundary.find_edge(slots[(k + 1) % 3], slots[k]);
  }
  if (cand[0] == kNone && cand[1] == kNone && cand[2] == kNone)
    return bad_sequence("triangle " + std::to_string(t.v[0]) + " " + std::to_string(t.v[1]) + " " +
                        std::to_string(t.v[2]) + " completes no boundary edge and introduces " +
                        std::to_string(nnew) + " vertices");
  return Status();
}

Status PsqEncoder::Impl::triangle(const SequenceTriangle& t) {
  if (segment_due) PSQ_RETURN_IF_ERROR(write_segment());
  {
    Status s;
    if (fast_direct(t, &s)) return s;
  }
  if (!expect_final.empty())
    return bad_sequence("vertex " + std::to_string(expect_final.front()) +
                        " is not finalized right after its last triangle (spec/psq-dump.md A.2)");
  if (t.v[0] == t.v[1] || t.v[1] == t.v[2] || t.v[0] == t.v[2]) return bad_sequence("degenerate triangle");
  int pend[3] = {-1, -1, -1};
  uint32_t slots[3] = {kNone, kNone, kNone};
  int nnew = 0;
  for (int k = 0; k < 3; ++k) {
    for (size_t i = 0; i < pending.size(); ++i)
      if (pending[i].in_index == t.v[k]) pend[k] = static_cast<int>(i);
    if (pend[k] >= 0) {
      ++nnew;
      continue;
    }
    slots[k] = slot_by_hint(t.vslot[k], t.v[k]);
    if (slots[k] != kNone) continue;
    // A vertex without a slot, or whose slot was too large for the array
    // (register_vertex()), is in the map.
    auto it = slot_of.find(t.v[k]);
    if (it == slot_of.end() && t.vslot[k] != kNoSlot)
      return bad_sequence("triangle uses vertex " + std::to_string(t.v[k]) + " with boundary slot " +
                          std::to_string(t.vslot[k]) + ", which is not its active vertex's");
    if (it == slot_of.end())
      return bad_sequence("triangle uses vertex " + std::to_string(t.v[k]) + ", which is not active");
    slots[k] = it->second;
  }
  if (static_cast<size_t>(nnew) != pending.size())
    return bad_sequence("vertex " + std::to_string(pending.front().in_index) +
                        " was introduced but the next triangle does not use it");
  if (nnew == 2) return bad_sequence("a triangle introduces exactly two vertices");
  return code_triangle(t, pend, slots, nnew);
}

Status PsqEncoder::Impl::register_vertex(const PendingVertex& v, uint32_t* slot) {
  const uint32_t s = boundary.new_vertex(out_index_of(v.in_index), v.in_index, v.pos);
  if (s == kNone) return boundary_full("active vertices");
  *slot = s;
  used.vertex_begins(s);
  // The input's slots stay below the size of its working set
  // (psq/sequence.h: the converter's waiting area, or the boundary); one
  // beyond the vertices introduced so far plus 2^20 goes to the map, so
  // that no input can make the array much larger than the stream.
  if (v.in_slot != kNoSlot && v.in_slot <= next_in + (uint64_t{1} << 20)) {
    if (v.in_slot >= by_inslot.size()) by_inslot.resize(std::max<size_t>(v.in_slot + 1, 2 * by_inslot.size()), kNone);
    by_inslot[v.in_slot] = s;
  } else {
    slot_of[v.in_index] = s;
  }
  return Status();
}

Status PsqEncoder::Impl::boundary_full(const char* what) const {
  return Status(ErrorCode::kLimit,
                "more than " + std::to_string(opt.boundary_limit) + " " + what + " (the boundary limit)");
}

Status PsqEncoder::Impl::isolated(size_t at) {
  if (segment_due) PSQ_RETURN_IF_ERROR(write_segment());
  PendingVertex v = std::move(pending[at]);
  pending.erase(pending.begin() + static_cast<std::ptrdiff_t>(at));
  PSQ_RETURN_IF_ERROR(introduce(v));
  code_isolated(v);
  code_attributes(nullptr, nullptr, 0, 0);
  return after_record();
}

void PsqEncoder::Impl::code_attributes(const uint32_t* corner, const uint32_t* eslot, uint8_t fresh,
                                       uint8_t entering, uint8_t final, bool flush) {
  if (attrs->empty()) return;
  AttributeRecord& r = attr_rec;
  r.triangle = corner != nullptr;
  r.flush = flush;
  if (r.triangle) {
    for (int k = 0; k < 3; ++k) {
      r.c[k] = corner[k];
      r.e[k] = eslot[k];
      r.v[k] = boundary.vertex(corner[k]).index;
      r.pos[k] = header.lossless ? nullptr : boundary.vertex(corner[k]).pos;
    }
    r.new_mask = fresh;
    r.entering_mask = entering;
    r.final_mask = final;
  }
  if (rans) {
    attrs->encode_fast(attr_fast, r, attr_q.data());
  } else {
    Encoder enc(attr_rc.get());
    attrs->encode(enc, r, attr_q.data());
  }
  r = AttributeRecord();
}

Status PsqEncoder::Impl::after_record() {
  ++chunk_records;
  ++records_so_far;
  stats.max_active_vertices = std::max(stats.max_active_vertices, boundary.active_vertices());
  stats.max_open_edges = std::max(stats.max_open_edges, boundary.open_edges());
  // The back-ends code a chunk at its end: estimate 4 bits a symbol for
  // the target size. The limit of a chunk's coded records (spec 10) must
  // hold whatever the symbols cost: with the rANS back-end a symbol costs
  // at most about kRansScaleBits bits (its frequency is at least 1; the
  // states' rounding adds a fraction of a bit over a chunk), and the
  // tables at most a presence bit and a gamma code per symbol.
  const size_t coded = fast_raw.bits() / 8 + fast_symbols.size() / 2;
  // An adaptive symbol costs at most 7 binary decisions (the largest
  // tree) of at most 12 bits each (a model's probability stays at least
  // 32/65536).
  constexpr size_t kTableBound = size_t{kFastTables} * (1 + kRansMaxSymbols * (2 * kRansScaleBits)) / 8 + 64;
  constexpr size_t kRecordBound = 4096;  // one more record, with room to spare
  const size_t symbol_bound = rans ? fast_symbols.size() * kRansScaleBits / 8 + kTableBound
                                   : fast_symbols.size() * (7 * 12) / 8 + 16;
  const bool full = fast_raw.bits() / 8 + symbol_bound + 8 + kRecordBound >= kMaxRecordBytes;
  // The attribute section is closed at the property target too, far
  // below its limit (spec 4.4): a record adds at most a few hundred bytes.
  // Spec 4.6: a segment begins after the record that brings the
  // triangles to a multiple of the segment size; its chunk ends there.
  if (segment_next != 0 && stats.triangles == segment_next) {
    segment_next += opt.segment_triangles;
    segment_due = true;
    return close_chunk();
  }
  if (coded >= opt.chunk_bytes || full || props->raw_size() >= kChunkPropertyTarget ||
      std::max(attr_bytes.size(), attr_fast.size_estimate()) >= kChunkPropertyTarget ||
      chunk_records >= kMaxChunkRecords)
    return close_chunk();
  return Status();
}

Status PsqEncoder::Impl::close_chunk() {
  if (chunk_records == 0) return Status();
  record_section(&records);
  std::vector<uint8_t> raw, packed;
  if (!props->empty()) {
    props->take(&raw);
    zstd_compress(raw, opt.zstd_level, &packed);
  }
  // Spec 8.4: the normals still waiting end the chunk's attributes.
  if (attrs->late()) code_attributes(nullptr, nullptr, 0, 0, 0, true);
  if (attr_rc) attr_rc->finish();
  if (rans && !attrs->empty()) attrs->finish_fast(attr_fast, &attr_bytes);
  std::vector<uint8_t> chunk;
  Put put(&chunk);
  put.u8(kChunkTag);
  put.varint(chunk_records);
  put.varint(chunk_vertices);
  put.varint(chunk_triangles);
  put.varint(records.size());
  put.varint(packed.size());
  put.varint(raw.size());
  put.varint(attr_bytes.size());
  const size_t fields = chunk.size();
  put.bytes(records.data(), records.size());
  put.bytes(packed.data(), packed.size());
  put.bytes(attr_bytes.data(), attr_bytes.size());
  stats.attribute_bytes += attr_bytes.size();
  attr_bytes.clear();
  if (attr_rc) attr_rc = std::make_unique<RangeEncoder>(&attr_bytes);
  seal(&chunk);
  stats.record_bytes += records.size();
  stats.property_bytes += packed.size();
  stats.chunk_overhead_bytes += fields + 4;
  ++stats.chunks;
  records.clear();
  chunk_records = chunk_vertices = chunk_triangles = 0;
  return emit(chunk);
}

void PsqEncoder::Impl::seal(std::vector<uint8_t>* rec) {
  Put(rec).u32(crc32c_update(0, rec->data(), rec->size()));
  chain_crc = crc32c_update(chain_crc, rec->data() + rec->size() - 4, 4);
}

Status PsqEncoder::Impl::write_segment() {
  segment_due = false;
  SegmentState st;
  st.records = records_so_far;
  st.vertices = next_out;
  st.triangles = stats.triangles;
  st.context = static_cast<uint32_t>(fast_context);
  st.choice = static_cast<uint32_t>(fast_choice);
  std::copy(last_pos, last_pos + 3, st.last);
  capture_boundary(boundary, &st);
  capture_dead(boundary, used, &st);
  if (!attrs->empty()) capture_attributes(*attrs, &st);
  std::vector<uint8_t> raw, packed;
  serialize_state(st, attrs->dims(), &raw);
  if (raw.size() <= kMaxStateRaw) zstd_compress(raw, std::max(opt.zstd_level, 19), &packed);
  if (raw.size() > kMaxStateRaw || packed.size() > kMaxStateBytes)
    return Status(ErrorCode::kLimit, "the boundary at triangle " + std::to_string(stats.triangles) +
                                         " is too large for a segment record (use fewer segments)");
  std::vector<uint8_t> rec;
  Put put(&rec);
  put.u8(kSegmentTag);
  put.varint(packed.size());
  put.varint(raw.size());
  put.bytes(packed.data(), packed.size());
  seal(&rec);
  segments.push_back({stats.total_bytes, st.vertices, st.triangles});
  ++stats.segments;
  stats.segment_bytes += rec.size();
  // Spec 4.6: the state restarts from its canonical form, as a decoder's
  // does: the slots renumbered in the state's order, the ring rebuilt,
  // the attribute models fresh. The maps from the input's slots follow.
  std::vector<uint32_t> vmap(boundary.vertex_capacity(), kNone), emap(boundary.edge_capacity(), kNone);
  for (uint32_t i = 0; i < st.vertex.size(); ++i) vmap[st.vertex[i].slot] = i;
  for (uint32_t j = 0; j < st.edge.size(); ++j) emap[st.edge[j].slot] = j;
  auto remap = [](const std::vector<uint32_t>& map, uint32_t s) { return s < map.size() ? map[s] : kNone; };
  for (uint32_t& s : by_inslot) s = remap(vmap, s);
  for (auto& kv : slot_of) kv.second = remap(vmap, kv.second);
  for (uint32_t& s : by_ineslot) s = remap(emap, s);
  boundary.reset();
  used.reset();
  load_state(st, &boundary, &used, &ring, attrs.get());
  attrs->restart_models();
  return emit(rec);
}

Status PsqEncoder::Impl::finish() {
  if (!expect_final.empty())
    return bad_sequence("vertex " + std::to_string(expect_final.front()) + " is never finalized");
  if (!pending.empty())
    return bad_sequence("vertex " + std::to_string(pending.front().in_index) + " is never used or finalized");
  if (boundary.active_vertices() != 0)
    return bad_sequence(std::to_string(boundary.active_vertices()) + " vertices are still active at the end");
  PSQ_RETURN_IF_ERROR(close_chunk());
  // Spec 4.7: the index of the segment records (none for a stream of one
  // segment), which also tells a reader where the end record is.
  uint64_t index_at = 0;
  {
    std::vector<uint8_t> index;
    Put put(&index);
    put.u8(kIndexTag);
    put.varint(segments.size());
    std::array<uint64_t, 3> prev = {0, 0, 0};
    for (const auto& s : segments) {
      for (int i = 0; i < 3; ++i) put.varint(s[i] - prev[i]);
      prev = s;
    }
    seal(&index);
    index_at = stats.total_bytes;
    stats.segment_bytes += index.size();
    PSQ_RETURN_IF_ERROR(emit(index));
  }
  std::vector<uint8_t> end;
  Put put(&end);
  put.u8(kEndTag);
  put.varint(stats.vertices);
  put.varint(stats.triangles);
  put.varint(stats.chunks);
  put.varint(stats.max_active_vertices);
  put.varint(stats.max_open_edges);
  put.u64(index_at);
  put.u32(crc32c_update(chain_crc, end.data(), end.size()));
  stats.chunk_overhead_bytes += end.size();
  stats.connectivity_bits = cost[kCostConnectivity];
  stats.geometry_bits = cost[kCostGeometry];
  return emit(end);
}

// ------------------------------------------------------------------ API

PsqEncoder::PsqEncoder(ByteWriter* out, const EncodeOptions& options) : impl_(std::make_unique<Impl>()) {
  impl_->out = out;
  impl_->opt = options;
}

PsqEncoder::~PsqEncoder() = default;

Status PsqEncoder::begin(const MeshSchema& schema) {
  if (!impl_->error.ok()) return impl_->error;
  return impl_->fail(impl_->begin(schema));
}

Status PsqEncoder::vertex(const SequenceVertex& v) {
  Impl& m = *impl_;
  if (!m.error.ok()) return m.error;
  if (!m.begun || m.finished) return m.fail(bad_sequence("vertex event outside begin()..finish()"));
  if (!m.expect_final.empty())
    return m.fail(bad_sequence("vertex " + std::to_string(m.expect_final.front()) +
                               " is not finalized right after its last triangle (spec/psq-dump.md A.2)"));
  if (v.index != m.next_in)
    return m.fail(bad_sequence("vertex " + std::to_string(v.index) + " introduced where " +
                               std::to_string(m.next_in) + " is next"));
  if (m.next_in == 0xffffffffu) return m.fail(Status(ErrorCode::kLimit, "more than 4294967295 vertices"));
  if (v.reappears != kNoVertex && v.reappears >= v.index)
    return m.fail(bad_sequence("vertex " + std::to_string(v.index) + " re-appears a later vertex"));
  if (m.pending.size() >= 3)
    return m.fail(bad_sequence("vertex " + std::to_string(m.pending.front().in_index) +
                               " was introduced but the next triangle does not use it"));
  if (!values_match(m.header.schema.vertex_properties, v.values))
    return m.fail(Status(ErrorCode::kBadValue, "vertex property values do not match the schema"));
  PendingVertex p;
  p.in_index = v.index;
  p.in_slot = v.slot;
  p.reappears = v.reappears;
  if (!v.values.empty()) p.values = v.values;
  Status s = m.coded_position(v.position, v.index, p.pos);
  if (!s.ok()) return m.fail(s);
  ++m.next_in;
  m.pending.push_back(std::move(p));
  return Status();
}

Status PsqEncoder::triangle(const SequenceTriangle& t) {
  Impl& m = *impl_;
  if (!m.error.ok()) return m.error;
  if (!m.begun || m.finished) return m.fail(bad_sequence("triangle event outside begin()..finish()"));
  Status s = m.triangle(t);
  if (!s.ok()) return m.fail(s);  // not on success: fail() copies the status twice
  return s;
}

Status PsqEncoder::finalize(uint32_t index) {
  Impl& m = *impl_;
  if (!m.error.ok()) return m.error;
  if (!m.begun || m.finished) return m.fail(bad_sequence("finalize event outside begin()..finish()"));
  auto it = std::find(m.expect_final.begin(), m.expect_final.end(), index);
  if (it != m.expect_final.end()) {
    m.expect_final.erase(it);
    return Status();
  }
  if (!m.expect_final.empty())
    return m.fail(bad_sequence("vertex " + std::to_string(m.expect_final.front()) +
                               " is not finalized right after its last triangle (spec/psq-dump.md A.2)"));
  for (size_t i = 0; i < m.pending.size(); ++i)
    if (m.pending[i].in_index == index) return m.fail(m.isolated(i));
  return m.fail(bad_sequence("vertex " + std::to_string(index) +
                             " is finalized while boundary edges touch it, or is not active"));
}

Status PsqEncoder::finish() {
  Impl& m = *impl_;
  if (!m.error.ok()) return m.error;
  if (!m.begun || m.finished) return m.fail(bad_sequence("finish() without begin() or twice"));
  Status s = m.finish();
  m.finished = true;
  return m.fail(s);
}

const PsqStats& PsqEncoder::stats() const { return impl_->stats; }

}  // namespace psq
