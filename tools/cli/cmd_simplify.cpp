// SPDX-License-Identifier: Apache-2.0
// psq simplify: out-of-core simplification, processing sequence in,
// processing sequence (or any mesh format) out (paper sections 3 and 5).
#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "cli_util.h"
#include "clustering_run.h"
#include "commands.h"
#include "filter_output.h"
#include "progress.h"
#include "run_progress.h"
#include "psq/clustering.h"
#include "psq/mesh_formats.h"
#include "psq/mesh_stream.h"
#include "psq/psq_codec.h"
#include "psq/sequence_builder.h"
#include "psq/threaded_sink.h"

namespace psq::cli {
namespace {

const char kHelp[] =
    "Usage: psq simplify IN OUT [OPTIONS]\n"
    "\n"
    "Simplifies IN into OUT out of core: the mesh streams through memory as a\n"
    "processing sequence (a .psq through its decoder, any other mesh through\n"
    "the sequence builder, within --memory) and the simplified mesh streams\n"
    "out, to .psq through the processing-sequence converter, or to PLY, OBJ or\n"
    "Draco. Memory depends on the processing boundary, not on the mesh (except\n"
    "--cells global, and Draco output, which is in-core). IN and OUT may be\n"
    "'-'. The output is written to a temporary file and renamed on success.\n"
    "\n"
    "Methods (--method):\n"
    "  clustering     vertex clustering on a uniform grid (Lindstrom's OoCS with\n"
    "                 the processing-sequence extensions of Isenburg et al. 2003):\n"
    "                 each cluster of a cell becomes the vertex minimizing its\n"
    "                 quadric (plane quadrics, border quadrics along the mesh's\n"
    "                 borders), clamped to the cell; triangles whose corners fall\n"
    "                 into three cells remain\n"
    "  qem            quadric edge collapse in a fixed triangle buffer between\n"
    "                 the input and the output boundary (Wu and Kobbelt's\n"
    "                 stream decimation, paper section 6): adaptive, slower;\n"
    "                 its options: psq simplify --method qem --help\n"
    "\n"
    "Options:\n"
    "  --method M          clustering (the default) or qem\n"
    "  --cells MODE        clustering: what a cluster is:\n"
    "                        connected (default): a connected part of a cell's\n"
    "                          vertices (layers through a cell stay apart)\n"
    "                        active: a cell while the processing boundary is in it\n"
    "                        global: a cell for the whole run (the original OoCS;\n"
    "                          memory grows with the output)\n"
    "  --grid N            N cells along the longest side of the bounding box\n"
    "                      (default 256; a fraction makes cells of the longest\n"
    "                      side / N)\n"
    "  --cell SIZE         cells of edge SIZE instead\n"
    "  --triangles N       aim at N output triangles: a trial pass picks the grid\n"
    "                      (two passes over IN; a pipe is spooled to --tmpdir); the\n"
    "                      count reached is reported\n"
    "  --ratio P           aim at this fraction of the input's triangles (0.1 or\n"
    "                      10%), as --triangles\n"
    "  --border-weight W   weight of the border quadrics (default 1; 0: none)\n"
    "  --merge NAME=RULE[,NAME=RULE...]\n"
    "                      what a property becomes when vertices (or duplicate\n"
    "                      triangles) merge: average, first or drop. Defaults:\n"
    "                      normals averaged and renormalized, colours and\n"
    "                      texture coordinates averaged, other scalars the\n"
    "                      first vertex's, lists dropped\n"
    "  --memory SIZE       memory budget (default 256M): half for the sequence\n"
    "                      builder (non-.psq input), a quarter for the filter,\n"
    "                      a 64th for the output converter's lookahead\n"
    "  --to FORMAT         output format: psq, ply, obj or drc (needed when OUT\n"
    "                      is '-'; else from OUT's extension)\n"
    "  --bits N            quantize positions to N bits: .psq 1..31, .drc 1..30\n"
    "                      (default: a quantized .psq input's bits, else 16);\n"
    "                      .psq output uses the input's bounding box; its\n"
    "                      normals and texture coordinates keep a .psq\n"
    "                      input's quantization, else psq convert's (10, 12)\n"
    "  --lossless          .psq, .drc: keep the output positions bit-exact\n"
    "  --profile P         .psq: compact, fast or auto (default: fast when the\n"
    "                      input is a fast .psq or declares 131072 triangles or\n"
    "                      more)\n"
    "  --ascii             write ascii PLY instead of binary little-endian\n"
    "  --tmpdir DIR        directory for temporary files (default $TMPDIR)\n"
    "  --threads N         1 runs on one thread; 2 (the default on two or more\n"
    "                      cores) writes the output (the converter and encoder,\n"
    "                      or the writer) on a second; 3 also reads the input\n"
    "                      on a third, which pays only when both cores are free\n"
    "                      (it hands every input event over); the output is\n"
    "                      the same\n"
    "  -f, --force         overwrite OUT if it exists\n"
    "  -q, --quiet         print no notes, no progress line and no summary\n"
    "  --json              print a JSON summary on standard output (not with OUT\n"
    "                      '-'): counts in and out, the output's non-manifold\n"
    "                      vertices and edges, the filter's peak memory, time\n"
    "  -h, --help          show this help\n";

// The input, opened once per pass. Standard input that must be read more
// than once (a trial pass, or a lossless .psq whose bounding box takes a
// pass of its own) is spooled to an unlinked temporary file first.
class Input {
 public:
  ~Input() {
    if (spool_fd_ >= 0) ::close(spool_fd_);
  }
  // `passes`: the caller knows it reads the input more than once.
  Status prepare(const std::string& path, bool passes, const std::string& tmpdir) {
    path_ = path;
    if (path != "-") return Status();
    pending_ = std::make_unique<InputStream>();
    PSQ_RETURN_IF_ERROR(pending_->open(path));
    size_t avail = 0;
    PSQ_RETURN_IF_ERROR(pending_->fill(4096, &avail));
    // A lossless .psq (header flags, spec 4.2: bit 0 of the u16 at offset
    // 10) has no bounding box: the grid needs a pass to measure it.
    const uint8_t* p = pending_->cursor();
    if (avail >= 12 && is_psq(p, avail) && (p[10] & 1)) passes = true;
    if (!passes) return Status();
    PSQ_RETURN_IF_ERROR(detail::create_unlinked_temp(tmpdir, "psq-simplify", &spool_fd_));
    for (;;) {
      PSQ_RETURN_IF_ERROR(pending_->fill(1 << 20, &avail));
      if (avail == 0) break;
      PSQ_RETURN_IF_ERROR(detail::write_all(spool_fd_, pending_->cursor(), avail, "temporary file"));
      pending_->advance(avail);
    }
    pending_.reset();
    return Status();
  }
  Status open(const OpenOptions& options, OpenedMesh* mesh) {
    if (spool_fd_ >= 0) {
      if (::lseek(spool_fd_, 0, SEEK_SET) != 0) return Status(ErrorCode::kIo, "cannot rewind the spooled input");
      const int fd = ::dup(spool_fd_);
      if (fd < 0) return Status(ErrorCode::kIo, "cannot reopen the spooled input");
      auto stream = std::make_unique<InputStream>();
      Status s = stream->open_fd(fd, true, "-");
      if (!s.ok()) {
        ::close(fd);
        return s;
      }
      return open_mesh(std::move(stream), options, mesh);
    }
    if (pending_) return open_mesh(std::move(pending_), options, mesh);
    return open_mesh(path_, options, mesh);
  }

