// SPDX-License-Identifier: Apache-2.0
// SequenceConverter (psq/converter.h): the waiting area that turns loosely
// ordered indexed triangles into a processing sequence (Isenburg, Lindstrom,
// Gumhold, Snoeyink 2003, section 3 and Figure 3), cutting non-manifold
// vertices and edges so that only the five ops of Figure 2 occur.
//
// Work per vertex is linear in its valence: its neighbours are grouped into
// spokes through a mark on the neighbour's pool entry (the pool slot is a
// perfect hash of a waiting vertex), each edge is decided once (at the
// finalization of whichever end comes first) and stored on its triangles as
// a partner reference (triangle * 4 + edge), and fans are walked through
// those references. A waiting triangle and a waiting vertex take one cache
// line each; a vertex's corners are stored with it, contiguous (Vert), so
// that walking them overlaps the loads of its triangles; positions and
// property values live in side arrays touched only at emission.
#include "psq/converter.h"

#include "flat_map.h"

#include <algorithm>
#include <array>
#include <iterator>
#include <map>
#include <string>
#include <unordered_map>
#include <vector>

namespace psq {
namespace {

constexpr uint32_t kNone = 0xffffffffu;
// Ready triangles the converter keeps waiting while input still arrives: it
// emits only while more are ready. With this lookahead the region grows
// into triangles that already arrived instead of hopping along the front of
// a sweep-ordered input, and needless starts (each costs a join later) wait
// until the triangles that continue the current regions had their chance
// (on shuffled input, that keeps the starts near the number of
// components). Sweeps such as iso-surfaces code much smaller with it, for
// a little more memory; a shallower lookahead gives up part of the gain
// (bench/HISTORY.md, "Converter lookahead").
constexpr uint64_t kLookahead = 65536;
// ... and at least this many per open boundary edge, within the budget of
// set_lookahead_budget() at about kLookaheadBytes each: a long boundary
// (the front of a large sweep) needs a deeper lookahead for the same
// choice, or the region meets triangles not yet ready along the front and
// leaves through nonzero gate offsets and far gates. 32 per edge trades
// bytes for memory on large sweeps: 16 gives up part of the gain, 64 adds
// little and doubles the memory (bench/HISTORY.md, "A lookahead that grows
// with the boundary").
constexpr uint64_t kLookaheadPerEdge = 32;
constexpr uint64_t kLookaheadBytes = 200;
// Triangle slots are stored as slot * 4 + corner (or edge).
constexpr uint32_t kMaxTriangles = 1u << 30;

// A waiting triangle: one cache line. Its face values live in
// Impl::tri_values (touched only when there are any).
struct alignas(64) Tri {
  uint32_t vs[3];       // vertex pool slots of its corners, input orientation
  uint32_t seg[3];      // fan (dense vertex slot) of each corner, once settled
  uint32_t partner[3];  // across edge k (corner k to k+1): partner slot * 4 + its edge, or kNone
  uint32_t eslot[3];    // boundary slot of edge k once its partner entered it
  uint8_t cut_mask;     // edge k is cut: non-manifold, or a link a fan split broke
  uint8_t nm_mask;      // edge k is non-manifold (more than two triangles, or misoriented)
  uint8_t done_mask;    // edge k's partner was emitted
  uint8_t state;        // kSettledMask: corners settled; kReady, kEmitted, kHasValues

  static constexpr uint8_t kSettledMask = 3, kReady = 4, kEmitted = 8, kHasValues = 16;
  bool ready() const { return state & kReady; }
  bool emitted() const { return state & kEmitted; }
  int completed() const { return (done_mask & 1) + ((done_mask >> 1) & 1) + (done_mask >> 2); }
  void reset() {
    for (int k = 0; k < 3; ++k) vs[k] = seg[k] = partner[k] = eslot[k] = kNone;
    cut_mask = nm_mask = done_mask = state = 0;
  }
};
static_assert(sizeof(Tri) == 64, "a triangle fills one cache line");

// A waiting vertex: one cache line, holding its corners (the triangles
// around it, slot * 4 + corner, in input order, until settled) up to
// kInlineCorners, the rest in Impl::vert_spill. Finalization walks that list
// (decide_spokes, settle): kept contiguous, next to the counters that the
// same steps touch, its triangles' addresses are all known at once and their
// loads overlap, where a list linked through the triangles costs one
// dependent cache miss per corner. Its position is cold (read when it is
// emitted: Impl::vert_pos), its values in Impl::vert_values.
constexpr uint32_t kInlineCorners = 8;
struct alignas(64) Vert {
  uint32_t stamp = 0;              // scratch: `spoke` is valid while stamp == visit_stamp
  uint32_t spoke = 0;              // scratch: its spoke around the vertex being finalized
  uint32_t waiting_neighbors = 0;  // neighbours not yet finalized (after finalization)
  uint32_t unemitted = 0;          // incident triangles not yet emitted
  uint32_t first_dense = kNone;    // dense index of its first fan emitted
  uint32_t id = kNone;
  bool finalized = false;
  bool settled = false;
  bool has_data = false;
  bool has_values = false;
  uint32_t n_corners = 0;
  uint32_t corner[kInlineCorners];  // the first corners; the rest in Impl::vert_spill
};
static_assert(sizeof(Vert) == 64, "a vertex fills one cache line");

// One undecided spoke (edge) of the vertex being finalized: the neighbour,
// not finalized yet, and the triangles using the edge in each direction.
struct Spoke {
  uint32_t out_edge;    // first triangle with the edge vertex -> neighbour: slot * 4 + edge
  uint32_t in_edge;     // first triangle with neighbour -> vertex
  uint32_t n_out;
  uint32_t n_in;
  bool cut;             // non-manifold: cut on all its triangles
};

// A side of a corner, in decide_spokes(): the neighbour across one of the
// corner's two edges, and that edge (slot * 4 + edge), out of the vertex or
// into it.
struct Side {
  uint32_t ws;
  uint32_t edge;
  bool outgoing;
};

struct Seg {
  uint32_t dense = kNone;   // dense index once emitted
  uint32_t remaining = 0;   // triangles of the fan not yet emitted
};

using detail::IdMap;

// The input ids finalized so far, so that vertex() and triangle() reject an
// id whose vertex has left the waiting area. Ids are grouped in pages of
// 2^16: a page keeps its finalized ids as a sorted list while it has at most
// 4096 (2 bytes each), then as a bitmap (8 KiB), and nothing once all its
// ids are finalized (runs of such full pages are kept as intervals). Dense
// ids finalized roughly in order (coherent input) thus cost a few pages; in
// any order at most one bit per id of the pages in use.
class FinalizedIds {
 public:
  bool contains(uint32_t id) {
    if (empty_ || id > max_) return false;  // ids mostly grow: new ones end here
    uint32_t p = id >> kShift;
    const Page* pg = find(p);
    if (pg == nullptr) return full(p);
    uint16_t low = static_cast<uint16_t>(id);
    if (!pg->bits.empty()) return (pg->bits[low >> 6] >> (low & 63)) & 1;
    return std::binary_search(pg->list.begin(), pg->list.end(), low);
  }
  // `id` must not be in the set.
  void insert(uint32_t id) {
    if (empty_ || id > max_) max_ = id;
    empty_ = false;
    uint32_t p = id >> kShift;
    Page* pg = find(p);
    if (pg == nullptr) {
      pg = &pages_[p];
      cached_page_ = p;
      cached_ = pg;
    }
    uint16_t low = static_cast<uint16_t>(id);
    if (pg->bits.empty() && pg->list.size() < kListMax) {
      if (pg->list.empty() || pg->list.back() < low) {
        pg->list.push_back(low);
      } else {
        pg->list.insert(std::lower_bound(pg->list.begin(), pg->list.end(), low), low);
      }
    } else {
      if (pg->bits.empty()) {
        pg->bits.assign(kPageSize / 64, 0);
        for (uint16_t x : pg->list) pg->bits[x >> 6] |= uint64_t{1} << (x & 63);
        std::vector<uint16_t>().swap(pg->list);
      }
      pg->bits[low >> 6] |= uint64_t{1} << (low & 63);
    }
    if (++pg->count == kPageSize) {
      pages_.erase(p);
      cached_ = nullptr;
      cached_page_ = kNone;
      add_full(p);
    }
  }

