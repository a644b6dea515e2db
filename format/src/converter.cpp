// SequenceConverter (psq/converter.h): the waiting area that turns loosely
// ordered indexed triangles into a processing sequence (Isenburg, Lindstrom,
// Gumhold, Snoeyink 2003, section 3 and Figure 3), cutting non-manifold
// vertices and edges so that only the five ops of Figure 2 occur.
#include "psq/converter.h"

#include <algorithm>
#include <array>
#include <deque>
#include <string>
#include <unordered_set>
#include <vector>

namespace psq {
namespace {

constexpr uint32_t kNone = 0xffffffffu;
// Ready triangles the converter lets wait before it starts a new region while
// input still arrives (measured on the shared meshes: 256 gave 3992 starts on
// iso_ball_200k_shuffled, 65536 gave 36, its component count).
constexpr uint64_t kStartDelay = 65536;

uint64_t edge_key(uint32_t a, uint32_t b) {
  return a < b ? (uint64_t{a} << 32) | b : (uint64_t{b} << 32) | a;
}

struct Tri {
  uint32_t v[3] = {kNone, kNone, kNone};        // input ids, input orientation
  uint32_t vs[3] = {kNone, kNone, kNone};       // their slots in the vertex pool
  uint32_t seg[3] = {kNone, kNone, kNone};      // fan of each corner, once settled
  uint32_t partner[3] = {kNone, kNone, kNone};  // triangle across edge k (k: corner k to k+1)
  uint32_t eslot[3] = {kNone, kNone, kNone};    // boundary slot of edge k once its partner entered it
  uint8_t cut_mask = 0;     // edge k is non-manifold (cut)
  uint8_t linked_mask = 0;  // edge k's partner is decided (set from either end)
  uint8_t done_mask = 0;    // edge k's partner was emitted
  uint8_t settled = 0;      // corners whose vertex is settled
  uint8_t completed = 0;    // popcount(done_mask)
  bool ready = false;
  bool emitted = false;
  PropertyValues values;

  // Back to a fresh triangle, keeping the values' capacity.
  void reset() {
    PropertyValues keep;
    keep.swap(values);
    *this = Tri();
    keep.clear();
    values.swap(keep);
  }
};

// One spoke of a vertex: the neighbour and the triangles using that edge.
struct Spoke {
  uint32_t other;
  uint32_t tris[2];    // the first two triangles (local indices)
  bool out[2];         // the triangle's edge runs vertex -> other
  uint32_t count = 0;  // triangles on the edge
};

struct Vert {
  uint32_t id = kNone;
  bool has_data = false;
  bool finalized = false;
  bool settled = false;
  double position[3] = {0, 0, 0};
  PropertyValues values;
  std::vector<uint32_t> tris;     // incident triangles not yet emitted (and emitted ones until settled)
  uint32_t waiting_neighbors = 0; // neighbours not yet finalized (after finalization)
  uint32_t first_dense = kNone;   // dense index of its first fan emitted
  uint32_t unemitted = 0;
  uint64_t stamp = 0;             // marks visits during one finalization
  bool repeats = false;           // a neighbour repeats on a side (found at finalization)
};

struct Seg {
  uint32_t vertex = kNone;  // input id
  uint32_t dense = kNone;   // dense index once emitted
  uint32_t remaining = 0;   // triangles of the fan not yet emitted
};


// Input vertex id -> slot in the vertex pool: open addressing with linear
// probing and backward-shift deletion, so that the waiting area costs no
// allocation per vertex once warm.
class IdMap {
 public:
  IdMap() { rehash(1024); }
  size_t size() const { return size_; }
  // The slot of `id`, or kNone.
  uint32_t find(uint32_t id) const {
    for (size_t i = hash(id);; i = (i + 1) & mask_) {
      if (keys_[i] == kNone) return kNone;
      if (keys_[i] == id) return values_[i];
    }
  }
  void insert(uint32_t id, uint32_t value) {
    if (2 * (size_ + 1) > keys_.size()) rehash(2 * keys_.size());
    size_t i = hash(id);
    while (keys_[i] != kNone) i = (i + 1) & mask_;
    keys_[i] = id;
    values_[i] = value;
    ++size_;
  }
  void erase(uint32_t id) {
    size_t i = hash(id);
    while (keys_[i] != id) {
      if (keys_[i] == kNone) return;
      i = (i + 1) & mask_;
    }
    // Shift later members of the probe run back into the hole.
    for (size_t j = (i + 1) & mask_; keys_[j] != kNone; j = (j + 1) & mask_) {
      size_t home = hash(keys_[j]);
      if (((j - home) & mask_) >= ((j - i) & mask_)) {
        keys_[i] = keys_[j];
        values_[i] = values_[j];
        i = j;
      }
    }
    keys_[i] = kNone;
    --size_;
  }
  template <class F>
  void for_each(F f) const {
    for (size_t i = 0; i < keys_.size(); ++i) {
      if (keys_[i] != kNone) f(keys_[i], values_[i]);
    }
  }

