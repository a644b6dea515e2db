// SPDX-License-Identifier: Apache-2.0
// psq/psq_codec.h: the .psq encoder (a SequenceSink) and decoder (a
// SequenceSource), specified in spec/psq-format.md.
//
// The encoder takes a processing sequence (psq/sequence.h) event by event
// and writes the compressed stream in one pass: it never seeks, so its
// output may be a pipe. Its memory is the processing boundary plus one
// chunk (spec 4.3). The decoder reads the stream in one pass from any
// InputStream (file, pipe or memory) and yields the same sequence with the
// same memory bound. Both treat their input as hostile: the encoder checks
// the sequence it is given (kBadSequence), the decoder checks every field,
// checksum and limit of the stream and reports the byte offset of the first
// problem.
//
// What a decoded sequence keeps of the encoded one (spec 2.3): every
// triangle with its orientation, op and border and cut flags; every vertex
// with its properties, its position (bit-exact when lossless, else on the
// quantization grid) and its re-appearance reference; every face property.
// Vertices are numbered in the order the decoder introduces them, which is
// the encoder's input order. A triangle's first corner is the decoder's
// choice (its gate edge first) unless the mesh has face properties, which
// may depend on it: then the input's rotation is kept too.
#ifndef PSQ_PSQ_CODEC_H_
#define PSQ_PSQ_CODEC_H_

#include <algorithm>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "psq/io.h"
#include "psq/mesh_arrays.h"
#include "psq/sequence.h"
#include "psq/status.h"

namespace psq {

// The first 8 bytes of every .psq stream (spec 4.1).
extern const uint8_t kPsqMagic[8];

// Where the encoder's bytes go.
class ByteWriter {
 public:
  virtual ~ByteWriter() = default;
  virtual Status write(const void* data, size_t size) = 0;
};

// Appends to a vector.
class VectorWriter : public ByteWriter {
 public:
  explicit VectorWriter(std::vector<uint8_t>* out) : out_(out) {}
  Status write(const void* data, size_t size) override;

 private:
  std::vector<uint8_t>* out_;
};

// Writes to an OutputFile (which its owner commits).
class FileWriter : public ByteWriter {
 public:
  explicit FileWriter(OutputFile* out) : out_(out) {}
  Status write(const void* data, size_t size) override { return out_->write(data, size); }