 private:
  static constexpr int kShift = 16;
  static constexpr uint32_t kPageSize = 1u << kShift;
  static constexpr size_t kListMax = kPageSize / 16;  // as many bytes as the bitmap
  struct Page {
    uint32_t count = 0;
    std::vector<uint16_t> list;  // sorted low 16 bits, while at most kListMax
    std::vector<uint64_t> bits;  // once more
  };

  Page* find(uint32_t p) {
    if (p == cached_page_) return cached_;
    auto it = pages_.find(p);
    if (it == pages_.end()) return nullptr;
    cached_page_ = p;
    cached_ = &it->second;  // nodes of an unordered_map stay put
    return cached_;
  }
  bool full(uint32_t p) const {
    auto it = full_.upper_bound(p);
    return it != full_.begin() && std::prev(it)->second > p;
  }
  void add_full(uint32_t p) {
    uint32_t hi = p + 1;  // at most 2^16
    auto next = full_.find(hi);
    if (next != full_.end()) {
      hi = next->second;
      full_.erase(next);
    }
    auto it = full_.lower_bound(p);
    if (it != full_.begin() && std::prev(it)->second == p) {
      std::prev(it)->second = hi;
      return;
    }
    full_[p] = hi;
  }

  std::unordered_map<uint32_t, Page> pages_;  // pages with some, not all, ids finalized
  std::map<uint32_t, uint32_t> full_;         // runs of full pages: first -> one past the last
  uint32_t cached_page_ = kNone;
  Page* cached_ = nullptr;
  uint32_t max_ = 0;  // the largest id in the set
  bool empty_ = true;
};

// A FIFO queue of triangle slots (a vector and a read position; the read
// part is dropped once it is the larger half).
class SlotQueue {
 public:
  bool empty() const { return head_ == items_.size(); }
  size_t size() const { return items_.size() - head_; }
  void push(uint32_t x) { items_.push_back(x); }
  // The most recently pushed item.
  uint32_t pop_newest() {
    uint32_t x = items_.back();
    items_.pop_back();
    if (items_.size() == head_) {
      items_.clear();
      head_ = 0;
    }
    return x;
  }
  // The oldest item.
  uint32_t pop() {
    uint32_t x = items_[head_++];
    if (head_ == items_.size()) {
      items_.clear();
      head_ = 0;
    } else if (head_ >= 4096 && 2 * head_ >= items_.size()) {
      items_.erase(items_.begin(), items_.begin() + static_cast<std::ptrdiff_t>(head_));
      head_ = 0;
    }
    return x;
  }
  // Keeps the items for which keep(x) holds, in order. keep() reads two
  // levels of records (a triangle, then what it points to): touch(x) is
  // called on the item 16 places further on, touch_next(x) on the item 8
  // places further on, to prefetch the first and the second level, so that
  // the scan does not wait for cache misses one item after the other.
  template <class Keep, class Touch, class TouchNext>
  void filter(Keep keep, Touch touch, TouchNext touch_next) {
    constexpr size_t kAhead = 16, kAheadNext = 8;
    size_t n = 0;
    for (size_t i = head_; i < items_.size(); ++i) {
      if (i + kAhead < items_.size()) touch(items_[i + kAhead]);
      if (i + kAheadNext < items_.size()) touch_next(items_[i + kAheadNext]);
      if (keep(items_[i])) items_[n++] = items_[i];
    }
    items_.resize(n);
    head_ = 0;
  }

