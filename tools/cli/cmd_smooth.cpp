// SPDX-License-Identifier: Apache-2.0
// psq smooth: Taubin lambda|mu smoothing, streaming (psq/taubin_smooth.h).
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "commands.h"
#include "filter_io.h"
#include "psq/taubin_smooth.h"

namespace psq::cli {
namespace {

const char kHelp[] =
    "Usage: psq smooth IN OUT [OPTIONS]\n"
    "\n"
    "Smooths IN with Taubin's lambda|mu steps (each vertex moves towards the\n"
    "average of its neighbours by lambda, then back by mu, which removes noise\n"
    "without shrinking the surface) and writes OUT on the fly. It runs in a\n"
    "fixed triangle buffer between the input and the output boundary of the\n"
    "processing sequence: any size of mesh in the same memory. Every vertex\n"
    "at least K rings from where a full buffer had to write early gets\n"
    "exactly the result of smoothing the whole mesh at once; border vertices\n"
    "stay. IN is any mesh psq reads ('-' for standard input); OUT is .psq,\n"
    ".ply, .obj or .drc ('-' with --to).\n"
    "\n"
    "Options:\n"
    "  --iterations K  smoothing steps, alternately lambda and mu, 0..255\n"
    "                  (default 10)\n"
    "  --lambda L      the smoothing factor (default 0.5)\n"
    "  --mu M          the inflating factor, negative, |M| > L (default -0.53)\n"
    "  --buffer N      triangles in the buffer (default: what --memory allows)\n";

bool parse_double(const std::string& text, double* v) {
  char* end = nullptr;
  *v = std::strtod(text.c_str(), &end);
  return !text.empty() && *end == 0 && std::isfinite(*v);
}

}  // namespace

int cmd_smooth(int argc, char** argv) {
  Args args(argc, argv, 1);
  if (args.flag("--help", "-h")) {
    std::fputs(kHelp, stdout);
    std::fputs(kFilterOptionsHelp, stdout);
    return kExitOk;
  }
  FilterOptions fo;
  std::string error = parse_filter_options(args, &fo);
  const std::string iterations_text = args.option("--iterations", "10");
  const std::string lambda_text = args.option("--lambda", "0.5");
  const std::string mu_text = args.option("--mu", "-0.53");
  const std::string buffer_text = args.option("--buffer");
  std::vector<std::string> files = args.positionals();
  if (!args.error().empty()) return usage_error("smooth", args.error());
  if (!error.empty()) return usage_error("smooth", error);
  if (files.size() != 2) return usage_error("smooth", "smooth takes IN and OUT");
  fo.in = files[0];
  fo.out = files[1];
  fo.output_share = 1;  // smoothing keeps every triangle

  SmoothOptions so;
  {
    char* end = nullptr;
    long k = std::strtol(iterations_text.c_str(), &end, 10);
    if (iterations_text.empty() || *end != 0 || k < 0 || k > 255)
      return usage_error("smooth", "bad --iterations '" + iterations_text + "' (0..255)");
    so.iterations = static_cast<int>(k);
  }
  if (!parse_double(lambda_text, &so.lambda) || !(so.lambda > 0 && so.lambda < 1))
    return usage_error("smooth", "bad --lambda '" + lambda_text + "' (between 0 and 1)");
  if (!parse_double(mu_text, &so.mu) || !(so.mu < 0 && so.mu > -1))
    return usage_error("smooth", "bad --mu '" + mu_text + "' (between -1 and 0)");
  if (!buffer_text.empty()) {
    char* end = nullptr;
    unsigned long long b = std::strtoull(buffer_text.c_str(), &end, 10);
    if (*end != 0 || buffer_text[0] == '-' || b < 16 || b > (1ull << 28))
      return usage_error("smooth", "bad --buffer '" + buffer_text + "' (16 to 268435456 triangles)");
    so.buffer_triangles = static_cast<uint32_t>(b);
  }

  FilterRun run;
  int code = run.open("smooth", fo);
  if (code >= 0) return code;
  so.memory_budget = run.filter_budget();
  TaubinSmoother smoother(run.sink(), so);
  Status s = run.run(&smoother);
  const SmoothReport& r = smoother.report();
  std::vector<std::string> notes = run.input_notes();
  if (r.stopped_vertices)
    notes.push_back(std::to_string(r.stopped_vertices) + " vertices took fewer steps: the buffer (" +
                    std::to_string(r.buffer_triangles) + " triangles) was full before their neighbourhood was read");
  if (r.isolated_dropped) notes.push_back(std::to_string(r.isolated_dropped) + " isolated vertices dropped");
  char summary[256];
  std::snprintf(summary, sizeof summary, "%llu triangles, %llu vertices smoothed, %llu bytes",
                static_cast<unsigned long long>(r.output_triangles),
                static_cast<unsigned long long>(r.smoothed_vertices),
                static_cast<unsigned long long>(run.bytes_out()));
  code = run.finish(s, summary, notes);
  if (code != kExitOk || !fo.json) return code;
  std::string o = "{\"input\": \"" + json_escape(fo.in) + "\", \"output\": \"" + json_escape(fo.out) +
                  "\", \"input_format\": \"" + run.input_format() + "\", \"output_format\": \"" +
                  run.output_format() + "\", \"vertices\": " + std::to_string(r.output_vertices) +
                  ", \"triangles\": " + std::to_string(r.output_triangles) +
                  ", \"smoothed_vertices\": " + std::to_string(r.smoothed_vertices) +
                  ", \"stopped_vertices\": " + std::to_string(r.stopped_vertices) +
                  ", \"iterations\": " + std::to_string(so.iterations) + ", \"lambda\": " + json_number(so.lambda) +
                  ", \"mu\": " + json_number(so.mu) + ", \"buffer_triangles\": " + std::to_string(r.buffer_triangles) +
                  ", \"max_buffer_triangles\": " + std::to_string(r.max_buffer_triangles) +
                  ", \"bytes_out\": " + std::to_string(run.bytes_out()) + ", \"seconds\": " +
                  json_number(run.seconds()) + ", \"lossless\": " + (run.lossless() ? "true" : "false") +
                  ", \"bits\": " + std::to_string(run.bits()) + ", \"notes\": [";
  for (size_t i = 0; i < notes.size(); ++i) o += (i ? ", \"" : "\"") + json_escape(notes[i]) + "\"";
  o += "]}\n";
  std::fputs(o.c_str(), stdout);
  return kExitOk;
}

}  // namespace psq::cli
