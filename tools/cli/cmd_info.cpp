// SPDX-License-Identifier: Apache-2.0
// psq info: what a mesh holds, counted in one streaming pass.
#include <algorithm>
#include <cstdio>
#include <string>

#include "cli_util.h"
#include "commands.h"
#include "progress.h"
#include "psq/mesh_formats.h"
#include "psq/mesh_stats.h"
#include "psq/sequence_builder.h"
#include "psq/sequence_check.h"
#include "psq/sequence_count.h"

namespace psq::cli {
namespace {

const char kHelp[] =
    "Usage: psq info FILE [--json]\n"
    "\n"
    "Reads FILE (PLY, OBJ, OFF, STL or .psq, recognised by content; '-' for\n"
    "standard input) and prints its vertex and triangle counts, properties,\n"
    "bounding box, unreferenced vertices, degenerate triangles (a repeated\n"
    "vertex index), border, non-manifold and misoriented edges and\n"
    "non-manifold vertices, and, from its processing sequence (paper\n"
    "Table 1): components, border loops (holes), handles (genus), the\n"
    "vertices that re-appear, the ops and the longest processing boundary\n"
    "(most vertices and edges active at once).\n"
    "\n"
    "For a .psq, the sequence figures (ops, re-appearances, the longest\n"
    "boundary, and handles, counted where the file cuts non-manifold input)\n"
    "are the file's own: counted as it is decoded, in the decoder's memory,\n"
    "nothing rebuilt. The mesh figures are those of the mesh the file holds,\n"
    "with each re-appearing vertex merged into its first occurrence, so that\n"
    "they agree with those of the same mesh in PLY (but for degenerate\n"
    "triangles, which psq convert drops). A .psq also gives its format version,\n"
    "quantization, size and bits per vertex split into connectivity,\n"
    "geometry, properties and framing. Any other input is turned into the\n"
    "processing sequence psq convert would build (spooled, and sorted when\n"
    "its order is not coherent; --memory, --tmpdir).\n"
    "\n"
    "Options:\n"
    "  --json         print one JSON object instead of text\n"
    "  -q, --quiet    no progress line\n"
    "  --memory SIZE  memory budget for the external sort (default 512M)\n"
    "  --tmpdir DIR   directory for temporary files (default $TMPDIR)\n"
    "  -h, --help     show this help\n"
    "\n"
    "While it reads, a progress line goes to stderr when that is a terminal.\n";

// Passes every item of a source on, and shows it to a sink on the way.
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

// A .psq's sequence as decoded: counted (SequenceCounter), its bounding box
// taken, and its triangles shown to the progress line.
class PsqInfoSink : public SequenceSink {
 public:
  explicit PsqInfoSink(Progress* progress) : progress_(progress) {}
  Status begin(const MeshSchema& s) override { return counter.begin(s); }
  Status vertex(const SequenceVertex& v) override {
    if (vertices_++ == 0) {
      for (int k = 0; k < 3; ++k) bbox_min[k] = bbox_max[k] = v.position[k];
    }
    for (int k = 0; k < 3; ++k) {
      bbox_min[k] = std::min(bbox_min[k], v.position[k]);
      bbox_max[k] = std::max(bbox_max[k], v.position[k]);
    }
    return counter.vertex(v);
  }
  Status triangle(const SequenceTriangle& t) override {
    progress_->written();
    return counter.triangle(t);
  }
  Status finalize(uint32_t i) override { return counter.finalize(i); }
  Status finish() override { return counter.finish(); }

  SequenceCounter counter;
  double bbox_min[3] = {0, 0, 0}, bbox_max[3] = {0, 0, 0};