 private:
  std::string path_;
  std::unique_ptr<InputStream> pending_;  // standard input for its one pass
  int spool_fd_ = -1;
};

// The processing sequence of the input into `filter`: a .psq through its
// decoder, any other mesh through the sequence builder. With three threads
// the filter and everything behind it run on a thread of their own.
Status feed(OpenedMesh& mesh, SequenceSink& filter, const BuildOptions& build, Progress& progress, int threads,
            BuildReport* report) {
  std::unique_ptr<ThreadedSequenceSink> threaded;
  SequenceSink* next = &filter;
  if (threads > 2) {
    threaded = std::make_unique<ThreadedSequenceSink>(&filter);
    next = threaded.get();
  }
  RunProgress observer(&progress);
  return detail::feed_sequence(mesh, *next, build, report, &observer);
}

// --merge NAME=RULE[,NAME=RULE...]: the rule of the vertex and face
// properties called NAME, over the defaults (psq/property_merge.h).
bool parse_merge_rules(const std::string& text, const MeshSchema& schema, MergePolicy* policy, std::string* error) {
  *policy = default_merge_policy(schema);
  size_t at = 0;
  while (at <= text.size()) {
    const size_t end = std::min(text.find(',', at), text.size());
    const std::string item = text.substr(at, end - at);
    const size_t eq = item.find('=');
    const std::string name = item.substr(0, eq);
    const std::string rule_text = eq == std::string::npos ? "" : item.substr(eq + 1);
    MergeRule rule;
    if (rule_text == "average") {
      rule = MergeRule::kAverage;
    } else if (rule_text == "first") {
      rule = MergeRule::kFirst;
    } else if (rule_text == "drop") {
      rule = MergeRule::kDrop;
    } else {
      *error = "bad --merge '" + item + "' (NAME=average, NAME=first or NAME=drop)";
      return false;
    }
    bool found = false;
    for (size_t i = 0; i < schema.vertex_properties.size(); ++i)
      if (schema.vertex_properties[i].name == name) policy->vertex[i] = rule, found = true;
    for (size_t i = 0; i < schema.face_properties.size(); ++i)
      if (schema.face_properties[i].name == name) policy->face[i] = rule, found = true;
    if (!found) {
      *error = "--merge: the input has no property '" + name + "'";
      return false;
    }
    at = end + 1;
  }
  return true;
}

bool parse_uint(const std::string& text, uint64_t max, uint64_t* v) {
  if (text.empty()) return false;
  char* end = nullptr;
  errno = 0;
  const unsigned long long x = std::strtoull(text.c_str(), &end, 10);
  if (*end != 0 || errno != 0 || text[0] == '-' || x > max) return false;
  *v = x;
  return true;
}

bool parse_double(const std::string& text, double* v) {
  if (text.empty()) return false;
  char* end = nullptr;
  const double x = std::strtod(text.c_str(), &end);
  if (*end != 0 || !std::isfinite(x)) return false;
  *v = x;
  return true;
}

}  // namespace

int cmd_simplify(int argc, char** argv) {
  // --method qem has options of its own (cmd_qem.cpp).
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--") break;
    if (a == "--method=qem" || (a == "--method" && i + 1 < argc && std::string(argv[i + 1]) == "qem"))
      return cmd_simplify_qem(argc, argv);
  }
  const auto start = std::chrono::steady_clock::now();
  Args args(argc, argv, 1);
  if (args.flag("--help", "-h")) {
    std::fputs(kHelp, stdout);
    return kExitOk;
  }
  const bool force = args.flag("--force", "-f");
  const bool quiet = args.flag("--quiet", "-q");
  const bool json = args.flag("--json");
  const bool ascii = args.flag("--ascii");
  const bool lossless = args.flag("--lossless");
  const std::string method = args.option("--method", "clustering");
  const std::string cells_text = args.option("--cells", "connected");
  const std::string grid_text = args.option("--grid");
  const std::string cell_text = args.option("--cell");
  const std::string target_text = args.option("--triangles");
  const std::string ratio_text = args.option("--ratio");
  const std::string border_text = args.option("--border-weight", "1");
  const std::string memory = args.option("--memory", "256M");
  const std::string to = args.option("--to");
  const std::string bits_text = args.option("--bits");
  const std::string profile = args.option("--profile", "auto");
  const std::string tmpdir = args.option("--tmpdir");
  const std::string merge_text = args.option("--merge");
  const std::string threads_text = args.option("--threads", std::thread::hardware_concurrency() >= 2 ? "2" : "1");
  const std::vector<std::string> files = args.positionals();
  if (!args.error().empty()) return usage_error("simplify", args.error());
  if (files.size() != 2) return usage_error("simplify", "simplify takes IN and OUT");
  const std::string& in = files[0];
  const std::string& out = files[1];

