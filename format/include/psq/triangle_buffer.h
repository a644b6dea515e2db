// SPDX-License-Identifier: Apache-2.0
// psq/triangle_buffer.h: buffer-based processing (paper section 3, "buffer-
// based processing", and section 6).
//
// A triangle buffer holds the part of a mesh between two processing
// boundaries: the input boundary, where triangles of an input processing
// sequence arrive, and the output boundary, where triangles leave through the
// processing-sequence converter (psq/converter.h) to any SequenceSink. An
// algorithm (its "client": an edge-collapse simplifier, an iterative
// smoother) works on the triangles in between, with full connectivity:
//
// - Every triangle knows the triangle across each of its edges, or why there
//   is none: the edge is a border of the mesh (the sequence says so, so a
//   hole is never mistaken for the input boundary, paper section 6), the
//   triangle across was not read yet (the input boundary), or it was
//   written already (the output boundary). The input sequence's boundary
//   slots pair the two triangles of an edge without hashing (paper section
//   3, "connectivity reconstruction").
// - Every vertex lists its triangles in the buffer (in no particular
//   order; a vertex on a boundary may have several separate fans).
// - A vertex is locked while it is on either boundary: until the input
//   finalizes it (more triangles will use it) and from the moment one of
//   its triangles is written (its output is under way; its position is
//   fixed). A client may move and merge only unlocked vertices; those are
//   kept in a set it can sample (free_vertex()).
// - Vertices of non-manifold cuts (the input re-appears them, or an edge
//   is a border only because the input was cut) are marked cut(): a client
//   must not move them, or the copies of a non-manifold vertex would drift
//   apart; they may still absorb a neighbour. A re-appearance is written as
//   a vertex of its own at the same place (its first occurrence may have
//   been merged away before it came): the output is cut where the input
//   was non-manifold.
//
// Writing: write(t) hands a triangle to the converter, giving each of its
// vertices an output number the first time, and finalizes a vertex in the
// converter when its last triangle has left the buffer and the input
// finalized it. pick_output() proposes the next triangle to write, as
// section 6 of the paper does: a triangle that completes three, two or one
// edges of the output boundary (end, fill, join, in that order; among
// triangles that complete one edge, a few random candidates, a join if one
// is among them, else the add whose free vertex has the largest
// client-given score), and only when no triangle touches the output
// boundary, the oldest one in the buffer (a start).
//
// Requirements on the input: the boundary slots of every triangle
// (SequenceTriangle::vslot and eslot) and its edge and final masks, as the
// .psq decoder and the converter give them. A sequence without them is
// refused (kUsage). Vertices used by no triangle (isolated) are dropped
// and counted. The input is checked as it arrives (a vertex
// referenced by a slot it does not hold, an edge that is not one of border,
// leaving or entering, an open edge left at the end: kBadSequence), so a
// hostile source cannot corrupt the buffer; the buffer is safe on
// untrusted input.
//
// Memory: kTriangleBytes per triangle and kVertexBytes per vertex in the
// buffer (plus property values, if the mesh has any), the converter's
// waiting area (at least 65536 triangles of about 200 bytes), and arrays
// over the input's boundary slots; never the mesh. The buffer does not
// bound itself: its client decides when to write.
//
// Errors are sticky only as the client propagates them: after an error the
// buffer's state is unspecified, and the client must stop.
#ifndef PSQ_TRIANGLE_BUFFER_H_
#define PSQ_TRIANGLE_BUFFER_H_

#include <cstdint>
#include <memory>
#include <vector>

#include "psq/converter.h"
#include "psq/sequence.h"
#include "psq/status.h"

