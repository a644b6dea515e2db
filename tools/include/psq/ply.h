// SPDX-License-Identifier: Apache-2.0
// psq/ply.h: streaming PLY reader and writer.
//
// PlyReader is a MeshSource over ascii, binary little-endian and binary
// big-endian PLY. It reads one element at a time: memory does not depend on
// the file's size. Header lines may end in LF, CRLF or CR, mixed; binary
// data starts right after end_header's own line end ("end_header\r\n" after
// lines ending in a lone CR is settled by the data's size when it can be,
// else read as CR, and a later error says so). A header line with no PLY
// keyword after the format line is read as a comment, with a note in
// report(), unless it looks like a declaration (see open()). The vertex element
// needs float or double x, y, z; every other vertex property, scalar or list,
// of any type, is carried. Faces come from a `face` element (list property
// `vertex_indices` or `vertex_index`; polygons are split into fans) or a
// `tristrips` element (`vertex_indices` with -1 restarts); every other face
// property is carried per triangle. Other elements are skipped.
//
// Safe on untrusted input: every malformed file gives a Status with the byte
// offset (binary) or line (ascii) and no allocation depends on a count in the
// header.
#ifndef PSQ_PLY_H_
#define PSQ_PLY_H_

#include <memory>
#include <string>

#include "psq/indexed_mesh.h"
#include "psq/io.h"
#include "psq/psq_codec.h"

namespace psq {

enum class PlyEncoding { kAscii, kBinaryLittleEndian, kBinaryBigEndian };

// True when `data` (at least the first 4 bytes of an input) starts like PLY.
bool looks_like_ply(const uint8_t* data, size_t size);

class PlyReader : public MeshSource {
 public:
  PlyReader();
  ~PlyReader() override;

  // Reads and checks the header from `in`, which must outlive the reader.
  // Errors: kBadHeader (no "ply" magic; no format line, or two; missing
  // end_header: the input ends, or binary bytes come, before it; unknown
  // format or type; a line with no PLY keyword before the format line, or
  // one that looks like a declaration: a keyword in the wrong case, a type
  // name or "list" as second word, or a name and a count; no vertex element
  // or no x/y/z; a face element without an index list), kLimit (no
  // end_header in the first 1 MiB), kIo.
  Status open(InputStream* in);

  PlyEncoding encoding() const;
  const MeshSchema& schema() const override;
  // Errors: kTruncated (the data ends before the header's counts are read),
  // kBadValue (a malformed ascii number, a NaN or infinite position, a face
  // with fewer than 3 indices, a list count that is negative or overruns its
  // line), kBadIndex (an index < 0 or >= the vertex count), kIo.
  Status next(MeshItem* item) override;
  const SourceReport& report() const override;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

struct PlyWriteOptions {
  PlyEncoding encoding = PlyEncoding::kBinaryLittleEndian;
  // Where to spool vertices or faces when the source does not know their
  // count up front (PLY needs counts in its header); empty means $TMPDIR.
  std::string spool_dir;
};

// Writes a PLY file with the schema's properties and types. When the schema
// knows the vertex and triangle counts the data is written straight through;
// otherwise it is spooled to an unlinked temporary file and copied after the
// header. Errors: kIo, kBadValue (a value that the declared type cannot
// hold, such as a finite value beyond float range for a float type).
class PlyWriter : public MeshSink {
 public:
  // `out` must be open and outlive the writer; the caller commits it after
  // finish().
  PlyWriter(OutputFile* out, PlyWriteOptions options = {});
  ~PlyWriter() override;

  Status begin(const MeshSchema& schema) override;
  Status vertex(const double position[3], const PropertyValues& values) override;
  Status triangle(const uint32_t index[3], const PropertyValues& values) override;
  Status finish() override;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Writes the mesh of the .psq file `path` as binary little-endian PLY to
// `out`, the bytes PlyWriter would write, decoding `threads` of its
// segments at once (0: one per core; psq/psq_codec.h,
// decode_mesh_segments()) and writing each range of vertices and faces in
// place as it comes, so that memory holds only what the segments decode
// between two chunks (no spool file, as PlyWriter needs when the counts
// come after the elements). Sets the counts written. Errors:
// kUnsupported, with `out` emptied, when the stream or the output does
// not allow it (positions that are not float, properties, a vertex that
// re-appears, an output that is not a regular file): write it through
// PlyWriter instead; the decoder's and the output's errors.
Status write_ply_by_segments(const std::string& path, OutputFile* out, int threads, uint64_t* vertices,
                             uint64_t* triangles);

}  // namespace psq

#endif  // PSQ_PLY_H_