  if (method != "clustering") return usage_error("simplify", "unknown --method '" + method + "' (clustering or qem)");
  ClusteringOptions options;
  if (!parse_cell_mode(cells_text, &options.cells))
    return usage_error("simplify", "bad --cells '" + cells_text + "' (connected, active or global)");
  if (!grid_text.empty() + !cell_text.empty() + !target_text.empty() + !ratio_text.empty() > 1)
    return usage_error("simplify", "give one of --grid, --cell, --triangles and --ratio");
  uint64_t target = 0;
  double ratio = 0;
  if (!grid_text.empty()) {
    if (!parse_double(grid_text, &options.grid) || !(options.grid >= 1) || !(options.grid < ClusterGrid::kMaxDim))
      return usage_error("simplify", "bad --grid '" + grid_text + "' (1 to " + std::to_string(ClusterGrid::kMaxDim - 1) + ")");
  } else if (!cell_text.empty()) {
    if (!parse_double(cell_text, &options.cell_size) || !(options.cell_size > 0))
      return usage_error("simplify", "bad --cell '" + cell_text + "' (a positive number)");
    options.grid = 0;
  } else if (!target_text.empty()) {
    if (!parse_uint(target_text, uint64_t{1} << 40, &target) || target < 1)
      return usage_error("simplify", "bad --triangles '" + target_text + "' (a positive count)");
    options.grid = first_grid_for_triangles(target);
  } else if (!ratio_text.empty()) {
    if (!parse_ratio(ratio_text, &ratio))
      return usage_error("simplify", "bad --ratio '" + ratio_text + "' (a fraction in (0, 1] or a percentage)");
  }
  if (!parse_double(border_text, &options.border_weight) || options.border_weight < 0)
    return usage_error("simplify", "bad --border-weight '" + border_text + "' (a number >= 0)");
  uint64_t memory_bytes = 0;
  if (!parse_size(memory, &memory_bytes)) return usage_error("simplify", "bad --memory '" + memory + "' (e.g. 256M, 2G)");
  if (threads_text != "1" && threads_text != "2" && threads_text != "3")
    return usage_error("simplify", "bad --threads '" + threads_text + "' (1, 2 or 3)");
  const int threads = threads_text[0] - '0';
  if (profile != "compact" && profile != "fast" && profile != "auto")
    return usage_error("simplify", "bad --profile '" + profile + "' (compact, fast or auto)");
  uint64_t bits = 0;
  if (!bits_text.empty() && (!parse_uint(bits_text, 31, &bits) || bits < 1))
    return usage_error("simplify", "bad --bits '" + bits_text + "' (1..31)");

