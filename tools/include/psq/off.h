// SPDX-License-Identifier: Apache-2.0
// psq/off.h: streaming reader of the Object File Format (OFF).
//
// OffReader is a MeshSource over ascii OFF as Geomview defines it: an
// optional header keyword `OFF`, `COFF` (a colour per vertex), `NOFF` (a
// normal per vertex) or `CNOFF` (both), then the counts `V F E` (E, the edge
// count, is optional and ignored; the counts may follow the keyword on its
// own line, as in "OFF 8 6 0" or "OFF8 6 0"), then V vertex lines and F face
// lines. Comments (`#` to the end of a line) and blank lines are allowed
// anywhere; lines may end in LF, CRLF or CR. The keyword is required here
// (Geomview makes it optional) so that content detection stays reliable.
//
//  - A vertex line is `x y z`, then `nx ny nz` for N, then a colour for C:
//    3 or 4 numbers (r g b [a]), as the first vertex line decides for the
//    whole file. Numbers are parsed as float (rounded once from the decimal
//    text; a leading '+' is accepted). Normals are carried as float vertex
//    properties `nx ny nz`; colours as float `red green blue [alpha]` with
//    the values as written, on the file's own scale (0-255 or 0-1).
//  - A face line is `n i1 ... in`, optionally followed by a face colour of
//    up to 4 numbers, which is checked and skipped (report().notes says how
//    many faces had one). Faces of more than 3 corners are split into fans
//    (corners 0, k, k+1), counted in report().polygons_triangulated.
//
// The schema declares float positions, vertex_count = V and triangle_count
// unknown (faces may be polygons) unless F is 0. Vertices are yielded as
// they are read, then triangles: memory does not depend on the file's size
// (one line at a time, at most InputStream::kMaxLine bytes).
//
// Not supported (kUnsupported, with the keyword named): binary OFF
// (`OFF BINARY`), texture coordinates (`ST...OFF`), homogeneous coordinates
// (`4OFF`) and n-dimensional files (`nOFF`).
//
// Safe on untrusted input: every malformed file gives a Status with the line
// (or, for a count the file cannot hold, the byte offset where the data
// begins), and no allocation depends on a count in the header.
#ifndef PSQ_OFF_H_
#define PSQ_OFF_H_

#include <cstddef>
#include <cstdint>
#include <memory>

#include "psq/indexed_mesh.h"
#include "psq/io.h"

namespace psq {

// True when `data` (the first bytes of an input) starts, after optional
// blank and `#` comment lines, with an OFF header keyword followed by a
// blank, a line end, a digit, a `#` or the end of `data`. The keywords of the
// unsupported variants (STOFF, 4OFF, nOFF, ...) count too, so that
// OffReader::open() can say why it does not read them.
bool looks_like_off(const uint8_t* data, size_t size);

class OffReader : public MeshSource {
 public:
  OffReader();
  ~OffReader() override;

  // Reads the header (and, for a C file, peeks at the first vertex line to
  // learn whether colours have 3 or 4 components) from `in`, which must
  // outlive the reader. Errors: kBadHeader (no OFF keyword, missing or
  // malformed counts), kUnsupported (binary OFF, ST, 4 or n variants),
  // kLimit (more than 4294967295 vertices, a count beyond 64 bits, no
  // keyword and counts in the first 1 MiB),
  // kTruncated (the input ends in the header, or the counts need more bytes
  // than follow: at least 6 per vertex and per face, when the input's size
  // is known), kBadValue (the first vertex line of a C file has neither 3
  // nor 4 colour components), kIo.
  Status open(InputStream* in);

  const MeshSchema& schema() const override;
  // Errors: kTruncated (the input ends before the declared vertices and
  // faces), kBadValue (a wrong number of values on a vertex line, a
  // malformed number, a number beyond float range, a non-finite value, a
  // face with fewer than 3 corners or fewer indices than it declares, more
  // than 4 values after a face's indices, non-blank content after the last
  // face), kBadIndex (an index that is negative or >= V), kLimit (a line
  // over InputStream::kMaxLine), kIo.
  Status next(MeshItem* item) override;
  const SourceReport& report() const override;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace psq

#endif  // PSQ_OFF_H_
