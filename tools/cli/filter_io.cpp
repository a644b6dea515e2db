// SPDX-License-Identifier: Apache-2.0
// Plumbing of the sequence-filter commands; see filter_io.h.
#include "filter_io.h"

#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <thread>

#include "run_progress.h"

namespace psq::cli {

const char kFilterOptionsHelp[] =
    "  --to FORMAT    output format: psq, ply, obj or drc (needed when OUT is '-';\n"
    "                 else from OUT's extension)\n"
    "  --bits N       .psq: quantize positions to N bits, 1..31 (default: the\n"
    "                 input's, for a quantized .psq; else 16); normals and\n"
    "                 texture coordinates keep a .psq input's quantization,\n"
    "                 else psq convert's (10 and 12 bits)\n"
    "  --lossless     .psq: keep positions bit-exact (the default for a\n"
    "                 lossless .psq input)\n"
    "  --profile P    .psq: compact, fast or auto (the input's profile for a\n"
    "                 .psq input, else compact)\n"
    "  --memory SIZE  memory budget of the whole run (default 64M)\n"
    "  --tmpdir DIR   directory for temporary files (default $TMPDIR)\n"
    "  --threads N    .psq output: 1 runs on one thread; 2 (the default on two\n"
    "                 or more cores) encodes on a second thread (the output is\n"
    "                 the same)\n"
    "  -f, --force    overwrite OUT if it exists\n"
    "  -q, --quiet    print no notes, no progress line and no summary\n"
    "  --json         print a JSON summary on standard output (not with OUT '-')\n"
    "  -h, --help     show this help\n";

std::string parse_filter_options(Args& args, FilterOptions* o) {
  o->force = args.flag("--force", "-f");
  o->quiet = args.flag("--quiet", "-q");
  o->json = args.flag("--json");
  o->lossless = args.flag("--lossless");
  o->to = args.option("--to");
  o->bits = args.option("--bits");
  o->profile = args.option("--profile", "auto");
  o->tmpdir = args.option("--tmpdir");
  std::string threads = args.option("--threads", std::thread::hardware_concurrency() >= 2 ? "2" : "1");
  if (threads != "1" && threads != "2") return "bad --threads '" + threads + "' (1 or 2)";
  o->threads = threads == "2" ? 2 : 1;
  std::string memory = args.option("--memory", "64M");
  if (!parse_size(memory, &o->memory)) return "bad --memory '" + memory + "' (e.g. 64M, 1G)";
  if (o->memory < (uint64_t{8} << 20)) return "--memory must be at least 8M";
  if (o->profile != "compact" && o->profile != "fast" && o->profile != "auto")
    return "bad --profile '" + o->profile + "' (compact, fast or auto)";
  if (!o->bits.empty() && o->lossless) return "--bits and --lossless exclude each other";
  return "";
}

FilterRun::~FilterRun() {
  chain_.stop();  // joins the encoder's thread before its sink goes
}

int64_t FilterRun::declared_triangles() const {
  const MeshSchema& s = mesh_.decoder ? mesh_.decoder->schema() : mesh_.source->schema();
  return s.triangle_count;
}

std::vector<std::string> FilterRun::input_notes() const {
  return detail::input_notes(mesh_, build_report_);
}

uint64_t FilterRun::bytes_in() const { return mesh_.stream ? mesh_.stream->offset() : 0; }

int FilterRun::open(const std::string& command, const FilterOptions& o) {
  o_ = o;
  const std::string& in = o.in;
  const std::string& out = o.out;
  out_format_ = detail::output_format(o.to, out);
  if (out_format_ == MeshFormat::kUnknown) {
    if (!o.to.empty()) return usage_error(command, "unknown output format '" + o.to + "' (psq, ply, obj or drc)");
    return usage_error(command, "cannot tell the output format from '" + out + "': use --to psq|ply|obj|drc");
  }
  if (same_file(in, out)) return usage_error(command, "IN and OUT are the same file");
  if (out == "-" && o.json) return usage_error(command, "--json needs OUT to be a file (stdout carries the mesh)");
  if (out == "-" && ::isatty(STDOUT_FILENO) && out_format_ != MeshFormat::kObj)
    return usage_error(command, "refusing to write binary data to a terminal");
  int bits = 0;  // not given
  if (!o.bits.empty()) {
    char* end = nullptr;
    long b = std::strtol(o.bits.c_str(), &end, 10);
    if (*end != 0 || b < 1 || b > 31) return usage_error(command, "bad --bits '" + o.bits + "' (1..31)");
    bits = static_cast<int>(b);
  }

  OpenOptions open_options;
  open_options.spool_dir = o.tmpdir;
  open_options.memory_budget = o.memory;
  Status s = open_mesh(in, open_options, &mesh_);
  if (!s.ok()) return report_error(in, s);
  input_format_ = format_name(mesh_.format);
  output_format_ = format_name(out_format_);

  // A .psq input keeps its quantization unless told otherwise; a lossless
  // one has no bounding box to quantize on (the grid needs it before the
  // first vertex), so its output stays lossless.
  if (!detail::filter_encoding(mesh_, bits, o.lossless, o.profile, true, &encode_))
    return usage_error(command, "--bits: the input is a lossless .psq, which gives no bounding box to quantize "
                                "on; use --lossless");
  detail::filter_segments(mesh_, o.output_triangles, o.output_share, &encode_);
  build_.tmpdir = o.tmpdir;
  build_.memory_budget = o.memory / 2;
  filter_budget_ = detail::sequence_filter_budget(o.memory, static_cast<bool>(mesh_.decoder));

  s = output_.open(out, o.force);
  if (!s.ok()) return report_error(out, s);
  progress_ = std::make_unique<Progress>(mesh_.stream.get(), !o.quiet);
  WriteOptions w;
  w.spool_dir = o.tmpdir;
  w.memory_budget = o.memory;
  chain_.open(&output_, out_format_, encode_, w);
  // A .psq is encoded on a thread of its own with --threads 2.
  SequenceSink* chain = chain_.sequence_sink(out_format_ == MeshFormat::kPsq && o.threads >= 2);
  sink_ = std::make_unique<ProgressSequenceSink>(chain, progress_.get());
  return -1;
}

int FilterRun::count_psq_triangles(uint64_t* count) {
  if (o_.in == "-") return -2;
  OpenedMesh again;
  OpenOptions open_options;
  open_options.spool_dir = o_.tmpdir;
  Status s = open_mesh(o_.in, open_options, &again);
  if (s.ok() && !again.decoder) s = Status(ErrorCode::kUnknownFormat, "not a .psq any more");
  detail::SequenceBox counter;
  if (s.ok()) s = again.decoder->pump(counter);
  if (!s.ok()) return report_error(o_.in, s);
  *count = counter.triangles;
  return -1;
}

Status FilterRun::run(SequenceSink* filter, std::function<void(uint64_t)> at_begin) {
  // (Decoding a .psq on a thread of its own does not pay: handing every
  // event over costs about what decoding it does; bench/RESULTS.md.)
  RunProgress observer(progress_.get());
  return detail::feed_sequence(mesh_, *filter, build_, &build_report_, &observer, at_begin);
}

int FilterRun::finish(const Status& run_status, const std::string& summary, const std::vector<std::string>& notes) {
  if (!run_status.ok()) {
    chain_.stop();
    output_.discard();
    return report_pipeline_error(o_.in, o_.out, run_status);
  }
  Status s = output_.commit();
  if (!s.ok()) return report_error(o_.out, s);
  if (!o_.quiet)
    for (const std::string& n : notes) note(o_.in, n);
  progress_->finish(o_.in, o_.out, summary);
  return kExitOk;
}

}  // namespace psq::cli