 private:
  std::vector<uint32_t> items_;
  size_t head_ = 0;
};

// Corner arithmetic: the next and previous corner. Edge k joins corners k
// and k + 1, so the edges at corner c are c (out) and kPrev[c] (in).
constexpr uint32_t kNext[3] = {1, 2, 0};
constexpr uint32_t kPrev[3] = {2, 0, 1};
// The two edges at corner c, as a mask.
constexpr uint8_t kEdgesAt[3] = {5, 3, 6};

}  // namespace

struct SequenceConverter::Impl {
  SequenceSink* out = nullptr;
  Status error;              // the first error; every later call returns it
  ConverterStats stats;
  // Input id -> slot in vpool: a table indexed by the id's low bits, kept
  // at least twice as large as the pool, with the ids whose cell another
  // waiting id holds in a hash map beside it. The ids of a coherent input
  // are dense and waiting ids span a window not much wider than the
  // waiting area, so they rarely meet in a cell, and ids given or
  // finalized one after the other share cache lines, where a hash
  // scatters them over a table beyond the L2 cache (its lookups and
  // erasures were most of release_vertex's time). Any ids work, in any
  // order: the overflow map takes what the table cannot.
  std::vector<uint32_t> id_table = std::vector<uint32_t>(kIdTableMin, kNone);
  IdMap id_overflow;
  uint64_t live_ids = 0;
  static constexpr size_t kIdTableMin = size_t{1} << 12;
  // The slot of waiting vertex `id`, or kNone.
  uint32_t find_slot(uint32_t id) const {
    const uint32_t slot = id_table[id & (id_table.size() - 1)];
    if (slot != kNone && vpool[slot].id == id) return slot;
    return id_overflow.size() == 0 ? kNone : id_overflow.find(id);
  }
  void insert_id(uint32_t id, uint32_t slot) {
    uint32_t& cell = id_table[id & (id_table.size() - 1)];
    if (cell == kNone) {
      cell = slot;
    } else {
      id_overflow.insert(id, slot);
    }
    ++live_ids;
  }
  void erase_id(uint32_t id, uint32_t slot) {
    uint32_t& cell = id_table[id & (id_table.size() - 1)];
    if (cell == slot) {
      cell = kNone;
    } else {
      id_overflow.erase(id);
    }
    --live_ids;
  }
  // Doubles the table until it has twice the pool's slots, and fills it
  // again from the pool.
  void grow_id_table(size_t pool) {
    size_t n = id_table.size();
    while (n < 2 * pool) n *= 2;
    if (n == id_table.size()) return;
    id_table.assign(n, kNone);
    id_overflow = IdMap();
    live_ids = 0;
    for (uint32_t slot = 0; slot < vpool.size(); ++slot)
      if (vpool[slot].id != kNone) insert_id(vpool[slot].id, slot);
  }
  FinalizedIds finalized_ids;
  std::vector<Vert> vpool;
  std::vector<std::array<double, 3>> vert_pos;  // per vpool slot
  std::vector<std::vector<uint32_t>> vert_spill;  // per vpool slot: corners past kInlineCorners
  // Per vpool slot, sized on the first vertex with values (and the same
  // for tri_values): a mesh without properties never touches them.
  std::vector<PropertyValues> vert_values;  // per vpool slot, when has_values
  std::vector<uint32_t> free_verts;
  std::vector<Tri> tris;
  std::vector<PropertyValues> tri_values;   // per tris slot, when kHasValues
  std::vector<uint32_t> free_tris;
  std::vector<Seg> segs;          // a fan's index is its vertex's boundary slot
  std::vector<uint32_t> free_segs;
  uint32_t edge_slots = 0;        // boundary edge slots handed out so far
  std::vector<uint32_t> free_edge_slots;
  // Emission candidates by op preference (end, fill, join, add): those an
  // emission made emittable, next to the grown regions, and those that
  // became emittable when their input arrived (make_ready), which in a
  // sweep-ordered input lie along the front of the sweep.
  SlotQueue buckets[4];
  SlotQueue arrived[4];
  uint32_t prefer[3] = {kNone, kNone, kNone};  // neighbours of the last triangle
  SlotQueue starts;  // ready triangles that are start candidates
  uint32_t next_dense = 0;
  uint32_t last_finalized = kNone;  // finalize(): the id finalized last
  uint64_t waiting = 0;
  uint64_t ready = 0;       // ready triangles not yet emitted
  uint64_t lookahead_cap = (uint64_t{128} << 20) / kLookaheadBytes;  // set_lookahead_budget()
  uint64_t lookahead_min = kLookahead;                                // set_lookahead_minimum()
  bool finishing = false;   // no more input: start regions freely

  SequenceTriangle st;  // reused
  SequenceVertex sv;

  // Scratch.
  std::vector<Spoke> spokes;                // of the vertex being finalized: the first n_spokes
  std::vector<Side> sides;                  // decide_spokes: two per corner
  std::vector<uint32_t> now_ready;          // settle: the triangles it makes ready, the first n_now_ready
  uint32_t n_now_ready = 0;
  uint32_t n_spokes = 0;
  std::vector<uint32_t> to_settle;
  std::vector<uint32_t> local_of;           // triangle slot -> index in the vertex's corner list (split_fans)
  std::vector<uint32_t> fan_corners;        // split_fans: the vertex's corners
  std::vector<uint64_t> seen;               // split_fans: per vpool slot, marks of the fan walk
  std::vector<std::array<int, 2>> fan_next; // split_fans: linked triangle per side
  std::vector<char> visited;
  uint32_t visit_stamp = 0;                 // one per finalization: at most 2^32 - 1 ids
  uint64_t seen_stamp = 0;

  // The internal steps return false after storing the error in `error`.
  bool fail(Status s) {
    error = std::move(s);
    return false;
  }
  bool vertex(uint32_t id, const double position[3], const PropertyValues& values);
  bool triangle(const uint32_t id[3], const PropertyValues& values);
  bool finalize(uint32_t id);
  bool finish();

