// SequenceChecker (psq/sequence_check.h): recomputes the processing boundary
// of a sequence from its triangles (paper section 3, Figure 2) and checks the
// stream's claims against it, counting Table 1's statistics on the way.
#include "psq/sequence_check.h"

#include <string>
#include <unordered_map>
#include <unordered_map>
#include <unordered_set>
#include <vector>

namespace psq {
namespace {

uint64_t directed(uint32_t a, uint32_t b) { return (uint64_t{a} << 32) | b; }
uint64_t undirected(uint32_t a, uint32_t b) { return a < b ? directed(a, b) : directed(b, a); }

// Union-find over dense indices, grown as vertices arrive.
class UnionFind {
 public:
  uint32_t add() {
    parent_.push_back(static_cast<uint32_t>(parent_.size()));
    return parent_.back();
  }
  uint32_t find(uint32_t x) {
    while (parent_[x] != x) {
      parent_[x] = parent_[parent_[x]];
      x = parent_[x];
    }
    return x;
  }
  // True when x and y were in different sets.
  bool unite(uint32_t x, uint32_t y) {
    x = find(x);
    y = find(y);
    if (x == y) return false;
    if (x < y) std::swap(x, y);
    parent_[x] = y;
    return true;
  }

 private:
  std::vector<uint32_t> parent_;
};

struct Active {
  uint32_t slot = kNoSlot;      // as the producer gave it
  uint32_t uses = 0;            // triangles so far
  uint32_t open_edges = 0;      // boundary edges (entering, not yet completed) at this vertex
  bool fresh = true;            // introduced, not yet used by a triangle
  std::vector<uint64_t> border; // keys of border edges, to forget them at finalization
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
  std::unordered_map<uint32_t, Active> active;
  std::unordered_map<uint64_t, uint32_t> boundary;  // directed edges waiting for their partner -> edge slot
  std::unordered_set<uint32_t> vertex_slots;        // slots of active vertices
  std::unordered_set<uint32_t> edge_slots;          // slots of open boundary edges
  std::unordered_set<uint64_t> borders;   // undirected border edges between active vertices
  UnionFind components;                   // by dense vertex, cut vertices joined to their origin
  UnionFind loops;                        // by dense vertex, over border edges (cut mesh)
  UnionFind holes;                        // by first occurrence, over true border edges
  std::vector<uint32_t> origin;           // dense index -> first occurrence
  std::unordered_set<uint32_t> cut_origins;
  std::unordered_set<uint64_t> cut_edges;  // undirected, by origin
  std::vector<uint8_t> used;               // dense index -> used by a triangle
  std::vector<uint8_t> on_border;          // dense index -> has a border edge
  std::vector<uint8_t> on_hole;            // first occurrence -> has a true border edge

