// SPDX-License-Identifier: Apache-2.0
// The plumbing of a pipeline from an input mesh to an output file; see
// pipeline.h. The sequence into an indexed mesh follows
// spec/psq-dump.md A.2.1.
#include "pipeline.h"

#include <sys/stat.h>

#include <algorithm>

#include "json.h"
#include "psq/draco.h"
#include "psq/obj.h"

namespace psq::detail {

bool same_file(const std::string& a, const std::string& b) {
  if (a == "-" || b == "-") return false;
  if (a == b) return true;
  struct stat sa, sb;
  if (::stat(a.c_str(), &sa) != 0 || ::stat(b.c_str(), &sb) != 0) return false;
  return sa.st_dev == sb.st_dev && sa.st_ino == sb.st_ino;
}

bool error_is_about_output(const Status& status) {
  return status.line() == Status::kNoPlace && status.offset() == Status::kNoPlace && status.code() == ErrorCode::kIo;
}

MeshFormat output_format(const std::string& name, const std::string& path) {
  return name.empty() ? format_from_extension(path) : format_from_name(name);
}

bool auto_fast_profile(const MeshSchema& schema) {
  if (schema.triangle_count != MeshSchema::kUnknown) return schema.triangle_count >= 131072;
  return schema.vertex_count != MeshSchema::kUnknown && schema.vertex_count >= 65536;
}

std::vector<std::string> writer_notes(MeshFormat format, MeshSink* writer) {
  std::vector<std::string> notes;
  if (format == MeshFormat::kObj)
    for (const std::string& d : static_cast<ObjWriter*>(writer)->dropped())
      notes.push_back("property '" + d + "' dropped: OBJ cannot hold it");
  if (format == MeshFormat::kDraco) {
    for (const std::string& d : static_cast<DracoWriter*>(writer)->dropped())
      notes.push_back("property '" + d + "' dropped: Draco output keeps scalar vertex properties only");
    for (const std::string& n : static_cast<DracoWriter*>(writer)->notes()) notes.push_back(n);
  }
  return notes;
}

std::vector<std::string> input_notes(const OpenedMesh& mesh, const BuildReport& build) {
  std::vector<std::string> notes = mesh.source->report().notes;
  if (build.converter.degenerate_dropped)
    notes.push_back(std::to_string(build.converter.degenerate_dropped) + " degenerate triangle(s) dropped");
  return notes;
}

namespace {
// The share of duplicated positions above which convert suggests --weld:
// "most vertices" (a soup of a closed mesh repeats about 5 in 6).
constexpr double kSuggestWeld = 0.5;
// With normals or texture coordinates, what a mesh split at its seams
// repeats: a few percent of its vertices and more.
constexpr double kSuggestCorners = 0.05;

const char* weld_name(WeldMode m) {
  return m == WeldMode::kOff ? "off" : m == WeldMode::kAll ? "all" : "positions";
}
}  // namespace

std::vector<std::string> weld_notes(WeldMode weld, const BuildReport& report, const MeshSchema& input) {
  std::vector<std::string> notes;
  // A mesh split at its seams repeats fewer positions than a soup, and
  // carries normals or texture coordinates (--weld=corners).
  bool attributes = false;
  for (const Property& p : input.vertex_properties)
    for (const char* n : {"nx", "u", "s", "texture_u", "texture_s"}) attributes = attributes || p.name == n;
  const std::string share = std::to_string(static_cast<int>(100 * report.duplicate_share + 0.5));
  if (weld != WeldMode::kOff) {
    notes.push_back("--weld merged " + std::to_string(report.welded_vertices) + " of " +
                    std::to_string(report.input_vertices) + " vertices and dropped " +
                    std::to_string(report.weld_dropped) + " triangle(s) it made degenerate");
  } else if (attributes && report.duplicate_share > kSuggestCorners) {
    notes.push_back("about " + share + "% of the vertices repeat another vertex's position: --weld would merge "
                    "identical ones, --weld=corners those that differ in normals or texture coordinates only");
  } else if (report.duplicate_share > kSuggestWeld) {
    notes.push_back("about " + share +
                    "% of the vertices repeat another vertex's position (a triangle soup?): --weld would merge them");
  }
  return notes;
}

std::string json_weld(WeldMode weld, const BuildReport& report, bool from_mesh, const CornerWelder* corners) {
  if (corners != nullptr)
    return ", \"weld\": \"corners\", \"input_vertices\": " + std::to_string(corners->input_vertices()) +
           ", \"input_triangles\": " + std::to_string(corners->input_triangles()) +
           ", \"welded_vertices\": " + std::to_string(corners->merged_vertices()) +
           ", \"weld_dropped_triangles\": " + std::to_string(corners->dropped_triangles());
  std::string o = std::string(", \"weld\": \"") + weld_name(weld) + "\"";
  if (from_mesh) {
    o += ", \"input_vertices\": " + std::to_string(report.input_vertices) +
         ", \"input_triangles\": " + std::to_string(report.input_triangles) +
         ", \"welded_vertices\": " + std::to_string(report.welded_vertices) +
         ", \"weld_dropped_triangles\": " + std::to_string(report.weld_dropped);
  }
  return o;
}

std::string json_encoding(const EncodeOptions& e) {
  return std::string(", \"lossless\": ") + (e.lossless ? "true" : "false") +
         ", \"bits\": " + std::to_string(e.lossless ? 0 : e.bits) + ", \"profile\": \"" + (e.fast ? "fast" : "compact") +
         "\"";
}

std::string json_bits_per_vertex(const PsqStats& st) {
  const double nv = st.vertices ? static_cast<double>(st.vertices) : 1.0;
  return "\"bits_per_vertex\": " + json_number(8.0 * st.total_bytes / nv) +
         ", \"connectivity_bits_per_vertex\": " + json_number(st.connectivity_bits / nv) +
         ", \"geometry_bits_per_vertex\": " + json_number(st.geometry_bits / nv) +
         ", \"property_bits_per_vertex\": " + json_number(8.0 * st.property_bytes / nv);
}

Status SequenceToMesh::begin(const MeshSchema& schema) {
  MeshSchema s = schema;
  s.vertex_count = MeshSchema::kUnknown;
  s.triangle_count = MeshSchema::kUnknown;
  return out_->begin(s);
}

Status SequenceToMesh::vertex(const SequenceVertex& v) {
  if (v.reappears != kNoVertex) {
    reappearing_.push_back(v.index);
    first_.push_back(mesh_index(v.reappears));
    return Status();
  }
  return out_->vertex(v.position, v.values);
}

Status SequenceToMesh::triangle(const SequenceTriangle& t) {
  const uint32_t index[3] = {mesh_index(t.v[0]), mesh_index(t.v[1]), mesh_index(t.v[2])};
  return out_->triangle(index, t.values);
}

uint32_t SequenceToMesh::mesh_index(uint32_t dense) const {
  auto it = std::lower_bound(reappearing_.begin(), reappearing_.end(), dense);
  if (it != reappearing_.end() && *it == dense) return first_[static_cast<size_t>(it - reappearing_.begin())];
  return dense - static_cast<uint32_t>(it - reappearing_.begin());
}

Status SequenceBox::vertex(const SequenceVertex& v) {
  for (int a = 0; a < 3; ++a) {
    lo[a] = any ? std::min(lo[a], v.position[a]) : v.position[a];
    hi[a] = any ? std::max(hi[a], v.position[a]) : v.position[a];
  }
  any = true;
  return Status();
}

Status ObservedSource::next(MeshItem* item) {
  Status s = in_->next(item);
  if (observer_ && s.ok() && item->kind == MeshItem::Kind::kTriangle) observer_->triangle_read();
  return s;
}

Status ObservedSequence::triangle(const SequenceTriangle& t) {
  if (observer_) {
    if (written_) observer_->triangle_written();
    else observer_->triangle_read();
  }
  return out_->triangle(t);
}

namespace {

// Counts a source's triangles.
class CountingSource : public MeshSource {
 public:
  explicit CountingSource(MeshSource* in) : in_(in) {}
  const MeshSchema& schema() const override { return in_->schema(); }
  const SourceReport& report() const override { return in_->report(); }
  Status next(MeshItem* item) override {
    Status s = in_->next(item);
    if (s.ok() && item->kind == MeshItem::Kind::kTriangle) ++triangles;
    return s;
  }
  uint64_t triangles = 0;

