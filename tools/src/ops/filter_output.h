// SPDX-License-Identifier: Apache-2.0
// tools/src/ops (see json.h): the output side of a filter (psq simplify,
// psq smooth, psq.simplify): a .psq through the encoder, or PLY, OBJ or
// Draco through a mesh writer, fed by a sequence filter (stream edge
// collapse, smoothing) or by a mesh-stream filter (vertex clustering,
// whose output the processing-sequence converter orders for the encoder).
#ifndef PSQ_TOOLS_OPS_FILTER_OUTPUT_H_
#define PSQ_TOOLS_OPS_FILTER_OUTPUT_H_

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "psq/converter.h"
#include "psq/mesh_formats.h"
#include "psq/mesh_stream.h"
#include "psq/psq_codec.h"
#include "psq/threaded_mesh_sink.h"
#include "psq/threaded_sink.h"

namespace psq::detail {

// How a filter's .psq output is encoded, from its input and options:
// `bits` when given (not 0), else a quantized .psq input's bits, else 16;
// lossless when asked, or for a sequence filter (`sequence_filter`) over
// a lossless .psq, which gives no bounding box to quantize on before its
// first vertex; profile "fast", "compact" or "auto": fast when the input is
// a fast .psq or, for a mesh-stream filter (clustering), a large mesh
// (auto_fast_profile()). False when `bits` was given for a sequence filter
// over a lossless .psq (the caller words the usage error). Normals and
// texture coordinates keep a .psq input's quantization (exact when it
// kept them exact); from another input they are quantized as psq convert
// does by default (10 and 12 bits).
// Its chunks close at kFilterChunkBytes coded bytes. Its segments split
// the output in four, as a conversion of a mesh of that size would, once
// filter_segments() knows how many triangles to expect.
bool filter_encoding(const OpenedMesh& input, int bits, bool lossless, const std::string& profile,
                     bool sequence_filter, EncodeOptions* encode);
constexpr uint32_t kFilterChunkBytes = 256u << 10;

// Sets encode->segment_triangles (when left automatic) for an output of
// about `triangles` triangles, or else of `share` times the input's
// (auto_segment_triangles()): without it the encoder takes 2^21-triangle
// segments, as for any stream of unknown length, which on a filter's
// large output (smoothing keeps every triangle) is many more than two
// cores use, each with its state block. Nothing is set when neither is
// known (0).
void filter_segments(OpenedMesh& input, uint64_t triangles, double share, EncodeOptions* encode);

// How psq simplify's --memory is split among the stages of a clustering
// run (psq/memory_budget.h): half for the sequence builder (a mesh
// input), a quarter for the filter, a 64th for the output converter's
// lookahead, the rest for an in-core writer (Draco).
struct ClusteringBudget {
  uint64_t build = 0, filter = 0, lookahead = 0, writer = 0;
};
ClusteringBudget split_clustering_budget(uint64_t memory);

// A sequence filter's share of `memory` (psq simplify --method qem,
// psq smooth): the sequence builder reads a mesh input within half of it;
// the decoder of a .psq and the encoder keep their boundaries and a chunk
// each, the process about 30 MB on a 200M-triangle foam ball
// (bench/RESULTS.md, "Simplification: stream edge collapse"); the filter
// gets the rest.
uint64_t sequence_filter_budget(uint64_t memory, bool psq_input);

class FilterOutput {
 public:
  FilterOutput() = default;
  ~FilterOutput();  // stops the output's thread first
  FilterOutput(const FilterOutput&) = delete;
  FilterOutput& operator=(const FilterOutput&) = delete;

  // The writer of `format` into `file` (which must outlive this): the .psq
  // encoder with `encode`, else make_mesh_writer() with `write`, whose
  // Draco bits (at most 30) and losslessness come from `encode`.
  void open(OutputFile* file, MeshFormat format, const EncodeOptions& encode, WriteOptions write);

  // What a sequence filter writes to: the encoder (with `threaded` on a
  // thread of its own), or the mesh writer through SequenceToMesh. Once.
  SequenceSink* sequence_sink(bool threaded);

  // What a mesh-stream filter writes to: the converter into the encoder,
  // or the mesh writer through DenseMeshSink; with `count_nonmanifold`, for
  // a mesh format, a converter besides that only counts the output's
  // non-manifold vertices and edges (converter_stats()). The converters'
  // lookahead: `lookahead_budget` bytes, at least kLookaheadMinimum
  // triangles. With `threaded`, all of it runs on a thread of its own.
  // Once.
  StreamingMeshSink* mesh_sink(uint64_t lookahead_budget, bool count_nonmanifold, bool threaded);

  // The converter's statistics, or null when there is none.
  const ConverterStats* converter_stats() const { return converter_ ? &converter_->stats() : nullptr; }
  // What the mesh writer could not hold (writer_notes()).
  std::vector<std::string> notes() const;
  // Stops the output's thread (before a failed output is discarded).
  void stop();

  // The converter keeps at least this many ready triangles waiting
  // (psq/converter.h, set_lookahead_minimum()): its default of 65536 and
  // 32 per open edge made it the largest structure of a run (65 MB peak
  // for a 50M-triangle foam simplified to 10%). This, with a 64th of
  // --memory as its cap (4 MB by default), keeps a 200M-triangle foam at
  // 10% under 57 MB for 0.4% more output bytes than a 32nd.
  static constexpr uint64_t kLookaheadMinimum = 4096;

 private:
  MeshFormat format_ = MeshFormat::kUnknown;
  std::unique_ptr<FileWriter> byte_writer_;
  std::unique_ptr<PsqEncoder> encoder_;
  std::unique_ptr<MeshSink> writer_;
  std::unique_ptr<SequenceSink> to_mesh_;
  std::unique_ptr<DenseMeshSink> dense_;
  std::unique_ptr<SequenceSink> discard_;
  std::unique_ptr<SequenceConverter> converter_;
  std::unique_ptr<TeeMeshSink> tee_;
  std::unique_ptr<ThreadedSequenceSink> threaded_sequence_;
  std::unique_ptr<ThreadedMeshSink> threaded_mesh_;
};

}  // namespace psq::detail

#endif  // PSQ_TOOLS_OPS_FILTER_OUTPUT_H_
