// SPDX-License-Identifier: Apache-2.0
// python/src/tools.cpp: psq.convert, psq.simplify, psq.info and
// psq.distance. They assemble the library's pipelines as the psq command
// does (tools/cli/cmd_*.cpp) and return the JSON object that command
// prints with --json, with the same fields, so that scripts can move
// between the two. Progress lines and notes on stderr are the command's
// business and are left out; notes come back in the object.
#include <sys/stat.h>

#include <algorithm>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <thread>

#include "binding.h"
#include "psq/clustering.h"
#include "psq/converter.h"
#include "psq/distance.h"
#include "psq/draco.h"
#include "psq/memory_budget.h"
#include "psq/mesh_formats.h"
#include "psq/mesh_stats.h"
#include "psq/mesh_stream.h"
#include "psq/obj.h"
#include "psq/sequence_builder.h"
#include "psq/sequence_check.h"
#include "psq/sequence_count.h"
#include "psq/stream_qem.h"
#include "psq/threaded_sink.h"

namespace psq::python {

std::string json_escape(const std::string& s) {
  std::string out;
  for (unsigned char c : s) {
    switch (c) {
      case '"': out += "\\\""; break;
      case '\\': out += "\\\\"; break;
      case '\n': out += "\\n"; break;
      case '\r': out += "\\r"; break;
      case '\t': out += "\\t"; break;
      default:
        if (c < 0x20) {
          char buf[8];
          std::snprintf(buf, sizeof buf, "\\u%04x", c);
          out += buf;
        } else {
          out += static_cast<char>(c);
        }
    }
  }
  return out;
}

std::string json_number(double v) {
  if (!std::isfinite(v)) return "null";
  char buf[64];
  auto r = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, r.ptr);
}

namespace {

std::string n(uint64_t v) { return std::to_string(v); }
std::string q(const std::string& s) { return "\"" + json_escape(s) + "\""; }

std::string json_notes(const std::vector<std::string>& notes) {
  std::string o = "[";
  for (size_t i = 0; i < notes.size(); ++i) o += (i ? ", " : "") + q(notes[i]);
  return o + "]";
}

bool same_file(const std::string& a, const std::string& b) {
  struct stat sa, sb;
  return ::stat(a.c_str(), &sa) == 0 && ::stat(b.c_str(), &sb) == 0 && sa.st_dev == sb.st_dev &&
         sa.st_ino == sb.st_ino;
}

// Where a pipeline's error goes: a place in the input, or anything about
// the data, concerns IN; an I/O error without a place (a write) OUT.
[[noreturn]] void pipeline_error(const Status& s, const std::string& in, const std::string& out) {
  const bool about_out = s.line() == Status::kNoPlace && s.offset() == Status::kNoPlace && s.code() == ErrorCode::kIo;
  throw StatusError(s, about_out ? out : in);
}

MeshFormat output_format(const std::string& format, const std::string& path) {
  const MeshFormat f = format.empty() ? format_from_extension(path) : format_from_name(format);
  if (f == MeshFormat::kUnknown) {
    if (!format.empty()) usage("unknown output format '" + format + "' (psq, ply, obj or drc)");
    usage("cannot tell the output format from '" + path + "': give to='psq', 'ply', 'obj' or 'drc'");
  }
  return f;
}

// As psq convert --profile auto.
bool auto_fast(const MeshSchema& schema) {
  if (schema.triangle_count != MeshSchema::kUnknown) return schema.triangle_count >= 131072;
  return schema.vertex_count != MeshSchema::kUnknown && schema.vertex_count >= 65536;
}

// A processing sequence written as an indexed mesh, re-appearing vertices
// merged back into the vertex they re-appear (spec/psq-dump.md A.2.1).
class SequenceToMesh : public SequenceSink {
 public:
  explicit SequenceToMesh(MeshSink* out) : out_(out) {}
  Status begin(const MeshSchema& schema) override {
    MeshSchema s = schema;
    s.vertex_count = MeshSchema::kUnknown;
    s.triangle_count = MeshSchema::kUnknown;
    return out_->begin(s);
  }
  Status vertex(const SequenceVertex& v) override {
    if (v.reappears != kNoVertex) {
      reappearing_.push_back(v.index);
      first_.push_back(mesh_index(v.reappears));
      return Status();
    }
    return out_->vertex(v.position, v.values);
  }
  Status triangle(const SequenceTriangle& t) override {
    const uint32_t index[3] = {mesh_index(t.v[0]), mesh_index(t.v[1]), mesh_index(t.v[2])};
    return out_->triangle(index, t.values);
  }
  Status finalize(uint32_t) override { return Status(); }
  Status finish() override { return out_->finish(); }

