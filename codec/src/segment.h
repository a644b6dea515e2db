// SPDX-License-Identifier: Apache-2.0
// codec/src/segment.h: the state block of a segment record (spec 4.6):
// what a decoder carries over from one chunk to the next (13.9), written
// out where a segment begins, so that a decoder can start there.
//
// The processing sequence at a segment start has an open boundary: a
// restart with an empty one would cut the mesh along every segment start.
// So the block holds the boundary as it is, in a canonical form: its open
// edges loop by loop, the vertices in the order the loops reach them, and
// only what the records can still see (an edge's age only among the last
// 128 edges that entered, 13.6.2). At a segment start, the encoder and
// every decoder load this form back: vertex i of the state in slot i, edge
// j in slot j, fresh neighbour lists, the ring rebuilt, fresh attribute
// models. The slots a decoder reports stay those its elements had
// (PsqDecoder::Impl's report maps, spec 4.6): slots are part of the
// decoded sequence (psq/sequence.h). One serialization: the encoder
// writes the block from its own state, a decoder that reads the stream
// from the start checks that its state serializes to the same bytes, and
// a decoder that starts at the segment loads the block, then checks at
// its end that its state serializes to the next segment's block. Every
// decoder therefore accepts exactly the same streams.
#ifndef PSQ_CODEC_SEGMENT_H_
#define PSQ_CODEC_SEGMENT_H_

#include <cstdint>
#include <utility>
#include <vector>

#include "boundary.h"
#include "neighbors.h"

namespace psq {
namespace codec {

class AttributeCoder;
class FastRing;

// Edges further back than this many entered edges have no recency rank
// (spec 13.6.2), so the state does not keep their age.
constexpr uint32_t kStateRecency = 128;
struct SegmentState {
  // What came before: records, vertex events (the next dense index) and
  // triangle events; edges that ever entered (spec 6.1.2 step 2).
  uint64_t records = 0, vertices = 0, triangles = 0, entered = 0;
  uint32_t reference = kNone;  // the reference edge R (its position in `edge`)
  uint32_t context = 0;        // the context of table A (13.7.1)
  uint32_t choice = 0;         // the previous prediction choice (13.8.2)
  int64_t last[3] = {0, 0, 0};  // the prediction state (7.3)
  struct Vertex {
    uint32_t slot = 0;  // the slot it had (capture_boundary()), not serialized
    uint32_t index = 0, degree = 0;
    uint32_t key = 0;  // BVertex::key: carried over, not serialized
    int64_t pos[3] = {0, 0, 0};
  };
  struct Edge {
    uint32_t slot = 0;  // likewise
    uint32_t org = 0, dst = 0;  // vertices: positions in `vertex`
    uint32_t next = kNone;      // a position in `edge`, or kNone
    uint32_t recency = 0;       // entered - age when at most kStateRecency, else 0
    int64_t opp[3] = {0, 0, 0};
  };
  // The active vertices and open edges in canonical order.
  std::vector<Vertex> vertex;
  std::vector<Edge> edge;
  // The loops: the lengths of the runs of `edge` that follow one another
  // by `next`, and whether each closes (the last one's next is the first).
  std::vector<std::pair<uint32_t, bool>> loop;
  // Pairs of active vertices (positions, first < second, ascending) joined by
  // an edge that is not open: the dead edges of the new-edge check (13.6.3).
  std::vector<std::pair<uint32_t, uint32_t>> dead;
  // Attributes (8.3): the last values, then dims() values per vertex and
  // per edge, in the order above.
  std::vector<int32_t> attr_last, attr_vertex, attr_edge;
};

// The boundary's part of a state (slots, links, ages, R, `entered`, and
// the keys), in canonical order.
template <bool L>
void capture_boundary(const BasicBoundary<L>& b, SegmentState* s);
// The dead pairs, after capture_boundary(): the pairs of active vertices
// that `n` lists and that are no open edge (spec 13.6.3).
template <bool L>
void capture_dead(const BasicBoundary<L>& b, const Neighbors& n, SegmentState* s);
// The attributes' part, after capture_boundary().
void capture_attributes(AttributeCoder& a, SegmentState* s);

// The bytes of a state (before compression), with `attr_dims` attribute
// values per vertex (AttributeCoder::dims()).
void serialize_state(const SegmentState& s, int attr_dims, std::vector<uint8_t>* out);
// Parses and checks the bytes of a state: at most `limit` vertices and
// edges, endpoints distinct, indices below the vertex count, coordinates
// within [lo, hi], attribute values within their components' ranges
// (`attrs`, when attr_dims > 0). Returns nullptr, or what is wrong.
const char* parse_state(const uint8_t* p, size_t n, uint32_t limit, int attr_dims, int64_t lo, int64_t hi,
                        const AttributeCoder* attrs, SegmentState* s);

// Loads a state into a fresh boundary and fresh neighbour lists, the ring
// and the attributes' values (their models are the caller's to restart).
template <bool L>
void load_state(const SegmentState& s, BasicBoundary<L>* b, Neighbors* n, FastRing* ring, AttributeCoder* a);

}  // namespace codec
}  // namespace psq

#endif  // PSQ_CODEC_SEGMENT_H_
