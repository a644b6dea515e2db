// SPDX-License-Identifier: Apache-2.0
// psq_bench_compare: end-to-end size and speed of mesh codecs on the same
// meshes, in one process.
//
// Each mesh is read once into memory (positions as float, triangles as
// uint32 indices; parsing is not timed). Every codec of the table below then
// runs in a forked child: the child encodes the mesh --runs times and sends
// the last encoding back to the parent; a second child decodes those bytes
// --runs times. Timings are medians of the runs. Peak memory of a run is the
// child's ru_maxrss (from wait4) minus its resident size right after fork,
// that is what the codec allocated beyond the mesh (and, for a decoder, the
// encoded bytes) already in memory. See bench/compare_README.md.
//
// Adding a codec is one entry in make_codecs(): a name, an encode function
// (BenchMesh -> bytes) and a decode function (bytes -> decoded counts).
// BenchMeshSource presents a BenchMesh as a psq::MeshSource for codecs that
// read one (the .psq encoder through build_sequence).

#include <draco/compression/decode.h>
#include <draco/compression/encode.h>
#include <draco/core/draco_version.h>
#include <dirent.h>
#include <draco/mesh/mesh.h>
#include <malloc.h>
#include <meshoptimizer.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>
#include <zstd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <chrono>
#include <cinttypes>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <functional>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "psq/indexed_mesh.h"
#include "psq/mesh_formats.h"
#include "psq/psq_codec.h"
#include "psq/psq_memory.h"
#include "psq/sequence_builder.h"
#include "psq/status.h"

#ifndef PSQ_BENCH_MESH_DIR
#define PSQ_BENCH_MESH_DIR ""
#endif

namespace {

using psq::ErrorCode;
using psq::Status;

// ------------------------------------------------------------------ the mesh

// A mesh in memory, the common input of every codec.
struct BenchMesh {
  std::string name;                // file name without directory
  std::vector<float> positions;    // x, y, z per vertex
  std::vector<uint32_t> indices;   // 3 per triangle
  float bounds_min[3] = {0, 0, 0};
  float bounds_max[3] = {0, 0, 0};
  bool converted_from_double = false;  // the file had float64 positions
  size_t dropped_properties = 0;       // vertex and face properties not kept

  uint64_t vertices() const { return positions.size() / 3; }
  uint64_t triangles() const { return indices.size() / 3; }
};

// What a decoder produced, to check against the input.
struct DecodedCounts {
  uint64_t vertices = 0;
  uint64_t triangles = 0;
  bool operator==(const DecodedCounts& o) const {
    return vertices == o.vertices && triangles == o.triangles;
  }
};

using Bytes = std::vector<uint8_t>;

// Presents a BenchMesh as a psq::MeshSource: float positions, the counts and
// the bounding box in the schema, every vertex, then every triangle.
class BenchMeshSource : public psq::MeshSource {
 public:
  explicit BenchMeshSource(const BenchMesh& mesh) : mesh_(mesh) {
    schema_.position_type = psq::ScalarType::kFloat32;
    schema_.vertex_count = static_cast<int64_t>(mesh.vertices());
    schema_.triangle_count = static_cast<int64_t>(mesh.triangles());
    schema_.has_bounds = mesh.vertices() > 0;
    for (int a = 0; a < 3; ++a) {
      schema_.bounds_min[a] = mesh.bounds_min[a];
      schema_.bounds_max[a] = mesh.bounds_max[a];
    }
  }
  const psq::MeshSchema& schema() const override { return schema_; }
  Status next(psq::MeshItem* item) override {
    item->values.clear();
    if (next_vertex_ < mesh_.vertices()) {
      item->kind = psq::MeshItem::Kind::kVertex;
      for (int a = 0; a < 3; ++a) item->position[a] = mesh_.positions[3 * next_vertex_ + a];
      ++next_vertex_;
    } else if (next_triangle_ < mesh_.triangles()) {
      item->kind = psq::MeshItem::Kind::kTriangle;
      for (int c = 0; c < 3; ++c) item->index[c] = mesh_.indices[3 * next_triangle_ + c];
      ++next_triangle_;
    } else {
      item->kind = psq::MeshItem::Kind::kEnd;
    }
    return Status();
  }
  const psq::SourceReport& report() const override { return report_; }

