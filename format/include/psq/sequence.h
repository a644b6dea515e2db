// SPDX-License-Identifier: Apache-2.0
// psq/sequence.h: the processing-sequence model (paper section 3).
//
// A processing sequence is a stream of events: a vertex is introduced right
// before the first triangle that uses it, triangles follow one another so
// that each is one of five operations relative to the processing boundary
// (the edges between processed and unprocessed triangles), and a vertex is
// finalized right after its last use. Vertices are numbered densely in the
// order they are introduced (0, 1, 2, ...).
//
// The ops (paper, Figure 2), for a triangle with n new vertices that
// completes e boundary edges:
//   start  n = 3, e = 0   a new boundary component
//   add    n = 1, e = 1   completes one edge, adds a vertex and two edges
//   join   n = 0, e = 1   completes one edge; its third vertex is already on
//                         the boundary (merges or splits boundary loops)
//   fill   n = 0, e = 2   completes two edges
//   end    n = 0, e = 3   completes three edges, closing a loop
//
// Non-manifold input is cut (paper, end of section 3): a vertex whose
// triangles do not form one fan, or an edge with more than two triangles or
// two of the same orientation, re-appears as a new vertex that refers to its
// earlier occurrence (`reappears`). Nothing is duplicated silently, and the
// sequence itself is an oriented manifold with borders: every edge is used by
// one triangle (a border edge) or by two of opposite orientation.
//
// A vertex used by no triangle is introduced and finalized with no triangle
// in between (an isolated vertex), so that no input vertex is lost.
#ifndef PSQ_SEQUENCE_H_
#define PSQ_SEQUENCE_H_

#include <algorithm>
#include <cstdint>
#include <vector>

#include "psq/indexed_mesh.h"
#include "psq/status.h"

namespace psq {

enum class Op : uint8_t { kStart = 0, kAdd = 1, kJoin = 2, kFill = 3, kEnd = 4 };

// "start", "add", "join", "fill" or "end".
const char* op_name(Op op);

constexpr uint32_t kNoVertex = 0xffffffffu;
constexpr uint32_t kNoSlot = 0xffffffffu;

// Boundary slots (paper section 3, "connectivity reconstruction"): every
// active vertex and every open boundary edge has a small slot number, unique
// while the element is active and recycled after it leaves the boundary (a
// vertex at its finalization, an edge when a triangle completes it). An
// algorithm keeps its own per-vertex and per-edge data in arrays indexed by
// slot (BoundaryData below): it finds what it stored at a vertex's or edge's
// first appearance when the element appears again, in constant time and
// without hashing global indices. Slots stay below the size of the
// producer's working set (the boundary for a decoder, the waiting area for
// the converter), so the arrays stay that small. Producers that have no
// slots (a parsed dump) leave them kNoSlot.

struct SequenceVertex {
  uint32_t index = 0;              // dense index
  uint32_t slot = kNoSlot;         // its boundary slot until finalized
  uint32_t reappears = kNoVertex;  // dense index of the first occurrence, for a cut vertex
  double position[3] = {0, 0, 0};
  PropertyValues values;           // per the schema's vertex properties
};

// Edge k of a triangle joins corner k and corner (k + 1) % 3.
struct SequenceTriangle {
  uint32_t v[3] = {0, 0, 0};    // dense indices, in the input's orientation
  Op op = Op::kStart;
  uint8_t new_mask = 0;         // bit k: corner k's vertex is introduced for this triangle
  uint8_t final_mask = 0;       // bit k: this is the last use of corner k's vertex
  uint8_t border_mask = 0;      // bit k: edge k is a border: no other triangle shares it
  uint8_t nonmanifold_mask = 0; // bit k: edge k is a border only because the input was cut
  uint8_t leaving_mask = 0;     // bit k: edge k completes a boundary edge (it leaves the boundary)
  uint8_t entering_mask = 0;    // bit k: edge k enters the boundary (a later triangle completes it)
  uint32_t vslot[3] = {kNoSlot, kNoSlot, kNoSlot};  // boundary slot of corner k's vertex
  // Boundary slot of edge k: a new slot for an entering edge; for a leaving
  // edge, the slot it had when it entered (free again after this triangle);
  // kNoSlot for a border edge.
  uint32_t eslot[3] = {kNoSlot, kNoSlot, kNoSlot};
  PropertyValues values;        // per the schema's face properties
};

// Per-slot user data of type T (a vertex or edge slot of a sequence): grows
// to the largest slot used; the caller resets an entry when its slot is
// given out again.
template <class T>
class BoundaryData {
 public:
  T& operator[](uint32_t slot) {
    if (slot >= data_.size()) data_.resize(std::max<size_t>(slot + 1, 2 * data_.size()));
    return data_[slot];
  }
  size_t capacity() const { return data_.size(); }

 private:
  std::vector<T> data_;
};

// Consumer of a processing sequence (push). Call order: begin, then vertex /
// triangle / finalize events as described above, then finish.
struct MeshBuffers;  // psq/mesh_arrays.h

class SequenceSink {
 public:
  virtual ~SequenceSink() = default;
  virtual Status begin(const MeshSchema& schema) = 0;
  // Introduces vertex `v.index` (the next dense index).
  virtual Status vertex(const SequenceVertex& v) = 0;
  virtual Status triangle(const SequenceTriangle& t) = 0;
  // Vertex `index` is used by no later triangle.
  virtual Status finalize(uint32_t index) = 0;
  virtual Status finish() = 0;
  // A sink that keeps only the mesh, as MeshArraySink does (positions as
  // floats, triangles as vertex indices, re-appearing vertices merged into
  // their first occurrence, nothing else), may return its arrays here: a
  // producer that can append to them directly then does so after begin()
  // instead of calling vertex(), triangle() and finalize(), and calls
  // finish() at the end. nullptr (the default): every event through the
  // calls above.
  virtual MeshBuffers* mesh_arrays() { return nullptr; }
};

struct SequenceEvent {
  enum class Kind { kVertex, kTriangle, kFinalize, kEnd };
  Kind kind = Kind::kEnd;
  SequenceVertex vertex;      // kVertex
  SequenceTriangle triangle;  // kTriangle
  uint32_t finalized = 0;     // kFinalize
};

// Producer of a processing sequence (pull). Errors are sticky.
class SequenceSource {
 public:
  virtual ~SequenceSource() = default;
  virtual const MeshSchema& schema() const = 0;
  virtual Status next(SequenceEvent* event) = 0;
};

// Pulls every event of `source` into `sink`, begin to finish.
Status pump_sequence(SequenceSource& source, SequenceSink& sink);

}  // namespace psq

#endif  // PSQ_SEQUENCE_H_
