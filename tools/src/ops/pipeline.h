// SPDX-License-Identifier: Apache-2.0
// tools/src/ops (see json.h): the plumbing of a pipeline from an input
// mesh to an output file, as psq simplify, psq smooth and the Python
// module's psq.simplify assemble it.
#ifndef PSQ_TOOLS_OPS_PIPELINE_H_
#define PSQ_TOOLS_OPS_PIPELINE_H_

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "corner_weld.h"
#include "psq/mesh_formats.h"
#include "psq/psq_codec.h"
#include "psq/sequence.h"
#include "psq/sequence_builder.h"

namespace psq::detail {

// What a long run reports as it goes: the psq command draws its progress
// line from it (tools/cli/progress.h). Called on the thread that reads the
// input.
class RunObserver {
 public:
  virtual ~RunObserver() = default;
  // One triangle of the input read.
  virtual void triangle_read() = 0;
  // One triangle passed on after the input was read (a spooled or decoded
  // sequence going out).
  virtual void triangle_written() = 0;
};

// Whether two paths name the same existing file ("-", standard input or
// output, never does).
bool same_file(const std::string& a, const std::string& b);

// Whether the error of a pipeline from IN to OUT concerns OUT: an I/O
// error with no place in the input (a write that failed). A place in the
// input, or any complaint about the data (a position the output cannot
// hold, a count over a limit), concerns IN.
bool error_is_about_output(const Status& status);

// The output format named `name` ("psq", "ply", "obj", "drc"), or when
// `name` is empty the one of `path`'s extension; kUnknown when neither
// tells.
MeshFormat output_format(const std::string& name, const std::string& path);

// What --profile auto picks for a .psq written from a mesh of `schema`
// (psq convert, psq simplify): fast for 131072 triangles or more, or, when
// the triangles are not declared, 65536 vertices or more.
bool auto_fast_profile(const MeshSchema& schema);

// The notes of a mesh writer of `format` (make_mesh_writer()): the
// properties OBJ or Draco could not hold, and the Draco writer's own.
std::vector<std::string> writer_notes(MeshFormat format, MeshSink* writer);

// The input's notes: the reader's, and the triangles the sequence builder
// dropped as degenerate.
std::vector<std::string> input_notes(const OpenedMesh& mesh, const BuildReport& build);

// The notes of psq convert's weld (psq/sequence_builder.h): how many
// vertices --weld merged, or, without it, a suggestion when most vertices
// of the input repeat another's position (--weld), or a few of them and
// it has normals or texture coordinates (--weld=corners too).
std::vector<std::string> weld_notes(WeldMode weld, const BuildReport& build, const MeshSchema& input);
// The weld fields of a .psq summary, each after ", ": "weld" ("off",
// "all", "positions" or "corners"), and for a mesh input (`from_mesh`) the
// input's counts and what the weld merged and dropped (`corners`: what
// --weld=corners merged in front of the builder, corner_weld.h).
std::string json_weld(WeldMode weld, const BuildReport& build, bool from_mesh,
                      const CornerWelder* corners = nullptr);

// The fields of a .psq summary that say how it was encoded, each after
// ", ": "lossless", "bits" (0 when lossless) and "profile".
std::string json_encoding(const EncodeOptions& encode);
// The fields of a .psq's size per vertex (PsqStats), "bits_per_vertex"
// first, then connectivity, geometry and properties, without a leading
// ", ".
std::string json_bits_per_vertex(const PsqStats& stats);

// A processing sequence written as an indexed mesh: vertices in the order
// they are introduced, re-appearing vertices (non-manifold cuts, paper
// section 3) merged back into the vertex they re-appear
// (spec/psq-dump.md A.2.1).
class SequenceToMesh : public SequenceSink {
 public:
  explicit SequenceToMesh(MeshSink* out) : out_(out) {}
  Status begin(const MeshSchema& schema) override;
  Status vertex(const SequenceVertex& v) override;
  Status triangle(const SequenceTriangle& t) override;
  Status finalize(uint32_t) override { return Status(); }
  Status finish() override { return out_->finish(); }

 private:
  // Dense sequence index to mesh index: minus the re-appearances before
  // it, or the index of the vertex it re-appears.
  uint32_t mesh_index(uint32_t dense) const;

  MeshSink* out_;
  std::vector<uint32_t> reappearing_, first_;
};

// Passes a mesh on to `next`, counting its vertices and triangles (the
// summary of a conversion to a mesh format).
struct MeshCounter : MeshSink {
  explicit MeshCounter(MeshSink* to) : next(to) {}
  Status begin(const MeshSchema& schema) override { return next->begin(schema); }
  Status vertex(const double position[3], const PropertyValues& values) override {
    ++vertices;
    return next->vertex(position, values);
  }
  Status triangle(const uint32_t index[3], const PropertyValues& values) override {
    ++triangles;
    return next->triangle(index, values);
  }
  Status finish() override { return next->finish(); }

  MeshSink* next;
  uint64_t vertices = 0, triangles = 0;
};

// Takes a sequence's bounding box and counts its triangles, keeping
// nothing else (a lossless .psq declares no box; an input's count).
class SequenceBox : public SequenceSink {
 public:
  Status begin(const MeshSchema&) override { return Status(); }
  Status vertex(const SequenceVertex& v) override;
  Status triangle(const SequenceTriangle&) override {
    ++triangles;
    return Status();
  }
  Status finalize(uint32_t) override { return Status(); }
  Status finish() override { return Status(); }

  bool any = false;  // a vertex went by
  double lo[3] = {0, 0, 0}, hi[3] = {0, 0, 0};
  uint64_t triangles = 0;
};

// Passes a mesh source on, showing its triangles to an observer (if any)
// as read.
class ObservedSource : public MeshSource {
 public:
  ObservedSource(MeshSource* in, RunObserver* observer) : in_(in), observer_(observer) {}
  const MeshSchema& schema() const override { return in_->schema(); }
  const SourceReport& report() const override { return in_->report(); }
  Status next(MeshItem* item) override;

 private:
  MeshSource* in_;
  RunObserver* observer_;
};

// Passes a sequence on, showing its triangles to an observer (if any) as
// read, or with `written` as written.
class ObservedSequence : public SequenceSink {
 public:
  ObservedSequence(SequenceSink* out, RunObserver* observer, bool written = false)
      : out_(out), observer_(observer), written_(written) {}
  Status begin(const MeshSchema& s) override { return out_->begin(s); }
  Status vertex(const SequenceVertex& v) override { return out_->vertex(v); }
  Status triangle(const SequenceTriangle& t) override;
  Status finalize(uint32_t i) override { return out_->finalize(i); }
  Status finish() override { return out_->finish(); }

 private:
  SequenceSink* out_;
  RunObserver* observer_;
  bool written_;
};

// The processing sequence of an opened input into `sink`: a .psq through
// its decoder, any other mesh through the sequence builder (`report`
// filled). With an observer, the triangles read are reported to it.
// `at_begin`, if set, is called right before the sink's begin() with the
// triangles the input yielded so far: all of them for a mesh input, which
// the sequence builder reads completely first; none for a .psq.
Status feed_sequence(OpenedMesh& mesh, SequenceSink& sink, const BuildOptions& build, BuildReport* report,
                     RunObserver* observer = nullptr, const std::function<void(uint64_t)>& at_begin = nullptr);

// The triangles of an opened input: its header's count when it declares
// one, else counted by reading it through (the input is used up then).
Status count_triangles(OpenedMesh& mesh, uint64_t* count);

}  // namespace psq::detail

#endif  // PSQ_TOOLS_OPS_PIPELINE_H_
