// SPDX-License-Identifier: Apache-2.0
// codec/src/decoder.cpp: the .psq decoder (psq/psq_codec.h). Section
// numbers refer to spec/psq-format.md.
#include <algorithm>
#include <new>
#include <cmath>

#include "decoder_impl.h"
#include "geometry.h"

namespace psq {

Status PsqDecoder::Impl::open(InputStream* stream) {
  in = stream;
  uint8_t fixed[kFixedHeaderBytes];
  size_t avail = 0;
  PSQ_RETURN_IF_ERROR(in->fill(kFixedHeaderBytes, &avail));
  if (avail < 8 || !is_psq(in->cursor(), avail))
    return Status(ErrorCode::kUnknownFormat, "not a .psq stream (no PSQ magic)", 0);
  PSQ_RETURN_IF_ERROR(read(fixed, kFixedHeaderBytes));
  Get get(fixed + 8, 4);
  header.version_major = get.u8();
  header.version_minor = get.u8();
  uint16_t flags = get.u16();
  // Spec 4.2, 11: another major version is unsupported; any minor version
  // of this one is read.
  if (header.version_major != kVersionMajor)
    return Status(ErrorCode::kUnsupported, "format version " + std::to_string(header.version_major) + "." +
                                               std::to_string(header.version_minor) + "; this psq reads " +
                                               std::to_string(kVersionMajor) + ".x", 8);
  if (flags & ~kKnownFlags)
    return Status(ErrorCode::kUnsupported, "unknown header flags (value " + std::to_string(flags & ~kKnownFlags) + ")", 10);
  uint64_t length = 0;
  PSQ_RETURN_IF_ERROR(read_varint(&length, nullptr));
  const uint64_t payload_at = in->offset();
  if (length > kMaxHeaderPayload)
    return Status(ErrorCode::kLimit, "header payload of " + std::to_string(length) + " bytes (limit " +
                                         std::to_string(kMaxHeaderPayload) + ")", 12);
  header.lossless = flags & kFlagLossless;
  header.rotation = flags & kFlagRotation;
  header.fast = rans = flags & kFlagFast;
  fast_choices = fast_codes_choices(header.lossless, rans);
  std::vector<uint8_t> payload;
  PSQ_RETURN_IF_ERROR(read_block(length, &payload));
  PSQ_RETURN_IF_ERROR(read_checksum(file_crc, "header"));
  in_header = false;
  alone_result.header_chain = chain_crc;
  PSQ_RETURN_IF_ERROR(parse_header_payload(payload.data(), payload.size(), payload_at, &header));
  stats.header_bytes = payload_at + length + 4;
  {
    fboundary = FastBoundary(header.boundary_limit);
    // Address space for the slots that most streams need, so that the
    // arrays do not move and copy themselves as the boundary grows (each
    // doubling touches twice the pages). Reserved memory is not touched
    // until used, and the header's limit bounds it only up to 2^16 slots.
    const uint32_t slots = std::min<uint32_t>(header.boundary_limit, 1u << 16);
    fboundary.reserve(slots);
    fneighbors.reserve(slots);
    if (rans) {
      ftables.resize(kFastTables);  // absent until a chunk sends them
      std::fill(std::begin(ftable_absent), std::end(ftable_absent), true);
    }
  }
  attrs = std::make_unique<AttributeCoder>(header.schema, header.attributes);
  attr_q.resize(3 * static_cast<size_t>(attrs->dims()));
  attr_cq.resize(3 * static_cast<size_t>(attrs->corner_dims()));
  late = attrs->late();
  late_vertices = attrs->late_vertices();
  corners = attrs->corner_dims() > 0;
  props = std::make_unique<PropertyUnpacker>(attrs->column_properties(), attrs->face_column_properties());
  segment_next = header.segment_triangles;
  if (!header.lossless) {
    grid_max = static_cast<int64_t>((uint64_t{1} << header.bits) - 1);
    for (int i = 0; i < 3; ++i) last_pos[i] = grid_max / 2;
  }
  opened = true;
  return Status();
}

Status PsqDecoder::Impl::next_chunk() {
  chunk_offset = in->offset();
  uint8_t tag;
  PSQ_RETURN_IF_ERROR(read(&tag, 1));
  // Spec 4.6: a segment record comes exactly where the triangles reach a
  // multiple of the segment size, unless the stream ends there.
  const bool due = segment_next != 0 && triangles_so_far() == segment_next;
  if (tag == kSegmentTag) {
    if (!due || index_at != 0) return Status(ErrorCode::kBadHeader, "segment record where no segment begins", chunk_offset);
    if (alone) {
      // The segment decoded alone ends here; its caller compares the
      // state it reached with the next segment's block.
      SegmentState st;
      capture_state(&st, &alone_result.end_state);
      alone_result.stopped_at = chunk_offset;
      ended = true;
      return Status();
    }
    return read_segment(false);
  }
  if (tag == kIndexTag) return read_index();
  if (tag == kEndTag) {
    if (index_at == 0 && !alone) return Status(ErrorCode::kBadHeader, "the end record comes without an index", chunk_offset);
    return read_end();
  }
  if (tag != kChunkTag)
    return Status(ErrorCode::kBadHeader, "unknown chunk tag " + std::to_string(tag), chunk_offset);
  if (due)
    return Status(ErrorCode::kBadHeader, "a chunk where the segment record of triangle " +
                                             std::to_string(segment_next) + " must come", chunk_offset);
  if (index_at != 0) return Status(ErrorCode::kBadHeader, "a chunk after the index", chunk_offset);
  // Spec 4.3: seven varint fields.
  std::vector<uint8_t> f(1, kChunkTag);  // the tag and fields, for the checksum
  uint64_t records, vertices, triangles, conn_size, prop_size, prop_raw, attr_size;
  for (uint64_t* field : {&records, &vertices, &triangles, &conn_size, &prop_size, &prop_raw, &attr_size})
    PSQ_RETURN_IF_ERROR(read_varint(field, &f));
  auto bad = [&](const std::string& what) { return Status(ErrorCode::kBadHeader, "chunk: " + what, chunk_offset); };
  if (records == 0 || records > kMaxChunkRecords) return bad("record count " + std::to_string(records) + " not in 1..2^24");
  if (triangles > records || vertices > 3ull * records) return bad("more vertices or triangles than its records hold");
  if (conn_size > kMaxRecordBytes || prop_size > kMaxPropertyBytes || prop_raw > kMaxPropertyRaw ||
      attr_size > kMaxAttributeBytes)
    return bad("a section is larger than the limits of spec 4.4");
  if (attrs->empty() && attr_size != 0) return bad("attribute section without attributes");
  const bool has_props = !attrs->column_properties().empty() || !attrs->face_column_properties().empty();
  if (!has_props && (prop_size != 0 || prop_raw != 0)) return bad("property section without properties");
  if (has_props && prop_size == 0) return bad("no property section");
  if (segment_next != 0 && triangles_so_far() + triangles > segment_next)
    return bad("its triangles run past the segment start at triangle " + std::to_string(segment_next));
  uint32_t crc = crc32c_update(0, f.data(), f.size());
  conn_offset = in->offset();
  csize = static_cast<size_t>(conn_size);
  cdata = in->view(csize);
  if (cdata == nullptr) {
    PSQ_RETURN_IF_ERROR(read_block(conn_size, &conn));
    cdata = conn.data();
  }
  crc = crc32c_update(crc, cdata, csize);
  PSQ_RETURN_IF_ERROR(read_block(prop_size, &packed));
  crc = crc32c_update(crc, packed.data(), packed.size());
  attr_offset = in->offset();
  PSQ_RETURN_IF_ERROR(read_block(attr_size, &attr_bytes));
  crc = crc32c_update(crc, attr_bytes.data(), attr_bytes.size());
  PSQ_RETURN_IF_ERROR(read_checksum(crc, "chunk"));
  if (has_props) {
    if (!zstd_decompress(packed.data(), packed.size(), prop_raw, &raw))
      return Status(ErrorCode::kBadValue, "property section does not decompress to its declared size",
                    conn_offset + conn_size);
    if (!props->load(std::move(raw), vertices, triangles))
      return Status(ErrorCode::kBadValue, "property section does not match the chunk's vertices and triangles",
                    conn_offset + conn_size);
  }
  PSQ_RETURN_IF_ERROR(open_records());
  if (!attrs->empty() && rans) {
    if (const char* why = attrs->open_fast(attr_fast, attr_bytes.data(), attr_bytes.size()))
      return Status(ErrorCode::kBadValue, std::string("attribute section: ") + why, attr_offset);
  } else if (!attrs->empty()) {
    attr_rc = std::make_unique<RangeDecoder>(attr_bytes.data(), attr_bytes.size());
  }
  records_left = static_cast<uint32_t>(records);
  chunk_vertices = static_cast<uint32_t>(vertices);
  chunk_triangles = static_cast<uint32_t>(triangles);
  seen_vertices = seen_triangles = 0;
  ++stats.chunks;
  stats.record_bytes += conn_size;
  stats.property_bytes += prop_size;
  stats.attribute_bytes += attr_size;
  stats.chunk_overhead_bytes += f.size() + 4;
  return Status();
}

void PsqDecoder::Impl::capture_state(SegmentState* st, std::vector<uint8_t>* out) {
  st->records = record_no;
  st->vertices = next_out;
  st->triangles = triangles_so_far();
  st->context = static_cast<uint32_t>(fast_context);
  st->choice = static_cast<uint32_t>(fast_choice);
  std::copy(last_pos, last_pos + 3, st->last);
  capture_boundary(fboundary, st);
  capture_dead(fboundary, fneighbors, st);
  if (!attrs->empty()) capture_attributes(*attrs, st);
  serialize_state(*st, attrs->dims(), out);
}

void PsqDecoder::Impl::keep_reported_slots(const SegmentState& st) {
  // Spec 4.6: the elements keep the slots they were reported with; the
  // free reported slots are the others below the highest one ever used,
  // the lowest taken first. (decode_into() reports no slots.)
  if (direct != nullptr) return;
  if (!report_slots) {
    report_vertex_top = fboundary.vertex_capacity();
    report_edge_top = fboundary.edge_capacity();
  }
  auto remap = [&](std::vector<uint32_t>* to, uint32_t top, SlotStack* free, auto slot_of, size_t n) {
    std::vector<uint32_t> next(n);
    std::vector<uint8_t> used(top, 0);
    for (size_t i = 0; i < n; ++i) {
      const uint32_t old = slot_of(i);
      next[i] = !report_slots ? old : old < to->size() ? (*to)[old] : kNoSlot;
      if (next[i] < top) used[next[i]] = 1;
    }
    *to = std::move(next);
    free->clear();
    for (uint32_t k = top; k-- > 0;)
      if (!used[k]) free->push(k);
  };
  remap(&report_vertex, report_vertex_top, &report_vertex_free, [&](size_t i) { return st.vertex[i].slot; },
        st.vertex.size());
  remap(&report_edge, report_edge_top, &report_edge_free, [&](size_t j) { return st.edge[j].slot; }, st.edge.size());
  report_slots = true;
}

void PsqDecoder::Impl::report(SequenceEvent& e) {
  auto take = [](SlotStack& free, uint32_t& top) { return free.empty() ? top++ : free.pop(); };
  if (e.kind == SequenceEvent::Kind::kTriangle) {
    SequenceTriangle& t = e.triangle;
    // Every slot a triangle names but its entering edges' was mapped when
    // its element was reported or at the restart (keep_reported_slots()):
    // within the maps. The leaving edges' reported slots are looked up
    // first, then the entering edges take theirs, then the leaving ones
    // give theirs back (free again after the triangle: an entering edge
    // never takes one), and the finalized vertices theirs.
    const uint32_t leaving_mask = t.leaving_mask, entering_mask = t.entering_mask;
    uint32_t leaving[3] = {kNoSlot, kNoSlot, kNoSlot};
    if (leaving_mask)
      for (int k = 0; k < 3; ++k)
        if (leaving_mask >> k & 1) leaving[k] = report_edge[t.eslot[k]];
    if (entering_mask)
      for (int k = 0; k < 3; ++k)
        if (entering_mask >> k & 1) {
          const uint32_t s = t.eslot[k];
          if (s >= report_edge.size()) report_edge.resize(size_t{s} + 1, kNoSlot);
          t.eslot[k] = report_edge[s] = take(report_edge_free, report_edge_top);
        }
    if (leaving_mask)
      for (int k = 0; k < 3; ++k)
        if (leaving_mask >> k & 1) {
          t.eslot[k] = leaving[k];
          report_edge_free.push(leaving[k]);
        }
    const uint32_t* map = report_vertex.data();
    for (int k = 0; k < 3; ++k) t.vslot[k] = map[t.vslot[k]];
    if (t.final_mask)
      for (int k = 0; k < 3; ++k)
        if (t.final_mask >> k & 1) report_vertex_free.push(t.vslot[k]);
  } else if (e.kind == SequenceEvent::Kind::kVertex && e.vertex.slot != kNoSlot) {
    const uint32_t s = e.vertex.slot;
    if (s >= report_vertex.size()) report_vertex.resize(size_t{s} + 1, kNoSlot);
    e.vertex.slot = report_vertex[s] = take(report_vertex_free, report_vertex_top);
  }
}

Status PsqDecoder::Impl::read_segment(bool load) {
  // Spec 4.6: the tag, two varints, the zstd frame, the checksum.
  const uint64_t at = chunk_offset;
  std::vector<uint8_t> f(1, kSegmentTag);
  uint64_t packed_size, raw_size;
  PSQ_RETURN_IF_ERROR(read_varint(&packed_size, &f));
  PSQ_RETURN_IF_ERROR(read_varint(&raw_size, &f));
  auto bad = [&](const std::string& what) { return Status(ErrorCode::kBadHeader, "segment record: " + what, at); };
  if (packed_size == 0 || packed_size > kMaxStateBytes || raw_size > kMaxStateRaw)
    return bad("state block sizes beyond the limits of spec 4.4");
  uint32_t crc = crc32c_update(0, f.data(), f.size());
  const uint64_t block_at = in->offset();
  // Locals, not members: a state is up to a few MB on a long boundary, and
  // segment records are few; kept, they would stay in the peak memory.
  std::vector<uint8_t> state_packed, state_raw;
  PSQ_RETURN_IF_ERROR(read_block(packed_size, &state_packed));
  crc = crc32c_update(crc, state_packed.data(), state_packed.size());
  PSQ_RETURN_IF_ERROR(read_checksum(crc, "segment record"));
  if (!zstd_decompress(state_packed.data(), state_packed.size(), raw_size, &state_raw))
    return Status(ErrorCode::kBadValue, "segment record: state block does not decompress to its declared size", block_at);
  std::vector<uint8_t>().swap(state_packed);
  SegmentState st;
  if (load) {
    int64_t lo = 0, hi = grid_max;
    if (header.lossless) {
      const bool is_float = header.schema.position_type == ScalarType::kFloat32;
      lo = is_float ? -(int64_t{1} << 31) : INT64_MIN;
      hi = is_float ? (int64_t{1} << 31) - 1 : INT64_MAX;
    }
    if (const char* why = parse_state(state_raw.data(), state_raw.size(), header.boundary_limit, attrs->dims(), lo,
                                      hi, attrs.get(), &st))
      return Status(ErrorCode::kBadValue, std::string("segment record: ") + why, block_at);
    if (st.triangles == 0 || header.segment_triangles == 0 || st.triangles % header.segment_triangles != 0)
      return Status(ErrorCode::kBadValue, "segment record: its triangle count is no segment start", block_at);
    record_no = st.records;
    base_triangles = st.triangles;
    next_out = st.vertices;
    fast_context = static_cast<int>(st.context);
    fast_choice = static_cast<int>(st.choice);
    std::copy(st.last, st.last + 3, last_pos);
    segment_next = st.triangles;
    alone_result.start_state = std::move(state_raw);
  } else {
    {
      std::vector<uint8_t> state_mine;
      capture_state(&st, &state_mine);
      if (state_mine != state_raw)
        return Status(ErrorCode::kBadValue, "segment record: its state block is not the decoder's state", block_at);
    }
    std::vector<uint8_t>().swap(state_raw);
    keep_reported_slots(st);
  }
  // Spec 4.6: the state restarts in its canonical form: a fresh boundary,
  // neighbour lists, ring and attribute models.
  fboundary.reset();
  fneighbors.reset();
  load_state(st, &fboundary, &fneighbors, &ring, attrs.get());
  attrs->restart_models();
  seen_segments.push_back(PsqSegment{at, next_out, triangles_so_far()});
  segment_next += header.segment_triangles;
  ++stats.segments;
  stats.segment_bytes += f.size() + packed_size + 4;
  return Status();
}

Status PsqDecoder::Impl::read_index() {
  // Spec 4.7: the count, then per segment record three varint deltas.
  const uint64_t at = chunk_offset;
  auto bad = [&](const std::string& what) { return Status(ErrorCode::kBadHeader, "index: " + what, at); };
  if (index_at != 0) return bad("a second index");
  std::vector<uint8_t> f(1, kIndexTag);
  uint64_t n;
  PSQ_RETURN_IF_ERROR(read_varint(&n, &f));
  if (alone) {
    // A segment decoded alone knows only the segments up to its own;
    // the index's entries are its caller's to check.
    if (n > (uint64_t{1} << 32)) return bad("more entries than segments");
  } else if (n != seen_segments.size()) {
    return bad(std::to_string(n) + " entries for " + std::to_string(seen_segments.size()) + " segment records");
  }
  std::vector<PsqSegment> entries;
  PSQ_RETURN_IF_ERROR(read_index_entries(n, &f, &entries, true));
  for (size_t i = 0; i < entries.size() && !alone; ++i) {
    const PsqSegment &e = entries[i], &s = seen_segments[i];
    if (e.offset != s.offset || e.vertices != s.vertices || e.triangles != s.triangles)
      return bad("entry " + std::to_string(i) + " differs from its segment record");
  }
  index_at = at;
  stats.segment_bytes += f.size() + 4;
  return Status();
}

Status PsqDecoder::Impl::read_index_entries(uint64_t n, std::vector<uint8_t>* f, std::vector<PsqSegment>* out,
                                            bool chain) {
  PsqSegment e;
  for (uint64_t i = 0; i < n; ++i) {
    uint64_t d[3];
    for (uint64_t& x : d) PSQ_RETURN_IF_ERROR(read_varint(&x, f));
    e.offset += d[0];
    e.vertices += d[1];
    e.triangles += d[2];
    out->push_back(e);
  }
  return read_checksum(crc32c_update(0, f->data(), f->size()), "index", chain);
}

Status PsqDecoder::Impl::decode_attributes(bool flush) {
  AttributeRecord r;
  r.flush = flush;
  SequenceVertex* fresh[3] = {nullptr, nullptr, nullptr};
  SequenceTriangle* face = nullptr;  // the triangle, when it has corner values (8.5)
  for (size_t i = 0; i < qcount && !flush; ++i) {
    SequenceEvent& e = queue[i];
    if (e.kind == SequenceEvent::Kind::kVertex) {
      fresh[r.nnew] = &e.vertex;
      r.index[r.nnew++] = e.vertex.index;
    } else if (e.kind == SequenceEvent::Kind::kTriangle) {
      SequenceTriangle& t = e.triangle;
      r.triangle = true;
      if (corners) {
        face = &t;
        r.corners = attr_cq.data();
        r.event = held_end + i;  // where hold() puts it
      }
      for (int k = 0; k < 3; ++k) {
        r.v[k] = t.v[k];
        r.c[k] = t.vslot[k];
        r.e[k] = t.eslot[k];
        if (!header.lossless) r.pos[k] = fboundary.vertex(t.vslot[k]).pos;
      }
      r.new_mask = t.new_mask;
      r.entering_mask = t.entering_mask;
      r.final_mask = t.final_mask;
    }
  }
  const char* why;
  if (rans) {
    why = attrs->decode_fast(attr_fast, r, attr_q.data());
  } else {
    Decoder dec(attr_rc.get());
    why = attrs->decode(dec, r, attr_q.data());
  }
  if (why)
    return Status(ErrorCode::kBadValue, "record " + std::to_string(record_no) + ": " + why,
                  attr_offset + (rans ? 0 : attr_rc->consumed()));
  if (rans ? attr_fast.rans->overran() || attr_fast.raw->overran() : attr_rc->overran())
    return Status(ErrorCode::kTruncated, "record " + std::to_string(record_no) + ": attribute data ends early",
                  attr_offset + attr_bytes.size());
  if (face != nullptr) {
    attr_columns.swap(face->values);
    attrs->merge_face(attr_columns, attr_cq.data(), &face->values);
  }
  // A vertex's values are whole now unless its normal waits (8.4).
  if (!late_vertices) {
    for (int i = 0; i < r.nnew; ++i) {
      attr_columns.swap(fresh[i]->values);
      attrs->merge(attr_columns, attr_q.data() + i * attrs->dims(), &fresh[i]->values);
    }
    if (!late) return Status();  // nor corner normals: nothing is held
  }
  // Spec 8.4: the record's events join those held back; a vertex's
  // values stay its property columns until its normal comes.
  for (size_t i = 0; i < qcount && !flush; ++i) hold(queue[i]);
  if (face != nullptr)
    held_waiting[static_cast<size_t>(r.event & (held.size() - 1))] = static_cast<uint8_t>(attrs->pending_corners());
  for (const AttributeCoder::Settled& st : attrs->settled()) {
    const uint64_t k = uint64_t{st.index} - held_first_vertex;
    if (st.index < held_first_vertex || k >= held_vertex.size()) return corrupt("a normal for a vertex that does not wait for one");
    const uint64_t at = held_vertex[static_cast<size_t>(k)] & (held.size() - 1);
    SequenceVertex& v = held[static_cast<size_t>(at)].vertex;
    attr_columns.swap(v.values);
    attrs->merge(attr_columns, st.q, &v.values);
    held_waiting[static_cast<size_t>(at)] = 0;
  }
  // Spec 8.5: corner normals into the triangles that wait for them.
  if (corners)
    for (const AttributeCoder::SettledCorner& st : attrs->settled_corners()) {
      const size_t at = static_cast<size_t>(st.event & (held.size() - 1));
      if (st.event < held_ready || st.event >= held_end || held[at].kind != SequenceEvent::Kind::kTriangle ||
          held_waiting[at] == 0)
        return corrupt("a corner normal for a triangle that does not wait for one");
      attrs->patch_face(&held[at].triangle.values, st);
      --held_waiting[at];
    }
  const uint64_t mask = held.size() - 1;
  while (held_ready < held_end && !held_waiting[held_ready & mask]) {
    if (held[held_ready & mask].kind == SequenceEvent::Kind::kVertex) {
      held_vertex.pop_front();
      ++held_first_vertex;
    }
    ++held_ready;
  }
  qhead = 0;
  qcount = static_cast<size_t>(held_ready - held_begin);
  return Status();
}

void PsqDecoder::Impl::hold(SequenceEvent& e) {
  if (report_slots) report(e);
  if (held_end - held_begin == held.size()) {
    // A larger ring: each event moves to its position's new place.
    std::vector<SequenceEvent> grown(std::max<size_t>(64, 2 * held.size()));
    std::vector<uint8_t> waiting(grown.size());
    for (uint64_t p = held_begin; p < held_end; ++p) {
      std::swap(grown[p & (grown.size() - 1)], held[p & (held.size() - 1)]);
      waiting[p & (grown.size() - 1)] = held_waiting[p & (held.size() - 1)];
    }
    held.swap(grown);
    held_waiting.swap(waiting);
  }
  const size_t at = static_cast<size_t>(held_end++ & (held.size() - 1));
  SequenceEvent& h = held[at];
  // Only what the kind uses moves (the vectors keep their capacity).
  h.kind = e.kind;
  held_waiting[at] = e.kind == SequenceEvent::Kind::kVertex && late_vertices;
  switch (e.kind) {
    case SequenceEvent::Kind::kVertex:
      std::swap(h.vertex, e.vertex);
      if (held_vertex.empty()) held_first_vertex = h.vertex.index;
      held_vertex.push_back(held_end - 1);
      break;
    case SequenceEvent::Kind::kTriangle: std::swap(h.triangle, e.triangle); break;
    case SequenceEvent::Kind::kFinalize: h.finalized = e.finalized; break;
    case SequenceEvent::Kind::kEnd: break;
  }
}

Status PsqDecoder::Impl::read_end() {
  // Spec 4.5: the tag, five varint fields and the index's offset.
  std::vector<uint8_t> f(1, kEndTag);
  uint64_t fields[5];  // vertices, triangles, chunks, max_active, max_open
  for (uint64_t& field : fields) PSQ_RETURN_IF_ERROR(read_varint(&field, &f));
  uint8_t ix[8];
  PSQ_RETURN_IF_ERROR(read(ix, 8));
  f.insert(f.end(), ix, ix + 8);
  const uint64_t index_field = Get(ix, 8).u64();
  if (alone) {
    // The stream checksum and the fields are the caller's to check, over
    // every segment (parallel.cpp).
    AloneResult& r = alone_result;
    std::copy(fields, fields + 5, r.end_fields);
    r.end_index_at = index_field;
    r.end_bytes = f;
    uint8_t c[4];
    PSQ_RETURN_IF_ERROR(read(c, 4));
    r.end_checksum = Get(c, 4).u32();
  } else {
    PSQ_RETURN_IF_ERROR(read_checksum(crc32c_update(chain_crc, f.data(), f.size()), "stream", false));
    PSQ_RETURN_IF_ERROR(check_end(fields, index_field, index_at, stats, chunk_offset));
  }
  if (fboundary.active_vertices() != 0)
    return Status(ErrorCode::kBadHeader, "end record: the stream ends with " +
                                             std::to_string(fboundary.active_vertices()) + " vertices still active",
                  chunk_offset);
  bool at_end = false;
  PSQ_RETURN_IF_ERROR(in->at_end(&at_end));
  if (!at_end) return Status(ErrorCode::kBadHeader, "data after the end record", in->offset());
  alone_result.reached_end = ended = true;
  if (alone) return Status();
  stats.chunk_overhead_bytes += f.size() + 4;
  stats.total_bytes = in->offset();
  stats.connectivity_bits = cost[kCostConnectivity];
  stats.geometry_bits = cost[kCostGeometry];
  return Status();
}

namespace codec {

Status check_end(const uint64_t f[5], uint64_t index_field, uint64_t index_at, const PsqStats& s, uint64_t at) {
  auto bad = [&](const std::string& what) { return Status(ErrorCode::kBadHeader, "end record: " + what, at); };
  if (index_field == 0 || index_field != index_at)
    return bad("index offset " + std::to_string(index_field) + " is not the index's");
  if (f[0] != s.vertices || f[1] != s.triangles || f[2] != s.chunks)
    return bad("totals " + std::to_string(f[0]) + " vertices, " + std::to_string(f[1]) + " triangles, " +
               std::to_string(f[2]) + " chunks differ from the stream's " + std::to_string(s.vertices) + ", " +
               std::to_string(s.triangles) + ", " + std::to_string(s.chunks));
  if (f[3] != s.max_active_vertices || f[4] != s.max_open_edges) return bad("boundary maxima differ from the stream's");
  return Status();
}

Status check_float_range(const PsqHeader& header, const MeshBuffers& mesh) {
  // The arrays hold floats: a double stream's position beyond float range
  // (finite, by 7.1 and 7.2) became an infinity, which is refused rather
  // than returned.
  if (header.schema.position_type == ScalarType::kFloat64) {
    for (size_t i = 0; i < mesh.positions.size(); ++i)
      if (!std::isfinite(mesh.positions[i]))
        return Status(ErrorCode::kLimit, "vertex " + std::to_string(i / 3) +
                                             ": position beyond float range (decode_mesh returns floats; "
                                             "PsqDecoder gives doubles)");
  }
  return Status();
}

}  // namespace codec

Status PsqDecoder::Impl::decode_loop() {
  while (!ended) {
    if (records_left == 0) PSQ_RETURN_IF_ERROR(flush_direct());
    if (records_left > 0 && props->empty() && attrs->empty()) {
      PSQ_RETURN_IF_ERROR(rans ? direct_records<RansSymbolDecoder>() : direct_records<AdaptiveSymbolDecoder>());
      continue;
    }
    qhead = qcount = 0;
    PSQ_RETURN_IF_ERROR(advance());
    for (size_t i = 0; i < qcount; ++i) {
      const SequenceEvent& e = event(i);
      if (direct_fixed) PSQ_RETURN_IF_ERROR(direct_fixed_check(e));
      if (e.kind == SequenceEvent::Kind::kVertex) direct_vertex(e.vertex);
      else if (e.kind == SequenceEvent::Kind::kTriangle) direct_triangle(e.triangle.v);
    }
  }
  qhead = qcount = 0;
  return Status();
}

Status PsqDecoder::Impl::decode_range(MeshBuffers* mesh, size_t np_begin, size_t np_end, size_t ni_begin,
                                      size_t ni_end) {
  direct = mesh;
  direct_fixed = true;
  direct_np = np_begin;
  direct_ni = ni_begin;
  direct_np_end = np_end;
  direct_ni_end = ni_end;
  flushed_np = np_begin;
  flushed_ni = ni_begin;
  PSQ_RETURN_IF_ERROR(decode_loop());
  if (direct_np != np_end || direct_ni != ni_end) return direct_overflow();
  return flush_direct();
}

const char* PsqDecoder::Impl::position_of(const int64_t pos[3], double out[3]) const {
  const bool is_float = header.schema.position_type == ScalarType::kFloat32;
  for (int i = 0; i < 3; ++i) {
    double x;
    if (!header.lossless) {
      if (pos[i] < 0 || pos[i] > grid_max) return "position outside the quantization grid";
      x = header.origin[i] + static_cast<double>(pos[i]) * header.step;
      if (is_float) x = round_to_float(x);
    } else if (is_float) {
      if (pos[i] < -(int64_t{1} << 31) || pos[i] >= (int64_t{1} << 31)) return "position is not a float";
      x = static_cast<double>(float_from_ordered(pos[i]));
    } else {
      x = double_from_ordered(pos[i]);
    }
    if (!std::isfinite(x)) return "position is not finite";
    out[i] = x;
  }
  return nullptr;
}

void PsqDecoder::Impl::emit_triangle(FastBoundary& b, const BTriangle& bt, Op op, uint32_t r, uint8_t cut) {
  // The triangle in output order: output corner j is canonical (j + r) % 3.
  static constexpr uint8_t kCorner[3][3] = {{0, 1, 2}, {1, 2, 0}, {2, 0, 1}};
  const uint8_t* corner = kCorner[r];
  SequenceEvent& ev = push();
  ev.kind = SequenceEvent::Kind::kTriangle;
  SequenceTriangle& t = ev.triangle;
  t.op = op;
  // The masks without a jump per corner (which corners are new, final or
  // on a border varies from one triangle to the next).
  uint32_t new_mask = 0, final_mask = 0, border_mask = 0, cut_mask = 0, leaving_mask = 0, entering_mask = 0;
  for (int j = 0; j < 3; ++j) {
    const int k = corner[j];
    const uint32_t slot = bt.c[k];
    const EdgeState state = bt.state[k];
    t.v[j] = b.vertex(slot).index;
    t.vslot[j] = slot;
    t.eslot[j] = bt.eslot[k];  // kNone (kNoSlot) for a border: apply() sets it
    new_mask |= static_cast<uint32_t>(bt.is_new[k]) << j;
    final_mask |= static_cast<uint32_t>(bt.final[k]) << j;
    border_mask |= static_cast<uint32_t>(state == EdgeState::kBorder) << j;
    cut_mask |= ((cut >> k) & 1u) << j;
    leaving_mask |= static_cast<uint32_t>(state == EdgeState::kCompletes) << j;
    entering_mask |= static_cast<uint32_t>(state == EdgeState::kEnters) << j;
  }
  t.new_mask = static_cast<uint8_t>(new_mask);
  t.final_mask = static_cast<uint8_t>(final_mask);
  t.border_mask = static_cast<uint8_t>(border_mask);
  t.nonmanifold_mask = static_cast<uint8_t>(cut_mask);
  t.leaving_mask = static_cast<uint8_t>(leaving_mask);
  t.entering_mask = static_cast<uint8_t>(entering_mask);
  props->next_face(&t.values);
  ++seen_triangles;
  ++stats.triangles;
  // Spec 6.4: finalization, slots freed in canonical order, events in
  // output order.
  for (int j = 0; j < 3; ++j)
    if (t.final_mask & (1u << j)) {
      SequenceEvent& fin = push();
      fin.kind = SequenceEvent::Kind::kFinalize;
      fin.finalized = t.v[j];
    }
  for (int k = 0; k < 3; ++k)
    if (bt.final[k]) b.free_vertex(bt.c[k]);
}

// ------------------------------------------------------------------ API

PsqDecoder::PsqDecoder() : impl_(std::make_unique<Impl>()) {}
PsqDecoder::~PsqDecoder() = default;

Status PsqDecoder::open(InputStream* in) {
  Status s = impl_->open(in);
  return s.ok() ? s : impl_->fail(s);
}

Status PsqDecoder::segments(std::vector<PsqSegment>* out, PsqSegment* end) {
  Impl& m = *impl_;
  if (end) *end = PsqSegment();
  PSQ_RETURN_IF_ERROR(m.ready());
  out->clear();
  InputStream& in = *m.in;
  const uint64_t back = in.offset();
  const uint64_t first = m.stats.header_bytes;
  out->push_back(PsqSegment{first, 0, 0});
  if (!in.can_rewind()) return Status(ErrorCode::kIo, "the segments of a stream need an input that can seek");
  const uint64_t size = static_cast<uint64_t>(in.size());
  if (size < first + 12) return Status();  // too short for an end record: the decoder tells
  const Status s = [&]() -> Status {
    // Spec 4.5: the end record ends with the index's offset and the
    // stream checksum.
    uint8_t tail[12];
    PSQ_RETURN_IF_ERROR(in.seek(size - 12));
    PSQ_RETURN_IF_ERROR(in.read_exact(tail, 12));
    const uint64_t at = Get(tail, 8).u64();
    if (at == 0) return Status(ErrorCode::kBadHeader, "end record: no index offset", size - 12);
    if (at < first || at >= size - 12)
      return Status(ErrorCode::kBadHeader, "end record: index offset beyond the stream", size - 12);
    // Spec 4.7.
    auto bad = [&](const std::string& what) { return Status(ErrorCode::kBadHeader, "index: " + what, at); };
    std::vector<uint8_t> f(1, kIndexTag);
    uint8_t tag = 0;
    uint64_t n = 0;
    PSQ_RETURN_IF_ERROR(in.seek(at));
    PSQ_RETURN_IF_ERROR(m.read(&tag, 1));
    if (tag != kIndexTag) return bad("no index record at the end record's offset");
    PSQ_RETURN_IF_ERROR(m.read_varint(&n, &f));
    if (n > (size - at) / 3) return bad("more entries than the index has bytes");
    PSQ_RETURN_IF_ERROR(m.read_index_entries(n, &f, out, false));
    for (size_t i = 1; i < out->size(); ++i)
      if ((*out)[i].offset <= (*out)[i - 1].offset || (*out)[i].offset >= at)
        return bad("entry " + std::to_string(i - 1) + " is not a segment record's offset");
    if (!end) return Status();
    // Spec 4.5: the end record follows the index: its tag, then the
    // totals.
    PsqSegment e{in.offset(), 0, 0};
    PSQ_RETURN_IF_ERROR(m.read(&tag, 1));
    if (tag != kEndTag) return Status(ErrorCode::kBadHeader, "no end record after the index", e.offset);
    PSQ_RETURN_IF_ERROR(m.read_varint(&e.vertices, nullptr));
    PSQ_RETURN_IF_ERROR(m.read_varint(&e.triangles, nullptr));
    *end = e;
    return Status();
  }();
  const Status r = in.seek(back);
  if (!s.ok()) out->resize(1);
  return s.ok() ? r : s;
}

Status PsqDecoder::start_segment(const PsqSegment& segment) {
  Impl& m = *impl_;
  if (!m.error.ok()) return m.error;
  if (!m.opened || m.record_no != 0 || m.alone || m.records_left != 0)
    return m.fail(Status(ErrorCode::kUsage, "start_segment() right after open()"));
  m.alone = true;
  if (segment.offset == m.stats.header_bytes) return Status();
  Status s = m.in->seek(segment.offset);
  if (!s.ok()) return m.fail(s);
  m.chunk_offset = segment.offset;
  uint8_t tag = 0;
  s = m.read(&tag, 1);
  if (s.ok() && tag != kSegmentTag)
    s = Status(ErrorCode::kBadHeader, "no segment record at this offset", segment.offset);
  if (s.ok()) s = m.read_segment(true);
  if (s.ok() && (m.next_out != segment.vertices || m.base_triangles != segment.triangles))
    s = Status(ErrorCode::kBadHeader, "the segment record's counts differ from the index's", segment.offset);
  return s.ok() ? s : m.fail(s);
}

const PsqHeader& PsqDecoder::header() const { return impl_->header; }
const MeshSchema& PsqDecoder::schema() const { return impl_->header.schema; }
void PsqDecoder::measure_costs(bool on) { impl_->measure = on; }
const PsqStats& PsqDecoder::stats() const { return impl_->stats; }

Status PsqDecoder::Impl::advance() {
  if (late) {
    // Every released event was taken. Their entries give up large
    // property values, so that the ring keeps no more than the events it
    // holds (a stream may bring large lists now and then).
    constexpr size_t kKeep = 16;
    for (; held_begin < held_ready; ++held_begin) {
      SequenceEvent& e = held[held_begin & (held.size() - 1)];
      if (e.vertex.values.capacity() > kKeep) PropertyValues().swap(e.vertex.values);
      if (e.triangle.values.capacity() > kKeep) PropertyValues().swap(e.triangle.values);
    }
  }
  qhead = qcount = 0;
  if (records_left == 0) return next_chunk();
  PSQ_RETURN_IF_ERROR(rans ? decode_record<RansSymbolDecoder>() : decode_record<AdaptiveSymbolDecoder>());
  if (!attrs->empty()) PSQ_RETURN_IF_ERROR(decode_attributes());
  ++record_no;
  stats.max_active_vertices = std::max(stats.max_active_vertices, fboundary.active_vertices());
  stats.max_open_edges = std::max(stats.max_open_edges, fboundary.open_edges());
  if (--records_left == 0) {
    if (late) {
      PSQ_RETURN_IF_ERROR(decode_attributes(true));
      // Spec 8.4: no normal waits past its chunk, so no event either.
      if (held_ready != held_end) return corrupt("events held back past the end of their chunk");
    }
    PSQ_RETURN_IF_ERROR(close_records());
    if (!attrs->empty() && rans) {
      // Spec 13.8.4: both blocks end where the chunk's attributes do.
      if (attr_fast.rans->overran() || attr_fast.raw->overran())
        return Status(ErrorCode::kTruncated, "attribute data ends early", attr_offset + attr_bytes.size());
      if (!attr_fast.rans->at_clean_end() || !attr_fast.raw->at_clean_end())
        return Status(ErrorCode::kBadValue, "the attribute blocks do not end where the chunk's attributes do",
                      attr_offset);
    } else if (!attrs->empty() && attr_rc->consumed() != attr_bytes.size()) {
      return Status(ErrorCode::kBadValue, std::to_string(attr_bytes.size() - attr_rc->consumed()) +
                                              " unused bytes after the chunk's attributes",
                    attr_offset + attr_rc->consumed());
    }
    if (seen_vertices != chunk_vertices || seen_triangles != chunk_triangles)
      return Status(ErrorCode::kBadHeader, "chunk declares other vertex or triangle counts than it holds", chunk_offset);
  }
  return Status();
}

namespace {

// The sums of the vertex and triangle counts that the chunks in
// data[at, size) declare (spec 4.3), read by skipping from chunk to chunk
// by their section lengths, with no other check: decode_into()'s hint for
// the arrays' capacity. It stops at the first tag or field that does not
// parse; the decoder reports what is wrong when it gets there.
void declared_totals(const uint8_t* data, size_t size, size_t at, uint64_t* vertices, uint64_t* triangles) {
  *vertices = *triangles = 0;
  while (at < size && data[at] == kChunkTag) {
    ++at;
    uint64_t f[7];  // records, vertices, triangles, R, Z, U, A
    for (int i = 0; i < 7; ++i) {
      const int n = parse_varint(data + at, size - at, &f[i]);
      if (n <= 0) return;
      at += static_cast<size_t>(n);
    }
    if (f[3] > kMaxRecordBytes || f[4] > kMaxPropertyBytes || f[6] > kMaxAttributeBytes || f[2] > f[0] ||
        f[1] > 3 * f[0] || f[0] > kMaxChunkRecords)
      return;
    const uint64_t skip = f[3] + f[4] + f[6] + 4;
    if (skip > size - at) return;
    at += static_cast<size_t>(skip);
    *vertices += f[1];
    *triangles += f[2];
  }
}

}  // namespace

Status PsqDecoder::Impl::decode_into(MeshBuffers* mesh) {
  direct = mesh;
  // Spec 4.3: the chunks declare their vertex and triangle counts, and
  // the whole stream is in memory: their sums size the arrays' capacity
  // once. Grown chunk by chunk instead, the arrays would copy what the
  // earlier chunks wrote and fault in new pages for it, a noticeable share
  // of the decoding time (bench/HISTORY.md, "The decoder's memory"). A
  // hostile stream's sums are capped at four per input byte, as
  // direct_records() caps a chunk's room; the capacity is address
  // space, which stays untouched until records write it (direct_room()).
  // Memory input only: a stream's later chunks are not at hand.
  if (in->size() >= 0 && static_cast<uint64_t>(in->size()) == in->offset() + in->buffered()) {
    uint64_t vertices = 0, triangles = 0;
    declared_totals(in->cursor(), in->buffered(), 0, &vertices, &triangles);
    // A reservation the system refuses is no error: the arrays then grow.
    const uint64_t cap = 4 * static_cast<uint64_t>(in->size()) + 64;
    try {
      mesh->positions.reserve(mesh->positions.size() + 3 * static_cast<size_t>(std::min(vertices, cap)));
      mesh->indices.reserve(mesh->indices.size() + 3 * static_cast<size_t>(std::min(triangles, cap)));
    } catch (const std::bad_alloc&) {
    }
  }
  PSQ_RETURN_IF_ERROR(decode_loop());
  mesh->positions.resize(direct_np);
  mesh->indices.resize(direct_ni);
  return check_float_range(header, *mesh);
}

Status PsqDecoder::next(SequenceEvent* event) {
  Impl& m = *impl_;
  PSQ_RETURN_IF_ERROR(m.ready());
  while (m.qhead == m.qcount) {
    if (m.ended) {
      event->kind = SequenceEvent::Kind::kEnd;
      return Status();
    }
    Status s = m.advance();
    if (!s.ok()) return m.fail(s);
  }
  // Copy only what the event kind uses (the vectors keep their capacity).
  SequenceEvent& e = m.event(m.qhead++);
  if (m.report_slots && !m.late) m.report(e);
  event->kind = e.kind;
  switch (e.kind) {
    case SequenceEvent::Kind::kVertex: event->vertex = e.vertex; break;
    case SequenceEvent::Kind::kTriangle: event->triangle = e.triangle; break;
    case SequenceEvent::Kind::kFinalize: event->finalized = e.finalized; break;
    case SequenceEvent::Kind::kEnd: break;
  }
  return Status();
}

Status PsqDecoder::pump(SequenceSink& sink) {
  Impl& m = *impl_;
  PSQ_RETURN_IF_ERROR(m.ready());
  PSQ_RETURN_IF_ERROR(sink.begin(m.header.schema));
  // A sink that keeps only the mesh takes its arrays straight from the
  // records (psq/sequence.h), when no event was taken by next() yet.
  if (MeshBuffers* arrays = sink.mesh_arrays(); arrays != nullptr && m.record_no == 0 && m.qcount == 0) {
    Status s = m.decode_into(arrays);
    if (!s.ok()) return m.fail(s);
    return sink.finish();
  }
  for (;;) {
    // Events already queued by next() go first.
    for (; m.qhead < m.qcount; ++m.qhead) {
      SequenceEvent& e = m.event(m.qhead);
      if (m.report_slots && !m.late) m.report(e);
      switch (e.kind) {
        case SequenceEvent::Kind::kVertex: PSQ_RETURN_IF_ERROR(sink.vertex(e.vertex)); break;
        case SequenceEvent::Kind::kTriangle: PSQ_RETURN_IF_ERROR(sink.triangle(e.triangle)); break;
        case SequenceEvent::Kind::kFinalize: PSQ_RETURN_IF_ERROR(sink.finalize(e.finalized)); break;
        case SequenceEvent::Kind::kEnd: break;
      }
    }
    if (m.ended) return sink.finish();
    Status s = m.advance();
    if (!s.ok()) return m.fail(s);
  }
}

}  // namespace psq