 private:
  OutputFile* out_;
};

// A vertex attribute that the stream codes with predictions across the
// gate and the range coder (spec 8.3) instead of a property column. Its
// components are vertex properties of the schema, recognized by their names
// (nx ny nz; u v, s t, texture_u texture_v, texture_s texture_t; red green
// blue [alpha], r g b [a]). A corner attribute (spec 8.5) is a face list
// property with a value per corner, as the OBJ reader gives normals and
// texture coordinates that differ between the corners at one vertex
// (corner_normals: nx ny nz of each corner; corner_uv: u v of each
// corner); the stream codes, per corner, which of its vertex's values so
// far it takes, else a new one predicted from the triangle.
struct CodedAttribute {
  enum class Kind : uint8_t { kNormal = 1, kTexcoord = 2, kColor = 3, kCornerNormal = 4, kCornerTexcoord = 5 };
  Kind kind = Kind::kNormal;
  // Normals: bits of each octahedral coordinate, 2..16 (a lossy change:
  // the decoder gives back unit vectors within the angle of that grid);
  // texture coordinates: a grid of step 2^-bits, 1..24 (within half a
  // step); colours: 8 (exact uint8 values).
  int bits = 0;
  // The components, as indices of the schema's vertex properties; for a
  // corner attribute, the one face property that holds them.
  std::vector<uint32_t> properties;
  bool per_corner() const { return kind == Kind::kCornerNormal || kind == Kind::kCornerTexcoord; }
};

struct EncodeOptions {
  // Quantization bits per coordinate, 1..31 (spec 7.1). Ignored when
  // lossless.
  int bits = 16;
  // Keep positions bit-exact (spec 7.2).
  bool lossless = false;
  // The entropy back-end that codes the records (spec/psq-format.md,
  // 13.2). true: static rANS tables per chunk and, when quantized, every
  // new vertex predicted across its gate (13.8.2), for the fastest
  // decoding; every chunk carries its tables, which weighs on small
  // meshes. false: adaptive models with the range coder, for the smallest
  // files, decoding several times slower. Both code the same records
  // (bench/RESULTS.md has the current figures).
  bool fast = false;
  // Normals (float or double nx ny nz) quantized octahedrally with this
  // many bits per coordinate, 2..16 (spec 8.3); 0 keeps them bit-exact in a
  // property column. Ignored when lossless.
  int normal_bits = 0;
  // Texture coordinates (float or double) on a grid of step 2^-uv_bits,
  // 1..24 (spec 8.3); 0 keeps them bit-exact. Ignored when lossless.
  int uv_bits = 0;
  // zstd level of the property streams (spec 8), 1..22.
  int zstd_level = 9;
  // A chunk is closed after the record that brings its coded connectivity
  // and geometry to this many bytes (spec 4.3).
  uint32_t chunk_bytes = 1u << 20;
  // The boundary limit written to the header (spec 4.2): the most active
  // vertices and open edges the stream may have at once. The encoder fails
  // with kLimit when the sequence exceeds it.
  uint32_t boundary_limit = 1u << 24;
  // Triangles per segment (spec 4.6): every this many triangles the
  // encoder writes a segment record, the decoder's state at that point,
  // where a decoder can start (PsqDecoder::start_segment()), so that the
  // segments decode in parallel (decode_segments()). 0: one segment.
  // kAutoSegments (the default): a quarter of the schema's triangle count
  // rounded up to a multiple of 2^16 (four segments, two per core on two
  // cores), at least 2^21; 2^21 when the count is unknown. A segment
  // record costs about 5 bytes per vertex of the boundary where it is
  // (bench/RESULTS.md).
  static constexpr uint64_t kAutoSegments = ~uint64_t{0};
  uint64_t segment_triangles = kAutoSegments;
  // kAutoSegments's size for a mesh with the counts of `schema` (the
  // triangles, else twice the vertices, as a closed mesh has; a PLY
  // header's faces may be polygons): for a caller that knows the input's
  // schema when the encoder's does not have the counts (the sequence
  // builder does not promise them).
  static uint64_t auto_segment_triangles(const MeshSchema& schema) {
    constexpr uint64_t kLeast = uint64_t{1} << 21;
    // Rounded up to a multiple of 2^16, so that a count a little short
    // (an estimate) leaves no tiny fifth segment.
    constexpr uint64_t kRound = uint64_t{1} << 16;
    const int64_t t = schema.triangle_count >= 0 ? schema.triangle_count
                      : schema.vertex_count >= 0 ? 2 * schema.vertex_count
                                                 : -1;
    if (t < 0) return kLeast;
    const uint64_t quarter = (static_cast<uint64_t>(t) + 3) / 4;
    return std::max<uint64_t>(kLeast, (quarter + kRound - 1) / kRound * kRound);
  }
  // Split stats()'s coded bits into connectivity and geometry
  // (PsqStats::connectivity_bits, geometry_bits); off, they stay 0 and
  // encoding is faster (the pricing is skipped).
  bool measure_costs = false;
};

// Sizes and counts of an encoded or decoded stream.
struct PsqStats {
  uint64_t vertices = 0;
  uint64_t triangles = 0;
  uint64_t chunks = 0;
  uint64_t header_bytes = 0;
  uint64_t chunk_overhead_bytes = 0;   // chunk fields, checksums, the end record
  uint64_t segments = 0;               // segment records (spec 4.6): the segments less one
  uint64_t segment_bytes = 0;          // segment records and the index (spec 4.6, 4.7)
  uint64_t record_bytes = 0;           // coded connectivity and geometry (spec 13.2)
  uint64_t property_bytes = 0;         // zstd-compressed properties
  uint64_t attribute_bytes = 0;        // coded attributes (spec 8.3)
  uint64_t total_bytes = 0;
  // The record bytes split by the information content of what was coded
  // (only when measured: EncodeOptions::measure_costs, PsqDecoder::measure_costs):
  double connectivity_bits = 0;
  double geometry_bits = 0;
  uint32_t max_active_vertices = 0;
  uint32_t max_open_edges = 0;
  // Records by how they name their gate (spec 13.7.1): the reference edge,
  // its neighbours, far, and start or isolated vertex; far gates by how
  // they are named: recency rank, slot (an escape) (diagnostics: `psq info`).
  uint64_t gates[4] = {0, 0, 0, 0};
  uint64_t far_gates[2] = {0, 0};
  // Adds by what predicted the new vertex (spec 7.3): the parallelogram
  // across the gate, across the open edge before it, after it, the mean of
  // the gate's and the one before, and of the gate's and the one after.
  uint64_t predictions[5] = {0, 0, 0, 0, 0};
};

class PsqEncoder : public SequenceSink {
 public:
  // `out` must outlive the encoder.
  PsqEncoder(ByteWriter* out, const EncodeOptions& options);
  ~PsqEncoder() override;

