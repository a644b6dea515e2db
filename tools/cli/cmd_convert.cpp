// psq convert: stream a mesh from one format to another.
#include <unistd.h>

#include <cstdio>
#include <string>

#include "cli_util.h"
#include "commands.h"
#include "psq/mesh_formats.h"
#include "psq/obj.h"

namespace psq::cli {
namespace {

const char kHelp[] =
    "Usage: psq convert IN OUT [OPTIONS]\n"
    "\n"
    "Converts IN to OUT, streaming: one element in memory at a time (an OBJ\n"
    "with normals or texture coordinates is read in memory; see README).\n"
    "The input format is recognised by content; the output format comes\n"
    "from --to or OUT's extension (.ply, .obj). IN and OUT may be '-'.\n"
    "The output is written to a temporary file and renamed on success.\n"
    "\n"
    "Options:\n"
    "  --to FORMAT    output format: ply or obj (needed when OUT is '-')\n"
    "  --ascii        write ascii PLY instead of binary little-endian\n"
    "  --tmpdir DIR   directory for temporary spool files (default $TMPDIR)\n"
    "  -f, --force    overwrite OUT if it exists\n"
    "  -q, --quiet    print no notes\n"
    "  --json         print a JSON summary on standard output (not with OUT '-')\n"
    "  -h, --help     show this help\n";

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
  std::string to = args.option("--to");
  std::string tmpdir = args.option("--tmpdir");
  std::vector<std::string> files = args.positionals();
  if (!args.error().empty()) return usage_error("convert", args.error());
  if (files.size() != 2) return usage_error("convert", "convert takes IN and OUT");
  const std::string& in = files[0];
  const std::string& out = files[1];

  MeshFormat out_format = to.empty() ? format_from_extension(out) : format_from_name(to);
  if (out_format == MeshFormat::kUnknown) {
    if (!to.empty()) return usage_error("convert", "unknown output format '" + to + "' (ply or obj)");
    return usage_error("convert", "cannot tell the output format from '" + out + "': use --to ply|obj");
  }
  if (same_file(in, out)) return usage_error("convert", "IN and OUT are the same file");
  if (out == "-" && json) return usage_error("convert", "--json needs OUT to be a file (stdout carries the mesh)");
  if (out == "-" && ::isatty(STDOUT_FILENO) && !(out_format == MeshFormat::kObj || ascii)) {
    return usage_error("convert", "refusing to write binary data to a terminal");
  }

  OpenOptions open_options;
  open_options.spool_dir = tmpdir;
  OpenedMesh mesh;
  Status s = open_mesh(in, open_options, &mesh);
  if (!s.ok()) return report_error(in, s);

  OutputFile output;
  s = output.open(out, force);
  if (!s.ok()) return report_error(out, s);
  WriteOptions write_options;
  write_options.ascii = ascii;
  write_options.spool_dir = tmpdir;
  std::unique_ptr<MeshSink> writer = make_mesh_writer(out_format, &output, write_options);

  // Count what passes through for the summary.
  struct Counter : MeshSink {
    MeshSink* next = nullptr;
    uint64_t vertices = 0, triangles = 0;
    Status begin(const MeshSchema& sc) override { return next->begin(sc); }
    Status vertex(const double p[3], const PropertyValues& v) override {
      ++vertices;
      return next->vertex(p, v);
    }
    Status triangle(const uint32_t i[3], const PropertyValues& v) override {
      ++triangles;
      return next->triangle(i, v);
    }
    Status finish() override { return next->finish(); }
  } counter;
  counter.next = writer.get();

  s = pump(*mesh.source, counter);
  // Errors of the sink are about OUT unless they carry an input place.
  if (!s.ok()) {
    output.discard();
    return report_pipeline_error(in, out, s);
  }
  s = output.commit();
  if (!s.ok()) return report_error(out, s);

  std::vector<std::string> notes = mesh.source->report().notes;
  if (out_format == MeshFormat::kObj) {
    for (const std::string& d : static_cast<ObjWriter*>(writer.get())->dropped()) {
      notes.push_back("property '" + d + "' dropped: OBJ cannot hold it");
    }
  }
  if (!quiet) {
    for (const std::string& n : notes) note(in, n);
  }
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
