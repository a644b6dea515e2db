// SPDX-License-Identifier: Apache-2.0
// python/src/mesh_io.cpp: whole meshes between numpy-ready buffers and
// files or bytes (psq.read, psq.write, psq.encode, psq.decode), and the
// chunked streaming reader behind psq.open.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

#include "binding.h"
#include "pipeline.h"
#include "psq/mesh_formats.h"
#include "psq/sequence_builder.h"

namespace psq::python {

void check(const Status& s, const std::string& file) {
  if (!s.ok()) throw StatusError(s, file);
}

void usage(const std::string& message) { throw StatusError(Status(ErrorCode::kUsage, message), ""); }

namespace {

// Reservations made from a header's counts are capped, so that a hostile
// header cannot make the reader allocate what the file does not hold; the
// buffers grow past this as elements actually arrive.
constexpr uint64_t kMaxReserve = uint64_t{1} << 24;

template <class T>
void append_as(Buffer<uint8_t>* out, double v) {
  const T t = static_cast<T>(v);
  const size_t at = out->size();
  out->resize(at + sizeof(T));
  std::memcpy(out->data() + at, &t, sizeof(T));
}

void append_value(Buffer<uint8_t>* out, ScalarType type, double v) {
  switch (type) {
    case ScalarType::kInt8: return append_as<int8_t>(out, v);
    case ScalarType::kUInt8: return append_as<uint8_t>(out, v);
    case ScalarType::kInt16: return append_as<int16_t>(out, v);
    case ScalarType::kUInt16: return append_as<uint16_t>(out, v);
    case ScalarType::kInt32: return append_as<int32_t>(out, v);
    case ScalarType::kUInt32: return append_as<uint32_t>(out, v);
    case ScalarType::kFloat32: return append_as<float>(out, v);
    case ScalarType::kFloat64: return append_as<double>(out, v);
  }
}

double value_at(const void* data, ScalarType type, uint64_t i) {
  switch (type) {
    case ScalarType::kInt8: return static_cast<const int8_t*>(data)[i];
    case ScalarType::kUInt8: return static_cast<const uint8_t*>(data)[i];
    case ScalarType::kInt16: return static_cast<const int16_t*>(data)[i];
    case ScalarType::kUInt16: return static_cast<const uint16_t*>(data)[i];
    case ScalarType::kInt32: return static_cast<const int32_t*>(data)[i];
    case ScalarType::kUInt32: return static_cast<const uint32_t*>(data)[i];
    case ScalarType::kFloat32: return static_cast<const float*>(data)[i];
    case ScalarType::kFloat64: return static_cast<const double*>(data)[i];
  }
  return 0;
}

std::vector<Column> make_columns(const std::vector<Property>& props) {
  std::vector<Column> cols(props.size());
  for (size_t i = 0; i < props.size(); ++i) cols[i].prop = props[i];
  return cols;
}

// Appends one element's flattened values (psq/indexed_mesh.h) to the columns.
void append_values(std::vector<Column>* cols, const PropertyValues& values) {
  size_t at = 0;
  for (Column& c : *cols) {
    if (!c.prop.is_list) {
      append_value(&c.values, c.prop.type, values[at++]);
      ++c.value_count;
      continue;
    }
    const uint32_t n = static_cast<uint32_t>(values[at++]);
    c.counts.push_back(n);
    for (uint32_t k = 0; k < n; ++k) append_value(&c.values, c.prop.type, values[at++]);
    c.value_count += n;
  }
}

void reserve_columns(std::vector<Column>* cols, int64_t count) {
  if (count <= 0) return;
  const uint64_t n = std::min<uint64_t>(static_cast<uint64_t>(count), kMaxReserve);
  for (Column& c : *cols) {
    if (c.prop.is_list) c.counts.reserve(n);
    else c.values.reserve(n * static_cast<uint64_t>(scalar_size(c.prop.type)));
  }
}

// Pulls every element of `source` into `out`.
Status read_source(MeshSource& source, MeshData* out) {
  const MeshSchema& schema = source.schema();
  out->position_type = schema.position_type == ScalarType::kFloat64 ? ScalarType::kFloat64 : ScalarType::kFloat32;
  out->vertex_properties = make_columns(schema.vertex_properties);
  out->face_properties = make_columns(schema.face_properties);
  const bool dbl = out->position_type == ScalarType::kFloat64;
  if (schema.vertex_count > 0) {
    const uint64_t n = 3 * std::min<uint64_t>(static_cast<uint64_t>(schema.vertex_count), kMaxReserve);
    if (dbl) out->positions_d.reserve(n);
    else out->positions_f.reserve(n);
  }
  if (schema.triangle_count > 0)
    out->faces.reserve(3 * std::min<uint64_t>(static_cast<uint64_t>(schema.triangle_count), kMaxReserve));
  reserve_columns(&out->vertex_properties, schema.vertex_count);
  reserve_columns(&out->face_properties, schema.triangle_count);
  MeshItem item;
  for (;;) {
    PSQ_RETURN_IF_ERROR(source.next(&item));
    if (item.kind == MeshItem::Kind::kEnd) break;
    if (item.kind == MeshItem::Kind::kVertex) {
      for (int k = 0; k < 3; ++k) {
        if (dbl) out->positions_d.push_back(item.position[k]);
        else out->positions_f.push_back(static_cast<float>(item.position[k]));
      }
      if (!out->vertex_properties.empty()) append_values(&out->vertex_properties, item.values);
    } else {
      out->faces.insert(out->faces.end(), item.index, item.index + 3);
      if (!out->face_properties.empty()) append_values(&out->face_properties, item.values);
    }
  }
  out->notes = source.report().notes;
  return Status();
}

// A .psq the fast path can take: float positions, no properties.
bool fast_psq(const uint8_t* data, size_t size) {
  if (size < 8 || !is_psq(data, size)) return false;
  InputStream in;
  in.open_memory(data, size);
  PsqDecoder decoder;
  if (!decoder.open(&in).ok()) return false;  // the general path reports it
  const MeshSchema& s = decoder.schema();
  return s.position_type == ScalarType::kFloat32 && s.vertex_properties.empty() && s.face_properties.empty();
}

void read_stream(std::unique_ptr<InputStream> stream, const std::string& name, MeshData* out) {
  OpenedMesh mesh;
  check(open_mesh(std::move(stream), OpenOptions(), &mesh), name);
  out->format = format_name(mesh.format);
  check(read_source(*mesh.source, out), name);
}

}  // namespace

void read_memory(const uint8_t* data, size_t size, const std::string& name, MeshData* out) {
  *out = MeshData();
  if (fast_psq(data, size)) {
    MeshBuffers buffers;
    check(decode_mesh(data, size, &buffers), name);
    out->format = "psq";
    out->position_type = ScalarType::kFloat32;
    out->positions_f = std::move(buffers.positions);
    out->faces = std::move(buffers.indices);
    return;
  }
  auto stream = std::make_unique<InputStream>();
  stream->open_memory(data, size, name);
  read_stream(std::move(stream), name, out);
}

void read_path(const std::string& path, MeshData* out) {
  *out = MeshData();
  auto stream = std::make_unique<InputStream>();
  check(stream->open(path), path);
  size_t available = 0;
  check(stream->fill(8, &available), path);
  // A .psq file of known size is read whole and decoded in memory (the
  // fast path); anything else streams through its reader.
  if (available >= 8 && is_psq(stream->cursor(), available) && stream->size() >= 0) {
    Buffer<uint8_t> bytes(static_cast<size_t>(stream->size()));
    check(stream->read_exact(bytes.data(), bytes.size()), path);
    bool end = false;
    check(stream->at_end(&end), path);
    if (!end) check(Status(ErrorCode::kIo, "the file grew while it was read"), path);
    read_memory(bytes.data(), bytes.size(), path, out);
    return;
  }
  read_stream(std::move(stream), path, out);
}

// ----------------------------------------------------------------- writing

namespace {

// The caller's arrays as a mesh source: every vertex, then every triangle.
class ArraySource : public MeshSource {
 public:
  explicit ArraySource(const InMesh& mesh) : mesh_(mesh) {
    schema_.position_type = mesh.positions_double ? ScalarType::kFloat64 : ScalarType::kFloat32;
    schema_.vertex_count = static_cast<int64_t>(mesh.vertices);
    schema_.triangle_count = static_cast<int64_t>(mesh.triangles);
    for (const InColumn& c : mesh.vertex_properties) schema_.vertex_properties.push_back(c.prop);
    for (const InColumn& c : mesh.face_properties) schema_.face_properties.push_back(c.prop);
    vertex_list_at_.assign(mesh.vertex_properties.size(), 0);
    face_list_at_.assign(mesh.face_properties.size(), 0);
  }
  const MeshSchema& schema() const override { return schema_; }
  const SourceReport& report() const override { return report_; }
  Status next(MeshItem* item) override {
    if (!error_.ok()) return error_;
    if (at_ < mesh_.vertices) {
      item->kind = MeshItem::Kind::kVertex;
      for (int k = 0; k < 3; ++k) {
        const uint64_t i = 3 * at_ + static_cast<uint64_t>(k);
        const double p = mesh_.positions_double ? static_cast<const double*>(mesh_.positions)[i]
                                                : static_cast<const float*>(mesh_.positions)[i];
        if (!std::isfinite(p))
          return error_ = Status(ErrorCode::kBadValue, "vertex " + std::to_string(at_) + ": position is not finite");
        item->position[k] = p;
      }
      gather(mesh_.vertex_properties, &vertex_list_at_, at_, &item->values);
      ++at_;
      return Status();
    }
    const uint64_t t = at_ - mesh_.vertices;
    if (t < mesh_.triangles) {
      item->kind = MeshItem::Kind::kTriangle;
      for (int k = 0; k < 3; ++k) {
        const uint32_t v = mesh_.faces[3 * t + static_cast<uint64_t>(k)];
        if (v >= mesh_.vertices)
          return error_ = Status(ErrorCode::kBadIndex, "face " + std::to_string(t) + ": index " + std::to_string(v) +
                                                           " is not below the vertex count " +
                                                           std::to_string(mesh_.vertices));
        item->index[k] = v;
      }
      gather(mesh_.face_properties, &face_list_at_, t, &item->values);
      ++at_;
      return Status();
    }
    item->kind = MeshItem::Kind::kEnd;
    return Status();
  }

