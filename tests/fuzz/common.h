// SPDX-License-Identifier: Apache-2.0
// Shared pieces of psq's libFuzzer targets: a sink that discards, a soup
// source, a sequence recorder, and the "every accepted mesh gives a valid
// processing sequence" oracle.
#ifndef PSQ_TESTS_FUZZ_COMMON_H_
#define PSQ_TESTS_FUZZ_COMMON_H_

#include <array>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

#include "psq/indexed_mesh.h"
#include "psq/io.h"
#include "psq/mesh_formats.h"
#include "psq/sequence.h"
#include "psq/sequence_builder.h"
#include "psq/sequence_check.h"
#include "psq/status.h"

namespace psq::fuzz {

// Accepts everything, counts what it saw.
class DiscardSink : public MeshSink {
 public:
  Status begin(const MeshSchema&) override { return Status(); }
  Status vertex(const double[3], const PropertyValues&) override {
    ++vertices;
    return Status();
  }
  Status triangle(const uint32_t[3], const PropertyValues&) override {
    ++triangles;
    return Status();
  }
  Status finish() override { return Status(); }
  uint64_t vertices = 0;
  uint64_t triangles = 0;
};

// A SequenceChecker that remembers whether it rejected anything, so that a
// checker failure can be told apart from an error of the source.
class RecordingChecker : public SequenceSink {
 public:
  Status begin(const MeshSchema& s) override { return note(checker.begin(s)); }
  Status vertex(const SequenceVertex& v) override { return note(checker.vertex(v)); }
  Status triangle(const SequenceTriangle& t) override { return note(checker.triangle(t)); }
  Status finalize(uint32_t i) override { return note(checker.finalize(i)); }
  Status finish() override { return note(checker.finish()); }
  SequenceChecker checker;
  bool rejected = false;
  Status first_error;

 private:
  Status note(Status s) {
    if (!s.ok() && !rejected) {
      rejected = true;
      first_error = s;
    }
    return s;
  }
};

// An index soup of up to 64 vertices: vertex i at (i, i*i mod 7, i mod 3),
// optionally with a uchar vertex property (i mod 256) and an int face
// property (minus the triangle's number), vertices before triangles or
// after them (fuzz_sequence, fuzz_encoder).
struct Soup {
  uint32_t n = 0;
  bool faces_first = false;
  bool with_values = false;
  std::vector<std::array<uint32_t, 3>> triangles;
};

class SoupSource : public MeshSource {
 public:
  explicit SoupSource(const Soup& soup) : soup_(soup) {
    schema_.position_type = ScalarType::kFloat32;
    schema_.vertex_count = soup.n;
    schema_.triangle_count = static_cast<int64_t>(soup.triangles.size());
    if (soup.with_values) {
      Property q;
      q.name = "quality";
      q.type = ScalarType::kUInt8;
      schema_.vertex_properties.push_back(q);
      // Attributes the encoder codes by prediction (spec 8.3), when asked.
      for (const char* name : {"nx", "ny", "nz", "u", "v", "red", "green", "blue"}) {
        Property a;
        a.name = name;
        a.type = name[0] == 'n' || name[1] == 0 ? ScalarType::kFloat32 : ScalarType::kUInt8;
        schema_.vertex_properties.push_back(a);
      }
      // Corner attributes (spec 8.5), coded as such when asked; with an
      // odd vertex count no other face property, so no rotation kept.
      for (const char* name : {"corner_normals", "corner_uv"}) {
        Property c;
        c.name = name;
        c.type = ScalarType::kFloat32;
        c.is_list = true;
        c.count_type = ScalarType::kUInt8;
        schema_.face_properties.push_back(c);
      }
      if (soup.n % 2 == 0) {
        Property id;
        id.name = "face_id";
        id.type = ScalarType::kInt32;
        schema_.face_properties.push_back(id);
      }
    }
  }

  const MeshSchema& schema() const override { return schema_; }
  const SourceReport& report() const override { return report_; }

