// SPDX-License-Identifier: Apache-2.0
// SequenceCounter (psq/sequence_count.h): Table 1's statistics of a
// processing sequence (Isenburg, Lindstrom, Gumhold, Snoeyink 2003, "Large
// Mesh Simplification using Processing Sequences", section 3) in the
// sequence's own order, with per-vertex data on boundary slots.
//
// Components, border loops and holes are union-finds whose elements are
// not vertices but what outlives them: a component of the sequence grows
// from one start op (every other op completes an edge of an existing
// region, and only a join can touch a second region), so the union-find of
// components has one node per start; a border loop or a hole has one node
// per vertex that carries a border edge. Euler's formula over the cut mesh
// gives the handles, as in SequenceChecker.
#include "psq/sequence_count.h"

#include <algorithm>
#include <cstdlib>
#include <string>
#include <utility>
#include <vector>

#include "flat_map.h"
#include "union_find.h"

namespace psq {
namespace {

using detail::FlatMap;

constexpr uint32_t kNone = 0xffffffffu;

using detail::UnionFind;

// What a vertex slot holds while its vertex is active.
struct Slot {
  uint32_t dense = kNone;   // the vertex
  uint32_t origin = kNone;  // its first occurrence (itself unless it re-appears)
  uint32_t region = kNone;  // node of `cut_regions` once a triangle used it
  uint32_t loop = kNone;    // node of `loops` once it has a border edge
  uint32_t hole = kNone;    // node of `holes` (its origin's) once it has an uncut border edge
};

struct Cut {
  uint32_t triangles = 0;
  int32_t direction = 0;  // +1 per triangle running from the smaller origin to the larger, -1 otherwise
};

}  // namespace

struct SequenceCounter::Impl {
  SequenceStats stats;
  BoundaryData<Slot> slots;
  uint64_t introduced = 0;
  uint64_t active = 0;
  int64_t open_edges = 0;
  // Vertices introduced since the last triangle or finalize event: a
  // finalization right after one is that of an isolated vertex (A.2 rule 4).
  int fresh = 0;
  // The last vertex introduced, when it came without a slot: it must be
  // isolated (the decoder gives an isolated vertex no slot).
  bool last_unslotted = false;
  Slot unslotted;
  uint32_t last_slot = 0;
  // Regions (start ops) joined by joins (cut_regions, the cut mesh) and
  // also by re-appearances (mesh_regions, the input mesh): the same nodes.
  UnionFind cut_regions, mesh_regions;
  // (first dense index, region) of runs of consecutive vertices that
  // entered one region, kNone for isolated vertices: the region of any
  // vertex, long after its finalization.
  std::vector<std::pair<uint32_t, uint32_t>> runs;
  UnionFind loops;  // border edges of the cut mesh, by dense vertex
  UnionFind holes;  // uncut border edges, by first occurrence
  FlatMap<uint32_t> hole_of;      // first occurrence -> its node of `holes`
  FlatMap<uint32_t> origin_of;    // re-appearing vertex -> first occurrence
  FlatMap<uint8_t> cut_origins;   // first occurrences that re-appear
  FlatMap<Cut> cut_edges;         // undirected, by origin
  FlatMap<uint8_t> revived;       // isolated first occurrences that a used re-appearance references
  uint64_t isolated_origins = 0;  // isolated vertices that re-appear nothing