  const MeshFormat out_format = detail::output_format(to, out);
  if (out_format == MeshFormat::kUnknown) {
    if (!to.empty()) return usage_error("simplify", "unknown output format '" + to + "' (psq, ply, obj or drc)");
    return usage_error("simplify", "cannot tell the output format from '" + out + "': use --to psq|ply|obj|drc");
  }
  if (out_format == MeshFormat::kDraco && !lossless && bits > 30)
    return usage_error("simplify", "bad --bits " + bits_text + " for Draco (1..30)");
  if (same_file(in, out)) return usage_error("simplify", "IN and OUT are the same file");
  if (out == "-" && json) return usage_error("simplify", "--json needs OUT to be a file (stdout carries the mesh)");
  if (out == "-" && ::isatty(STDOUT_FILENO) && !(out_format == MeshFormat::kObj || ascii))
    return usage_error("simplify", "refusing to write binary data to a terminal");

  // One budget, split here among the stages (psq/memory_budget.h).
  const detail::ClusteringBudget budget = detail::split_clustering_budget(memory_bytes);
  BuildOptions build;
  build.tmpdir = tmpdir;
  build.memory_budget = budget.build;
  options.memory_budget = budget.filter;
  OpenOptions open_options;
  open_options.spool_dir = tmpdir;
  open_options.memory_budget = build.memory_budget;

