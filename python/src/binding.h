// SPDX-License-Identifier: Apache-2.0
// python/src/binding.h: the C++ half of the Python module `psq`, free of
// pybind11 so that only module.cpp pays for its headers. Everything here
// runs without the GIL: it takes and returns plain C++ buffers, which
// module.cpp hands to numpy without copying (the vectors move into capsules
// that become the arrays' bases).
//
// Errors are thrown as StatusError (a psq::Status and the file it is
// about); module.cpp turns them into the psq.Error subclass of the code.
#ifndef PSQ_PYTHON_BINDING_H_
#define PSQ_PYTHON_BINDING_H_

#include <cstdint>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "psq/indexed_mesh.h"
#include "psq/io.h"
#include "psq/mesh_formats.h"
#include "psq/psq_codec.h"
#include "psq/psq_memory.h"
#include "psq/status.h"
#include "psq/stream_qem.h"

namespace psq::python {

template <class T>
using Buffer = std::vector<T, DefaultInitAllocator<T>>;

// A psq::Status that left the library, with the file (or "<memory>") it
// concerns.
class StatusError : public std::runtime_error {
 public:
  StatusError(Status status, std::string file)
      : std::runtime_error(status.to_string()), status_(std::move(status)), file_(std::move(file)) {}
  const Status& status() const { return status_; }
  const std::string& file() const { return file_; }

 private:
  Status status_;
  std::string file_;
};

// Throws StatusError for an error status.
void check(const Status& s, const std::string& file);
// Throws a kUsage StatusError.
[[noreturn]] void usage(const std::string& message);

// One vertex or face property as columns: a scalar property has one value
// per element in `values` (raw bytes of prop.type); a list property has a
// count per element in `counts` and all the lists' values, concatenated, in
// `values`.
struct Column {
  Property prop;
  Buffer<uint8_t> values;
  Buffer<uint32_t> counts;
  uint64_t value_count = 0;
};

// A whole mesh in memory.
struct MeshData {
  ScalarType position_type = ScalarType::kFloat32;
  Buffer<float> positions_f;   // float32 meshes: x y z per vertex
  Buffer<double> positions_d;  // float64 meshes
  Buffer<uint32_t> faces;      // three indices per triangle
  std::vector<Column> vertex_properties, face_properties;
  std::string format;               // "psq", "ply", ...
  std::vector<std::string> notes;   // the reader's (SourceReport::notes)
  uint64_t vertex_count() const {
    return (position_type == ScalarType::kFloat64 ? positions_d.size() : positions_f.size()) / 3;
  }
};

// Reads any mesh psq reads (by content) from a path (a regular file, a
// pipe) or from memory. A .psq without properties and with float
// positions goes through decode_mesh(), the codec's fastest path.
void read_path(const std::string& path, MeshData* out);
void read_memory(const uint8_t* data, size_t size, const std::string& name, MeshData* out);

// Borrowed arrays to write (held alive by the caller).
struct InColumn {
  Property prop;
  const void* values = nullptr;     // prop.type values
  uint64_t value_count = 0;
  const uint32_t* counts = nullptr;  // lists: one per element
};
struct InMesh {
  const void* positions = nullptr;
  bool positions_double = false;
  uint64_t vertices = 0;
  const uint32_t* faces = nullptr;
  uint64_t triangles = 0;
  std::vector<InColumn> vertex_properties, face_properties;
};

struct WriteParams {
  std::string format;     // "psq", "ply", "obj", "drc"; empty: from the path
  int bits = 16;
  bool lossless = false;
  int normal_bits = 0;           // normals: octahedral bits (2..16), 0 exact
  int uv_bits = 0;               // texture coordinates: a grid of 2^-uv_bits (1..24), 0 exact
  std::string profile = "auto";  // compact, fast, auto
  uint32_t chunk_bytes = 1u << 20;
  int zstd_level = 9;
  bool ascii = false;
  bool overwrite = true;
  uint64_t memory = uint64_t{512} << 20;
  std::string tmpdir;
};

// The .psq encoder's options of `params` (kUsage when bits, profile,
// chunk_bytes or zstd_level are out of range); `fast_auto`: what profile
// "auto" means for the input at hand.
EncodeOptions encode_options(const WriteParams& params, bool fast_auto);
// The mesh writers' options of `params`.
WriteOptions write_options(const WriteParams& params);

// Checks the columns against the element counts (kUsage).
void check_in_mesh(const InMesh& mesh);
// Writes `mesh` to `path` in the format of `params` or its extension.
// Returns notes on what the format could not hold (properties OBJ or
// Draco drop), as psq convert prints them.
std::vector<std::string> write_path(const InMesh& mesh, const std::string& path, const WriteParams& params);
// Encodes `mesh` to .psq bytes.
void encode_bytes(const InMesh& mesh, const WriteParams& params, std::vector<uint8_t>* out);

// What a streaming chunk holds (psq.open): the events of the processing
// sequence between two chunk boundaries.
struct Chunk {
  uint64_t vertex_start = 0;    // dense index of the first vertex introduced here
  uint64_t triangle_start = 0;  // index of the first triangle here
  Buffer<float> positions_f;    // the vertices introduced, as MeshData
  Buffer<double> positions_d;
  Buffer<int64_t> reappears;    // per introduced vertex: its first occurrence, or -1
  Buffer<uint32_t> faces;       // dense (sequence) indices
  Buffer<uint8_t> ops, new_mask, final_mask, border_mask;
  Buffer<uint32_t> finalized;   // vertices whose last use went by, in order
  std::vector<Column> vertex_properties, face_properties;
  bool end = false;             // nothing more: the stream ended before any event
};

// A .psq read chunk by chunk with the streaming decoder: memory is the
// decoder's (the processing boundary and one compressed chunk) plus the
// chunk being filled.
class StreamReader {
 public:
  StreamReader();
  ~StreamReader();
  // Opens a path, or memory that must outlive the reader.
  void open_path(const std::string& path);
  void open_memory(const uint8_t* data, size_t size);
  const PsqHeader& header() const;
  const std::string& name() const { return name_; }
  // The next chunk: events until `max_triangles` triangles (and the
  // finalizations right after the last) or `max_triangles` introduced
  // vertices. chunk->end when the sequence had ended.
  void next(uint64_t max_triangles, Chunk* chunk);
  const PsqStats& stats() const;
  void close();