 private:
  Progress* progress_;
  uint64_t vertices_ = 0;
};

// What info prints, from either path.
struct Report {
  MeshSchema schema;
  uint64_t vertices = 0, triangles = 0, unreferenced = 0, degenerate = 0;
  const double* bbox_min = nullptr;
  const double* bbox_max = nullptr;
  uint64_t border_edges = 0, nonmanifold_vertices = 0, nonmanifold_edges = 0, misoriented_edges = 0;
  const SequenceStats* sequence = nullptr;  // components, loops, handles, ops, boundary
  bool from_file = false;                   // the .psq's own sequence
  const BuildReport* build = nullptr;       // else the sequence built from the input
};

std::string type_list(const std::vector<Property>& props) {
  std::string s;
  for (const Property& p : props) {
    if (!s.empty()) s += ' ';
    s += p.name + ":" + (p.is_list ? "list<" + std::string(scalar_name(p.type)) + ">" : std::string(scalar_name(p.type)));
  }
  return s.empty() ? "none" : s;
}

std::string json_props(const std::vector<Property>& props) {
  std::string s = "[";
  for (size_t i = 0; i < props.size(); ++i) {
    const Property& p = props[i];
    if (i) s += ", ";
    s += "{\"name\": \"" + json_escape(p.name) + "\", \"type\": \"" + scalar_name(p.type) + "\"";
    if (p.is_list) s += std::string(", \"list\": true, \"count_type\": \"") + scalar_name(p.count_type) + "\"";
    s += "}";
  }
  return s + "]";
}

// The header's coded attributes (spec 8.3), as "normals (nx ny nz)
// quantized, 8-bit octahedral; ...": what a quantized stream changed beyond
// the positions.
std::string attribute_text(const PsqHeader& h) {
  std::string o;
  for (const CodedAttribute& a : h.attributes) {
    if (!o.empty()) o += "; ";
    o += a.kind == CodedAttribute::Kind::kNormal     ? "normals ("
         : a.kind == CodedAttribute::Kind::kTexcoord ? "texture coordinates ("
                                                     : "colours (";
    for (size_t i = 0; i < a.properties.size(); ++i)
      o += (i ? " " : "") + h.schema.vertex_properties[a.properties[i]].name;
    o += a.kind == CodedAttribute::Kind::kNormal     ? ") quantized, " + std::to_string(a.bits) + "-bit octahedral"
         : a.kind == CodedAttribute::Kind::kTexcoord ? ") quantized to steps of 2^-" + std::to_string(a.bits)
                                                     : std::string(") exact");
  }
  return o.empty() ? "none" : o;
}

std::string attribute_json(const PsqHeader& h) {
  std::string o = "[";
  for (const CodedAttribute& a : h.attributes) {
    if (o.size() > 1) o += ", ";
    o += std::string("{\"kind\": \"") +
         (a.kind == CodedAttribute::Kind::kNormal     ? "normal"
          : a.kind == CodedAttribute::Kind::kTexcoord ? "texcoord"
                                                      : "color") +
         "\", \"bits\": " + std::to_string(a.bits) + ", \"properties\": [";
    for (size_t i = 0; i < a.properties.size(); ++i)
      o += (i ? ", \"" : "\"") + json_escape(h.schema.vertex_properties[a.properties[i]].name) + "\"";
    o += "]}";
  }
  return o + "]";
}

void print_json(const std::string& file, const OpenedMesh& mesh, const SourceReport& rep, const Report& r) {
  const SequenceStats& q = *r.sequence;
  auto n = [](uint64_t v) { return std::to_string(v); };
  std::string o = "{\n";
  o += "  \"file\": \"" + json_escape(file) + "\",\n";
  o += std::string("  \"format\": \"") + format_name(mesh.format) + "\",\n";
  o += "  \"vertices\": " + n(r.vertices) + ",\n";
  o += "  \"triangles\": " + n(r.triangles) + ",\n";
  o += "  \"unreferenced_vertices\": " + n(r.unreferenced) + ",\n";
  o += "  \"degenerate_triangles\": " + n(r.degenerate) + ",\n";
  o += "  \"polygons_triangulated\": " + n(rep.polygons_triangulated) + ",\n";
  o += "  \"strip_triangles\": " + n(rep.strip_triangles) + ",\n";
  o += std::string("  \"position_type\": \"") + scalar_name(r.schema.position_type) + "\",\n";
  o += "  \"bbox\": {\"min\": [" + json_number(r.bbox_min[0]) + ", " + json_number(r.bbox_min[1]) + ", " +
       json_number(r.bbox_min[2]) + "], \"max\": [" + json_number(r.bbox_max[0]) + ", " + json_number(r.bbox_max[1]) +
       ", " + json_number(r.bbox_max[2]) + "]},\n";
  o += "  \"components\": " + n(q.components) + ",\n";
  o += "  \"border_edges\": " + n(r.border_edges) + ",\n";
  o += "  \"border_loops\": " + n(q.border_loops) + ",\n";
  o += "  \"handles\": " + std::to_string(q.handles) + ",\n";
  o += "  \"nonmanifold_vertices\": " + n(r.nonmanifold_vertices) + ",\n";
  o += "  \"nonmanifold_edges\": " + n(r.nonmanifold_edges) + ",\n";
  o += "  \"misoriented_edges\": " + n(r.misoriented_edges) + ",\n";
  o += "  \"reappearances\": " + n(q.reappearances) + ",\n";
  o += "  \"max_boundary_vertices\": " + n(q.max_boundary_vertices) + ",\n";
  o += "  \"max_boundary_edges\": " + n(q.max_boundary_edges) + ",\n";
  o += "  \"ops\": {\"start\": " + n(q.ops[0]) + ", \"add\": " + n(q.ops[1]) + ", \"join\": " + n(q.ops[2]) +
       ", \"fill\": " + n(q.ops[3]) + ", \"end\": " + n(q.ops[4]) + "},\n";
  if (r.from_file) {
    o += "  \"sequence_order\": \"file\",\n";
  } else {
    const BuildReport& b = *r.build;
    o += std::string("  \"sequence_order\": \"") + (b.sorted ? "sorted" : "coherent") + "\",\n";
    o += "  \"coherence_window\": " + n(b.window) + ",\n";
    o += "  \"max_waiting_triangles\": " + n(b.converter.max_waiting_triangles) + ",\n";
    o += "  \"max_waiting_vertices\": " + n(b.converter.max_waiting_vertices) + ",\n";
  }
  o += "  \"vertex_properties\": " + json_props(r.schema.vertex_properties) + ",\n";
  o += "  \"face_properties\": " + json_props(r.schema.face_properties) + ",\n";
  if (mesh.decoder) {
    const PsqHeader& h = mesh.decoder->header();
    const PsqStats& p = mesh.decoder->stats();
    const double nv = p.vertices ? static_cast<double>(p.vertices) : 1.0;
    o += "  \"psq\": {\"version\": \"" + std::to_string(h.version_major) + "." + std::to_string(h.version_minor) +
         "\", \"profile\": \"" + (h.fast ? "fast" : "compact") + "\", \"lossless\": " + (h.lossless ? "true" : "false") +
         ", \"bits\": " + std::to_string(h.bits) + ", \"step\": " + json_number(h.step) + ", \"chunks\": " + n(p.chunks) +
         ", \"bytes\": " + n(p.total_bytes) + ", \"sequence_vertices\": " + n(p.vertices) +
         ", \"bits_per_vertex\": " + json_number(8.0 * p.total_bytes / nv) +
         ", \"connectivity_bits_per_vertex\": " + json_number(p.connectivity_bits / nv) +
         ", \"geometry_bits_per_vertex\": " + json_number(p.geometry_bits / nv) +
         ", \"property_bits_per_vertex\": " + json_number(8.0 * p.property_bytes / nv) +
         ", \"attribute_bits_per_vertex\": " + json_number(8.0 * p.attribute_bytes / nv) +
         ", \"attributes\": " + attribute_json(h) +
         ", \"overhead_bits_per_vertex\": " + json_number(8.0 * (p.header_bytes + p.chunk_overhead_bytes) / nv) +
         ", \"gates\": {\"offset_0\": " + n(p.gates[0]) + ", \"offset\": " + n(p.gates[1]) +
         ", \"far_rank\": " + n(p.far_gates[0]) + ", \"far_resume\": " + n(p.far_gates[1]) +
         ", \"far_raw\": " + n(p.far_gates[2]) + ", \"start_or_isolated\": " + n(p.gates[3]) +
         "}, \"add_predictions\": {\"gate\": " + n(p.predictions[0]) + ", \"before\": " + n(p.predictions[1]) +
         ", \"after\": " + n(p.predictions[2]) + ", \"mean_before\": " + n(p.predictions[3]) +
         ", \"mean_after\": " + n(p.predictions[4]) + "}},\n";
  }
  o += "  \"notes\": [";
  for (size_t i = 0; i < rep.notes.size(); ++i) o += (i ? ", \"" : "\"") + json_escape(rep.notes[i]) + "\"";
  o += "]\n}\n";
  std::fputs(o.c_str(), stdout);
}

void print_text(const std::string& file, const OpenedMesh& mesh, const SourceReport& rep, const Report& r) {
  const SequenceStats& q = *r.sequence;
  auto u = [](uint64_t v) { return static_cast<unsigned long long>(v); };
  std::printf("file                   %s\n", file.c_str());
  std::printf("format                 %s\n", format_name(mesh.format));
  std::printf("vertices               %llu\n", u(r.vertices));
  std::printf("triangles              %llu\n", u(r.triangles));
  std::printf("unreferenced vertices  %llu\n", u(r.unreferenced));
  std::printf("degenerate triangles   %llu\n", u(r.degenerate));
  if (rep.polygons_triangulated != 0) std::printf("polygons triangulated  %llu\n", u(rep.polygons_triangulated));
  if (rep.strip_triangles != 0) std::printf("strip triangles        %llu\n", u(rep.strip_triangles));
  std::printf("position type          %s\n", scalar_name(r.schema.position_type));
  std::printf("bounding box           [%.9g %.9g %.9g] .. [%.9g %.9g %.9g]\n", r.bbox_min[0], r.bbox_min[1],
              r.bbox_min[2], r.bbox_max[0], r.bbox_max[1], r.bbox_max[2]);
  std::printf("components             %llu\n", u(q.components));
  std::printf("border edges           %llu\n", u(r.border_edges));
  std::printf("border loops           %llu\n", u(q.border_loops));
  std::printf("handles                %lld\n", static_cast<long long>(q.handles));
  std::printf("non-manifold vertices  %llu (%llu re-appearances)\n", u(r.nonmanifold_vertices), u(q.reappearances));
  std::printf("non-manifold edges     %llu\n", u(r.nonmanifold_edges));
  std::printf("misoriented edges      %llu\n", u(r.misoriented_edges));
  std::printf("max boundary           %llu vertices, %llu edges\n", u(q.max_boundary_vertices), u(q.max_boundary_edges));
  std::printf("ops                    start %llu, add %llu, join %llu, fill %llu, end %llu\n", u(q.ops[0]), u(q.ops[1]),
              u(q.ops[2]), u(q.ops[3]), u(q.ops[4]));
  if (r.from_file) std::printf("sequence order         the file's own sequence\n");
  else std::printf("sequence order         %s\n", r.build->sorted ? "sorted (external sort)" : "coherent (file order)");
  std::printf("vertex properties      %s\n", type_list(r.schema.vertex_properties).c_str());
  std::printf("face properties        %s\n", type_list(r.schema.face_properties).c_str());
  if (mesh.decoder) {
    const PsqHeader& h = mesh.decoder->header();
    const PsqStats& p = mesh.decoder->stats();
    const double nv = p.vertices ? static_cast<double>(p.vertices) : 1.0;
    std::printf("psq version            %d.%d, %s profile\n", h.version_major, h.version_minor, h.fast ? "fast" : "compact");
    if (h.lossless) std::printf("positions              lossless\n");
    else std::printf("positions              quantized to %d bits (step %.9g)\n", h.bits, h.step);
    std::printf("coded attributes       %s\n", attribute_text(h).c_str());
    std::printf("size                   %llu bytes in %llu chunks, %.3f bits/vertex\n", u(p.total_bytes), u(p.chunks),
                8.0 * p.total_bytes / nv);
    std::printf("  connectivity         %.3f bits/vertex\n", p.connectivity_bits / nv);
    std::printf("  geometry             %.3f bits/vertex\n", p.geometry_bits / nv);
    std::printf("  properties           %.3f bits/vertex\n", 8.0 * p.property_bytes / nv);
    std::printf("  attributes           %.3f bits/vertex\n", 8.0 * p.attribute_bytes / nv);
    std::printf("  framing              %.3f bits/vertex\n", 8.0 * (p.header_bytes + p.chunk_overhead_bytes) / nv);
    std::printf("gates                  offset 0 %llu, offset %llu, far %llu (rank %llu, resume %llu, raw %llu), "
                "start or isolated %llu\n",
                u(p.gates[0]), u(p.gates[1]), u(p.gates[2]), u(p.far_gates[0]), u(p.far_gates[1]), u(p.far_gates[2]),
                u(p.gates[3]));
    std::printf("add predictions        across the gate %llu, the edge before %llu, the edge after %llu, "
                "mean with before %llu, mean with after %llu\n",
                u(p.predictions[0]), u(p.predictions[1]), u(p.predictions[2]), u(p.predictions[3]), u(p.predictions[4]));
  }
  for (const std::string& s : rep.notes) std::printf("note                   %s\n", s.c_str());
}

}  // namespace

int cmd_info(int argc, char** argv) {
  Args args(argc, argv, 1);
  if (args.flag("--help", "-h")) {
    std::fputs(kHelp, stdout);
    return kExitOk;
  }
  bool json = args.flag("--json");
  bool quiet = args.flag("--quiet", "-q");
  std::string memory = args.option("--memory", "512M");
  BuildOptions build_options;
  build_options.tmpdir = args.option("--tmpdir");
  std::vector<std::string> files = args.positionals();
  if (!args.error().empty()) return usage_error("info", args.error());
  if (!parse_size(memory, &build_options.memory_budget)) {
    return usage_error("info", "bad --memory '" + memory + "' (e.g. 256M, 2G)");
  }
  if (files.size() != 1) return usage_error("info", files.empty() ? "missing FILE" : "info takes one FILE");
  const std::string& file = files[0];

  OpenedMesh mesh;
  OpenOptions open_options;
  open_options.spool_dir = build_options.tmpdir;
  Status s = open_mesh(file, open_options, &mesh);
  if (!s.ok()) return report_error(file, s);
  Progress progress(mesh.stream.get(), !quiet);
  Report r;
  // Kept alive until the report is printed (r points into them).
  PsqInfoSink psq_sink(&progress);
  MeshStats stats;
  SequenceChecker checker;
  BuildReport build;
  if (mesh.decoder) {
    // The file's own sequence, counted as it is decoded: the decoder's
    // memory, nothing rebuilt.
    mesh.decoder->measure_costs(true);
    s = mesh.decoder->pump(psq_sink);
    if (!s.ok()) return report_error(file, s);
    const SequenceStats& q = psq_sink.counter.stats();
    r.schema = mesh.decoder->schema();
    r.vertices = q.vertices;
    r.triangles = q.triangles;
    r.unreferenced = q.unreferenced_vertices;
    r.degenerate = q.degenerate_triangles;
    r.bbox_min = psq_sink.bbox_min;
    r.bbox_max = psq_sink.bbox_max;
    r.border_edges = q.mesh_border_edges;
    r.nonmanifold_vertices = q.nonmanifold_vertices;
    r.nonmanifold_edges = q.mesh_nonmanifold_edges;
    r.misoriented_edges = q.mesh_misoriented_edges;
    r.sequence = &q;
    r.from_file = true;
  } else {
    TeeSource tee(mesh.source.get(), &stats);
    ProgressSource source(&tee, &progress);
    ProgressSequenceSink sink(&checker, &progress);
    s = build_sequence(source, sink, build_options, &build);
    if (!s.ok()) return report_error(file, s);
    const MeshStatsResult& m = stats.result();
    const ConverterStats& c = build.converter;
    r.schema = m.schema;
    r.vertices = m.vertices;
    r.triangles = m.triangles;
    r.unreferenced = m.unreferenced_vertices;
    r.degenerate = m.degenerate_triangles;
    r.bbox_min = m.bbox_min;
    r.bbox_max = m.bbox_max;
    r.border_edges = c.border_edges;
    r.nonmanifold_vertices = c.nonmanifold_vertices;
    r.nonmanifold_edges = c.nonmanifold_edges;
    r.misoriented_edges = c.misoriented_edges;
    r.sequence = &checker.stats();
    r.build = &build;
  }
  progress.clear();
  const SourceReport& rep = mesh.source->report();
  if (json) print_json(file, mesh, rep, r);
  else print_text(file, mesh, rep, r);
  std::fflush(stdout);
  if (r.degenerate != 0) {
    warn(file, std::to_string(r.degenerate) + " degenerate triangle(s) repeat a vertex index");
  }
  return kExitOk;
}

}  // namespace psq::cli
