// SPDX-License-Identifier: Apache-2.0
// psq dump: the processing sequence of any input as text (spec/psq-dump.md).
#include <cstdio>
#include <string>

#include "cli_util.h"
#include "progress.h"
#include "commands.h"
#include "psq/mesh_formats.h"
#include "psq/sequence_builder.h"
#include "sequence_dump.h"

namespace psq::cli {
namespace {

const char kHelp[] =
    "Usage: psq dump IN [OPTIONS]\n"
    "\n"
    "Prints the processing sequence of IN (PLY, OBJ, OFF, STL or .psq; '-'\n"
    "for standard input) as text, one event a line (format: spec/psq-dump.md):\n"
    "  v X Y Z [~K] [NAME=VALUE ...]   a new vertex (~K: re-appears vertex K)\n"
    "  t A B C OP M [NAME=VALUE ...]   a triangle, its op and border mask\n"
    "  x A                             vertex A is finalized\n"
    "A .psq prints as stored. Coherent mesh input converts in one pass;\n"
    "other input goes through an external sort within --memory.\n"
    "\n"
    "Options:\n"
    "  -o FILE        write to FILE instead of standard output\n"
    "  -f, --force    overwrite FILE if it exists\n"
    "  --memory SIZE  memory budget for the external sort (default 512M)\n"
    "  --tmpdir DIR   directory for temporary files (default $TMPDIR)\n"
    "  --sort         use the external sort even for coherent input\n"
    "  -h, --help     show this help\n";

}  // namespace

int cmd_dump(int argc, char** argv) {
  Args args(argc, argv, 1);
  if (args.flag("--help", "-h")) {
    std::fputs(kHelp, stdout);
    return kExitOk;
  }
  bool force = args.flag("--force", "-f");
  bool sort = args.flag("--sort");
  std::string out_path = args.option("-o", "-");
  std::string memory = args.option("--memory", "512M");
  std::string tmpdir = args.option("--tmpdir");
  std::vector<std::string> files = args.positionals();
  if (!args.error().empty()) return usage_error("dump", args.error());
  if (files.size() != 1) return usage_error("dump", files.empty() ? "missing IN" : "dump takes one IN");
  BuildOptions options;
  if (!parse_size(memory, &options.memory_budget)) return usage_error("dump", "bad --memory '" + memory + "' (e.g. 256M, 2G)");
  options.tmpdir = tmpdir;
  options.force_sort = sort;
  const std::string& in = files[0];
  if (same_file(in, out_path)) return usage_error("dump", "IN and -o are the same file");

  OpenOptions open_options;
  open_options.spool_dir = tmpdir;
  OpenedMesh mesh;
  Status s = open_mesh(in, open_options, &mesh);
  if (!s.ok()) return report_error(in, s);
  OutputFile out;
  s = out.open(out_path, force);
  if (!s.ok()) return report_error(out_path, s);
  DumpWriter writer(&out);
  BuildReport report;
  // A .psq holds a processing sequence already: print it as decoded.
  // Progress only when the dump goes to a file (stderr may share the
  // terminal with a dump on stdout).
  Progress progress(mesh.stream.get(), out_path != "-");
  ProgressSequenceSink sink(&writer, &progress);
  ProgressSource source(mesh.source.get(), &progress);
  if (mesh.decoder) s = mesh.decoder->pump(sink);
  else s = build_sequence(source, sink, options, &report);
  if (!s.ok()) {
    out.discard();
    return report_pipeline_error(in, out_path, s);
  }
  s = out.commit();
  if (!s.ok()) return report_error(out_path, s);
  return kExitOk;
}

}  // namespace psq::cli