namespace psq {

struct TriangleBufferStats {
  uint64_t triangles_read = 0;
  uint64_t vertices_read = 0;       // used by a triangle (re-appearances included)
  uint64_t isolated_dropped = 0;    // input vertices used by no triangle
  uint64_t triangles_written = 0;
  uint64_t vertices_written = 0;
  uint64_t collapses = 0;
  uint64_t triangles_discarded = 0;  // by discard()
  uint64_t cuts = 0;                 // by cut()
  uint64_t starts_written = 0;      // triangles written that touched no written triangle
  uint64_t max_triangles = 0;       // most triangles in the buffer at once
  uint64_t max_vertices = 0;        // most vertices in the buffer at once
};

class TriangleBuffer {
 public:
  static constexpr uint32_t kNone = 0xffffffffu;
  // What opposite() returns for an edge without a triangle across in the
  // buffer; any value below kOpen is a corner (half-edge) of the buffer.
  static constexpr uint32_t kBorder = 0xffffffffu;  // a border edge of the mesh
  static constexpr uint32_t kWritten = 0xfffffffeu; // the triangle across was written
  static constexpr uint32_t kOpen = 0x80000000u;    // at or above (and below kWritten): not read yet

  // Triangles go to `out` through a converter; `out` must outlive the buffer.
  explicit TriangleBuffer(SequenceSink* out);
  ~TriangleBuffer();
  TriangleBuffer(const TriangleBuffer&) = delete;
  TriangleBuffer& operator=(const TriangleBuffer&) = delete;

  // The converter's lookahead (SequenceConverter::set_lookahead_budget).
  void set_lookahead_budget(uint64_t bytes);
  // Allocates room for this many triangles and vertices at once, so that
  // the buffer does not grow by doubling (and copying) as it fills.
  void reserve(uint32_t triangles, uint32_t vertices);
  // Bytes the buffer takes per triangle and per vertex it holds (without
  // property values).
  static constexpr uint32_t kTriangleBytes = 71, kVertexBytes = 56;
  // Seeds the random choices of pick_output() (default 1).
  void set_seed(uint64_t seed);

  // ---- input side: the client passes its input sequence's events on.
  // Starts the output with `schema` (counts unknown). Errors: the sink's.
  Status begin(const MeshSchema& schema);
  // A vertex waits for its first triangle. Errors: kBadSequence (more than
  // three waiting).
  Status vertex(const SequenceVertex& v);
  // Adds a triangle; `*id` is its number in the buffer. The vertices of its
  // new corners are allocated here (their numbers: vertex_of(3 * id + k));
  // the vertices of its final corners become input-final after it.
  // Errors: kUsage (no slots or masks), kBadSequence, kLimit (more than
  // 2^29 triangles in the buffer).
  Status triangle(const SequenceTriangle& t, uint32_t* id);
  // A waiting vertex finalized before any triangle used it is dropped
  // (isolated); the others are finalized by their triangles' final masks.
  Status finalize(uint32_t index);
  // The input ended. Errors: kBadSequence when a vertex was left open.
  Status end_input();

  // ---- output side.
  // Writes triangle `t` (alive) to the converter and removes it. Errors: the
  // converter's and the sink's.
  Status write(uint32_t t);
  // The triangle to write next (see above), or kNone when the buffer is
  // empty. `score` (indexed by vertex; may be null: no preference) ranks
  // adds by their free vertex; `candidates` (at least 1) is how many
  // triangles that complete one edge are compared.
  uint32_t pick_output(int candidates, const float* score);
  // Writes every triangle left (pick_output order, no scores) and finishes
  // the converter and the sink. Call after end_input().
  Status finish();

