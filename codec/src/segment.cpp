// SPDX-License-Identifier: Apache-2.0
// codec/src/segment.cpp: see segment.h; the layout is spec/psq-format.md
// section 4.6.
#include "segment.h"

#include <algorithm>

#include "attributes.h"
#include "container.h"
#include "records.h"

namespace psq {
namespace codec {

namespace {

uint64_t zigzag(int64_t v) { return (static_cast<uint64_t>(v) << 1) ^ static_cast<uint64_t>(v >> 63); }
int64_t unzigzag(uint64_t u) { return static_cast<int64_t>(u >> 1) ^ -static_cast<int64_t>(u & 1); }

// Spec 4.6: how the state names an edge's endpoint and its opposite vertex.
enum : uint64_t {
  kNewVertex = 0,   // the next vertex slot, whose fields follow
  kSameVertex = 1,  // org: the previous edge's dst; dst: the loop's first org
  kSlotBase = 2,    // 2 + slot: a vertex named before
};
enum : uint64_t {
  kOppBefore = 0,  // the position of the org of the edge before it in its loop
  kOppAfter = 1,   // the position of the dst of the edge after it
  kOppMidpoint = 2,  // forgotten: the midpoint of the edge, which makes the
                     // parallelogram across it predict that midpoint (7.3)
};

void midpoint(const int64_t a[3], const int64_t b[3], int64_t out[3]) {
  for (int i = 0; i < 3; ++i) out[i] = codec::midpoint(a[i], b[i]);
}

bool same_position(const int64_t a[3], const int64_t b[3]) { return a[0] == b[0] && a[1] == b[1] && a[2] == b[2]; }

// The edge before edge `e` and after it in its loop (kNone at a chain's
// ends), for edges in canonical order with the loops' first edges.
struct LoopLinks {
  std::vector<uint32_t> before, after;
  explicit LoopLinks(const SegmentState& s) : before(s.edge.size(), kNone), after(s.edge.size(), kNone) {
    uint32_t first = 0;
    for (const auto& l : s.loop) {
      for (uint32_t i = 0; i < l.first; ++i) {
        const uint32_t e = first + i;
        if (i > 0) before[e] = e - 1;
        if (i + 1 < l.first) after[e] = e + 1;
      }
      if (l.second && l.first > 0) {
        before[first] = first + l.first - 1;
        after[first + l.first - 1] = first;
      }
      first += l.first;
    }
  }
  // How the state names edge k's opposite vertex `opp` (spec 4.6).
  uint64_t opp_code(const SegmentState& s, uint32_t k, const int64_t opp[3]) const {
    if (before[k] != kNone && same_position(opp, s.vertex[s.edge[before[k]].org].pos)) return kOppBefore;
    if (after[k] != kNone && same_position(opp, s.vertex[s.edge[after[k]].dst].pos)) return kOppAfter;
    return kOppMidpoint;
  }
};

}  // namespace

template <bool L>
void capture_boundary(const BasicBoundary<L>& b, SegmentState* s) {
  s->entered = b.entered();
  s->vertex.clear();
  s->edge.clear();
  s->loop.clear();
  // Spec 4.6: the loops in order: first the chains (an edge that no edge
  // links to begins one), then the closed loops, each begun at its oldest
  // edge not yet taken; chains likewise by the age of their first edge.
  std::vector<std::pair<uint64_t, uint32_t>> by_age;
  by_age.reserve(b.open_edges());
  for (uint32_t e = 0; e < b.edge_capacity(); ++e)
    if (b.edge_live(e)) by_age.emplace_back(b.edge(e).age, e);
  std::sort(by_age.begin(), by_age.end());
  std::vector<uint32_t> edge_at(b.edge_capacity(), kNone), vertex_at(b.vertex_capacity(), kNone);
  std::vector<uint32_t> edges, vertices;  // slots in canonical order
  auto walk = [&](uint32_t e0, bool closed) {
    uint32_t n = 0;
    for (uint32_t e = e0; e != kNone && edge_at[e] == kNone; e = b.edge(e).next) {
      edge_at[e] = static_cast<uint32_t>(edges.size());
      edges.push_back(e);
      ++n;
    }
    s->loop.emplace_back(n, closed);
  };
  for (const auto& a : by_age)
    if (edge_at[a.second] == kNone && b.edge(a.second).prev == kNone) walk(a.second, false);
  for (const auto& a : by_age)
    if (edge_at[a.second] == kNone) walk(a.second, true);
  auto number = [&](uint32_t v) {
    if (vertex_at[v] == kNone) {
      vertex_at[v] = static_cast<uint32_t>(vertices.size());
      vertices.push_back(v);
    }
  };
  for (uint32_t e : edges) {
    number(b.edge(e).org);
    number(b.edge(e).dst);
  }
  for (uint32_t v = 0; v < b.vertex_capacity(); ++v)
    if (b.vertex_live(v)) number(v);
  s->vertex.reserve(vertices.size());
  s->edge.reserve(edges.size());
  for (uint32_t v : vertices) {
    const BVertex& x = b.vertex(v);
    SegmentState::Vertex y;
    y.slot = v;
    y.index = x.index;
    y.degree = x.degree;
    y.key = x.key;
    std::copy(x.pos, x.pos + 3, y.pos);
    s->vertex.push_back(y);
  }
  for (uint32_t e : edges) {
    const BEdge& x = b.edge(e);
    SegmentState::Edge y;
    y.slot = e;
    y.org = vertex_at[x.org];
    y.dst = vertex_at[x.dst];
    y.next = x.next == kNone ? kNone : edge_at[x.next];
    const uint64_t back = s->entered - x.age;
    y.recency = back <= kStateRecency ? static_cast<uint32_t>(back) : 0;
    std::copy(x.opp, x.opp + 3, y.opp);
    s->edge.push_back(y);
  }
  s->reference = b.reference() == kNone ? kNone : edge_at[b.reference()];
  // Spec 4.6: the state keeps an edge's opposite vertex only where the
  // loop names it; it forgets the others (their midpoints).
  const LoopLinks links(*s);
  for (uint32_t k = 0; k < s->edge.size(); ++k) {
    SegmentState::Edge& x = s->edge[k];
    if (links.opp_code(*s, k, x.opp) == kOppMidpoint) midpoint(s->vertex[x.org].pos, s->vertex[x.dst].pos, x.opp);
  }
}
template void capture_boundary(const BasicBoundary<true>&, SegmentState*);
template void capture_boundary(const BasicBoundary<false>&, SegmentState*);

namespace {
// Sorts the dead pairs (by slot) into positions, without open edges.
void finish_dead(SegmentState* s, std::vector<std::pair<uint32_t, uint32_t>>* by_slot) {
  std::vector<uint32_t> at;
  for (uint32_t i = 0; i < s->vertex.size(); ++i) {
    if (s->vertex[i].slot >= at.size()) at.resize(s->vertex[i].slot + 1, kNone);
    at[s->vertex[i].slot] = i;
  }
  std::vector<std::pair<uint32_t, uint32_t>> open;
  for (const SegmentState::Edge& e : s->edge) open.emplace_back(std::min(e.org, e.dst), std::max(e.org, e.dst));
  std::sort(open.begin(), open.end());
  s->dead.clear();
  for (const auto& d : *by_slot) {
    const uint32_t a = at[d.first], c = at[d.second];
    const std::pair<uint32_t, uint32_t> p(std::min(a, c), std::max(a, c));
    if (!std::binary_search(open.begin(), open.end(), p)) s->dead.push_back(p);
  }
  std::sort(s->dead.begin(), s->dead.end());
  s->dead.erase(std::unique(s->dead.begin(), s->dead.end()), s->dead.end());
}
}  // namespace

template <bool L>
void capture_dead(const BasicBoundary<L>& b, const Neighbors& n, SegmentState* s) {
  std::vector<std::pair<uint32_t, uint32_t>> old;
  for (const SegmentState::Vertex& x : s->vertex)
    n.for_each_current(x.slot, [&](uint32_t w) {
      if (w > x.slot && b.vertex_live(w)) old.emplace_back(x.slot, w);
    });
  finish_dead(s, &old);
}
template void capture_dead(const BasicBoundary<true>&, const Neighbors&, SegmentState*);
template void capture_dead(const BasicBoundary<false>&, const Neighbors&, SegmentState*);

void capture_attributes(AttributeCoder& a, SegmentState* s) {
  const int d = a.dims();
  s->attr_last.assign(a.last(), a.last() + d);
  s->attr_vertex.clear();
  s->attr_edge.clear();
  for (const SegmentState::Vertex& v : s->vertex) {
    const int32_t* x = a.vertex_state(v.slot);
    s->attr_vertex.insert(s->attr_vertex.end(), x, x + d);
  }
  for (const SegmentState::Edge& e : s->edge) {
    const int32_t* x = a.edge_state(e.slot);
    s->attr_edge.insert(s->attr_edge.end(), x, x + d);
  }
}

void serialize_state(const SegmentState& s, int dims, std::vector<uint8_t>* out) {
  out->clear();
  Put put(out);
  const uint64_t head[] = {s.records, s.vertices, s.triangles, s.entered,
                           s.reference == kNone ? 0 : uint64_t{s.reference} + 1, s.context, s.choice};
  for (uint64_t v : head) put.varint(v);
  for (int i = 0; i < 3; ++i) put.varint(zigzag(s.last[i]));
  // A new vertex's fields: its index and position from the previous new
  // vertex's, its degree.
  uint32_t numbered = 0;
  int64_t prev_index = static_cast<int64_t>(s.vertices), prev_pos[3] = {0, 0, 0};
  auto vertex = [&](uint32_t v) {
    const SegmentState::Vertex& x = s.vertex[v];
    put.varint(zigzag(static_cast<int64_t>(x.index) - prev_index));
    put.varint(x.degree);
    for (int i = 0; i < 3; ++i) put.varint(zigzag(wrap_sub(x.pos[i], prev_pos[i])));
    prev_index = x.index;
    std::copy(x.pos, x.pos + 3, prev_pos);
    ++numbered;
  };
  put.varint(s.loop.size());
  uint32_t e = 0;
  for (const auto& l : s.loop) {
    put.varint(uint64_t{l.first} << 1 | (l.second ? 1 : 0));
    const uint32_t first = e;
    for (uint32_t i = 0; i < l.first; ++i, ++e) {
      const SegmentState::Edge& x = s.edge[e];
      if (x.org == numbered) {
        put.varint(kNewVertex);
        vertex(x.org);
      } else {
        put.varint(i > 0 && x.org == s.edge[e - 1].dst ? kSameVertex : kSlotBase + x.org);
      }
      if (x.dst == numbered) {
        put.varint(kNewVertex);
        vertex(x.dst);
      } else {
        put.varint(x.dst == s.edge[first].org ? kSameVertex : kSlotBase + x.dst);
      }
      put.varint(x.recency);
    }
  }
  put.varint(s.vertex.size() - numbered);
  while (numbered < s.vertex.size()) vertex(numbered);
  const LoopLinks links(s);
  for (uint32_t k = 0; k < s.edge.size(); ++k) put.varint(links.opp_code(s, k, s.edge[k].opp));
  put.varint(s.dead.size());
  uint32_t prev_a = 0;
  for (const auto& d : s.dead) {
    put.varint(d.first - prev_a);
    put.varint(d.second - d.first - 1);
    prev_a = d.first;
  }
  if (dims > 0) {
    for (int32_t v : s.attr_last) put.varint(zigzag(v));
    for (int32_t v : s.attr_vertex) put.varint(zigzag(v));
    for (int32_t v : s.attr_edge) put.varint(zigzag(v));
  }
}

const char* parse_state(const uint8_t* p, size_t n, uint32_t limit, int dims, int64_t lo, int64_t hi,
                        const AttributeCoder* attrs, SegmentState* s) {
  static const char* const kShort = "state block ends early or holds a malformed varint";
  Get get(p, n);
  *s = SegmentState();
  auto ok = [&] { return !get.malformed() && !get.short_read(); };
  uint64_t ref, ctx, choice;
  for (uint64_t* v : {&s->records, &s->vertices, &s->triangles, &s->entered, &ref, &ctx, &choice}) *v = get.varint();
  for (int i = 0; i < 3; ++i) s->last[i] = unzigzag(get.varint());
  if (!ok()) return kShort;
  if (s->vertices > 0xffffffffu) return "vertex count beyond 2^32 - 1";
  if (ctx >= kFastAContexts || choice >= kChoices) return "context or prediction choice out of range";
  s->context = static_cast<uint32_t>(ctx);
  s->choice = static_cast<uint32_t>(choice);
  auto coordinate_ok = [&](const int64_t* v) { return v[0] >= lo && v[0] <= hi && v[1] >= lo && v[1] <= hi && v[2] >= lo && v[2] <= hi; };
  if (!coordinate_ok(s->last)) return "prediction state outside the coordinates";
  int64_t prev_index = static_cast<int64_t>(s->vertices), prev_pos[3] = {0, 0, 0};
  // Every element takes at least one byte, so no count below allocates
  // beyond the bytes of the block.
  auto vertex = [&]() -> const char* {
    if (s->vertex.size() >= limit) return "more active vertices than the boundary limit";
    SegmentState::Vertex v;
    const int64_t index = wrap_add(prev_index, unzigzag(get.varint()));
    const uint64_t degree = get.varint();
    for (int i = 0; i < 3; ++i) v.pos[i] = wrap_add(prev_pos[i], unzigzag(get.varint()));
    if (!ok()) return kShort;
    if (index < 0 || static_cast<uint64_t>(index) >= s->vertices) return "active vertex index beyond the vertices so far";
    if (degree > 0xffffffffu) return "vertex degree out of range";
    if (!coordinate_ok(v.pos)) return "active vertex position outside the coordinates";
    v.slot = static_cast<uint32_t>(s->vertex.size());
    v.index = v.key = static_cast<uint32_t>(index);
    v.degree = static_cast<uint32_t>(degree);
    prev_index = index;
    std::copy(v.pos, v.pos + 3, prev_pos);
    s->vertex.push_back(v);
    return nullptr;
  };
  const uint64_t loops = get.varint();
  if (!ok() || loops > get.left()) return "bad loop count";
  for (uint64_t l = 0; l < loops; ++l) {
    const uint64_t head = get.varint();
    if (!ok()) return kShort;
    const uint64_t len = head >> 1;
    if (len == 0 || len > limit || s->edge.size() + len > limit) return "bad loop length";
    if (len > get.left()) return kShort;
    const uint32_t first = static_cast<uint32_t>(s->edge.size());
    for (uint64_t i = 0; i < len; ++i) {
      SegmentState::Edge x;
      for (int end = 0; end < 2; ++end) {
        const uint64_t code = get.varint();
        if (!ok()) return kShort;
        uint32_t v;
        if (code == kNewVertex) {
          if (const char* why = vertex()) return why;
          v = static_cast<uint32_t>(s->vertex.size() - 1);
        } else if (code == kSameVertex) {
          if (end == 0 && i == 0) return "the first edge of a loop names the edge before it";
          v = end == 0 ? s->edge.back().dst : (i == 0 ? x.org : s->edge[first].org);
        } else {
          if (code - kSlotBase >= s->vertex.size()) return "edge endpoint names no vertex";
          v = static_cast<uint32_t>(code - kSlotBase);
        }
        (end == 0 ? x.org : x.dst) = v;
      }
      if (x.org == x.dst) return "open edge from a vertex to itself";
      const uint64_t r = get.varint();
      if (!ok()) return kShort;
      x.slot = static_cast<uint32_t>(s->edge.size());
      if (r > kStateRecency || r > s->entered) return "edge recency out of range";
      x.recency = static_cast<uint32_t>(r);
      x.next = i + 1 < len ? static_cast<uint32_t>(s->edge.size() + 1) : (head & 1) ? first : kNone;
      s->edge.push_back(x);
    }
    s->loop.emplace_back(static_cast<uint32_t>(len), (head & 1) != 0);
  }
  const uint64_t extra = get.varint();
  if (!ok() || extra > get.left()) return "bad count of vertices off the loops";
  for (uint64_t i = 0; i < extra; ++i)
    if (const char* why = vertex()) return why;
  const LoopLinks links(*s);
  for (uint32_t k = 0; k < s->edge.size(); ++k) {
    SegmentState::Edge& x = s->edge[k];
    const uint64_t code = get.varint();
    if (!ok()) return kShort;
    if (code == kOppBefore && links.before[k] != kNone) {
      std::copy_n(s->vertex[s->edge[links.before[k]].org].pos, 3, x.opp);
    } else if (code == kOppAfter && links.after[k] != kNone) {
      std::copy_n(s->vertex[s->edge[links.after[k]].dst].pos, 3, x.opp);
    } else if (code == kOppMidpoint) {
      midpoint(s->vertex[x.org].pos, s->vertex[x.dst].pos, x.opp);
    } else {
      return "bad opposite vertex code";
    }
  }
  if (ref != 0 && ref - 1 >= s->edge.size()) return "reference edge is not open";
  s->reference = ref == 0 ? kNone : static_cast<uint32_t>(ref - 1);
  const uint64_t nd = get.varint();
  if (!ok() || nd > get.left()) return "bad dead pair count";
  uint64_t prev_a = 0;
  for (uint64_t i = 0; i < nd; ++i) {
    const uint64_t a = prev_a + get.varint();
    const uint64_t b = a + 1 + get.varint();
    if (!ok()) return kShort;
    if (b >= s->vertex.size()) return "dead pair of vertices that are not active";
    if (i > 0 && a == s->dead.back().first && b <= s->dead.back().second) return "dead pairs out of order";
    s->dead.emplace_back(static_cast<uint32_t>(a), static_cast<uint32_t>(b));
    prev_a = a;
  }
  if (dims > 0) {
    auto values = [&](std::vector<int32_t>* out, size_t count) -> const char* {
      if (count > get.left()) return kShort;
      out->resize(count);
      for (size_t i = 0; i < count; ++i) {
        const int64_t v = unzigzag(get.varint());
        if (!ok()) return kShort;
        if (!attrs->in_range(static_cast<int>(i % static_cast<size_t>(dims)), v)) return "attribute value out of range";
        (*out)[i] = static_cast<int32_t>(v);
      }
      return nullptr;
    };
    const size_t d = static_cast<size_t>(dims);
    if (const char* why = values(&s->attr_last, d)) return why;
    if (const char* why = values(&s->attr_vertex, d * s->vertex.size())) return why;
    if (const char* why = values(&s->attr_edge, d * s->edge.size())) return why;
  }
  if (get.left() != 0) return "unused bytes at the end of the state block";
  return nullptr;
}

template <bool L>
void load_state(const SegmentState& s, BasicBoundary<L>* b, Neighbors* n, FastRing* ring, AttributeCoder* a) {
  // Spec 4.6: vertex i of the state takes slot i, edge j slot j.
  b->reserve(static_cast<uint32_t>(std::max(s.vertex.size(), s.edge.size())));
  for (uint32_t i = 0; i < s.vertex.size(); ++i) {
    const SegmentState::Vertex& v = s.vertex[i];
    b->load_vertex(i, v.index, v.key, v.degree, v.pos);
  }
  std::vector<uint32_t> next;
  next.reserve(s.edge.size());
  for (uint32_t j = 0; j < s.edge.size(); ++j) {
    const SegmentState::Edge& e = s.edge[j];
    // An edge beyond the recency window gets age 0, which no rank reaches.
    b->load_edge(j, e.org, e.dst, e.recency ? s.entered - e.recency : 0, e.opp);
    next.push_back(e.next);
  }
  b->load_end(next.data(), s.entered, s.reference);
  for (uint32_t i = 0; i < s.vertex.size(); ++i) n->vertex_begins(i);
  for (const SegmentState::Edge& e : s.edge) n->insert(e.org, e.dst);
  for (const auto& d : s.dead) n->insert(d.first, d.second);
  ring->rebuild(*b);
  const size_t d = a ? static_cast<size_t>(a->dims()) : 0;
  if (d > 0) {
    a->set_last(s.attr_last.data());
    for (size_t i = 0; i < s.vertex.size(); ++i)
      std::copy_n(s.attr_vertex.data() + i * d, d, a->vertex_state(static_cast<uint32_t>(i)));
    for (size_t i = 0; i < s.edge.size(); ++i)
      std::copy_n(s.attr_edge.data() + i * d, d, a->edge_state(static_cast<uint32_t>(i)));
  }
}
template void load_state(const SegmentState&, BasicBoundary<true>*, Neighbors*, FastRing*, AttributeCoder*);
template void load_state(const SegmentState&, BasicBoundary<false>*, Neighbors*, FastRing*, AttributeCoder*);

}  // namespace codec
}  // namespace psq