 private:
  const BenchMesh& mesh_;
  psq::MeshSchema schema_;
  psq::SourceReport report_;
  uint64_t next_vertex_ = 0;
  uint64_t next_triangle_ = 0;
};

// Reads `path` with psq's readers (any format psq reads) into `mesh`.
Status load_mesh(const std::string& path, BenchMesh* mesh) {
  psq::OpenedMesh opened;
  PSQ_RETURN_IF_ERROR(psq::open_mesh(path, psq::OpenOptions(), &opened));
  const psq::MeshSchema& schema = opened.source->schema();
  mesh->converted_from_double = schema.position_type == psq::ScalarType::kFloat64;
  mesh->dropped_properties = schema.vertex_properties.size() + schema.face_properties.size();
  if (schema.vertex_count > 0) mesh->positions.reserve(3 * static_cast<size_t>(schema.vertex_count));
  if (schema.triangle_count > 0) mesh->indices.reserve(3 * static_cast<size_t>(schema.triangle_count));
  psq::MeshItem item;
  for (;;) {
    PSQ_RETURN_IF_ERROR(opened.source->next(&item));
    if (item.kind == psq::MeshItem::Kind::kEnd) break;
    if (item.kind == psq::MeshItem::Kind::kVertex) {
      for (int a = 0; a < 3; ++a) mesh->positions.push_back(static_cast<float>(item.position[a]));
    } else {
      for (int c = 0; c < 3; ++c) mesh->indices.push_back(item.index[c]);
    }
  }
  if (mesh->vertices() > UINT32_MAX)
    return Status(ErrorCode::kLimit, "more than 2^32 vertices");
  for (uint64_t v = 0; v < mesh->vertices(); ++v) {
    for (int a = 0; a < 3; ++a) {
      float p = mesh->positions[3 * v + a];
      if (v == 0 || p < mesh->bounds_min[a]) mesh->bounds_min[a] = p;
      if (v == 0 || p > mesh->bounds_max[a]) mesh->bounds_max[a] = p;
    }
  }
  return Status();
}

// --------------------------------------------------------------------- Draco

Status draco_encode(const BenchMesh& mesh, int quantization_bits, int compression_level,
                    Bytes* out) {
  draco::Mesh dm;
  const uint32_t nv = static_cast<uint32_t>(mesh.vertices());
  dm.set_num_points(nv);
  draco::GeometryAttribute position;
  position.Init(draco::GeometryAttribute::POSITION, nullptr, 3, draco::DT_FLOAT32, false,
                3 * sizeof(float), 0);
  const int id = dm.AddAttribute(position, true, nv);
  if (id < 0) return Status(ErrorCode::kInternal, "draco: AddAttribute failed");
  dm.attribute(id)->buffer()->Write(0, mesh.positions.data(), mesh.positions.size() * sizeof(float));
  dm.SetNumFaces(mesh.triangles());
  for (uint64_t t = 0; t < mesh.triangles(); ++t) {
    const uint32_t* c = &mesh.indices[3 * t];
    dm.SetFace(draco::FaceIndex(static_cast<uint32_t>(t)),
               {draco::PointIndex(c[0]), draco::PointIndex(c[1]), draco::PointIndex(c[2])});
  }
  draco::Encoder encoder;
  encoder.SetAttributeQuantization(draco::GeometryAttribute::POSITION, quantization_bits);
  encoder.SetSpeedOptions(10 - compression_level, 10 - compression_level);
  encoder.SetEncodingMethod(draco::MESH_EDGEBREAKER_ENCODING);
  draco::EncoderBuffer buffer;
  const draco::Status s = encoder.EncodeMeshToBuffer(dm, &buffer);
  if (!s.ok()) return Status(ErrorCode::kInternal, std::string("draco: ") + s.error_msg());
  out->assign(buffer.data(), buffer.data() + buffer.size());
  return Status();
}

// Decodes into a draco::Mesh (float positions, faces of point indices).
Status draco_decode(const Bytes& in, DecodedCounts* counts) {
  draco::DecoderBuffer buffer;
  buffer.Init(reinterpret_cast<const char*>(in.data()), in.size());
  draco::Decoder decoder;
  auto decoded = decoder.DecodeMeshFromBuffer(&buffer);
  if (!decoded.ok())
    return Status(ErrorCode::kBadValue, std::string("draco: ") + decoded.status().error_msg());
  const std::unique_ptr<draco::Mesh> dm = std::move(decoded).value();
  counts->vertices = dm->num_points();
  counts->triangles = dm->num_faces();
  return Status();
}

// ----------------------------------------------------------------------- PLY

// Binary little-endian PLY with float x, y, z and `list uchar int
// vertex_indices`, written in memory.
Status ply_encode(const BenchMesh& mesh, Bytes* out) {
  char header[256];
  const int n = std::snprintf(header, sizeof header,
                              "ply\nformat binary_little_endian 1.0\n"
                              "element vertex %" PRIu64 "\n"
                              "property float x\nproperty float y\nproperty float z\n"
                              "element face %" PRIu64 "\n"
                              "property list uchar int vertex_indices\nend_header\n",
                              mesh.vertices(), mesh.triangles());
  const size_t body = mesh.positions.size() * sizeof(float) + mesh.triangles() * 13;
  out->resize(static_cast<size_t>(n) + body);
  uint8_t* p = out->data();
  std::memcpy(p, header, static_cast<size_t>(n));
  p += n;
  std::memcpy(p, mesh.positions.data(), mesh.positions.size() * sizeof(float));
  p += mesh.positions.size() * sizeof(float);
  for (uint64_t t = 0; t < mesh.triangles(); ++t) {
    *p++ = 3;
    std::memcpy(p, &mesh.indices[3 * t], 12);
    p += 12;
  }
  return Status();
}

// Parses exactly the layout ply_encode writes into float positions and
// uint32 indices: a floor for reading PLY, not a general reader.
Status ply_decode(const Bytes& in, DecodedCounts* counts) {
  static const char kEnd[] = "end_header\n";
  const char* begin = reinterpret_cast<const char*>(in.data());
  const char* end = begin + in.size();
  const char* header_end = std::search(begin, end, kEnd, kEnd + sizeof kEnd - 1);
  if (header_end == end) return Status(ErrorCode::kBadHeader, "ply: no end_header");
  const std::string header(begin, header_end);
  unsigned long long nv = 0, nt = 0;
  const size_t ev = header.find("element vertex ");
  const size_t ef = header.find("element face ");
  if (ev == std::string::npos || ef == std::string::npos ||
      std::sscanf(header.c_str() + ev, "element vertex %llu", &nv) != 1 ||
      std::sscanf(header.c_str() + ef, "element face %llu", &nt) != 1)
    return Status(ErrorCode::kBadHeader, "ply: no vertex or face count");
  const uint8_t* p = reinterpret_cast<const uint8_t*>(header_end + sizeof kEnd - 1);
  if (static_cast<uint64_t>(in.data() + in.size() - p) != nv * 12 + nt * 13)
    return Status(ErrorCode::kTruncated, "ply: body size does not match the counts");
  std::vector<float> positions(3 * nv);
  std::memcpy(positions.data(), p, nv * 12);
  p += nv * 12;
  std::vector<uint32_t> indices(3 * nt);
  for (uint64_t t = 0; t < nt; ++t) {
    if (*p != 3) return Status(ErrorCode::kUnsupported, "ply: a face is not a triangle");
    std::memcpy(&indices[3 * t], p + 1, 12);
    p += 13;
  }
  for (uint32_t i : indices)
    if (i >= nv) return Status(ErrorCode::kBadIndex, "ply: index out of range");
  counts->vertices = nv;
  counts->triangles = nt;
  return Status();
}

// ---------------------------------------------------------------------- zstd

Status zstd_compress(const Bytes& in, int level, Bytes* out) {
  out->resize(ZSTD_compressBound(in.size()));
  const size_t n = ZSTD_compress(out->data(), out->size(), in.data(), in.size(), level);
  if (ZSTD_isError(n)) return Status(ErrorCode::kInternal, std::string("zstd: ") + ZSTD_getErrorName(n));
  out->resize(n);
  return Status();
}

Status zstd_decompress(const Bytes& in, Bytes* out) {
  const unsigned long long size = ZSTD_getFrameContentSize(in.data(), in.size());
  if (size == ZSTD_CONTENTSIZE_ERROR || size == ZSTD_CONTENTSIZE_UNKNOWN)
    return Status(ErrorCode::kBadValue, "zstd: no content size in the frame");
  out->resize(size);
  const size_t n = ZSTD_decompress(out->data(), out->size(), in.data(), in.size());
  if (ZSTD_isError(n)) return Status(ErrorCode::kBadValue, std::string("zstd: ") + ZSTD_getErrorName(n));
  if (n != size) return Status(ErrorCode::kTruncated, "zstd: short frame");
  return Status();
}

// ------------------------------------------------------------- meshoptimizer

// Container of the meshoptimizer coding: this header, the encoded index
// buffer, the encoded vertex buffer. Vertices are uint16 x, y, z and 2
// bytes of zero padding, quantized on the bounding box.
struct MeshoptHeader {
  uint64_t vertex_count;
  uint64_t index_count;
  uint64_t index_bytes;
  float origin[3];
  float step[3];  // position = origin + q * step
};
constexpr size_t kMeshoptVertexSize = 8;

Status meshopt_encode(const BenchMesh& mesh, Bytes* out) {
  const size_t nv = mesh.vertices();
  const size_t ni = mesh.indices.size();
  std::vector<uint32_t> indices(ni);
  meshopt_optimizeVertexCache(indices.data(), mesh.indices.data(), ni, nv);

  MeshoptHeader h{};
  float scale[3];
  for (int a = 0; a < 3; ++a) {
    const float extent = mesh.bounds_max[a] - mesh.bounds_min[a];
    h.origin[a] = mesh.bounds_min[a];
    h.step[a] = extent > 0 ? extent / 65535.0f : 0.0f;
    scale[a] = extent > 0 ? 65535.0f / extent : 0.0f;
  }
  std::vector<uint16_t> quantized(4 * nv);
  for (size_t v = 0; v < nv; ++v) {
    for (int a = 0; a < 3; ++a) {
      const float q = std::round((mesh.positions[3 * v + a] - h.origin[a]) * scale[a]);
      quantized[4 * v + a] = static_cast<uint16_t>(std::min(65535.0f, std::max(0.0f, q)));
    }
    quantized[4 * v + 3] = 0;
  }
  std::vector<uint16_t> fetched(4 * nv);
  // Drops unreferenced vertices: the decoded vertex count may be smaller.
  const size_t unique = meshopt_optimizeVertexFetch(fetched.data(), indices.data(), ni,
                                                    quantized.data(), nv, kMeshoptVertexSize);
  quantized = std::vector<uint16_t>();

  const size_t index_bound = meshopt_encodeIndexBufferBound(ni, unique);
  const size_t vertex_bound = meshopt_encodeVertexBufferBound(unique, kMeshoptVertexSize);
  out->resize(sizeof h + index_bound + vertex_bound);
  const size_t index_bytes = meshopt_encodeIndexBuffer(out->data() + sizeof h, index_bound,
                                                       indices.data(), ni);
  if (index_bytes == 0 && ni > 0) return Status(ErrorCode::kInternal, "meshopt: index buffer");
  const size_t vertex_bytes = meshopt_encodeVertexBuffer(
      out->data() + sizeof h + index_bytes, vertex_bound, fetched.data(), unique, kMeshoptVertexSize);
  if (vertex_bytes == 0) return Status(ErrorCode::kInternal, "meshopt: vertex buffer");
  h.vertex_count = unique;
  h.index_count = ni;
  h.index_bytes = index_bytes;
  std::memcpy(out->data(), &h, sizeof h);
  out->resize(sizeof h + index_bytes + vertex_bytes);
  return Status();
}

// Decodes the index buffer and the vertex buffer and dequantizes the
// positions to float, so that the output is the same float x, y, z and
// uint32 indices as the other decoders give.
Status meshopt_decode(const uint8_t* data, size_t size, DecodedCounts* counts) {
  MeshoptHeader h;
  if (size < sizeof h) return Status(ErrorCode::kTruncated, "meshopt: no header");
  std::memcpy(&h, data, sizeof h);
  if (h.index_bytes > size - sizeof h || h.index_count % 3 != 0 || h.vertex_count > UINT32_MAX)
    return Status(ErrorCode::kBadHeader, "meshopt: bad header");
  std::vector<uint32_t> indices(h.index_count);
  if (meshopt_decodeIndexBuffer(indices.data(), h.index_count, sizeof(uint32_t), data + sizeof h,
                                h.index_bytes) != 0)
    return Status(ErrorCode::kBadValue, "meshopt: index buffer does not decode");
  std::vector<uint16_t> quantized(4 * h.vertex_count);
  if (meshopt_decodeVertexBuffer(quantized.data(), h.vertex_count, kMeshoptVertexSize,
                                 data + sizeof h + h.index_bytes,
                                 size - sizeof h - h.index_bytes) != 0)
    return Status(ErrorCode::kBadValue, "meshopt: vertex buffer does not decode");
  std::vector<float> positions(3 * h.vertex_count);
  for (size_t v = 0; v < h.vertex_count; ++v)
    for (int a = 0; a < 3; ++a)
      positions[3 * v + a] = h.origin[a] + static_cast<float>(quantized[4 * v + a]) * h.step[a];
  counts->vertices = h.vertex_count;
  counts->triangles = h.index_count / 3;
  return Status();
}

// -------------------------------------------------------------- psq

// psq: the mesh through the sequence builder (converter, or external sort
// for unordered input) into the .psq encoder, all in this process; decode
// pulls every event through PsqDecoder::pump.
Status psq_encode(const BenchMesh& m, int bits, bool fast, Bytes* out) {
  BenchMeshSource source(m);
  psq::VectorWriter writer(out);
  psq::EncodeOptions options;
  options.bits = bits > 0 ? bits : 16;
  options.lossless = bits == 0;
  options.fast = fast;
  psq::PsqEncoder encoder(&writer, options);
  psq::BuildOptions build;
  psq::BuildReport report;
  return psq::build_sequence(source, encoder, build, &report);
}

// A processing sequence recorded in memory, so that the encoder can be timed
// on its own ("encode from a processing sequence", the codec issue's
// criterion): the converter runs before the clock starts. Compact words:
// a vertex is 9 (tag, index, slot, reappears, three doubles as two words
// each), a triangle 11, a finalization 2; about 60 bytes per triangle.
// BenchMesh has no properties, so none are recorded.
class RecordedSequence : public psq::SequenceSink {
 public:
  Status begin(const psq::MeshSchema& schema) override {
    schema_ = schema;
    return Status();
  }
  Status vertex(const psq::SequenceVertex& v) override {
    words_.insert(words_.end(), {0u, v.index, v.slot, v.reappears});
    for (double d : v.position) {
      uint64_t b;
      std::memcpy(&b, &d, 8);
      words_.insert(words_.end(), {static_cast<uint32_t>(b), static_cast<uint32_t>(b >> 32)});
    }
    return Status();
  }
  Status triangle(const psq::SequenceTriangle& t) override {
    words_.insert(words_.end(), {1u, t.v[0], t.v[1], t.v[2], t.vslot[0], t.vslot[1], t.vslot[2], t.eslot[0],
                                 t.eslot[1], t.eslot[2]});
    words_.push_back(static_cast<uint32_t>(t.op) | uint32_t{t.new_mask} << 4 | uint32_t{t.final_mask} << 8 |
                     uint32_t{t.border_mask} << 12 | uint32_t{t.nonmanifold_mask} << 16 |
                     uint32_t{t.leaving_mask} << 20 | uint32_t{t.entering_mask} << 24);
    return Status();
  }
  Status finalize(uint32_t index) override {
    words_.insert(words_.end(), {2u, index});
    return Status();
  }
  Status finish() override { return Status(); }