 private:
  MeshSource* in_;
};

// Calls a hook right before the sink's begin().
class BeginHook : public SequenceSink {
 public:
  BeginHook(SequenceSink* out, std::function<void()> hook) : out_(out), hook_(std::move(hook)) {}
  Status begin(const MeshSchema& s) override {
    hook_();
    return out_->begin(s);
  }
  Status vertex(const SequenceVertex& v) override { return out_->vertex(v); }
  Status triangle(const SequenceTriangle& t) override { return out_->triangle(t); }
  Status finalize(uint32_t i) override { return out_->finalize(i); }
  Status finish() override { return out_->finish(); }

 private:
  SequenceSink* out_;
  std::function<void()> hook_;
};

}  // namespace

Status feed_sequence(OpenedMesh& mesh, SequenceSink& sink, const BuildOptions& build, BuildReport* report,
                     RunObserver* observer, const std::function<void(uint64_t)>& at_begin) {
  if (mesh.decoder) {
    ObservedSequence observed(&sink, observer);
    if (!at_begin) return mesh.decoder->pump(observed);
    BeginHook hooked(&observed, [&] { at_begin(0); });
    return mesh.decoder->pump(hooked);
  }
  ObservedSource observed(mesh.source.get(), observer);
  if (!at_begin) return build_sequence(observed, sink, build, report);
  CountingSource counting(&observed);
  BeginHook hooked(&sink, [&] { at_begin(counting.triangles); });
  return build_sequence(counting, hooked, build, report);
}

Status count_triangles(OpenedMesh& mesh, uint64_t* count) {
  if (mesh.decoder) {
    if (mesh.decoder->schema().triangle_count >= 0) {
      *count = static_cast<uint64_t>(mesh.decoder->schema().triangle_count);
      return Status();
    }
    SequenceBox counter;
    PSQ_RETURN_IF_ERROR(mesh.decoder->pump(counter));
    *count = counter.triangles;
    return Status();
  }
  if (mesh.source->schema().triangle_count >= 0) {
    *count = static_cast<uint64_t>(mesh.source->schema().triangle_count);
    return Status();
  }
  MeshItem item;
  uint64_t t = 0;
  for (;;) {
    PSQ_RETURN_IF_ERROR(mesh.source->next(&item));
    if (item.kind == MeshItem::Kind::kEnd) break;
    if (item.kind == MeshItem::Kind::kTriangle) ++t;
  }
  *count = t;
  return Status();
}

}  // namespace psq::detail
