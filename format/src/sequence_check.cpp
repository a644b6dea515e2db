// SPDX-License-Identifier: Apache-2.0
// SequenceChecker (psq/sequence_check.h): recomputes the processing boundary
// of a sequence from its triangles (paper section 3, Figure 2) and checks the
// stream's claims against it, counting Table 1's statistics on the way.
#include "psq/sequence_check.h"

#include <cstdlib>
#include <string>
#include <unordered_set>
#include <vector>

#include "flat_map.h"
#include "union_find.h"

namespace psq {
namespace {

using detail::UnionFind;
using detail::FlatMap;

struct Empty {};

struct Active {
  uint32_t slot = kNoSlot;      // as the producer gave it
  uint32_t uses = 0;            // triangles so far
  uint32_t open_edges = 0;      // boundary edges (entering, not yet completed) at this vertex
  bool fresh = true;            // introduced, not yet used by a triangle
  std::vector<uint64_t> edges;  // keys of the edges at it (in Impl::edges), to forget them at finalization
};

// An edge between active vertices: open (on the boundary, in one direction)
// or closed (a border, or completed by its second triangle; rule 3).
struct Edge {
  enum State : uint8_t { kOpenUp, kOpenDown, kClosed };  // up: from the smaller index to the larger
  uint32_t slot = kNoSlot;  // of an open edge, as the producer gave it
  State state = kClosed;
};

}  // namespace

const char* op_name(Op op) {
  switch (op) {
    case Op::kStart: return "start";
    case Op::kAdd: return "add";
    case Op::kJoin: return "join";
    case Op::kFill: return "fill";
    case Op::kEnd: return "end";
  }
  return "?";
}

Status pump_sequence(SequenceSource& source, SequenceSink& sink) {
  PSQ_RETURN_IF_ERROR(sink.begin(source.schema()));
  SequenceEvent e;
  for (;;) {
    PSQ_RETURN_IF_ERROR(source.next(&e));
    switch (e.kind) {
      case SequenceEvent::Kind::kVertex: PSQ_RETURN_IF_ERROR(sink.vertex(e.vertex)); break;
      case SequenceEvent::Kind::kTriangle: PSQ_RETURN_IF_ERROR(sink.triangle(e.triangle)); break;
      case SequenceEvent::Kind::kFinalize: PSQ_RETURN_IF_ERROR(sink.finalize(e.finalized)); break;
      case SequenceEvent::Kind::kEnd: return sink.finish();
    }
  }
}

struct SequenceChecker::Impl {
  SequenceStats stats;
  uint64_t introduced = 0;
  // Active vertices: dense index -> record in `pool` (kNoVertex once
  // finalized); records are recycled, keeping their edge lists' capacity.
  std::vector<uint32_t> active_of;
  std::vector<Active> pool;
  std::vector<uint32_t> free_pool;
  uint64_t active = 0;
  // Undirected edges between active vertices: the boundary (open edges) and
  // the closed edges that no later triangle may use.
  FlatMap<Edge> edges;
  uint64_t open_edges = 0;
  FlatMap<Empty> vertex_slots;  // slots of active vertices
  FlatMap<Empty> edge_slots;    // slots of open boundary edges
  // Rule 1: vertices introduced since the last triangle or finalize event,
  // waiting for the next triangle (at most 3).
  uint32_t fresh[3] = {0, 0, 0};
  int fresh_count = 0;
  // Rule 4: corners of the last triangle that no boundary edge touches any
  // more, to be finalized next, in this order.
  uint32_t pending[3] = {0, 0, 0};
  int pending_count = 0, pending_next = 0;
  // True once a triangle carried leaving, entering or final masks: from then
  // on every triangle must carry them (a producer that computes no masks,
  // such as a parsed dump, leaves all three zero throughout).
  bool masks = false;
  UnionFind components;                   // by dense vertex, cut vertices joined to their origin
  UnionFind loops;                        // by dense vertex, over border edges (cut mesh)
  UnionFind holes;                        // by first occurrence, over true border edges
  std::vector<uint32_t> origin;           // dense index -> first occurrence
  std::unordered_set<uint32_t> cut_origins;
  // Cut edges of non-degenerate triangles, undirected, by origin: their
  // triangles, and +1 / -1 for each that runs up / down (smaller origin to
  // larger / larger to smaller).
  struct Cut {
    uint32_t triangles = 0;
    int32_t direction = 0;
  };
  FlatMap<Cut> cut_edges;
  std::vector<uint8_t> used;               // dense index -> used by a triangle
  std::vector<uint8_t> on_border;          // dense index -> has a border edge
  std::vector<uint8_t> on_hole;            // first occurrence -> has a true border edge