  // Sends the recorded events to `sink`, begin() to finish().
  Status replay(psq::SequenceSink& sink) const {
    PSQ_RETURN_IF_ERROR(sink.begin(schema_));
    psq::SequenceVertex v;
    psq::SequenceTriangle t;
    for (size_t i = 0; i < words_.size();) {
      const uint32_t* w = words_.data() + i;
      if (w[0] == 0) {
        v.index = w[1];
        v.slot = w[2];
        v.reappears = w[3];
        for (int k = 0; k < 3; ++k) {
          const uint64_t b = w[4 + 2 * k] | uint64_t{w[5 + 2 * k]} << 32;
          std::memcpy(&v.position[k], &b, 8);
        }
        PSQ_RETURN_IF_ERROR(sink.vertex(v));
        i += 10;
      } else if (w[0] == 1) {
        for (int k = 0; k < 3; ++k) {
          t.v[k] = w[1 + k];
          t.vslot[k] = w[4 + k];
          t.eslot[k] = w[7 + k];
        }
        const uint32_t f = w[10];
        t.op = static_cast<psq::Op>(f & 15);
        t.new_mask = (f >> 4) & 15;
        t.final_mask = (f >> 8) & 15;
        t.border_mask = (f >> 12) & 15;
        t.nonmanifold_mask = (f >> 16) & 15;
        t.leaving_mask = (f >> 20) & 15;
        t.entering_mask = (f >> 24) & 15;
        PSQ_RETURN_IF_ERROR(sink.triangle(t));
        i += 11;
      } else {
        PSQ_RETURN_IF_ERROR(sink.finalize(w[1]));
        i += 2;
      }
    }
    return sink.finish();
  }

