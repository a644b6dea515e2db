// SPDX-License-Identifier: Apache-2.0
// psq_simplify_compare: the pieces of the simplification benchmark that run
// as processes of their own (bench/run_simplify_compare.py drives them):
//
//   psq_simplify_compare meshopt [--sloppy] IN OUT (--ratio R | --triangles N) [--error E]
//       Reads IN (any mesh psq reads) into arrays, simplifies it with
//       meshoptimizer's meshopt_simplify (or meshopt_simplifySloppy) to
//       3 N indices, and writes the used vertices and the triangles to OUT
//       (binary PLY). Prints one JSON object: meshoptimizer's own figures
//       (the index count it returned, its result_error: relative to
//       meshopt_simplifyScale, the largest extent of the box) and the
//       seconds of the call. As a process of its own, its peak memory is
//       meshoptimizer's in-core footprint with the arrays it needs.
//
//   psq_simplify_compare quality IN OUT [--threads N]
//       Counts what a simplification OUT of IN did to the triangles, one
//       JSON object: triangles, used vertices, degenerate triangles (a
//       repeated corner or zero area) and flipped ones (the normal more than
//       90 degrees from that of the input triangle nearest to the output
//       triangle's centroid; psq/distance.h's nearest_triangles(), which
//       streams IN, so that a 50M-triangle input need not fit).
//
// Exit status: 0, 1 on a data or I/O error, 2 on a usage error.
#include <meshoptimizer.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "psq/distance.h"
#include "psq/mesh_formats.h"
#include "psq/ply.h"

