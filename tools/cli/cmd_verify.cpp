// SPDX-License-Identifier: Apache-2.0
// psq verify: decode a .psq completely and check it.
#include <cstdio>
#include <string>

#include "cli_util.h"
#include "progress.h"
#include "commands.h"
#include "psq/mesh_formats.h"

namespace psq::cli {
namespace {

const char kHelp[] =
    "Usage: psq verify FILE [-q] [--json] [--threads N]\n"
    "\n"
    "Decodes the .psq FILE ('-' for standard input) in one pass, checks every\n"
    "checksum, limit and count of the stream (spec/psq-format.md), and every\n"
    "record against the boundary it decodes, so that what it yields is a\n"
    "valid processing sequence (spec/psq-dump.md A.2). Exit 0\n"
    "and a one-line summary when it is; exit 1 and the first problem with\n"
    "its byte offset otherwise. Memory: the processing boundary and one\n"
    "chunk, whatever the size of the file.\n"
    "\n"
    "Options:\n"
    "  -q, --quiet    print nothing on success\n"
    "  --threads N    decode N segments at once (spec 4.6; default 0: one\n"
    "                 per core); a stream of one segment, or a pipe, takes one\n"
    "  --json         print the summary as one JSON object (file, version,\n"
    "                 profile, vertices, triangles, chunks, bytes,\n"
    "                 max_boundary_vertices)\n"
    "  -h, --help     show this help\n";

}  // namespace

int cmd_verify(int argc, char** argv) {
  Args args(argc, argv, 1);
  if (args.flag("--help", "-h")) {
    std::fputs(kHelp, stdout);
    return kExitOk;
  }
  bool quiet = args.flag("--quiet", "-q");
  bool json = args.flag("--json");
  const std::string threads_text = args.option("--threads", "0");
  int threads = 0;
  if (!parse_threads(threads_text, 0, &threads))
    return usage_error("verify", "bad --threads '" + threads_text + "' (0 for one per core)");
  std::vector<std::string> files = args.positionals();
  if (!args.error().empty()) return usage_error("verify", args.error());
  if (files.size() != 1) return usage_error("verify", files.empty() ? "missing FILE" : "verify takes one FILE");
  const std::string& file = files[0];
  OpenedMesh mesh;
  Status s = open_mesh(file, OpenOptions(), &mesh);
  if (!s.ok()) return report_error(file, s);
  if (!mesh.decoder) return report_error(file, Status(ErrorCode::kUnknownFormat, std::string("not a .psq file (") + format_name(mesh.format) + ")", 0));
  // The decoder checks every record against its boundary (spec 6, 9), so
  // pulling every event is the whole check; a SequenceChecker would add
  // statistics whose union-finds grow with the mesh (psq info has them).
  struct Discard : SequenceSink {
    Status begin(const MeshSchema&) override { return Status(); }
    Status vertex(const SequenceVertex&) override { return Status(); }
    Status triangle(const SequenceTriangle&) override { return Status(); }
    Status finalize(uint32_t) override { return Status(); }
    Status finish() override { return Status(); }
  } discard;
  // A stream of several segments (spec 4.6) in a file: every segment at
  // once, each thread with its own view of the file.
  std::vector<PsqSegment> segments;
  PsqStats parallel_stats;
  bool parallel = false;
  if (threads != 1 && mesh.stream->can_rewind() && mesh.decoder->segments(&segments).ok() && segments.size() > 1) {
    auto open = [&](InputStream* in) { return in->open(file); };
    auto work = [&](PsqDecoder& d, size_t) { return d.pump(discard); };
    s = decode_segments(open, threads, work, &parallel_stats);
    if (!s.ok()) return report_error(file, s);
    parallel = true;
    if (parallel && !quiet && !json) std::fprintf(stderr, "%s: verified %zu segments\n", file.c_str(), segments.size());
  }
  if (!parallel) {
    Progress progress(mesh.stream.get(), !quiet);
    ProgressSequenceSink sink(&discard, &progress);
    s = mesh.decoder->pump(sink);
    if (!s.ok()) return report_error(file, s);
    progress.finish(file, "verified", std::to_string(mesh.decoder->stats().triangles) + " triangles");
  }
  const PsqStats& st = parallel ? parallel_stats : mesh.decoder->stats();
  if (json) {
    const PsqHeader& h = mesh.decoder->header();
    std::printf("{\"file\": \"%s\", \"ok\": true, \"version\": \"%d.%d\", \"profile\": \"%s\", "
                "\"vertices\": %llu, \"triangles\": %llu, \"chunks\": %llu, \"bytes\": %llu, "
                "\"max_boundary_vertices\": %u}\n",
                json_escape(file).c_str(), h.version_major, h.version_minor, h.fast ? "fast" : "compact",
                static_cast<unsigned long long>(st.vertices), static_cast<unsigned long long>(st.triangles),
                static_cast<unsigned long long>(st.chunks), static_cast<unsigned long long>(st.total_bytes),
                st.max_active_vertices);
  } else if (!quiet) {
    std::printf("%s: ok: %llu vertices, %llu triangles, %llu chunks, %llu bytes, boundary at most %u vertices\n",
                file.c_str(), static_cast<unsigned long long>(st.vertices), static_cast<unsigned long long>(st.triangles),
                static_cast<unsigned long long>(st.chunks), static_cast<unsigned long long>(st.total_bytes),
                st.max_active_vertices);
  }
  return kExitOk;
}

}  // namespace psq::cli
