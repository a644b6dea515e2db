// SPDX-License-Identifier: Apache-2.0
// psq/obj.h: Wavefront OBJ reader and writer.
//
// ObjReader is a MeshSource over `v` (with optional r g b colour), `vn`,
// `vt` and `f` lines in every slash form (v, v/t, v//n, v/t/n), negative
// (relative) indices, polygons (split into fans: corners 0, i-1, i) and
// comments; other statements of the OBJ specification (o, g, s, usemtl,
// mtllib, l, p, ...) are ignored, and lines with no OBJ keyword are ignored
// with a note in report(). Numbers are parsed as float, rounded once from the decimal text
// (a leading '+' is accepted; a value beyond float range is an error, one
// below it becomes 0 or a denormal), and positions and attributes are
// declared float, so that ObjWriter reproduces them exactly.
//
// Connectivity is kept exactly: the vertices are the `v` lines, in order,
// never split or merged. OBJ indexes normals and texture coordinates per
// corner; each kind is carried separately:
//  - when every position is used with at most one index of that kind (a
//    corner without one is compatible with any), as vertex properties
//    `nx ny nz` / `u v` (float; 0 where a vertex has none);
//  - otherwise (a flat-shaded cube: a position with several normals), as a
//    face property of every triangle, with no vertex property of that kind:
//    `corner_normals`, a list (count uchar) of 9 floats, nx ny nz of
//    corners 0, 1, 2 in the triangle's order, or `corner_uv`, a list of 6
//    floats, u v per corner; 0s for a corner without one. report().notes
//    says so and at how many vertices the attribute varies.
// Indices of a kind the file has no lines of (`f 1//1 2//2 3//3` without
// any `vn`) are checked to be well-formed, then ignored, with a note.
//
// Memory: an OBJ without `vn` and `vt` streams (constant memory); one whose
// `v` lines follow `f` lines is read twice (vertices, then faces) so that
// every vertex is yielded before the first triangle. An OBJ with `vn` or
// `vt` is read in memory (positions, attributes and triangle corners), since
// which way each attribute is carried is known only after the last face. A
// pipe is first spooled to a temporary file.
//
// Safe on untrusted input: errors name the line.
#ifndef PSQ_OBJ_H_
#define PSQ_OBJ_H_

#include <memory>
#include <string>

#include "psq/indexed_mesh.h"
#include "psq/io.h"

namespace psq {

// True when `data` (the first bytes of an input) looks like OBJ text.
bool looks_like_obj(const uint8_t* data, size_t size);

class ObjReader : public MeshSource {
 public:
  ObjReader();
  ~ObjReader() override;

  // Prepares reading from `in`, which must outlive the reader (bytes peeked
  // with fill() are not lost). When `in` cannot be rewound (a pipe), it is
  // first copied to a temporary file in `spool_dir` (empty: $TMPDIR).
  // Errors: kIo, and any error of next() when the file is read in memory.
  Status open(InputStream* in, const std::string& spool_dir = "");

  const MeshSchema& schema() const override;
  // Errors: kBadValue (a malformed number, a number beyond float range, a
  // NaN or infinite position, a wrong number of coordinates, a face with
  // fewer than 3 corners), kBadIndex (an index of 0, or one that refers to
  // an element not yet defined), kLimit (a line or continued statement over
  // InputStream::kMaxLine; more than 2^32 - 16 vertices, normals or texture
  // coordinates), kIo (including an input that changed between passes).
  Status next(MeshItem* item) override;
  const SourceReport& report() const override;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Writes `v` lines (with r g b when the schema has float red/green/blue or
// uchar/ushort colours), `vn` when it has nx/ny/nz, `vt` when it has u/v,
// s/t or texture_u/texture_v, and `f` lines, streaming; each corner refers
// to the vn and vt numbered like its vertex. Without per-vertex normals
// (texture coordinates), a float or double face list `corner_normals` of 9
// values (`corner_uv` of 6), as ObjReader makes them, is written per
// corner: before each `f` line, vn (vt) lines for its corners, which the
// face refers to (a corner equal to the line just written reuses it).
// Properties OBJ cannot hold are not written; dropped() names them after
// begin(). Errors: kIo; kBadValue for a finite value beyond float range
// where the type is float (naming the vertex); kInternal when values do not
// match the schema or a triangle's corner list does not have 9 (6) values.
class ObjWriter : public MeshSink {
 public:
  explicit ObjWriter(OutputFile* out);
  ~ObjWriter() override;

  Status begin(const MeshSchema& schema) override;
  Status vertex(const double position[3], const PropertyValues& values) override;
  Status triangle(const uint32_t index[3], const PropertyValues& values) override;
  Status finish() override;

  const std::vector<std::string>& dropped() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace psq

#endif  // PSQ_OBJ_H_