 private:
  size_t hash(uint32_t id) const { return (uint64_t{id} * 0x9E3779B97F4A7C15ull >> 20) & mask_; }
  void rehash(size_t capacity) {
    std::vector<uint32_t> k(capacity, kNone), v(capacity, 0);
    k.swap(keys_);
    v.swap(values_);
    mask_ = capacity - 1;
    size_ = 0;
    for (size_t i = 0; i < k.size(); ++i) {
      if (k[i] != kNone) insert(k[i], v[i]);
    }
  }
  std::vector<uint32_t> keys_, values_;
  size_t mask_ = 0;
  size_t size_ = 0;
};

}  // namespace

struct SequenceConverter::Impl {
  SequenceSink* out = nullptr;
  ConverterStats stats;
  IdMap ids;                 // input id -> slot in vpool
  std::vector<Vert> vpool;
  std::vector<uint32_t> free_verts;
  std::vector<Tri> tris;
  std::vector<uint32_t> free_tris;
  std::vector<Seg> segs;          // a fan's index is its vertex's boundary slot
  std::vector<uint32_t> free_segs;
  uint32_t edge_slots = 0;        // boundary edge slots handed out so far
  std::vector<uint32_t> free_edge_slots;
  std::unordered_set<uint64_t> broken;  // manifold edges whose link a fan split cut
  // Emission candidates by op preference: end, fill, join, add.
  std::deque<uint32_t> buckets[4];
  std::deque<uint32_t> starts;  // ready triangles, candidates for a start
  uint32_t next_dense = 0;
  uint64_t waiting = 0;
  uint64_t ready = 0;       // ready triangles not yet emitted
  bool finishing = false;   // no more input: start regions freely

  SequenceTriangle st;  // reused
  SequenceVertex sv;

  // Scratch: the spokes of one vertex, and per triangle of its fan the
  // out-spoke (id -> next) and in-spoke (prev -> id); see spokes_of().
  std::vector<Spoke> spokes;
  std::vector<std::array<uint32_t, 2>> spoke_index;
  std::vector<uint32_t> to_settle;      // scratch
  std::vector<uint32_t> fan_next, fan_prev;  // scratch: neighbours after / before a vertex in its triangles
  std::vector<std::array<int, 2>> mate;      // scratch: linked fan triangle per spoke side
  std::vector<std::array<bool, 2>> cut;      // scratch: the spoke side is cut
  std::vector<uint32_t> stack, seg_of;  // scratch
  uint64_t visit_stamp = 0;

