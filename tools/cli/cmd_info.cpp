// psq info: what a mesh holds, counted in one streaming pass.
#include <cstdio>
#include <string>

#include "cli_util.h"
#include "commands.h"
#include "psq/mesh_formats.h"
#include "psq/mesh_stats.h"
#include "psq/sequence_builder.h"
#include "psq/sequence_check.h"

namespace psq::cli {
namespace {

const char kHelp[] =
    "Usage: psq info FILE [--json]\n"
    "\n"
    "Reads FILE (PLY, OBJ, OFF, STL or .psq, recognised by content; '-' for\n"
    "standard input) and prints its vertex and triangle counts, properties, bounding box,\n"
    "unreferenced vertices and degenerate triangles (a repeated vertex\n"
    "index), and, from its processing sequence (paper Table 1): components,\n"
    "border loops (holes), handles (genus), non-manifold vertices and edges,\n"
    "and the longest processing boundary (most vertices active at once).\n"
    "For .psq: the format version, quantization, size and bits per vertex\n"
    "split into connectivity, geometry, properties and framing.\n"
    "\n"
    "Options:\n"
    "  --json         print one JSON object instead of text\n"
    "  --memory SIZE  memory budget for the external sort (default 512M)\n"
    "  --tmpdir DIR   directory for temporary files (default $TMPDIR)\n"
    "  -h, --help     show this help\n";

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

}  // namespace

int cmd_info(int argc, char** argv) {
  Args args(argc, argv, 1);
  if (args.flag("--help", "-h")) {
    std::fputs(kHelp, stdout);
    return kExitOk;
  }
  bool json = args.flag("--json");
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
  if (mesh.decoder) mesh.decoder->measure_costs(true);
  MeshStats stats;
  TeeSource tee(mesh.source.get(), &stats);
  SequenceChecker checker;
  BuildReport build;
  s = build_sequence(tee, checker, build_options, &build);
  if (!s.ok()) return report_error(file, s);
  const MeshStatsResult& r = stats.result();
  const SourceReport& rep = mesh.source->report();
  const SequenceStats& q = checker.stats();
  const ConverterStats& c = build.converter;

  if (json) {
    std::string o = "{\n";
    o += "  \"file\": \"" + json_escape(file) + "\",\n";
    o += std::string("  \"format\": \"") + format_name(mesh.format) + "\",\n";
    o += "  \"vertices\": " + std::to_string(r.vertices) + ",\n";
    o += "  \"triangles\": " + std::to_string(r.triangles) + ",\n";
    o += "  \"unreferenced_vertices\": " + std::to_string(r.unreferenced_vertices) + ",\n";
    o += "  \"degenerate_triangles\": " + std::to_string(r.degenerate_triangles) + ",\n";
    o += "  \"polygons_triangulated\": " + std::to_string(rep.polygons_triangulated) + ",\n";
    o += "  \"strip_triangles\": " + std::to_string(rep.strip_triangles) + ",\n";
    o += std::string("  \"position_type\": \"") + scalar_name(r.schema.position_type) + "\",\n";
    o += "  \"bbox\": {\"min\": [" + json_number(r.bbox_min[0]) + ", " + json_number(r.bbox_min[1]) + ", " +
         json_number(r.bbox_min[2]) + "], \"max\": [" + json_number(r.bbox_max[0]) + ", " +
         json_number(r.bbox_max[1]) + ", " + json_number(r.bbox_max[2]) + "]},\n";
    o += "  \"components\": " + std::to_string(q.components) + ",\n";
    o += "  \"border_edges\": " + std::to_string(c.border_edges) + ",\n";
    o += "  \"border_loops\": " + std::to_string(q.border_loops) + ",\n";
    o += "  \"handles\": " + std::to_string(q.handles) + ",\n";
    o += "  \"nonmanifold_vertices\": " + std::to_string(c.nonmanifold_vertices) + ",\n";
    o += "  \"nonmanifold_edges\": " + std::to_string(c.nonmanifold_edges) + ",\n";
    o += "  \"misoriented_edges\": " + std::to_string(c.misoriented_edges) + ",\n";
    o += "  \"reappearances\": " + std::to_string(q.reappearances) + ",\n";
    o += "  \"max_boundary_vertices\": " + std::to_string(q.max_boundary_vertices) + ",\n";
    o += "  \"max_boundary_edges\": " + std::to_string(q.max_boundary_edges) + ",\n";
    o += "  \"ops\": {\"start\": " + std::to_string(q.ops[0]) + ", \"add\": " + std::to_string(q.ops[1]) +
         ", \"join\": " + std::to_string(q.ops[2]) + ", \"fill\": " + std::to_string(q.ops[3]) +
         ", \"end\": " + std::to_string(q.ops[4]) + "},\n";
    o += std::string("  \"sequence_order\": \"") + (build.sorted ? "sorted" : "coherent") + "\",\n";
    o += "  \"coherence_window\": " + std::to_string(build.window) + ",\n";
    o += "  \"max_waiting_triangles\": " + std::to_string(c.max_waiting_triangles) + ",\n";
    o += "  \"max_waiting_vertices\": " + std::to_string(c.max_waiting_vertices) + ",\n";
    o += "  \"vertex_properties\": " + json_props(r.schema.vertex_properties) + ",\n";
    o += "  \"face_properties\": " + json_props(r.schema.face_properties) + ",\n";
    if (mesh.decoder) {
      const PsqHeader& h = mesh.decoder->header();
      const PsqStats& p = mesh.decoder->stats();
      const double nv = p.vertices ? static_cast<double>(p.vertices) : 1.0;
      o += "  \"psq\": {\"version\": \"" + std::to_string(h.version_major) + "." + std::to_string(h.version_minor) +
           "\", \"profile\": \"" + (h.fast ? "fast" : "compact") + "\", \"lossless\": " + (h.lossless ? "true" : "false") + ", \"bits\": " + std::to_string(h.bits) +
           ", \"step\": " + json_number(h.step) + ", \"chunks\": " + std::to_string(p.chunks) +
           ", \"bytes\": " + std::to_string(p.total_bytes) + ", \"sequence_vertices\": " + std::to_string(p.vertices) +
           ", \"bits_per_vertex\": " + json_number(8.0 * p.total_bytes / nv) +
           ", \"connectivity_bits_per_vertex\": " + json_number(p.connectivity_bits / nv) +
           ", \"geometry_bits_per_vertex\": " + json_number(p.geometry_bits / nv) +
           ", \"property_bits_per_vertex\": " + json_number(8.0 * p.property_bytes / nv) +
           ", \"overhead_bits_per_vertex\": " + json_number(8.0 * (p.header_bytes + p.chunk_overhead_bytes) / nv) +
           ", \"gates\": {\"offset_0\": " + std::to_string(p.gates[0]) + ", \"offset\": " + std::to_string(p.gates[1]) +
           ", \"far_rank\": " + std::to_string(p.far_gates[0]) + ", \"far_resume\": " + std::to_string(p.far_gates[1]) +
           ", \"far_raw\": " + std::to_string(p.far_gates[2]) + ", \"start_or_isolated\": " + std::to_string(p.gates[3]) +
           "}, \"add_predictions\": {\"gate\": " + std::to_string(p.predictions[0]) +
           ", \"before\": " + std::to_string(p.predictions[1]) + ", \"after\": " + std::to_string(p.predictions[2]) +
           ", \"mean_before\": " + std::to_string(p.predictions[3]) +
           ", \"mean_after\": " + std::to_string(p.predictions[4]) + "}},\n";
    }
    o += "  \"notes\": [";
    for (size_t i = 0; i < rep.notes.size(); ++i) o += (i ? ", \"" : "\"") + json_escape(rep.notes[i]) + "\"";
    o += "]\n}\n";
    std::fputs(o.c_str(), stdout);
  } else {
    std::printf("file                   %s\n", file.c_str());
    std::printf("format                 %s\n", format_name(mesh.format));
    std::printf("vertices               %llu\n", static_cast<unsigned long long>(r.vertices));
    std::printf("triangles              %llu\n", static_cast<unsigned long long>(r.triangles));
    std::printf("unreferenced vertices  %llu\n", static_cast<unsigned long long>(r.unreferenced_vertices));
    std::printf("degenerate triangles   %llu\n", static_cast<unsigned long long>(r.degenerate_triangles));
    if (rep.polygons_triangulated != 0) {
      std::printf("polygons triangulated  %llu\n", static_cast<unsigned long long>(rep.polygons_triangulated));
    }
    if (rep.strip_triangles != 0) {
      std::printf("strip triangles        %llu\n", static_cast<unsigned long long>(rep.strip_triangles));
    }
    std::printf("position type          %s\n", scalar_name(r.schema.position_type));
    std::printf("bounding box           [%.9g %.9g %.9g] .. [%.9g %.9g %.9g]\n", r.bbox_min[0], r.bbox_min[1],
                r.bbox_min[2], r.bbox_max[0], r.bbox_max[1], r.bbox_max[2]);
    std::printf("components             %llu\n", static_cast<unsigned long long>(q.components));
    std::printf("border edges           %llu\n", static_cast<unsigned long long>(c.border_edges));
    std::printf("border loops           %llu\n", static_cast<unsigned long long>(q.border_loops));
    std::printf("handles                %lld\n", static_cast<long long>(q.handles));
    std::printf("non-manifold vertices  %llu (%llu re-appearances)\n",
                static_cast<unsigned long long>(c.nonmanifold_vertices), static_cast<unsigned long long>(q.reappearances));
    std::printf("non-manifold edges     %llu\n", static_cast<unsigned long long>(c.nonmanifold_edges));
    std::printf("misoriented edges      %llu\n", static_cast<unsigned long long>(c.misoriented_edges));
    std::printf("max boundary           %llu vertices, %llu edges\n",
                static_cast<unsigned long long>(q.max_boundary_vertices),
                static_cast<unsigned long long>(q.max_boundary_edges));
    std::printf("ops                    start %llu, add %llu, join %llu, fill %llu, end %llu\n",
                static_cast<unsigned long long>(q.ops[0]), static_cast<unsigned long long>(q.ops[1]),
                static_cast<unsigned long long>(q.ops[2]), static_cast<unsigned long long>(q.ops[3]),
                static_cast<unsigned long long>(q.ops[4]));
    std::printf("sequence order         %s\n", build.sorted ? "sorted (external sort)" : "coherent (file order)");
    std::printf("vertex properties      %s\n", type_list(r.schema.vertex_properties).c_str());
    std::printf("face properties        %s\n", type_list(r.schema.face_properties).c_str());
    if (mesh.decoder) {
      const PsqHeader& h = mesh.decoder->header();
      const PsqStats& p = mesh.decoder->stats();
      const double nv = p.vertices ? static_cast<double>(p.vertices) : 1.0;
      std::printf("psq version            %d.%d, %s profile\n", h.version_major, h.version_minor,
                  h.fast ? "fast" : "compact");
      if (h.lossless) std::printf("positions              lossless\n");
      else std::printf("positions              quantized to %d bits (step %.9g)\n", h.bits, h.step);
      std::printf("size                   %llu bytes in %llu chunks, %.3f bits/vertex\n",
                  static_cast<unsigned long long>(p.total_bytes), static_cast<unsigned long long>(p.chunks),
                  8.0 * p.total_bytes / nv);
      std::printf("  connectivity         %.3f bits/vertex\n", p.connectivity_bits / nv);
      std::printf("  geometry             %.3f bits/vertex\n", p.geometry_bits / nv);
      std::printf("  properties           %.3f bits/vertex\n", 8.0 * p.property_bytes / nv);
      std::printf("  framing              %.3f bits/vertex\n", 8.0 * (p.header_bytes + p.chunk_overhead_bytes) / nv);
      auto u = [](uint64_t v) { return static_cast<unsigned long long>(v); };
      std::printf("gates                  offset 0 %llu, offset %llu, far %llu (rank %llu, resume %llu, raw %llu), "
                  "start or isolated %llu\n",
                  u(p.gates[0]), u(p.gates[1]), u(p.gates[2]), u(p.far_gates[0]), u(p.far_gates[1]), u(p.far_gates[2]),
                  u(p.gates[3]));
      std::printf("add predictions        across the gate %llu, the edge before %llu, the edge after %llu, "
                  "mean with before %llu, mean with after %llu\n",
                  u(p.predictions[0]), u(p.predictions[1]), u(p.predictions[2]), u(p.predictions[3]),
                  u(p.predictions[4]));
    }
    for (const std::string& n : rep.notes) std::printf("note                   %s\n", n.c_str());
  }
  std::fflush(stdout);
  if (r.degenerate_triangles != 0) {
    warn(file, std::to_string(r.degenerate_triangles) + " degenerate triangle(s) repeat a vertex index");
  }
  return kExitOk;
}

}  // namespace psq::cli