  Status bad(const std::string& m) const {
    return Status(ErrorCode::kBadSequence, "triangle " + std::to_string(stats.triangles) + ": " + m);
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
  if (v.slot != kNoSlot && !m.vertex_slots.insert(v.slot).second) {
    return m.bad("vertex " + std::to_string(v.index) + " takes slot " + std::to_string(v.slot) + ", which an active vertex holds");
  }
  Active fresh;
  fresh.slot = v.slot;
  m.active.emplace(v.index, fresh);
  m.stats.max_boundary_vertices = std::max<uint64_t>(m.stats.max_boundary_vertices, m.active.size());
  return Status();
}

Status SequenceChecker::triangle(const SequenceTriangle& t) {
  Impl& m = *impl_;
  Active* a[3];
  for (int k = 0; k < 3; ++k) {
    auto it = m.active.find(t.v[k]);
    if (it == m.active.end()) {
      return m.bad("vertex " + std::to_string(t.v[k]) + (t.v[k] < m.introduced ? " was finalized" : " was never introduced"));
    }
    a[k] = &it->second;
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
  for (int k = 0; k < 3; ++k) {
    uint32_t x = t.v[k], y = t.v[(k + 1) % 3];
    bool border = ((t.border_mask >> k) & 1) != 0;
    if (m.borders.count(undirected(x, y))) return m.bad("edge " + std::to_string(k) + " reuses an edge flagged border");
    if (m.boundary.count(directed(x, y))) {
      return m.bad("edge " + std::to_string(k) + " has the orientation of an open boundary edge (inconsistent orientation)");
    }
    if (m.boundary.count(directed(y, x))) {
      if (border) return m.bad("edge " + std::to_string(k) + " is flagged border but completes a boundary edge");
      leaving |= static_cast<uint8_t>(1u << k);
      ++e;
    } else if (!border) {
      entering |= static_cast<uint8_t>(1u << k);
    }
  }
  if ((t.leaving_mask | t.entering_mask) != 0 && (t.leaving_mask != leaving || t.entering_mask != entering)) {
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

  // Apply.
  for (int k = 0; k < 3; ++k) {
    uint32_t x = t.v[k], y = t.v[(k + 1) % 3];
    if ((leaving >> k) & 1) {
      auto it = m.boundary.find(directed(y, x));
      if (t.eslot[k] != kNoSlot && t.eslot[k] != it->second) {
        return m.bad("edge " + std::to_string(k) + " completes an edge of slot " + std::to_string(it->second) +
                     " but names slot " + std::to_string(t.eslot[k]));
      }
      m.edge_slots.erase(it->second);
      m.boundary.erase(it);
      --a[k]->open_edges;
      --a[(k + 1) % 3]->open_edges;
    } else if ((entering >> k) & 1) {
      if (t.eslot[k] != kNoSlot && !m.edge_slots.insert(t.eslot[k]).second) {
        return m.bad("edge " + std::to_string(k) + " enters with slot " + std::to_string(t.eslot[k]) + ", which an open edge holds");
      }
      m.boundary.emplace(directed(x, y), t.eslot[k]);
      ++a[k]->open_edges;
      ++a[(k + 1) % 3]->open_edges;
    } else {
      uint64_t key = undirected(x, y);
      m.borders.insert(key);
      a[k]->border.push_back(key);
      a[(k + 1) % 3]->border.push_back(key);
      ++m.stats.border_edges;
      m.loops.unite(x, y);
      m.on_border[x] = m.on_border[y] = 1;
      if ((t.nonmanifold_mask >> k) & 1) {
        m.cut_edges.insert(undirected(m.origin[x], m.origin[y]));
      } else {
        m.holes.unite(m.origin[x], m.origin[y]);
        m.on_hole[m.origin[x]] = m.on_hole[m.origin[y]] = 1;
      }
    }
  }
  for (int k = 0; k < 3; ++k) {
    a[k]->fresh = false;
    ++a[k]->uses;
    m.used[t.v[k]] = 1;
  }
  m.components.unite(t.v[0], t.v[1]);
  m.components.unite(t.v[1], t.v[2]);
  ++m.stats.triangles;
  ++m.stats.ops[static_cast<int>(op)];
  m.stats.max_boundary_edges = std::max<uint64_t>(m.stats.max_boundary_edges, m.boundary.size());
  return Status();
}

Status SequenceChecker::finalize(uint32_t index) {
  Impl& m = *impl_;
  auto it = m.active.find(index);
  if (it == m.active.end()) {
    return m.bad("finalizes vertex " + std::to_string(index) + (index < m.introduced ? " twice" : " before introducing it"));
  }
  Active& a = it->second;
  if (a.open_edges != 0) {
    return m.bad("finalizes vertex " + std::to_string(index) + " with " + std::to_string(a.open_edges) +
                 " boundary edges still open (they should be flagged border)");
  }
  if (a.uses == 0) ++m.stats.isolated_vertices;
  if (a.slot != kNoSlot) m.vertex_slots.erase(a.slot);
  for (uint64_t key : a.border) m.borders.erase(key);
  m.active.erase(it);
  return Status();
}

Status SequenceChecker::finish() {
  Impl& m = *impl_;
  if (!m.active.empty()) {
    return Status(ErrorCode::kBadSequence, std::to_string(m.active.size()) + " vertices never finalized");
  }
  if (!m.boundary.empty()) {
    return Status(ErrorCode::kBadSequence, std::to_string(m.boundary.size()) + " boundary edges left open");
  }
  // Components of the cut mesh (for its Euler characteristic), then of the
  // input mesh: a cut vertex joins the component of its first occurrence.
  uint64_t used = 0, cut_components = 0, components = 0, loops = 0, holes = 0;
  for (uint32_t v = 0; v < m.introduced; ++v) {
    if (!m.used[v]) continue;
    ++used;
    if (m.components.find(v) == v) ++cut_components;
    // Each border vertex of the cut mesh has exactly two border edges, so
    // the border edges form disjoint cycles: count their components.
    if (m.on_border[v] && m.loops.find(v) == v) ++loops;
    if (m.on_hole[v] && m.holes.find(v) == v) ++holes;
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
  return Status();
}

const SequenceStats& SequenceChecker::stats() const { return impl_->stats; }

}  // namespace psq