  bool check_unknown_id(uint32_t id);
  uint32_t vertex_slot(uint32_t id);  // a new one
  void release_vertex(uint32_t slot);
  bool decide_spokes(uint32_t vslot, uint32_t* waiting_neighbors);
  void split_fans(uint32_t vslot);
  void break_link(uint32_t t, uint32_t edge);
  bool settle(uint32_t vslot);
  void make_ready(uint32_t t);
  // Requests the fans that classify(t) reads (those of a settled triangle).
  void prefetch_segs(const Tri& t) const {
    if ((t.state & Tri::kSettledMask) != 3) return;
    for (int k = 0; k < 3; ++k) __builtin_prefetch(&segs[t.seg[k]]);
  }
  int classify(const Tri& t) const;
  // Emits triangle `t`, whose classify() is `cls` (0..4).
  bool emit(uint32_t t, int cls);
  bool emit_vertex(uint32_t vslot, uint32_t sg);
  bool drain();
  uint32_t new_seg();
  void add_corner(uint32_t vslot, uint32_t e) {
    Vert& v = vpool[vslot];
    if (v.n_corners < kInlineCorners) {
      v.corner[v.n_corners] = e;
    } else {
      vert_spill[vslot].push_back(e);
    }
    ++v.n_corners;
  }
  // Calls f(corner) for the corners of vertex `vslot`, in input order.
  template <class F>
  void for_each_corner(uint32_t vslot, F f) {
    const Vert& v = vpool[vslot];
    const uint32_t n = std::min(v.n_corners, kInlineCorners);
    for (uint32_t i = 0; i < n; ++i) f(v.corner[i]);
    if (v.n_corners > kInlineCorners) {
      for (uint32_t e : vert_spill[vslot]) f(e);
    }
  }
  void clear_corners(uint32_t vslot) {
    Vert& v = vpool[vslot];
    if (v.n_corners > kInlineCorners) {
      std::vector<uint32_t>& spill = vert_spill[vslot];
      // A vertex of very high valence does not leave its list's memory to
      // the slot's later vertices.
      if (spill.capacity() > 1024) {
        std::vector<uint32_t>().swap(spill);
      } else {
        spill.clear();
      }
    }
    v.n_corners = 0;
  }
};

uint32_t SequenceConverter::Impl::new_seg() {
  uint32_t sg;
  if (!free_segs.empty()) {
    sg = free_segs.back();
    free_segs.pop_back();
    segs[sg] = Seg();
  } else {
    sg = static_cast<uint32_t>(segs.size());
    segs.emplace_back();
  }
  return sg;
}

// An id the waiting area does not hold is either new or was finalized.
bool SequenceConverter::Impl::check_unknown_id(uint32_t id) {
  if (id == kNone) return fail(Status(ErrorCode::kBadIndex, "vertex id 4294967295 is reserved"));
  if (finalized_ids.contains(id)) {
    return fail(Status(ErrorCode::kBadIndex, "vertex " + std::to_string(id) + " is used after its finalization"));
  }
  return true;
}

uint32_t SequenceConverter::Impl::vertex_slot(uint32_t id) {
  uint32_t slot;
  if (!free_verts.empty()) {
    slot = free_verts.back();
    free_verts.pop_back();
    if (!free_verts.empty()) {
      __builtin_prefetch(&vpool[free_verts.back()], 1);
      __builtin_prefetch(&vert_pos[free_verts.back()], 1);
    }
  } else {
    slot = static_cast<uint32_t>(vpool.size());
    grow_id_table(vpool.size() + 1);
    vpool.emplace_back();
    vert_pos.emplace_back();
    vert_spill.emplace_back();
  }
  vpool[slot].id = id;
  insert_id(id, slot);
  stats.max_waiting_vertices = std::max<uint64_t>(stats.max_waiting_vertices, live_ids);
  return slot;
}

void SequenceConverter::Impl::release_vertex(uint32_t slot) {
  Vert& v = vpool[slot];
  erase_id(v.id, slot);
  v.id = kNone;
  v.has_data = v.finalized = v.settled = false;
  if (v.has_values) {
    vert_values[slot].clear();
    v.has_values = false;
  }
  clear_corners(slot);
  v.waiting_neighbors = 0;
  v.first_dense = kNone;
  v.unemitted = 0;
  free_verts.push_back(slot);
}

SequenceConverter::SequenceConverter(SequenceSink* out) : impl_(std::make_unique<Impl>()) { impl_->out = out; }
SequenceConverter::~SequenceConverter() = default;

void SequenceConverter::set_lookahead_budget(uint64_t bytes) { impl_->lookahead_cap = bytes / kLookaheadBytes; }

// Growing the pools by doubling copies each one and touches about twice its
// final size in fresh pages, which on a mesh of a few hundred thousand
// triangles costs more than the pages themselves. Reserving touches
// nothing: the pages are faulted in as slots are used. The cap keeps the reservation (about 180
// bytes of address space a triangle, for the pools of a triangle and a
// vertex) within the lookahead's budget.
void SequenceConverter::reserve(uint64_t vertices, uint64_t triangles) {
  Impl& m = *impl_;
  const uint64_t cap = std::min<uint64_t>(std::max(m.lookahead_min, m.lookahead_cap), kMaxTriangles);
  const size_t nt = static_cast<size_t>(std::min(triangles, cap));
  const size_t nv = static_cast<size_t>(std::min(vertices, cap));
  m.tris.reserve(nt);
  m.vpool.reserve(nv);
  m.vert_pos.reserve(nv);
  m.vert_spill.reserve(nv);
  m.free_tris.reserve(nt);
  m.free_verts.reserve(nv);
}
void SequenceConverter::set_lookahead_minimum(uint64_t triangles) {
  impl_->lookahead_min = std::max<uint64_t>(1, triangles);
}
const ConverterStats& SequenceConverter::stats() const { return impl_->stats; }

// triangle() reads each corner's record (the id check, the corner list,
// the counters): a cache miss per corner on a large waiting area, unless
// requested ahead.
void SequenceConverter::prefetch(const uint32_t id[3]) const {
  const Impl& m = *impl_;
  for (int k = 0; k < 3; ++k) {
    const uint32_t slot = m.id_table[id[k] & (m.id_table.size() - 1)];
    if (slot != kNone) __builtin_prefetch(&m.vpool[slot], 1);
  }
}

// Every public call returns the first error again once there was one.
Status SequenceConverter::begin(const MeshSchema& schema) {
  Impl& m = *impl_;
  if (m.error.ok()) {
    Status s = m.out->begin(schema);
    if (s.ok()) return s;
    m.error = s;
  }
  return m.error;
}
Status SequenceConverter::vertex(uint32_t id, const double position[3], const PropertyValues& values) {
  Impl& m = *impl_;
  if (m.error.ok() && m.vertex(id, position, values)) return Status();
  return m.error;
}
Status SequenceConverter::triangle(const uint32_t id[3], const PropertyValues& values) {
  Impl& m = *impl_;
  if (m.error.ok() && m.triangle(id, values)) return Status();
  return m.error;
}
Status SequenceConverter::finalize(uint32_t id) {
  Impl& m = *impl_;
  if (m.error.ok() && m.finalize(id)) return Status();
  return m.error;
}
Status SequenceConverter::finish() {
  Impl& m = *impl_;
  if (m.error.ok() && m.finish()) return Status();
  return m.error;
}

bool SequenceConverter::Impl::vertex(uint32_t id, const double position[3], const PropertyValues& values) {
  uint32_t slot = find_slot(id);
  if (slot == kNone) {
    if (!check_unknown_id(id)) return false;
    slot = vertex_slot(id);
  }
  Vert& v = vpool[slot];
  if (v.has_data || v.finalized) return fail(Status(ErrorCode::kBadIndex, "vertex " + std::to_string(id) + " given twice"));
  v.has_data = true;
  vert_pos[slot] = {position[0], position[1], position[2]};
  if (!values.empty()) {
    if (vert_values.size() < vpool.size()) vert_values.resize(vpool.size());
    vert_values[slot] = values;
    v.has_values = true;
  }
  ++stats.vertices_in;
  return true;
}

bool SequenceConverter::Impl::triangle(const uint32_t id[3], const PropertyValues& values) {
  ++stats.triangles_in;
  uint32_t vs[3];
  for (int k = 0; k < 3; ++k) {
    vs[k] = find_slot(id[k]);
    if (vs[k] == kNone) {
      if (!check_unknown_id(id[k])) return false;
    } else if (vpool[vs[k]].finalized) {
      return fail(Status(ErrorCode::kBadIndex, "a triangle uses vertex " + std::to_string(id[k]) + " after its finalization"));
    }
  }
  if (id[0] == id[1] || id[1] == id[2] || id[2] == id[0]) {
    ++stats.degenerate_dropped;
    return true;
  }
  for (int k = 0; k < 3; ++k) {
    if (vs[k] == kNone) vs[k] = vertex_slot(id[k]);
  }
  uint32_t slot;
  if (!free_tris.empty()) {
    slot = free_tris.back();
    free_tris.pop_back();
    // The next triangle takes the next free slot: a line last touched
    // long ago.
    if (!free_tris.empty()) __builtin_prefetch(&tris[free_tris.back()], 1);
  } else {
    if (tris.size() >= kMaxTriangles) return fail(Status(ErrorCode::kLimit, "more than 2^30 triangles waiting"));
    slot = static_cast<uint32_t>(tris.size());
    tris.emplace_back();
  }
  Tri& t = tris[slot];
  t.reset();
  for (uint32_t k = 0; k < 3; ++k) {
    t.vs[k] = vs[k];
    add_corner(vs[k], slot * 4 + k);
    ++vpool[vs[k]].unemitted;
  }
  if (!values.empty()) {
    if (tri_values.size() < tris.size()) tri_values.resize(tris.size());
    tri_values[slot] = values;
    t.state |= Tri::kHasValues;
  }
  ++waiting;
  if (waiting > stats.max_waiting_triangles) stats.max_waiting_triangles = waiting;
  return true;
}

// For vertex `vslot`, being finalized (so all its triangles are in): visits
// its neighbours in the order they first appear (triangles in input order,
// corners in corner order). A finalized neighbour decided the edge between
// them already and waits for one neighbour less: if for none now, it goes on
// `to_settle`. The edges to the others are decided now, after grouping the
// triangles by neighbour: a link between the two triangles of a manifold
// edge, a cut on every triangle of a non-manifold one, or a border. Returns
// whether any edge at the vertex is non-manifold; counts the neighbours not
// finalized into *waiting_neighbors.
bool SequenceConverter::Impl::decide_spokes(uint32_t vslot, uint32_t* waiting_neighbors) {
  const uint32_t stamp = ++visit_stamp;
  n_spokes = 0;
  uint32_t waiting_nb = 0;
  uint8_t nm = 0;
  auto side = [&](uint32_t ws, bool outgoing, uint32_t edge) {
    Vert& w = vpool[ws];
    if (w.stamp != stamp) {
      w.stamp = stamp;
      if (w.finalized) {
        if (!w.settled && --w.waiting_neighbors == 0) to_settle.push_back(ws);
        return;
      }
      ++waiting_nb;
      if (n_spokes == spokes.size()) spokes.resize(2 * spokes.size() + 16);
      w.spoke = n_spokes;
      spokes[n_spokes++] = Spoke{kNone, kNone, 0, 0, false};
    } else if (w.finalized) {
      return;
    }
    Spoke& sp = spokes[w.spoke];
    if (outgoing) {
      if (sp.n_out++ == 0) sp.out_edge = edge;
    } else {
      if (sp.n_in++ == 0) sp.in_edge = edge;
    }
  };
  // In passes, so that the cache misses of one pass overlap instead of
  // waiting one behind the other: the triangles are requested, then read
  // (their neighbours' records requested), then the spokes grouped.
  for_each_corner(vslot, [&](uint32_t e) { __builtin_prefetch(&tris[e >> 2]); });
  const uint32_t n_sides = 2 * vpool[vslot].n_corners;
  if (sides.size() < n_sides) sides.resize(n_sides);
  uint32_t n = 0;
  auto add_side = [&](uint32_t ws, bool outgoing, uint32_t edge) {
    __builtin_prefetch(&vpool[ws], 1);
    sides[n++] = Side{ws, edge, outgoing};
  };
  for_each_corner(vslot, [&](uint32_t e) {
    const Tri& t = tris[e >> 2];
    const uint32_t base = e & ~3u;
    nm |= t.nm_mask & kEdgesAt[e & 3];
    switch (e & 3) {
      case 0:
        add_side(t.vs[1], true, base | 0);
        add_side(t.vs[2], false, base | 2);
        break;
      case 1:
        add_side(t.vs[0], false, base | 0);
        add_side(t.vs[2], true, base | 1);
        break;
      default:
        add_side(t.vs[0], true, base | 2);
        add_side(t.vs[1], false, base | 1);
        break;
    }
  });
  for (uint32_t i = 0; i < n_sides; ++i) side(sides[i].ws, sides[i].outgoing, sides[i].edge);
  *waiting_neighbors = waiting_nb;
  bool any_cut = false;
  for (uint32_t i = 0; i < n_spokes; ++i) {
    Spoke& sp = spokes[i];
    if (sp.n_out == 1 && sp.n_in == 1) {
      tris[sp.out_edge >> 2].partner[sp.out_edge & 3] = sp.in_edge;
      tris[sp.in_edge >> 2].partner[sp.in_edge & 3] = sp.out_edge;
    } else if (sp.n_out + sp.n_in == 1) {
      ++stats.border_edges;
    } else {
      sp.cut = any_cut = true;
      if (sp.n_out + sp.n_in > 2) {
        ++stats.nonmanifold_edges;
      } else {
        ++stats.misoriented_edges;
      }
    }
  }
  if (!any_cut) return nm != 0;
  for_each_corner(vslot, [&](uint32_t e) {
    Tri& t = tris[e >> 2];
    uint32_t c = e & 3;
    const Vert& wn = vpool[t.vs[kNext[c]]];
    const Vert& wp = vpool[t.vs[kPrev[c]]];
    if (!wn.finalized && spokes[wn.spoke].cut) {
      t.cut_mask |= static_cast<uint8_t>(1u << c);
      t.nm_mask |= static_cast<uint8_t>(1u << c);
    }
    if (!wp.finalized && spokes[wp.spoke].cut) {
      t.cut_mask |= static_cast<uint8_t>(1u << kPrev[c]);
      t.nm_mask |= static_cast<uint8_t>(1u << kPrev[c]);
    }
  });
  return true;
}

// Cuts the link across edge `edge` of triangle `t` on both of its triangles.
void SequenceConverter::Impl::break_link(uint32_t t, uint32_t edge) {
  uint32_t p = tris[t].partner[edge];
  Tri& pt = tris[p >> 2];
  pt.partner[p & 3] = kNone;
  pt.cut_mask |= static_cast<uint8_t>(1u << (p & 3));
  tris[t].partner[edge] = kNone;
  tris[t].cut_mask |= static_cast<uint8_t>(1u << edge);
}

// At finalization, after decide_spokes found a non-manifold spoke: walk each
// fan and break links so that no fan holds two triangles that share a
// non-manifold spoke; otherwise both would use the same edge of the sequence.
void SequenceConverter::Impl::split_fans(uint32_t vslot) {
  fan_corners.clear();
  for_each_corner(vslot, [&](uint32_t e) { fan_corners.push_back(e); });
  const std::vector<uint32_t>& corners = fan_corners;
  size_t n = corners.size();
  if (local_of.size() < tris.size()) local_of.resize(tris.size());
  if (seen.size() < vpool.size()) seen.resize(vpool.size(), 0);
  for (size_t i = 0; i < n; ++i) local_of[corners[i] >> 2] = static_cast<uint32_t>(i);
  // Per local triangle: the triangle linked through its out- (0) and in-spoke (1).
  fan_next.assign(n, {-1, -1});
  for (size_t i = 0; i < n; ++i) {
    const Tri& t = tris[corners[i] >> 2];
    uint32_t c = corners[i] & 3;
    uint32_t po = t.partner[c], pi = t.partner[kPrev[c]];
    if (po != kNone) fan_next[i][0] = static_cast<int>(local_of[po >> 2]);
    if (pi != kNone) fan_next[i][1] = static_cast<int>(local_of[pi >> 2]);
  }
  // The neighbour across side sl (0: out, 1: in) of local triangle i, if
  // that spoke is non-manifold, else kNone.
  auto nm_neighbour = [&](size_t i, int sl) -> uint32_t {
    const Tri& t = tris[corners[i] >> 2];
    uint32_t c = corners[i] & 3;
    uint32_t edge = sl == 0 ? c : kPrev[c];
    if (!((t.nm_mask >> edge) & 1)) return kNone;
    return t.vs[sl == 0 ? kNext[c] : kPrev[c]];
  };
  visited.assign(n, 0);
  auto walk = [&](int start) {
    int prev = -1, cur = start;
    ++seen_stamp;  // the neighbours of non-manifold spokes seen since the last break
    while (cur >= 0 && !visited[cur]) {
      visited[cur] = 1;
      bool clash = false;
      for (int sl = 0; sl < 2; ++sl) {
        uint32_t w = nm_neighbour(cur, sl);
        if (w != kNone && seen[w] == seen_stamp) clash = true;
      }
      if (clash && prev >= 0) {
        // Break the link between prev and cur: it runs through their shared spoke.
        uint32_t e = corners[cur];
        uint32_t c = e & 3;
        for (int sl = 0; sl < 2; ++sl) {
          if (fan_next[cur][sl] == prev) break_link(e >> 2, sl == 0 ? c : kPrev[c]);
        }
        ++seen_stamp;
      }
      for (int sl = 0; sl < 2; ++sl) {
        uint32_t w = nm_neighbour(cur, sl);
        if (w != kNone) seen[w] = seen_stamp;
      }
      int nxt = -1;
      for (int sl = 0; sl < 2; ++sl) {
        int x = fan_next[cur][sl];
        if (x >= 0 && x != prev && !visited[x]) nxt = x;
      }
      prev = cur;
      cur = nxt;
    }
  };
  // Paths first, from their ends; whatever is left are closed fans, which
  // have no non-manifold spoke.
  for (size_t i = 0; i < n; ++i) {
    if (!visited[i] && (fan_next[i][0] < 0 || fan_next[i][1] < 0)) walk(static_cast<int>(i));
  }
}

bool SequenceConverter::Impl::finalize(uint32_t id) {
  uint32_t slot = find_slot(id);
  if (slot == kNone || vpool[slot].finalized) {
    bool twice = slot != kNone || (id != kNone && finalized_ids.contains(id));
    return fail(Status(ErrorCode::kBadIndex,
                       "vertex " + std::to_string(id) + (twice ? " finalized twice" : " finalized but never given")));
  }
  // Coherent input is finalized in increasing id order (build_sequence's
  // one pass), and a finalization waits on cache misses: the vertex, its
  // corners' triangles and its neighbours. Start loading those of later
  // ids in stages, each stage reading only lines an earlier stage asked
  // for: the vertex 12 ids on, the triangles of the one 6 on, and those
  // triangles' vertices for the one 3 on. Hints only: nothing changes.
  // Only while the ids come in order (not on the sort path's order, where
  // the lookups would be wasted).
  if (id == last_finalized + 1) {
    const uint32_t far = find_slot(id + 12);
    if (far != kNone) __builtin_prefetch(&vpool[far]);
    const uint32_t mid = find_slot(id + 6);
    if (mid != kNone) {
      const Vert& m = vpool[mid];
      for (uint32_t k = 0; k < std::min(m.n_corners, kInlineCorners); ++k) __builtin_prefetch(&tris[m.corner[k] >> 2]);
    }
    const uint32_t near = find_slot(id + 3);
    if (near != kNone) {
      const Vert& n = vpool[near];
      for (uint32_t k = 0; k < std::min(n.n_corners, kInlineCorners); ++k) {
        const Tri& t = tris[n.corner[k] >> 2];
        for (int j = 0; j < 3; ++j) __builtin_prefetch(&vpool[t.vs[j]]);
      }
    }
  }
  last_finalized = id;
  Vert& v = vpool[slot];
  if (!v.has_data) return fail(Status(ErrorCode::kBadIndex, "vertex " + std::to_string(id) + " is used but was never given"));
  finalized_ids.insert(id);
  // Neighbours that waited only for this vertex go on to_settle.
  to_settle.clear();
  uint32_t waiting_nb;
  if (decide_spokes(slot, &waiting_nb)) split_fans(slot);
  v.finalized = true;
  v.waiting_neighbors = waiting_nb;
  if (waiting_nb == 0) to_settle.push_back(slot);
  for (uint32_t u : to_settle) {
    if (!settle(u)) return false;
  }
  return drain();
}

// Emits the dense vertex of fan `sg` of vertex `vslot`.
bool SequenceConverter::Impl::emit_vertex(uint32_t vslot, uint32_t sg) {
  Vert& v = vpool[vslot];
  sv.index = next_dense++;
  sv.slot = sg;
  sv.reappears = v.first_dense;
  if (v.first_dense == kNone) v.first_dense = sv.index;
  const std::array<double, 3>& pos = vert_pos[vslot];
  sv.position[0] = pos[0];
  sv.position[1] = pos[1];
  sv.position[2] = pos[2];
  // Lent to the sink, and back.
  if (v.has_values) sv.values.swap(vert_values[vslot]);
  Status s = out->vertex(sv);
  if (v.has_values) sv.values.swap(vert_values[vslot]);
  return s.ok() || fail(std::move(s));
}

// Every neighbour is finalized, so every edge around the vertex is decided:
// its fans (triangles connected through links) become its segments.
bool SequenceConverter::Impl::settle(uint32_t vslot) {
  Vert& v = vpool[vslot];
  v.settled = true;
  if (v.n_corners == 0) {
    // An isolated vertex: introduced and finalized with no triangle. It
    // takes a slot like any vertex (free again at once).
    uint32_t sg = new_seg();
    free_segs.push_back(sg);
    if (!emit_vertex(vslot, sg)) return false;
    Status s = out->finalize(sv.index);
    if (!s.ok()) return fail(std::move(s));
    release_vertex(vslot);
    return true;
  }
  // The corners' triangles are all read below: request them at once.
  for_each_corner(vslot, [&](uint32_t e) { __builtin_prefetch(&tris[e >> 2], 1); });
  // One segment per fan. A fan is a path or a cycle of triangles linked
  // across the vertex's edges: walk it from its first triangle forwards (out
  // edges) and, unless it closed, backwards (in edges). Across an out-edge
  // the vertex is the partner's corner after the shared edge's start; across
  // an in-edge it is that edge's start.
  uint32_t fans = 0;
  for_each_corner(vslot, [&](uint32_t start) {
    Tri& t0 = tris[start >> 2];
    if (t0.seg[start & 3] != kNone) return;
    uint32_t sg = new_seg();
    ++fans;
    t0.seg[start & 3] = sg;
    uint32_t count = 1;
    bool closed = false;
    for (uint32_t e = start;;) {
      uint32_t p = tris[e >> 2].partner[e & 3];
      if (p == kNone) break;
      e = (p & ~3u) | kNext[p & 3];
      if (e == start) {
        closed = true;
        break;
      }
      tris[e >> 2].seg[e & 3] = sg;
      ++count;
    }
    if (!closed) {
      for (uint32_t e = start;;) {
        uint32_t p = tris[e >> 2].partner[kPrev[e & 3]];
        if (p == kNone) break;
        e = p;
        tris[e >> 2].seg[e & 3] = sg;
        ++count;
      }
    }
    segs[sg].remaining = count;
  });
  // The triangles settled now are classified: request their fans first.
  n_now_ready = 0;
  if (now_ready.size() < v.n_corners) now_ready.resize(v.n_corners);
  for_each_corner(vslot, [&](uint32_t e) {
    Tri& t = tris[e >> 2];
    if ((++t.state & Tri::kSettledMask) == 3) {
      prefetch_segs(t);
      now_ready[n_now_ready++] = e >> 2;
    }
  });
  for (uint32_t i = 0; i < n_now_ready; ++i) make_ready(now_ready[i]);
  clear_corners(vslot);
  if (fans > 1) ++stats.nonmanifold_vertices;
  return true;
}

void SequenceConverter::Impl::make_ready(uint32_t slot) {
  Tri& t = tris[slot];
  t.state |= Tri::kReady;
  ++ready;
  int c = classify(t);
  if (c >= 0 && c < 4) {
    arrived[c].push(slot);
    // Most arrivals are emitted from elsewhere (as a neighbour, or from
    // buckets, where an emission that changes a triangle's op puts it):
    // drop such entries now and then, so that these queues stay
    // proportional to the waiting area.
    SlotQueue& q = arrived[c];
    if (q.size() > 2 * ready + 4096) {
      q.filter(
          [&](uint32_t x) {
            const Tri& tx = tris[x];
            return !tx.emitted() && tx.ready() && classify(tx) == c;
          },
          [&](uint32_t x) { __builtin_prefetch(&tris[x]); }, [&](uint32_t x) { prefetch_segs(tris[x]); });
    }
  } else if (c == 4) {
    // A triangle that is no start candidate now never becomes one (it
    // touches an emitted fan, and fans only get emitted).
    starts.push(slot);
    // Entries of triangles that growth reached instead stay until a start
    // is needed, which coherent input rarely needs: drop them now and then
    // so that the queue stays proportional to the waiting area.
    if (starts.size() > 2 * ready + 4096) {
      starts.filter(
          [&](uint32_t x) {
            const Tri& tx = tris[x];
            return !tx.emitted() && tx.ready() && classify(tx) == 4;
          },
          [&](uint32_t x) { __builtin_prefetch(&tris[x]); }, [&](uint32_t x) { prefetch_segs(tris[x]); });
    }
  }
}

// 0 end, 1 fill, 2 join, 3 add, 4 start, -1 not emittable now.
int SequenceConverter::Impl::classify(const Tri& t) const {
  int completed = t.completed();
  if (completed >= 2) return 3 - completed;
  int fresh = (segs[t.seg[0]].dense == kNone) + (segs[t.seg[1]].dense == kNone) + (segs[t.seg[2]].dense == kNone);
  if (completed == 1) return fresh == 0 ? 2 : 3;
  return fresh == 3 ? 4 : -1;
}

bool SequenceConverter::Impl::emit(uint32_t slot, int cls) {
  static const Op kOps[] = {Op::kEnd, Op::kFill, Op::kJoin, Op::kAdd, Op::kStart};
  Tri& t = tris[slot];
  if (cls < 0) return fail(Status(ErrorCode::kInternal, "converter emitted a triangle that is none of the five ops"));
  st.op = kOps[cls];
  // The partners across this triangle's edges are marked below, after the
  // sink's work on the triangle, and its vertices' records, positions and
  // fans are read and updated: start loading all their cache lines now,
  // so that the misses overlap (most of emit()'s time went to those loads).
  for (uint32_t k = 0; k < 3; ++k) {
    if (t.partner[k] != kNone) __builtin_prefetch(&tris[t.partner[k] >> 2], 1);
    __builtin_prefetch(&segs[t.seg[k]], 1);
    __builtin_prefetch(&vpool[t.vs[k]], 1);
    __builtin_prefetch(&vert_pos[t.vs[k]]);
  }
  uint32_t new_mask = 0, final_mask = 0, border_mask = 0, nonmanifold_mask = 0, leaving_mask = 0, entering_mask = 0;
  for (uint32_t k = 0; k < 3; ++k) {
    Seg& s = segs[t.seg[k]];
    if (s.dense == kNone) {
      if (!emit_vertex(t.vs[k], t.seg[k])) return false;
      s.dense = sv.index;
      new_mask |= 1u << k;
    }
    st.v[k] = s.dense;
    st.vslot[k] = t.seg[k];
    if (s.remaining == 1) final_mask |= 1u << k;
  }
  for (uint32_t k = 0; k < 3; ++k) {
    uint32_t bit = 1u << k;
    if (t.partner[k] == kNone) {
      border_mask |= bit;
      nonmanifold_mask |= t.cut_mask & bit;
      st.eslot[k] = kNone;
    } else if (t.done_mask & bit) {
      leaving_mask |= bit;
      st.eslot[k] = t.eslot[k];
    } else {
      entering_mask |= bit;
      if (!free_edge_slots.empty()) {
        st.eslot[k] = free_edge_slots.back();
        free_edge_slots.pop_back();
      } else {
        st.eslot[k] = edge_slots++;
      }
    }
  }
  st.new_mask = static_cast<uint8_t>(new_mask);
  st.final_mask = static_cast<uint8_t>(final_mask);
  st.border_mask = static_cast<uint8_t>(border_mask);
  st.nonmanifold_mask = static_cast<uint8_t>(nonmanifold_mask);
  st.leaving_mask = static_cast<uint8_t>(leaving_mask);
  st.entering_mask = static_cast<uint8_t>(entering_mask);
  if (t.state & Tri::kHasValues) {
    st.values.swap(tri_values[slot]);
  } else {
    st.values.clear();
  }
  {
    Status s = out->triangle(st);
    if (!s.ok()) return fail(std::move(s));
  }
  if (t.state & Tri::kHasValues) {
    st.values.swap(tri_values[slot]);
    tri_values[slot].clear();
  }
  t.state |= Tri::kEmitted;
  // The next triangle should continue here (drain()): the neighbours across
  // this one's entering edges, starting after its first leaving edge (the
  // reference edge of the .psq gate coder, spec/psq-format.md 6.1.2 step 5).
  {
    int g = 2;  // a start has no leaving edge: edge 0 first
    for (int k = 2; k >= 0; --k)
      if (leaving_mask & (1u << k)) g = k;
    int n = 0;
    for (int i = 1; i <= 3; ++i) {
      const int k = (g + i) % 3;
      if (entering_mask & (1u << k)) prefer[n++] = t.partner[k] >> 2;
    }
    for (; n < 3; ++n) prefer[n] = kNone;
  }
  // Tell unemitted partners that their edge is now on the boundary.
  for (uint32_t k = 0; k < 3; ++k) {
    if (!(entering_mask & (1u << k))) continue;
    uint32_t p = t.partner[k];
    Tri& pt = tris[p >> 2];
    pt.done_mask |= static_cast<uint8_t>(1u << (p & 3));
    pt.eslot[p & 3] = st.eslot[k];
    // The next triangle is most often one of these (prefer): the only
    // vertex it may introduce is the one off the shared edge, whose record
    // and position emit_vertex() reads. Request them now, a whole sink
    // call ahead.
    const uint32_t off = pt.vs[kPrev[p & 3]];
    __builtin_prefetch(&vpool[off], 1);
    __builtin_prefetch(&vert_pos[off]);
    // ... and its own partners, whose lines its emission writes first.
    for (uint32_t j = 0; j < 3; ++j)
      if (j != (p & 3) && pt.partner[j] != kNone) __builtin_prefetch(&tris[pt.partner[j] >> 2], 1);
    if (pt.ready()) {
      int c = classify(pt);
      if (c >= 0 && c < 4) buckets[c].push(p >> 2);
    }
  }
  // Edges this triangle completed leave the boundary: their slots are free.
  for (uint32_t k = 0; k < 3; ++k) {
    if (leaving_mask & (1u << k)) free_edge_slots.push_back(st.eslot[k]);
  }
  // Finalize fans that this triangle completes; forget finished vertices.
  for (uint32_t k = 0; k < 3; ++k) {
    Seg& s = segs[t.seg[k]];
    if (--s.remaining == 0) {
      Status st_f = out->finalize(s.dense);
      if (!st_f.ok()) return fail(std::move(st_f));
      free_segs.push_back(t.seg[k]);
    }
    Vert& v = vpool[t.vs[k]];
    if (--v.unemitted == 0 && v.settled) release_vertex(t.vs[k]);
  }
  --waiting;
  --ready;
  free_tris.push_back(slot);
  return true;
}

bool SequenceConverter::Impl::drain() {
  for (;;) {
    if (!finishing) {
      const uint64_t open_edges = edge_slots - free_edge_slots.size();
      const uint64_t lookahead = std::max(lookahead_min, std::min(lookahead_cap, kLookaheadPerEdge * open_edges));
      if (ready < lookahead) return true;
    }
    bool emitted = false;
    // Locality first (it keeps the boundary short and the .psq gate codes
    // cheap): a neighbour of the last triangle, unless a better op waits
    // next to the grown regions (an end or fill before a join or add).
    // Better ops that arrived elsewhere do not count: following them makes
    // the region hop along the front of a sweep, with many more far gates
    // (bench/HISTORY.md, "Converter lookahead").
    for (int i = 0; i < 3 && !emitted; ++i) {
      const uint32_t slot = prefer[i];
      if (slot == kNone) continue;
      const Tri& t = tris[slot];
      if (t.emitted() || !t.ready()) continue;
      const int c = classify(t);
      if (c < 0 || c > 3) continue;
      bool better = false;
      for (int b = 0; b < c && b < 2; ++b) better = better || !buckets[b].empty();
      if (better) continue;
      if (!emit(slot, c)) return false;
      emitted = true;
    }
    if (emitted) continue;
    // Then the newest candidate of the best op (depth first: the region
    // grows in a spiral instead of jumping along the whole boundary), next
    // to the grown regions before those that arrived elsewhere.
    for (int i = 0; i < 8 && !emitted; ++i) {
      const int b = i % 4;
      SlotQueue& queue = i < 4 ? buckets[b] : arrived[b];
      while (!queue.empty()) {
        uint32_t slot = queue.pop_newest();
        const Tri& t = tris[slot];
        if (t.emitted() || !t.ready()) continue;  // stale entry (slots are reused only after emission)
        int c = classify(t);
        if (c != b) {
          if (c >= 0 && c < 4) buckets[c].push(slot);
          continue;
        }
        if (!emit(slot, c)) return false;
        emitted = true;
        break;
      }
    }
    if (emitted) continue;
    // Nothing adjacent to the boundary: start a new region (the lookahead
    // is full, or the input ended).
    while (!starts.empty()) {
      uint32_t slot = starts.pop();
      const Tri& t = tris[slot];
      if (t.emitted() || !t.ready()) continue;
      if (classify(t) == 4) {
        if (!emit(slot, 4)) return false;
        emitted = true;
        break;
      }
    }
    if (!emitted) return true;
  }
}

bool SequenceConverter::Impl::finish() {
  finishing = true;
  // Finalize what the caller left open (a source that finalizes nothing
  // leaves the whole mesh to this point).
  std::vector<uint32_t> open;
  for (const Vert& v : vpool)
    if (v.id != kNone && !v.finalized) open.push_back(v.id);
  std::sort(open.begin(), open.end());
  for (uint32_t id : open) {
    if (!finalize(id)) return false;
  }
  if (!drain()) return false;
  if (waiting != 0 || live_ids != 0) {
    return fail(Status(ErrorCode::kInternal, std::to_string(waiting) + " triangles left in the waiting area"));
  }
  Status s = out->finish();
  return s.ok() || fail(std::move(s));
}

}  // namespace psq