  uint32_t vertex_slot(uint32_t id);  // existing or new
  void release_vertex(uint32_t slot);
  Status settle(uint32_t slot);
  void split_fans(uint32_t id, Vert& v);
  void spokes_of(uint32_t id, const Vert& v);
  // With `check` false, returns what the check found at finalization.
  bool fan_neighbours(uint32_t id, const Vert& v, bool check);
  void make_ready(uint32_t t);
  int classify(const Tri& t) const;
  // Emits triangle `t`, whose classify() is `cls` (0..4).
  Status emit(uint32_t t, int cls);
  Status drain();
};

uint32_t SequenceConverter::Impl::vertex_slot(uint32_t id) {
  uint32_t slot = ids.find(id);
  if (slot != kNone) return slot;
  if (!free_verts.empty()) {
    slot = free_verts.back();
    free_verts.pop_back();
  } else {
    slot = static_cast<uint32_t>(vpool.size());
    vpool.emplace_back();
  }
  vpool[slot].id = id;
  ids.insert(id, slot);
  stats.max_waiting_vertices = std::max<uint64_t>(stats.max_waiting_vertices, ids.size());
  return slot;
}

void SequenceConverter::Impl::release_vertex(uint32_t slot) {
  Vert& v = vpool[slot];
  ids.erase(v.id);
  // Keep the vectors' capacity for the next vertex in this slot.
  std::vector<uint32_t> tris_keep;
  PropertyValues values_keep;
  tris_keep.swap(v.tris);
  values_keep.swap(v.values);
  v = Vert();
  tris_keep.clear();
  values_keep.clear();
  v.tris.swap(tris_keep);
  v.values.swap(values_keep);
  free_verts.push_back(slot);
}

SequenceConverter::SequenceConverter(SequenceSink* out) : impl_(std::make_unique<Impl>()) { impl_->out = out; }
SequenceConverter::~SequenceConverter() = default;
const ConverterStats& SequenceConverter::stats() const { return impl_->stats; }

Status SequenceConverter::begin(const MeshSchema& schema) { return impl_->out->begin(schema); }

Status SequenceConverter::vertex(uint32_t id, const double position[3], const PropertyValues& values) {
  Impl& m = *impl_;
  if (id == kNone) return Status(ErrorCode::kBadIndex, "vertex id 4294967295 is reserved");
  Vert& v = m.vpool[m.vertex_slot(id)];
  if (v.has_data || v.finalized) return Status(ErrorCode::kBadIndex, "vertex " + std::to_string(id) + " given twice");
  v.has_data = true;
  std::copy(position, position + 3, v.position);
  v.values = values;
  ++m.stats.vertices_in;
  return Status();
}

Status SequenceConverter::triangle(const uint32_t id[3], const PropertyValues& values) {
  Impl& m = *impl_;
  ++m.stats.triangles_in;
  if (id[0] == id[1] || id[1] == id[2] || id[2] == id[0]) {
    ++m.stats.degenerate_dropped;
    return Status();
  }
  uint32_t vs[3];
  for (int k = 0; k < 3; ++k) {
    if (id[k] == kNone) return Status(ErrorCode::kBadIndex, "vertex id 4294967295 is reserved");
    vs[k] = m.vertex_slot(id[k]);
    if (m.vpool[vs[k]].finalized) {
      return Status(ErrorCode::kBadIndex, "a triangle uses vertex " + std::to_string(id[k]) + " after its finalization");
    }
  }
  uint32_t slot;
  if (!m.free_tris.empty()) {
    slot = m.free_tris.back();
    m.free_tris.pop_back();
    m.tris[slot].reset();
  } else {
    slot = static_cast<uint32_t>(m.tris.size());
    m.tris.emplace_back();
  }
  Tri& t = m.tris[slot];
  for (int k = 0; k < 3; ++k) {
    t.v[k] = id[k];
    t.vs[k] = vs[k];
    Vert& v = m.vpool[t.vs[k]];
    v.tris.push_back(slot);
    ++v.unemitted;
  }
  t.values = values;
  ++m.waiting;
  m.stats.max_waiting_triangles = std::max(m.stats.max_waiting_triangles, m.waiting);
  return Status();
}

// The spokes (edges) of vertex `id` over its waiting triangles, into
// `spokes`; spoke_index[i] names the out-spoke (id -> next) and in-spoke
// (prev -> id) of its i-th triangle.
void SequenceConverter::Impl::spokes_of(uint32_t id, const Vert& v) {
  spokes.clear();
  spoke_index.resize(v.tris.size());
  for (uint32_t i = 0; i < v.tris.size(); ++i) {
    const Tri& t = tris[v.tris[i]];
    int c = t.v[0] == id ? 0 : t.v[1] == id ? 1 : 2;
    uint32_t nb[2] = {t.v[(c + 1) % 3], t.v[(c + 2) % 3]};
    for (int s = 0; s < 2; ++s) {
      uint32_t si = 0;
      while (si < spokes.size() && spokes[si].other != nb[s]) ++si;
      if (si == spokes.size()) spokes.push_back(Spoke{nb[s], {kNone, kNone}, {false, false}, 0});
      Spoke& sp = spokes[si];
      if (sp.count < 2) {
        sp.tris[sp.count] = i;
        sp.out[sp.count] = s == 0;
      }
      ++sp.count;
      spoke_index[i][s] = si;
    }
  }
}

// Fills fan_next/fan_prev with the neighbour after and before vertex `id`
// in each of its triangles; returns true when one repeats on a side, the
// only way a spoke can have more than one triangle on a side (non-manifold
// or misoriented).
bool SequenceConverter::Impl::fan_neighbours(uint32_t id, const Vert& v, bool check) {
  size_t n = v.tris.size();
  fan_next.resize(n);
  fan_prev.resize(n);
  for (size_t i = 0; i < n; ++i) {
    const Tri& t = tris[v.tris[i]];
    int c = t.v[0] == id ? 0 : t.v[1] == id ? 1 : 2;
    fan_next[i] = t.v[(c + 1) % 3];
    fan_prev[i] = t.v[(c + 2) % 3];
  }
  if (!check) return v.repeats;
  for (size_t i = 0; i < n; ++i) {
    for (size_t j = i + 1; j < n; ++j) {
      if (fan_next[i] == fan_next[j] || fan_prev[i] == fan_prev[j]) return true;
    }
  }
  return false;
}

// A spoke links its two triangles when it has exactly two, of opposite
// orientation, and no fan split broke the link.
static bool is_link(const Spoke& s, uint32_t id, const std::unordered_set<uint64_t>& broken) {
  return s.count == 2 && s.out[0] != s.out[1] && (broken.empty() || !broken.count(edge_key(id, s.other)));
}

static bool is_nonmanifold(const Spoke& s) { return s.count >= 3 || (s.count == 2 && s.out[0] == s.out[1]); }

// At finalization (phase A): walk each fan of the vertex and break links so
// that no fan holds two triangles that share a non-manifold spoke; otherwise
// both would use the same edge of the sequence.
void SequenceConverter::Impl::split_fans(uint32_t id, Vert& v) {
  // Only a repeated neighbour makes a spoke non-manifold.
  v.repeats = fan_neighbours(id, v, true);
  if (!v.repeats) return;
  spokes_of(id, v);
  bool any_nonmanifold = false;
  for (const Spoke& s : spokes) any_nonmanifold = any_nonmanifold || is_nonmanifold(s);
  if (!any_nonmanifold) return;  // a disk or half-disk, or only broken links
  size_t n = v.tris.size();
  // Per local triangle: the triangle linked through each of its two spokes.
  std::vector<std::array<int, 2>> next(n, {-1, -1});
  for (size_t i = 0; i < n; ++i) {
    for (int sl = 0; sl < 2; ++sl) {
      const Spoke& s = spokes[spoke_index[i][sl]];
      if (is_link(s, id, broken)) next[i][sl] = static_cast<int>(s.tris[0] == i ? s.tris[1] : s.tris[0]);
    }
  }
  std::vector<char> visited(n, 0);
  std::vector<uint32_t> seen;
  auto walk = [&](int start) {
    int prev = -1, cur = start;
    seen.clear();
    while (cur >= 0 && !visited[cur]) {
      visited[cur] = 1;
      bool clash = false;
      for (int sl = 0; sl < 2; ++sl) {
        const Spoke& s = spokes[spoke_index[cur][sl]];
        if (is_nonmanifold(s) && std::find(seen.begin(), seen.end(), s.other) != seen.end()) clash = true;
      }
      if (clash && prev >= 0) {
        // Break the link between prev and cur: it runs through their shared spoke.
        for (int sl = 0; sl < 2; ++sl) {
          if (next[cur][sl] == prev) broken.insert(edge_key(id, spokes[spoke_index[cur][sl]].other));
        }
        seen.clear();
      }
      for (int sl = 0; sl < 2; ++sl) {
        const Spoke& s = spokes[spoke_index[cur][sl]];
        if (is_nonmanifold(s)) seen.push_back(s.other);
      }
      int nxt = -1;
      for (int sl = 0; sl < 2; ++sl) {
        if (next[cur][sl] >= 0 && next[cur][sl] != prev && !visited[next[cur][sl]]) nxt = next[cur][sl];
      }
      prev = cur;
      cur = nxt;
    }
  };
  // Paths first, from their ends; whatever is left are closed fans, which
  // have no non-manifold spoke.
  for (size_t i = 0; i < n; ++i) {
    if (!visited[i] && (next[i][0] < 0 || next[i][1] < 0)) walk(static_cast<int>(i));
  }
}

Status SequenceConverter::finalize(uint32_t id) {
  Impl& m = *impl_;
  uint32_t slot = m.ids.find(id);
  if (slot == kNone || m.vpool[slot].finalized) {
    return Status(ErrorCode::kBadIndex, "vertex " + std::to_string(id) + (slot == kNone ? " finalized but never given" : " finalized twice"));
  }
  Vert& v = m.vpool[slot];
  if (!v.has_data) return Status(ErrorCode::kBadIndex, "vertex " + std::to_string(id) + " is used but was never given");
  m.split_fans(id, v);
  v.finalized = true;
  // Neighbours: settle those that waited only for this vertex. A neighbour
  // appears in two triangles of a fan; count each once by marking it.
  m.to_settle.clear();
  uint32_t waiting = 0;
  ++m.visit_stamp;
  for (uint32_t ts : v.tris) {
    for (uint32_t us : m.tris[ts].vs) {
      Vert& nv = m.vpool[us];
      if (us == slot || nv.stamp == m.visit_stamp) continue;
      nv.stamp = m.visit_stamp;
      if (!nv.finalized) {
        ++waiting;
      } else if (!nv.settled && --nv.waiting_neighbors == 0) {
        m.to_settle.push_back(us);
      }
    }
  }
  v.waiting_neighbors = waiting;
  if (waiting == 0) m.to_settle.push_back(slot);
  for (size_t i = 0; i < m.to_settle.size(); ++i) PSQ_RETURN_IF_ERROR(m.settle(m.to_settle[i]));
  return m.drain();
}

// Phase B: every neighbour is finalized, so every link around the vertex is
// decided. Its fans become the vertex's segments; the partners of its spokes
// are set on both triangles.
Status SequenceConverter::Impl::settle(uint32_t vslot) {
  Vert& v = vpool[vslot];
  const uint32_t id = v.id;
  v.settled = true;
  if (v.tris.empty()) {
    // An isolated vertex: introduced and finalized with no triangle. It
    // takes a slot like any vertex (free again at once).
    uint32_t sg;
    if (!free_segs.empty()) {
      sg = free_segs.back();
    } else {
      sg = static_cast<uint32_t>(segs.size());
      segs.emplace_back();
      free_segs.push_back(sg);
    }
    sv.index = next_dense++;
    sv.slot = sg;
    sv.reappears = kNone;
    std::copy(v.position, v.position + 3, sv.position);
    sv.values = v.values;
    PSQ_RETURN_IF_ERROR(out->vertex(sv));
    PSQ_RETURN_IF_ERROR(out->finalize(sv.index));
    release_vertex(vslot);
    return Status();
  }
  // For each triangle's out-spoke (sl 0: id -> next) and in-spoke (sl 1:
  // prev -> id): the fan triangle it links to (or -1), or whether it is cut.
  size_t n = v.tris.size();
  mate.resize(n);
  cut.resize(n);
  if (!fan_neighbours(id, v, false)) {
    // Fast path, every spoke has at most one triangle on each side: a spoke
    // with two links them (unless a fan split broke the link), one with a
    // single triangle is a border.
    for (uint32_t i = 0; i < n; ++i) {
      for (int sl = 0; sl < 2; ++sl) {
        uint32_t w = sl == 0 ? fan_next[i] : fan_prev[i];
        const std::vector<uint32_t>& other_side = sl == 0 ? fan_prev : fan_next;
        int j = -1;
        for (uint32_t k = 0; k < n; ++k) {
          if (other_side[k] == w) {
            j = static_cast<int>(k);
            break;
          }
        }
        bool link = j >= 0 && (broken.empty() || !broken.count(edge_key(id, w)));
        mate[i][sl] = link ? j : -1;
        cut[i][sl] = j >= 0 && !link;
        if (j < 0 && id < w) ++stats.border_edges;  // each edge once: at its smaller end
      }
    }
  } else {
    spokes_of(id, v);
    for (const Spoke& sp : spokes) {
      if (id < sp.other) {  // each edge once: at the settling of its smaller end
        if (sp.count == 1) ++stats.border_edges;
        else if (sp.count > 2) ++stats.nonmanifold_edges;
        else if (sp.out[0] == sp.out[1]) ++stats.misoriented_edges;
      }
    }
    for (uint32_t i = 0; i < n; ++i) {
      for (int sl = 0; sl < 2; ++sl) {
        const Spoke& sp = spokes[spoke_index[i][sl]];
        bool link = is_link(sp, id, broken);
        mate[i][sl] = link ? static_cast<int>(sp.tris[0] == i ? sp.tris[1] : sp.tris[0]) : -1;
        cut[i][sl] = !link && sp.count >= 2;
      }
    }
  }
  // Partners and cuts on the triangles.
  for (uint32_t i = 0; i < n; ++i) {
    Tri& t = tris[v.tris[i]];
    int c = t.v[0] == id ? 0 : t.v[1] == id ? 1 : 2;
    for (int sl = 0; sl < 2; ++sl) {
      int k = sl == 0 ? c : (c + 2) % 3;  // out-spoke: edge c; in-spoke: edge c-1
      uint8_t bit = static_cast<uint8_t>(1u << k);
      // The edge's partner is decided at whichever end settles first.
      if (t.linked_mask & bit) continue;
      t.linked_mask |= bit;
      int j = mate[i][sl];
      if (j >= 0) {
        t.partner[k] = v.tris[j];
      } else if (cut[i][sl]) {
        t.cut_mask |= bit;
      }
    }
  }
  // One segment per fan: the triangles connected through links (each has at
  // most two), found by walking them.
  seg_of.assign(n, kNone);
  uint32_t fans = 0;
  for (uint32_t start = 0; start < n; ++start) {
    if (seg_of[start] != kNone) continue;
    uint32_t sg;
    if (!free_segs.empty()) {
      sg = free_segs.back();
      free_segs.pop_back();
      segs[sg] = Seg();
    } else {
      sg = static_cast<uint32_t>(segs.size());
      segs.emplace_back();
    }
    segs[sg].vertex = id;
    ++fans;
    stack.clear();
    stack.push_back(start);
    seg_of[start] = sg;
    while (!stack.empty()) {
      uint32_t i = stack.back();
      stack.pop_back();
      for (int sl = 0; sl < 2; ++sl) {
        int j = mate[i][sl];
        if (j >= 0 && seg_of[j] == kNone) {
          seg_of[j] = sg;
          stack.push_back(static_cast<uint32_t>(j));
        }
      }
    }
  }
  for (uint32_t i = 0; i < n; ++i) {
    uint32_t sg = seg_of[i];
    ++segs[sg].remaining;
    Tri& t = tris[v.tris[i]];
    for (int k = 0; k < 3; ++k) {
      if (t.v[k] == id) t.seg[k] = sg;
    }
    if (++t.settled == 3) make_ready(v.tris[i]);
  }
  if (fans > 1) ++stats.nonmanifold_vertices;
  return Status();
}

void SequenceConverter::Impl::make_ready(uint32_t slot) {
  Tri& t = tris[slot];
  t.ready = true;
  ++ready;
  int c = classify(t);
  if (c >= 0 && c < 4) buckets[c].push_back(slot);
  starts.push_back(slot);
  // Entries of emitted triangles, or of triangles that touch an emitted fan
  // (growth reaches those), stay in `starts` until a start is needed, which
  // coherent input rarely needs: drop them now and then so that the queue
  // stays proportional to the waiting area, not to the mesh.
  if (starts.size() > 2 * ready + 4096) {
    std::deque<uint32_t> keep;
    for (uint32_t x : starts) {
      const Tri& tx = tris[x];
      if (!tx.emitted && tx.ready && classify(tx) == 4) keep.push_back(x);
    }
    starts.swap(keep);
  }
}

// 0 end, 1 fill, 2 join, 3 add, 4 start, -1 not emittable now.
int SequenceConverter::Impl::classify(const Tri& t) const {
  int fresh = 0;
  for (int k = 0; k < 3; ++k) fresh += segs[t.seg[k]].dense == kNone;
  switch (t.completed) {
    case 3: return 0;
    case 2: return 1;
    case 1: return fresh == 0 ? 2 : 3;
    default: return fresh == 3 ? 4 : -1;
  }
}

Status SequenceConverter::Impl::emit(uint32_t slot, int cls) {
  static const Op kOps[] = {Op::kEnd, Op::kFill, Op::kJoin, Op::kAdd, Op::kStart};
  Tri& t = tris[slot];
  if (cls < 0) return Status(ErrorCode::kInternal, "converter emitted a triangle that is none of the five ops");
  st.op = kOps[cls];
  st.new_mask = st.final_mask = st.border_mask = st.nonmanifold_mask = st.leaving_mask = st.entering_mask = 0;
  for (int k = 0; k < 3; ++k) {
    Seg& s = segs[t.seg[k]];
    if (s.dense == kNone) {
      Vert& v = vpool[t.vs[k]];
      s.dense = next_dense++;
      sv.index = s.dense;
      sv.slot = t.seg[k];
      sv.reappears = v.first_dense;
      if (v.first_dense == kNone) v.first_dense = s.dense;
      std::copy(v.position, v.position + 3, sv.position);
      sv.values = v.values;
      PSQ_RETURN_IF_ERROR(out->vertex(sv));
      st.new_mask |= static_cast<uint8_t>(1u << k);
    }
    st.v[k] = s.dense;
    st.vslot[k] = t.seg[k];
    if (s.remaining == 1) st.final_mask |= static_cast<uint8_t>(1u << k);
  }
  for (int k = 0; k < 3; ++k) {
    uint8_t bit = static_cast<uint8_t>(1u << k);
    st.eslot[k] = kNone;
    if (t.partner[k] == kNone) {
      st.border_mask |= bit;
      if (t.cut_mask & bit) st.nonmanifold_mask |= bit;
    } else if (t.done_mask & bit) {
      st.leaving_mask |= bit;
      st.eslot[k] = t.eslot[k];
    } else {
      st.entering_mask |= bit;
      if (!free_edge_slots.empty()) {
        st.eslot[k] = free_edge_slots.back();
        free_edge_slots.pop_back();
      } else {
        st.eslot[k] = edge_slots++;
      }
    }
  }
  st.values.swap(t.values);
  PSQ_RETURN_IF_ERROR(out->triangle(st));
  t.emitted = true;
  // Tell unemitted partners that their edge is now on the boundary.
  for (int k = 0; k < 3; ++k) {
    uint32_t p = t.partner[k];
    if (p == kNone || (t.done_mask & (1u << k))) continue;
    Tri& pt = tris[p];
    for (int j = 0; j < 3; ++j) {
      // The same edge, reversed (two triangles may share more than one edge).
      if (pt.partner[j] == slot && pt.v[j] == t.v[(k + 1) % 3] && pt.v[(j + 1) % 3] == t.v[k]) {
        pt.done_mask |= static_cast<uint8_t>(1u << j);
        pt.eslot[j] = st.eslot[k];
        ++pt.completed;
        break;
      }
    }
    if (pt.ready) {
      int c = classify(pt);
      if (c >= 0 && c < 4) buckets[c].push_back(p);
    }
  }
  // Edges this triangle completed leave the boundary: their slots are free.
  for (int k = 0; k < 3; ++k) {
    if (st.leaving_mask & (1u << k)) free_edge_slots.push_back(st.eslot[k]);
  }
  // Finalize fans that this triangle completes; forget finished vertices.
  for (int k = 0; k < 3; ++k) {
    Seg& s = segs[t.seg[k]];
    if (--s.remaining == 0) {
      PSQ_RETURN_IF_ERROR(out->finalize(s.dense));
      free_segs.push_back(t.seg[k]);
    }
    Vert& v = vpool[t.vs[k]];
    if (--v.unemitted == 0 && v.settled) release_vertex(t.vs[k]);
  }
  --waiting;
  --ready;
  t.values.clear();
  free_tris.push_back(slot);
  return Status();
}

Status SequenceConverter::Impl::drain() {
  for (;;) {
    bool emitted = false;
    for (int b = 0; b < 4 && !emitted; ++b) {
      while (!buckets[b].empty()) {
        uint32_t slot = buckets[b].front();
        buckets[b].pop_front();
        Tri& t = tris[slot];
        if (t.emitted || !t.ready) continue;  // stale entry (slots are reused only after emission)
        int c = classify(t);
        if (c != b) {
          if (c >= 0 && c < 4) buckets[c].push_back(slot);
          continue;
        }
        PSQ_RETURN_IF_ERROR(emit(slot, c));
        emitted = true;
        break;
      }
    }
    if (emitted) continue;
    // Nothing adjacent to the boundary: start a new region, but while input
    // still arrives only once enough triangles wait, since the triangles
    // that continue the current regions may simply not be ready yet; each
    // needless start costs a join later.
    if (!finishing && ready < kStartDelay) return Status();
    while (!starts.empty()) {
      uint32_t slot = starts.front();
      starts.pop_front();
      Tri& t = tris[slot];
      if (t.emitted || !t.ready) continue;
      if (classify(t) == 4) {
        PSQ_RETURN_IF_ERROR(emit(slot, 4));
        emitted = true;
        break;
      }
    }
    if (!emitted) return Status();
  }
}

Status SequenceConverter::finish() {
  Impl& m = *impl_;
  m.finishing = true;
  // Finalize what the caller left open (a source that finalizes nothing
  // leaves the whole mesh to this point).
  std::vector<uint32_t> open;
  m.ids.for_each([&](uint32_t id, uint32_t slot) {
    if (!m.vpool[slot].finalized) open.push_back(id);
  });
  std::sort(open.begin(), open.end());
  for (uint32_t id : open) PSQ_RETURN_IF_ERROR(finalize(id));
  PSQ_RETURN_IF_ERROR(m.drain());
  if (m.waiting != 0 || m.ids.size() != 0) {
    return Status(ErrorCode::kInternal, std::to_string(m.waiting) + " triangles left in the waiting area");
  }
  return m.out->finish();
}

}  // namespace psq