namespace {

int usage(const char* message) {
  std::fprintf(stderr,
               "psq_simplify_compare: %s\n"
               "usage: psq_simplify_compare meshopt [--sloppy] IN OUT (--ratio R | --triangles N) [--error E]\n"
               "       psq_simplify_compare quality IN OUT [--threads N]\n",
               message);
  return 2;
}

int fail(const std::string& file, const psq::Status& s) {
  std::fprintf(stderr, "psq_simplify_compare: %s: %s\n", file.c_str(), s.to_string().c_str());
  return 1;
}

double now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

// A whole mesh in arrays: float positions as meshoptimizer takes them, or
// double.
template <class T>
struct Arrays {
  std::vector<T> positions;       // 3 a vertex
  std::vector<uint32_t> indices;  // 3 a triangle
};

template <class T>
psq::Status read_arrays(const std::string& path, Arrays<T>* m) {
  psq::OpenedMesh opened;
  PSQ_RETURN_IF_ERROR(psq::open_mesh(path, psq::OpenOptions(), &opened));
  psq::MeshItem item;
  for (;;) {
    PSQ_RETURN_IF_ERROR(opened.source->next(&item));
    if (item.kind == psq::MeshItem::Kind::kEnd) return psq::Status();
    if (item.kind == psq::MeshItem::Kind::kVertex) m->positions.insert(m->positions.end(), item.position, item.position + 3);
    else m->indices.insert(m->indices.end(), item.index, item.index + 3);
  }
}

int run_meshopt(int argc, char** argv) {
  bool sloppy = false;
  double ratio = -1, error = 1;
  long long triangles = -1;
  std::vector<std::string> files;
  for (int i = 0; i < argc; ++i) {
    std::string a = argv[i];
    if (a == "--sloppy") sloppy = true;
    else if (a == "--ratio" && i + 1 < argc) ratio = std::atof(argv[++i]);
    else if (a == "--triangles" && i + 1 < argc) triangles = std::atoll(argv[++i]);
    else if (a == "--error" && i + 1 < argc) error = std::atof(argv[++i]);
    else if (!a.empty() && a[0] == '-') return usage(("unknown option " + a).c_str());
    else files.push_back(a);
  }
  if (files.size() != 2) return usage("meshopt needs IN and OUT");
  if ((ratio < 0) == (triangles < 0)) return usage("give one of --ratio and --triangles");
  if (ratio > 1 || !(error > 0)) return usage("--ratio is at most 1, --error above 0");

  const double t0 = now();
  Arrays<float> in;
  psq::Status s = read_arrays(files[0], &in);
  if (!s.ok()) return fail(files[0], s);
  const double t_read = now();
  const std::vector<float>& pos = in.positions;
  const size_t vertices = pos.size() / 3, index_count = in.indices.size();
  const size_t target = triangles >= 0 ? static_cast<size_t>(triangles)
                                       : static_cast<size_t>(std::llround(ratio * static_cast<double>(index_count / 3)));
  std::vector<uint32_t> out(index_count);  // meshoptimizer: room for index_count, not the target
  float result_error = 0;
  const double t1 = now();
  size_t n = sloppy ? meshopt_simplifySloppy(out.data(), in.indices.data(), index_count, pos.data(), vertices,
                                             3 * sizeof(float), 3 * target, static_cast<float>(error), &result_error)
                    : meshopt_simplify(out.data(), in.indices.data(), index_count, pos.data(), vertices,
                                       3 * sizeof(float), 3 * target, static_cast<float>(error), 0, &result_error);
  const double t2 = now();
  const float scale = meshopt_simplifyScale(pos.data(), vertices, 3 * sizeof(float));
  out.resize(n);

  // The used vertices, in index order, and the triangles renumbered.
  std::vector<uint32_t> remap(vertices, UINT32_MAX);
  for (uint32_t v : out) remap[v] = 0;
  uint32_t used = 0;
  for (uint32_t& r : remap)
    if (r == 0) r = used++;
  psq::MeshSchema schema;
  schema.position_type = psq::ScalarType::kFloat32;
  schema.vertex_count = used;
  schema.triangle_count = static_cast<int64_t>(n / 3);
  psq::OutputFile file;
  s = file.open(files[1], true);
  if (!s.ok()) return fail(files[1], s);
  psq::PlyWriter writer(&file);
  s = writer.begin(schema);
  const psq::PropertyValues none;
  for (size_t v = 0; v < vertices && s.ok(); ++v) {
    if (remap[v] == UINT32_MAX) continue;
    const double p[3] = {pos[3 * v], pos[3 * v + 1], pos[3 * v + 2]};
    s = writer.vertex(p, none);
  }
  for (size_t i = 0; i + 2 < n && s.ok(); i += 3) {
    const uint32_t t[3] = {remap[out[i]], remap[out[i + 1]], remap[out[i + 2]]};
    s = writer.triangle(t, none);
  }
  if (s.ok()) s = writer.finish();
  if (s.ok()) s = file.commit();
  if (!s.ok()) return fail(files[1], s);
  std::printf(
      "{\"method\": \"%s\", \"input_triangles\": %zu, \"input_vertices\": %zu, \"target_triangles\": %zu, "
      "\"result_index_count\": %zu, \"output_triangles\": %zu, \"output_vertices\": %u, \"result_error\": %.9g, "
      "\"scale\": %.9g, \"target_error\": %.9g, \"seconds_read\": %.6f, \"seconds_simplify\": %.6f, "
      "\"seconds\": %.6f, \"meshoptimizer_version\": %d}\n",
      sloppy ? "meshopt_simplifySloppy" : "meshopt_simplify", index_count / 3, vertices, target, n, n / 3, used,
      result_error, scale, error, t_read - t0, t2 - t1, now() - t0, MESHOPTIMIZER_VERSION);
  return 0;
}

int run_quality(int argc, char** argv) {
  psq::DistanceOptions options;
  std::vector<std::string> files;
  for (int i = 0; i < argc; ++i) {
    std::string a = argv[i];
    if (a == "--threads" && i + 1 < argc) options.threads = std::atoi(argv[++i]);
    else if (!a.empty() && a[0] == '-') return usage(("unknown option " + a).c_str());
    else files.push_back(a);
  }
  if (files.size() != 2) return usage("quality needs IN and OUT");
  const double t0 = now();
  Arrays<double> out;
  psq::Status s = read_arrays(files[1], &out);
  if (!s.ok()) return fail(files[1], s);
  const size_t triangles = out.indices.size() / 3;
  std::vector<bool> used(out.positions.size() / 3, false);
  uint64_t degenerate = 0, vertices = 0;
  std::vector<double> centroids, normals;
  for (size_t t = 0; t < triangles; ++t) {
    const uint32_t* f = &out.indices[3 * t];
    for (int k = 0; k < 3; ++k) used[f[k]] = true;
    const double* a = &out.positions[3 * f[0]];
    const double* b = &out.positions[3 * f[1]];
    const double* c = &out.positions[3 * f[2]];
    const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    const double n[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
    const double len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    if (f[0] == f[1] || f[1] == f[2] || f[2] == f[0] || !(len > 0)) {
      ++degenerate;
      continue;
    }
    for (int k = 0; k < 3; ++k) {
      centroids.push_back((a[k] + b[k] + c[k]) / 3);
      normals.push_back(n[k] / len);
    }
  }
  for (bool u : used) vertices += u;
  uint64_t flipped = 0;
  if (!centroids.empty()) {
    psq::OpenedMesh in;
    s = psq::open_mesh(files[0], psq::OpenOptions(), &in);
    if (!s.ok()) return fail(files[0], s);
    std::vector<psq::NearestTriangle> nearest;
    s = psq::nearest_triangles(*in.source, centroids, options, &nearest);
    if (!s.ok()) return fail(files[0], s);
    for (size_t i = 0; i < nearest.size(); ++i) {
      const double* n = &normals[3 * i];
      if (n[0] * nearest[i].normal[0] + n[1] * nearest[i].normal[1] + n[2] * nearest[i].normal[2] < 0) ++flipped;
    }
  }
  std::printf(
      "{\"triangles\": %zu, \"vertices\": %llu, \"degenerate_triangles\": %llu, \"flipped_triangles\": %llu, "
      "\"seconds\": %.3f}\n",
      triangles, static_cast<unsigned long long>(vertices), static_cast<unsigned long long>(degenerate),
      static_cast<unsigned long long>(flipped), now() - t0);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) return usage("missing mode");
  const std::string mode = argv[1];
  if (mode == "meshopt") return run_meshopt(argc - 2, argv + 2);
  if (mode == "quality") return run_quality(argc - 2, argv + 2);
  return usage(("unknown mode " + mode).c_str());
}
