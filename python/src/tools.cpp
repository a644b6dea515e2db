// SPDX-License-Identifier: Apache-2.0
// python/src/tools.cpp: psq.convert, psq.simplify, psq.info and
// psq.distance. psq.info and psq.distance return the JSON text psq info
// --json and psq distance --json print (tools/src/ops, shared with the
// command); psq.convert and psq.simplify assemble their pipelines from
// the same pieces and return the command's fields, so that scripts can
// move between the two. Progress lines and notes on stderr are the
// command's business and are left out; notes come back in the object.
#include <chrono>
#include <cmath>

#include "binding.h"
#include "clustering_run.h"
#include "corner_weld.h"
#include "distance_report.h"
#include "filter_output.h"
#include "info.h"
#include "json.h"
#include "pipeline.h"
#include "psq/clustering.h"
#include "psq/distance.h"
#include "psq/mesh_formats.h"
#include "psq/mesh_stream.h"
#include "psq/sequence_builder.h"
#include "psq/stream_qem.h"
#include "psq/threaded_sink.h"

namespace psq::python {

namespace {

using detail::json_number;
using detail::json_strings;
using detail::same_file;

std::string n(uint64_t v) { return std::to_string(v); }
std::string q(const std::string& s) { return detail::json_string(s); }

// Where a pipeline's error goes (tools/src/ops/pipeline.h).
[[noreturn]] void pipeline_error(const Status& s, const std::string& in, const std::string& out) {
  throw StatusError(s, detail::error_is_about_output(s) ? out : in);
}

MeshFormat output_format(const std::string& format, const std::string& path) {
  const MeshFormat f = detail::output_format(format, path);
  if (f == MeshFormat::kUnknown) {
    if (!format.empty()) usage("unknown output format '" + format + "' (psq, ply, obj or drc)");
    usage("cannot tell the output format from '" + path + "': give to='psq', 'ply', 'obj' or 'drc'");
  }
  return f;
}

void open_input(const std::string& path, const OpenOptions& options, OpenedMesh* mesh) {
  *mesh = OpenedMesh();
  check(open_mesh(path, options, mesh), path);
}

double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace

// ------------------------------------------------------------------ convert

std::string convert(const std::string& in, const std::string& out, const ConvertParams& p) {
  const WriteParams& w = p.write;
  const MeshFormat out_format = output_format(w.format, out);
  if (!w.lossless && (w.bits < 1 || w.bits > 31)) usage("bits must be 1..31");
  if (out_format == MeshFormat::kDraco && !w.lossless && w.bits > 30) usage("bits must be 1..30 for Draco");
  if (w.profile != "auto" && w.profile != "fast" && w.profile != "compact")
    usage("profile must be 'auto', 'fast' or 'compact'");
  if (w.chunk_bytes < 1 || w.chunk_bytes > (1u << 24)) usage("chunk_bytes must be 1 to 16M");
  if (p.threads != 1 && p.threads != 2) usage("threads must be 1 or 2");
  if (same_file(in, out)) usage("the input and the output are the same file");
  if (p.weld != "off" && p.weld != "all" && p.weld != "positions" && p.weld != "corners")
    usage("weld must be 'off', 'all', 'positions' or 'corners'");
  const WeldMode weld = p.weld == "all" ? WeldMode::kAll : p.weld == "positions" ? WeldMode::kPositions : WeldMode::kOff;
  const bool weld_corners = p.weld == "corners";
  if ((weld != WeldMode::kOff || weld_corners) && out_format != MeshFormat::kPsq) usage("weld applies to .psq output");
  OpenOptions open_options;
  open_options.spool_dir = w.tmpdir;
  open_options.memory_budget = w.memory;
  OpenedMesh mesh;
  open_input(in, open_options, &mesh);
  if ((weld != WeldMode::kOff || weld_corners) && mesh.decoder) usage("weld applies to a mesh input, not to a .psq");
  if (weld_corners) {
    auto welder = std::make_unique<detail::CornerWelder>(std::move(mesh.source), w.memory);
    check(welder->open(), in);
    mesh.source = std::move(welder);
  }
  OutputFile output;
  check(output.open(out, w.overwrite), out);
  std::vector<std::string> notes;
  std::string o = "{\"input\": " + q(in) + ", \"output\": " + q(out) + ", \"input_format\": \"" +
                  format_name(mesh.format) + "\", \"output_format\": \"" + format_name(out_format) + "\"";
  if (out_format == MeshFormat::kPsq) {
    EncodeOptions e = encode_options(w, mesh.decoder ? mesh.decoder->header().fast ||
                                                           detail::auto_fast_profile(mesh.decoder->schema())
                                                     : detail::auto_fast_profile(mesh.source->schema()));
    e.measure_costs = p.measure_costs;
    // As psq convert: the input's counts size the segments (spec 4.6).
    e.segment_triangles = auto_segment_triangles(mesh);
    FileWriter writer(&output);
    PsqEncoder encoder(&writer, e);
    std::unique_ptr<ThreadedSequenceSink> threaded;
    if (p.threads > 1) threaded = std::make_unique<ThreadedSequenceSink>(&encoder);
    SequenceSink* sink = threaded ? static_cast<SequenceSink*>(threaded.get()) : &encoder;
    BuildOptions build;
    build.tmpdir = w.tmpdir;
    build.memory_budget = w.memory;
    build.weld = weld;
    BuildReport report;
    Status s = detail::feed_sequence(mesh, *sink, build, &report);
    threaded.reset();  // joins the encoder's thread
    if (!s.ok()) {
      output.discard();
      pipeline_error(s, in, out);
    }
    check(output.commit(), out);
    const PsqStats& st = encoder.stats();
    notes = detail::input_notes(mesh, report);
    if (!mesh.decoder)
      for (std::string& x : detail::weld_notes(weld, report, mesh.source->schema())) notes.push_back(std::move(x));
    o += ", \"vertices\": " + n(st.vertices) + ", \"triangles\": " + n(st.triangles) +
         ", \"bytes_in\": " + n(mesh.stream->offset()) + ", \"bytes_out\": " + n(output.size()) +
         ", " + detail::json_bits_per_vertex(st) + detail::json_encoding(e) +
         detail::json_weld(weld, report, !mesh.decoder, dynamic_cast<const detail::CornerWelder*>(mesh.source.get()));
  } else {
    std::unique_ptr<MeshSink> writer = make_mesh_writer(out_format, &output, write_options(w));
    detail::MeshCounter counter(writer.get());
    Status s = pump(*mesh.source, counter);
    if (!s.ok()) {
      output.discard();
      pipeline_error(s, in, out);
    }
    check(output.commit(), out);
    notes = mesh.source->report().notes;
    for (const std::string& x : detail::writer_notes(out_format, writer.get())) notes.push_back(x);
    o += ", \"vertices\": " + n(counter.vertices) + ", \"triangles\": " + n(counter.triangles) +
         ", \"bytes_in\": " + n(mesh.stream->offset()) + ", \"bytes_out\": " + n(output.size());
  }
  return o + ", \"notes\": " + json_strings(notes) + "}";
}

// ----------------------------------------------------------------- simplify

namespace {

// The output file of a simplification and its writers.
struct Output {
  OutputFile file;
  MeshFormat format = MeshFormat::kUnknown;
  detail::FilterOutput chain;  // after `file`: goes first

