// SPDX-License-Identifier: Apache-2.0
// psq info's count of a mesh file in one streaming pass (the mesh figures
// by MeshStats, the processing sequence's by SequenceChecker or, for a
// .psq, SequenceCounter: paper Table 1); see info.h.
#include "info.h"

#include <algorithm>

#include "json.h"
#include "psq/mesh_stats.h"
#include "psq/sequence_count.h"

namespace psq::detail {
namespace {

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
// taken, its triangles shown to the observer.
class PsqInfoSink : public SequenceSink {
 public:
  explicit PsqInfoSink(RunObserver* observer) : observer_(observer) {}
  Status begin(const MeshSchema& s) override { return counter.begin(s); }
  Status vertex(const SequenceVertex& v) override {
    PSQ_RETURN_IF_ERROR(box.vertex(v));
    return counter.vertex(v);
  }
  Status triangle(const SequenceTriangle& t) override {
    if (observer_) observer_->triangle_written();
    return counter.triangle(t);
  }
  Status finalize(uint32_t i) override { return counter.finalize(i); }
  Status finish() override { return counter.finish(); }

  SequenceCounter counter;
  SequenceBox box;

 private:
  RunObserver* observer_;
};

void set_mesh_figures(InfoReport* r, uint64_t vertices, uint64_t triangles, uint64_t unreferenced,
                      uint64_t degenerate, const double lo[3], const double hi[3]) {
  r->vertices = vertices;
  r->triangles = triangles;
  r->unreferenced = unreferenced;
  r->degenerate = degenerate;
  std::copy(lo, lo + 3, r->bbox_min);
  std::copy(hi, hi + 3, r->bbox_max);
}

void set_edge_figures(InfoReport* r, uint64_t border, uint64_t nonmanifold_vertices, uint64_t nonmanifold_edges,
                      uint64_t misoriented) {
  r->border_edges = border;
  r->nonmanifold_vertices = nonmanifold_vertices;
  r->nonmanifold_edges = nonmanifold_edges;
  r->misoriented_edges = misoriented;
}

// The header's coded attributes (spec 8.3) as JSON: kind, bits and the
// properties each one codes.
std::string attribute_json(const PsqHeader& h) {
  std::string o = "[";
  for (const CodedAttribute& a : h.attributes) {
    if (o.size() > 1) o += ", ";
    o += std::string("{\"kind\": \"") +
         (a.kind == CodedAttribute::Kind::kNormal           ? "normal"
          : a.kind == CodedAttribute::Kind::kTexcoord       ? "texcoord"
          : a.kind == CodedAttribute::Kind::kColor          ? "color"
          : a.kind == CodedAttribute::Kind::kCornerNormal   ? "corner normal"
                                                            : "corner texcoord") +
         "\", \"bits\": " + std::to_string(a.bits) + ", \"properties\": [";
    const std::vector<Property>& props = a.per_corner() ? h.schema.face_properties : h.schema.vertex_properties;
    for (size_t i = 0; i < a.properties.size(); ++i)
      o += (i ? ", \"" : "\"") + json_escape(props[a.properties[i]].name) + "\"";
    o += "]}";
  }
  return o + "]";
}

}  // namespace

Status measure_info(OpenedMesh& mesh, const BuildOptions& build, InfoReport* r, RunObserver* observer) {
  *r = InfoReport();
  r->format = mesh.format;
  if (mesh.decoder) {
    // The file's own sequence, counted as it is decoded: the decoder's
    // memory, nothing rebuilt.
    PsqInfoSink sink(observer);
    mesh.decoder->measure_costs(true);
    PSQ_RETURN_IF_ERROR(mesh.decoder->pump(sink));
    const SequenceStats& q = sink.counter.stats();
    r->schema = mesh.decoder->schema();
    set_mesh_figures(r, q.vertices, q.triangles, q.unreferenced_vertices, q.degenerate_triangles, sink.box.lo,
                     sink.box.hi);
    set_edge_figures(r, q.mesh_border_edges, q.nonmanifold_vertices, q.mesh_nonmanifold_edges,
                     q.mesh_misoriented_edges);
    r->sequence = q;
    r->from_file = true;
    r->header = mesh.decoder->header();
    r->psq = mesh.decoder->stats();
  } else {
    MeshStats stats;
    SequenceChecker checker;
    TeeSource tee(mesh.source.get(), &stats);
    ObservedSource source(&tee, observer);
    ObservedSequence sink(&checker, observer, true);
    PSQ_RETURN_IF_ERROR(build_sequence(source, sink, build, &r->build));
    const MeshStatsResult& m = stats.result();
    const ConverterStats& c = r->build.converter;
    r->schema = m.schema;
    set_mesh_figures(r, m.vertices, m.triangles, m.unreferenced_vertices, m.degenerate_triangles, m.bbox_min,
                     m.bbox_max);
    set_edge_figures(r, c.border_edges, c.nonmanifold_vertices, c.nonmanifold_edges, c.misoriented_edges);
    r->sequence = checker.stats();
  }
  const SourceReport& rep = mesh.source->report();
  r->polygons_triangulated = rep.polygons_triangulated;
  r->strip_triangles = rep.strip_triangles;
  r->notes = rep.notes;
  return Status();
}

std::string info_json(const std::string& file, const InfoReport& r) {
  const SequenceStats& q = r.sequence;
  auto n = [](uint64_t v) { return std::to_string(v); };
  std::string o = "{\n";
  o += "  \"file\": " + json_string(file) + ",\n";
  o += std::string("  \"format\": \"") + format_name(r.format) + "\",\n";
  o += "  \"vertices\": " + n(r.vertices) + ",\n";
  o += "  \"triangles\": " + n(r.triangles) + ",\n";
  o += "  \"unreferenced_vertices\": " + n(r.unreferenced) + ",\n";
  o += "  \"degenerate_triangles\": " + n(r.degenerate) + ",\n";
  o += "  \"polygons_triangulated\": " + n(r.polygons_triangulated) + ",\n";
  o += "  \"strip_triangles\": " + n(r.strip_triangles) + ",\n";
  o += std::string("  \"position_type\": \"") + scalar_name(r.schema.position_type) + "\",\n";
  o += "  \"bbox\": " + json_box(r.bbox_min, r.bbox_max) + ",\n";
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
    const BuildReport& b = r.build;
    o += std::string("  \"sequence_order\": \"") + (b.sorted ? "sorted" : "coherent") + "\",\n";
    o += "  \"coherence_window\": " + n(b.window) + ",\n";
    o += "  \"max_waiting_triangles\": " + n(b.converter.max_waiting_triangles) + ",\n";
    o += "  \"max_waiting_vertices\": " + n(b.converter.max_waiting_vertices) + ",\n";
  }
  o += "  \"vertex_properties\": " + json_properties(r.schema.vertex_properties) + ",\n";
  o += "  \"face_properties\": " + json_properties(r.schema.face_properties) + ",\n";
  if (r.from_file) {
    const PsqHeader& h = r.header;
    const PsqStats& p = r.psq;
    const double nv = p.vertices ? static_cast<double>(p.vertices) : 1.0;
    o += "  \"psq\": {\"version\": \"" + std::to_string(h.version_major) + "." + std::to_string(h.version_minor) +
         "\", \"profile\": \"" + (h.fast ? "fast" : "compact") + "\", \"lossless\": " + (h.lossless ? "true" : "false") +
         ", \"bits\": " + std::to_string(h.bits) + ", \"step\": " + json_number(h.step) + ", \"chunks\": " + n(p.chunks) +
         ", \"bytes\": " + n(p.total_bytes) + ", \"sequence_vertices\": " + n(p.vertices) +
         ", " + json_bits_per_vertex(p) +
         ", \"attribute_bits_per_vertex\": " + json_number(8.0 * p.attribute_bytes / nv) +
         ", \"attributes\": " + attribute_json(h) +
         ", \"overhead_bits_per_vertex\": " + json_number(8.0 * (p.header_bytes + p.chunk_overhead_bytes) / nv) +
         ", \"segments\": " + n(p.segments + 1) + ", \"segment_triangles\": " + n(h.segment_triangles) +
         ", \"segment_bytes\": " + n(p.segment_bytes) +
         ", \"gates\": {\"offset_0\": " + n(p.gates[0]) + ", \"offset\": " + n(p.gates[1]) +
         ", \"far_rank\": " + n(p.far_gates[0]) + ", \"far_slot\": " + n(p.far_gates[1]) +
         ", \"start_or_isolated\": " + n(p.gates[3]) +
         "}, \"add_predictions\": {\"gate\": " + n(p.predictions[0]) + ", \"before\": " + n(p.predictions[1]) +
         ", \"after\": " + n(p.predictions[2]) + ", \"mean_before\": " + n(p.predictions[3]) +
         ", \"mean_after\": " + n(p.predictions[4]) + "}},\n";
  }
  o += "  \"notes\": " + json_strings(r.notes) + "\n}\n";
  return o;
}

}  // namespace psq::detail
