// SPDX-License-Identifier: Apache-2.0
// codec/src/encoder.cpp: the .psq encoder (psq/psq_codec.h). Section
// numbers refer to spec/psq-format.md.
#include <algorithm>
#include <charconv>
#include <cmath>
#include <unordered_map>

#include "encoder_impl.h"
#include "training.h"
#include "container.h"
#include "crc32c.h"
#include "geometry.h"
#include "properties.h"
#include "attributes.h"
#include "psq/psq_codec.h"

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
  header.fast = fast = opt.fast;
  header.rotation = !schema.face_properties.empty();
  header.boundary_limit = opt.boundary_limit;
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
  header.attributes = recognize_attributes(schema.vertex_properties, opt.lossless ? 0 : opt.normal_bits,
                                           opt.lossless ? 0 : opt.uv_bits);
  attrs = std::make_unique<AttributeCoder>(schema.vertex_properties, header.attributes);
  props = std::make_unique<PropertyPacker>(attrs->column_properties(), schema.face_properties);
  if (!attrs->empty()) {
    if (!opt.fast) attr_rc = std::make_unique<RangeEncoder>(&attr_bytes);
    attr_q.resize(3 * static_cast<size_t>(attrs->dims()));
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
  if (fast) {
    fast_begin();
    boundary.drop_recency();
  } else {
    rc = std::make_unique<RangeEncoder>(&records);
  }
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

int PsqEncoder::Impl::name_far_gate(const uint32_t cand[3], FarName* name) {
  // The lowest recency rank of a candidate.
  uint32_t recent[kRecentRanks];
  const uint32_t n = boundary.recent_edges(recent, kRecentRanks);
  for (uint32_t r = 0; r < n; ++r)
    for (int k = 0; k < 3; ++k)
      if (cand[k] != kNone && cand[k] == recent[r]) {
        name->far = r;
        return k;
      }
  // The first departure point (most recent first) and then the first
  // offset symbol (0, +1, -1, +2, -2, ...) that reach a candidate. Found
  // backwards, from the candidates: their edges within 15 links, checked
  // against the departure points marked in dep_mark (links are symmetric:
  // next(e) = f exactly when prev(f) = e), which costs 93 steps instead of
  // 16 x 31 walks from the departures.
  if (dep_mark.size() < boundary.edge_capacity()) dep_mark.resize(boundary.edge_capacity(), 0);
  uint32_t marked[kDepartures];
  uint32_t nmarked = 0;
  for (uint32_t j = 0; j < boundary.departures(); ++j) {
    const uint32_t d = boundary.departure(j);
    if (d != kNone) {
      dep_mark[d] = static_cast<uint8_t>(j + 1);
      marked[nmarked++] = d;
    }
  }
  uint32_t best_j = kDepartures, best_s = 0;
  int best_k = -1;
  auto consider = [&](uint32_t e, uint32_t s, int k) {
    if (e == kNone || dep_mark[e] == 0) return;
    const uint32_t j = dep_mark[e] - 1u;
    if (j < best_j || (j == best_j && s < best_s)) {
      best_j = j;
      best_s = s;
      best_k = k;
    }
  };
  for (int k = 0; k < 3 && nmarked > 0; ++k) {
    if (cand[k] == kNone) continue;
    consider(cand[k], 0, k);
    uint32_t fwd = cand[k], back = cand[k];
    for (uint32_t t = 1; t <= static_cast<uint32_t>(kMaxResumeOffset); ++t) {
      // d = next^t(candidate): the candidate is t links before d, offset -t.
      if (fwd != kNone) consider(fwd = boundary.edge(fwd).next, 2 * t, k);
      // d = prev^t(candidate): offset +t.
      if (back != kNone) consider(back = boundary.edge(back).prev, 2 * t - 1, k);
    }
  }
  for (uint32_t i = 0; i < nmarked; ++i) dep_mark[marked[i]] = 0;
  if (best_k >= 0) {
    name->far = kFarResume;
    name->index = best_j;
    name->offset = best_s;
    return best_k;
  }
  name->far = kFarEscape;
  return cand[0] != kNone ? 0 : cand[1] != kNone ? 1 : 2;
}

// Spec 7.3 leaves the choice to the encoder. This one takes the
// prediction that codes cheapest in the models' current state: the
// choice's own bits and the three residuals with their length contexts.
// Ties go to the lower choice number. The choice's cost counts fully only
// from the 2000th choice on, and from nothing at the first: the choice
// models and the residual models of kinds 2 and 3 start untrained, so that
// a strict count would keep choosing the gate on a mesh where a neighbour
// predicts better (on a regular grid whose gate parallelograms cross the
// wrong diagonals it does, and only the ramp lets the neighbours win
// there: bench/HISTORY.md, "Prediction choice and means of parallelograms").
int PsqEncoder::Impl::choose_prediction(uint32_t gate, uint32_t mask, int shape, const int64_t pos[3],
                                        Prediction* pred) {
  constexpr double kRamp = 2000;
  const BEdge& g = boundary.edge(gate);
  const uint32_t edge[3] = {gate, g.prev, g.next};  // by side
  // The five points, and the bits of their residuals alone: a candidate
  // whose residuals have more bits than the gate's is not worth pricing
  // (pricing also those a little longer would cost the encoder more work
  // than it saves bytes).
  int64_t point[kChoices][3];
  int rough[kChoices] = {0, 0, 0, 0, 0};
  uint32_t keep = 1u << kChoiceGate;
  parallelogram(boundary, gate, point[kChoiceGate]);
  for (int k = 0; k < 3; ++k) rough[kChoiceGate] += bit_length64(coord_distance(pos[k], point[kChoiceGate][k]));
  for (int side = kChoiceBefore; side <= kChoiceAfter; ++side) {
    if (!(mask & (1u << (side - 1)))) continue;
    const int mean = side + 2;
    parallelogram(boundary, edge[side], point[side]);
    for (int k = 0; k < 3; ++k) {
      point[mean][k] = midpoint(point[kChoiceGate][k], point[side][k]);
      rough[side] += bit_length64(coord_distance(pos[k], point[side][k]));
      rough[mean] += bit_length64(coord_distance(pos[k], point[mean][k]));
    }
    if (rough[side] <= rough[kChoiceGate]) keep |= 1u << side;
    if (rough[mean] <= rough[kChoiceGate]) keep |= 1u << mean;
  }
  // The extents of the three predicting triangles, as needed.
  int extent[3][3];
  uint32_t have = 0;
  auto candidate = [&](int ch) {
    Prediction p;
    const int t = predicting_side(ch);
    if (!(have & (1u << t))) {
      triangle_extents(boundary, edge[t], extent[t]);
      have |= 1u << t;
    }
    for (int k = 0; k < 3; ++k) {
      p.pos[k] = point[ch][k];
      p.extent[k] = extent[t][k];
    }
    p.kind = prediction_kind(ch);
    return p;
  };
  if (keep == 1u << kChoiceGate) {
    *pred = candidate(kChoiceGate);
    return kChoiceGate;
  }
  const float weight = static_cast<float>(std::min(1.0, static_cast<double>(choices_coded) / kRamp));
  const float* table = bit_cost_table();
  int best = kChoiceGate;
  float best_cost = 0;
  for (int ch = kChoiceGate; ch < kChoices; ++ch) {
    if (!(keep & (1u << ch))) continue;
    const Prediction pr = candidate(ch);
    float c = weight * Encoder::choice_cost(table, models->choice[shape], mask, ch);
    int lengths[3] = {0, 0, 0};
    for (int a = 0; a < 3; ++a) {
      const int lc = length_context(pr.kind, a, pr.extent[a], std::max(lengths[0], lengths[1]));
      c += Encoder::residual_cost(table, models->residual[pr.kind][a][lc], wrap_sub(pos[a], pr.pos[a]), &lengths[a]);
    }
    if (ch == kChoiceGate || c < best_cost) {
      best = ch;
      best_cost = c;
      *pred = pr;
    }
  }
  return best;
}

// Spec 6.3 and 7.4: the re-appearance flag (and distance), then the
// residuals of the position against `pred`.
void PsqEncoder::Impl::code_new_vertex(Encoder& enc, const PendingVertex& v, const int64_t pred[3], int kind,
                                        const int extent[3]) {
  const uint32_t out_index = out_index_of(v.in_index);
  enc.bit(models->reappears, v.reappears != kNoVertex, kCostConnectivity);
  // (triangle() and isolated() checked that the re-appeared vertex comes
  // earlier in the decoded numbering.)
  if (v.reappears != kNoVertex)
    (void)enc.residual(models->distance, static_cast<int64_t>(out_index - out_index_of(v.reappears)) - 1,
                       kCostConnectivity);
  int lengths[3] = {0, 0, 0};
  for (int i = 0; i < 3; ++i) {
    const int c = length_context(kind, i, extent[i], std::max(lengths[0], lengths[1]));
    lengths[i] = enc.residual(models->residual[kind][i][c], wrap_sub(v.pos[i], pred[i]),
                              kCostGeometry);
  }
  for (int i = 0; i < 3; ++i) last_pos[i] = v.pos[i];
}

// Spec 6.2.1: a gate is an open edge that the triangle completes; both
// profiles' records name one of these.
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
  if (fast) {
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
    const uint32_t hint = t.vslot[k];
    if (hint != kNoSlot) {
      const uint32_t s = hint < by_inslot.size() ? by_inslot[hint] : kNone;
      if (s != kNone && boundary.vertex_live(s) && boundary.vertex(s).key == t.v[k]) {
        slots[k] = s;
        continue;
      }
      // A vertex whose slot was too large for the array (register_vertex())
      // is in the map.
      auto it = slot_of.find(t.v[k]);
      if (it == slot_of.end())
        return bad_sequence("triangle uses vertex " + std::to_string(t.v[k]) + " with boundary slot " +
                            std::to_string(hint) + ", which is not its active vertex's");
      slots[k] = it->second;
      continue;
    }
    auto it = slot_of.find(t.v[k]);
    if (it == slot_of.end())
      return bad_sequence("triangle uses vertex " + std::to_string(t.v[k]) + ", which is not active");
    slots[k] = it->second;
  }
  if (static_cast<size_t>(nnew) != pending.size())
    return bad_sequence("vertex " + std::to_string(pending.front().in_index) +
                        " was introduced but the next triangle does not use it");
  if (nnew == 2) return bad_sequence("a triangle introduces exactly two vertices");
  if (fast) return triangle_fast(t, pend, slots, nnew);

  Encoder enc(rc.get(), opt.measure_costs ? cost : nullptr);
  const int ctx = gate_context(boundary.reference(), last_op, last_gate);
  int rot = 0;  // canonical corner k is input corner (rot + k) % 3
  uint32_t gate_sym = kGateStart;
  uint32_t gate = kNone;
  int shape = 0;  // the gate's shape context (spec 6.2.2)
  FarName far_name;  // how a far gate is coded (spec 6.2.1)
  const bool far_reference_none = boundary.reference() == kNone;
  if (nnew == 3) {
    // Spec 6.2.4: corner 0 is the vertex introduced first.
    rot = pend[0] == 0 ? 0 : pend[1] == 0 ? 1 : 2;
    if (!far_reference_none) boundary.depart(boundary.reference());  // spec 6.2.1: a start leaves R
  } else {
    uint32_t cand[3];
    PSQ_RETURN_IF_ERROR(candidate_gates(t, pend, slots, nnew, cand));
    // Spec 6.2.1: offsets from the reference edge in the order 0, +1, -1,
    // +2, -2, ...; the first that reaches a candidate is coded.
    gate_sym = kGateFar;
    const uint32_t R = boundary.reference();
    uint32_t fwd = R, back = R;
    for (uint32_t s = 0; R != kNone && s < kGateFar && gate_sym == kGateFar; ++s) {
      uint32_t e = R;
      if (s % 2 == 1) e = fwd = fwd == kNone ? kNone : boundary.edge(fwd).next;
      else if (s > 0) e = back = back == kNone ? kNone : boundary.edge(back).prev;
      if (e == kNone) continue;
      for (int k = 0; k < 3; ++k)
        if (cand[k] == e) {
          gate_sym = s;
          rot = k;
        }
    }
    if (gate_sym == kGateFar) {
      // Spec 6.2.1: a far gate leaves the region at R; then the candidate
      // named most cheaply: the lowest recency rank, else the first
      // departure point (most recent first) and offset that reach it, else
      // the first candidate in the input's corner order, by its slot.
      if (R != kNone) boundary.depart(R);
      rot = name_far_gate(cand, &far_name);
    }
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
  const int r = (3 - rot) % 3;  // spec 6.2.3: output corner j is canonical corner (j + r) % 3

  enc.gate(*models, ctx, gate_sym);
  last_gate = gate_sym;
  ++stats.gates[gate_kind(gate_sym)];
  uint32_t intro[3];  // canonical corners in the order their vertices are introduced
  int nintro = 0;
  if (nnew == 3) {
    const bool swap = cp[2] == 1;  // corner 2 was introduced second
    enc.bit(models->swap, swap, kCostConnectivity);
    intro[0] = 0;
    intro[1] = swap ? 2 : 1;
    intro[2] = swap ? 1 : 2;
    nintro = 3;
  } else {
    if (gate_sym == kGateFar) {
      enc.symbol<kFarBits>(models->far[far_reference_none], far_name.far, kCostConnectivity);
      ++stats.far_gates[far_kind(far_name.far)];
      if (far_name.far == kFarResume) {
        enc.symbol<kResumeIndexBits>(models->resume_index, far_name.index, kCostConnectivity);
        enc.symbol<kResumeOffsetBits>(models->resume_offset, far_name.offset, kCostConnectivity);
      } else if (far_name.far == kFarEscape) {
        enc.raw(gate, slot_bits(boundary.edge_capacity()), kCostConnectivity);
      }
    }
    const BEdge& g = boundary.edge(gate);
    const uint32_t p = g.org, q = g.dst;
    uint32_t third = kThirdNew;
    if (!bt.is_new[2]) {
      const uint32_t x = bt.c[2];
      if (g.prev != kNone && boundary.edge(g.prev).org == x) third = kThirdLeft;
      else if (g.next != kNone && boundary.edge(g.next).dst == x) third = kThirdRight;
      else third = kThirdJoin;
    }
    const BVertex& vp = boundary.vertex(p);
    const BVertex& vq = boundary.vertex(q);
    shape = third_shape_context(boundary, gate);
    enc.third(models->third[shape][third_context(vp.degree, vq.degree)], third);
    if (third == kThirdJoin) {
      // Spec 6.2.2: an open edge at x names it and the gap the triangle
      // goes into: its first edge leaving x, else its first entering x.
      const BLinks& vx = boundary.links(bt.c[2]);
      uint32_t j = vx.first_out != kNone ? vx.first_out : vx.first_in;
      if (j == kNone) return bad_sequence("join over vertex " + std::to_string(t.v[(rot + 2) % 3]) +
                                          ", which is not on the boundary");
      enc.bit(models->join_side, j == vx.first_out ? 0 : 1, kCostConnectivity);
      enc.raw(j, slot_bits(boundary.edge_capacity()), kCostConnectivity);
      bt.join_edge = j;
    }
    if (bt.is_new[2]) {
      intro[0] = 2;
      nintro = 1;
    }
  }
  if (header.rotation) enc.symbol<2>(models->rotation, static_cast<uint32_t>(r), kCostConnectivity);

  // New vertices in the order of introduction, with their predictions.
  for (int i = 0; i < nintro; ++i) {
    const int k = static_cast<int>(intro[i]);
    PendingVertex& v = pending[cp[k]];
    PSQ_RETURN_IF_ERROR(introduce(v));
    v.coded = true;
    const int64_t* first = i >= 1 ? pending[cp[intro[0]]].pos : nullptr;
    const int64_t* second = i >= 2 ? pending[cp[intro[1]]].pos : nullptr;
    Prediction pr;
    int choice = kChoiceGate;
    // Spec 7.3: an add may be predicted across a neighbour of the gate.
    const uint32_t mask = nnew == 1 ? prediction_choices(boundary, gate) : 0;
    if (mask != 0) {
      choice = choose_prediction(gate, mask, shape, v.pos, &pr);
      enc.choice(models->choice[shape], mask, choice);
      ++choices_coded;
    } else {
      pr = predict_new_vertex(boundary, nnew == 1 ? gate : kNone, i, last_pos, first, second);
    }
    if (nnew == 1) ++stats.predictions[choice];
    code_new_vertex(enc, v, pr.pos, pr.kind, pr.extent);
    PSQ_RETURN_IF_ERROR(register_vertex(v, &bt.c[k]));
  }

  if (!boundary.find_completions(bt))
    return bad_sequence("triangle " + std::to_string(t.v[0]) + " " + std::to_string(t.v[1]) + " " +
                        std::to_string(t.v[2]) + " uses a directed edge already on the boundary, or a border edge");
  // Spec 6.2.5: border flags of the edges that do not complete, then the
  // cut flag of each border.
  const int start = nnew == 3 ? 1 : 0;
  int completed = 0;
  for (int k = 0; k < 3; ++k) {
    const int ik = (rot + k) % 3;
    if (bt.state[k] == EdgeState::kCompletes) {
      ++completed;
      if ((t.border_mask >> ik) & 1)
        return bad_sequence("a border edge completes a boundary edge");
      continue;
    }
    enc.bit(models->border[start][k][border_context(boundary, bt, k)], bt.border[k], kCostConnectivity);
  }
  for (int k = 0; k < 3; ++k)
    if (bt.state[k] == EdgeState::kBorder)
      enc.bit(models->cut[start], (t.nonmanifold_mask >> ((rot + k) % 3)) & 1, kCostConnectivity);
  return close_triangle(t, bt, nnew);
}

Status PsqEncoder::Impl::register_vertex(const PendingVertex& v, uint32_t* slot) {
  const uint32_t s = boundary.new_vertex(out_index_of(v.in_index), v.in_index, v.pos);
  if (s == kNone)
    return Status(ErrorCode::kLimit, "more than " + std::to_string(opt.boundary_limit) +
                                         " active vertices (the boundary limit)");
  *slot = s;
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
  if (!boundary.apply(bt))
    return Status(ErrorCode::kLimit, "more than " + std::to_string(opt.boundary_limit) +
                                         " open edges (the boundary limit)");
  if (fast)  // spec 13.6.2: entering edges join the ring, in edge order
    for (int k = 0; k < 3; ++k)
      if (bt.state[k] == EdgeState::kEnters) ring.push(boundary, bt.eslot[k]);
  if (!attrs->empty()) {
    uint8_t entering = 0;
    for (int k = 0; k < 3; ++k) entering |= static_cast<uint8_t>((bt.state[k] == EdgeState::kEnters) << k);
    uint8_t fresh = 0;
    for (int k = 0; k < 3; ++k) fresh |= static_cast<uint8_t>(bt.is_new[k] << k);
    code_attributes(bt.c, bt.eslot, fresh, entering);
  }
  pending.clear();
  last_op = static_cast<int>(op);
  // Spec 6.4: vertices left with no open edge are finalized, in canonical
  // corner order; the input must finalize exactly these next.
  for (int k = 0; k < 3; ++k)
    if (bt.final[k]) {
      const BVertex& v = boundary.vertex(bt.c[k]);
      expect_final.push_back(v.key);
      if (!slot_of.empty()) slot_of.erase(v.key);
      boundary.free_vertex(bt.c[k]);
    }
  if (!props->add_face(t.values))
    return Status(ErrorCode::kBadValue, "face property values do not match the schema or their types");
  ++stats.triangles;
  ++chunk_triangles;
  return after_record();
}

Status PsqEncoder::Impl::isolated(size_t at) {
  if (fast) {
    PendingVertex v = std::move(pending[at]);
    pending.erase(pending.begin() + static_cast<std::ptrdiff_t>(at));
    PSQ_RETURN_IF_ERROR(introduce(v));
    PSQ_RETURN_IF_ERROR(isolated_fast(v));
    code_attributes(nullptr, nullptr, 0, 0);
    return after_record();
  }
  Encoder enc(rc.get(), opt.measure_costs ? cost : nullptr);
  const int ctx = gate_context(boundary.reference(), last_op, last_gate);
  enc.gate(*models, ctx, kGateIsolated);
  last_gate = kGateIsolated;
  ++stats.gates[gate_kind(kGateIsolated)];
  PendingVertex v = std::move(pending[at]);
  pending.erase(pending.begin() + static_cast<std::ptrdiff_t>(at));
  PSQ_RETURN_IF_ERROR(introduce(v));
  const int no_extent[3] = {0, 0, 0};
  code_new_vertex(enc, v, last_pos, kPredOther, no_extent);
  code_attributes(nullptr, nullptr, 0, 0);
  return after_record();
}

void PsqEncoder::Impl::code_attributes(const uint32_t* corner, const uint32_t* eslot, uint8_t fresh,
                                       uint8_t entering) {
  if (attrs->empty()) return;
  AttributeRecord& r = attr_rec;
  r.triangle = corner != nullptr;
  if (r.triangle) {
    for (int k = 0; k < 3; ++k) {
      r.c[k] = corner[k];
      r.e[k] = eslot[k];
      r.v[k] = boundary.vertex(corner[k]).index;
      r.pos[k] = header.lossless ? nullptr : boundary.vertex(corner[k]).pos;
    }
    r.new_mask = fresh;
    r.entering_mask = entering;
  }
  if (fast) {
    attrs->encode_fast(attr_fast, r, attr_q.data());
  } else {
    Encoder enc(attr_rc.get(), nullptr);
    attrs->encode(enc, r, attr_q.data());
  }
  r = AttributeRecord();
}

Status PsqEncoder::Impl::after_record() {
  ++chunk_records;
  stats.max_active_vertices = std::max(stats.max_active_vertices, boundary.active_vertices());
  stats.max_open_edges = std::max(stats.max_open_edges, boundary.open_edges());
  // The fast profile codes a chunk at its end: estimate 4 bits a symbol
  // for the target size. The limit of a chunk's coded records (spec 10)
  // must hold whatever the symbols cost: a symbol costs at most about
  // kRansScaleBits bits (its frequency is at least 1; the states' rounding
  // adds a fraction of a bit over a chunk), and the tables at most a
  // presence bit and a gamma code per symbol.
  const size_t coded = fast ? fast_raw.bits() / 8 + fast_symbols.size() / 2 : records.size();
  bool full = false;
  if (fast) {
    constexpr size_t kTableBound = size_t{kFastTables} * (1 + kRansMaxSymbols * (2 * kRansScaleBits)) / 8 + 64;
    constexpr size_t kRecordBound = 4096;  // one more record, with room to spare
    const size_t bound = fast_raw.bits() / 8 + fast_symbols.size() * kRansScaleBits / 8 + 8 + kTableBound;
    full = bound + kRecordBound >= kMaxRecordBytes;
  }
  // The attribute section is closed at the property target too, far
  // below its limit (spec 4.4): a record adds at most a few hundred bytes.
  if (coded >= opt.chunk_bytes || full || props->raw_size() >= kChunkPropertyTarget ||
      std::max(attr_bytes.size(), attr_fast.size_estimate()) >= kChunkPropertyTarget ||
      chunk_records >= kMaxChunkRecords)
    return close_chunk();
  return Status();
}

Status PsqEncoder::Impl::close_chunk() {
  if (chunk_records == 0) return Status();
  if (fast) fast_section(&records);
  else rc->finish();
  std::vector<uint8_t> raw, packed;
  if (!props->empty()) {
    props->take(&raw);
    zstd_compress(raw, opt.zstd_level, &packed);
  }
  if (attr_rc) attr_rc->finish();
  if (fast && !attrs->empty()) attrs->finish_fast(attr_fast, &attr_bytes);
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
  put.u32(crc32c_update(0, chunk.data(), chunk.size()));
  stats.record_bytes += records.size();
  stats.property_bytes += packed.size();
  stats.chunk_overhead_bytes += fields + 4;
  ++stats.chunks;
  records.clear();
  if (!fast) rc = std::make_unique<RangeEncoder>(&records);
  chunk_records = chunk_vertices = chunk_triangles = 0;
  chain_crc = crc32c_update(chain_crc, chunk.data() + chunk.size() - 4, 4);
  return emit(chunk);
}

Status PsqEncoder::Impl::finish() {
  if (!expect_final.empty())
    return bad_sequence("vertex " + std::to_string(expect_final.front()) + " is never finalized");
  if (!pending.empty())
    return bad_sequence("vertex " + std::to_string(pending.front().in_index) + " is never used or finalized");
  if (boundary.active_vertices() != 0)
    return bad_sequence(std::to_string(boundary.active_vertices()) + " vertices are still active at the end");
  PSQ_RETURN_IF_ERROR(close_chunk());
  std::vector<uint8_t> end;
  Put put(&end);
  put.u8(kEndTag);
  put.varint(stats.vertices);
  put.varint(stats.triangles);
  put.varint(stats.chunks);
  put.varint(stats.max_active_vertices);
  put.varint(stats.max_open_edges);
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
  if (!options.fast) impl_->models = std::make_unique<Models>();
}

PsqEncoder::~PsqEncoder() = default;

namespace codec {
void TrainingAccess::use_flat_models(PsqEncoder& e) { e.impl_->models = std::make_unique<Models>(false); }
const Models& TrainingAccess::models(const PsqEncoder& e) { return *e.impl_->models; }
}  // namespace codec

Status PsqEncoder::begin(const MeshSchema& schema) {
  if (!impl_->error.ok()) return impl_->error;
  Status s = impl_->begin(schema);
  if (!s.ok()) return impl_->fail(s);
  return s;
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
  if (!s.ok()) return m.fail(s);
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
    if (m.pending[i].in_index == index) {
      Status s = m.isolated(i);
      if (!s.ok()) return m.fail(s);
      return s;
    }
  return m.fail(bad_sequence("vertex " + std::to_string(index) +
                             " is finalized while boundary edges touch it, or is not active"));
}

Status PsqEncoder::finish() {
  Impl& m = *impl_;
  if (!m.error.ok()) return m.error;
  if (!m.begun || m.finished) return m.fail(bad_sequence("finish() without begin() or twice"));
  Status s = m.finish();
  m.finished = true;
  if (!s.ok()) return m.fail(s);
  return s;
}

const PsqStats& PsqEncoder::stats() const { return impl_->stats; }

}  // namespace psq
