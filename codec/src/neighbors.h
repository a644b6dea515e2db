// SPDX-License-Identifier: Apache-2.0
// codec/src/neighbors.h: which active vertices are joined by an edge, for
// the new-edge check (spec 13.6.3).
//
// The decoder is told which open edges a triangle completes; every other
// edge between two old vertices must be new to the mesh, or the decoded
// sequence would not be an oriented manifold with borders (psq/sequence.h,
// spec A.2). The encoder asks the same to tell such an edge from a dead
// one (a border, or an edge two triangles completed). Here each vertex
// slot lists the neighbours its vertex has had (a slot and that slot's
// generation): two appends per new edge, a scan of one short list per
// edge between old vertices (a fill has one), and nothing when a vertex
// is finalized. A neighbour finalized since is stale (its slot's generation
// moved on) and never matches; a slot's list is cleared when a new vertex
// takes the slot, a full slot drops its stale entries before its list
// spills out of it, and a long list drops them before it grows,
// so that a vertex that stays active while many neighbours come and go
// (the centre of a large fan) lists about as many as are active: the
// lists' size follows the boundary, not the mesh.
#ifndef PSQ_CODEC_NEIGHBORS_H_
#define PSQ_CODEC_NEIGHBORS_H_

#include <algorithm>
#include <cstdint>
#include <utility>
#include <vector>

namespace psq {
namespace codec {

class Neighbors {
 public:
  // Room for `n` slots without moving the array (nothing is touched).
  void reserve(uint32_t n) { slots_.reserve(n); }
  // Empty, as a new one, but keeping the array's room: a segment restart
  // (spec 4.6) fills about as many slots again, and a fresh array would
  // grow by doubling and copying, beside the old one until it is freed.
  void reset() {
    slots_.clear();
    spill_.clear();
  }
  // Vertex slot `s` now holds a new vertex, with no neighbours yet.
  void vertex_begins(uint32_t s) {
    if (s >= slots_.size()) grow(s);
    Slot& v = slots_[s];
    ++v.gen;
    if (v.count > kInline) spill_[s].clear();
    v.count = 0;
  }
  // An edge joins the vertices in slots a and b.
  __attribute__((always_inline)) void insert(uint32_t a, uint32_t b) {
    Slot* slots = slots_.data();
    Slot& va = slots[a];
    Slot& vb = slots[b];
    const uint64_t ea = uint64_t{a} << 32 | va.gen, eb = uint64_t{b} << 32 | vb.gen;
    if (va.count < kInline) va.e[va.count++] = eb;
    else spill(a, eb);
    if (vb.count < kInline) vb.e[vb.count++] = ea;
    else spill(b, ea);
  }
  // vertex_begins(s), insert(p, s) and insert(s, q) in one step: an add's
  // new vertex and its two edges (the same lists, with less work).
  __attribute__((always_inline)) void add_vertex(uint32_t s, uint32_t p, uint32_t q) {
    vertex_begins(s);
    Slot* slots = slots_.data();
    Slot& vs = slots[s];
    vs.e[0] = uint64_t{p} << 32 | slots[p].gen;
    vs.e[1] = uint64_t{q} << 32 | slots[q].gen;
    vs.count = 2;
    const uint64_t es = uint64_t{s} << 32 | vs.gen;
    Slot& vp = slots[p];
    if (vp.count < kInline) vp.e[vp.count++] = es;
    else spill(p, es);
    Slot& vq = slots[q];
    if (vq.count < kInline) vq.e[vq.count++] = es;
    else spill(q, es);
  }
  // Calls f(b) for each neighbour slot b that slot `s` lists with b's
  // current generation (a neighbour whose vertex was finalized and whose
  // slot no new vertex took since is among them: the caller tells).
  template <class F>
  void for_each_current(uint32_t s, F f) const {
    if (s >= slots_.size()) return;
    const Slot& v = slots_[s];
    auto visit = [&](uint64_t x) {
      const uint32_t b = static_cast<uint32_t>(x >> 32);
      if (slots_[b].gen == static_cast<uint32_t>(x)) f(b);
    };
    const uint32_t n = v.count < kInline ? v.count : kInline;
    for (uint32_t i = 0; i < n; ++i) visit(v.e[i]);
    if (v.count > kInline)
      for (uint64_t x : spill_[s]) visit(x);
  }
  // How many neighbours slot `s` lists, stale ones included (for tests).
  uint32_t listed(uint32_t s) const { return s < slots_.size() ? slots_[s].count : 0; }
  // Whether an edge joins the vertices now in slots a and b.
  __attribute__((always_inline)) bool contains(uint32_t a, uint32_t b) const {
    // Scan the shorter list for the other vertex as it is now.
    if (slots_[b].count < slots_[a].count) std::swap(a, b);
    const Slot& va = slots_[a];
    const uint64_t want = uint64_t{b} << 32 | slots_[b].gen;
    const uint32_t n = va.count < kInline ? va.count : kInline;
    for (uint32_t i = 0; i < n; ++i)
      if (va.e[i] == want) return true;
    if (va.count > kInline)
      for (uint64_t x : spill_[a])
        if (x == want) return true;
    return false;
  }

