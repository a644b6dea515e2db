// psq/obj.h: Wavefront OBJ reader and writer.
//
// ObjReader is a MeshSource over `v` (with optional r g b colour), `vn`,
// `vt` and `f` lines in every slash form (v, v/t, v//n, v/t/n), negative
// (relative) indices, polygons (split into fans) and comments; other
// statements (o, g, s, usemtl, mtllib, l, p, ...) are ignored.
//
// Memory: an OBJ without `vn` and `vt` streams (constant memory). OBJ gives
// normals and texture coordinates index spaces of their own that resolve
// only when faces arrive, so an OBJ with them is read in memory (positions,
// attributes and faces), then yielded with one normal and texture coordinate
// per vertex; a vertex used with different attributes is split, and the
// report says how many. A pipe is first spooled to a temporary file.
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
  // Errors: kBadValue (a malformed number, a NaN or infinite position, a
  // face with fewer than 3 corners), kBadIndex (an index of 0, or one that
  // refers to an element not yet defined), kIo.
  Status next(MeshItem* item) override;
  const SourceReport& report() const override;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Writes `v` lines (with r g b when the schema has float red/green/blue or
// uchar colours), `vn` when it has nx/ny/nz, `vt` when it has u/v, s/t or
// texture_u/texture_v, and `f` lines, streaming. Properties OBJ cannot hold
// are not written; dropped() names them after begin(). Errors: kIo.
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