 private:
  psq::MeshSchema schema_;
  std::vector<uint32_t> words_;
};

// psq-qN-seq: records the mesh's processing sequence (untimed), then the
// timed part encodes it.
Status psq_prepare_sequence(const BenchMesh& m, int bits, bool fast, std::function<Status(Bytes*)>* timed) {
  auto recorded = std::make_shared<RecordedSequence>();
  BenchMeshSource source(m);
  psq::BuildOptions build;
  psq::BuildReport report;
  PSQ_RETURN_IF_ERROR(psq::build_sequence(source, *recorded, build, &report));
  *timed = [recorded, bits, fast](Bytes* out) {
    psq::VectorWriter writer(out);
    psq::EncodeOptions options;
    options.bits = bits;
    options.fast = fast;
    psq::PsqEncoder encoder(&writer, options);
    return recorded->replay(encoder);
  };
  return Status();
}

Status psq_decode(const Bytes& in, DecodedCounts* counts) {
  struct Count : psq::SequenceSink {
    DecodedCounts* c;
    Status begin(const psq::MeshSchema&) override { return Status(); }
    Status vertex(const psq::SequenceVertex& v) override {
      if (v.reappears == psq::kNoVertex) ++c->vertices;  // re-appearances merge back
      return Status();
    }
    Status triangle(const psq::SequenceTriangle&) override {
      ++c->triangles;
      return Status();
    }
    Status finalize(uint32_t) override { return Status(); }
    Status finish() override { return Status(); }
  } count;
  count.c = counts;
  psq::InputStream stream;
  stream.open_memory(in.data(), in.size(), "psq");
  psq::PsqDecoder decoder;
  PSQ_RETURN_IF_ERROR(decoder.open(&stream));
  return decoder.pump(count);
}

// psq-q16-arrays: decode_mesh (psq/psq_memory.h) into vertex and index
// arrays, as Draco decodes into its mesh.
Status psq_decode_arrays(const Bytes& in, DecodedCounts* counts) {
  psq::MeshBuffers mesh;
  PSQ_RETURN_IF_ERROR(psq::decode_mesh(in.data(), in.size(), &mesh));
  counts->vertices = mesh.positions.size() / 3;
  counts->triangles = mesh.indices.size() / 3;
  return Status();
}

// -------------------------------------------------------------- codec table

struct Codec {
  std::string name;   // unique; --codecs and --ref select by it
  std::string notes;  // what the codec keeps or changes, for the table
  std::function<Status(const BenchMesh&, Bytes*)> encode;
  std::function<Status(const Bytes&, DecodedCounts*)> decode;
  // Optional: run in the child before the clock starts; it replaces
  // `encode` for the timed runs (psq-qN-seq: the encoder alone).
  std::function<Status(const BenchMesh&, std::function<Status(Bytes*)>*)> prepare = nullptr;
};

std::vector<Codec> make_codecs() {
  std::vector<Codec> codecs;
  for (int bits : {11, 14, 16, 0}) {
    codecs.push_back({bits ? "psq-q" + std::to_string(bits) : std::string("psq-lossless"),
                      "streaming (one pass, or an external sort for incoherent input); keeps orientation and non-manifold vertices",
                      [bits](const BenchMesh& m, Bytes* out) { return psq_encode(m, bits, false, out); }, psq_decode});
  }
  // The fast profile (spec/psq-format.md, section 13).
  for (int bits : {11, 14, 16}) {
    codecs.push_back({"psq-fast-q" + std::to_string(bits),
                      "the fast profile: static rANS tables per chunk, a boundary without lookups in the decoder",
                      [bits](const BenchMesh& m, Bytes* out) { return psq_encode(m, bits, true, out); }, psq_decode});
  }
  codecs.push_back({"psq-q16-arrays", "as psq-q16, decoded into vertex and index arrays (decode_mesh)",
                    [](const BenchMesh& m, Bytes* out) { return psq_encode(m, 16, false, out); }, psq_decode_arrays});
  codecs.push_back({"psq-fast-q16-arrays", "as psq-fast-q16, decoded into vertex and index arrays (decode_mesh)",
                    [](const BenchMesh& m, Bytes* out) { return psq_encode(m, 16, true, out); }, psq_decode_arrays});
  // The codec issue's encode criterion: from a processing sequence.
  codecs.push_back({"psq-q16-seq",
                    "the encoder alone: the sequence is recorded in memory first (untimed; its memory counts)",
                    nullptr, psq_decode,
                    [](const BenchMesh& m, std::function<Status(Bytes*)>* timed) {
                      return psq_prepare_sequence(m, 16, false, timed);
                    }});
  codecs.push_back({"psq-fast-q16-seq", "the fast profile's encoder alone, from a recorded sequence", nullptr,
                    psq_decode, [](const BenchMesh& m, std::function<Status(Bytes*)>* timed) {
                      return psq_prepare_sequence(m, 16, true, timed);
                    }});
  for (int level : {7, 10}) {
    for (int bits : {11, 14, 16}) {
      codecs.push_back(
          {"draco-q" + std::to_string(bits) + "-cl" + std::to_string(level),
           "edgebreaker, speed " + std::to_string(10 - level) + "; reorders",
           [bits, level](const BenchMesh& m, Bytes* out) { return draco_encode(m, bits, level, out); },
           draco_decode});
    }
  }
  codecs.push_back({"ply", "lossless", ply_encode, ply_decode});
  for (int level : {3, 19}) {
    codecs.push_back(
        {"ply+zstd" + std::to_string(level), "lossless; zstd time only",
         [level](const BenchMesh& m, Bytes* out) {
           Bytes ply;
           PSQ_RETURN_IF_ERROR(ply_encode(m, &ply));
           return zstd_compress(ply, level, out);
         },
         [](const Bytes& in, DecodedCounts* counts) {
           Bytes ply;
           PSQ_RETURN_IF_ERROR(zstd_decompress(in, &ply));
           // Counts only: parsing is the "ply" row's decode.
           unsigned long long nv = 0, nt = 0;
           const std::string head(reinterpret_cast<const char*>(ply.data()),
                                  std::min<size_t>(ply.size(), 256));
           const size_t ev = head.find("element vertex "), ef = head.find("element face ");
           if (ev == std::string::npos || ef == std::string::npos ||
               std::sscanf(head.c_str() + ev, "element vertex %llu", &nv) != 1 ||
               std::sscanf(head.c_str() + ef, "element face %llu", &nt) != 1)
             return Status(ErrorCode::kBadHeader, "ply: no vertex or face count");
           counts->vertices = nv;
           counts->triangles = nt;
           return Status();
         }});
  }
  const std::string meshopt_notes = "cache + fetch optimized: reorders";
  codecs.push_back({"meshopt-q16", meshopt_notes, meshopt_encode,
                    [](const Bytes& in, DecodedCounts* counts) {
                      return meshopt_decode(in.data(), in.size(), counts);
                    }});
  codecs.push_back({"meshopt-q16+zstd19", meshopt_notes,
                    [](const BenchMesh& m, Bytes* out) {
                      Bytes raw;
                      PSQ_RETURN_IF_ERROR(meshopt_encode(m, &raw));
                      return zstd_compress(raw, 19, out);
                    },
                    [](const Bytes& in, DecodedCounts* counts) {
                      Bytes raw;
                      PSQ_RETURN_IF_ERROR(zstd_decompress(in, &raw));
                      return meshopt_decode(raw.data(), raw.size(), counts);
                    }});
  return codecs;
}

// ------------------------------------------------------------ forked runs

// A little serialization for the pipe between a child and the parent.
void put_u64(std::string* s, uint64_t v) { s->append(reinterpret_cast<const char*>(&v), 8); }
void put_f64(std::string* s, double v) { s->append(reinterpret_cast<const char*>(&v), 8); }
struct Reader {
  const std::string& s;
  size_t pos = 0;
  bool ok = true;
  uint64_t u64() {
    uint64_t v = 0;
    if (pos + 8 > s.size()) {
      ok = false;
      return 0;
    }
    std::memcpy(&v, s.data() + pos, 8);
    pos += 8;
    return v;
  }
  double f64() {
    double v = 0;
    if (pos + 8 > s.size()) {
      ok = false;
      return 0;
    }
    std::memcpy(&v, s.data() + pos, 8);
    pos += 8;
    return v;
  }
};

bool write_all(int fd, const void* data, size_t size) {
  const char* p = static_cast<const char*>(data);
  while (size > 0) {
    const ssize_t n = write(fd, p, size);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return false;
    p += n;
    size -= static_cast<size_t>(n);
  }
  return true;
}

bool read_all(int fd, void* data, size_t size) {
  char* p = static_cast<char*>(data);
  while (size > 0) {
    const ssize_t n = read(fd, p, size);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return false;
    p += n;
    size -= static_cast<size_t>(n);
  }
  return true;
}

// A length-prefixed block.
bool write_block(int fd, const void* data, uint64_t size) {
  return write_all(fd, &size, 8) && write_all(fd, data, size);
}
template <typename Buffer>
bool read_block(int fd, Buffer* out) {
  uint64_t size = 0;
  if (!read_all(fd, &size, 8)) return false;
  out->resize(size);
  return read_all(fd, &(*out)[0], size);
}

// Resident set size of this process in KiB, from /proc/self/statm.
long resident_kib() {
  std::FILE* f = std::fopen("/proc/self/statm", "r");
  if (!f) return -1;
  long total = 0, resident = -1;
  if (std::fscanf(f, "%ld %ld", &total, &resident) != 2) resident = -1;
  std::fclose(f);
  return resident < 0 ? -1 : resident * (sysconf(_SC_PAGESIZE) / 1024);
}

struct ChildRun {
  std::string error;        // empty on success
  std::string payload;      // small results (timings, counts)
  Bytes data;               // bulk results (the encoding)
  long start_rss_kib = -1;  // the child's RSS right after fork
  long max_rss_kib = -1;    // the child's ru_maxrss
  long peak_kib() const { return start_rss_kib < 0 || max_rss_kib < 0 ? -1 : max_rss_kib - start_rss_kib; }
};

// Runs `body` in a forked child. `body` returns an error message or "", and
// fills `payload` (small) and `data` (bulk, sent from where it lies, so that
// sending it does not raise the child's peak memory).
ChildRun run_in_child(const std::function<std::string(std::string* payload, Bytes* data)>& body) {
  ChildRun run;
  std::fflush(stdout);
  std::fflush(stderr);
  malloc_trim(0);  // freed heap pages would otherwise count as the child's start RSS
  int fds[2];
  if (pipe(fds) != 0) {
    run.error = std::string("pipe: ") + std::strerror(errno);
    return run;
  }
  const pid_t pid = fork();
  if (pid < 0) {
    run.error = std::string("fork: ") + std::strerror(errno);
    close(fds[0]);
    close(fds[1]);
    return run;
  }
  if (pid == 0) {
    close(fds[0]);
    const int64_t start = resident_kib();
    std::string message, payload;
    Bytes data;
    try {
      message = body(&payload, &data);
    } catch (const std::exception& e) {
      message = std::string("exception: ") + e.what();
    }
    if (!message.empty()) {
      payload.clear();
      data = Bytes();
    }
    const bool sent = write_all(fds[1], &start, 8) && write_block(fds[1], message.data(), message.size()) &&
                      write_block(fds[1], payload.data(), payload.size()) &&
                      write_block(fds[1], data.data(), data.size());
    close(fds[1]);
    _exit(sent ? 0 : 3);
  }
  close(fds[1]);
  int64_t start = -1;
  const bool received = read_all(fds[0], &start, 8) && read_block(fds[0], &run.error) &&
                        read_block(fds[0], &run.payload) && read_block(fds[0], &run.data);
  close(fds[0]);
  int status = 0;
  struct rusage usage;
  std::memset(&usage, 0, sizeof usage);
  while (wait4(pid, &status, 0, &usage) < 0 && errno == EINTR) {
  }
  run.max_rss_kib = usage.ru_maxrss;
  if (WIFSIGNALED(status)) {
    run.error = "child killed by signal " + std::to_string(WTERMSIG(status));
  } else if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
    run.error = "child failed with exit status " + std::to_string(WEXITSTATUS(status));
  } else if (!received) {
    run.error = "short message from the child";
  } else {
    run.start_rss_kib = static_cast<long>(start);
  }
  return run;
}