  Input input;
  Status s = input.prepare(in, target > 0 || ratio > 0, tmpdir);
  if (!s.ok()) return report_error(in, s);
  OutputFile output;
  s = output.open(out, force);
  if (!s.ok()) return report_error(out, s);

  std::vector<std::string> notes;
  int passes = 0;
  OpenedMesh mesh;
  s = input.open(open_options, &mesh);
  if (!s.ok()) return report_error(in, s);
  if (!merge_text.empty()) {
    const MeshSchema& schema = mesh.decoder ? mesh.decoder->schema() : mesh.source->schema();
    std::string error;
    if (!parse_merge_rules(merge_text, schema, &options.merge, &error)) return usage_error("simplify", error);
  }
  // A lossless .psq declares no bounding box: a first pass measures it.
  if (mesh.decoder && !mesh.decoder->schema().has_bounds) {
    ++passes;
    s = detail::measure_bounds(*mesh.decoder, &options);
    if (!s.ok()) return report_error(in, s);
    mesh = OpenedMesh();
    s = input.open(open_options, &mesh);
    if (!s.ok()) return report_error(in, s);
  }
  // --ratio: the target follows from the input's triangle count, declared
  // by its header or else counted by the first trial pass.
  if (ratio > 0) {
    const MeshSchema& schema = mesh.decoder ? mesh.decoder->schema() : mesh.source->schema();
    target = detail::ratio_target(ratio, schema.triangle_count);
    if (target > 0) options.grid = first_grid_for_triangles(target);
  }
  // --triangles: trial passes count the output of a grid.
  if (target > 0 || ratio > 0) {
    bool reopening = false;  // an error of opening IN again, not of a pass
    s = detail::search_grid(&target, ratio, &options, [&](const ClusteringOptions& trial, uint64_t* tin, uint64_t* tout) {
      CountingMeshSink count;
      ClusteringFilter filter(&count, trial);
      Progress none(nullptr, false);
      BuildReport report;
      ++passes;
      PSQ_RETURN_IF_ERROR(feed(mesh, filter, build, none, threads, &report));
      *tin = filter.stats().triangles_in;
      *tout = count.triangles;
      mesh = OpenedMesh();
      reopening = true;
      PSQ_RETURN_IF_ERROR(input.open(open_options, &mesh));
      reopening = false;
      return Status();
    });
    if (!s.ok()) return reopening ? report_error(in, s) : report_pipeline_error(in, out, s);
  }

  // The output.
  EncodeOptions encode_options;
  detail::filter_encoding(mesh, static_cast<int>(bits), lossless, profile, false, &encode_options);
  // A target (--triangles, --ratio) tells the output's size; a grid alone does not.
  detail::filter_segments(mesh, target, 0, &encode_options);
  if (out_format == MeshFormat::kDraco && !lossless && encode_options.bits > 30)
    return usage_error("simplify", "the input's " + std::to_string(encode_options.bits) +
                                       " bits are too many for Draco: give --bits (1..30)");
  WriteOptions write_options;
  write_options.ascii = ascii;
  write_options.spool_dir = tmpdir;
  write_options.memory_budget = budget.writer;
  detail::FilterOutput chain;
  chain.open(&output, out_format, encode_options, write_options);
  // With --json the output's non-manifold vertices and edges are counted.
  // With two threads or more, the output side runs on a thread of its own.
  StreamingMeshSink* sink = chain.mesh_sink(budget.lookahead, json, threads > 1);
  ClusteringFilter filter(sink, options);
  Progress progress(mesh.stream.get(), !quiet);
  BuildReport report;
  ++passes;
  s = feed(mesh, filter, build, progress, threads, &report);
  if (!s.ok()) {
    chain.stop();  // stops the output's thread before the output goes
    output.discard();
    return report_pipeline_error(in, out, s);
  }
  s = output.commit();
  if (!s.ok()) return report_error(out, s);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