  Active* find_active(uint32_t index) {
    if (index >= active_of.size() || active_of[index] == kNoVertex) return nullptr;
    return &pool[active_of[index]];
  }
  Status bad(const std::string& m) const {
    return Status(ErrorCode::kBadSequence, "triangle " + std::to_string(stats.triangles) + ": " + m);
  }
  // Rule 4: the corners the last triangle left without boundary edges must
  // be finalized before anything else happens.
  Status check_no_pending(const char* what) const {
    if (pending_next == pending_count) return Status();
    return Status(ErrorCode::kBadSequence,
                  "triangle " + std::to_string(stats.triangles - 1) + ": no boundary edge touches vertex " +
                      std::to_string(pending[pending_next]) + " after it, but " + what +
                      " comes before its finalization (finalization must follow the triangle at once, in corner order)");
  }
};

SequenceChecker::SequenceChecker() : impl_(std::make_unique<Impl>()) {}
SequenceChecker::~SequenceChecker() = default;

Status SequenceChecker::begin(const MeshSchema&) {
  impl_ = std::make_unique<Impl>();
  return Status();
}

Status SequenceChecker::vertex(const SequenceVertex& v) {
  Impl& m = *impl_;
  PSQ_RETURN_IF_ERROR(m.check_no_pending("a vertex event"));
  if (m.fresh_count == 3) {
    return m.bad("vertex " + std::to_string(v.index) + " is the fourth vertex introduced before a triangle: vertex " +
                 std::to_string(m.fresh[0]) + " is not used by the next triangle");
  }
  if (v.index != m.introduced) {
    return m.bad("vertex introduced as " + std::to_string(v.index) + ", expected " + std::to_string(m.introduced));
  }
  uint32_t origin = v.index;
  if (v.reappears != kNoVertex) {
    if (v.reappears >= v.index) return m.bad("vertex " + std::to_string(v.index) + " re-appears a later vertex");
    origin = m.origin[v.reappears];
    ++m.stats.reappearances;
    m.cut_origins.insert(origin);
  } else {
    ++m.stats.vertices;
  }
  ++m.introduced;
  m.origin.push_back(origin);
  m.used.push_back(0);
  m.on_border.push_back(0);
  m.on_hole.push_back(0);
  m.holes.add();
  m.components.add();
  m.loops.add();
  if (v.slot != kNoSlot && !m.vertex_slots.insert(v.slot, Empty())) {
    return m.bad("vertex " + std::to_string(v.index) + " takes slot " + std::to_string(v.slot) + ", which an active vertex holds");
  }
  uint32_t record;
  if (!m.free_pool.empty()) {
    record = m.free_pool.back();
    m.free_pool.pop_back();
  } else {
    record = static_cast<uint32_t>(m.pool.size());
    m.pool.emplace_back();
  }
  Active& fresh = m.pool[record];
  fresh.slot = v.slot;
  fresh.uses = fresh.open_edges = 0;
  fresh.fresh = true;
  fresh.edges.clear();
  m.active_of.push_back(record);
  ++m.active;
  m.fresh[m.fresh_count++] = v.index;
  m.stats.max_boundary_vertices = std::max<uint64_t>(m.stats.max_boundary_vertices, m.active);
  return Status();
}

Status SequenceChecker::triangle(const SequenceTriangle& t) {
  Impl& m = *impl_;
  PSQ_RETURN_IF_ERROR(m.check_no_pending("the next triangle"));
  Active* a[3];
  for (int k = 0; k < 3; ++k) {
    a[k] = m.find_active(t.v[k]);
    if (a[k] == nullptr) {
      return m.bad("vertex " + std::to_string(t.v[k]) + (t.v[k] < m.introduced ? " was finalized" : " was never introduced"));
    }
  }
  if (t.v[0] == t.v[1] || t.v[1] == t.v[2] || t.v[2] == t.v[0]) return m.bad("repeats a vertex");

  int n = 0, e = 0;
  uint8_t leaving = 0, entering = 0;
  for (int k = 0; k < 3; ++k) {
    if (t.vslot[k] != kNoSlot && t.vslot[k] != a[k]->slot) {
      return m.bad("corner " + std::to_string(k) + " names slot " + std::to_string(t.vslot[k]) + ", not its vertex's");
    }
  }
  for (int k = 0; k < 3; ++k) {
    bool is_new = a[k]->fresh;
    if (is_new != (((t.new_mask >> k) & 1) != 0)) {
      return m.bad("corner " + std::to_string(k) + (is_new ? " is new but not flagged so" : " is flagged new but was used before"));
    }
    n += is_new;
  }
  // Rule 1: the vertices introduced since the last event are this
  // triangle's new corners, all of them.
  if (n != m.fresh_count) {
    for (int i = 0; i < m.fresh_count; ++i) {
      uint32_t f = m.fresh[i];
      if (f != t.v[0] && f != t.v[1] && f != t.v[2]) {
        return m.bad("vertex " + std::to_string(f) + " was introduced right before this triangle but is not one of its corners");
      }
    }
  }
  Edge* found[3];
  for (int k = 0; k < 3; ++k) {
    uint32_t x = t.v[k], y = t.v[(k + 1) % 3];
    bool border = ((t.border_mask >> k) & 1) != 0;
    found[k] = m.edges.find(detail::undirected_edge(x, y));
    if (found[k] != nullptr) {
      if (found[k]->state == Edge::kClosed) {
        return m.bad("edge " + std::to_string(k) + " reuses a closed edge (flagged border, or completed by two triangles)");
      }
      if (found[k]->state == (x < y ? Edge::kOpenUp : Edge::kOpenDown)) {
        return m.bad("edge " + std::to_string(k) + " has the orientation of an open boundary edge (inconsistent orientation)");
      }
      if (border) return m.bad("edge " + std::to_string(k) + " is flagged border but completes a boundary edge");
      leaving |= static_cast<uint8_t>(1u << k);
      ++e;
    } else if (!border) {
      entering |= static_cast<uint8_t>(1u << k);
    } else if (t.eslot[k] != kNoSlot) {
      return m.bad("edge " + std::to_string(k) + " is a border but names edge slot " + std::to_string(t.eslot[k]));
    }
  }
  if ((t.leaving_mask | t.entering_mask | t.final_mask) != 0) m.masks = true;
  if (m.masks && (t.leaving_mask != leaving || t.entering_mask != entering)) {
    return m.bad("leaving/entering flags disagree with the boundary");
  }
  if ((t.nonmanifold_mask & ~t.border_mask) != 0) return m.bad("a non-manifold edge that is not a border");
  Op op;
  if (n == 3 && e == 0) {
    op = Op::kStart;
  } else if (n == 1 && e == 1) {
    op = Op::kAdd;
  } else if (n == 0 && e == 1) {
    op = Op::kJoin;
  } else if (n == 0 && e == 2) {
    op = Op::kFill;
  } else if (n == 0 && e == 3) {
    op = Op::kEnd;
  } else {
    return m.bad("with " + std::to_string(n) + " new vertices and " + std::to_string(e) +
                 " completed edges it is none of the five ops");
  }
  if (op != t.op) return m.bad(std::string("claims op ") + op_name(t.op) + " but is " + op_name(op));
  if (op == Op::kJoin) {
    // Rule 2: the vertex opposite the completed edge is on the boundary.
    int third = leaving == 1 ? 2 : leaving == 2 ? 0 : 1;
    if (a[third]->open_edges == 0) {
      return m.bad("a join whose third vertex " + std::to_string(t.v[third]) + " is not on the boundary");
    }
  }

  // Apply: completed edges first (inserting others may move the edges
  // found above).
  for (int k = 0; k < 3; ++k) {
    if (!((leaving >> k) & 1)) continue;
    Edge& edge = *found[k];
    if (t.eslot[k] != kNoSlot && t.eslot[k] != edge.slot) {
      return m.bad("edge " + std::to_string(k) + " completes an edge of slot " + std::to_string(edge.slot) +
                   " but names slot " + std::to_string(t.eslot[k]));
    }
    if (edge.slot != kNoSlot) m.edge_slots.erase(edge.slot);
    edge.state = Edge::kClosed;
    --m.open_edges;
    --a[k]->open_edges;
    --a[(k + 1) % 3]->open_edges;
  }
  const uint32_t o[3] = {m.origin[t.v[0]], m.origin[t.v[1]], m.origin[t.v[2]]};
  const bool degenerate = o[0] == o[1] || o[1] == o[2] || o[2] == o[0];
  if (degenerate) ++m.stats.degenerate_triangles;
  for (int k = 0; k < 3; ++k) {
    uint32_t x = t.v[k], y = t.v[(k + 1) % 3];
    Active* ax = a[k];
    Active* ay = a[(k + 1) % 3];
    if ((leaving >> k) & 1) {
      continue;
    } else if ((entering >> k) & 1) {
      if (t.eslot[k] != kNoSlot && !m.edge_slots.insert(t.eslot[k], Empty())) {
        return m.bad("edge " + std::to_string(k) + " enters with slot " + std::to_string(t.eslot[k]) + ", which an open edge holds");
      }
      uint64_t key = detail::undirected_edge(x, y);
      Edge edge;
      edge.slot = t.eslot[k];
      edge.state = x < y ? Edge::kOpenUp : Edge::kOpenDown;
      m.edges.insert(key, edge);
      ax->edges.push_back(key);
      ay->edges.push_back(key);
      ++m.open_edges;
      ++ax->open_edges;
      ++ay->open_edges;
    } else {
      uint64_t key = detail::undirected_edge(x, y);
      m.edges.insert(key, Edge());
      ax->edges.push_back(key);
      ay->edges.push_back(key);
      ++m.stats.border_edges;
      m.loops.unite(x, y);
      m.on_border[x] = m.on_border[y] = 1;
      const uint32_t ox = o[k], oy = o[(k + 1) % 3];
      if ((t.nonmanifold_mask >> k) & 1) {
        if (!degenerate) {
          Impl::Cut& c = m.cut_edges[detail::undirected_edge(ox, oy)];
          ++c.triangles;
          c.direction += ox < oy ? 1 : -1;
        }
      } else {
        if (!degenerate) ++m.stats.mesh_border_edges;
        m.holes.unite(ox, oy);
        m.on_hole[ox] = m.on_hole[oy] = 1;
      }
    }
  }
  // Rule 4: the corners no boundary edge touches any more are finalized
  // next, in corner order; final_mask must say so.
  uint8_t finals = 0;
  m.pending_count = m.pending_next = 0;
  for (int k = 0; k < 3; ++k) {
    if (a[k]->open_edges == 0) {
      finals |= static_cast<uint8_t>(1u << k);
      m.pending[m.pending_count++] = t.v[k];
    }
  }
  if (m.masks && t.final_mask != finals) {
    return m.bad("final_mask " + std::to_string(t.final_mask) + " disagrees with the corners left without boundary edges (" +
                 std::to_string(finals) + ")");
  }
  for (int k = 0; k < 3; ++k) {
    a[k]->fresh = false;
    ++a[k]->uses;
    m.used[t.v[k]] = 1;
  }
  m.fresh_count = 0;
  m.components.unite(t.v[0], t.v[1]);
  m.components.unite(t.v[1], t.v[2]);
  ++m.stats.triangles;
  ++m.stats.ops[static_cast<int>(op)];
  m.stats.max_boundary_edges = std::max<uint64_t>(m.stats.max_boundary_edges, m.open_edges);
  return Status();
}

Status SequenceChecker::finalize(uint32_t index) {
  Impl& m = *impl_;
  bool expected = m.pending_next < m.pending_count;
  if (expected && index != m.pending[m.pending_next]) {
    return m.check_no_pending(("the finalization of vertex " + std::to_string(index)).c_str());
  }
  Active* found = m.find_active(index);
  if (found == nullptr) {
    return m.bad("finalizes vertex " + std::to_string(index) + (index < m.introduced ? " twice" : " before introducing it"));
  }
  Active& a = *found;
  if (a.open_edges != 0) {
    return m.bad("finalizes vertex " + std::to_string(index) + " with " + std::to_string(a.open_edges) +
                 " boundary edges still open (they should be flagged border)");
  }
  if (expected) {
    ++m.pending_next;
  } else if (a.fresh) {
    // Rule 1: an isolated vertex is finalized right after its vertex event.
    if (m.fresh_count != 1) {
      return m.bad("finalizes isolated vertex " + std::to_string(index) + " while vertex " +
                   std::to_string(m.fresh[0] == index ? m.fresh[1] : m.fresh[0]) + " waits for its triangle");
    }
    m.fresh_count = 0;
  } else if (m.fresh_count != 0) {
    return m.bad("finalizes vertex " + std::to_string(index) + " while vertex " + std::to_string(m.fresh[0]) +
                 " waits for its triangle");
  } else {
    // A used vertex without boundary edges was due right after the triangle
    // that closed its last one (rule 4).
    return m.bad("finalizes vertex " + std::to_string(index) + " later than right after the triangle that closed its last boundary edge");
  }
  if (a.uses == 0) ++m.stats.isolated_vertices;
  if (a.slot != kNoSlot) m.vertex_slots.erase(a.slot);
  for (uint64_t key : a.edges) m.edges.erase(key);  // the other end may have done so already
  m.free_pool.push_back(m.active_of[index]);
  m.active_of[index] = kNoVertex;
  --m.active;
  return Status();
}

Status SequenceChecker::finish() {
  Impl& m = *impl_;
  PSQ_RETURN_IF_ERROR(m.check_no_pending("the end of the stream"));
  if (m.active != 0) {
    return Status(ErrorCode::kBadSequence, std::to_string(m.active) + " vertices never finalized");
  }
  if (m.open_edges != 0) {
    return Status(ErrorCode::kBadSequence, std::to_string(m.open_edges) + " boundary edges left open");
  }
  // Components of the cut mesh (for its Euler characteristic), then of the
  // input mesh: a cut vertex joins the component of its first occurrence.
  uint64_t used = 0, cut_components = 0, components = 0, loops = 0, holes = 0;
  std::vector<uint8_t> referenced(m.introduced, 0);  // first occurrence -> some occurrence is used
  for (uint32_t v = 0; v < m.introduced; ++v) {
    if (m.on_hole[v] && m.holes.find(v) == v) ++holes;
    if (!m.used[v]) continue;
    ++used;
    referenced[m.origin[v]] = 1;
    if (m.components.find(v) == v) ++cut_components;
    // Each border vertex of the cut mesh has exactly two border edges, so
    // the border edges form disjoint cycles: count their components.
    if (m.on_border[v] && m.loops.find(v) == v) ++loops;
  }
  for (uint32_t v = 0; v < m.introduced; ++v) {
    if (m.origin[v] == v && !referenced[v]) ++m.stats.unreferenced_vertices;
  }
  for (uint32_t v = 0; v < m.introduced; ++v) {
    if (m.used[v] && m.used[m.origin[v]]) m.components.unite(v, m.origin[v]);
  }
  for (uint32_t v = 0; v < m.introduced; ++v) {
    if (m.used[v] && m.components.find(v) == v) ++components;
  }
  m.stats.components = components;
  m.stats.border_loops = holes;
  // V - E + F = 2C - 2G - B summed over the components of the cut mesh.
  int64_t faces = static_cast<int64_t>(m.stats.triangles);
  int64_t edges = (3 * faces + static_cast<int64_t>(m.stats.border_edges)) / 2;
  int64_t chi = static_cast<int64_t>(used) - edges + faces;
  m.stats.handles = (2 * static_cast<int64_t>(cut_components) - static_cast<int64_t>(loops) - chi) / 2;
  m.stats.nonmanifold_vertices = m.cut_origins.size();
  m.stats.nonmanifold_edges = m.cut_edges.size();
  // An edge with two triangles of opposite orientation is manifold: it was
  // cut only where a fan was split (it counts as neither).
  m.cut_edges.for_each([&](uint64_t, const Impl::Cut& c) {
    if (c.triangles > 2) ++m.stats.mesh_nonmanifold_edges;
    else if (c.triangles == 2 && std::abs(c.direction) == 2) ++m.stats.mesh_misoriented_edges;
  });
  return Status();
}

const SequenceStats& SequenceChecker::stats() const { return impl_->stats; }

}  // namespace psq