  // Writes the header. Errors: kUsage (bad options; quantization without
  // the schema's bounds, or bounds with a minimum above the maximum),
  // kBadValue (bounds not finite), kLimit (schema too large; quantized, a
  // box whose extent overflows a double or whose step underflows to zero:
  // no grid holds it, encode lossless), the writer's.
  Status begin(const MeshSchema& schema) override;
  // A vertex introduced with a boundary slot (SequenceVertex::slot) must be
  // referenced by triangles with that slot (SequenceTriangle::vslot), as the
  // converter and the decoder do; the encoder then finds it without
  // hashing. Errors for the events: kBadSequence when they do not form a
  // valid processing sequence (spec/psq-dump.md A.2), kLimit when the boundary
  // exceeds the limit, kBadValue for a position that is not finite, not of
  // the position type, or (quantized) outside the grid of the bounds given
  // to begin(), kLimit for a quantized position that would not decode
  // within half a step (spec 2.3, 7.1: never clamped), and the writer's
  // errors; position errors name the vertex. Errors are sticky.
  Status vertex(const SequenceVertex& v) override;
  Status triangle(const SequenceTriangle& t) override;
  Status finalize(uint32_t index) override;
  // Writes the last chunk and the end record.
  Status finish() override;

  const PsqStats& stats() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// The header of a .psq stream (spec 4.2).
struct PsqHeader {
  int version_major = 1;
  int version_minor = 0;
  bool lossless = false;
  bool rotation = false;  // triangle rotations are coded (face properties)
  bool fast = false;      // the rANS back-end (spec/psq-format.md, 13.2); else adaptive
  int bits = 0;           // 0 when lossless
  double origin[3] = {0, 0, 0};
  double step = 0;
  uint32_t boundary_limit = 0;
  // Triangles per segment (spec 4.6): a decoder can start at each segment
  // record, one every this many triangles; 0: the stream is one segment.
  uint64_t segment_triangles = 0;
  MeshSchema schema;
  // The vertex attributes coded by prediction (spec 8.3), with their bits:
  // what a quantized stream changed beyond the positions.
  std::vector<CodedAttribute> attributes;
};


// A segment of a stream (spec/psq-format.md 4.6): where its segment
// record starts (for the first, the first byte after the header), and the
// vertex and triangle events before it.
struct PsqSegment {
  uint64_t offset = 0;
  uint64_t vertices = 0;
  uint64_t triangles = 0;
};

class PsqDecoder : public SequenceSource {
 public:
  PsqDecoder();
  ~PsqDecoder() override;

  // Reads and checks the header from `in`, which must outlive the decoder.
  // Errors (with the byte offset): kUnknownFormat (no magic), kUnsupported
  // (version or flags), kBadHeader, kLimit, kChecksum, kTruncated, kIo.
  Status open(InputStream* in);

