// SPDX-License-Identifier: Apache-2.0
// psq distance: Metro's surface distance between two meshes (psq/distance.h).
#include <charconv>
#include <cstdio>
#include <string>

#include "cli_util.h"
#include "commands.h"
#include "distance_report.h"

namespace psq::cli {
namespace {

const char kHelp[] =
    "Usage: psq distance A B [OPTIONS]\n"
    "\n"
    "Measures the distance between the surfaces of meshes A and B (PLY, OBJ,\n"
    "OFF, STL, .psq or Draco; one of them may be '-' for standard input) as\n"
    "Metro does (Cignoni, Rocchini, Scopigno 1998): points sampled on A (every\n"
    "vertex a triangle uses, then random points spread over the triangles by\n"
    "area) are measured to the nearest point of B's surface, and points on B\n"
    "to A's surface. Prints for each direction the number of samples, the\n"
    "largest distance (one-sided Hausdorff), the mean and the RMS; the\n"
    "symmetric row gives the larger of the two directions (its max is the\n"
    "Hausdorff distance); then all of it divided by the diagonal of A's\n"
    "bounding box. The time and speed go to standard error (and to 'timing'\n"
    "in --json); the rest is the same on every run with the same --seed,\n"
    "whatever --threads and --hold.\n"
    "\n"
    "Memory: the mesh with fewer triangles (as its header counts them) is\n"
    "HELD in memory: its triangles in a search tree (about 110 bytes each)\n"
    "and its samples in another (about 60 bytes each: 240 MB for the 4M\n"
    "samples of a mesh of 400k triangles or more). The other STREAMS: its\n"
    "positions stay in memory (12 bytes a vertex for float input, 24\n"
    "otherwise), its triangles are spooled to a temporary file (12 bytes\n"
    "each) and stream past the held mesh's samples. 50M triangles against\n"
    "1M take about 800 MB. Both meshes are held when neither has more than\n"
    "2M triangles. Streaming is exact, not an estimate: it gives the same\n"
    "numbers as holding both.\n"
    "\n"
    "Options:\n"
    "  --samples N    samples per direction, vertices included (default 10 per\n"
    "                 triangle, at most 4M, and at least every used vertex);\n"
    "                 k, M, G multiply by 10^3, 10^6, 10^9\n"
    "  --seed S       seed of the random points (default 1)\n"
    "  --threads N    threads (default: one per processor)\n"
    "  --hold A|B     hold this mesh in memory and stream the other\n"
    "  --in-memory    hold both meshes (nothing streams)\n"
    "  --tmpdir DIR   directory for the spool file (default $TMPDIR)\n"
    "  --json         print one JSON object instead of text\n"
    "  -h, --help     show this help\n";

// A count with an optional k, M or G (powers of 1000).
bool parse_count(const std::string& text, uint64_t* n) {
  uint64_t v = 0;
  const char* b = text.data();
  const char* e = b + text.size();
  auto r = std::from_chars(b, e, v);
  if (r.ec != std::errc() || r.ptr == b) return false;
  uint64_t mul = 1;
  if (r.ptr != e) {
    if (r.ptr + 1 != e) return false;
    switch (*r.ptr) {
      case 'k': case 'K': mul = 1000; break;
      case 'M': case 'm': mul = 1000000; break;
      case 'G': case 'g': mul = 1000000000; break;
      default: return false;
    }
  }
  if (v > UINT64_MAX / mul) return false;
  *n = v * mul;
  return true;
}

void text_row(const char* name, const DirectionDistance& d, double div, bool counts) {
  if (counts) std::printf("%-10s %12llu", name, static_cast<unsigned long long>(d.samples));
  else std::printf("%-10s %12s", name, "");
  std::printf("  %12.6g  %12.6g  %12.6g\n", d.max / div, d.mean / div, d.rms / div);
}

}  // namespace

int cmd_distance(int argc, char** argv) {
  Args args(argc, argv, 1);
  if (args.flag("--help", "-h")) {
    std::fputs(kHelp, stdout);
    return kExitOk;
  }
  const bool json = args.flag("--json");
  const bool in_memory = args.flag("--in-memory");
  const std::string samples_text = args.option("--samples");
  const std::string seed_text = args.option("--seed", "1");
  const std::string threads_text = args.option("--threads");
  const std::string hold_text = args.option("--hold");
  DistanceOptions options;
  options.tmpdir = args.option("--tmpdir");
  std::vector<std::string> files = args.positionals();
  if (!args.error().empty()) return usage_error("distance", args.error());
  if (files.size() != 2) return usage_error("distance", files.size() < 2 ? "distance needs A and B" : "distance takes two meshes, A and B");
  if (files[0] == "-" && files[1] == "-") return usage_error("distance", "only one of A and B can be standard input");
  if (!samples_text.empty() && (!parse_count(samples_text, &options.samples) || options.samples == 0 ||
                                options.samples > kMaxSamples)) {
    return usage_error("distance", "bad --samples '" + samples_text + "' (1 to 1G)");
  }
  if (!parse_count(seed_text, &options.seed) || seed_text.find_first_not_of("0123456789") != std::string::npos) {
    return usage_error("distance", "bad --seed '" + seed_text + "' (a number)");
  }
  if (!threads_text.empty()) {
    uint64_t t = 0;
    if (!parse_count(threads_text, &t) || t == 0 || t > 1024) {
      return usage_error("distance", "bad --threads '" + threads_text + "' (1 to 1024)");
    }
    options.threads = static_cast<int>(t);
  }
  if (!hold_text.empty() && in_memory) return usage_error("distance", "--hold and --in-memory exclude each other");
  if (hold_text == "A" || hold_text == "a") options.hold = DistanceHold::kA;
  else if (hold_text == "B" || hold_text == "b") options.hold = DistanceHold::kB;
  else if (!hold_text.empty()) return usage_error("distance", "bad --hold '" + hold_text + "' (A or B)");
  if (in_memory) options.hold = DistanceHold::kBoth;

  OpenOptions open_options;
  open_options.spool_dir = options.tmpdir;
  OpenedMesh a, b;
  Status s = open_mesh(files[0], open_options, &a);
  if (!s.ok()) return report_error(files[0], s);
  s = open_mesh(files[1], open_options, &b);
  if (!s.ok()) return report_error(files[1], s);
  // Counts the headers do not give are estimated from the file sizes.
  if (options.hold == DistanceHold::kAuto) options.hold = detail::auto_hold(a, b);

  DistanceResult r;
  s = measure_distance(*a.source, *b.source, options, &r);
  if (!s.ok()) return report_error(detail::distance_error_file(r, files[0], files[1], options.tmpdir), s);
  const detail::DistanceSummary sum = detail::summarize_distance(r, options);
  const DirectionDistance& sym = sum.symmetric;
  const double diag = sum.diagonal;
  const double rate = sum.samples_per_second;
  const int threads = sum.threads;

  if (json) {
    std::fputs(detail::distance_json(files[0], files[1], options, r).c_str(), stdout);
  } else {
    std::printf("A  %s: %llu triangles, %s\n", files[0] == "-" ? "<stdin>" : files[0].c_str(),
                static_cast<unsigned long long>(r.a.triangles), r.a.held ? "held" : "streamed");
    std::printf("B  %s: %llu triangles, %s\n", files[1] == "-" ? "<stdin>" : files[1].c_str(),
                static_cast<unsigned long long>(r.b.triangles), r.b.held ? "held" : "streamed");
    std::printf("\n%-10s %12s  %12s  %12s  %12s\n", "distance", "samples", "max", "mean", "rms");
    text_row("A -> B", r.a_to_b, 1, true);
    text_row("B -> A", r.b_to_a, 1, true);
    text_row("symmetric", sym, 1, false);
    std::printf("\n/ diagonal of A's bounding box (%.6g)\n", r.diagonal);
    text_row("A -> B", r.a_to_b, diag, false);
    text_row("B -> A", r.b_to_a, diag, false);
    text_row("symmetric", sym, diag, false);
  }
  std::fflush(stdout);
  std::fprintf(stderr, "psq: distance: %.2f s, %.3g samples/s on %d thread%s\n", r.seconds, rate, threads,
               threads == 1 ? "" : "s");
  return kExitOk;
}

}  // namespace psq::cli