  Status next(MeshItem* item) override {
    const size_t nv = soup_.n, nt = soup_.triangles.size();
    if (at_ >= nv + nt) {
      item->kind = MeshItem::Kind::kEnd;
      item->values.clear();
      return Status();
    }
    const size_t k = at_++;
    const bool vertex = soup_.faces_first ? k >= nt : k < nv;
    item->values.clear();
    if (vertex) {
      const uint32_t i = static_cast<uint32_t>(soup_.faces_first ? k - nt : k);
      item->kind = MeshItem::Kind::kVertex;
      item->position[0] = i;
      item->position[1] = (i * i) % 7;
      item->position[2] = i % 3;
      if (soup_.with_values) {
        item->values.push_back(i % 256);
        const double n[3] = {static_cast<double>(i % 3) - 1, static_cast<double>((i * i) % 5) - 2, 1};
        item->values.insert(item->values.end(), n, n + 3);
        item->values.push_back(0.125 * (i % 7));
        item->values.push_back(0.25 * (i % 11) - 1);
        for (uint32_t m : {37u, 11u, 5u}) item->values.push_back((i * m) % 256);
      }
    } else {
      const size_t t = soup_.faces_first ? k : k - nv;
      item->kind = MeshItem::Kind::kTriangle;
      for (int c = 0; c < 3; ++c) item->index[c] = soup_.triangles[t][c];
      if (soup_.with_values) {
        // Corner normals and texture coordinates by vertex, split where
        // the triangle's index says (a crease, a seam).
        item->values.push_back(9);
        for (int c = 0; c < 3; ++c) {
          const uint32_t i = item->index[c];
          const double n[3] = {static_cast<double>(i % 3) - 1, static_cast<double>(t % 3 == 0), 1};
          item->values.insert(item->values.end(), n, n + 3);
        }
        item->values.push_back(6);
        for (int c = 0; c < 3; ++c) {
          const uint32_t i = item->index[c];
          item->values.push_back(0.125 * (i % 7) + (t % 4 == 0 ? 0.5 : 0));
          item->values.push_back(0.25 * (i % 11) - 1);
        }
        if (soup_.n % 2 == 0) item->values.push_back(-static_cast<double>(t));
      }
    }
    return Status();
  }

 private:
  const Soup& soup_;
  MeshSchema schema_;
  SourceReport report_;
  size_t at_ = 0;
};

// Records a sequence's schema and events.
struct SequenceRecorder : SequenceSink {
  Status begin(const MeshSchema& s) override {
    schema = s;
    return Status();
  }
  Status vertex(const SequenceVertex& v) override {
    push(SequenceEvent::Kind::kVertex).vertex = v;
    return Status();
  }
  Status triangle(const SequenceTriangle& t) override {
    push(SequenceEvent::Kind::kTriangle).triangle = t;
    return Status();
  }
  Status finalize(uint32_t index) override {
    push(SequenceEvent::Kind::kFinalize).finalized = index;
    return Status();
  }
  Status finish() override { return Status(); }
  MeshSchema schema;
  std::vector<SequenceEvent> events;

 private:
  SequenceEvent& push(SequenceEvent::Kind kind) {
    events.emplace_back();
    events.back().kind = kind;
    return events.back();
  }
};

[[noreturn]] inline void die(const char* what, const Status& s) {
  std::fprintf(stderr, "psq fuzz: %s: %s (%s)\n", what, s.to_string().c_str(),
               error_name(s.code()));
  __builtin_trap();
}

// Builds the processing sequence of `source` into a SequenceChecker. Traps
// when the checker rejects the sequence or when build_sequence fails with
// an error that `source` (which must be a fresh source over input that was
// already read successfully once) cannot explain. kIo (temporary files) is
// the environment, not psq, and is ignored.
inline void check_sequence(MeshSource& source, const BuildOptions& options, const char* what) {
  RecordingChecker checker;
  BuildReport report;
  Status s = build_sequence(source, checker, options, &report);
  if (checker.rejected) die(what, checker.first_error);
  if (!s.ok() && s.code() != ErrorCode::kIo) die(what, s);
}

// Options of the forced external-sort path with a small budget.
inline BuildOptions sort_options() {
  BuildOptions o;
  o.force_sort = true;
  o.memory_budget = uint64_t{1} << 20;
  return o;
}

// The whole body of a reader's fuzz target: the reader over the bytes (any
// Status is fine); when it accepts them, the mesh again into build_sequence,
// with default options and with the forced external sort, whose sequence
// must pass SequenceChecker. Meshes over `max_elements` skip the second part
// (it would only be slower).
template <class Reader>
int fuzz_reader(const uint8_t* data, size_t size, const char* format, uint64_t max_elements = 100000) {
  (void)detect_format(data, size);  // content sniffing is a parser too
  DiscardSink sink;
  {
    InputStream in;
    in.open_memory(data, size, "<fuzz>");
    Reader reader;
    if (!reader.open(&in).ok()) return 0;
    if (!pump(reader, sink).ok()) return 0;
    (void)reader.report();
  }
  if (sink.vertices > max_elements || sink.triangles > max_elements) return 0;
  const BuildOptions options[2] = {BuildOptions(), sort_options()};
  const char* paths[2] = {"build_sequence (default)", "build_sequence (force_sort, 1 MiB)"};
  for (int i = 0; i < 2; ++i) {
    InputStream in;
    in.open_memory(data, size, "<fuzz>");
    Reader reader;
    Status s = reader.open(&in);
    if (!s.ok()) die("input accepted once, rejected the second time", s);
    std::string what = std::string(format) + " -> " + paths[i];
    check_sequence(reader, options[i], what.c_str());
  }
  return 0;
}

}  // namespace psq::fuzz

#endif  // PSQ_TESTS_FUZZ_COMMON_H_
