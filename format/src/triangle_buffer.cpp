// SPDX-License-Identifier: Apache-2.0
// Buffer-based processing: a triangle buffer between an input and an output
// processing boundary (Isenburg, Lindstrom, Gumhold, Snoeyink, "Large Mesh
// Simplification using Processing Sequences", 2003, sections 3 and 6; the
// buffer of Wu and Kobbelt, "A Stream Algorithm for the Decimation of
// Massive Meshes", 2003). The link condition of can_collapse() is that of
// Dey, Edelsbrunner, Guha and Nekhayev, "Topology preserving edge
// contraction", 1999, with the border closed by a dummy vertex.
#include "psq/triangle_buffer.h"

#include <algorithm>
#include <string>
#include "float_round.h"

namespace psq {
namespace {

// Entries of the edge-slot map: 0 is an empty slot, else the open corner
// plus one, or kWrittenEdge when the corner's triangle was written before
// the input completed the edge.
constexpr uint32_t kWrittenEdge = 0xffffffffu;
// Corners stay below kOpen.
constexpr uint32_t kMaxTriangles = uint32_t{1} << 29;
// Slots map into [kOpen, kWritten).
constexpr uint32_t kMaxSlot = 0x7ffffffdu;

Status bad_sequence(uint64_t triangle, const std::string& what) {
  return Status(ErrorCode::kBadSequence, "triangle " + std::to_string(triangle) + ": " + what);
}

}  // namespace

TriangleBuffer::TriangleBuffer(SequenceSink* out) : converter_(out) {}
TriangleBuffer::~TriangleBuffer() = default;

void TriangleBuffer::set_lookahead_budget(uint64_t bytes) { converter_.set_lookahead_budget(bytes); }
void TriangleBuffer::set_seed(uint64_t seed) { rng_ = seed; }

void TriangleBuffer::reserve(uint32_t triangles, uint32_t vertices) {
  corners_.reserve(3 * static_cast<size_t>(triangles));
  alive_flag_.reserve(triangles);
  out_count_.reserve(triangles);
  open_count_.reserve(triangles);
  out_pos_.reserve(triangles);
  arrival_when_.reserve(triangles);
  free_triangles_.reserve(triangles);
  arrival_.reserve(2 * static_cast<size_t>(triangles) + 1024);
  verts_.reserve(vertices);
  free_vertices_.reserve(vertices);
  free_.reserve(vertices);
}

const ConverterStats& TriangleBuffer::converter_stats() const { return converter_.stats(); }

uint64_t TriangleBuffer::random() {
  // splitmix64: every seed, zero included, gives a full-period stream.
  uint64_t z = (rng_ += 0x9e3779b97f4a7c15ull);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
  return z ^ (z >> 31);
}

Status TriangleBuffer::begin(const MeshSchema& schema) {
  schema_ = schema;
  schema_.vertex_count = MeshSchema::kUnknown;
  schema_.triangle_count = MeshSchema::kUnknown;
  has_vertex_values_ = !schema.vertex_properties.empty();
  has_face_values_ = !schema.face_properties.empty();
  float_positions_ = schema.position_type == ScalarType::kFloat32;
  return converter_.begin(schema_);
}

void TriangleBuffer::round_position(double p[3]) const {
  if (!float_positions_) return;
  for (int i = 0; i < 3; ++i) p[i] = detail::round_to_float(p[i]);
}

void TriangleBuffer::set_position(uint32_t v, const double p[3]) {
  for (int i = 0; i < 3; ++i) verts_[v].p[i] = p[i];
  round_position(verts_[v].p);
}

const PropertyValues& TriangleBuffer::vertex_values(uint32_t v) const {
  return has_vertex_values_ ? vertex_values_[v] : empty_values_;
}

const PropertyValues& TriangleBuffer::face_values(uint32_t t) const {
  return has_face_values_ ? face_values_[t] : empty_values_;
}

PropertyValues* TriangleBuffer::mutable_face_values(uint32_t t) { return has_face_values_ ? &face_values_[t] : nullptr; }

Status TriangleBuffer::vertex(const SequenceVertex& v) {
  // A vertex is introduced right before its first triangle, or finalized
  // right away (isolated): at most three wait for their triangle.
  if (pending_.size() >= 3)
    return Status(ErrorCode::kBadSequence, "vertex " + std::to_string(v.index) +
                                               ": more than three vertices introduced before a triangle");
  pending_.push_back(v);
  return Status();
}

Status TriangleBuffer::finalize(uint32_t index) {
  for (size_t i = 0; i < pending_.size(); ++i) {
    if (pending_[i].index == index) {
      pending_.erase(pending_.begin() + static_cast<std::ptrdiff_t>(i));
      ++stats_.isolated_dropped;
      return Status();
    }
  }
  // Vertices used by triangles were finalized by their triangle's final mask.
  return Status();
}

uint32_t TriangleBuffer::new_vertex(const SequenceVertex& sv) {
  uint32_t v;
  if (!free_vertices_.empty()) {
    v = free_vertices_.back();
    free_vertices_.pop_back();
  } else {
    v = static_cast<uint32_t>(verts_.size());
    verts_.emplace_back();
    if (has_vertex_values_) vertex_values_.emplace_back();
  }
  for (int i = 0; i < 3; ++i) verts_[v].p[i] = sv.position[i];
  verts_[v].head = kNone;
  verts_[v].out_id = kNone;
  verts_[v].dense = sv.index;
  verts_[v].free_pos = kNone;
  verts_[v].flags = sv.reappears != kNoVertex ? kCut : 0;
  if (has_vertex_values_) vertex_values_[v] = sv.values;
  ++vertices_;
  ++open_vertices_;
  ++stats_.vertices_read;
  stats_.max_vertices = std::max<uint64_t>(stats_.max_vertices, vertices_);
  return v;
}

void TriangleBuffer::free_vertex_record(uint32_t v) {
  if (verts_[v].free_pos != kNone) free_erase(v);
  verts_[v].dense = kNone;
  verts_[v].flags = 0;
  verts_[v].head = kNone;
  if (has_vertex_values_) PropertyValues().swap(vertex_values_[v]);
  free_vertices_.push_back(v);
  --vertices_;
}

void TriangleBuffer::free_insert(uint32_t v) {
  verts_[v].free_pos = static_cast<uint32_t>(free_.size());
  free_.push_back(v);
}

void TriangleBuffer::free_erase(uint32_t v) {
  const uint32_t at = verts_[v].free_pos;
  const uint32_t last = free_.back();
  free_[at] = last;
  verts_[last].free_pos = at;
  free_.pop_back();
  verts_[v].free_pos = kNone;
}

void TriangleBuffer::add_corner(uint32_t v, uint32_t c) {
  corners_[c].next = verts_[v].head;
  verts_[v].head = c;
}

void TriangleBuffer::remove_corner(uint32_t v, uint32_t c) {
  uint32_t* link = &verts_[v].head;
  while (*link != c) link = &corners_[*link].next;
  *link = corners_[c].next;
}

void TriangleBuffer::set_out_count(uint32_t t, uint8_t count) {
  const uint8_t old = out_count_[t];
  if (old == count) return;
  if (old > 0) {
    std::vector<uint32_t>& set = out_set_[old];
    const uint32_t at = out_pos_[t];
    const uint32_t last = set.back();
    set[at] = last;
    out_pos_[last] = at;
    set.pop_back();
  }
  if (count > 0) {
    out_pos_[t] = static_cast<uint32_t>(out_set_[count].size());
    out_set_[count].push_back(t);
  }
  out_count_[t] = count;
}

void TriangleBuffer::kill_triangle(uint32_t t) {
  set_out_count(t, 0);
  for (uint32_t k = 0; k < 3; ++k) remove_corner(corners_[3 * t + k].vertex, 3 * t + k);
  if (open_count_[t] > 0) --band_;
  alive_flag_[t] = 0;
  --alive_;
  if (has_face_values_) PropertyValues().swap(face_values_[t]);
  free_triangles_.push_back(t);
}

void TriangleBuffer::mark_input_final(uint32_t v) {
  verts_[v].flags |= kInputFinal;
  --open_vertices_;
  for (uint32_t c = verts_[v].head; c != kNone; c = corners_[c].next) {
    if (--open_count_[c / 3] == 0) --band_;
  }
  if (!written(v)) free_insert(v);
}

Status TriangleBuffer::triangle(const SequenceTriangle& t, uint32_t* id) {
  const uint64_t number = stats_.triangles_read;
  for (int k = 0; k < 3; ++k) {
    if (t.vslot[k] == kNoSlot || t.vslot[k] > kMaxSlot)
      return Status(ErrorCode::kUsage, "triangle " + std::to_string(number) +
                                           ": no boundary slot for a corner (the triangle buffer needs them)");
  }
  const uint32_t kinds = t.border_mask | t.leaving_mask | t.entering_mask;
  if (kinds == 0)
    return Status(ErrorCode::kUsage, "triangle " + std::to_string(number) +
                                         ": no edge masks (the triangle buffer needs border, leaving and "
                                         "entering edges)");
  if (kinds != 7 || (t.border_mask & t.leaving_mask) || (t.border_mask & t.entering_mask) ||
      (t.leaving_mask & t.entering_mask))
    return bad_sequence(number, "each edge must be exactly one of border, leaving and entering");
  if (t.v[0] == t.v[1] || t.v[1] == t.v[2] || t.v[2] == t.v[0])
    return bad_sequence(number, "repeated vertex");
  if (alive_ >= kMaxTriangles)
    return Status(ErrorCode::kLimit, "more than " + std::to_string(kMaxTriangles) + " triangles in the buffer");

  // Resolve the corners before changing anything.
  uint32_t vert[3];
  size_t pending_at[3] = {0, 0, 0};
  for (int k = 0; k < 3; ++k) {
    if (t.new_mask & (1u << k)) {
      size_t i = 0;
      while (i < pending_.size() && pending_[i].index != t.v[k]) ++i;
      if (i == pending_.size())
        return bad_sequence(number, "new vertex " + std::to_string(t.v[k]) + " was not introduced right before");
      pending_at[k] = i;
      vert[k] = kNone;
    } else {
      const uint32_t e = vslot_[t.vslot[k]];
      const uint32_t v = e - 1;
      if (e == 0 || v >= verts_.size() || verts_[v].dense != t.v[k] || !input_open(v))
        return bad_sequence(number, "vertex " + std::to_string(t.v[k]) + " is not active in slot " +
                                        std::to_string(t.vslot[k]));
      vert[k] = v;
    }
  }
  for (int k = 0; k < 3; ++k) {
    if (!(t.leaving_mask & (1u << k))) continue;
    if (t.eslot[k] > kMaxSlot) return bad_sequence(number, "leaving edge without a slot");
    const uint32_t e = eslot_[t.eslot[k]];
    if (e == 0) return bad_sequence(number, "leaving edge slot " + std::to_string(t.eslot[k]) + " is not open");
    if (e == kWrittenEdge) continue;
    const uint32_t o = e - 1;
    // The open edge must run the other way between the same vertices.
    if (vert[k] == kNone || vert[(k + 1) % 3] == kNone || corners_[o].vertex != vert[(k + 1) % 3] ||
        corners_[next(o)].vertex != vert[k])
      return bad_sequence(number, "leaving edge slot " + std::to_string(t.eslot[k]) + " names another edge");
  }
  for (int k = 0; k < 3; ++k) {
    if (!(t.entering_mask & (1u << k))) continue;
    if (t.eslot[k] > kMaxSlot) return bad_sequence(number, "entering edge without a valid slot");
    if (eslot_[t.eslot[k]] != 0)
      return bad_sequence(number, "entering edge slot " + std::to_string(t.eslot[k]) + " is in use");
  }
  // New vertices, taken from the pending list (highest index first, so the
  // others' positions stay valid).
  for (int pass = 0; pass < 3; ++pass) {
    int pick = -1;
    for (int k = 0; k < 3; ++k)
      if (vert[k] == kNone && (pick < 0 || pending_at[k] > pending_at[pick])) pick = k;
    if (pick < 0) break;
    const uint32_t v = new_vertex(pending_[pending_at[pick]]);
    pending_.erase(pending_.begin() + static_cast<std::ptrdiff_t>(pending_at[pick]));
    vslot_[t.vslot[pick]] = v + 1;
    vert[pick] = v;
  }

  const uint32_t tri = allocate_triangle(3);
  ++band_;
  ++alive_;
  if (has_face_values_) face_values_[tri] = t.values;
  uint8_t written_edges = 0;
  for (uint32_t k = 0; k < 3; ++k) {
    const uint32_t c = 3 * tri + k;
    corners_[c].vertex = vert[k];
    add_corner(vert[k], c);
  }
  for (uint32_t k = 0; k < 3; ++k) {
    const uint32_t c = 3 * tri + k;
    const uint32_t bit = 1u << k;
    if (t.border_mask & bit) {
      corners_[c].opposite = kBorder;
      verts_[vert[k]].flags |= kBorderVertex;
      verts_[vert[(k + 1) % 3]].flags |= kBorderVertex;
      // A border made by a non-manifold cut: its other side is elsewhere in
      // the sequence, at the same positions.
      if (t.nonmanifold_mask & bit) {
        verts_[vert[k]].flags |= kCut;
        verts_[vert[(k + 1) % 3]].flags |= kCut;
      }
    } else if (t.leaving_mask & bit) {
      const uint32_t e = eslot_[t.eslot[k]];
      eslot_[t.eslot[k]] = 0;
      --open_edges_;
      if (e == kWrittenEdge) {
        corners_[c].opposite = kWritten;
        ++written_edges;
      } else {
        corners_[c].opposite = e - 1;
        corners_[e - 1].opposite = c;
      }
    } else {
      corners_[c].opposite = kOpen | t.eslot[k];
      eslot_[t.eslot[k]] = c + 1;
      ++open_edges_;
    }
  }
  set_out_count(tri, written_edges);
  // An entry names its triangle by number and by when it was read: the
  // number of a triangle that left is given to later ones.
  const uint32_t when = static_cast<uint32_t>(stats_.triangles_read);
  arrival_when_[tri] = when;
  arrival_.push_back({tri, when});
  if (arrival_.size() > 2 * static_cast<size_t>(alive_) + 1024) {
    // Drop the entries of triangles that left, keeping the order.
    size_t w = 0;
    for (size_t i = arrival_head_; i < arrival_.size(); ++i)
      if (arrived(arrival_[i])) arrival_[w++] = arrival_[i];
    arrival_.resize(w);
    arrival_head_ = 0;
  }
  for (uint32_t k = 0; k < 3; ++k)
    if (t.final_mask & (1u << k)) mark_input_final(vert[k]);
  ++stats_.triangles_read;
  stats_.max_triangles = std::max<uint64_t>(stats_.max_triangles, alive_);
  *id = tri;
  return Status();
}

Status TriangleBuffer::end_input() {
  if (!pending_.empty())
    return Status(ErrorCode::kBadSequence, "vertex " + std::to_string(pending_[0].index) +
                                               " was introduced but neither used nor finalized");
  if (open_vertices_ > 0 || open_edges_ > 0)
    return Status(ErrorCode::kBadSequence, "the sequence ended with an open boundary (" +
                                               std::to_string(open_vertices_) + " vertices, " +
                                               std::to_string(open_edges_) + " edges)");
  return Status();
}

Status TriangleBuffer::retire_if_done(uint32_t v) {
  if (verts_[v].head != kNone || input_open(v)) return Status();
  Status s;
  if (written(v)) s = converter_.finalize(verts_[v].out_id);
  free_vertex_record(v);
  return s;
}

Status TriangleBuffer::write(uint32_t t) {
  uint32_t ids[3];
  for (uint32_t k = 0; k < 3; ++k) {
    const uint32_t v = corners_[3 * t + k].vertex;
    if (!written(v)) {
      if (verts_[v].free_pos != kNone) free_erase(v);
      verts_[v].flags |= kHasOutput;
      verts_[v].out_id = next_out_id_++;
      ++stats_.vertices_written;
      PSQ_RETURN_IF_ERROR(converter_.vertex(verts_[v].out_id, verts_[v].p, vertex_values(v)));
    }
    ids[k] = verts_[v].out_id;
  }
  PSQ_RETURN_IF_ERROR(converter_.triangle(ids, face_values(t)));
  if (out_count_[t] == 0) ++stats_.starts_written;
  ++stats_.triangles_written;
  for (uint32_t k = 0; k < 3; ++k) {
    const uint32_t o = corners_[3 * t + k].opposite;
    if (o < kOpen) {
      corners_[o].opposite = kWritten;
      set_out_count(o / 3, static_cast<uint8_t>(out_count_[o / 3] + 1));
    } else if (o < kWritten) {
      eslot_[o & ~kOpen] = kWrittenEdge;
    }
  }
  const uint32_t v0 = corners_[3 * t].vertex, v1 = corners_[3 * t + 1].vertex, v2 = corners_[3 * t + 2].vertex;
  kill_triangle(t);
  PSQ_RETURN_IF_ERROR(retire_if_done(v0));
  PSQ_RETURN_IF_ERROR(retire_if_done(v1));
  return retire_if_done(v2);
}

uint32_t TriangleBuffer::pick_output(int candidates, const float* score) {
  if (!out_set_[3].empty()) return out_set_[3].back();
  if (!out_set_[2].empty()) return out_set_[2].back();
  const std::vector<uint32_t>& ones = out_set_[1];
  if (!ones.empty()) {
    uint32_t best = kNone;
    float best_score = 0;
    const int n = std::max(1, candidates);
    for (int i = 0; i < n; ++i) {
      const uint32_t t = ones[ones.size() == 1 ? 0 : random() % ones.size()];
      uint32_t c = 3 * t;
      while (corners_[c].opposite != kWritten) ++c;
      const uint32_t free_vertex = corners_[prev(c)].vertex;
      if (written(free_vertex)) return t;  // a join
      const float s = score ? score[free_vertex] : 0.0f;
      if (best == kNone || s > best_score) {
        best = t;
        best_score = s;
      }
    }
    return best;
  }
  while (arrival_head_ < arrival_.size() && !arrived(arrival_[arrival_head_])) ++arrival_head_;
  if (arrival_head_ < arrival_.size()) return arrival_[arrival_head_].triangle;
  return kNone;
}

Status TriangleBuffer::finish() {
  while (alive_ > 0) {
    const uint32_t t = pick_output(1, nullptr);
    if (t == kNone) return Status(ErrorCode::kInternal, "triangle buffer: no triangle to write");
    PSQ_RETURN_IF_ERROR(write(t));
  }
  return converter_.finish();
}

bool TriangleBuffer::can_collapse(uint32_t h) {
  const uint32_t a = corners_[h].vertex, b = corners_[next(h)].vertex;
  if (locked(a) || locked(b)) return false;
  const uint32_t o = corners_[h].opposite;
  const bool interior = o < kOpen;
  if (!interior && o != kBorder) return false;
  // Both ends on a border, joined through the interior: the collapse would
  // pinch the surface at one vertex (the dummy vertex closing the border
  // is a common neighbour that is not across the edge).
  if (interior && border(a) && border(b)) return false;
  if (epoch_ > 0xfffffff0u) {
    for (Vertex& r : verts_) r.mark = 0;
    epoch_ = 0;
  }
  epoch_ += 2;
  uint32_t fan_a = 0, fan_b = 0;
  for (uint32_t c = verts_[a].head; c != kNone; c = corners_[c].next) {
    verts_[corners_[next(c)].vertex].mark = epoch_;
    verts_[corners_[prev(c)].vertex].mark = epoch_;
    ++fan_a;
  }
  uint32_t common = 0;
  for (uint32_t c = verts_[b].head; c != kNone; c = corners_[c].next) {
    ++fan_b;
    for (uint32_t u : {corners_[next(c)].vertex, corners_[prev(c)].vertex}) {
      if (u != a && verts_[u].mark == epoch_) {
        verts_[u].mark = epoch_ + 1;
        ++common;
      }
    }
  }
  const uint32_t across = interior ? 2 : 1;
  if (common != across) return false;
  const uint32_t remaining = fan_a + fan_b - 2 * across;
  if (remaining < ((border(a) || border(b)) ? 1u : 3u)) return false;
  // Each vertex across the edge keeps a triangle.
  for (uint32_t c : {prev(h), interior ? prev(o) : kNone}) {
    if (c == kNone) continue;
    const uint32_t first = verts_[corners_[c].vertex].head;
    if (corners_[first].next == kNone) return false;
  }
  return true;
}

uint32_t TriangleBuffer::collapse(uint32_t h, bool keep_start) {
  const uint32_t a = corners_[h].vertex, b = corners_[next(h)].vertex;
  const uint32_t keep = keep_start ? a : b, gone = keep_start ? b : a;
  const uint32_t o = corners_[h].opposite;
  for (uint32_t e : {h, o < kOpen ? o : kNone}) {
    if (e == kNone) continue;
    // The triangle's two other edges become one: the triangles across them
    // face each other (a border on one side makes the other a border).
    const uint32_t x = corners_[next(e)].opposite, y = corners_[prev(e)].opposite;
    if (x < kOpen) corners_[x].opposite = y;
    if (y < kOpen) corners_[y].opposite = x;
    kill_triangle(e / 3);
  }
  // The corners of the gone vertex now belong to the kept one.
  uint32_t tail = kNone;
  for (uint32_t c = verts_[gone].head; c != kNone; c = corners_[c].next) {
    corners_[c].vertex = keep;
    tail = c;
  }
  if (tail != kNone) {
    corners_[tail].next = verts_[keep].head;
    verts_[keep].head = verts_[gone].head;
  }
  verts_[keep].flags |= verts_[gone].flags & (kBorderVertex | kCut);
  verts_[gone].head = kNone;
  free_vertex_record(gone);
  ++stats_.collapses;
  return keep;
}

bool TriangleBuffer::can_discard(uint32_t t) const {
  for (uint32_t k = 0; k < 3; ++k)
    if (locked(corners_[3 * t + k].vertex)) return false;
  return true;
}

void TriangleBuffer::discard(uint32_t t) {
  uint32_t v[3];
  for (uint32_t k = 0; k < 3; ++k) {
    const uint32_t c = 3 * t + k;
    v[k] = corners_[c].vertex;
    const uint32_t o = corners_[c].opposite;
    if (o < kOpen) {
      // Unlocked ends: the edge is neither open nor written, so the
      // triangle across is in the buffer; its edge is a border now.
      corners_[o].opposite = kBorder;
      verts_[corners_[o].vertex].flags |= kBorderVertex;
      verts_[corners_[next(o)].vertex].flags |= kBorderVertex;
    }
  }
  kill_triangle(t);
  ++stats_.triangles_discarded;
  // Unlocked vertices are input-final and unwritten: one left without
  // triangles is dropped (nothing to finalize in the converter).
  for (uint32_t k = 0; k < 3; ++k) {
    const bool repeated = (k > 0 && v[k] == v[0]) || (k > 1 && v[k] == v[1]);
    if (!repeated && verts_[v[k]].head == kNone) free_vertex_record(v[k]);
  }
}

bool TriangleBuffer::cycle_of(uint32_t h, uint32_t* third) {
  const uint32_t a = corners_[h].vertex, b = corners_[next(h)].vertex;
  const uint32_t o = corners_[h].opposite;
  if (o >= kOpen) return false;
  for (uint32_t v : {a, b})
    if (locked(v) || border(v) || cut(v)) return false;
  if (epoch_ > 0xfffffff0u) {
    for (Vertex& r : verts_) r.mark = 0;
    epoch_ = 0;
  }
  epoch_ += 2;
  for (uint32_t c = verts_[a].head; c != kNone; c = corners_[c].next) {
    verts_[corners_[next(c)].vertex].mark = epoch_;
    verts_[corners_[prev(c)].vertex].mark = epoch_;
  }
  const uint32_t x = corners_[prev(h)].vertex, y = corners_[prev(o)].vertex;
  for (uint32_t c = verts_[b].head; c != kNone; c = corners_[c].next) {
    for (uint32_t u : {corners_[next(c)].vertex, corners_[prev(c)].vertex}) {
      if (u == a || u == x || u == y || verts_[u].mark != epoch_) continue;
      if (locked(u) || border(u) || cut(u)) continue;
      *third = u;
      return true;
    }
  }
  return false;
}

// The corners of v on the left of the path from -> v -> to... going round
// v from its corner whose edge runs to `to` until the one whose previous
// corner is `from`; false if the fan does not close that way.
bool TriangleBuffer::left_fan(uint32_t v, uint32_t from, uint32_t to, std::vector<uint32_t>* out) const {
  out->clear();
  uint32_t start = kNone, fan = 0;
  for (uint32_t c = verts_[v].head; c != kNone; c = corners_[c].next) {
    ++fan;
    if (corners_[next(c)].vertex == to) start = c;
  }
  if (start == kNone) return false;
  uint32_t c = start;
  for (uint32_t i = 0; i < fan; ++i) {
    out->push_back(c);
    if (corners_[prev(c)].vertex == from) return out->size() < fan;
    const uint32_t o = corners_[prev(c)].opposite;
    if (o >= kOpen || corners_[o].vertex != v) return false;
    c = o;
  }
  return false;
}

uint32_t TriangleBuffer::clone_vertex(uint32_t v) {
  uint32_t w;
  if (!free_vertices_.empty()) {
    w = free_vertices_.back();
    free_vertices_.pop_back();
  } else {
    w = static_cast<uint32_t>(verts_.size());
    verts_.emplace_back();
    if (has_vertex_values_) vertex_values_.emplace_back();
  }
  Vertex& r = verts_[w];
  for (int i = 0; i < 3; ++i) r.p[i] = verts_[v].p[i];
  r.head = kNone;
  r.out_id = kNone;
  r.dense = kNone;  // no input slot refers to it
  r.free_pos = kNone;
  r.mark = 0;
  r.flags = kInputFinal;
  if (has_vertex_values_) vertex_values_[w] = vertex_values_[v];
  ++vertices_;
  stats_.max_vertices = std::max<uint64_t>(stats_.max_vertices, vertices_);
  free_insert(w);
  return w;
}

uint32_t TriangleBuffer::allocate_triangle(uint8_t open) {
  uint32_t tri;
  if (!free_triangles_.empty()) {
    tri = free_triangles_.back();
    free_triangles_.pop_back();
  } else {
    tri = static_cast<uint32_t>(alive_flag_.size());
    corners_.resize(corners_.size() + 3);
    alive_flag_.push_back(0);
    out_count_.push_back(0);
    open_count_.push_back(0);
    out_pos_.push_back(0);
    arrival_when_.push_back(0);
    if (has_face_values_) face_values_.emplace_back();
  }
  alive_flag_[tri] = 1;
  out_count_[tri] = 0;
  open_count_[tri] = open;
  return tri;
}

uint32_t TriangleBuffer::new_cap(uint32_t v0, uint32_t v1, uint32_t v2, uint32_t values_from) {
  const uint32_t tri = allocate_triangle(0);
  ++alive_;
  if (has_face_values_) face_values_[tri] = face_values_[values_from];
  const uint32_t vs[3] = {v0, v1, v2};
  for (uint32_t k = 0; k < 3; ++k) {
    corners_[3 * tri + k].vertex = vs[k];
    corners_[3 * tri + k].opposite = kBorder;  // paired by the caller
    add_corner(vs[k], 3 * tri + k);
  }
  const uint32_t when = static_cast<uint32_t>(stats_.triangles_read);
  arrival_when_[tri] = when;
  arrival_.push_back({tri, when});
  stats_.max_triangles = std::max<uint64_t>(stats_.max_triangles, alive_);
  return tri;
}

bool TriangleBuffer::cut(uint32_t h, uint32_t c, uint32_t new_vertices[3], uint32_t caps[2]) {
  const uint32_t a = corners_[h].vertex, b = corners_[next(h)].vertex;
  if (alive_ + 2 > kMaxTriangles) return false;
  // The left side of a -> b -> c -> a, around each vertex of the cycle.
  std::vector<uint32_t> fan_a, fan_b, fan_c;
  if (!left_fan(a, c, b, &fan_a) || !left_fan(b, a, c, &fan_b) || !left_fan(c, b, a, &fan_c)) return false;
  // The corners along the cycle: on the left (their edges run with it) and
  // across them on the right.
  const uint32_t left[3] = {fan_a.front(), fan_b.front(), fan_c.front()};  // a->b, b->c, c->a
  uint32_t right[3];
  for (int k = 0; k < 3; ++k) {
    right[k] = corners_[left[k]].opposite;
    if (right[k] >= kOpen) return false;
  }
  if (fan_a.back() / 3 != left[2] / 3 || fan_b.back() / 3 != left[0] / 3 || fan_c.back() / 3 != left[1] / 3)
    return false;
  const uint32_t v[3] = {a, b, c};
  const std::vector<uint32_t>* fans[3] = {&fan_a, &fan_b, &fan_c};
  for (int k = 0; k < 3; ++k) {
    const uint32_t w = clone_vertex(v[k]);
    new_vertices[k] = w;
    for (uint32_t corner : *fans[k]) {
      remove_corner(v[k], corner);
      corners_[corner].vertex = w;
      add_corner(w, corner);
    }
  }
  const uint32_t a2 = new_vertices[0], b2 = new_vertices[1], c2 = new_vertices[2];
  // Right: (a, b, c), edges a->b, b->c, c->a against the right corners
  // (b->a, c->b, a->c). Left: (a', c', b'), edges a'->c', c'->b', b'->a'
  // against the left corners (c'->a', b'->c', a'->b').
  const uint32_t r = new_cap(a, b, c, right[0] / 3);
  const uint32_t l = new_cap(a2, c2, b2, left[0] / 3);
  const uint32_t pair_right[3] = {3 * r, 3 * r + 1, 3 * r + 2};
  for (int k = 0; k < 3; ++k) {
    corners_[pair_right[k]].opposite = right[k];
    corners_[right[k]].opposite = pair_right[k];
  }
  const uint32_t pair_left[3] = {3 * l + 2, 3 * l + 1, 3 * l};  // b'->a', c'->b', a'->c'
  for (int k = 0; k < 3; ++k) {
    corners_[pair_left[k]].opposite = left[k];
    corners_[left[k]].opposite = pair_left[k];
  }
  caps[0] = r;
  caps[1] = l;
  ++stats_.cuts;
  return true;
}

}  // namespace psq