  const PsqHeader& header() const;
  const MeshSchema& schema() const override;
  // The next event; after the last, Kind::kEnd. Errors (sticky, with the
  // byte offset): kTruncated, kChecksum, kBadValue (corrupt records),
  // kLimit, kBadHeader (bad chunk or end fields), kIo.
  Status next(SequenceEvent* event) override;

  // Pushes the rest of the sequence into `sink`: begin, every event, finish.
  // The same events as next() without copying them; the fastest way to
  // decode. A sink that gives its arrays (SequenceSink::mesh_arrays(),
  // MeshArraySink in psq/mesh_arrays.h) gets the mesh appended to them
  // straight from the records instead, unless next() was called before.
  // Errors: next()'s, and the sink's.
  Status pump(SequenceSink& sink);

  // Independent segments (spec/psq-format.md 4.6, 4.7). After open(), on
  // an input that can seek (a file or memory): the stream's segments from
  // its index, in order; the first starts after the header. A stream
  // without segment records is one segment. Errors: kIo (a pipe), the
  // index's errors (kBadHeader, kChecksum, kTruncated). `end` (optional):
  // where the end record begins and the totals it declares.
  Status segments(std::vector<PsqSegment>* out, PsqSegment* end = nullptr);
  // After open() and before any event: decode only `segment` (one of
  // segments()). next() and pump() then give its events, with the
  // stream's vertex indices (its first vertex event has index
  // segment.vertices; its triangles may use vertices of earlier segments
  // that are still active, and re-appearing vertices may name any earlier
  // vertex), and end (Kind::kEnd) at its end. The checks that need the
  // other segments (the stream checksum, the totals of the end record,
  // and that each segment ends in the state the next one starts from) are
  // decode_segments()'s. The slots it reports are its boundary's, numbered
  // from the segment record (spec 4.6): the other events are those of a
  // decoder that reads the stream from its start. Errors: next()'s, and
  // kBadValue for a state block that is not one.
  Status start_segment(const PsqSegment& segment);
  // Enables the connectivity/geometry cost split in stats() (slower).
  void measure_costs(bool on);
  // Complete once next() returned Kind::kEnd.
  const PsqStats& stats() const;

 private:
  friend class SegmentRun;
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Decodes a stream segment by segment (spec/psq-format.md 4.6), `threads`
// segments at a time (0: one per core): each thread opens the stream
// with `open` (a fresh InputStream on the same bytes: a file or memory),
// and `work(decoder, k)` decodes segment k with a decoder that
// start_segment() began there (pump() or next() to the end). Then it
// makes the checks that need every segment, so that it accepts exactly
// the streams that one decoder reading from the start accepts: each
// segment ends in the state the next one starts from, the stream
// checksum, the end record's totals and maxima. `stats` (optional): the
// sums over the segments. A stream of one segment is decoded by one
// thread. Errors: the first segment's error in stream order, else the
// decoder's errors for the checks above; kIo for an input that cannot
// seek.
Status decode_segments(const std::function<Status(InputStream*)>& open, int threads,
                       const std::function<Status(PsqDecoder&, size_t)>& work, PsqStats* stats);

// The mesh of a stream of several segments decoded with decode_segments()
// straight into `mesh`'s arrays, which it sizes for the whole mesh from
// the index and the end record (their pages are touched only as the
// segments write them). `flush` (optional) is called by the thread that
// decodes a segment, between chunks, with the ranges of the arrays it
// wrote since its last call: positions [p0, p1) and indices [i0, i1) (in
// floats and indices), so that a writer can take them and drop their
// pages. Errors: kUnsupported when the stream cannot be decoded this way
// (no readable index, a vertex that re-appears: decode it with one
// decoder instead); decode_segments()'s and `flush`'s errors.
Status decode_mesh_segments(const std::function<Status(InputStream*)>& open, int threads, MeshBuffers* mesh,
                            const std::function<Status(size_t, size_t, size_t, size_t)>& flush);

// True when `data` (at least 8 bytes) starts with the .psq magic.
bool is_psq(const uint8_t* data, size_t size);

}  // namespace psq

#endif  // PSQ_PSQ_CODEC_H_