 private:
  std::string name_;
  std::unique_ptr<InputStream> in_;
  std::unique_ptr<PsqDecoder> decoder_;
  SequenceEvent pending_;
  bool has_pending_ = false;
  bool done_ = false;
  uint64_t vertices_ = 0, triangles_ = 0;
};

// The library's tools, each returning the JSON text the psq command prints
// with --json (module.cpp parses it into a dict).
struct ConvertParams {
  WriteParams write;
  std::string weld = "off";  // "all" or "positions": psq convert --weld
  int threads = 2;
  bool measure_costs = false;
};
std::string convert(const std::string& in, const std::string& out, const ConvertParams& params);

struct SimplifyParams {
  std::string method = "clustering";  // or "qem"
  double ratio = 0;                   // 0: none
  uint64_t triangles = 0;             // 0: none
  // clustering
  double grid = 0;                    // 0: the default 256 unless cell or a target is given
  double cell = 0;
  std::string cells = "connected";
  double border_weight = 1;
  // qem: max_error, buffer_triangles, candidates, lock_border, seed (its
  // ratio, target and budget come from the fields here)
  QemOptions qem;
  // output
  std::string format;
  int bits = 0;                       // 0: the input's (a quantized .psq), else 16
  bool lossless = false;
  std::string profile = "auto";
  bool ascii = false;
  bool overwrite = true;
  uint64_t memory = uint64_t{256} << 20;
  std::string tmpdir;
};
std::string simplify(const std::string& in, const std::string& out, const SimplifyParams& params);

struct InfoParams {
  uint64_t memory = uint64_t{512} << 20;
  std::string tmpdir;
};
std::string info(const std::string& path, const InfoParams& params);

struct DistanceParams {
  uint64_t samples = 0;
  uint64_t seed = 1;
  int threads = 0;
  std::string hold = "auto";  // auto, a, b, both
  std::string tmpdir;
};
std::string distance(const std::string& a, const std::string& b, const DistanceParams& params);

}  // namespace psq::python

#endif  // PSQ_PYTHON_BINDING_H_
