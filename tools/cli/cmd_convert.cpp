// SPDX-License-Identifier: Apache-2.0
// psq convert: stream a mesh from one format to another.
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>
#include <thread>

#include "cli_util.h"
#include "progress.h"
#include "commands.h"
#include "corner_weld.h"
#include "psq/ply.h"
#include "pipeline.h"
#include "psq/draco.h"
#include "psq/mesh_formats.h"
#include "psq/obj.h"
#include "psq/psq_codec.h"
#include "psq/sequence_builder.h"
#include "psq/threaded_sink.h"

namespace psq::cli {
namespace {

const char kHelp[] =
    "Usage: psq convert IN OUT [OPTIONS]\n"
    "       psq convert -o OUT IN [OPTIONS]\n"
    "\n"
    "Converts IN to OUT, streaming: one element in memory at a time (an OBJ\n"
    "with normals or texture coordinates is read in memory; see README).\n"
    "The input format is recognised by content (PLY, OBJ, OFF, STL, .psq,\n"
    "Draco); the output format comes from --to or OUT's extension (.ply,\n"
    ".obj, .psq, .drc). IN and OUT may be '-'. To .psq, the mesh goes through\n"
    "the processing-sequence converter (one pass when coherent, else an\n"
    "external sort within --memory). Draco (.drc) is in-core: the whole mesh\n"
    "is held in memory, and a mesh that would take more than --memory is\n"
    "refused. .drc is written with edgebreaker at compression level 7;\n"
    "normals, uchar colors, u/v and other scalar vertex\n"
    "properties are kept; face and list properties are dropped (named in a\n"
    "note). The output is written to a temporary file and renamed on success.\n"
    "Output to stdout, a pipe or a device cannot be taken back after an error.\n"
    "When standard error is a terminal, a progress line (percent of input,\n"
    "triangles per second, time left; at most ten updates a second) and a\n"
    "one-line summary go there.\n"
    "\n"
    "Options:\n"
    "  -o, --output OUT  write to OUT (instead of the second argument)\n"
    "  --to FORMAT    output format: ply, obj, psq or drc (needed when OUT is '-')\n"
    "  --bits N       quantize positions to N bits: .psq 1..31 (default 16), .drc 1..30\n"
    "  --lossless     .psq, .drc: keep positions bit-exact instead of quantizing\n"
    "                 (Draco stores unquantized floats raw); .psq: normals and\n"
    "                 texture coordinates too\n"
    "  --normal-bits N  .psq: normals (nx ny nz) on an octahedral grid of N bits\n"
    "                 a coordinate, 2..16, or 0 to keep them exact (default 10)\n"
    "  --uv-bits N    .psq: texture coordinates (u v, s t, ...) on a grid of step\n"
    "                 2^-N, 1..24, or 0 to keep them exact (default 12)\n"
    "  --memory SIZE  memory budget of the external sort, of the converter's\n"
    "                 lookahead (a quarter) and of Draco input or output\n"
    "                 (default 512M)\n"
    "  --chunk SIZE   .psq: close a chunk at this many coded bytes (default 1M)\n"
    "  --segment N    .psq: a segment every N triangles, where a decoder can\n"
    "                 start: segments decode in parallel. 0: one segment;\n"
    "                 auto (default): four, of at least 2M triangles each\n"
    "  --profile P    .psq: compact (the smallest files), fast (table-driven:\n"
    "                 several times faster to decode, a few percent larger;\n"
    "                 bench/RESULTS.md has the figures) or auto (the default:\n"
    "                 fast when the input declares 131072 triangles or more,\n"
    "                 or, not declaring its triangles (a PLY, whose faces may\n"
    "                 be polygons), 65536 vertices or more, where the fast\n"
    "                 profile's per-chunk tables no longer weigh; a .psq input\n"
    "                 keeps its own profile)\n"
    "  --weld[=positions|corners]  .psq from a mesh: merge vertices with\n"
    "                 identical positions and property values (=positions:\n"
    "                 identical positions alone; the first vertex keeps its\n"
    "                 values; =corners: identical positions and values but\n"
    "                 normals and texture coordinates, which are then kept\n"
    "                 per corner where they differ, the mesh read in memory:\n"
    "                 for meshes split at texture seams and creases)\n"
    "                 before the sequence is built, and drop the triangles\n"
    "                 this makes degenerate. Identical: the same bits as read,\n"
    "                 -0.0 equal to 0.0. Without it the mesh is kept exactly,\n"
    "                 and a note suggests --weld when most vertices repeat\n"
    "                 another vertex's position (a triangle soup)\n"
    "  --ascii        write ascii PLY instead of binary little-endian\n"
    "  --tmpdir DIR   directory for temporary spool files (default $TMPDIR)\n"
    "  --threads N    1 runs on one thread. More (the default: one per core):\n"
    "                 to .psq, the encoder runs on a second thread while the\n"
    "                 first reads and converts; from a .psq file to binary\n"
    "                 PLY, N of its segments decode at once and are written\n"
    "                 in place (the output is the same)\n"
    "  -f, --force    overwrite OUT if it exists\n"
    "  -q, --quiet    print no notes, no progress line and no summary\n"
    "  --json         print a JSON summary on standard output (not with OUT '-')\n"
    "  -h, --help     show this help\n";

// --profile auto: the fast profile from this many declared triangles or,
// when the input does not declare its triangles (a PLY's faces may be
// polygons), this many declared vertices: a closed mesh has about twice as
// many triangles as vertices.
constexpr int64_t kAutoFastTriangles = 131072;
constexpr int64_t kAutoFastVertices = 65536;

bool auto_fast(const MeshSchema& schema) {
  if (schema.triangle_count != MeshSchema::kUnknown) return schema.triangle_count >= kAutoFastTriangles;
  return schema.vertex_count != MeshSchema::kUnknown && schema.vertex_count >= kAutoFastVertices;
}

// IN (any mesh, or .psq) to a .psq OUT: the processing sequence of the
// mesh, or the decoded sequence of a .psq, into the encoder.
int to_psq(const std::string& in, const std::string& out, OpenedMesh& mesh, OutputFile& output,
           const EncodeOptions& encode_options, const BuildOptions& build_options, int threads, bool quiet,
           bool json) {
  FileWriter writer(&output);
  PsqEncoder encoder(&writer, encode_options);
  Status s;
  BuildReport report;
  Progress progress(mesh.stream.get(), !quiet);
  // With two threads the encoder runs on the second (psq/threaded_sink.h).
  std::unique_ptr<ThreadedSequenceSink> threaded;
  if (threads > 1) threaded = std::make_unique<ThreadedSequenceSink>(&encoder);
  ProgressSequenceSink sink(threaded ? static_cast<SequenceSink*>(threaded.get()) : &encoder, &progress);
  if (mesh.decoder) {
    s = mesh.decoder->pump(sink);
  } else {
    ProgressSource source(mesh.source.get(), &progress);
    s = build_sequence(source, sink, build_options, &report);
  }
  if (!s.ok()) {
    threaded.reset();  // stops the encoder's thread before the output goes
    output.discard();
    return report_pipeline_error(in, out, s);
  }
  s = output.commit();
  if (!s.ok()) return report_error(out, s);
  const PsqStats& st = encoder.stats();
  std::vector<std::string> notes = detail::input_notes(mesh, report);
  if (!mesh.decoder)
    for (std::string& n : detail::weld_notes(build_options.weld, report, mesh.source->schema()))
      notes.push_back(std::move(n));
  const bool welded = build_options.weld != WeldMode::kOff;
  if (!quiet)
    for (const std::string& n : notes) note(in, n);
  const double nv = st.vertices ? static_cast<double>(st.vertices) : 1.0;
  {
    char summary[256];
    std::snprintf(summary, sizeof summary, "%llu triangles, %llu -> %llu bytes, %.2f bits/vertex",
                  static_cast<unsigned long long>(st.triangles), static_cast<unsigned long long>(mesh.stream->offset()),
                  static_cast<unsigned long long>(output.size()), 8.0 * st.total_bytes / nv);
    std::string line = summary;
    if (welded) line += ", " + std::to_string(report.welded_vertices) + " vertices welded";
    progress.finish(in, out, line);
  }
  if (json) {
    std::string o = "{\"input\": \"" + json_escape(in) + "\", \"output\": \"" + json_escape(out) +
                    "\", \"input_format\": \"" + format_name(mesh.format) +
                    "\", \"output_format\": \"psq\", \"vertices\": " + std::to_string(st.vertices) +
                    ", \"triangles\": " + std::to_string(st.triangles) + ", \"bytes_out\": " +
                    std::to_string(output.size()) + ", \"bits_per_vertex\": " + json_number(8.0 * st.total_bytes / nv) +
                    ", \"connectivity_bits_per_vertex\": " + json_number(st.connectivity_bits / nv) +
                    ", \"geometry_bits_per_vertex\": " + json_number(st.geometry_bits / nv) +
                    ", \"property_bits_per_vertex\": " + json_number(8.0 * st.property_bytes / nv) +
                    ", \"lossless\": " + (encode_options.lossless ? "true" : "false") +
                    ", \"bits\": " + std::to_string(encode_options.lossless ? 0 : encode_options.bits) +
                    detail::json_weld(build_options.weld, report, !mesh.decoder,
                                      dynamic_cast<const detail::CornerWelder*>(mesh.source.get()));
    o += ", \"notes\": [";
    for (size_t i = 0; i < notes.size(); ++i) o += (i ? ", \"" : "\"") + json_escape(notes[i]) + "\"";
    o += "]}\n";
    std::fputs(o.c_str(), stdout);
  }
  return kExitOk;
}

}  // namespace

int cmd_convert(int argc, char** argv) {
  Args args(argc, argv, 1);
  if (args.flag("--help", "-h")) {
    std::fputs(kHelp, stdout);
    return kExitOk;
  }
  bool force = args.flag("--force", "-f");
  bool quiet = args.flag("--quiet", "-q");
  bool json = args.flag("--json");
  bool ascii = args.flag("--ascii");
  bool lossless = args.flag("--lossless");
  // --weld alone, or --weld=all|positions.
  const bool weld_flag = args.flag("--weld");
  std::string weld_text = args.option("--weld", weld_flag ? "all" : "off");
  std::string to = args.option("--to");
  std::string out_option = args.option("--output", args.option("-o"));
  std::string tmpdir = args.option("--tmpdir");
  std::string bits_text = args.option("--bits", "16");
  std::string normal_bits_text = args.option("--normal-bits", "10");
  std::string uv_bits_text = args.option("--uv-bits", "12");
  std::string memory = args.option("--memory", "512M");
  std::string chunk = args.option("--chunk", "1M");
  std::string segment = args.option("--segment", "auto");
  std::string profile = args.option("--profile", "auto");
  std::string threads_text = args.option("--threads", std::to_string(std::max(1u, std::thread::hardware_concurrency())));
  std::vector<std::string> files = args.positionals();
  if (!args.error().empty()) return usage_error("convert", args.error());
  // OUT is the second positional, or -o's value (as in zstd and draco_encoder).
  if (!out_option.empty()) files.push_back(out_option);
  if (files.size() != 2) {
    return usage_error("convert", files.size() < 2 ? "convert takes IN and OUT (or -o OUT)"
                                                   : "convert takes one IN and one OUT (OUT given twice?)");
  }
  const std::string& in = files[0];
  const std::string& out = files[1];
  EncodeOptions encode_options;
  encode_options.lossless = lossless;
  {
    char* end = nullptr;
    long b = std::strtol(bits_text.c_str(), &end, 10);
    if (bits_text.empty() || *end != 0 || b < 1 || b > 31)
      return usage_error("convert", "bad --bits '" + bits_text + "' (1..31)");
    encode_options.bits = static_cast<int>(b);
    b = std::strtol(normal_bits_text.c_str(), &end, 10);
    if (normal_bits_text.empty() || *end != 0 || b < 0 || b == 1 || b > 16)
      return usage_error("convert", "bad --normal-bits '" + normal_bits_text + "' (0, or 2..16)");
    encode_options.normal_bits = static_cast<int>(b);
    b = std::strtol(uv_bits_text.c_str(), &end, 10);
    if (uv_bits_text.empty() || *end != 0 || b < 0 || b > 24)
      return usage_error("convert", "bad --uv-bits '" + uv_bits_text + "' (0 to 24)");
    encode_options.uv_bits = static_cast<int>(b);
  }
  uint64_t chunk_bytes = 0;
  if (!parse_size(chunk, &chunk_bytes) || chunk_bytes > (uint64_t{1} << 24))
    return usage_error("convert", "bad --chunk '" + chunk + "' (1 to 16M)");
  encode_options.chunk_bytes = static_cast<uint32_t>(chunk_bytes);
  if (segment == "0") encode_options.segment_triangles = 0;
  else if (segment != "auto" && !parse_size(segment, &encode_options.segment_triangles))
    return usage_error("convert", "bad --segment '" + segment + "' (a count of triangles, 0 for one segment)");
  // The JSON summary splits the bits into connectivity and geometry.
  encode_options.measure_costs = json;
  if (profile != "compact" && profile != "fast" && profile != "auto")
    return usage_error("convert", "bad --profile '" + profile + "' (compact, fast or auto)");
  int threads = 0;
  if (!parse_threads(threads_text, 1, &threads))
    return usage_error("convert", "bad --threads '" + threads_text + "' (1 to 1024)");
  BuildOptions build_options;
  build_options.tmpdir = tmpdir;
  if (!parse_size(memory, &build_options.memory_budget))
    return usage_error("convert", "bad --memory '" + memory + "' (e.g. 256M, 2G)");
  if (weld_text == "all") build_options.weld = WeldMode::kAll;
  else if (weld_text == "positions") build_options.weld = WeldMode::kPositions;
  else if (weld_text != "off" && weld_text != "corners")
    return usage_error("convert", "bad --weld '" + weld_text + "' (--weld, --weld=positions or --weld=corners)");
  const bool weld_corners = weld_text == "corners";

  MeshFormat out_format = to.empty() ? format_from_extension(out) : format_from_name(to);
  if (out_format == MeshFormat::kUnknown) {
    if (!to.empty()) return usage_error("convert", "unknown output format '" + to + "' (ply, obj, psq or drc)");
    return usage_error("convert", "cannot tell the output format from '" + out + "': use --to ply|obj|psq|drc");
  }
  if (out_format == MeshFormat::kDraco && !lossless && encode_options.bits > 30)
    return usage_error("convert", "bad --bits " + bits_text + " for Draco (1..30)");
  if ((build_options.weld != WeldMode::kOff || weld_corners) && out_format != MeshFormat::kPsq)
    return usage_error("convert", "--weld applies to .psq output");
  if (same_file(in, out)) return usage_error("convert", "IN and OUT are the same file");
  if (out == "-" && json) return usage_error("convert", "--json needs OUT to be a file (stdout carries the mesh)");
  if (out == "-" && ::isatty(STDOUT_FILENO) && !(out_format == MeshFormat::kObj || ascii)) {
    return usage_error("convert", "refusing to write binary data to a terminal");
  }

  OpenOptions open_options;
  open_options.spool_dir = tmpdir;
  open_options.memory_budget = build_options.memory_budget;
  OpenedMesh mesh;
  Status s = open_mesh(in, open_options, &mesh);
  if (!s.ok()) return report_error(in, s);
  if (mesh.decoder && (build_options.weld != WeldMode::kOff || weld_corners)) {
    // A .psq input is re-encoded as decoded, without a builder to weld.
    return usage_error("convert", "--weld applies to a mesh input, not to a .psq");
  }
  if (weld_corners) {
    auto welder = std::make_unique<detail::CornerWelder>(std::move(mesh.source), build_options.memory_budget);
    s = welder->open();
    if (!s.ok()) return report_error(in, s);
    mesh.source = std::move(welder);
  }

  OutputFile output;
  s = output.open(out, force);
  if (!s.ok()) return report_error(out, s);
  if (profile == "fast") encode_options.fast = true;
  // A .psq input's mesh source declares no counts: its header tells the
  // profile it was written in, and the decoder's schema the counts it knows.
  if (profile == "auto")
    encode_options.fast = mesh.decoder ? mesh.decoder->header().fast || auto_fast(mesh.decoder->schema())
                                       : auto_fast(mesh.source->schema());
  // Spec 4.6: the input's counts size the segments (the sequence builder
  // does not pass them on; a .psq file has them in its end record).
  if (encode_options.segment_triangles == EncodeOptions::kAutoSegments)
    encode_options.segment_triangles = auto_segment_triangles(mesh);
  if (out_format == MeshFormat::kPsq) return to_psq(in, out, mesh, output, encode_options, build_options, threads, quiet, json);
  WriteOptions write_options;
  write_options.ascii = ascii;
  write_options.spool_dir = tmpdir;
  write_options.draco_bits = encode_options.bits;
  write_options.lossless = lossless;
  write_options.memory_budget = build_options.memory_budget;
  // A .psq file to binary PLY: the segments decode at once and each
  // writes its part of the file in place (spec 4.6).
  if (mesh.decoder && out_format == MeshFormat::kPly && !ascii && mesh.stream->can_rewind() &&
      output.seekable()) {
    uint64_t nv = 0, nt = 0;
    Progress progress(mesh.stream.get(), !quiet);
    s = write_ply_by_segments(in, &output, threads, &nv, &nt);
    if (s.ok()) {
      s = output.commit();
      if (!s.ok()) return report_error(out, s);
      progress.finish(in, out,
                      std::to_string(nt) + " triangles, " + std::to_string(mesh.stream->size()) + " -> " +
                          std::to_string(output.size()) + " bytes");
      if (json)
        std::printf("{\"input\": \"%s\", \"output\": \"%s\", \"input_format\": \"psq\", \"output_format\": "
                    "\"ply\", \"vertices\": %llu, \"triangles\": %llu, \"bytes_out\": %llu, \"notes\": []}\n",
                    json_escape(in).c_str(), json_escape(out).c_str(), static_cast<unsigned long long>(nv),
                    static_cast<unsigned long long>(nt), static_cast<unsigned long long>(output.size()));
      return kExitOk;
    }
    if (s.code() != ErrorCode::kUnsupported) {
      output.discard();
      return report_pipeline_error(in, out, s);
    }
  }
  std::unique_ptr<MeshSink> writer = make_mesh_writer(out_format, &output, write_options);

  // One thread: a writer's work per element is too small to pay for
  // handing elements to another core (bench/RESULTS.md, "Two threads in
  // psq convert").
  detail::MeshCounter counter(writer.get());

  Progress progress(mesh.stream.get(), !quiet);
  ProgressSource source(mesh.source.get(), &progress);
  s = pump(source, counter);
  // Errors of the sink are about OUT unless they carry an input place.
  if (!s.ok()) {
    output.discard();
    return report_pipeline_error(in, out, s);
  }
  s = output.commit();
  if (!s.ok()) return report_error(out, s);

  std::vector<std::string> notes = mesh.source->report().notes;
  for (std::string& n : detail::writer_notes(out_format, writer.get())) notes.push_back(std::move(n));
  if (!quiet) {
    for (const std::string& n : notes) note(in, n);
  }
  progress.finish(in, out,
                  std::to_string(counter.triangles) + " triangles, " + std::to_string(mesh.stream->offset()) + " -> " +
                      std::to_string(output.size()) + " bytes");
  if (json) {
    std::string o = "{\"input\": \"" + json_escape(in) + "\", \"output\": \"" + json_escape(out) +
                    "\", \"input_format\": \"" + format_name(mesh.format) + "\", \"output_format\": \"" +
                    format_name(out_format) + "\", \"vertices\": " + std::to_string(counter.vertices) +
                    ", \"triangles\": " + std::to_string(counter.triangles) +
                    ", \"bytes_out\": " + std::to_string(output.size()) + ", \"notes\": [";
    for (size_t i = 0; i < notes.size(); ++i) o += (i ? ", \"" : "\"") + json_escape(notes[i]) + "\"";
    o += "]}\n";
    std::fputs(o.c_str(), stdout);
  }
  return kExitOk;
}

}  // namespace psq::cli
