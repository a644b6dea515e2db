// SPDX-License-Identifier: Apache-2.0
// codec/src/boundary.h: the processing boundary as the .psq encoder and
// decoder both track it (spec/psq-format.md section 6.1).
//
// The encoder and the decoder run this same code on the same triangles, so
// they agree on every slot number and link that the bitstream refers to.
//
// Elements:
// - a vertex slot per active vertex (introduced, not finalized): its dense
//   index, its coded coordinates, how many triangles used it so far and
//   (kLookups only) its lists of open boundary edges leaving and entering
//   it;
// - an edge slot per open boundary edge (a directed edge of a coded
//   triangle that no second triangle completed yet and that is not a
//   border): its endpoints, the coordinates of the triangle's third vertex
//   (for the parallelogram prediction, spec 7.3) and `next`/`prev` links
//   that chain the boundary edges into loops (section 6.1.2).
//
// The encoder decides which edges a triangle completes by looking the
// reversed edge up among the open edges of its endpoint; the decoder takes
// them from the record, and its new-edge check (neighbors.h, spec 13.6.3)
// rejects a record that would complete an edge it does not name. The links
// serve to name the gate and the third vertex cheaply (`next(R)`,
// "the vertex before the gate", spec 13.7.3); they are updated by fixed
// local rules that both sides apply identically.
#ifndef PSQ_CODEC_BOUNDARY_H_
#define PSQ_CODEC_BOUNDARY_H_

#include <cassert>
#include <cstdint>
#include <vector>

#include "coding.h"
#include "geometry.h"
#include "neighbors.h"

namespace psq {
namespace codec {

constexpr uint32_t kNone = 0xffffffffu;

struct BVertex {
  uint32_t index = 0;        // dense index in the sequence
  uint32_t key = 0;          // the encoder's input index (for its map); decode_mesh's mesh index
  uint32_t open = 0;         // open edges touching it
  uint32_t degree = 0;       // triangles that used it so far
  int64_t pos[3] = {0, 0, 0};  // coded coordinates (spec 7.1)
};

// A vertex's lookups (kLookups only), beside its BVertex rather than in it,
// so that the fast decoder's vertices take 40 bytes instead of 48 (its
// boundary's arrays are what it touches at random).
struct BLinks {
  uint32_t first_out = kNone;  // open edges leaving it (through BEdge::next_out)
  uint32_t first_in = kNone;   // open edges entering it (through BEdge::next_in)
};

struct BEdge {
  uint32_t org = kNone, dst = kNone;  // vertex slots
  uint32_t next = kNone, prev = kNone;  // loop links (edge slots)
  uint32_t next_out = kNone;  // next open edge leaving `org`
  uint32_t next_in = kNone;   // next open edge entering `dst`
  int64_t opp[3] = {0, 0, 0};  // coordinates of the third vertex of its triangle
  uint64_t age = 0;  // when it entered: the count of edges that entered before it (spec 6.1.1, 13.6.2)
  bool live = false;
};

// What a triangle does to each of its edges (spec 6.2.2).
enum class EdgeState : uint8_t { kCompletes, kEnters, kBorder };

// A triangle in the codec's canonical corner order: corner 0 = q, 1 = p,
// 2 = x for a triangle on gate p->q (edge 0, q->p, completes the gate), or
// three new vertices for a start. Filled in by the caller, then by apply().
struct BTriangle {
  uint32_t c[3] = {kNone, kNone, kNone};  // vertex slots
  bool is_new[3] = {false, false, false};
  // Input to apply(): border flag for each edge that does not complete.
  bool border[3] = {false, false, false};
  // Input to apply() for a join: the open edge that names the gap at the
  // third vertex into which the triangle goes (spec 6.1.2), else kNone.
  uint32_t join_edge = kNone;
  // Input to find_completions(): the open gate edge p->q that edge 0
  // (q->p) completes, or kNone for a start.
  uint32_t gate = kNone;
  // Output of find_completions() and apply():
  uint32_t completes[3] = {kNone, kNone, kNone};  // the open edge each edge completes
  EdgeState state[3] = {EdgeState::kEnters, EdgeState::kEnters, EdgeState::kEnters};
  uint32_t eslot[3] = {kNone, kNone, kNone};  // completed or entering edge slot
  bool final[3] = {false, false, false};      // corner's vertex has no open edge left
};

// The free slots of one kind, last freed first (the order the spec's slot
// numbers follow, section 6.1.1).
using SlotStack = ArrayStack<uint32_t, 64>;

// kLookups: whether the boundary can find an open edge by its endpoints
// (the encoder, which must find a triangle's completions and check its
// input). Without them (the decoder, whose
// records name every completion, spec 13.6), it keeps only slots, counts
// and loop links: find_edge() and find_completions() must not be used,
// and apply() takes the completions it is given.
template <bool kLookups>
class BasicBoundary {
 public:
  // `limit`: most vertex slots and most edge slots that may be in use at
  // once (the header's boundary limit, spec 4.2).
  explicit BasicBoundary(uint32_t limit) : limit_(limit) {}