 private:
  uint32_t mesh_index(uint32_t dense) const {
    auto it = std::lower_bound(reappearing_.begin(), reappearing_.end(), dense);
    if (it != reappearing_.end() && *it == dense) return first_[static_cast<size_t>(it - reappearing_.begin())];
    return dense - static_cast<uint32_t>(it - reappearing_.begin());
  }
  MeshSink* out_;
  std::vector<uint32_t> reappearing_, first_;
};

class NullSequenceSink : public SequenceSink {
 public:
  Status begin(const MeshSchema&) override { return Status(); }
  Status vertex(const SequenceVertex& v) override {
    for (int a = 0; a < 3; ++a) {
      lo[a] = any ? std::min(lo[a], v.position[a]) : v.position[a];
      hi[a] = any ? std::max(hi[a], v.position[a]) : v.position[a];
    }
    any = true;
    return Status();
  }
  Status triangle(const SequenceTriangle&) override {
    ++triangles;
    return Status();
  }
  Status finalize(uint32_t) override { return Status(); }
  Status finish() override { return Status(); }
  uint64_t triangles = 0;
  bool any = false;
  double lo[3] = {0, 0, 0}, hi[3] = {0, 0, 0};
};

// The processing sequence of an opened input into `sink`.
Status feed(OpenedMesh& mesh, SequenceSink& sink, const BuildOptions& build, BuildReport* report) {
  if (mesh.decoder) return mesh.decoder->pump(sink);
  return build_sequence(*mesh.source, sink, build, report);
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
  OpenOptions open_options;
  open_options.spool_dir = w.tmpdir;
  open_options.memory_budget = w.memory;
  OpenedMesh mesh;
  open_input(in, open_options, &mesh);
  OutputFile output;
  check(output.open(out, w.overwrite), out);
  std::vector<std::string> notes;
  std::string o = "{\"input\": " + q(in) + ", \"output\": " + q(out) + ", \"input_format\": \"" +
                  format_name(mesh.format) + "\", \"output_format\": \"" + format_name(out_format) + "\"";
  if (out_format == MeshFormat::kPsq) {
    EncodeOptions e;
    e.bits = w.bits;
    e.lossless = w.lossless;
    e.chunk_bytes = w.chunk_bytes;
    e.zstd_level = w.zstd_level;
    e.measure_costs = p.measure_costs;
    e.fast = w.profile == "fast" ||
             (w.profile == "auto" && (mesh.decoder ? mesh.decoder->header().fast || auto_fast(mesh.decoder->schema())
                                                   : auto_fast(mesh.source->schema())));
    FileWriter writer(&output);
    PsqEncoder encoder(&writer, e);
    std::unique_ptr<ThreadedSequenceSink> threaded;
    if (p.threads > 1) threaded = std::make_unique<ThreadedSequenceSink>(&encoder);
    SequenceSink* sink = threaded ? static_cast<SequenceSink*>(threaded.get()) : &encoder;
    BuildOptions build;
    build.tmpdir = w.tmpdir;
    build.memory_budget = w.memory;
    BuildReport report;
    Status s = feed(mesh, *sink, build, &report);
    threaded.reset();  // joins the encoder's thread
    if (!s.ok()) {
      output.discard();
      pipeline_error(s, in, out);
    }
    check(output.commit(), out);
    const PsqStats& st = encoder.stats();
    notes = mesh.source->report().notes;
    if (report.converter.degenerate_dropped)
      notes.push_back(std::to_string(report.converter.degenerate_dropped) + " degenerate triangle(s) dropped");
    const double nv = st.vertices ? static_cast<double>(st.vertices) : 1.0;
    o += ", \"vertices\": " + n(st.vertices) + ", \"triangles\": " + n(st.triangles) +
         ", \"bytes_in\": " + n(mesh.stream->offset()) + ", \"bytes_out\": " + n(output.size()) +
         ", \"bits_per_vertex\": " + json_number(8.0 * st.total_bytes / nv) +
         ", \"connectivity_bits_per_vertex\": " + json_number(st.connectivity_bits / nv) +
         ", \"geometry_bits_per_vertex\": " + json_number(st.geometry_bits / nv) +
         ", \"property_bits_per_vertex\": " + json_number(8.0 * st.property_bytes / nv) +
         ", \"lossless\": " + (e.lossless ? "true" : "false") + ", \"bits\": " + std::to_string(e.lossless ? 0 : e.bits) +
         ", \"profile\": \"" + (e.fast ? "fast" : "compact") + "\"";
  } else {
    WriteOptions wo;
    wo.ascii = w.ascii;
    wo.spool_dir = w.tmpdir;
    wo.draco_bits = w.bits;
    wo.lossless = w.lossless;
    wo.memory_budget = w.memory;
    std::unique_ptr<MeshSink> writer = make_mesh_writer(out_format, &output, wo);
    struct Counter : MeshSink {
      MeshSink* next = nullptr;
      uint64_t vertices = 0, triangles = 0;
      Status begin(const MeshSchema& sc) override { return next->begin(sc); }
      Status vertex(const double pos[3], const PropertyValues& v) override {
        ++vertices;
        return next->vertex(pos, v);
      }
      Status triangle(const uint32_t i[3], const PropertyValues& v) override {
        ++triangles;
        return next->triangle(i, v);
      }
      Status finish() override { return next->finish(); }
    } counter;
    counter.next = writer.get();
    Status s = pump(*mesh.source, counter);
    if (!s.ok()) {
      output.discard();
      pipeline_error(s, in, out);
    }
    check(output.commit(), out);
    notes = mesh.source->report().notes;
    if (out_format == MeshFormat::kObj)
      for (const std::string& d : static_cast<ObjWriter*>(writer.get())->dropped())
        notes.push_back("property '" + d + "' dropped: OBJ cannot hold it");
    if (out_format == MeshFormat::kDraco) {
      for (const std::string& d : static_cast<DracoWriter*>(writer.get())->dropped())
        notes.push_back("property '" + d + "' dropped: Draco output keeps scalar vertex properties only");
      for (const std::string& x : static_cast<DracoWriter*>(writer.get())->notes()) notes.push_back(x);
    }
    o += ", \"vertices\": " + n(counter.vertices) + ", \"triangles\": " + n(counter.triangles) +
         ", \"bytes_in\": " + n(mesh.stream->offset()) + ", \"bytes_out\": " + n(output.size());
  }
  return o + ", \"notes\": " + json_notes(notes) + "}";
}

// ----------------------------------------------------------------- simplify

namespace {

// The output of a simplification: a .psq (through the converter for a
// clustering filter's mesh stream, directly for qem's sequence) or a mesh
// writer.
struct Output {
  OutputFile file;
  MeshFormat format = MeshFormat::kUnknown;
  std::unique_ptr<FileWriter> byte_writer;
  std::unique_ptr<PsqEncoder> encoder;
  std::unique_ptr<SequenceConverter> converter;
  std::unique_ptr<MeshSink> writer;
  std::unique_ptr<DenseMeshSink> dense;
  std::unique_ptr<SequenceToMesh> to_mesh;