// --best: the tables report each codec's fastest run instead of the median
// (steadier on a shared machine, where other load only ever slows a run).
bool g_best = false;

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : (v[n / 2 - 1] + v[n / 2]) / 2;
}

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

struct Result {
  std::string codec;
  std::string notes;
  std::string error;  // empty on success
  uint64_t bytes = 0;
  std::vector<double> encode_seconds, decode_seconds;
  DecodedCounts decoded;
  long encode_peak_kib = -1, decode_peak_kib = -1;
  long encode_maxrss_kib = -1, decode_maxrss_kib = -1;
};

Result measure(const Codec& codec, const BenchMesh& mesh, int runs) {
  Result result;
  result.codec = codec.name;
  result.notes = codec.notes;

  // Encode: each run starts with an empty output; the last one is kept.
  ChildRun enc = run_in_child([&](std::string* payload, Bytes* out) -> std::string {
    std::function<Status(Bytes*)> encode = [&](Bytes* o) { return codec.encode(mesh, o); };
    if (codec.prepare) {
      const Status s = codec.prepare(mesh, &encode);
      if (!s.ok()) return s.to_string();
    }
    for (int r = 0; r < runs; ++r) {
      *out = Bytes();
      const auto t0 = Clock::now();
      const Status s = encode(out);
      const double t = seconds_since(t0);
      if (!s.ok()) return s.to_string();
      put_f64(payload, t);
    }
    return std::string();
  });
  result.encode_peak_kib = enc.peak_kib();
  result.encode_maxrss_kib = enc.max_rss_kib;
  if (!enc.error.empty()) {
    result.error = "encode: " + enc.error;
    return result;
  }
  Reader r{enc.payload};
  for (int i = 0; i < runs; ++i) result.encode_seconds.push_back(r.f64());
  const Bytes encoded = std::move(enc.data);
  result.bytes = encoded.size();

  // Decode: every run must give the same counts.
  ChildRun dec = run_in_child([&](std::string* payload, Bytes*) -> std::string {
    DecodedCounts first;
    for (int i = 0; i < runs; ++i) {
      DecodedCounts counts;
      const auto t0 = Clock::now();
      const Status s = codec.decode(encoded, &counts);
      const double t = seconds_since(t0);
      if (!s.ok()) return s.to_string();
      if (i == 0) first = counts;
      if (!(counts == first)) return "decoded counts differ between runs";
      put_f64(payload, t);
    }
    put_u64(payload, first.vertices);
    put_u64(payload, first.triangles);
    return std::string();
  });
  result.decode_peak_kib = dec.peak_kib();
  result.decode_maxrss_kib = dec.max_rss_kib;
  if (!dec.error.empty()) {
    result.error = "decode: " + dec.error;
    return result;
  }
  Reader d{dec.payload};
  for (int i = 0; i < runs; ++i) result.decode_seconds.push_back(d.f64());
  result.decoded.vertices = d.u64();
  result.decoded.triangles = d.u64();
  return result;
}

