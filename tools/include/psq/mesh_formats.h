// SPDX-License-Identifier: Apache-2.0
// psq/mesh_formats.h: which mesh format a file is, and opening the right
// reader or writer for it.
//
// Input formats are recognised by content, never by file name; output
// formats by an explicit name or the file extension. OFF and STL are input
// formats only.
#ifndef PSQ_MESH_FORMATS_H_
#define PSQ_MESH_FORMATS_H_

#include <memory>
#include <string>

#include "psq/indexed_mesh.h"
#include "psq/io.h"
#include "psq/psq_codec.h"

namespace psq {

enum class MeshFormat { kUnknown, kPly, kObj, kOff, kStl, kPsq, kDraco };

// "ply", "obj", "off", "stl", "psq", "drc" or "unknown".
const char* format_name(MeshFormat f);
// The output format named `name` ("ply", "obj", "psq", "drc"; case-insensitive),
// or kUnknown (also for "off" and "stl", which psq does not write).
MeshFormat format_from_name(const std::string& name);
// The format of an output path by its extension, or kUnknown.
MeshFormat format_from_extension(const std::string& path);
// The format of input whose first bytes are `data`, or kUnknown.
// `total_size` is the whole input's size, or -1 when unknown (a pipe): a
// binary STL has no magic and is recognised by its size (84 + 50 * count),
// or, from a pipe, as the last resort for 84 bytes or more that match no
// other format.
MeshFormat detect_format(const uint8_t* data, size_t size, int64_t total_size = -1);

// An open input: the byte stream and the source reading it.
struct OpenedMesh {
  std::unique_ptr<InputStream> stream;
  // For .psq input: the decoder, open. Commands that want the processing
  // sequence itself pull it; `source` reads it as a mesh (psq/psq_mesh.h).
  std::unique_ptr<PsqDecoder> decoder;
  std::unique_ptr<MeshSource> source;
  MeshFormat format = MeshFormat::kUnknown;
};

struct OpenOptions {
  std::string spool_dir;  // for inputs that must be spooled (empty: $TMPDIR)
  // Draco input is decoded in memory: the most it may take (bytes).
  uint64_t memory_budget = uint64_t{512} << 20;
};

// Opens `path` ("-": standard input), detects its format by content and
// reads its header. Errors: kIo, kUnknownFormat, and the reader's errors.
Status open_mesh(const std::string& path, const OpenOptions& options, OpenedMesh* out);
// The same for a stream already open (nothing of it consumed: the format
// is detected from its first bytes); `out` takes it over.
Status open_mesh(std::unique_ptr<InputStream> stream, const OpenOptions& options, OpenedMesh* out);

// The .psq encoder's segment size for the opened input
// (EncodeOptions::auto_segment_triangles()): from the counts of its
// header, or for a .psq file from the totals of its end record. With
// `share`, for an output of that share of the input's triangles (a
// filter's: a simplification to 10% passes 0.1).
uint64_t auto_segment_triangles(OpenedMesh& mesh, double share = 1);

struct WriteOptions {
  bool ascii = false;     // PLY: ascii instead of binary little-endian
  std::string spool_dir;  // PLY: where to spool when counts are unknown
  int draco_bits = 16;    // Draco: position quantization bits (1..30)
  bool lossless = false;  // Draco: positions and float attributes unquantized
  uint64_t memory_budget = uint64_t{512} << 20;  // Draco: in-core limit (bytes)
};

// A sink writing `format` to `out`, which must outlive it. Never null for
// kPly, kObj and kDraco (a DracoWriter, in-core); null for kUnknown, kOff
// and kStl (input formats only) and kPsq (a sequence format: its writer is
// PsqEncoder).
std::unique_ptr<MeshSink> make_mesh_writer(MeshFormat format, OutputFile* out,
                                           const WriteOptions& options);

}  // namespace psq

#endif  // PSQ_MESH_FORMATS_H_