  void open(const std::string& path, const SimplifyParams& p, const EncodeOptions& e, uint64_t draco_budget,
            bool mesh_stream) {
    check(file.open(path, p.overwrite), path);
    if (format == MeshFormat::kPsq) {
      byte_writer = std::make_unique<FileWriter>(&file);
      encoder = std::make_unique<PsqEncoder>(byte_writer.get(), e);
      if (mesh_stream) {
        converter = std::make_unique<SequenceConverter>(encoder.get());
        converter->set_lookahead_minimum(4096);  // as psq simplify: a filter's output
      }
      return;
    }
    WriteOptions w;
    w.ascii = p.ascii;
    w.spool_dir = p.tmpdir;
    w.draco_bits = std::min(e.bits, 30);
    w.lossless = e.lossless;
    w.memory_budget = draco_budget;
    writer = make_mesh_writer(format, &file, w);
    if (mesh_stream) dense = std::make_unique<DenseMeshSink>(writer.get());
    else to_mesh = std::make_unique<SequenceToMesh>(writer.get());
  }
  StreamingMeshSink* mesh_sink() { return converter ? static_cast<StreamingMeshSink*>(converter.get()) : dense.get(); }
  SequenceSink* sequence_sink() { return encoder ? static_cast<SequenceSink*>(encoder.get()) : to_mesh.get(); }
};

uint64_t count_triangles(const std::string& in, const OpenOptions& oo) {
  OpenedMesh mesh;
  open_input(in, oo, &mesh);
  if (mesh.decoder) {
    if (mesh.decoder->schema().triangle_count >= 0) return static_cast<uint64_t>(mesh.decoder->schema().triangle_count);
    NullSequenceSink counter;
    check(mesh.decoder->pump(counter), in);
    return counter.triangles;
  }
  if (mesh.source->schema().triangle_count >= 0) return static_cast<uint64_t>(mesh.source->schema().triangle_count);
  MeshItem item;
  uint64_t t = 0;
  for (;;) {
    check(mesh.source->next(&item), in);
    if (item.kind == MeshItem::Kind::kEnd) break;
    if (item.kind == MeshItem::Kind::kTriangle) ++t;
  }
  return t;
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

  MemoryBudget budget(p.memory);
  BuildOptions build;
  build.tmpdir = p.tmpdir;
  build.memory_budget = budget.draw(1, 2);
  const uint64_t filter_budget = budget.draw(1, 4);
  const uint64_t lookahead = budget.draw(1, 64);
  const uint64_t draco_budget = budget.draw_rest();
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
  const bool lossless_psq = psq_in && mesh.decoder->header().lossless;
  EncodeOptions e;
  e.lossless = p.lossless || (lossless_psq && p.method == "qem");
  e.bits = p.bits ? p.bits : (psq_in && !lossless_psq) ? mesh.decoder->header().bits : 16;
  if (p.bits && lossless_psq && p.method == "qem")
    usage("bits: the input is a lossless .psq, which gives no bounding box to quantize on; use lossless=True");
  e.fast = p.profile == "fast" || (p.profile == "auto" && (psq_in ? mesh.decoder->header().fast : false)) ||
           (p.profile == "auto" && p.method == "clustering" && auto_fast(in_schema));
  if (output.format == MeshFormat::kDraco && !e.lossless && e.bits > 30)
    usage("the input's " + std::to_string(e.bits) + " bits are too many for Draco: give bits (1..30)");

  std::vector<std::string> notes;
  BuildReport report;
  std::string o = "{\"input\": " + q(in) + ", \"output\": " + q(out) + ", \"input_format\": \"" +
                  format_name(mesh.format) + "\", \"output_format\": \"" + format_name(output.format) +
                  "\", \"method\": \"" + p.method + "\"";

  if (p.method == "qem") {
    QemOptions qo;
    qo.ratio = p.ratio;
    qo.target_triangles = p.triangles;
    qo.max_error = p.max_error;
    qo.buffer_triangles = p.buffer;
    qo.candidates = p.candidates;
    qo.lock_border = p.lock_border;
    qo.seed = p.seed;
    // As psq simplify --method qem: the decoder and encoder keep their
    // boundaries; the filter gets the rest of the budget.
    qo.memory_budget = psq_in ? p.memory - std::min<uint64_t>(p.memory / 2, uint64_t{30} << 20) : p.memory / 2;
    build.memory_budget = p.memory / 2;
    if (qo.ratio == 0 && qo.target_triangles == 0 && qo.max_error < 0)
      usage("give a target: ratio, triangles or max_error");
    if (qo.target_triangles > 0 && psq_in && in_schema.triangle_count < 0) qo.input_triangles = count_triangles(in, oo);
    output.open(out, p, e, draco_budget, false);
    StreamQem qem(output.sequence_sink(), qo);
    Status s;
    if (psq_in) {
      s = mesh.decoder->pump(qem);
    } else {
      // The builder reads the whole mesh before the first event: its count
      // is known by the filter's begin().
      struct Counting : MeshSource {
        MeshSource* in;
        uint64_t triangles = 0;
        const MeshSchema& schema() const override { return in->schema(); }
        const SourceReport& report() const override { return in->report(); }
        Status next(MeshItem* item) override {
          Status st = in->next(item);
          if (st.ok() && item->kind == MeshItem::Kind::kTriangle) ++triangles;
          return st;
        }
      } counting;
      counting.in = mesh.source.get();
      struct AtBegin : SequenceSink {
        StreamQem* qem;
        Counting* counting;
        Status begin(const MeshSchema& sc) override {
          if (counting->triangles) qem->set_input_triangles(counting->triangles);
          return qem->begin(sc);
        }
        Status vertex(const SequenceVertex& v) override { return qem->vertex(v); }
        Status triangle(const SequenceTriangle& t) override { return qem->triangle(t); }
        Status finalize(uint32_t i) override { return qem->finalize(i); }
        Status finish() override { return qem->finish(); }
      } at_begin;
      at_begin.qem = &qem;
      at_begin.counting = &counting;
      s = build_sequence(counting, at_begin, build, &report);
    }
    if (!s.ok()) {
      output.file.discard();
      pipeline_error(s, in, out);
    }
    check(output.file.commit(), out);
    const QemReport& r = qem.report();
    notes = mesh.source->report().notes;
    if (report.converter.degenerate_dropped)
      notes.push_back(std::to_string(report.converter.degenerate_dropped) + " degenerate triangle(s) dropped");
    if (r.target_triangles > 0 &&
        std::fabs(static_cast<double>(r.output_triangles) - static_cast<double>(r.target_triangles)) >
            0.01 * static_cast<double>(r.target_triangles) + 2)
      notes.push_back("the target of " + std::to_string(r.target_triangles) + " triangles was not met (" +
                      std::to_string(r.output_triangles) + "): no more edges could be collapsed");
    if (r.isolated_dropped) notes.push_back(std::to_string(r.isolated_dropped) + " isolated vertices dropped");
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
    co.memory_budget = filter_budget;
    if (p.grid > 0) {
      if (!(p.grid >= 1) || !(p.grid < ClusterGrid::kMaxDim)) usage("grid must be 1 to 2097151");
      co.grid = p.grid;
    } else if (p.cell > 0) {
      co.cell_size = p.cell;
      co.grid = 0;
    }
    uint64_t target = p.triangles;
    if (p.ratio > 0) {
      const uint64_t total = count_triangles(in, oo);
      target = std::max<uint64_t>(1, static_cast<uint64_t>(std::llround(p.ratio * static_cast<double>(total))));
    }
    int passes = 0;
    // A lossless .psq declares no bounding box: a first pass measures it.
    if (psq_in && !in_schema.has_bounds) {
      NullSequenceSink box;
      ++passes;
      check(mesh.decoder->pump(box), in);
      co.has_bounds = true;
      std::copy(box.lo, box.lo + 3, co.bounds_min);
      std::copy(box.hi, box.hi + 3, co.bounds_max);
      open_input(in, oo, &mesh);
    }
    // A target: trial passes pick the grid, as psq simplify --triangles
    // does (the output grows about as the grid squared).
    if (target > 0) {
      co.grid = first_grid_for_triangles(target);
      double trial_grid[2] = {co.grid, 0};
      uint64_t trial_triangles[2] = {0, 0};
      for (int t = 0; t < 2; ++t) {
        ClusteringOptions trial = co;
        trial.grid = trial_grid[t];
        CountingMeshSink count;
        ClusteringFilter filter(&count, trial);
        BuildReport r;
        ++passes;
        Status s = feed(mesh, filter, build, &r);
        if (!s.ok()) pipeline_error(s, in, out);
        trial_triangles[t] = count.triangles;
        open_input(in, oo, &mesh);
        const double off =
            std::fabs(static_cast<double>(count.triangles) - static_cast<double>(target)) / static_cast<double>(target);
        if (off <= 0.02) {
          co.grid = trial_grid[t];
          break;
        }
        if (t == 0) {
          co.grid = corrected_grid_for_triangles(target, trial_grid[0], trial_triangles[0]);
          const double ratio = co.grid / trial_grid[0];
          if (ratio > 0.8 && ratio < 1.25) break;
          trial_grid[1] = co.grid;
        } else if (trial_triangles[0] > 0 && trial_triangles[1] > 0 && trial_triangles[0] != trial_triangles[1]) {
          const double slope = std::log(static_cast<double>(trial_triangles[1]) / trial_triangles[0]) /
                               std::log(trial_grid[1] / trial_grid[0]);
          co.grid = slope > 0.5 ? trial_grid[1] * std::pow(static_cast<double>(target) / trial_triangles[1], 1 / slope)
                                : corrected_grid_for_triangles(target, trial_grid[1], trial_triangles[1]);
          co.grid = std::min<double>(ClusterGrid::kMaxDim - 1, std::max(1.0, co.grid));
        } else {
          co.grid = corrected_grid_for_triangles(target, trial_grid[1], trial_triangles[1]);
        }
      }
    }
    output.open(out, p, e, draco_budget, true);
    if (output.converter) output.converter->set_lookahead_budget(lookahead);
    ClusteringFilter filter(output.mesh_sink(), co);
    ++passes;
    Status s = feed(mesh, filter, build, &report);
    if (!s.ok()) {
      output.file.discard();
      pipeline_error(s, in, out);
    }
    check(output.file.commit(), out);
    const ClusteringStats& st = filter.stats();
    notes = mesh.source->report().notes;
    for (const Property& pr : in_schema.vertex_properties)
      if (pr.is_list) notes.push_back("vertex property '" + pr.name + "' dropped: lists do not merge");
    for (const Property& pr : in_schema.face_properties)
      if (pr.is_list) notes.push_back("face property '" + pr.name + "' dropped: lists do not merge");
    if (st.triangles_in > 0 && st.triangles_out == 0)
      notes.push_back("no triangle has its corners in three cells: the output is empty (use a finer grid)");
    o += std::string(", \"cells\": \"") + cell_mode_name(co.cells) + "\", \"grid_longest\": " +
         (co.grid > 0 ? json_number(co.grid) : std::string("null")) + ", \"grid\": [" + n(st.grid.dims[0]) + ", " +
         n(st.grid.dims[1]) + ", " + n(st.grid.dims[2]) + "], \"cell_size\": " + json_number(st.grid.cell) +
         ", \"border_weight\": " + json_number(co.border_weight) +
         ", \"target_triangles\": " + (target ? n(target) : std::string("null")) + ", \"passes\": " + n(passes) +
         ", \"input_vertices\": " + n(st.vertices_in) + ", \"input_triangles\": " + n(st.triangles_in) +
         ", \"output_vertices\": " + n(st.vertices_out) + ", \"output_triangles\": " + n(st.triangles_out) +
         ", \"clusters\": " + n(st.clusters) + ", \"filter_peak_bytes\": " + n(st.peak_bytes);
  }
  if (output.format == MeshFormat::kObj)
    for (const std::string& d : static_cast<ObjWriter*>(output.writer.get())->dropped())
      notes.push_back("property '" + d + "' dropped: OBJ cannot hold it");
  if (output.format == MeshFormat::kDraco)
    for (const std::string& d : static_cast<DracoWriter*>(output.writer.get())->dropped())
      notes.push_back("property '" + d + "' dropped: Draco output keeps scalar vertex properties only");
  o += ", \"bytes_in\": " + n(mesh.stream ? mesh.stream->offset() : 0) + ", \"bytes_out\": " + n(output.file.size()) +
       ", \"seconds\": " + json_number(seconds_since(start));
  if (output.format == MeshFormat::kPsq)
    o += ", \"lossless\": " + std::string(e.lossless ? "true" : "false") + ", \"bits\": " +
         std::to_string(e.lossless ? 0 : e.bits) + ", \"profile\": \"" + (e.fast ? "fast" : "compact") + "\"";
  return o + ", \"notes\": " + json_notes(notes) + "}";
}

// --------------------------------------------------------------------- info

namespace {

class TeeSource : public MeshSource {
 public:
  TeeSource(MeshSource* in, MeshSink* side) : in_(in), side_(side) {}
  const MeshSchema& schema() const override { return in_->schema(); }
  const SourceReport& report() const override { return in_->report(); }
  Status next(MeshItem* item) override {
    if (!started_) {
      started_ = true;
      PSQ_RETURN_IF_ERROR(side_->begin(in_->schema()));
    }
    PSQ_RETURN_IF_ERROR(in_->next(item));
    switch (item->kind) {
      case MeshItem::Kind::kVertex: return side_->vertex(item->position, item->values);
      case MeshItem::Kind::kTriangle: return side_->triangle(item->index, item->values);
      case MeshItem::Kind::kEnd: return side_->finish();
    }
    return Status();
  }