// ------------------------------------------------------------------ output

std::string fmt(const char* format, double v) {
  char b[64];
  std::snprintf(b, sizeof b, format, v);
  return b;
}

// "12.3" M triangles per second, or "-".
std::string rate(uint64_t triangles, const std::vector<double>& seconds) {
  const double m = g_best && !seconds.empty() ? *std::min_element(seconds.begin(), seconds.end()) : median(seconds);
  if (seconds.empty() || m <= 0) return "-";
  return fmt("%.3g", static_cast<double>(triangles) / m / 1e6);
}

std::string mib(long kib) { return kib < 0 ? "-" : fmt("%.1f", kib / 1024.0); }

// "V 34834 (-1113)": a decoded count and its difference from the input's.
std::string count_difference(const char* what, uint64_t decoded, uint64_t input) {
  char b[96];
  std::snprintf(b, sizeof b, "%s %" PRIu64 " (%+" PRId64 ")", what, decoded,
                static_cast<int64_t>(decoded) - static_cast<int64_t>(input));
  return b;
}

// "=" when the decoded counts equal the input's, else what differs.
std::string count_check(const BenchMesh& mesh, const DecodedCounts& d) {
  std::string s;
  if (d.triangles != mesh.triangles()) s = count_difference("T", d.triangles, mesh.triangles());
  if (d.vertices != mesh.vertices())
    s += (s.empty() ? "" : ", ") + count_difference("V", d.vertices, mesh.vertices());
  return s.empty() ? "=" : s;
}

const Result* find_result(const std::vector<Result>& results, const std::string& name) {
  for (const Result& r : results)
    if (r.codec == name && r.error.empty()) return &r;
  return nullptr;
}

void print_table(const BenchMesh& mesh, const std::vector<Result>& results, const std::string& ref) {
  std::printf("### %s: %" PRIu64 " vertices, %" PRIu64 " triangles", mesh.name.c_str(),
              mesh.vertices(), mesh.triangles());
  if (mesh.converted_from_double) std::printf(" (float64 positions read as float)");
  if (mesh.dropped_properties)
    std::printf(" (%zu properties not compared)", mesh.dropped_properties);
  std::printf("\n\n");
  const Result* reference = ref.empty() ? nullptr : find_result(results, ref);
  std::printf("| codec | bytes | bits/vertex |%s enc Mtri/s | dec Mtri/s | enc peak MiB | dec peak MiB | decoded | notes |\n",
              ref.empty() ? "" : (" / " + ref + " |").c_str());
  std::printf("|---|---:|---:|%s---:|---:|---:|---:|---|---|\n", ref.empty() ? "" : "---:|");
  for (const Result& r : results) {
    if (!r.error.empty()) {
      std::printf("| %s | - | - |%s - | - | %s | %s | - | failed: %s |\n", r.codec.c_str(),
                  ref.empty() ? "" : " - |", mib(r.encode_peak_kib).c_str(),
                  mib(r.decode_peak_kib).c_str(), r.error.c_str());
      continue;
    }
    std::string ratio;
    if (!ref.empty())
      ratio = " " + (reference && reference->bytes
                         ? fmt("%.3f", static_cast<double>(r.bytes) / static_cast<double>(reference->bytes))
                         : std::string("-")) + " |";
    const double bpv = mesh.vertices() ? r.bytes * 8.0 / static_cast<double>(mesh.vertices()) : 0;
    std::printf("| %s | %" PRIu64 " | %s |%s %s | %s | %s | %s | %s | %s |\n", r.codec.c_str(), r.bytes,
                fmt("%.2f", bpv).c_str(), ratio.c_str(), rate(mesh.triangles(), r.encode_seconds).c_str(),
                rate(mesh.triangles(), r.decode_seconds).c_str(), mib(r.encode_peak_kib).c_str(),
                mib(r.decode_peak_kib).c_str(), count_check(mesh, r.decoded).c_str(), r.notes.c_str());
  }
  std::printf("\n");
  std::fflush(stdout);
}

