// psq info: what a mesh holds, counted in one streaming pass.
#include <cstdio>
#include <string>

#include "cli_util.h"
#include "commands.h"
#include "psq/mesh_formats.h"
#include "psq/mesh_stats.h"

namespace psq::cli {
namespace {

const char kHelp[] =
    "Usage: psq info FILE [--json]\n"
    "\n"
    "Reads FILE (PLY or OBJ, recognised by content; '-' for standard input)\n"
    "in one streaming pass and prints its vertex and triangle counts, its\n"
    "properties, its bounding box, unreferenced vertices and degenerate\n"
    "triangles (a repeated vertex index).\n"
    "\n"
    "Options:\n"
    "  --json       print one JSON object instead of text\n"
    "  -h, --help   show this help\n";

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
  std::vector<std::string> files = args.positionals();
  if (!args.error().empty()) return usage_error("info", args.error());
  if (files.size() != 1) return usage_error("info", files.empty() ? "missing FILE" : "info takes one FILE");
  const std::string& file = files[0];

  OpenedMesh mesh;
  Status s = open_mesh(file, OpenOptions(), &mesh);
  if (!s.ok()) return report_error(file, s);
  MeshStats stats;
  s = pump(*mesh.source, stats);
  if (!s.ok()) return report_error(file, s);
  const MeshStatsResult& r = stats.result();
  const SourceReport& rep = mesh.source->report();

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
    o += "  \"vertex_properties\": " + json_props(r.schema.vertex_properties) + ",\n";
    o += "  \"face_properties\": " + json_props(r.schema.face_properties) + ",\n";
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
    std::printf("vertex properties      %s\n", type_list(r.schema.vertex_properties).c_str());
    std::printf("face properties        %s\n", type_list(r.schema.face_properties).c_str());
    for (const std::string& n : rep.notes) std::printf("note                   %s\n", n.c_str());
  }
  std::fflush(stdout);
  if (r.degenerate_triangles != 0) {
    warn(file, std::to_string(r.degenerate_triangles) + " degenerate triangle(s) repeat a vertex index");
  }
  return kExitOk;
}

}  // namespace psq::cli