  // Room for `n` vertex slots and `n` edge slots without moving the arrays
  // (address space only: nothing is touched).
  void reserve(uint32_t n) {
    vertices_.reserve(n);
    if constexpr (kLookups) links_.reserve(n);
    vlive_.reserve(n);
    edges_.reserve(n);
  }
  // Empty, as a new one with the same limit, but keeping the arrays' room
  // (a segment restart, spec 4.6, loads about as many slots again).
  void reset() {
    vertices_.clear();
    links_.clear();
    vlive_.clear();
    free_vertices_.clear();
    edges_.clear();
    free_edges_.clear();
    active_vertices_ = open_edges_ = 0;
    reference_ = kNone;
    entered_ = 0;
    loaded_.clear();
  }
  // A new vertex slot, or kNone when `limit` vertices are active.
  uint32_t new_vertex(uint32_t index, uint32_t key, const int64_t pos[3]);
  // Releases a vertex slot (after its finalization).
  void free_vertex(uint32_t slot);

  BVertex& vertex(uint32_t slot) { return vertices_[slot]; }
  // A vertex's lookups (kLookups only).
  const BLinks& links(uint32_t slot) const { return links_[slot]; }
  const BVertex& vertex(uint32_t slot) const { return vertices_[slot]; }
  BEdge& edge(uint32_t slot) { return edges_[slot]; }
  const BEdge& edge(uint32_t slot) const { return edges_[slot]; }

  // Vertex slots in use, and slots ever handed out (slot numbers are below).
  uint32_t active_vertices() const { return active_vertices_; }
  uint32_t open_edges() const { return open_edges_; }
  uint32_t edge_capacity() const { return static_cast<uint32_t>(edges_.size()); }
  uint32_t vertex_capacity() const { return static_cast<uint32_t>(vertices_.size()); }
  bool edge_live(uint32_t slot) const { return slot < edges_.size() && edges_[slot].live; }
  bool vertex_live(uint32_t slot) const { return slot < vlive_.size() && vlive_[slot]; }

  // The open edge a->b, or kNone.
  uint32_t find_edge(uint32_t a, uint32_t b) const;

  // Fills t.completes and t.state for each edge (borders are taken from
  // t.border where an edge does not complete). Returns false when the
  // triangle would put an edge on the boundary twice or use a dead edge (a
  // border, or an edge already used by two triangles; spec 13.6.3): an
  // edge between old vertices that `used` (every edge between the active
  // vertices) lists and that is no open edge's twin.
  bool find_completions(BTriangle& t, const Neighbors& used) const;

  // Applies a triangle whose completions were found: removes completed
  // edges, adds entering ones (with `opp` from the corner positions),
  // relinks the loops and updates degrees and open counts. Fills t.eslot and
  // t.final. Returns false when an entering edge would exceed the limit.
  bool apply(BTriangle& t);
  // apply() for the two triangles whose kind the decoder's common records
  // know (common_record()), without a BTriangle (same slots, links and ages
  // as apply()).
  // lean_add(): an add of new vertex slot x on `gate` (p->q);
  // p->x and x->q enter (in that order), the gate closes. Returns the slot
  // of p->x (x->q is its `next`), or kNone when an edge would exceed the
  // limit. lean_fill(): a fill on `gate` whose third vertex x is the origin
  // of the gate's `prev` (left) or the end of its `next` (right), which the
  // triangle completes; x->q (left) or p->x (right) enters. Returns the
  // entering edge's slot, or kNone at the limit, and sets *final to the
  // corners (bit k for corner k of q, p, x) whose vertex has no open edge
  // left. With kLookups they keep the endpoint lists as apply() does, in
  // the same order, so that later lookups and join edges are the same.
  uint32_t lean_add(uint32_t gate, uint32_t x);
  uint32_t lean_fill(uint32_t gate, bool left, uint32_t* final);