std::string json_string(const std::string& s) {
  std::string out = "\"";
  for (char c : s) {
    if (c == '"' || c == '\\') {
      out += '\\';
      out += c;
    } else if (static_cast<unsigned char>(c) < 0x20) {
      char b[8];
      std::snprintf(b, sizeof b, "\\u%04x", c);
      out += b;
    } else {
      out += c;
    }
  }
  return out + "\"";
}

std::string json_array(const std::vector<double>& v) {
  std::string s = "[";
  for (size_t i = 0; i < v.size(); ++i) s += (i ? ", " : "") + fmt("%.9g", v[i]);
  return s + "]";
}

std::string json_mesh(const BenchMesh& mesh, const std::vector<Result>& results) {
  std::string s = "    {\"mesh\": " + json_string(mesh.name) +
                  ", \"vertices\": " + std::to_string(mesh.vertices()) +
                  ", \"triangles\": " + std::to_string(mesh.triangles()) +
                  ", \"float64_positions\": " + (mesh.converted_from_double ? "true" : "false") +
                  ", \"dropped_properties\": " + std::to_string(mesh.dropped_properties) +
                  ",\n     \"codecs\": [\n";
  for (size_t i = 0; i < results.size(); ++i) {
    const Result& r = results[i];
    const double bpv = mesh.vertices() ? r.bytes * 8.0 / static_cast<double>(mesh.vertices()) : 0;
    s += "      {\"codec\": " + json_string(r.codec) + ", \"ok\": " + (r.error.empty() ? "true" : "false");
    if (!r.error.empty()) s += ", \"error\": " + json_string(r.error);
    s += ", \"bytes\": " + std::to_string(r.bytes) + ", \"bits_per_vertex\": " + fmt("%.4f", bpv) +
         ", \"encode_seconds\": " + json_array(r.encode_seconds) +
         ", \"decode_seconds\": " + json_array(r.decode_seconds) +
         ", \"encode_median_seconds\": " + fmt("%.9g", median(r.encode_seconds)) +
         ", \"decode_median_seconds\": " + fmt("%.9g", median(r.decode_seconds)) +
         ", \"decoded_vertices\": " + std::to_string(r.decoded.vertices) +
         ", \"decoded_triangles\": " + std::to_string(r.decoded.triangles) +
         ", \"encode_peak_kib\": " + std::to_string(r.encode_peak_kib) +
         ", \"decode_peak_kib\": " + std::to_string(r.decode_peak_kib) +
         ", \"encode_child_maxrss_kib\": " + std::to_string(r.encode_maxrss_kib) +
         ", \"decode_child_maxrss_kib\": " + std::to_string(r.decode_maxrss_kib) +
         ", \"notes\": " + json_string(r.notes) + "}" + (i + 1 < results.size() ? ",\n" : "\n");
  }
  return s + "     ]}";
}

// --once PHASE: one encode or one decode per codec and mesh, in this
// process, untimed, for an instruction counter (bench/instructions.sh runs
// callgrind collecting inside once_operation only). Encode starts where
// the timed runs start (after `prepare`); decode gets the bytes of an
// encode done before. Not inlined, so that its name marks the operation.
__attribute__((noinline)) Status once_operation(const std::function<Status()>& op) { return op(); }

int run_once(const std::string& phase, const Codec& codec, const BenchMesh& mesh) {
  std::function<Status(Bytes*)> encode = [&](Bytes* o) { return codec.encode(mesh, o); };
  Status s;
  if (codec.prepare) s = codec.prepare(mesh, &encode);
  Bytes bytes;
  DecodedCounts counts;
  if (s.ok() && phase == "encode") s = once_operation([&] { return encode(&bytes); });
  if (s.ok() && phase == "decode") {
    s = encode(&bytes);
    if (s.ok()) s = once_operation([&] { return codec.decode(bytes, &counts); });
    if (s.ok() && counts.triangles != mesh.triangles()) s = Status(ErrorCode::kInternal, "decoded triangle count differs");
  }
  if (!s.ok()) {
    std::fprintf(stderr, "psq_bench_compare: %s: %s: %s\n", mesh.name.c_str(), codec.name.c_str(), s.to_string().c_str());
    return 1;
  }
  std::printf("once %s %s %s triangles %llu bytes %zu\n", phase.c_str(), mesh.name.c_str(), codec.name.c_str(),
              static_cast<unsigned long long>(mesh.triangles()), bytes.size());
  return 0;
}

// ---------------------------------------------------------------- the tool

const char kUsage[] =
    "usage: psq_bench_compare [options] [MESH|DIR]...\n"
    "Sizes and speeds of Draco, PLY, PLY+zstd and meshoptimizer on each mesh.\n"
    "A DIR stands for its .ply and .obj files. Default: " PSQ_BENCH_MESH_DIR "\n"
    "  --runs N         timed runs per codec and direction (default 5; the median is reported)\n"
    "  --best           report the fastest run instead of the median (for a noisy machine)\n"
    "  --json FILE      also write every number as JSON\n"
    "  --codecs A,B     only the codecs whose name contains one of these strings\n"
    "  --ref CODEC      add a column: bytes relative to CODEC\n"
    "  --list           print the codec names and exit\n"
    "  --once PHASE     encode or decode once per codec and mesh, in process and untimed\n"
    "                   (for instruction counts: bench/instructions.sh)\n"
    "  -q               no progress on stderr\n";

bool has_mesh_extension(const std::string& name) {
  const size_t dot = name.rfind('.');
  if (dot == std::string::npos) return false;
  std::string ext = name.substr(dot + 1);
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return ext == "ply" || ext == "obj";
}

