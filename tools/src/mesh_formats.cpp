// SPDX-License-Identifier: Apache-2.0
// Format detection by content and the reader/writer factory (psq/mesh_formats.h).
#include "psq/mesh_formats.h"
#include "psq/psq_mesh.h"

#include <algorithm>
#include <cctype>
#include <cmath>

#include "psq/draco.h"
#include "psq/obj.h"
#include "psq/off.h"
#include "psq/ply.h"
#include "psq/stl.h"

namespace psq {

const char* format_name(MeshFormat f) {
  switch (f) {
    case MeshFormat::kPly: return "ply";
    case MeshFormat::kObj: return "obj";
    case MeshFormat::kOff: return "off";
    case MeshFormat::kStl: return "stl";
    case MeshFormat::kPsq: return "psq";
    case MeshFormat::kDraco: return "drc";
    case MeshFormat::kUnknown: break;
  }
  return "unknown";
}

MeshFormat format_from_name(const std::string& name) {
  std::string n = name;
  std::transform(n.begin(), n.end(), n.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (n == "ply") return MeshFormat::kPly;
  if (n == "obj") return MeshFormat::kObj;
  if (n == "psq") return MeshFormat::kPsq;
  if (n == "drc" || n == "draco") return MeshFormat::kDraco;
  return MeshFormat::kUnknown;
}

MeshFormat format_from_extension(const std::string& path) {
  size_t dot = path.rfind('.');
  size_t slash = path.rfind('/');
  if (dot == std::string::npos || (slash != std::string::npos && dot < slash)) return MeshFormat::kUnknown;
  return format_from_name(path.substr(dot + 1));
}

MeshFormat detect_format(const uint8_t* data, size_t size, int64_t total_size) {
  if (is_psq(data, size)) return MeshFormat::kPsq;
  if (looks_like_draco(data, size)) return MeshFormat::kDraco;
  if (looks_like_ply(data, size)) return MeshFormat::kPly;
  // With a known size: a binary STL of exactly the size its count implies
  // (whatever its header says), or an ascii "solid ... facet".
  if (total_size >= 0 && looks_like_stl(data, size, total_size)) return MeshFormat::kStl;
  if (looks_like_off(data, size)) return MeshFormat::kOff;
  if (looks_like_obj(data, size)) return MeshFormat::kObj;
  // From a pipe, STL (ascii, or binary as the last resort) is asked last.
  if (total_size < 0 && looks_like_stl(data, size, total_size)) return MeshFormat::kStl;
  return MeshFormat::kUnknown;
}

uint64_t auto_segment_triangles(OpenedMesh& mesh, double share) {
  MeshSchema counts = mesh.decoder ? mesh.decoder->schema() : mesh.source->schema();
  std::vector<PsqSegment> segments;
  PsqSegment end;
  if (mesh.decoder && mesh.stream->can_rewind() && mesh.decoder->segments(&segments, &end).ok())
    counts.triangle_count = static_cast<int64_t>(end.triangles);
  if (share != 1) {
    // As EncodeOptions::auto_segment_triangles() counts: the triangles,
    // else twice the vertices.
    const int64_t t = counts.triangle_count >= 0 ? counts.triangle_count
                      : counts.vertex_count >= 0 ? 2 * counts.vertex_count
                                                 : -1;
    if (t >= 0) counts.triangle_count = std::llround(std::max(0.0, share) * static_cast<double>(t));
  }
  return EncodeOptions::auto_segment_triangles(counts);
}

Status open_mesh(const std::string& path, const OpenOptions& options, OpenedMesh* out) {
  auto stream = std::make_unique<InputStream>();
  PSQ_RETURN_IF_ERROR(stream->open(path));
  return open_mesh(std::move(stream), options, out);
}

Status open_mesh(std::unique_ptr<InputStream> stream, const OpenOptions& options, OpenedMesh* out) {
  out->stream = std::move(stream);
  // The first 4 KiB decide; comments at the top of an OBJ may be longer, in
  // which case looks_like_obj() sees only comment text and says no.
  size_t avail;
  PSQ_RETURN_IF_ERROR(out->stream->fill(4096, &avail));
  // fill() stops short only at the end of the input: then the whole input
  // is in view and its size is known even from a pipe.
  int64_t total = out->stream->size();
  if (total < 0 && avail < 4096) total = static_cast<int64_t>(avail);
  out->format = detect_format(out->stream->cursor(), avail, total);
  switch (out->format) {
    case MeshFormat::kPly: {
      auto reader = std::make_unique<PlyReader>();
      PSQ_RETURN_IF_ERROR(reader->open(out->stream.get()));
      out->source = std::move(reader);
      return Status();
    }
    case MeshFormat::kObj: {
      auto reader = std::make_unique<ObjReader>();
      PSQ_RETURN_IF_ERROR(reader->open(out->stream.get(), options.spool_dir));
      out->source = std::move(reader);
      return Status();
    }
    case MeshFormat::kOff: {
      auto reader = std::make_unique<OffReader>();
      PSQ_RETURN_IF_ERROR(reader->open(out->stream.get()));
      out->source = std::move(reader);
      return Status();
    }
    case MeshFormat::kStl: {
      auto reader = std::make_unique<StlReader>();
      PSQ_RETURN_IF_ERROR(reader->open(out->stream.get()));
      out->source = std::move(reader);
      return Status();
    }
    case MeshFormat::kPsq: {
      out->decoder = std::make_unique<PsqDecoder>();
      PSQ_RETURN_IF_ERROR(out->decoder->open(out->stream.get()));
      out->source = std::make_unique<PsqMeshSource>(out->decoder.get());
      return Status();
    }
    case MeshFormat::kDraco: {
      auto reader = std::make_unique<DracoReader>();
      PSQ_RETURN_IF_ERROR(reader->open(out->stream.get(), options.memory_budget));
      out->source = std::move(reader);
      return Status();
    }
    case MeshFormat::kUnknown: break;
  }
  if (avail == 0) return Status(ErrorCode::kUnknownFormat, "empty input", 0);
  return Status(ErrorCode::kUnknownFormat, "not a PLY, OBJ, OFF, STL, .psq or Draco file (unrecognised content)", 0);
}

std::unique_ptr<MeshSink> make_mesh_writer(MeshFormat format, OutputFile* out, const WriteOptions& options) {
  switch (format) {
    case MeshFormat::kPly: {
      PlyWriteOptions o;
      o.encoding = options.ascii ? PlyEncoding::kAscii : PlyEncoding::kBinaryLittleEndian;
      o.spool_dir = options.spool_dir;
      return std::make_unique<PlyWriter>(out, o);
    }
    case MeshFormat::kObj: return std::make_unique<ObjWriter>(out);
    case MeshFormat::kDraco: {
      DracoWriteOptions o;
      o.bits = options.draco_bits;
      o.lossless = options.lossless;
      o.memory_budget = options.memory_budget;
      return std::make_unique<DracoWriter>(out, o);
    }
    case MeshFormat::kOff:
    case MeshFormat::kStl:
    case MeshFormat::kPsq:
    case MeshFormat::kUnknown: break;
  }
  return nullptr;
}

}  // namespace psq
