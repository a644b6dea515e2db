// SPDX-License-Identifier: Apache-2.0
// psq info: what a mesh holds, counted in one streaming pass.
#include <cstdio>
#include <string>

#include "cli_util.h"
#include "commands.h"
#include "info.h"
#include "progress.h"
#include "run_progress.h"

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

std::string type_list(const std::vector<Property>& props) {
  std::string s;
  for (const Property& p : props) {
    if (!s.empty()) s += ' ';
    s += p.name + ":" + (p.is_list ? "list<" + std::string(scalar_name(p.type)) + ">" : std::string(scalar_name(p.type)));
  }
  return s.empty() ? "none" : s;
}

// The header's coded attributes (spec 8.3), as "normals (nx ny nz)
// quantized, 8-bit octahedral; ...": what a quantized stream changed beyond
// the positions.
std::string attribute_text(const PsqHeader& h) {
  std::string o;
  for (const CodedAttribute& a : h.attributes) {
    if (!o.empty()) o += "; ";
    const bool normal = a.kind == CodedAttribute::Kind::kNormal || a.kind == CodedAttribute::Kind::kCornerNormal;
    const bool texcoord = a.kind == CodedAttribute::Kind::kTexcoord || a.kind == CodedAttribute::Kind::kCornerTexcoord;
    o += std::string(a.per_corner() ? "per-corner " : "") +
         (normal ? "normals (" : texcoord ? "texture coordinates (" : "colours (");
    const std::vector<Property>& props = a.per_corner() ? h.schema.face_properties : h.schema.vertex_properties;
    for (size_t i = 0; i < a.properties.size(); ++i) o += (i ? " " : "") + props[a.properties[i]].name;
    o += normal     ? ") quantized, " + std::to_string(a.bits) + "-bit octahedral"
         : texcoord ? ") quantized to steps of 2^-" + std::to_string(a.bits)
                    : std::string(") exact");
  }
  return o.empty() ? "none" : o;
}

void print_text(const std::string& file, const detail::InfoReport& r) {
  const SequenceStats& q = r.sequence;
  auto u = [](uint64_t v) { return static_cast<unsigned long long>(v); };
  std::printf("file                   %s\n", file.c_str());
  std::printf("format                 %s\n", format_name(r.format));
  std::printf("vertices               %llu\n", u(r.vertices));
  std::printf("triangles              %llu\n", u(r.triangles));
  std::printf("unreferenced vertices  %llu\n", u(r.unreferenced));
  std::printf("degenerate triangles   %llu\n", u(r.degenerate));
  if (r.polygons_triangulated != 0) std::printf("polygons triangulated  %llu\n", u(r.polygons_triangulated));
  if (r.strip_triangles != 0) std::printf("strip triangles        %llu\n", u(r.strip_triangles));
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
  else std::printf("sequence order         %s\n", r.build.sorted ? "sorted (external sort)" : "coherent (file order)");
  std::printf("vertex properties      %s\n", type_list(r.schema.vertex_properties).c_str());
  std::printf("face properties        %s\n", type_list(r.schema.face_properties).c_str());
  if (r.from_file) {
    const PsqHeader& h = r.header;
    const PsqStats& p = r.psq;
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
    std::printf("  segments             %.3f bits/vertex\n", 8.0 * p.segment_bytes / nv);
    if (h.segment_triangles == 0) std::printf("segments               1 (no segment records)\n");
    else
      std::printf("segments               %llu of %llu triangles, %llu bytes of state (%.2f%%)\n", u(p.segments + 1),
                  u(h.segment_triangles), u(p.segment_bytes),
                  p.total_bytes ? 100.0 * static_cast<double>(p.segment_bytes) / static_cast<double>(p.total_bytes) : 0.0);
    std::printf("gates                  offset 0 %llu, offset %llu, far %llu (rank %llu, slot %llu), "
                "start or isolated %llu\n",
                u(p.gates[0]), u(p.gates[1]), u(p.gates[2]), u(p.far_gates[0]), u(p.far_gates[1]),
                u(p.gates[3]));
    std::printf("add predictions        across the gate %llu, the edge before %llu, the edge after %llu, "
                "mean with before %llu, mean with after %llu\n",
                u(p.predictions[0]), u(p.predictions[1]), u(p.predictions[2]), u(p.predictions[3]), u(p.predictions[4]));
  }
  for (const std::string& s : r.notes) std::printf("note                   %s\n", s.c_str());
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
  RunProgress observer(&progress);
  detail::InfoReport r;
  s = detail::measure_info(mesh, build_options, &r, &observer);
  if (!s.ok()) return report_error(file, s);
  progress.clear();
  if (json) std::fputs(detail::info_json(file, r).c_str(), stdout);
  else print_text(file, r);
  std::fflush(stdout);
  if (r.degenerate != 0) {
    warn(file, std::to_string(r.degenerate) + " degenerate triangle(s) repeat a vertex index");
  }
  return kExitOk;
}

}  // namespace psq::cli
