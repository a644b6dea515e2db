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

#include <algorithm>
#include <cstdint>
#include <utility>
#include <vector>

namespace psq {
namespace codec {

class Neighbors {
 public:
  // Vertex slot `s` now holds a new vertex, with no neighbours yet.
  void vertex_begins(uint32_t s) {
    if (s >= gen_.size()) grow(s);
    ++gen_[s];
    count_[s] = 0;
    if (s < spill_.size()) spill_[s].clear();
  }
  // An edge joins the vertices in slots a and b.
  void insert(uint32_t a, uint32_t b) {
    add(a, uint64_t{b} << 32 | gen_[b]);
    add(b, uint64_t{a} << 32 | gen_[a]);
  }
  // Whether an edge joins the vertices now in slots a and b.
  bool contains(uint32_t a, uint32_t b) const {
    // Scan the shorter list for the other vertex as it is now.
    if (count_[b] < count_[a]) std::swap(a, b);
    const uint64_t want = uint64_t{b} << 32 | gen_[b];
    const uint32_t n = count_[a];
    const uint64_t* in = &inline_[size_t{a} * kInline];
    for (uint32_t i = 0; i < n && i < kInline; ++i)
      if (in[i] == want) return true;
    if (n > kInline)
      for (uint64_t x : spill_[a])
        if (x == want) return true;
    return false;
  }

 private:
  // Most active vertices have at most this many neighbours: they live in
  // one flat array; the rest of a longer list spills into a vector.
  static constexpr uint32_t kInline = 8;

  void add(uint32_t s, uint64_t entry) {
    const uint32_t n = count_[s]++;
    if (n < kInline) {
      inline_[size_t{s} * kInline + n] = entry;
      return;
    }
    if (s >= spill_.size()) spill_.resize(gen_.size());
    spill_[s].push_back(entry);
  }
  void grow(uint32_t s) {
    const size_t n = std::max<size_t>(size_t{s} + 1, 2 * gen_.size());
    gen_.resize(n, 0);
    count_.resize(n, 0);
    inline_.resize(n * kInline);
  }

  std::vector<uint32_t> gen_;    // per slot: bumped when a new vertex takes it
  std::vector<uint32_t> count_;  // per slot: neighbours listed
  std::vector<uint64_t> inline_;  // per slot, kInline entries: slot << 32 | that slot's generation then
  std::vector<std::vector<uint64_t>> spill_;  // per slot: entries beyond kInline
};

}  // namespace codec
}  // namespace psq

#endif  // PSQ_CODEC_NEIGHBORS_H_