  // The reference edge R after the last apply() (spec 6.1.2 step 5,
  // 13.6.1): the first entering edge of the last triangle in edge order
  // 1, 2, 0, or kNone.
  uint32_t reference() const { return reference_; }
  // Edges that ever entered (spec 6.1.2 step 2).
  uint64_t entered() const { return entered_; }

  // A boundary loaded from the state of a segment record (segment.h), on
  // a fresh one: its vertices and edges in their slots, then load_end(),
  // which makes any other slot below the
  // highest one of each kind free, the lowest taken first (segment states
  // load dense slots, 0 to n - 1, which leaves none: spec 4.6).
  void load_vertex(uint32_t slot, uint32_t index, uint32_t key, uint32_t degree, const int64_t pos[3]);
  void load_edge(uint32_t slot, uint32_t org, uint32_t dst, uint64_t age, const int64_t opp[3]);
  // next[i] (kNone: none) for the i-th edge loaded.
  void load_end(const uint32_t* next, uint64_t entered, uint32_t reference);

 private:
  uint32_t alloc_edge();
  // alloc_edge() for lean_add() and lean_fill(), whose splice sets the
  // loop links: they are left as they were.
  uint32_t alloc_spliced_edge();
  // alloc_edge() without a free slot: a new one, or kNone at the limit.
  uint32_t grow_edges();
  // Pieces of apply(): edge k of t enters (a new slot, or kNone at the
  // limit); edge k completes t.completes[k]; degrees and final flags.
  uint32_t enter_edge(BTriangle& t, int k);
  void close_edge(BTriangle& t, int k);
  void finish_triangle(BTriangle& t);
  bool apply_on_gate(BTriangle& t);
  bool apply_add(BTriangle& t);
  bool apply_fill(BTriangle& t, int k);
  // kLookups: fresh edge s joins the endpoint lists; unlist() takes an
  // edge off them.
  void list_entered(uint32_t s);
  void unlist(uint32_t s);
  bool classify_old_edge(BTriangle& t, int k, const Neighbors& used) const;
  void free_edge(uint32_t slot);
  // free_edge() without the unlinking, for lean_fill() without lookups:
  // the loop links are symmetric (a.next = b exactly when b.prev = a, as
  // link() and the splices keep them), so the only links to the freed
  // edges are between them and from the edges before and after them,
  // which the splice overwrites.
  void retire_edge(uint32_t slot);
  void link(uint32_t p, uint32_t q);