  Status bad(const std::string& m) const {
    return Status(ErrorCode::kBadSequence, "triangle " + std::to_string(stats.triangles) + ": " + m);
  }
  void add_run(uint32_t dense, uint32_t region) {
    if (!runs.empty()) {
      const uint32_t last = runs.back().second;
      if (dense <= runs.back().first) return;  // out of order: not a valid sequence
      if (last == region || (last != kNone && region != kNone && cut_regions.find(last) == region)) return;
    }
    runs.emplace_back(dense, region);
  }
  // The region of vertex `dense` (introduced and used or finalized), kNone
  // for an isolated one.
  uint32_t region_of(uint32_t dense) const {
    auto it = std::upper_bound(runs.begin(), runs.end(), std::make_pair(dense, kNone));
    return it == runs.begin() ? kNone : std::prev(it)->second;
  }
  uint32_t loop_node(Slot& s) {
    if (s.loop == kNone) s.loop = loops.add();
    return s.loop;
  }
  uint32_t hole_node(Slot& s) {
    if (s.hole == kNone) {
      if (const uint32_t* h = hole_of.find(s.origin)) {
        s.hole = *h;
      } else {
        s.hole = holes.add();
        hole_of.insert(s.origin, s.hole);
      }
    }
    return s.hole;
  }
};

SequenceCounter::SequenceCounter() : impl_(std::make_unique<Impl>()) {}
SequenceCounter::~SequenceCounter() = default;

Status SequenceCounter::begin(const MeshSchema&) {
  impl_ = std::make_unique<Impl>();
  return Status();
}

Status SequenceCounter::vertex(const SequenceVertex& v) {
  Impl& m = *impl_;
  if (v.slot != kNoSlot && v.slot >= kMaxSlot) return m.bad("vertex " + std::to_string(v.index) + " has slot " + std::to_string(v.slot) + ", too large");
  if (v.index != m.introduced) {
    return m.bad("vertex introduced as " + std::to_string(v.index) + ", expected " + std::to_string(m.introduced));
  }
  uint32_t origin = v.index;
  if (v.reappears != kNoVertex) {
    if (v.reappears >= v.index) return m.bad("vertex " + std::to_string(v.index) + " re-appears a later vertex");
    const uint32_t* o = m.origin_of.find(v.reappears);
    origin = o != nullptr ? *o : v.reappears;
    m.origin_of.insert(v.index, origin);
    m.cut_origins.insert(origin, 1);
    ++m.stats.reappearances;
  } else {
    ++m.stats.vertices;
  }
  m.last_unslotted = v.slot == kNoSlot;
  Slot& s = m.last_unslotted ? m.unslotted : m.slots[v.slot];
  s = Slot();
  s.dense = v.index;
  s.origin = origin;
  ++m.introduced;
  ++m.active;
  ++m.fresh;
  m.last_slot = v.slot;
  m.stats.max_boundary_vertices = std::max(m.stats.max_boundary_vertices, m.active);
  return Status();
}

Status SequenceCounter::triangle(const SequenceTriangle& t) {
  Impl& m = *impl_;
  if (m.fresh > 0 && m.last_unslotted) {
    return m.bad("vertex " + std::to_string(m.unslotted.dense) + " has no slot but is not isolated (SequenceCounter needs slots)");
  }
  const int op = static_cast<int>(t.op);
  if (op < 0 || op > 4) return m.bad("op " + std::to_string(op));
  // A slot past the largest one given holds no vertex. The pointers stay
  // valid since no slot is added below; a slot is read only where the
  // triangle needs it (a fill or end without borders needs none), and
  // checked where it is read.
  Slot* c[3];
  for (int k = 0; k < 3; ++k) {
    if (t.vslot[k] >= m.slots.capacity()) {
      return m.bad("corner " + std::to_string(k) + " names slot " + std::to_string(t.vslot[k]) + ", which no vertex took");
    }
    c[k] = &m.slots[t.vslot[k]];
  }
  auto read = [&](int k) -> Slot* {
    return c[k]->dense == t.v[k] ? c[k] : nullptr;
  };
  auto misnamed = [&](int k) {
    return m.bad("corner " + std::to_string(k) + " names slot " + std::to_string(t.vslot[k]) + ", which holds vertex " +
                 std::to_string(c[k]->dense) + ", not " + std::to_string(t.v[k]));
  };
  // Origins matter (degenerate triangles) only once a vertex re-appeared.
  uint32_t o[3] = {t.v[0], t.v[1], t.v[2]};
  if (m.origin_of.size() != 0) {
    for (int k = 0; k < 3; ++k) {
      if (read(k) == nullptr) return misnamed(k);
      o[k] = c[k]->origin;
    }
  }
  const bool degenerate = o[0] == o[1] || o[1] == o[2] || o[2] == o[0];
  if (degenerate) ++m.stats.degenerate_triangles;

  // The triangle's region (paper Figure 2): an add's is its gate's, a join
  // may reach a second region, a fill or an end completes edges of one
  // region; a start begins a region.
  const int fresh_corners = (t.new_mask & 1) + (t.new_mask >> 1 & 1) + (t.new_mask >> 2 & 1);
  uint32_t region = kNone;
  if (fresh_corners < 3 && (op == static_cast<int>(Op::kJoin) || fresh_corners > 0)) {
    for (int k = 0; k < 3; ++k) {
      if ((t.new_mask >> k) & 1) continue;
      if (read(k) == nullptr) return misnamed(k);
      if (c[k]->region == kNone) continue;  // not a valid sequence
      const uint32_t r = m.cut_regions.find(c[k]->region);
      if (region == kNone) {
        region = r;
        if (op != static_cast<int>(Op::kJoin)) break;
      } else if (r != region) {
        m.cut_regions.unite(region, r);
        m.mesh_regions.unite(region, r);
        region = m.cut_regions.find(region);
      }
    }
  }
  if (fresh_corners > 0) {
    if (region == kNone) {
      region = m.cut_regions.add();
      m.mesh_regions.add();
    }
    // New corners, in the order they were introduced (consecutive dense
    // indices): their run, then their re-appearances joined to the region
    // of their first occurrence (once both are used, as SequenceChecker
    // does).
    int order[3], n = 0;
    for (int k = 0; k < 3; ++k) {
      if (!((t.new_mask >> k) & 1)) continue;
      if (read(k) == nullptr) return misnamed(k);
      int at = n++;
      for (; at > 0 && t.v[order[at - 1]] > t.v[k]; --at) order[at] = order[at - 1];
      order[at] = k;
    }
    for (int i = 0; i < n; ++i) {
      const int k = order[i];
      c[k]->region = region;
      m.add_run(t.v[k], region);
    }
    for (int i = 0; i < n; ++i) {
      const uint32_t origin = c[order[i]]->origin;
      if (origin == t.v[order[i]]) continue;
      const uint32_t first = m.region_of(origin);
      if (first != kNone) {
        m.mesh_regions.unite(region, first);
      } else {
        m.revived.insert(origin, 1);
      }
    }
  }

  int borders = 0;
  for (int k = 0; k < 3; ++k) {
    if (!((t.border_mask >> k) & 1)) continue;
    ++borders;
    const int k1 = (k + 1) % 3;
    if (read(k) == nullptr) return misnamed(k);
    if (read(k1) == nullptr) return misnamed(k1);
    Slot& x = *c[k];
    Slot& y = *c[k1];
    ++m.stats.border_edges;
    m.loops.unite(m.loop_node(x), m.loop_node(y));
    if ((t.nonmanifold_mask >> k) & 1) {
      if (!degenerate) {
        Cut& cut = m.cut_edges[detail::undirected_edge(x.origin, y.origin)];
        ++cut.triangles;
        cut.direction += x.origin < y.origin ? 1 : -1;
      }
    } else {
      if (!degenerate) ++m.stats.mesh_border_edges;
      m.holes.unite(m.hole_node(x), m.hole_node(y));
    }
  }
  // Paper Figure 2: the edges a triangle completes by its op; the others
  // that are not borders enter the boundary.
  static constexpr int kCompletes[5] = {0, 1, 1, 2, 3};
  m.open_edges += 3 - borders - 2 * kCompletes[op];
  m.stats.max_boundary_edges = std::max<uint64_t>(m.stats.max_boundary_edges, m.open_edges > 0 ? m.open_edges : 0);
  ++m.stats.ops[op];
  ++m.stats.triangles;
  m.fresh = 0;
  return Status();
}

Status SequenceCounter::finalize(uint32_t index) {
  Impl& m = *impl_;
  if (m.active == 0) return m.bad("finalizes vertex " + std::to_string(index) + " with no vertex active");
  --m.active;
  if (m.fresh == 0) return Status();
  // Finalized right after its vertex event: an isolated vertex (A.2 rule 4).
  const Slot& s = m.last_unslotted ? m.unslotted : m.slots[m.last_slot];
  if (m.fresh != 1 || s.dense != index) {
    return m.bad("finalizes vertex " + std::to_string(index) + " while vertex " + std::to_string(s.dense) +
                 " waits for its triangle");
  }
  m.fresh = 0;
  ++m.stats.isolated_vertices;
  if (s.origin == s.dense) ++m.isolated_origins;
  m.add_run(index, kNone);
  return Status();
}

Status SequenceCounter::finish() {
  Impl& m = *impl_;
  SequenceStats& st = m.stats;
  st.components = m.mesh_regions.sets();
  st.border_loops = m.holes.sets();
  // V - E + F = 2C - 2G - B summed over the components of the cut mesh.
  const int64_t faces = static_cast<int64_t>(st.triangles);
  const int64_t edges = (3 * faces + static_cast<int64_t>(st.border_edges)) / 2;
  const int64_t used = static_cast<int64_t>(m.introduced - st.isolated_vertices);
  const int64_t chi = used - edges + faces;
  st.handles = (2 * static_cast<int64_t>(m.cut_regions.sets()) - static_cast<int64_t>(m.loops.sets()) - chi) / 2;
  st.nonmanifold_vertices = m.cut_origins.size();
  st.nonmanifold_edges = m.cut_edges.size();
  // An edge with two triangles of opposite orientation is manifold: it was
  // cut only where a fan was split (it counts as neither).
  m.cut_edges.for_each([&](uint64_t, const Cut& c) {
    if (c.triangles > 2) ++st.mesh_nonmanifold_edges;
    else if (c.triangles == 2 && std::abs(c.direction) == 2) ++st.mesh_misoriented_edges;
  });
  st.unreferenced_vertices = m.isolated_origins - m.revived.size();
  return Status();
}

const SequenceStats& SequenceCounter::stats() const { return impl_->stats; }

}  // namespace psq