// Adds `path`, or the meshes of directory `path` in name order.
bool add_input(const std::string& path, std::vector<std::string>* inputs) {
  struct stat st;
  if (stat(path.c_str(), &st) != 0) return false;
  if (!S_ISDIR(st.st_mode)) {
    inputs->push_back(path);
    return true;
  }
  DIR* dir = opendir(path.c_str());
  if (!dir) return false;
  std::vector<std::string> names;
  while (const dirent* e = readdir(dir))
    if (has_mesh_extension(e->d_name)) names.push_back(e->d_name);
  closedir(dir);
  std::sort(names.begin(), names.end());
  for (const std::string& n : names) inputs->push_back(path + "/" + n);
  return true;
}

std::string base_name(const std::string& path) {
  const size_t slash = path.rfind('/');
  return slash == std::string::npos ? path : path.substr(slash + 1);
}

}  // namespace

int main(int argc, char** argv) {
  int runs = 5;
  std::string json_path, ref, filter, once;
  bool list = false, quiet = false;
  std::vector<std::string> args;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&](const char* option) -> std::string {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "psq_bench_compare: %s needs a value\n%s", option, kUsage);
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--runs") {
      runs = std::atoi(value("--runs").c_str());
      if (runs < 1 || runs > 1000) {
        std::fprintf(stderr, "psq_bench_compare: --runs must be 1 to 1000\n");
        return 2;
      }
    } else if (a == "--best") {
      g_best = true;
    } else if (a == "--json") {
      json_path = value("--json");
    } else if (a == "--codecs") {
      filter = value("--codecs");
    } else if (a == "--ref") {
      ref = value("--ref");
    } else if (a == "--once") {
      once = value("--once");
      if (once != "encode" && once != "decode") {
        std::fprintf(stderr, "psq_bench_compare: --once takes encode or decode\n");
        return 2;
      }
    } else if (a == "--list") {
      list = true;
    } else if (a == "-q") {
      quiet = true;
    } else if (a == "-h" || a == "--help") {
      std::fputs(kUsage, stdout);
      return 0;
    } else if (a.size() > 1 && a[0] == '-') {
      std::fprintf(stderr, "psq_bench_compare: unknown option %s\n%s", a.c_str(), kUsage);
      return 2;
    } else {
      args.push_back(a);
    }
  }
  const uint16_t one = 1;
  if (*reinterpret_cast<const uint8_t*>(&one) != 1) {
    std::fprintf(stderr, "psq_bench_compare: needs a little-endian machine\n");
    return 1;
  }

  std::vector<Codec> codecs;
  {
    std::vector<std::string> wanted;
    for (size_t start = 0; start <= filter.size();) {
      const size_t comma = std::min(filter.find(',', start), filter.size());
      if (comma > start) wanted.push_back(filter.substr(start, comma - start));
      start = comma + 1;
    }
    for (Codec& c : make_codecs()) {
      bool keep = wanted.empty();
      for (const std::string& w : wanted) keep = keep || c.name.find(w) != std::string::npos;
      if (keep) codecs.push_back(std::move(c));
    }
  }
  if (list) {
    for (const Codec& c : codecs) std::printf("%s\t%s\n", c.name.c_str(), c.notes.c_str());
    return 0;
  }
  if (codecs.empty()) {
    std::fprintf(stderr, "psq_bench_compare: --codecs %s selects no codec\n", filter.c_str());
    return 2;
  }
  if (!ref.empty() && std::none_of(codecs.begin(), codecs.end(),
                                   [&](const Codec& c) { return c.name == ref; })) {
    std::fprintf(stderr, "psq_bench_compare: --ref %s is not a selected codec (see --list)\n", ref.c_str());
    return 2;
  }

  std::vector<std::string> inputs;
  if (args.empty()) {
    if (!*PSQ_BENCH_MESH_DIR || !add_input(PSQ_BENCH_MESH_DIR, &inputs)) {
      std::fprintf(stderr, "psq_bench_compare: no mesh given and %s not found\n%s",
                   *PSQ_BENCH_MESH_DIR ? PSQ_BENCH_MESH_DIR : "no default directory", kUsage);
      return 2;
    }
  }
  for (const std::string& a : args) {
    if (!add_input(a, &inputs)) {
      std::fprintf(stderr, "psq_bench_compare: %s: %s\n", a.c_str(), std::strerror(errno));
      return 1;
    }
  }

  meshopt_encodeIndexVersion(1);
  if (once.empty())
    std::printf("Draco %s, zstd %s, meshoptimizer %d.%d. %s of %d runs; peak memory is the\n"
                "child's ru_maxrss minus its RSS at fork (what the codec added to the mesh in memory).\n\n",
                draco::kDracoVersion, ZSTD_versionString(), MESHOPTIMIZER_VERSION / 1000,
                MESHOPTIMIZER_VERSION / 10 % 100, g_best ? "Fastest" : "Medians", runs);

  int failures = 0;
  std::vector<std::string> json_meshes;
  for (const std::string& path : inputs) {
    BenchMesh mesh;
    mesh.name = base_name(path);
    const Status s = load_mesh(path, &mesh);
    if (!s.ok()) {
      std::fprintf(stderr, "psq_bench_compare: %s: %s\n", path.c_str(), s.to_string().c_str());
      ++failures;
      continue;
    }
    if (!once.empty()) {
      for (const Codec& codec : codecs) failures += run_once(once, codec, mesh);
      continue;
    }
    std::vector<Result> results;
    for (const Codec& codec : codecs) {
      if (!quiet) std::fprintf(stderr, "%s: %s...\n", mesh.name.c_str(), codec.name.c_str());
      results.push_back(measure(codec, mesh, runs));
      if (!results.back().error.empty()) {
        std::fprintf(stderr, "psq_bench_compare: %s: %s: %s\n", mesh.name.c_str(),
                     codec.name.c_str(), results.back().error.c_str());
        ++failures;
      }
    }
    print_table(mesh, results, ref);
    if (!json_path.empty()) json_meshes.push_back(json_mesh(mesh, results));
  }
  if (!once.empty()) return failures ? 1 : 0;

  if (!json_path.empty()) {
    std::FILE* f = std::fopen(json_path.c_str(), "w");
    if (!f) {
      std::fprintf(stderr, "psq_bench_compare: %s: %s\n", json_path.c_str(), std::strerror(errno));
      return 1;
    }
    std::fprintf(f, "{\"runs\": %d, \"draco\": \"%s\", \"zstd\": \"%s\", \"meshoptimizer\": %d,\n \"meshes\": [\n",
                 runs, draco::kDracoVersion, ZSTD_versionString(), MESHOPTIMIZER_VERSION);
    for (size_t i = 0; i < json_meshes.size(); ++i)
      std::fprintf(f, "%s%s\n", json_meshes[i].c_str(), i + 1 < json_meshes.size() ? "," : "");
    std::fprintf(f, " ]}\n");
    if (std::fclose(f) != 0) {
      std::fprintf(stderr, "psq_bench_compare: %s: write failed\n", json_path.c_str());
      return 1;
    }
  }
  return failures ? 1 : 0;
}
