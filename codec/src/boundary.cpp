// SPDX-License-Identifier: Apache-2.0
// codec/src/boundary.cpp: see boundary.h; the rules are spec/psq-format.md
// section 6.1.
#include "boundary.h"

#include <algorithm>
#include <cassert>

#include "coding.h"
#include "geometry.h"

namespace psq {
namespace codec {

// The pieces of apply() and the checks of find_completions() are forced
// inline (PSQ_INLINE, coding.h): GCC would keep them as calls, a few per
// triangle, in the decoder's and the encoder's loops.

// Edge k of t, whose endpoints are both old: new to the mesh, it enters or
// is a border as t.border says; else it must complete its open twin (an
// edge open already, or dead, is an error: spec 13.6.3).
template <bool L>
PSQ_INLINE bool BasicBoundary<L>::classify_old_edge(BTriangle& t, int k, const Neighbors& used) const {
  const uint32_t u = t.c[k], w = t.c[k == 2 ? 0 : k + 1];
  if (!used.contains(u, w)) {
    t.completes[k] = kNone;
    t.state[k] = t.border[k] ? EdgeState::kBorder : EdgeState::kEnters;
    return true;
  }
  t.completes[k] = find_edge(w, u);
  t.state[k] = EdgeState::kCompletes;
  return t.completes[k] != kNone;
}

// An edge with a new endpoint enters or is a border.
PSQ_INLINE void classify_new_edge(BTriangle& t, int k) {
  t.completes[k] = kNone;
  t.state[k] = t.border[k] ? EdgeState::kBorder : EdgeState::kEnters;
}

template <bool L>
bool BasicBoundary<L>::find_completions(BTriangle& t, const Neighbors& used) const {
  if (t.gate == kNone) {
    for (int k = 0; k < 3; ++k) {
      if (t.is_new[k] || t.is_new[(k + 1) % 3]) classify_new_edge(t, k);
      else if (!classify_old_edge(t, k, used)) return false;
    }
    return true;
  }
  // Edge 0 (q->p) completes the gate p->q. The lookups could not find
  // otherwise: an open p->q has no open twin q->p (that would have
  // completed it) and {p, q} is no dead edge (p->q could not have entered
  // over one, and nothing made it dead while p->q stayed open).
  t.completes[0] = t.gate;
  t.state[0] = EdgeState::kCompletes;
  if (t.is_new[2]) {  // an add: edges 1 and 2 touch the new vertex
    classify_new_edge(t, 1);
    classify_new_edge(t, 2);
    return true;
  }
  // When x is the vertex before the gate, edge 1 (p->x) completes the open
  // edge before it, x->p (its links end and start at the shared vertex,
  // spec 6.1.2); for the same reason as above, no lookup could find
  // otherwise. Likewise edge 2 (x->q) and the open edge after the gate.
  const BEdge& g = edges_[t.gate];
  const uint32_t x = t.c[2];
  if (g.prev != kNone && edges_[g.prev].org == x) {
    t.completes[1] = g.prev;
    t.state[1] = EdgeState::kCompletes;
    return classify_old_edge(t, 2, used);
  }
  if (g.next != kNone && edges_[g.next].dst == x) {
    t.completes[2] = g.next;
    t.state[2] = EdgeState::kCompletes;
    return classify_old_edge(t, 1, used);
  }
  return classify_old_edge(t, 1, used) && classify_old_edge(t, 2, used);
}

// Makes q follow p on its loop (either may be kNone), first detaching
// whatever followed p and whatever preceded q, so that next and prev stay
// mutual (spec 6.1.2).
template <bool L>
PSQ_INLINE void BasicBoundary<L>::link(uint32_t p, uint32_t q) {
  if (p != kNone) {
    uint32_t old = edges_[p].next;
    if (old != kNone && edges_[old].prev == p) edges_[old].prev = kNone;
    edges_[p].next = q;
  }
  if (q != kNone) {
    uint32_t old = edges_[q].prev;
    if (old != kNone && edges_[old].next == q) edges_[old].next = kNone;
    edges_[q].prev = p;
  }
}

template <bool L>
PSQ_INLINE uint32_t BasicBoundary<L>::enter_edge(BTriangle& t, int k) {
  const uint32_t s = alloc_edge();
  if (s == kNone) return kNone;
  const uint32_t org = t.c[k], dst = t.c[k == 2 ? 0 : k + 1], opp = t.c[k == 0 ? 2 : k - 1];
  BEdge& e = edges_[s];
  e.org = org;
  e.dst = dst;
  const BVertex& o = vertices_[opp];
  e.opp[0] = o.pos[0];
  e.opp[1] = o.pos[1];
  e.opp[2] = o.pos[2];
  BVertex& vo = vertices_[org];
  BVertex& vd = vertices_[dst];
  ++vo.open;
  ++vd.open;
  t.eslot[k] = s;
  e.age = entered_++;
  if constexpr (L) list_entered(s);
  return s;
}

template <bool L>
PSQ_INLINE void BasicBoundary<L>::close_edge(BTriangle& t, int k) {
  t.eslot[k] = t.completes[k];
  free_edge(t.completes[k]);
}

template <bool L>
PSQ_INLINE void BasicBoundary<L>::finish_triangle(BTriangle& t) {
  for (int k = 0; k < 3; ++k) {
    BVertex& v = vertices_[t.c[k]];
    ++v.degree;
    t.final[k] = v.open == 0;
  }
}

template <bool L>
bool BasicBoundary<L>::apply(BTriangle& t) {
  if (t.gate != kNone && t.join_edge == kNone && t.state[1] != EdgeState::kBorder &&
      t.state[2] != EdgeState::kBorder)
    return apply_on_gate(t);
  // Entering edges take their slots first (a completed edge's slot is freed
  // after them, so that no slot leaves and enters the boundary in one
  // triangle, psq/sequence.h). Taking a free slot changes no open edge's
  // links (next and prev are mutual, and freeing an edge clears its
  // neighbours' links to it), so the links below still read the old ones.
  uint32_t fresh[3] = {kNone, kNone, kNone};
  for (int k = 0; k < 3; ++k) {
    if (t.state[k] != EdgeState::kEnters) continue;
    fresh[k] = enter_edge(t, k);
    if (fresh[k] == kNone) return false;
  }
  // Spec 6.1.2: the links at each corner k, between what precedes it (from
  // its entering edge (k + 2) % 3) and what follows it (from its leaving
  // edge k), computed from the old links; an edge this triangle completes
  // links to nothing.
  auto is_completed = [&](uint32_t e) {
    return e != kNone && (e == t.completes[0] || e == t.completes[1] || e == t.completes[2]);
  };
  auto before = [&](int a) {  // what precedes corner (a + 1) % 3 along its edge a
    if (t.state[a] == EdgeState::kEnters) return fresh[a];
    if (t.state[a] == EdgeState::kBorder) return kNone;
    const uint32_t e = edges_[t.completes[a]].prev;
    return is_completed(e) ? kNone : e;
  };
  auto after = [&](int b) {  // what follows corner b along its edge b
    if (t.state[b] == EdgeState::kEnters) return fresh[b];
    if (t.state[b] == EdgeState::kBorder) return kNone;
    const uint32_t e = edges_[t.completes[b]].next;
    return is_completed(e) ? kNone : e;
  };
  uint32_t lp[4], lq[4];
  int nlinks = 0;
  for (int k = 0; k < 3; ++k) {
    const int a = k == 0 ? 2 : k - 1;
    const uint32_t P = before(a), Q = after(k);
    if (t.join_edge != kNone && t.state[a] != EdgeState::kCompletes && t.state[k] != EdgeState::kCompletes &&
        !t.is_new[k]) {
      // The triangle goes into the gap (gi, go) at an old vertex.
      const BEdge& j = edges_[t.join_edge];
      uint32_t gi, go;
      if (j.org == t.c[k]) { go = t.join_edge; gi = j.prev; }
      else { gi = t.join_edge; go = j.next; }
      if (is_completed(gi)) gi = kNone;
      if (is_completed(go)) go = kNone;
      lp[nlinks] = P; lq[nlinks] = go; ++nlinks;
      lp[nlinks] = gi; lq[nlinks] = Q; ++nlinks;
    } else {
      lp[nlinks] = P; lq[nlinks] = Q; ++nlinks;
    }
  }
  for (int k = 0; k < 3; ++k) {
    if (t.state[k] == EdgeState::kCompletes) close_edge(t, k);
    else if (t.state[k] == EdgeState::kBorder) t.eslot[k] = kNone;
  }
  for (int i = 0; i < nlinks; ++i) link(lp[i], lq[i]);
  // The reference edge R (spec 6.1.2 step 5): the first entering edge in edge order 1, 2, 0.
  reference_ = fresh[1] != kNone ? fresh[1] : fresh[2] != kNone ? fresh[2] : fresh[0];
  finish_triangle(t);
  return true;
}

// apply() for the common triangle: on a gate (edge 0 completes it), no
// join, edges 1 and 2 each entering or completing (adds, fills and ends
// without borders, most of a mesh). The same steps in the same order as the
// general case, with its tests on borders and joins resolved.
template <bool L>
bool BasicBoundary<L>::apply_on_gate(BTriangle& t) {
  // A fill whose completed neighbour is linked to the gate (the common
  // case, and every fill whose third vertex was named "left" or "right").
  const BEdge& gate = edges_[t.completes[0]];
  if (t.state[1] == EdgeState::kEnters) {
    if (t.state[2] == EdgeState::kEnters) return apply_add(t);
    if (t.completes[2] == gate.next) return apply_fill(t, 1);
  } else if (t.state[2] == EdgeState::kEnters && t.completes[1] == gate.prev) {
    return apply_fill(t, 2);
  }
  const bool enters1 = t.state[1] == EdgeState::kEnters, enters2 = t.state[2] == EdgeState::kEnters;
  uint32_t fresh1 = kNone, fresh2 = kNone;
  if (enters1 && (fresh1 = enter_edge(t, 1)) == kNone) return false;
  if (enters2 && (fresh2 = enter_edge(t, 2)) == kNone) return false;
  const uint32_t g = t.completes[0], c1 = t.completes[1], c2 = t.completes[2];  // c1, c2: kNone when entering
  // An old link to an edge this triangle completes links to nothing.
  auto kept = [&](uint32_t e) { return e == g || e == c1 || e == c2 ? kNone : e; };
  const uint32_t gate_prev = kept(edges_[g].prev), gate_next = kept(edges_[g].next);
  const uint32_t before1 = enters1 ? fresh1 : kept(edges_[c1].prev);
  const uint32_t after1 = enters1 ? fresh1 : kept(edges_[c1].next);
  const uint32_t before2 = enters2 ? fresh2 : kept(edges_[c2].prev);
  const uint32_t after2 = enters2 ? fresh2 : kept(edges_[c2].next);
  close_edge(t, 0);
  if (!enters1) close_edge(t, 1);
  if (!enters2) close_edge(t, 2);
  link(before2, gate_next);  // corner 0
  link(gate_prev, after1);   // corner 1
  link(before1, after2);     // corner 2
  reference_ = fresh1 != kNone ? fresh1 : fresh2;
  finish_triangle(t);
  return true;
}

// apply_on_gate() for an add (p->x and x->q enter, the gate closes) and
// for a fill whose edge 3 - k completes the gate's neighbour on its side
// (linked to it: the edge before the gate for k = 2, after it for k = 1)
// and whose edge k enters: lean_add() and lean_fill().
template <bool L>
PSQ_INLINE bool BasicBoundary<L>::apply_add(BTriangle& t) {
  const uint32_t f1 = lean_add(t.completes[0], t.c[2]);
  if (f1 == kNone) return false;
  t.eslot[0] = t.completes[0];
  t.eslot[1] = f1;
  t.eslot[2] = edges_[f1].next;
  t.final[0] = t.final[1] = t.final[2] = false;
  return true;
}

template <bool L>
PSQ_INLINE bool BasicBoundary<L>::apply_fill(BTriangle& t, int k) {
  uint32_t final;
  const uint32_t f = lean_fill(t.completes[0], k == 2, &final);
  if (f == kNone) return false;
  t.eslot[0] = t.completes[0];
  t.eslot[3 - k] = t.completes[3 - k];
  t.eslot[k] = f;
  for (int i = 0; i < 3; ++i) t.final[i] = (final >> i) & 1;
  return true;
}

template <bool L>
uint32_t BasicBoundary<L>::grow_edges() {
  if (edges_.size() >= limit_) return kNone;
  edges_.emplace_back();
  return static_cast<uint32_t>(edges_.size() - 1);
}

template <bool L>
void BasicBoundary<L>::load_vertex(uint32_t slot, uint32_t index, uint32_t key, uint32_t degree,
                                   const int64_t pos[3]) {
  if (slot >= vertices_.size()) {
    vertices_.resize(size_t{slot} + 1);
    vlive_.resize(size_t{slot} + 1, 0);
    if constexpr (L) links_.resize(size_t{slot} + 1);
  }
  BVertex& v = vertices_[slot];
  v = BVertex();
  v.index = index;
  v.key = key;
  v.degree = degree;
  for (int i = 0; i < 3; ++i) v.pos[i] = pos[i];
  vlive_[slot] = 1;
  ++active_vertices_;
}

template <bool L>
void BasicBoundary<L>::load_edge(uint32_t slot, uint32_t org, uint32_t dst, uint64_t age, const int64_t opp[3]) {
  if (slot >= edges_.size()) edges_.resize(size_t{slot} + 1);
  BEdge& e = edges_[slot];
  e.org = org;
  e.dst = dst;
  e.age = age;
  e.live = true;
  for (int i = 0; i < 3; ++i) e.opp[i] = opp[i];
  ++vertices_[org].open;
  ++vertices_[dst].open;
  ++open_edges_;
  loaded_.push_back(slot);
  if constexpr (L) list_entered(slot);
}

template <bool L>
void BasicBoundary<L>::load_end(const uint32_t* next, uint64_t entered, uint32_t reference) {
  // The links once every edge is there: next and prev mutual (6.1.2).
  for (size_t i = 0; i < loaded_.size(); ++i) {
    BEdge& e = edges_[loaded_[i]];
    e.next = next[i] == kNone ? kNone : loaded_[next[i]];
    e.prev = kNone;
  }
  for (uint32_t s : loaded_)
    if (edges_[s].next != kNone) edges_[edges_[s].next].prev = s;
  entered_ = entered;
  reference_ = reference == kNone ? kNone : loaded_[reference];
  loaded_.clear();
  loaded_.shrink_to_fit();
  // Spec 4.6: the free slots below the highest live one, the lowest on top.
  for (size_t s = vertices_.size(); s-- > 0;)
    if (!vlive_[s]) free_vertices_.push(static_cast<uint32_t>(s));
  for (size_t s = edges_.size(); s-- > 0;)
    if (!edges_[s].live) free_edges_.push(static_cast<uint32_t>(s));
}

template class BasicBoundary<true>;
template class BasicBoundary<false>;

}  // namespace codec
}  // namespace psq