  void open(const std::string& path, const SimplifyParams& p, const EncodeOptions& e, uint64_t draco_budget) {
    check(file.open(path, p.overwrite), path);
    WriteOptions w;
    w.ascii = p.ascii;
    w.spool_dir = p.tmpdir;
    w.memory_budget = draco_budget;
    chain.open(&file, format, e, w);
  }
};

uint64_t count_triangles(const std::string& in, const OpenOptions& oo) {
  OpenedMesh mesh;
  open_input(in, oo, &mesh);
  uint64_t count = 0;
  check(detail::count_triangles(mesh, &count), in);
  return count;
}

}  // namespace

std::string simplify(const std::string& in, const std::string& out, const SimplifyParams& p) {
  const auto start = std::chrono::steady_clock::now();
  if (p.method != "clustering" && p.method != "qem") usage("method must be 'clustering' or 'qem', not '" + p.method + "'");
  if (p.ratio != 0 && !(p.ratio > 0 && p.ratio <= 1)) usage("ratio must be in (0, 1]");
  if (p.ratio > 0 && p.triangles > 0) usage("give ratio or triangles, not both");
  if (p.bits != 0 && (p.bits < 1 || p.bits > 31)) usage("bits must be 1..31");
  if (p.bits != 0 && p.lossless) usage("bits and lossless exclude each other");
  if (p.profile != "auto" && p.profile != "fast" && p.profile != "compact")
    usage("profile must be 'auto', 'fast' or 'compact'");
  if (p.memory < (uint64_t{8} << 20)) usage("memory must be at least 8M");
  Output output;
  output.format = output_format(p.format, out);
  if (same_file(in, out)) usage("the input and the output are the same file");

  const detail::ClusteringBudget budget = detail::split_clustering_budget(p.memory);
  BuildOptions build;
  build.tmpdir = p.tmpdir;
  build.memory_budget = budget.build;
  OpenOptions oo;
  oo.spool_dir = p.tmpdir;
  oo.memory_budget = build.memory_budget;

  OpenedMesh mesh;
  open_input(in, oo, &mesh);
  const bool psq_in = static_cast<bool>(mesh.decoder);
  const MeshSchema in_schema = psq_in ? mesh.decoder->schema() : mesh.source->schema();
  // The output keeps a quantized .psq input's bits. For qem, a lossless
  // .psq input stays lossless: it has no bounding box to quantize on
  // before its first vertex (as psq simplify --method qem); clustering
  // measures the box in a first pass and passes it on.
  EncodeOptions e;
  if (!detail::filter_encoding(mesh, p.bits, p.lossless, p.profile, p.method == "qem", &e))
    usage("bits: the input is a lossless .psq, which gives no bounding box to quantize on; use lossless=True");
  if (output.format == MeshFormat::kDraco && !e.lossless && e.bits > 30)
    usage("the input's " + std::to_string(e.bits) + " bits are too many for Draco: give bits (1..30)");

  std::vector<std::string> notes;
  BuildReport report;
  std::string o = "{\"input\": " + q(in) + ", \"output\": " + q(out) + ", \"input_format\": \"" +
                  format_name(mesh.format) + "\", \"output_format\": \"" + format_name(output.format) +
                  "\", \"method\": \"" + p.method + "\"";

  if (p.method == "qem") {
    QemOptions qo = p.qem;
    qo.ratio = p.ratio;
    qo.target_triangles = p.triangles;
    // As psq simplify --method qem: the decoder and encoder keep their
    // boundaries; the filter gets the rest of the budget.
    qo.memory_budget = detail::sequence_filter_budget(p.memory, psq_in);
    build.memory_budget = p.memory / 2;
    if (qo.ratio == 0 && qo.target_triangles == 0 && qo.max_error < 0)
      usage("give a target: ratio, triangles or max_error");
    if (qo.target_triangles > 0 && psq_in && in_schema.triangle_count < 0) qo.input_triangles = count_triangles(in, oo);
    detail::filter_segments(mesh, p.triangles, p.ratio, &e);
    output.open(out, p, e, budget.writer);
    StreamQem qem(output.chain.sequence_sink(false), qo);
    // The builder reads the whole mesh before the first event: its count
    // is known by the filter's begin().
    Status s = detail::feed_sequence(mesh, qem, build, &report, nullptr, [&](uint64_t triangles) {
      if (triangles) qem.set_input_triangles(triangles);
    });
    if (!s.ok()) {
      output.file.discard();
      pipeline_error(s, in, out);
    }
    check(output.file.commit(), out);
    const QemReport& r = qem.report();
    notes = detail::input_notes(mesh, report);
    if (r.target_triangles > 0 &&
        std::fabs(static_cast<double>(r.output_triangles) - static_cast<double>(r.target_triangles)) >
            0.01 * static_cast<double>(r.target_triangles) + 2)
      notes.push_back("the target of " + std::to_string(r.target_triangles) + " triangles was not met (" +
                      std::to_string(r.output_triangles) + "): no more edges could be collapsed");
    if (r.isolated_dropped) notes.push_back(std::to_string(r.isolated_dropped) + " isolated vertices dropped");
    for (const std::string& x : output.chain.notes()) notes.push_back(x);
    o += ", \"input_vertices\": " + n(r.input_vertices) + ", \"input_triangles\": " + n(r.input_triangles) +
         ", \"output_vertices\": " + n(r.output_vertices) + ", \"output_triangles\": " + n(r.output_triangles) +
         ", \"target_triangles\": " + n(r.target_triangles) + ", \"collapses\": " + n(r.collapses) +
         ", \"max_error\": " + json_number(r.max_error) + ", \"buffer_triangles\": " + n(r.buffer_triangles) +
         ", \"max_buffer_triangles\": " + n(r.max_buffer_triangles) +
         ", \"max_buffer_vertices\": " + n(r.max_buffer_vertices);
  } else {
    ClusteringOptions co;
    if (!parse_cell_mode(p.cells, &co.cells)) usage("cells must be 'connected', 'active' or 'global'");
    if ((p.grid > 0) + (p.cell > 0) + (p.triangles > 0 || p.ratio > 0) > 1)
      usage("give one of grid, cell and a target (ratio or triangles)");
    if (p.grid < 0 || p.cell < 0) usage("grid and cell must be positive");
    if (p.border_weight < 0 || !std::isfinite(p.border_weight)) usage("border_weight must be a number >= 0");
    co.border_weight = p.border_weight;
    co.memory_budget = budget.filter;
    if (p.grid > 0) {
      if (!(p.grid >= 1) || !(p.grid < ClusterGrid::kMaxDim)) usage("grid must be 1 to 2097151");
      co.grid = p.grid;
    } else if (p.cell > 0) {
      co.cell_size = p.cell;
      co.grid = 0;
    }
    int passes = 0;
    // A lossless .psq declares no bounding box: a first pass measures it.
    if (psq_in && !in_schema.has_bounds) {
      ++passes;
      check(detail::measure_bounds(*mesh.decoder, &co), in);
      open_input(in, oo, &mesh);
    }
    // A target: trial passes pick the grid, as psq simplify --triangles
    // and --ratio do.
    uint64_t target = p.triangles;
    if (p.ratio > 0) target = detail::ratio_target(p.ratio, in_schema.triangle_count);
    if (target > 0) co.grid = first_grid_for_triangles(target);
    if (target > 0 || p.ratio > 0) {
      bool reopening = false;  // an error of opening IN again, not of a pass
      Status s = detail::search_grid(&target, p.ratio, &co,
                                     [&](const ClusteringOptions& trial, uint64_t* tin, uint64_t* tout) {
        CountingMeshSink count;
        ClusteringFilter filter(&count, trial);
        BuildReport r;
        ++passes;
        PSQ_RETURN_IF_ERROR(detail::feed_sequence(mesh, filter, build, &r));
        *tin = filter.stats().triangles_in;
        *tout = count.triangles;
        reopening = true;
        mesh = OpenedMesh();
        PSQ_RETURN_IF_ERROR(open_mesh(in, oo, &mesh));
        reopening = false;
        return Status();
      });
      if (!s.ok()) {
        if (reopening) throw StatusError(s, in);
        pipeline_error(s, in, out);
      }
    }
    detail::filter_segments(mesh, target, 0, &e);
    output.open(out, p, e, budget.writer);
    ClusteringFilter filter(output.chain.mesh_sink(budget.lookahead, false, false), co);
    ++passes;
    Status s = detail::feed_sequence(mesh, filter, build, &report);
    if (!s.ok()) {
      output.file.discard();
      pipeline_error(s, in, out);
    }
    check(output.file.commit(), out);
    const ClusteringStats& st = filter.stats();
    notes = mesh.source->report().notes;
    for (const std::string& x : detail::clustering_notes(in_schema, st, output.chain.notes())) notes.push_back(x);
    o += std::string(", \"cells\": \"") + cell_mode_name(co.cells) + "\", \"grid_longest\": " +
         (co.grid > 0 ? json_number(co.grid) : std::string("null")) + ", \"grid\": [" + n(st.grid.dims[0]) + ", " +
         n(st.grid.dims[1]) + ", " + n(st.grid.dims[2]) + "], \"cell_size\": " + json_number(st.grid.cell) +
         ", \"border_weight\": " + json_number(co.border_weight) +
         ", \"target_triangles\": " + (target ? n(target) : std::string("null")) + ", \"passes\": " + n(passes) +
         ", \"input_vertices\": " + n(st.vertices_in) + ", \"input_triangles\": " + n(st.triangles_in) +
         ", \"output_vertices\": " + n(st.vertices_out) + ", \"output_triangles\": " + n(st.triangles_out) +
         ", \"clusters\": " + n(st.clusters) + ", \"filter_peak_bytes\": " + n(st.peak_bytes);
  }
  o += ", \"bytes_in\": " + n(mesh.stream ? mesh.stream->offset() : 0) + ", \"bytes_out\": " + n(output.file.size()) +
       ", \"seconds\": " + json_number(seconds_since(start));
  if (output.format == MeshFormat::kPsq)
    o += detail::json_encoding(e);
  return o + ", \"notes\": " + json_strings(notes) + "}";
}

// --------------------------------------------------------------------- info

std::string info(const std::string& path, const InfoParams& p) {
  OpenOptions oo;
  oo.spool_dir = p.tmpdir;
  OpenedMesh mesh;
  open_input(path, oo, &mesh);
  BuildOptions build;
  build.tmpdir = p.tmpdir;
  build.memory_budget = p.memory;
  detail::InfoReport r;
  check(detail::measure_info(mesh, build, &r), path);
  return detail::info_json(path, r);
}

// ----------------------------------------------------------------- distance

std::string distance(const std::string& a_path, const std::string& b_path, const DistanceParams& p) {
  DistanceOptions options;
  options.samples = p.samples;
  options.seed = p.seed;
  options.tmpdir = p.tmpdir;
  if (p.samples > kMaxSamples) usage("samples must be at most 1G");
  if (p.threads < 0 || p.threads > 1024) usage("threads must be 0 (one per processor) to 1024");
  options.threads = p.threads;
  if (p.hold == "auto") options.hold = DistanceHold::kAuto;
  else if (p.hold == "a" || p.hold == "A") options.hold = DistanceHold::kA;
  else if (p.hold == "b" || p.hold == "B") options.hold = DistanceHold::kB;
  else if (p.hold == "both") options.hold = DistanceHold::kBoth;
  else usage("hold must be 'auto', 'a', 'b' or 'both'");
  OpenOptions oo;
  oo.spool_dir = p.tmpdir;
  OpenedMesh a, b;
  open_input(a_path, oo, &a);
  open_input(b_path, oo, &b);
  if (options.hold == DistanceHold::kAuto) options.hold = detail::auto_hold(a, b);
  DistanceResult r;
  Status s = measure_distance(*a.source, *b.source, options, &r);
  if (!s.ok()) throw StatusError(s, detail::distance_error_file(r, a_path, b_path, p.tmpdir));
  return detail::distance_json(a_path, b_path, options, r);
}

}  // namespace psq::python
