// codec/src/neighbors.h: which active vertices are joined by an edge, for
// the fast profile's decoder (spec/fast-profile-draft.md, section 3).
//
// The fast decoder is told which open edges a triangle completes; every
// other edge between two old vertices must be new to the mesh, or the
// decoded sequence would not be an oriented manifold with borders
// (psq/sequence.h, spec 6.1.3). Format 7's boundary answers that with
// per-vertex lists of open edges and dead-edge records, which its decoder
// keeps up to date at every completion and finalization. Here each vertex
// slot lists the neighbours its vertex has had (a slot and that slot's
// generation): two appends per new edge, a scan of one short list per edge
// between old vertices (a fill has one), and nothing when a vertex is
// finalized. A neighbour finalized since is stale (its slot's generation
// moved on) and never matches; a slot's list is cleared when a new vertex
// takes the slot. The lists hold the edges of active vertices only: their
// size follows the boundary.
#ifndef PSQ_CODEC_NEIGHBORS_H_
#define PSQ_CODEC_NEIGHBORS_H_

#include <cstdint>
#include <vector>

namespace psq {
namespace codec {

class Neighbors {
 public:
  // Vertex slot `s` now holds a new vertex, with no neighbours yet.
  void vertex_begins(uint32_t s) {
    if (s >= slots_.size()) slots_.resize(s + 1 > 2 * slots_.size() ? s + 1 : 2 * slots_.size());
    Slot& v = slots_[s];
    ++v.gen;
    v.list.clear();
  }
  // An edge joins the vertices in slots a and b.
  void insert(uint32_t a, uint32_t b) {
    Slot& va = slots_[a];
    Slot& vb = slots_[b];
    va.list.push_back(uint64_t{b} << 32 | vb.gen);
    vb.list.push_back(uint64_t{a} << 32 | va.gen);
  }
  // Whether an edge joins the vertices now in slots a and b.
  bool contains(uint32_t a, uint32_t b) const {
    const Slot& va = slots_[a];
    const Slot& vb = slots_[b];
    const std::vector<uint64_t>& list = va.list.size() <= vb.list.size() ? va.list : vb.list;
    const uint64_t want = va.list.size() <= vb.list.size() ? (uint64_t{b} << 32 | vb.gen) : (uint64_t{a} << 32 | va.gen);
    for (uint64_t x : list)
      if (x == want) return true;
    return false;
  }

 private:
  struct Slot {
    uint32_t gen = 0;
    std::vector<uint64_t> list;  // neighbours: slot << 32 | that slot's generation then
  };
  std::vector<Slot> slots_;
};

}  // namespace codec
}  // namespace psq

#endif  // PSQ_CODEC_NEIGHBORS_H_
