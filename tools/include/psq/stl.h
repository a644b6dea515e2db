// SPDX-License-Identifier: Apache-2.0
// psq/stl.h: reader of STL (stereolithography) files, binary and ascii.
//
// StlReader is a MeshSource over
//  - binary STL: an 80-byte header, a little-endian uint32 triangle count,
//    then per triangle 12 little-endian floats (the facet normal and three
//    vertices) and a uint16 attribute word;
//  - ascii STL: `solid [name]`, then per triangle `facet normal nx ny nz`,
//    `outer loop`, three `vertex x y z`, `endloop`, `endfacet`, and finally
//    `endsolid [name]`. Keywords are case-insensitive, tokens may be
//    separated by any whitespace and line ends (LF, CRLF or CR), `normal`
//    and its numbers may be missing, and several solids may follow each
//    other. Numbers are parsed as float, rounded once from the decimal text
//    (a leading '+' is accepted).
//
// STL has no indices: every triangle lists its three positions. Vertices
// are welded by exact position (bit-identical float x, y, z, with -0.0 taken
// as 0.0 and yielded as 0.0) and numbered in the order of first appearance.
// Triangles that become degenerate by welding (two corners at the same
// position) are kept. Facet normals and attribute words are not carried
// (report().notes says so); a printable binary header and the solid names
// are kept in schema().comments.
//
// Memory: STL is read in core. Welding needs every distinct position and a
// MeshSource yields every vertex before the first triangle, so open() reads
// the whole file: memory is about 12 bytes per distinct vertex plus 8 for
// its hash slot and 12 bytes per triangle, proportional to the real content
// of the input (never to a count in the header). The schema then knows both
// exact counts.
//
// Safe on untrusted input: errors give the byte offset (binary) or the line
// (ascii) and a one-line message.
#ifndef PSQ_STL_H_
#define PSQ_STL_H_

#include <cstddef>
#include <cstdint>
#include <memory>

#include "psq/indexed_mesh.h"
#include "psq/io.h"

namespace psq {

enum class StlEncoding { kAscii, kBinary };

// True when `data` (the first bytes of an input, at least 84 for a binary
// file to be recognised) looks like STL. `total_size` is the input's size,
// or -1 when unknown (a pipe).
//  - Known size: binary when it is exactly 84 + 50 * count (count from bytes
//    80..83), which is checked first since binary headers often start with
//    "solid" too; ascii when the data starts (after blanks) with "solid"
//    followed by a blank or line end, and "facet" or "endsolid" appears in
//    `data`.
//  - Unknown size: ascii by the same test, otherwise binary whenever `data`
//    holds the 84-byte header, since binary STL has no magic. Callers that
//    detect several formats must therefore ask this last.
bool looks_like_stl(const uint8_t* data, size_t size, int64_t total_size);

class StlReader : public MeshSource {
 public:
  StlReader();
  ~StlReader() override;

  // Reads the whole of `in` (which is not used after open() returns),
  // chooses the encoding like looks_like_stl() from its first 4 KiB and
  // welds the vertices.
  // Binary errors (with the byte offset): kTruncated (the input ends in the
  // header or before the triangles the header declares; with a known size
  // this is found before anything is read), kBadValue (bytes after the last
  // triangle, a NaN or infinite vertex coordinate, at the triangle's
  // offset).
  // Ascii errors (with the line): kBadHeader (no `solid` at the start),
  // kBadValue (a keyword other than the grammar's, a malformed number or
  // fewer than 3 of them after `vertex` or `normal` (reported at the line of
  // the keyword), a number beyond float range, a NaN or infinite vertex
  // coordinate, a facet without exactly 3 vertices, content after
  // `endsolid` other than another solid), kTruncated (the input ends inside
  // a solid), kLimit (a line over InputStream::kMaxLine).
  // Both: kLimit (more than 4294967295 distinct vertices), kIo.
  Status open(InputStream* in);

  StlEncoding encoding() const;
  const MeshSchema& schema() const override;
  // Yields the welded vertices, then the triangles; never fails after a
  // successful open() (kUsage before it).
  Status next(MeshItem* item) override;
  const SourceReport& report() const override;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace psq

#endif  // PSQ_STL_H_