  // ---- the buffer's mesh. Triangle t has corners 3t, 3t+1, 3t+2; the edge
  // of corner c runs from vertex_of(c) to vertex_of(next(c)).
  static uint32_t next(uint32_t c) { return c % 3 == 2 ? c - 2 : c + 1; }
  static uint32_t prev(uint32_t c) { return c % 3 == 0 ? c + 2 : c - 1; }
  uint32_t triangle_count() const { return alive_; }
  uint32_t triangle_capacity() const { return static_cast<uint32_t>(alive_flag_.size()); }
  uint32_t vertex_count() const { return vertices_; }
  uint32_t vertex_capacity() const { return static_cast<uint32_t>(verts_.size()); }
  bool alive(uint32_t t) const { return alive_flag_[t] != 0; }
  uint32_t vertex_of(uint32_t c) const { return corners_[c].vertex; }
  // The corner across the edge of corner c, or kBorder, kWritten, or a
  // value in [kOpen, kWritten).
  uint32_t opposite(uint32_t c) const { return corners_[c].opposite; }
  // The corners of vertex v: first_corner(v), then next_corner(c) until
  // kNone.
  uint32_t first_corner(uint32_t v) const { return verts_[v].head; }
  uint32_t next_corner(uint32_t c) const { return corners_[c].next; }
  const double* position(uint32_t v) const { return verts_[v].p; }
  // Sets v's position, rounded to float when the schema's positions are
  // float (so that what the client computes with is what is written).
  void set_position(uint32_t v, const double p[3]);
  // `p` rounded as set_position() would.
  void round_position(double p[3]) const;
  const PropertyValues& vertex_values(uint32_t v) const;
  const PropertyValues& face_values(uint32_t t) const;
  // Triangle t's values to change in place (a simplifier that moves a
  // corner's attributes), or null when the schema has no face property.
  PropertyValues* mutable_face_values(uint32_t t);
  // The input has not finalized v yet (it is on the input boundary).
  bool input_open(uint32_t v) const { return (verts_[v].flags & kInputFinal) == 0; }
  // A triangle of v was written (v is on the output boundary).
  bool written(uint32_t v) const { return (verts_[v].flags & kHasOutput) != 0; }
  bool locked(uint32_t v) const { return (verts_[v].flags & (kInputFinal | kHasOutput)) != kInputFinal; }
  bool cut(uint32_t v) const { return (verts_[v].flags & kCut) != 0; }
  // v has a border edge of the mesh (read, or made by a collapse).
  bool border(uint32_t v) const { return (verts_[v].flags & kBorderVertex) != 0; }
  // Unlocked vertices: free_vertex(i) for i < free_vertex_count().
  uint32_t free_vertex_count() const { return static_cast<uint32_t>(free_.size()); }
  uint32_t free_vertex(uint32_t i) const { return free_[i]; }
  // Triangles with a vertex the input has not finalized (the band along the
  // input boundary that nothing may change yet).
  uint32_t input_band() const { return band_; }
  const MeshSchema& schema() const { return schema_; }

  // ---- editing.
  // Whether the edge of corner h may be collapsed without changing the
  // topology: both ends unlocked; the link condition (the ends share
  // exactly the neighbours across the edge's triangles); an interior edge
  // not joining two border vertices; no vertex left without triangles; a
  // new vertex left with at least three triangles (one on a border).
  bool can_collapse(uint32_t h);
  // Collapses the edge of corner h (can_collapse(h) must hold): its one or
  // two triangles go, the end that is not kept merges into the kept one
  // (the start of h if keep_start, else its end), whose values stay and
  // whose position the client sets. Returns the kept vertex.
  uint32_t collapse(uint32_t h, bool keep_start);
  // Whether triangle t may be discarded: its three vertices are unlocked
  // (so every edge leads to a triangle in the buffer or is a border).
  bool can_discard(uint32_t t) const;
  // Removes triangle t (can_discard(t) must hold) without writing it: the
  // edges of the triangles across become borders, and a vertex left
  // without triangles goes. For a client that removes a whole component
  // (a simplifier whose target cannot be met with it).
  void discard(uint32_t t);
  // Whether the edge of corner h, from a to b, fails the link condition
  // through a vertex c besides the two across it: a, b and c are joined
  // pairwise by edges but bound no triangle (a handle, or a neck, three
  // edges around). Then *c is such a vertex (the first found), and
  // cut(h, *c) may run: a, b and c are unlocked, on no border, not cut.
  bool cycle_of(uint32_t h, uint32_t* c);
  // Cuts the surface along the cycle a -> b -> c of cycle_of(h, c): the
  // triangles on its left get copies a', b', c' of its vertices (position,
  // values), and each side is closed by a new triangle, (a, b, c) on the
  // right, (a', c', b') on the left, with the face values of the triangle
  // across its first edge. A handle goes (genus one less), or a neck
  // splits its component in two. new_vertices[] are a', b', c'; caps[] the
  // triangles (a, b, c) and (a', c', b'). Returns false, changing nothing,
  // when the fans around the cycle are not as cycle_of() found them.
  bool cut(uint32_t h, uint32_t c, uint32_t new_vertices[3], uint32_t caps[2]);

