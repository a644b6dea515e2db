// SPDX-License-Identifier: Apache-2.0
// The output side of a filter; see filter_output.h.
#include "filter_output.h"

#include <algorithm>

#include "pipeline.h"
#include "psq/memory_budget.h"

namespace psq::detail {
namespace {

// Drops a sequence: the converter in front of it only counts.
class DiscardSequence : public SequenceSink {
 public:
  Status begin(const MeshSchema&) override { return Status(); }
  Status vertex(const SequenceVertex&) override { return Status(); }
  Status triangle(const SequenceTriangle&) override { return Status(); }
  Status finalize(uint32_t) override { return Status(); }
  Status finish() override { return Status(); }
};

}  // namespace

bool filter_encoding(const OpenedMesh& input, int bits, bool lossless, const std::string& profile,
                     bool sequence_filter, EncodeOptions* e) {
  const PsqHeader* h = input.decoder ? &input.decoder->header() : nullptr;
  if (h && h->lossless && sequence_filter && bits && !lossless) return false;
  e->lossless = lossless || (h && h->lossless && sequence_filter);
  e->bits = bits ? bits : (h && !h->lossless) ? h->bits : 16;
  const bool large = !sequence_filter && auto_fast_profile(h ? input.decoder->schema() : input.source->schema());
  e->fast = profile == "fast" || (profile == "auto" && ((h && h->fast) || large));
  // A filter's output encoder holds a chunk's symbols (4 bytes each, up to
  // twice chunk_bytes of them: 8 MiB at the default 1 MiB) beside the
  // filter; smaller chunks keep psq simplify within 64 MB on the largest
  // inputs, for a little more in tables (bench/RESULTS.md, "Speed and
  // memory at 50M and 200M triangles").
  e->chunk_bytes = kFilterChunkBytes;
  // Normals and texture coordinates (spec 8.3 to 8.5): a .psq input's
  // quantization (0, exact, when it kept them in columns), else psq
  // convert's defaults.
  e->normal_bits = h ? 0 : 10;
  e->uv_bits = h ? 0 : 12;
  if (h)
    for (const CodedAttribute& a : h->attributes) {
      if (a.kind == CodedAttribute::Kind::kNormal || a.kind == CodedAttribute::Kind::kCornerNormal) e->normal_bits = a.bits;
      if (a.kind == CodedAttribute::Kind::kTexcoord || a.kind == CodedAttribute::Kind::kCornerTexcoord) e->uv_bits = a.bits;
    }
  return true;
}

void filter_segments(OpenedMesh& input, uint64_t triangles, double share, EncodeOptions* e) {
  if (e->segment_triangles != EncodeOptions::kAutoSegments) return;
  if (triangles > 0) {
    MeshSchema counts;
    counts.triangle_count = static_cast<int64_t>(std::min<uint64_t>(triangles, uint64_t{1} << 62));
    e->segment_triangles = EncodeOptions::auto_segment_triangles(counts);
  } else if (share > 0) {
    e->segment_triangles = auto_segment_triangles(input, share);
  }
}

ClusteringBudget split_clustering_budget(uint64_t memory) {
  MemoryBudget budget(memory);
  ClusteringBudget b;
  b.build = budget.draw(1, 2);
  b.filter = budget.draw(1, 4);
  b.lookahead = budget.draw(1, 64);
  b.writer = budget.draw_rest();
  return b;
}

uint64_t sequence_filter_budget(uint64_t memory, bool psq_input) {
  return psq_input ? memory - std::min<uint64_t>(memory / 2, uint64_t{30} << 20) : memory / 2;
}

FilterOutput::~FilterOutput() { stop(); }

void FilterOutput::stop() {
  threaded_mesh_.reset();
  threaded_sequence_.reset();
}

void FilterOutput::open(OutputFile* file, MeshFormat format, const EncodeOptions& encode, WriteOptions write) {
  format_ = format;
  if (format == MeshFormat::kPsq) {
    byte_writer_ = std::make_unique<FileWriter>(file);
    encoder_ = std::make_unique<PsqEncoder>(byte_writer_.get(), encode);
    return;
  }
  write.draco_bits = std::min(encode.bits, 30);
  write.lossless = encode.lossless;
  writer_ = make_mesh_writer(format, file, write);
}

SequenceSink* FilterOutput::sequence_sink(bool threaded) {
  SequenceSink* sink = nullptr;
  if (encoder_) {
    sink = encoder_.get();
  } else {
    to_mesh_ = std::make_unique<SequenceToMesh>(writer_.get());
    sink = to_mesh_.get();
  }
  if (threaded) {
    threaded_sequence_ = std::make_unique<ThreadedSequenceSink>(sink);
    sink = threaded_sequence_.get();
  }
  return sink;
}

StreamingMeshSink* FilterOutput::mesh_sink(uint64_t lookahead_budget, bool count_nonmanifold, bool threaded) {
  StreamingMeshSink* sink = nullptr;
  if (encoder_) {
    converter_ = std::make_unique<SequenceConverter>(encoder_.get());
    sink = converter_.get();
  } else {
    dense_ = std::make_unique<DenseMeshSink>(writer_.get());
    sink = dense_.get();
    if (count_nonmanifold) {
      discard_ = std::make_unique<DiscardSequence>();
      converter_ = std::make_unique<SequenceConverter>(discard_.get());
      tee_ = std::make_unique<TeeMeshSink>(dense_.get(), converter_.get());
      sink = tee_.get();
    }
  }
  if (converter_) {
    converter_->set_lookahead_budget(lookahead_budget);
    converter_->set_lookahead_minimum(kLookaheadMinimum);
  }
  if (threaded) {
    // Only the filter's output crosses, a tenth or less of its input.
    threaded_mesh_ = std::make_unique<ThreadedMeshSink>(sink);
    sink = threaded_mesh_.get();
  }
  return sink;
}

std::vector<std::string> FilterOutput::notes() const {
  return writer_ ? writer_notes(format_, writer_.get()) : std::vector<std::string>();
}

}  // namespace psq::detail