 private:
  static void gather(const std::vector<InColumn>& cols, std::vector<uint64_t>* list_at, uint64_t e,
                     PropertyValues* values) {
    values->clear();
    for (size_t c = 0; c < cols.size(); ++c) {
      const InColumn& col = cols[c];
      if (!col.prop.is_list) {
        values->push_back(value_at(col.values, col.prop.type, e));
        continue;
      }
      const uint32_t n = col.counts[e];
      values->push_back(n);
      uint64_t& at = (*list_at)[c];
      for (uint32_t k = 0; k < n; ++k) values->push_back(value_at(col.values, col.prop.type, at++));
    }
  }

  const InMesh& mesh_;
  MeshSchema schema_;
  SourceReport report_;
  Status error_;
  uint64_t at_ = 0;
  std::vector<uint64_t> vertex_list_at_, face_list_at_;
};

void check_columns(const std::vector<InColumn>& cols, uint64_t elements, const char* what) {
  for (const InColumn& c : cols) {
    const std::string name = std::string(what) + " property '" + c.prop.name + "'";
    if (c.prop.name.empty() || c.prop.name.find_first_of(" \t\r\n") != std::string::npos)
      usage(std::string(what) + " property names must be non-empty and without blanks: '" + c.prop.name + "'");
    if (!c.prop.is_list) {
      if (c.value_count != elements)
        usage(name + " has " + std::to_string(c.value_count) + " values for " + std::to_string(elements) + " elements");
      continue;
    }
    uint64_t total = 0;
    const double max_count = c.prop.count_type == ScalarType::kUInt8    ? 255
                             : c.prop.count_type == ScalarType::kUInt16 ? 65535
                                                                         : 4294967295.0;
    for (uint64_t e = 0; e < elements; ++e) {
      if (c.counts[e] > max_count)
        usage(name + ": element " + std::to_string(e) + " has a list of " + std::to_string(c.counts[e]) +
              " values, more than its count type holds");
      total += c.counts[e];
    }
    if (total != c.value_count)
      usage(name + ": the counts add up to " + std::to_string(total) + " but " + std::to_string(c.value_count) +
            " values were given");
  }
}

}  // namespace

EncodeOptions encode_options(const WriteParams& p, bool fast_auto) {
  EncodeOptions o;
  if (!p.lossless && (p.bits < 1 || p.bits > 31)) usage("bits must be 1..31, not " + std::to_string(p.bits));
  if (p.profile != "auto" && p.profile != "fast" && p.profile != "compact")
    usage("profile must be 'auto', 'fast' or 'compact', not '" + p.profile + "'");
  if (p.chunk_bytes < 1 || p.chunk_bytes > (1u << 24)) usage("chunk_bytes must be 1 to 16M");
  if (p.zstd_level < 1 || p.zstd_level > 22) usage("zstd_level must be 1..22");
  if (p.normal_bits < 0 || p.normal_bits == 1 || p.normal_bits > 16) usage("normal_bits must be 0 or 2..16");
  if (p.uv_bits < 0 || p.uv_bits > 24) usage("uv_bits must be 0..24");
  o.bits = p.bits;
  o.lossless = p.lossless;
  o.normal_bits = p.normal_bits;
  o.uv_bits = p.uv_bits;
  o.fast = p.profile == "fast" || (p.profile == "auto" && fast_auto);
  o.chunk_bytes = p.chunk_bytes;
  o.zstd_level = p.zstd_level;
  return o;
}

WriteOptions write_options(const WriteParams& p) {
  WriteOptions w;
  w.ascii = p.ascii;
  w.spool_dir = p.tmpdir;
  w.draco_bits = p.bits;
  w.lossless = p.lossless;
  w.memory_budget = p.memory;
  return w;
}

void check_in_mesh(const InMesh& mesh) {
  if (mesh.vertices >= 0xffffffffull) check(Status(ErrorCode::kLimit, "more than 4294967294 vertices"), "");
  check_columns(mesh.vertex_properties, mesh.vertices, "vertex");
  check_columns(mesh.face_properties, mesh.triangles, "face");
}

std::vector<std::string> write_path(const InMesh& mesh, const std::string& path, const WriteParams& params) {
  check_in_mesh(mesh);
  const MeshFormat format = detail::output_format(params.format, path);
  if (format == MeshFormat::kUnknown) {
    if (!params.format.empty()) usage("unknown format '" + params.format + "' (psq, ply, obj or drc)");
    usage("cannot tell the format from '" + path + "': give format='psq', 'ply', 'obj' or 'drc'");
  }
  ArraySource source(mesh);
  OutputFile output;
  check(output.open(path, params.overwrite), path);
  std::vector<std::string> notes;
  Status s;
  if (format == MeshFormat::kPsq) {
    FileWriter writer(&output);
    PsqEncoder encoder(&writer, encode_options(params, detail::auto_fast_profile(source.schema())));
    BuildOptions build;
    build.memory_budget = params.memory;
    build.tmpdir = params.tmpdir;
    BuildReport report;
    s = build_sequence(source, encoder, build, &report);
    if (s.ok() && report.converter.degenerate_dropped)
      notes.push_back(std::to_string(report.converter.degenerate_dropped) +
                      " degenerate triangle(s) dropped (a repeated vertex index)");
  } else {
    if (format == MeshFormat::kDraco && !params.lossless && params.bits > 30) usage("bits must be 1..30 for Draco");
    std::unique_ptr<MeshSink> writer = make_mesh_writer(format, &output, write_options(params));
    s = pump(source, *writer);
    if (s.ok()) notes = detail::writer_notes(format, writer.get());
  }
  if (!s.ok()) {
    output.discard();
    check(s, path);
  }
  check(output.commit(), path);
  return notes;
}

void encode_bytes(const InMesh& mesh, const WriteParams& params, std::vector<uint8_t>* out) {
  check_in_mesh(mesh);
  ArraySource source(mesh);
  VectorWriter writer(out);
  PsqEncoder encoder(&writer, encode_options(params, detail::auto_fast_profile(source.schema())));
  BuildOptions build;
  build.memory_budget = params.memory;
  build.tmpdir = params.tmpdir;
  BuildReport report;
  Status s = build_sequence(source, encoder, build, &report);
  if (!s.ok()) {
    out->clear();
    check(s, "<memory>");
  }
}

// ---------------------------------------------------------------- streaming

StreamReader::StreamReader() = default;
StreamReader::~StreamReader() = default;

void StreamReader::open_path(const std::string& path) {
  name_ = path;
  in_ = std::make_unique<InputStream>();
  check(in_->open(path), path);
  decoder_ = std::make_unique<PsqDecoder>();
  check(decoder_->open(in_.get()), path);
}

void StreamReader::open_memory(const uint8_t* data, size_t size) {
  name_ = "<memory>";
  in_ = std::make_unique<InputStream>();
  in_->open_memory(data, size, name_);
  decoder_ = std::make_unique<PsqDecoder>();
  check(decoder_->open(in_.get()), name_);
}

const PsqHeader& StreamReader::header() const { return decoder_->header(); }
const PsqStats& StreamReader::stats() const { return decoder_->stats(); }

void StreamReader::close() {
  // The input goes (its file is closed); the decoder stays, idle, for
  // header() and stats(): next() never calls it again.
  done_ = true;
  has_pending_ = false;
  pending_ = SequenceEvent();
  in_.reset();
}

void StreamReader::next(uint64_t max_triangles, Chunk* c) {
  *c = Chunk();
  const MeshSchema& schema = decoder_->schema();
  const bool dbl = schema.position_type == ScalarType::kFloat64;
  c->vertex_properties = make_columns(schema.vertex_properties);
  c->face_properties = make_columns(schema.face_properties);
  c->vertex_start = vertices_;
  c->triangle_start = triangles_;
  if (done_) {
    c->end = true;
    return;
  }
  max_triangles = std::max<uint64_t>(max_triangles, 1);
  uint64_t nv = 0, nt = 0;
  bool any = false;
  SequenceEvent ev;
  for (;;) {
    if (has_pending_) {
      ev = std::move(pending_);
      has_pending_ = false;
    } else {
      check(decoder_->next(&ev), name_);
    }
    if (ev.kind == SequenceEvent::Kind::kEnd) {
      done_ = true;
      break;
    }
    const bool full = nt >= max_triangles || nv >= max_triangles;
    if (full && ev.kind != SequenceEvent::Kind::kFinalize) {
      pending_ = std::move(ev);
      has_pending_ = true;
      break;
    }
    any = true;
    switch (ev.kind) {
      case SequenceEvent::Kind::kVertex: {
        const SequenceVertex& v = ev.vertex;
        for (int k = 0; k < 3; ++k) {
          if (dbl) c->positions_d.push_back(v.position[k]);
          else c->positions_f.push_back(static_cast<float>(v.position[k]));
        }
        c->reappears.push_back(v.reappears == kNoVertex ? -1 : static_cast<int64_t>(v.reappears));
        if (!c->vertex_properties.empty()) append_values(&c->vertex_properties, v.values);
        ++nv;
        break;
      }
      case SequenceEvent::Kind::kTriangle: {
        const SequenceTriangle& t = ev.triangle;
        c->faces.insert(c->faces.end(), t.v, t.v + 3);
        c->ops.push_back(static_cast<uint8_t>(t.op));
        c->new_mask.push_back(t.new_mask);
        c->final_mask.push_back(t.final_mask);
        c->border_mask.push_back(t.border_mask);
        if (!c->face_properties.empty()) append_values(&c->face_properties, t.values);
        ++nt;
        break;
      }
      case SequenceEvent::Kind::kFinalize: c->finalized.push_back(ev.finalized); break;
      case SequenceEvent::Kind::kEnd: break;
    }
  }
  vertices_ += nv;
  triangles_ += nt;
  c->end = !any;
}

}  // namespace psq::python
