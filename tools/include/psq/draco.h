// SPDX-License-Identifier: Apache-2.0
// psq/draco.h: Draco (.drc) reader and writer.
//
// Draco is an in-core format: a .drc is decoded or encoded as a whole, so
// both classes hold the whole mesh in memory and refuse (kLimit) when it
// would exceed the memory budget their caller gives them. Draco itself is a
// private dependency of psq_convert: this header does not include it.
//
// Attributes map to PLY-like vertex properties:
//   NORMAL     <-> nx ny nz (float)
//   COLOR      <-> red green blue [alpha] (uchar; a float color stays float)
//   TEX_COORD  <-> u v (float)
//   GENERIC    <-> any other scalar vertex property, one component each;
//                  the writer stores its name as attribute metadata ("name"),
//                  and the reader uses it when present, else attr<N>_<k>
//                  (attribute N, component k).
// The writer drops face properties and list properties (it names them in
// dropped()). Draco points are psq vertices: a decoded mesh yields one
// vertex per Draco point, in Draco's order, then its faces.
#ifndef PSQ_DRACO_H_
#define PSQ_DRACO_H_

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "psq/indexed_mesh.h"
#include "psq/io.h"

namespace psq {

// True when `data` starts with the Draco magic "DRACO".
bool looks_like_draco(const uint8_t* data, size_t size);

// What check_draco_header read from a .drc header.
struct DracoHeaderInfo {
  uint8_t version_major = 0;
  uint8_t version_minor = 0;
  bool mesh = false;  // a triangular mesh; else a point cloud
  int method = 0;     // mesh: 0 sequential, 1 edgebreaker; point cloud: 0 sequential, 1 k-d tree
  uint64_t faces = 0;
  uint64_t points = 0;           // declared points (edgebreaker: vertices plus split vertices)
  uint64_t estimated_bytes = 0;  // what decoding is estimated to allocate, the file included
};

// The hostile-input guard of DracoReader, run on the whole file before any
// byte reaches libdraco, which sizes its allocations by the counts a file
// declares. It reads, with its own bounds checks:
//  - the header: magic "DRACO", a bitstream version libdraco 1.5.5 reads
//    (1.0 to 2.2 for meshes, 2.3 for point clouds), geometry type, encoding
//    method, flags (only the metadata flag is defined);
//  - metadata, when flagged: every entry and sub-metadata must fit the
//    bytes left, nesting at most 32 deep (libdraco itself recurses);
//  - the element counts: point clouds, the int32 point count; sequential
//    meshes, face and point counts, and with raw indices, that all 3 x faces
//    indices are in the file; edgebreaker meshes, the traversal kind and
//    that symbols <= faces, split symbols <= symbols, vertices <= 3 x faces,
//    and for the standard traversal (one bit or more per symbol) that the
//    symbols fit the bytes left.
// What remains unbounded by the file's length (the valence traversal and
// all attribute values are entropy coded, and a constant stream costs
// almost no bytes) is bounded by memory instead: the counts give an
// estimate of libdraco's allocations (per face, per vertex, and 48 bytes per
// point, i.e. a float position with its decoding buffers), and an estimate
// over `memory_budget` is refused. Not pre-checked: the attribute
// declarations (they follow the entropy-coded connectivity), so a file whose
// points carry many wide attributes (up to 255 components of 8 bytes) can
// make libdraco allocate a multiple of the estimate before DracoReader
// measures the decoded mesh against the budget. Nor can it bound what
// libdraco (1.5.5, and upstream in 2026) does with the orientation count of a
// texture coordinate prediction (MESH_PREDICTION_TEX_COORDS_PORTABLE),
// which it reads from the attribute data and trusts: any count up to 2^31
// makes it allocate up to 256 MiB and loop up to 2^31 times (seconds),
// per attribute, before the file is refused.
// Returns OK, or (the offset is the byte where the problem is):
// kUnknownFormat (no magic), kTruncated (the header or counts end early),
// kBadHeader (unknown type, method, traversal or flags), kUnsupported (a
// newer bitstream version, too deep metadata), kBadValue (counts the bytes
// cannot hold, or that contradict each other), kLimit (over the budget).
// Files that libdraco would accept and that no Draco encoder writes (a
// varint over 32 bits, unknown flags) are refused too.
Status check_draco_header(const uint8_t* data, size_t size, uint64_t memory_budget,
                          DracoHeaderInfo* info = nullptr);

class DracoReader : public MeshSource {
 public:
  DracoReader();
  ~DracoReader() override;

  // Reads all of `in` (which need not outlive the reader), checks it with
  // check_draco_header and decodes it. Errors: those of check_draco_header,
  // kLimit (the file, or the decoded mesh, exceeds `memory_budget` bytes),
  // kBadValue (libdraco refused the data: the offset is where it stopped;
  // a mesh without positions, a non-finite position), kIo.
  Status open(InputStream* in, uint64_t memory_budget);

  const MeshSchema& schema() const override;
  Status next(MeshItem* item) override;
  const SourceReport& report() const override;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

struct DracoWriteOptions {
  // Position quantization bits (1..30); ignored when lossless.
  int bits = 16;
  // Positions and every float attribute unquantized (Draco stores them raw,
  // bit-exact); normals and texture coordinates are otherwise quantized to
  // 10 and 12 bits as draco_encoder does by default.
  bool lossless = false;
  // The most memory the buffered mesh may take (bytes).
  uint64_t memory_budget = uint64_t{512} << 20;
};

// Buffers the mesh and encodes it at finish() with Draco's edgebreaker
// (compression level 7: encoding and decoding speed 3); a mesh without
// triangles is written as a Draco point cloud. Positions are stored as
// floats (doubles only when lossless with double positions): a position or
// float attribute beyond float range is refused (kBadValue), and, quantized,
// a range that overflows Draco's float arithmetic or a double position that
// rounding to float would move by more than half a quantization step
// (kLimit), naming the vertex, rather than written changed. Errors: kLimit
// (also over the memory budget, or more than 2^31 vertices), kUsage (bits
// out of range), kInternal (Draco refused to encode), kIo.
class DracoWriter : public MeshSink {
 public:
  // `out` must be open and outlive the writer; the caller commits it after
  // finish().
  DracoWriter(OutputFile* out, DracoWriteOptions options = {});
  ~DracoWriter() override;

  Status begin(const MeshSchema& schema) override;
  Status vertex(const double position[3], const PropertyValues& values) override;
  Status triangle(const uint32_t index[3], const PropertyValues& values) override;
  Status finish() override;

  // Names of the properties that Draco does not carry (valid after begin).
  const std::vector<std::string>& dropped() const;
  // What Draco's edgebreaker changes, one line each (valid after finish):
  // it drops unreferenced vertices and degenerate triangles (a repeated
  // vertex) and duplicates the vertices of non-manifold edges and vertices.
  const std::vector<std::string>& notes() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace psq

#endif  // PSQ_DRACO_H_
