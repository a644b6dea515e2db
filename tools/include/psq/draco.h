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

class DracoReader : public MeshSource {
 public:
  DracoReader();
  ~DracoReader() override;

  // Reads all of `in` (which need not outlive the reader) and decodes it.
  // Errors: kLimit (the file, or the decoded mesh, exceeds
  // `memory_budget` bytes), kUnknownFormat (no Draco magic), kBadValue (a
  // corrupt or unsupported .drc, a mesh without positions, a non-finite
  // position), kIo.
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
// triangles is written as a Draco point cloud. Errors: kLimit (over the
// memory budget, or more than 2^31 vertices), kUsage (bits out of range),
// kInternal (Draco refused to encode), kIo.
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