  const ClusteringStats& st = filter.stats();
  for (const std::string& n : mesh.source->report().notes) notes.push_back(n);
  for (const std::string& n : detail::clustering_notes(mesh.source->schema(), st, chain.notes())) notes.push_back(n);
  if (target > 0)
    notes.push_back((ratio > 0 ? "--ratio " + ratio_text + " (" + std::to_string(target) + " triangles)"
                               : "--triangles " + std::to_string(target)) +
                    ": " + json_number(options.grid) +
                    " cells along the longest side, " + std::to_string(st.triangles_out) + " triangles");
  if (!quiet)
    for (const std::string& n : notes) note(in, n);
  {
    char summary[256];
    std::snprintf(summary, sizeof summary, "%llu -> %llu triangles, %llu vertices, grid %u x %u x %u (%s cells)",
                  static_cast<unsigned long long>(st.triangles_in), static_cast<unsigned long long>(st.triangles_out),
                  static_cast<unsigned long long>(st.vertices_out), st.grid.dims[0], st.grid.dims[1], st.grid.dims[2],
                  cell_mode_name(options.cells));
    progress.finish(in, out, summary);
  }
  if (json) {
    const ConverterStats* cs = chain.converter_stats();
    auto num = [](uint64_t v) { return std::to_string(v); };
    std::string o = "{\"input\": \"" + json_escape(in) + "\", \"output\": \"" + json_escape(out) +
                    "\", \"input_format\": \"" + format_name(mesh.format) + "\", \"output_format\": \"" +
                    format_name(out_format) + "\", \"method\": \"clustering\", \"cells\": \"" +
                    cell_mode_name(options.cells) + "\", \"grid_longest\": " +
                    (options.grid > 0 ? json_number(options.grid) : std::string("null")) + ", \"grid\": [" + num(st.grid.dims[0]) + ", " +
                    num(st.grid.dims[1]) + ", " + num(st.grid.dims[2]) + "], \"cell_size\": " +
                    json_number(st.grid.cell) + ", \"border_weight\": " + json_number(options.border_weight) +
                    ", \"target_triangles\": " + (target ? num(target) : std::string("null")) +
                    ", \"passes\": " + std::to_string(passes) + ", \"vertices_in\": " + num(st.vertices_in) +
                    ", \"triangles_in\": " + num(st.triangles_in) + ", \"vertices\": " + num(st.vertices_out) +
                    ", \"triangles\": " + num(st.triangles_out) +
                    ", \"nonmanifold_vertices\": " + num(cs ? cs->nonmanifold_vertices : 0) +
                    ", \"nonmanifold_edges\": " + num(cs ? cs->nonmanifold_edges : 0) +
                    ", \"misoriented_edges\": " + num(cs ? cs->misoriented_edges : 0) +
                    ", \"border_edges\": " + num(cs ? cs->border_edges : 0) + ", \"clusters\": " + num(st.clusters) +
                    ", \"duplicates\": " + num(st.duplicates) + ", \"max_clusters\": " + num(st.max_clusters) +
                    ", \"max_waiting_triangles\": " + num(st.max_waiting) +
                    ", \"converter_max_waiting_triangles\": " + num(cs ? cs->max_waiting_triangles : 0) +
                    ", \"filter_peak_bytes\": " + num(st.peak_bytes) + ", \"bytes_in\": " + num(mesh.stream->offset()) +
                    ", \"bytes_out\": " + num(output.size()) + ", \"seconds\": " + json_number(seconds) +
                    ", \"triangles_per_second\": " +
                    json_number(seconds > 0 ? static_cast<double>(st.triangles_in) / seconds : 0.0) +
                    ", \"threads\": " + std::to_string(threads);
    if (out_format == MeshFormat::kPsq)
      o += detail::json_encoding(encode_options);
    o += ", \"notes\": " + detail::json_strings(notes) + "}\n";
    std::fputs(o.c_str(), stdout);
  }
  return kExitOk;
}

}  // namespace psq::cli