 private:
  // Most active vertices have at most this many neighbours: they live in
  // the slot; the rest of a longer list spills into a vector. Seven make a
  // slot of 64 bytes, a cache line's size: a larger slot decodes much
  // slower, and a smaller one spills too often (bench/HISTORY.md, "The fast
  // decoder's loop and its pages").
  static constexpr uint32_t kInline = 7;

  struct Slot {
    Slot() {}  // not zero-filled as it would be without: e[] is read below count only
    uint32_t gen = 0;    // bumped when a new vertex takes the slot
    uint32_t count = 0;  // neighbours listed
    uint64_t e[kInline];  // the first ones: slot << 32 | that slot's generation then
  };

  __attribute__((noinline)) void spill(uint32_t s, uint64_t entry) {
    Slot& slot = slots_[s];
    if (slot.count == kInline) {
      // The slot is full and nothing has spilled yet: first drop the
      // neighbours finalized since they were listed (the earlier vertices
      // of a fan, mostly), which never match, and keep the entry inline
      // when that makes room.
      uint32_t n = 0;
      for (uint32_t i = 0; i < kInline; ++i)
        if (slots_[slot.e[i] >> 32].gen == static_cast<uint32_t>(slot.e[i])) slot.e[n++] = slot.e[i];
      if (n < kInline) {
        slot.e[n++] = entry;
        slot.count = n;
        return;
      }
    }
    if (s >= spill_.size()) spill_.resize(slots_.size());
    std::vector<uint64_t>& v = spill_[s];
    if (v.size() == v.capacity() && v.size() >= 16) {
      // Before the list grows, drop the neighbours finalized since they
      // were listed. When that frees less than half, the capacity doubles
      // as well, so that the next scan waits for as many new entries as
      // this one read: every scan is paid for by the pushes before it.
      const Slot* slots = slots_.data();
      v.erase(std::remove_if(v.begin(), v.end(),
                             [slots](uint64_t x) { return slots[x >> 32].gen != static_cast<uint32_t>(x); }),
              v.end());
      if (v.size() > v.capacity() / 2) v.reserve(2 * v.capacity());
    }
    v.push_back(entry);
    slots_[s].count = kInline + static_cast<uint32_t>(v.size());
  }
  // Slots are handed out in order, so within the reserved capacity the
  // array grows by the slot asked for (touching no page ahead of need);
  // beyond it, geometrically.
  __attribute__((noinline)) void grow(uint32_t s) {
    const size_t want = size_t{s} + 1;
    slots_.resize(want <= slots_.capacity() ? want : std::max(want, 2 * slots_.size()));
  }

  std::vector<Slot> slots_;
  std::vector<std::vector<uint64_t>> spill_;  // per slot: entries beyond kInline
};

}  // namespace codec
}  // namespace psq

#endif  // PSQ_CODEC_NEIGHBORS_H_
