// SPDX-License-Identifier: Apache-2.0
// Shared helpers for psq's tests: meshes generated in code, an in-memory sink,
// temporary directories and running the psq binary.
#ifndef PSQ_TESTS_TEST_UTIL_H_
#define PSQ_TESTS_TEST_UTIL_H_

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "psq/indexed_mesh.h"
#include "psq/io.h"
#include "psq/psq_codec.h"
#include "psq/sequence.h"

namespace psq::test {

// A whole mesh in memory, for comparisons in tests.
struct Mesh {
  MeshSchema schema;
  std::vector<std::array<double, 3>> positions;
  std::vector<PropertyValues> vertex_values;
  std::vector<std::array<uint32_t, 3>> triangles;
  std::vector<PropertyValues> face_values;
};

// A MeshSink that keeps everything.
class MemorySink : public MeshSink {
 public:
  Status begin(const MeshSchema& schema) override;
  Status vertex(const double position[3], const PropertyValues& values) override;
  Status triangle(const uint32_t index[3], const PropertyValues& values) override;
  Status finish() override;
  Mesh mesh;
  bool finished = false;
};

// A MeshSource over a Mesh (vertices first, then triangles).
class MemorySource : public MeshSource {
 public:
  explicit MemorySource(Mesh mesh);
  const MeshSchema& schema() const override { return mesh_.schema; }
  Status next(MeshItem* item) override;
  const SourceReport& report() const override { return report_; }

 private:
  Mesh mesh_;
  size_t at_ = 0;
  SourceReport report_;
};

// A closed genus-0 mesh: a UV sphere with `rings` x `segments` quads split in
// triangles, float positions, counts set in its schema.
Mesh make_sphere(int rings, int segments);
// An open grid of (n+1)^2 vertices and 2 n^2 triangles in the z = 0 plane.
Mesh make_grid(int n);
// A mesh of these positions and triangles, without properties, counts set.
Mesh make_mesh(std::vector<std::array<double, 3>> positions, std::vector<std::array<uint32_t, 3>> triangles);
// Sets empty property values for every vertex and triangle and the counts.
void reset_values(Mesh* mesh);

// Overwrites `count` random bytes of the coded records of a .psq stream's
// first chunk with random values and re-signs the chunk (its CRC-32C, spec
// 4.3), as a crafted file would: the decoder's record checks, not the
// checksum, must catch it. `seed` picks the bytes. The stream checksum of
// the end record (4.5) is left as it was.
void garble_first_chunk_records(std::vector<uint8_t>* bytes, uint32_t seed, int count);

// Reads the whole file; fails the test when it cannot.
std::string read_file(const std::string& path);
void write_file(const std::string& path, const std::string& contents);
bool file_exists(const std::string& path);

// A fresh directory under $TMPDIR, removed with its contents at destruction.
class TempDir {
 public:
  TempDir();
  ~TempDir();
  const std::string& path() const { return path_; }
  std::string file(const std::string& name) const { return path_ + "/" + name; }
  // Names of the entries in the directory, sorted.
  std::vector<std::string> entries() const;

 private:
  std::string path_;
};

// Runs the psq binary with `args` (a shell-quoted string); returns its exit
// status and fills stdout/stderr.
int run_psq(const std::string& args, std::string* out, std::string* err,
            const std::string& stdin_file = "");

// Reads `path` through open_mesh() into a Mesh; returns the status.
Status load_mesh(const std::string& path, Mesh* mesh);

// Sorted triangles with each rotated so its smallest index comes first, for
// order-independent comparisons that keep orientation.
std::vector<std::array<uint32_t, 3>> canonical_triangles(const Mesh& mesh);

// A closed genus-1 mesh: a torus (radii 1 and `thickness`) of `around` x
// `across` quads split in triangles, float positions, counts set.
Mesh make_torus(int around, int across, double thickness = 0.3);
// A fan of n triangles around vertex 0, its rim wavy (z = 0.2 sin 7a),
// float coordinates.
Mesh make_wavy_fan(uint32_t n);

// `m` with its vertices and its triangles in a random order (by `seed`),
// indices relabelled, values kept with their elements.
Mesh shuffled(const Mesh& m, uint32_t seed);

// Records every event of a sequence, and its schema.
struct EventLog : SequenceSink {
  Status begin(const MeshSchema& s) override;
  Status vertex(const SequenceVertex& v) override;
  Status triangle(const SequenceTriangle& t) override;
  Status finalize(uint32_t i) override;
  Status finish() override;
  // Every field of every event, one line each, for comparisons of runs.
  std::string text() const;

  MeshSchema schema;
  std::vector<SequenceEvent> events;
  bool finished = false;
};

// The processing sequence of `mesh` (the sequence builder's defaults);
// a failure of the builder fails the calling test.
EventLog build_events(const Mesh& mesh);
// A recorded sequence encoded as .psq into *bytes.
Status encode_sequence(const EventLog& ev, const EncodeOptions& o, std::vector<uint8_t>* bytes);
// 14-bit positions, the attributes' bits, the back-end.
EncodeOptions attribute_options(bool fast, int normal_bits, int uv_bits);
// .psq bytes decoded into *out (its schema and events up to the end), the
// header into *header when given.
Status decode_sequence(const std::vector<uint8_t>& bytes, EventLog* out, PsqHeader* header = nullptr);

// Replays a recorded sequence as a SequenceSource.
class EventReplay : public SequenceSource {
 public:
  explicit EventReplay(const EventLog& log) : log_(log) {}
  const MeshSchema& schema() const override { return log_.schema; }
  Status next(SequenceEvent* e) override;

 private:
  const EventLog& log_;
  size_t at_ = 0;
};

}  // namespace psq::test

#endif  // PSQ_TESTS_TEST_UTIL_H_