  uint32_t limit_;
  std::vector<BVertex> vertices_;
  std::vector<BLinks> links_;  // per vertex slot, kLookups only
  // Per vertex slot, 1 while a vertex holds it. Not bytes: a store of a byte
  // may alias anything, and would make the decoder reload every field it
  // holds in registers.
  std::vector<uint32_t> vlive_;
  SlotStack free_vertices_;
  std::vector<BEdge> edges_;
  SlotStack free_edges_;
  uint32_t active_vertices_ = 0;
  uint32_t open_edges_ = 0;
  uint32_t reference_ = kNone;
  uint64_t entered_ = 0;  // edges that ever entered
  std::vector<uint32_t> loaded_;  // load_edge()'s slots, in order, until load_end()
};

// The members that the fast decoder runs once or twice per triangle are
// defined here, inline, so that they join its loop: as calls into
// boundary.cpp they would cost it register saves, and reloads of what a
// call might have changed, on every triangle.

template <bool L>
PSQ_INLINE uint32_t BasicBoundary<L>::new_vertex(uint32_t index, uint32_t key, const int64_t pos[3]) {
  uint32_t slot;
  if (!free_vertices_.empty()) {
    slot = free_vertices_.pop();
  } else {
    if (vertices_.size() >= limit_) return kNone;
    slot = static_cast<uint32_t>(vertices_.size());
    vertices_.emplace_back();
    if constexpr (L) links_.emplace_back();
    vlive_.push_back(0);
  }
  BVertex& v = vertices_[slot];
  v.index = index;
  v.key = key;
  v.open = v.degree = 0;
  if constexpr (L) links_[slot] = BLinks();
  for (int i = 0; i < 3; ++i) v.pos[i] = pos[i];
  vlive_[slot] = 1;
  ++active_vertices_;
  return slot;
}

template <bool L>
PSQ_INLINE void BasicBoundary<L>::free_vertex(uint32_t slot) {
  vlive_[slot] = 0;
  --active_vertices_;
  free_vertices_.push(slot);
}

template <bool L>
PSQ_INLINE uint32_t BasicBoundary<L>::find_edge(uint32_t a, uint32_t b) const {
  for (uint32_t e = links_[a].first_out; e != kNone; e = edges_[e].next_out)
    if (edges_[e].dst == b) return e;
  return kNone;
}

template <bool L>
PSQ_INLINE uint32_t BasicBoundary<L>::alloc_edge() {
  const uint32_t slot = alloc_spliced_edge();
  if (slot == kNone) return kNone;
  // apply() sets every other field.
  edges_[slot].next = edges_[slot].prev = kNone;
  return slot;
}

template <bool L>
PSQ_INLINE uint32_t BasicBoundary<L>::alloc_spliced_edge() {
  uint32_t slot;
  if (!free_edges_.empty()) {
    slot = free_edges_.pop();
  } else {
    slot = grow_edges();
    if (slot == kNone) return kNone;
  }
  edges_[slot].live = true;
  ++open_edges_;
  return slot;
}

template <bool L>
PSQ_INLINE void BasicBoundary<L>::retire_edge(uint32_t slot) {
  BEdge& e = edges_[slot];
  --vertices_[e.org].open;
  --vertices_[e.dst].open;
  e.live = false;
  --open_edges_;
  free_edges_.push(slot);
}

template <bool L>
PSQ_INLINE void BasicBoundary<L>::free_edge(uint32_t slot) {
  BEdge& e = edges_[slot];
  if (e.next != kNone && edges_[e.next].prev == slot) edges_[e.next].prev = kNone;
  if (e.prev != kNone && edges_[e.prev].next == slot) edges_[e.prev].next = kNone;
  if constexpr (L) unlist(slot);
  retire_edge(slot);
}

template <bool L>
PSQ_INLINE void BasicBoundary<L>::list_entered(uint32_t s) {
  BEdge& e = edges_[s];
  BLinks& lo = links_[e.org];
  BLinks& ld = links_[e.dst];
  e.next_out = lo.first_out;
  lo.first_out = s;
  e.next_in = ld.first_in;
  ld.first_in = s;
}

template <bool L>
PSQ_INLINE void BasicBoundary<L>::unlist(uint32_t s) {
  const BEdge& e = edges_[s];
  uint32_t* p = &links_[e.org].first_out;
  while (*p != s) p = &edges_[*p].next_out;
  *p = e.next_out;
  p = &links_[e.dst].first_in;
  while (*p != s) p = &edges_[*p].next_in;
  *p = e.next_in;
}

// lean_add() and lean_fill(): apply_add() and apply_fill() with the corners
// of the triangle (q, p, x) known from the gate. The slots are allocated,
// aged and freed in the same order as apply() would, so the slot numbers
// and the ring's ages agree with the encoder's boundary. Their splices set
// the loop links; the fresh edge that comes first becomes the reference
// edge R (spec 6.1.2 step 5).
template <bool L>
PSQ_INLINE uint32_t BasicBoundary<L>::lean_add(uint32_t gate, uint32_t x) {
  const uint32_t p = edges_[gate].org, q = edges_[gate].dst;
  const uint32_t f1 = alloc_spliced_edge();
  if (f1 == kNone) return kNone;
  const uint32_t f2 = alloc_spliced_edge();
  if (f2 == kNone) return kNone;
  BVertex& vp = vertices_[p];
  BVertex& vq = vertices_[q];
  BVertex& vx = vertices_[x];
  BEdge& e1 = edges_[f1];
  BEdge& e2 = edges_[f2];
  e1.org = p;
  e1.dst = x;
  e2.org = x;
  e2.dst = q;
  for (int k = 0; k < 3; ++k) {
    e1.opp[k] = vq.pos[k];
    e2.opp[k] = vp.pos[k];
  }
  e1.age = entered_++;
  e2.age = entered_++;
  // p and q trade the gate for a fresh edge; x has two.
  vx.open += 2;
  ++vp.degree;
  ++vq.degree;
  ++vx.degree;
  BEdge& g = edges_[gate];
  const uint32_t gate_prev = g.prev, gate_next = g.next;
  if constexpr (L) {
    // apply()'s order: f1 and f2 join the lists, the gate leaves them.
    list_entered(f1);
    list_entered(f2);
    unlist(gate);
  }
  g.live = false;
  --open_edges_;
  free_edges_.push(gate);
  // Fresh f1 then f2 between the gate's old neighbours.
  e1.prev = gate_prev;
  e1.next = f2;
  e2.prev = f1;
  e2.next = gate_next;
  if (gate_prev != kNone) edges_[gate_prev].next = f1;
  if (gate_next != kNone) edges_[gate_next].prev = f2;
  reference_ = f1;
  return f1;
}

template <bool L>
PSQ_INLINE uint32_t BasicBoundary<L>::lean_fill(uint32_t gate, bool left, uint32_t* final) {
  const uint32_t c = left ? edges_[gate].prev : edges_[gate].next;
  const uint32_t p = edges_[gate].org, q = edges_[gate].dst;
  const uint32_t x = left ? edges_[c].org : edges_[c].dst;
  const uint32_t f = alloc_spliced_edge();
  if (f == kNone) return kNone;
  // Left: x->q enters, opposite p. Right: p->x enters, opposite q.
  BEdge& e = edges_[f];
  e.org = left ? x : p;
  e.dst = left ? q : x;
  const BVertex& o = vertices_[left ? p : q];
  for (int k = 0; k < 3; ++k) e.opp[k] = o.pos[k];
  e.age = entered_++;
  ++vertices_[e.org].open;
  ++vertices_[e.dst].open;
  // The fresh edge takes the place of the two completed ones on the loop,
  // between the neighbour's other neighbour and the gate's other
  // neighbour. The triangle completes neither of these: the neighbour's
  // other neighbour ends or starts at x, not at p or q, and the gate's
  // other neighbour would be the fresh edge's twin (it would complete it,
  // not enter).
  const uint32_t before = left ? edges_[c].prev : edges_[gate].prev;
  const uint32_t after = left ? edges_[gate].next : edges_[c].next;
  if constexpr (L) {
    // apply()'s order: f joins the lists; the gate and then the neighbour
    // leave them (free_edge()).
    list_entered(f);
    free_edge(gate);
    free_edge(c);
  } else {
    retire_edge(gate);
    retire_edge(c);
  }
  e.prev = before;
  e.next = after;
  if (before != kNone) edges_[before].next = f;
  if (after != kNone) edges_[after].prev = f;
  reference_ = f;
  const uint32_t corner[3] = {q, p, x};
  uint32_t m = 0;
  for (int k = 0; k < 3; ++k) {
    BVertex& v = vertices_[corner[k]];
    ++v.degree;
    if (v.open == 0) m |= 1u << k;
  }
  *final = m;
  return f;
}

using Boundary = BasicBoundary<true>;
using FastBoundary = BasicBoundary<false>;

// The prediction of a record's i-th new vertex (spec 7.3) and its residual
// contexts (7.4). For an add (gate != kNone), by `choice` (coding.h): the
// parallelogram across the gate (kChoiceGate: the gate's endpoints and its
// opposite vertex) or across the open edge before or after it
// (kChoiceBefore, kChoiceAfter: that edge's endpoints and opposite
// vertex), with that predicting triangle's extent along each axis as
// context; or the mean of the gate's parallelogram and the one before or
// after (kChoiceMeanBefore, kChoiceMeanAfter), with the gate triangle's
// extents. The caller checks with prediction_choices() that the neighbour
// exists. For a start's vertices,
// the last coded position, then the first vertex, then the midpoint of the
// first two; `first` and `second` are the start's vertices coded so far.
struct Prediction {
  int64_t pos[3];
  int kind;   // kPredParallelogram, kPredNeighbour, kPredMean or kPredOther (coding.h)
  int extent[3];  // per axis: the bit length of the predicting triangle's extent, or 0
};

// The parallelogram point across open edge `edge` (spec 7.3): its
// endpoints' coordinates added, its `opp` subtracted, modulo 2^64.
template <class B>
PSQ_INLINE void parallelogram(const B& boundary, uint32_t edge, int64_t out[3]) {
  const BEdge& g = boundary.edge(edge);
  const int64_t* a = boundary.vertex(g.org).pos;
  const int64_t* b = boundary.vertex(g.dst).pos;
  for (int k = 0; k < 3; ++k) out[k] = wrap_sub(wrap_add(a[k], b[k]), g.opp[k]);
}

// The extents (spec 7.4) of the triangle that made `edge` open: per axis,
// the bit length of the largest coordinate distance of its corners.
template <class B>
PSQ_INLINE void triangle_extents(const B& boundary, uint32_t edge, int out[3]) {
  const BEdge& g = boundary.edge(edge);
  const int64_t* a = boundary.vertex(g.org).pos;
  const int64_t* b = boundary.vertex(g.dst).pos;
  for (int k = 0; k < 3; ++k) out[k] = triangle_extent(a, b, g.opp, k);
}

template <class B>
inline Prediction predict_new_vertex(const B& boundary, uint32_t gate, int i, const int64_t last[3],
                                     const int64_t first[3], const int64_t second[3], int choice = 0) {
  Prediction p;
  p.kind = kPredOther;
  p.extent[0] = p.extent[1] = p.extent[2] = 0;
  if (gate != kNone) {
    // Spec 7.3: the parallelogram over the chosen open edge, whose
    // triangle is the predicting triangle, or the mean of the gate's and
    // a neighbour's parallelograms, whose predicting triangle is the
    // gate's.
    const BEdge& g = boundary.edge(gate);
    const uint32_t edge[3] = {gate, g.prev, g.next};  // by side
    // Both parallelograms, and the mean taken by a mask: the choice is a
    // decoded symbol, which a branch would mispredict.
    int64_t across_gate[3], across_side[3];
    parallelogram(boundary, gate, across_gate);
    parallelogram(boundary, edge[choice_side(choice)], across_side);
    const int64_t mean = 0 - static_cast<int64_t>(choice >= kChoiceMeanBefore);
    for (int k = 0; k < 3; ++k)
      p.pos[k] = across_side[k] ^ ((midpoint(across_gate[k], across_side[k]) ^ across_side[k]) & mean);
    p.kind = prediction_kind(choice);
    triangle_extents(boundary, edge[predicting_side(choice)], p.extent);
    return p;
  }
  for (int k = 0; k < 3; ++k)
    p.pos[k] = i == 0 ? last[k] : i == 1 ? first[k] : midpoint(first[k], second[k]);
  return p;
}

// predict_new_vertex() for an add by choice 0: the parallelogram across
// `gate` with the gate triangle's extents (kPredParallelogram), the only
// prediction of the gate records of quantized streams with the rANS
// back-end (spec 13.8.2). Computed alone: predict_new_vertex() also forms
// a neighbour's parallelogram and the mean, for a choice known only at run
// time.
template <class B>
PSQ_INLINE Prediction predict_across_gate(const B& boundary, uint32_t gate) {
  Prediction p;
  parallelogram(boundary, gate, p.pos);
  p.kind = kPredParallelogram;
  triangle_extents(boundary, gate, p.extent);
  return p;
}

// Which neighbours of `gate` may take part in predicting the new vertex
// of an add (spec 7.3): bit 0, the open edge before the gate (its `prev`
// link); bit 1, the one after it (`next`). 0: only the gate.
template <class B>
inline uint32_t prediction_choices(const B& boundary, uint32_t gate) {
  const BEdge& g = boundary.edge(gate);
  return (g.prev != kNone ? 1u : 0u) | (g.next != kNone ? 2u : 0u);
}

// The shape context of a gate record's B symbol in the adaptive back-end
// (spec 13.7.3): where the parallelogram across `gate` points. With e the
// gate's length and dl, dr the distances of the parallelogram point to the
// vertex before the gate and to the vertex after it (largest coordinate
// difference, modulo 2^64): 1 (before) or 2 (after) when the nearer of them
// is closer than e / 2, 3 or 4 when it is closer than e, else 0. A fill
// closes the gap the new triangle would cover, so a vertex near where a new
// vertex would go predicts it.
template <class B>
int shape_context(const B& boundary, uint32_t gate) {
  auto linf = [](const int64_t* a, const int64_t* b) {
    uint64_t m = 0;
    for (int k = 0; k < 3; ++k) m = std::max(m, coord_distance(a[k], b[k]));
    return m;
  };
  const BEdge& g = boundary.edge(gate);
  int64_t par[3];
  parallelogram(boundary, gate, par);
  const uint64_t e = linf(boundary.vertex(g.org).pos, boundary.vertex(g.dst).pos);
  const uint64_t none = ~uint64_t{0};
  const uint64_t dl = g.prev != kNone ? linf(par, boundary.vertex(boundary.edge(g.prev).org).pos) : none;
  const uint64_t dr = g.next != kNone ? linf(par, boundary.vertex(boundary.edge(g.next).dst).pos) : none;
  const uint64_t d = std::min(dl, dr);
  const int side = dl <= dr ? 0 : 1;
  return d < (e >> 1) ? 1 + side : d < e ? 3 + side : 0;
}

}  // namespace codec
}  // namespace psq

#endif  // PSQ_CODEC_BOUNDARY_H_