  const TriangleBufferStats& stats() const { return stats_; }
  const ConverterStats& converter_stats() const;

 private:
  static constexpr uint8_t kInputFinal = 1, kHasOutput = 2, kCut = 4, kBorderVertex = 8;

  uint32_t new_vertex(const SequenceVertex& v);
  uint32_t clone_vertex(uint32_t v);
  uint32_t new_cap(uint32_t v0, uint32_t v1, uint32_t v2, uint32_t values_from);
  // A triangle number, reused or new, marked alive with `open` open edges.
  uint32_t allocate_triangle(uint8_t open);
  bool left_fan(uint32_t v, uint32_t from, uint32_t to, std::vector<uint32_t>* corners) const;
  void free_vertex_record(uint32_t v);
  void add_corner(uint32_t v, uint32_t c);
  void remove_corner(uint32_t v, uint32_t c);
  void set_out_count(uint32_t t, uint8_t count);
  void kill_triangle(uint32_t t);
  void mark_input_final(uint32_t v);
  void free_insert(uint32_t v);
  void free_erase(uint32_t v);
  Status retire_if_done(uint32_t v);
  uint64_t random();

  SequenceConverter converter_;
  MeshSchema schema_;
  bool has_vertex_values_ = false, has_face_values_ = false, float_positions_ = true;
  // Triangles (struct of arrays, indexed by corner or triangle).
  // Per corner: its vertex, the corner across its edge (or why none) and
  // the next corner of its vertex, together for the walks around vertices.
  struct Corner {
    uint32_t vertex, opposite, next;
  };
  std::vector<Corner> corners_;
  std::vector<uint8_t> alive_flag_, out_count_, open_count_;
  std::vector<uint32_t> out_pos_;
  std::vector<PropertyValues> face_values_;
  std::vector<uint32_t> free_triangles_;
  uint32_t alive_ = 0;
  uint32_t band_ = 0;
  // Triangles touching the output boundary by 1, 2 or 3 edges.
  std::vector<uint32_t> out_set_[4];
  // Triangles in the order they were read (starts take the oldest).
  struct Arrival {
    uint32_t triangle, when;
  };
  bool arrived(const Arrival& a) const { return alive_flag_[a.triangle] && arrival_when_[a.triangle] == a.when; }
  std::vector<Arrival> arrival_;
  std::vector<uint32_t> arrival_when_;
  size_t arrival_head_ = 0;
  // Vertices.
  // Per vertex, together for the walks around vertices: its position, first
  // corner, output number, input number, place in the free set, mark of
  // can_collapse(), and flags.
  struct Vertex {
    double p[3] = {0, 0, 0};
    uint32_t head = kNone, out_id = kNone, dense = kNone, free_pos = kNone;
    uint32_t mark = 0;
    uint8_t flags = 0;
  };
  std::vector<Vertex> verts_;
  std::vector<PropertyValues> vertex_values_;
  std::vector<uint32_t> free_vertices_;
  std::vector<uint32_t> free_;
  uint32_t vertices_ = 0;
  uint32_t open_vertices_ = 0;
  uint32_t open_edges_ = 0;
  uint32_t next_out_id_ = 0;
  // Input boundary: vertex and edge slots to buffer vertices and corners.
  BoundaryData<uint32_t> vslot_;
  BoundaryData<uint32_t> eslot_;
  std::vector<SequenceVertex> pending_;  // introduced, not yet used
  // The mark of can_collapse().
  uint32_t epoch_ = 0;
  uint64_t rng_ = 1;
  TriangleBufferStats stats_;
  PropertyValues empty_values_;
};

}  // namespace psq

#endif  // PSQ_TRIANGLE_BUFFER_H_
