// SPDX-License-Identifier: Apache-2.0
// psq/sequence_count.h: the statistics of a processing sequence in memory
// proportional to its boundary (paper section 3 and Table 1).
//
// SequenceCounter is a SequenceSink that counts the same SequenceStats as
// SequenceChecker (psq/sequence_check.h) without checking the sequence, in
// the memory a decoder has: per-vertex data lives on the producer's vertex
// slots (SequenceVertex::slot, SequenceTriangle::vslot; psq/sequence.h), so
// that nothing is indexed by the mesh's size. `psq info` counts a .psq file
// with it as the decoder yields it.
//
// What it keeps beyond the boundary, for the components, holes and
// non-manifold counts that look back past finalized vertices:
// - 8 bytes per start op (a region of the sequence; union-finds of the
//   regions joined by joins and by re-appearances),
// - 8 bytes per run of consecutive vertices introduced into one region
//   (a re-appearing vertex finds the region of its first occurrence there),
// - 4 bytes per vertex that has a border edge (border loops) and a hash
//   entry (16 to 64 bytes) per first occurrence that has one (holes),
// - hash entries per re-appearing vertex and per cut edge.
// A closed manifold mesh grown in few regions thus costs its boundary and a
// few kilobytes; a mesh with borders, up to about 70 bytes more per border
// vertex; a soup of separate triangles (every vertex on a border), about
// 100 bytes per triangle, more than SequenceChecker.
//
// Requirements: every vertex that a triangle uses comes with a slot, and
// every triangle names its corners' slots, as the decoder (psq/psq_codec.h)
// and the converter (psq/converter.h) give them (an isolated vertex may come
// without one); the sequence is valid (spec/psq-dump.md A.2; the decoder
// checks every record, and SequenceChecker checks any sequence). On a
// sequence without slots it fails; on an invalid one its counts mean
// nothing, but it neither reads out of bounds nor allocates for slots it
// was not given: slots are bounded, and a slot is checked to hold the
// vertex a triangle names wherever the counter reads it (a fill or end
// without borders reads none).
#ifndef PSQ_SEQUENCE_COUNT_H_
#define PSQ_SEQUENCE_COUNT_H_

#include <cstdint>
#include <memory>

#include "psq/sequence.h"
#include "psq/sequence_check.h"

namespace psq {

class SequenceCounter : public SequenceSink {
 public:
  // Slots must stay below this (the decoder's are below its boundary limit).
  static constexpr uint32_t kMaxSlot = uint32_t{1} << 28;

  SequenceCounter();
  ~SequenceCounter() override;

  // Errors: kBadSequence for a vertex with a slot of kMaxSlot or more, a
  // triangle right after a vertex without a slot, a triangle that names a
  // slot no vertex took or, where it is read, a slot that does not hold the
  // vertex the triangle names, a vertex out of dense order,
  // one that re-appears a later vertex, or more finalizations than
  // vertices.
  Status begin(const MeshSchema& schema) override;
  Status vertex(const SequenceVertex& v) override;
  Status triangle(const SequenceTriangle& t) override;
  Status finalize(uint32_t index) override;
  Status finish() override;

  // Complete after finish().
  const SequenceStats& stats() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace psq

#endif  // PSQ_SEQUENCE_COUNT_H_
