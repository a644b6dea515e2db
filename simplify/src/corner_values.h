// SPDX-License-Identifier: Apache-2.0
// simplify/src/corner_values.h: texture coordinates and normals kept per
// corner (the face lists corner_uv and corner_normals, as psq's OBJ reader
// makes them from `vt` and `vn`) through the edge collapses of the stream
// simplifier.
//
// A vertex inside a texture chart (or on a smooth surface) has one value
// for all its corners; a vertex on a seam has one per side (a *wedge*).
// When edge (gone, keep) collapses, the corners of both ends that stay
// must get values at the merged vertex's new place, from the chart they
// belong to. The collapsed triangles hold, for each chart the edge
// touches, a corner of `gone` and one of `keep` with that chart's values:
// a corner of the merged vertex takes the value interpolated at the new
// place in the collapsed triangle whose corner at its old vertex has the
// same value. A corner whose value no collapsed triangle has is on a seam
// that does not run along the edge: the collapse would tear the texture
// (or smear a hard edge), so it is refused, unless that corner's vertex is
// `keep` and stays where it is (its values stay right). So is one whose
// value both collapsed triangles hold while they part at the edge's other
// end: a seam that ends at its vertex, which it could not follow. This is the
// wedge rule of Hoppe's progressive meshes and of meshoptimizer's
// attribute-aware simplifier, for the corner lists a streamed mesh
// carries.
#ifndef PSQ_SIMPLIFY_CORNER_VALUES_H_
#define PSQ_SIMPLIFY_CORNER_VALUES_H_

#include <cstddef>
#include <cstdint>
#include <vector>

#include "psq/indexed_mesh.h"
#include "psq/triangle_buffer.h"

namespace psq::detail {

class CornerValues {
 public:
  // Finds the schema's corner lists (float or double face lists named
  // corner_uv or corner_normals). Returns whether there is one.
  bool init(const MeshSchema& schema);
  bool active() const { return !lists_.empty(); }
  // Whether v's corners carry more than one value of some corner list: v
  // is on a seam (a chart's border, or a hard edge of the normals).
  bool seam_vertex(const TriangleBuffer& b, uint32_t v) const;
  // Whether the edge of corner h runs along a seam: the triangle across
  // it has other values at either end.
  bool seam_edge(const TriangleBuffer& b, uint32_t h) const;
  // Plans the values of the corners that stay when the edge of corner h
  // collapses, its kept end (the start if keep_start) moved to p (world
  // coordinates). Returns false when the collapse would tear a seam.
  bool plan(const TriangleBuffer& b, uint32_t h, bool keep_start, const double p[3]);
  // After TriangleBuffer::collapse() of the edge plan() was given: writes
  // the planned values.
  void apply(TriangleBuffer* b) const;
  // Gives the corners of cap t (a triangle TriangleBuffer::cut() made,
  // with another triangle's values) the values at their vertices of the
  // triangles across its edges, so that a cap brings no new value to a
  // vertex.
  void fill_cap(TriangleBuffer* b, uint32_t t) const;

 private:
  struct List {
    size_t property;  // index in the schema's face properties
    int arity;        // values per corner: 2 (texture) or 3 (normal)
    bool normal;      // renormalized after interpolation
  };
  struct Change {
    uint32_t triangle;
    size_t at;  // index of the corner's first value in the face values
    int arity;
    double value[3];
  };
  // Index of the first value of corner k of list `l` in face values `fv`,
  // or kNoValue when the triangle's list does not hold three values (or
  // the values are malformed: any SequenceSource may be the input).
  size_t value_index(const PropertyValues& fv, size_t l, uint32_t k) const;
  bool same_value(const TriangleBuffer& b, size_t l, uint32_t c, uint32_t d) const;

  static constexpr size_t kNoValue = ~size_t{0};
  std::vector<bool> is_list_;  // per face property of the schema
  std::vector<List> lists_;
  std::vector<Change> changes_;
};

}  // namespace psq::detail

#endif  // PSQ_SIMPLIFY_CORNER_VALUES_H_
