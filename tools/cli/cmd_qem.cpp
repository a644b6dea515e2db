// SPDX-License-Identifier: Apache-2.0
// psq simplify --method qem: stream edge-collapse simplification
// (psq/stream_qem.h). cmd_simplify hands its arguments here.
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "commands.h"
#include "filter_io.h"
#include "psq/stream_qem.h"

namespace psq::cli {
namespace {

const char kHelp[] =
    "Usage: psq simplify IN OUT --method qem [OPTIONS]\n"
    "\n"
    "Simplifies IN by quadric edge collapse in a fixed triangle buffer between\n"
    "the input and the output boundary of its processing sequence (Wu and\n"
    "Kobbelt's stream decimation, paper section 6), and writes OUT on the fly:\n"
    "memory is the buffer, never the mesh. IN is any mesh psq reads ('-' for\n"
    "standard input); a .psq streams through its decoder, other meshes through\n"
    "the sequence builder. OUT is .psq, .ply, .obj or .drc ('-' with --to).\n"
    "Give at least one target; simplification stops at the first reached.\n"
    "Components, handles and borders are kept, unless a count target cannot\n"
    "be met otherwise: then small components that no collapse can reduce\n"
    "further go whole, and handles three edges around are cut (reported).\n"
    "Texture coordinates and normals given per corner (an OBJ's vt and vn)\n"
    "follow their charts, and their seams are kept as borders are.\n"
    "The same input and options give the same output.\n"
    "\n"
    "Options:\n"
    "  --ratio P       keep this fraction of the triangles (0.1 or 10%)\n"
    "  --triangles N   keep N triangles (suffixes k, M: powers of 1000); needs\n"
    "                  the input's count, counted by decoding a .psq input\n"
    "                  once more when its header has none (not from a pipe)\n"
    "  --max-error E   collapse only while the error stays at most E times the\n"
    "                  diagonal of the input's bounding box\n"
    "  --buffer N      triangles in the buffer (default: what --memory allows)\n"
    "  --candidates C  random edges compared for each collapse, 1..64 (default 8)\n"
    "  --lock-border   keep every border vertex where it is\n"
    "  --seed S        seed of the random choices (default 1)\n";

// A count with an optional k, M or G suffix (powers of 1000).
bool parse_count(const std::string& text, uint64_t* n) {
  if (text.empty()) return false;
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  double mult = 1;
  std::string suffix = end;
  if (suffix == "k" || suffix == "K") mult = 1e3;
  else if (suffix == "M") mult = 1e6;
  else if (suffix == "G") mult = 1e9;
  else if (!suffix.empty()) return false;
  const double r = v * mult;
  if (!(r >= 1) || r > 1e15 || r != std::floor(r)) return false;
  *n = static_cast<uint64_t>(r);
  return true;
}

}  // namespace

int cmd_simplify_qem(int argc, char** argv) {
  Args args(argc, argv, 1);
  if (args.flag("--help", "-h")) {
    std::fputs(kHelp, stdout);
    std::fputs(kFilterOptionsHelp, stdout);
    return kExitOk;
  }
  args.option("--method");  // "qem": cmd_simplify chose this method by it
  FilterOptions fo;
  std::string error = parse_filter_options(args, &fo);
  const bool lock_border = args.flag("--lock-border");
  const std::string ratio_text = args.option("--ratio");
  const std::string triangles_text = args.option("--triangles");
  const std::string error_text = args.option("--max-error");
  const std::string buffer_text = args.option("--buffer");
  const std::string candidates_text = args.option("--candidates", "8");
  const std::string seed_text = args.option("--seed", "1");
  std::vector<std::string> files = args.positionals();
  if (!args.error().empty()) return usage_error("simplify", args.error());
  if (!error.empty()) return usage_error("simplify", error);
  if (files.size() != 2) return usage_error("simplify", "simplify takes IN and OUT");
  fo.in = files[0];
  fo.out = files[1];

  QemOptions q;
  q.lock_border = lock_border;
  if (!ratio_text.empty() && !parse_ratio(ratio_text, &q.ratio))
    return usage_error("simplify", "bad --ratio '" + ratio_text + "' (a fraction in (0, 1] or a percentage)");
  if (!triangles_text.empty() && !parse_count(triangles_text, &q.target_triangles))
    return usage_error("simplify", "bad --triangles '" + triangles_text + "' (a positive count)");
  if (!error_text.empty()) {
    char* end = nullptr;
    q.max_error = std::strtod(error_text.c_str(), &end);
    if (*end != 0 || !(q.max_error >= 0) || !std::isfinite(q.max_error))
      return usage_error("simplify", "bad --max-error '" + error_text + "' (a non-negative number)");
  }
  if (q.ratio == 0 && q.target_triangles == 0 && q.max_error < 0)
    return usage_error("simplify", "give a target: --ratio, --triangles or --max-error");
  if (!buffer_text.empty()) {
    uint64_t b = 0;
    if (!parse_count(buffer_text, &b) || b < 16 || b > (uint64_t{1} << 28))
      return usage_error("simplify", "bad --buffer '" + buffer_text + "' (16 to 268435456 triangles)");
    q.buffer_triangles = static_cast<uint32_t>(b);
  }
  {
    char* end = nullptr;
    long c = std::strtol(candidates_text.c_str(), &end, 10);
    if (candidates_text.empty() || *end != 0 || c < 1 || c > 64)
      return usage_error("simplify", "bad --candidates '" + candidates_text + "' (1..64)");
    q.candidates = static_cast<int>(c);
    end = nullptr;
    q.seed = std::strtoull(seed_text.c_str(), &end, 10);
    if (seed_text.empty() || *end != 0 || seed_text[0] == '-')
      return usage_error("simplify", "bad --seed '" + seed_text + "' (a non-negative integer)");
  }

  fo.output_triangles = q.target_triangles;
  fo.output_share = q.ratio;
  FilterRun run;
  int code = run.open("simplify", fo);
  if (code >= 0) return code;
  q.memory_budget = run.filter_budget();
  // A triangle count target needs the input's count: a .psq header may
  // not have it (then the .psq is decoded once to count); a mesh input is
  // counted as the sequence builder reads it, before the simplifier starts.
  if (q.target_triangles > 0 && run.input_is_psq() && run.declared_triangles() < 0) {
    uint64_t n = 0;
    code = run.count_psq_triangles(&n);
    if (code == -2)
      return usage_error("simplify", "--triangles: the .psq on standard input does not declare its triangle count; use "
                                "--ratio");
    if (code >= 0) return code;
    q.input_triangles = n;
  }
  StreamQem qem(run.sink(), q);
  Status s = run.run(&qem, [&](uint64_t counted) {
    if (counted > 0) qem.set_input_triangles(counted);
  });
  const QemReport& r = qem.report();
  std::vector<std::string> notes = run.input_notes();
  if (s.ok() && r.target_triangles > 0 &&
      std::fabs(static_cast<double>(r.output_triangles) - static_cast<double>(r.target_triangles)) >
          0.01 * static_cast<double>(r.target_triangles) + 2)
    notes.push_back("the target of " + std::to_string(r.target_triangles) + " triangles was not met (" +
                    std::to_string(r.output_triangles) + "): no more edges could be collapsed" +
                    (q.max_error >= 0 ? " within --max-error" : ""));
  if (r.components_dropped)
    notes.push_back(std::to_string(r.components_dropped) + " components that no collapse could reduce further (" +
                    std::to_string(r.triangles_dropped) + " triangles) dropped to come nearer the target");
  if (r.handles_cut)
    notes.push_back(std::to_string(r.handles_cut) +
                    " handles or necks that no collapse could reduce further cut to come nearer the target");
  if (r.isolated_dropped) notes.push_back(std::to_string(r.isolated_dropped) + " isolated vertices dropped");
  char summary[256];
  std::snprintf(summary, sizeof summary, "%llu -> %llu triangles, largest error %.3g of the diagonal, %llu bytes",
                static_cast<unsigned long long>(r.input_triangles), static_cast<unsigned long long>(r.output_triangles),
                r.max_error, static_cast<unsigned long long>(run.bytes_out()));
  code = run.finish(s, summary, notes);
  if (code != kExitOk || !fo.json) return code;
  std::string o = "{\"input\": \"" + json_escape(fo.in) + "\", \"output\": \"" + json_escape(fo.out) +
                  "\", \"input_format\": \"" + run.input_format() + "\", \"output_format\": \"" +
                  run.output_format() + "\", \"input_vertices\": " + std::to_string(r.input_vertices) +
                  ", \"input_triangles\": " + std::to_string(r.input_triangles) +
                  ", \"output_vertices\": " + std::to_string(r.output_vertices) +
                  ", \"output_triangles\": " + std::to_string(r.output_triangles) +
                  ", \"target_triangles\": " + std::to_string(r.target_triangles) +
                  ", \"collapses\": " + std::to_string(r.collapses) +
                  ", \"components_dropped\": " + std::to_string(r.components_dropped) +
                  ", \"triangles_dropped\": " + std::to_string(r.triangles_dropped) +
                  ", \"handles_cut\": " + std::to_string(r.handles_cut) +
                  ", \"max_error\": " + json_number(r.max_error) +
                  ", \"buffer_triangles\": " + std::to_string(r.buffer_triangles) +
                  ", \"max_buffer_triangles\": " + std::to_string(r.max_buffer_triangles) +
                  ", \"max_buffer_vertices\": " + std::to_string(r.max_buffer_vertices) +
                  ", \"max_waiting_triangles\": " + std::to_string(r.converter.max_waiting_triangles) +
                  ", \"bytes_out\": " + std::to_string(run.bytes_out()) + ", \"seconds\": " +
                  json_number(run.seconds()) + ", \"lossless\": " + (run.lossless() ? "true" : "false") +
                  ", \"bits\": " + std::to_string(run.bits()) + ", \"notes\": [";
  for (size_t i = 0; i < notes.size(); ++i) o += (i ? ", \"" : "\"") + json_escape(notes[i]) + "\"";
  o += "]}\n";
  std::fputs(o.c_str(), stdout);
  return kExitOk;
}

}  // namespace psq::cli