 private:
  MeshSource* in_;
  MeshSink* side_;
  bool started_ = false;
};

class PsqInfoSink : public SequenceSink {
 public:
  Status begin(const MeshSchema& s) override { return counter.begin(s); }
  Status vertex(const SequenceVertex& v) override {
    if (vertices_++ == 0)
      for (int k = 0; k < 3; ++k) bbox_min[k] = bbox_max[k] = v.position[k];
    for (int k = 0; k < 3; ++k) {
      bbox_min[k] = std::min(bbox_min[k], v.position[k]);
      bbox_max[k] = std::max(bbox_max[k], v.position[k]);
    }
    return counter.vertex(v);
  }
  Status triangle(const SequenceTriangle& t) override { return counter.triangle(t); }
  Status finalize(uint32_t i) override { return counter.finalize(i); }
  Status finish() override { return counter.finish(); }
  SequenceCounter counter;
  double bbox_min[3] = {0, 0, 0}, bbox_max[3] = {0, 0, 0};

 private:
  uint64_t vertices_ = 0;
};

std::string json_props(const std::vector<Property>& props) {
  std::string s = "[";
  for (size_t i = 0; i < props.size(); ++i) {
    const Property& pr = props[i];
    if (i) s += ", ";
    s += "{\"name\": " + q(pr.name) + ", \"type\": \"" + scalar_name(pr.type) + "\"";
    if (pr.is_list) s += std::string(", \"list\": true, \"count_type\": \"") + scalar_name(pr.count_type) + "\"";
    s += "}";
  }
  return s + "]";
}

std::string json_box(const double* lo, const double* hi) {
  return "{\"min\": [" + json_number(lo[0]) + ", " + json_number(lo[1]) + ", " + json_number(lo[2]) + "], \"max\": [" +
         json_number(hi[0]) + ", " + json_number(hi[1]) + ", " + json_number(hi[2]) + "]}";
}

}  // namespace

std::string info(const std::string& path, const InfoParams& p) {
  OpenOptions oo;
  oo.spool_dir = p.tmpdir;
  OpenedMesh mesh;
  open_input(path, oo, &mesh);
  BuildOptions build;
  build.tmpdir = p.tmpdir;
  build.memory_budget = p.memory;
  PsqInfoSink psq_sink;
  MeshStats stats;
  SequenceChecker checker;
  BuildReport br;
  const SequenceStats* qs = nullptr;
  MeshSchema schema;
  uint64_t vertices, triangles, unreferenced, degenerate, border, nm_vertices, nm_edges, misoriented;
  const double *lo, *hi;
  if (mesh.decoder) {
    mesh.decoder->measure_costs(true);
    check(mesh.decoder->pump(psq_sink), path);
    qs = &psq_sink.counter.stats();
    schema = mesh.decoder->schema();
    vertices = qs->vertices;
    triangles = qs->triangles;
    unreferenced = qs->unreferenced_vertices;
    degenerate = qs->degenerate_triangles;
    lo = psq_sink.bbox_min;
    hi = psq_sink.bbox_max;
    border = qs->mesh_border_edges;
    nm_vertices = qs->nonmanifold_vertices;
    nm_edges = qs->mesh_nonmanifold_edges;
    misoriented = qs->mesh_misoriented_edges;
  } else {
    TeeSource tee(mesh.source.get(), &stats);
    check(build_sequence(tee, checker, build, &br), path);
    const MeshStatsResult& m = stats.result();
    qs = &checker.stats();
    schema = m.schema;
    vertices = m.vertices;
    triangles = m.triangles;
    unreferenced = m.unreferenced_vertices;
    degenerate = m.degenerate_triangles;
    lo = m.bbox_min;
    hi = m.bbox_max;
    border = br.converter.border_edges;
    nm_vertices = br.converter.nonmanifold_vertices;
    nm_edges = br.converter.nonmanifold_edges;
    misoriented = br.converter.misoriented_edges;
  }
  const SequenceStats& s = *qs;
  const SourceReport& rep = mesh.source->report();
  std::string o = "{\"file\": " + q(path) + ", \"format\": \"" + format_name(mesh.format) + "\"";
  o += ", \"vertices\": " + n(vertices) + ", \"triangles\": " + n(triangles) +
       ", \"unreferenced_vertices\": " + n(unreferenced) + ", \"degenerate_triangles\": " + n(degenerate) +
       ", \"polygons_triangulated\": " + n(rep.polygons_triangulated) + ", \"strip_triangles\": " +
       n(rep.strip_triangles) + ", \"position_type\": \"" + scalar_name(schema.position_type) + "\"" +
       ", \"bbox\": " + json_box(lo, hi) + ", \"components\": " + n(s.components) + ", \"border_edges\": " + n(border) +
       ", \"border_loops\": " + n(s.border_loops) + ", \"handles\": " + std::to_string(s.handles) +
       ", \"nonmanifold_vertices\": " + n(nm_vertices) + ", \"nonmanifold_edges\": " + n(nm_edges) +
       ", \"misoriented_edges\": " + n(misoriented) + ", \"reappearances\": " + n(s.reappearances) +
       ", \"max_boundary_vertices\": " + n(s.max_boundary_vertices) +
       ", \"max_boundary_edges\": " + n(s.max_boundary_edges) + ", \"ops\": {\"start\": " + n(s.ops[0]) +
       ", \"add\": " + n(s.ops[1]) + ", \"join\": " + n(s.ops[2]) + ", \"fill\": " + n(s.ops[3]) +
       ", \"end\": " + n(s.ops[4]) + "}";
  if (mesh.decoder) {
    o += ", \"sequence_order\": \"file\"";
  } else {
    o += std::string(", \"sequence_order\": \"") + (br.sorted ? "sorted" : "coherent") + "\"";
    o += ", \"coherence_window\": " + n(br.window) +
         ", \"max_waiting_triangles\": " + n(br.converter.max_waiting_triangles) +
         ", \"max_waiting_vertices\": " + n(br.converter.max_waiting_vertices);
  }
  o += ", \"vertex_properties\": " + json_props(schema.vertex_properties) +
       ", \"face_properties\": " + json_props(schema.face_properties);
  if (mesh.decoder) {
    const PsqHeader& h = mesh.decoder->header();
    const PsqStats& st = mesh.decoder->stats();
    const double nv = st.vertices ? static_cast<double>(st.vertices) : 1.0;
    o += ", \"psq\": {\"version\": \"" + std::to_string(h.version_major) + "." + std::to_string(h.version_minor) +
         "\", \"profile\": \"" + (h.fast ? "fast" : "compact") + "\", \"lossless\": " + (h.lossless ? "true" : "false") +
         ", \"bits\": " + std::to_string(h.bits) + ", \"step\": " + json_number(h.step) + ", \"chunks\": " +
         n(st.chunks) + ", \"bytes\": " + n(st.total_bytes) + ", \"sequence_vertices\": " + n(st.vertices) +
         ", \"bits_per_vertex\": " + json_number(8.0 * st.total_bytes / nv) +
         ", \"connectivity_bits_per_vertex\": " + json_number(st.connectivity_bits / nv) +
         ", \"geometry_bits_per_vertex\": " + json_number(st.geometry_bits / nv) +
         ", \"property_bits_per_vertex\": " + json_number(8.0 * st.property_bytes / nv) +
         ", \"overhead_bits_per_vertex\": " + json_number(8.0 * (st.header_bytes + st.chunk_overhead_bytes) / nv) +
         ", \"gates\": {\"offset_0\": " + n(st.gates[0]) + ", \"offset\": " + n(st.gates[1]) +
         ", \"far_rank\": " + n(st.far_gates[0]) + ", \"far_resume\": " + n(st.far_gates[1]) +
         ", \"far_raw\": " + n(st.far_gates[2]) + ", \"start_or_isolated\": " + n(st.gates[3]) +
         "}, \"add_predictions\": {\"gate\": " + n(st.predictions[0]) + ", \"before\": " + n(st.predictions[1]) +
         ", \"after\": " + n(st.predictions[2]) + ", \"mean_before\": " + n(st.predictions[3]) +
         ", \"mean_after\": " + n(st.predictions[4]) + "}}";
  }
  return o + ", \"notes\": " + json_notes(rep.notes) + "}";
}

// ----------------------------------------------------------------- distance

namespace {

uint64_t estimated_triangles(const OpenedMesh& m) {
  const int64_t t = m.source->schema().triangle_count;
  if (t >= 0) return static_cast<uint64_t>(t);
  const int64_t size = m.stream->size();
  if (size >= 0) return static_cast<uint64_t>(size) / 25;
  return UINT64_MAX;
}

std::string json_stats(const DirectionDistance& d, double div, bool counts) {
  std::string s = "{";
  if (counts) s += "\"samples\": " + n(d.samples) + ", \"vertex_samples\": " + n(d.vertex_samples) + ", ";
  return s + "\"max\": " + json_number(d.max / div) + ", \"mean\": " + json_number(d.mean / div) +
         ", \"rms\": " + json_number(d.rms / div) + "}";
}

std::string json_mesh(const std::string& file, const MeshDistanceSummary& m) {
  return "{\"file\": " + q(file) + ", \"vertices\": " + n(m.vertices) + ", \"used_vertices\": " + n(m.used_vertices) +
         ", \"triangles\": " + n(m.triangles) + ", \"area\": " + json_number(m.area) +
         ", \"held\": " + (m.held ? "true" : "false") + "}";
}

}  // namespace

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
  if (options.hold == DistanceHold::kAuto) {
    const uint64_t ta = estimated_triangles(a), tb = estimated_triangles(b);
    if (std::max(ta, tb) <= kAutoInMemoryTriangles) options.hold = DistanceHold::kBoth;
    else options.hold = ta < tb ? DistanceHold::kA : DistanceHold::kB;
  }
  DistanceResult r;
  Status s = measure_distance(*a.source, *b.source, options, &r);
  if (!s.ok()) throw StatusError(s, r.error_input == 1 ? a_path : r.error_input == 2 ? b_path : "temporary file");
  DirectionDistance sym;
  sym.max = r.hausdorff;
  sym.mean = std::max(r.a_to_b.mean, r.b_to_a.mean);
  sym.rms = std::max(r.a_to_b.rms, r.b_to_a.rms);
  const uint64_t total = r.a_to_b.samples + r.b_to_a.samples;
  const double rate = r.seconds > 0 ? static_cast<double>(total) / r.seconds : 0;
  const int threads = options.threads > 0 ? options.threads
                                          : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  const double diag = r.diagonal > 0 ? r.diagonal : std::nan("");
  return "{\"a\": " + json_mesh(a_path, r.a) + ", \"b\": " + json_mesh(b_path, r.b) + ", \"seed\": " + n(options.seed) +
         ", \"a_to_b\": " + json_stats(r.a_to_b, 1, true) + ", \"b_to_a\": " + json_stats(r.b_to_a, 1, true) +
         ", \"hausdorff\": " + json_number(r.hausdorff) + ", \"symmetric\": " + json_stats(sym, 1, false) +
         ", \"diagonal\": " + json_number(r.diagonal) + ", \"relative\": {\"a_to_b\": " +
         json_stats(r.a_to_b, diag, false) + ", \"b_to_a\": " + json_stats(r.b_to_a, diag, false) +
         ", \"hausdorff\": " + json_number(r.hausdorff / diag) + ", \"symmetric\": " + json_stats(sym, diag, false) +
         "}, \"timing\": {\"seconds\": " + json_number(r.seconds) + ", \"samples_per_second\": " + json_number(rate) +
         ", \"threads\": " + std::to_string(threads) + "}}";
}

}  // namespace psq::python
