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
//       repeated corner or zero area), and flipped ones: the normal more
//       than 90 degrees from that of the input triangle nearest to the
//       output triangle's centroid (psq/distance.h's nearest_triangles(),
//       which streams IN), unless an input triangle facing within 90
//       degrees of it is within twice that nearest one's distance, plus a
//       tenth of its longest edge. Between the two sides of a thin wall (a
//       foam's, a sheet's), both about as near as the simplification's
//       error, the nearest side cannot tell which side a triangle stands
//       for: one that moved a little past the middle faces away from the
//       nearer side and is not flipped, while one turned over on a side
//       (distance about 0 to it, the wall's thickness to the other) is
//       ("opposed_nearest" counts both: the test without the exception).
//       The exception is checked in a second pass over IN, which holds
//       IN's positions, not its triangles.
//
// Exit status: 0, 1 on a data or I/O error, 2 on a usage error.
#include <meshoptimizer.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <unordered_map>
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

// The squared distance from p to triangle (a, b, c): the closest point by
// the triangle's Voronoi regions (Ericson, Real-Time Collision Detection,
// 5.1.5).
double point_triangle_distance2(const double p[3], const double a[3], const double b[3], const double c[3]) {
  auto sub = [](const double* x, const double* y, double* r) {
    for (int i = 0; i < 3; ++i) r[i] = x[i] - y[i];
  };
  auto dot = [](const double* x, const double* y) { return x[0] * y[0] + x[1] * y[1] + x[2] * y[2]; };
  double ab[3], ac[3], ap[3], q[3];
  sub(b, a, ab);
  sub(c, a, ac);
  sub(p, a, ap);
  auto at = [&](double v, double w) {
    for (int i = 0; i < 3; ++i) q[i] = a[i] + v * ab[i] + w * ac[i];
    double d[3];
    sub(p, q, d);
    return dot(d, d);
  };
  const double d1 = dot(ab, ap), d2 = dot(ac, ap);
  if (d1 <= 0 && d2 <= 0) return at(0, 0);
  double bp[3];
  sub(p, b, bp);
  const double d3 = dot(ab, bp), d4 = dot(ac, bp);
  if (d3 >= 0 && d4 <= d3) return at(1, 0);
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return at(d1 / (d1 - d3), 0);
  double cp[3];
  sub(p, c, cp);
  const double d5 = dot(ab, cp), d6 = dot(ac, cp);
  if (d6 >= 0 && d5 <= d6) return at(0, 1);
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return at(0, d2 / (d2 - d6));
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && d4 - d3 >= 0 && d5 - d6 >= 0) {
    const double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    return at(1 - w, w);
  }
  const double denom = 1 / (va + vb + vc);
  return at(vb * denom, vc * denom);
}

// Of the candidates (centroid, unit normal, reach: the distance within
// which an input triangle facing their way makes them ambiguous), marks
// in *ambiguous those that have one, streaming IN once.
psq::Status find_ambiguous(const std::string& in_path, const std::vector<double>& centroids,
                           const std::vector<double>& normals, const std::vector<double>& reach,
                           std::vector<bool>* ambiguous) {
  const size_t n = reach.size();
  ambiguous->assign(n, false);
  if (n == 0) return psq::Status();
  // A uniform grid over the candidates' reach boxes, cells the size of the
  // median reach, but no box more than 17 cells across.
  std::vector<double> sorted = reach;
  std::nth_element(sorted.begin(), sorted.begin() + n / 2, sorted.end());
  const double cell = std::max({sorted[n / 2], *std::max_element(reach.begin(), reach.end()) / 8, 1e-12});
  auto key = [](int64_t x, int64_t y, int64_t z) {
    return (static_cast<uint64_t>(x) * 0x9e3779b97f4a7c15ull) ^ (static_cast<uint64_t>(y) * 0xc2b2ae3d27d4eb4full) ^
           (static_cast<uint64_t>(z) * 0x165667b19e3779f9ull);
  };
  std::unordered_map<uint64_t, std::vector<uint32_t>> grid;
  for (size_t i = 0; i < n; ++i) {
    int64_t lo[3], hi[3];
    for (int k = 0; k < 3; ++k) {
      lo[k] = static_cast<int64_t>(std::floor((centroids[3 * i + k] - reach[i]) / cell));
      hi[k] = static_cast<int64_t>(std::floor((centroids[3 * i + k] + reach[i]) / cell));
    }
    for (int64_t x = lo[0]; x <= hi[0]; ++x)
      for (int64_t y = lo[1]; y <= hi[1]; ++y)
        for (int64_t z = lo[2]; z <= hi[2]; ++z) grid[key(x, y, z)].push_back(static_cast<uint32_t>(i));
  }
  psq::OpenedMesh opened;
  PSQ_RETURN_IF_ERROR(psq::open_mesh(in_path, psq::OpenOptions(), &opened));
  std::vector<double> positions;
  psq::MeshItem item;
  for (;;) {
    PSQ_RETURN_IF_ERROR(opened.source->next(&item));
    if (item.kind == psq::MeshItem::Kind::kEnd) return psq::Status();
    if (item.kind == psq::MeshItem::Kind::kVertex) {
      positions.insert(positions.end(), item.position, item.position + 3);
      continue;
    }
    const double* p[3];
    for (int k = 0; k < 3; ++k) {
      if (static_cast<uint64_t>(item.index[k]) * 3 >= positions.size())
        return psq::Status(psq::ErrorCode::kBadValue, "a triangle refers to a vertex not read yet");
      p[k] = &positions[3 * static_cast<size_t>(item.index[k])];
    }
    const double u[3] = {p[1][0] - p[0][0], p[1][1] - p[0][1], p[1][2] - p[0][2]};
    const double v[3] = {p[2][0] - p[0][0], p[2][1] - p[0][1], p[2][2] - p[0][2]};
    const double m[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
    if (!(m[0] * m[0] + m[1] * m[1] + m[2] * m[2] > 0)) continue;
    int64_t lo[3], hi[3];
    for (int k = 0; k < 3; ++k) {
      lo[k] = static_cast<int64_t>(std::floor(std::min({p[0][k], p[1][k], p[2][k]}) / cell));
      hi[k] = static_cast<int64_t>(std::floor(std::max({p[0][k], p[1][k], p[2][k]}) / cell));
    }
    auto test = [&](uint32_t i) {
      if ((*ambiguous)[i]) return;
      const double* nn = &normals[3 * i];
      if (!(m[0] * nn[0] + m[1] * nn[1] + m[2] * nn[2] > 0)) return;
      if (point_triangle_distance2(&centroids[3 * i], p[0], p[1], p[2]) <= reach[i] * reach[i]) (*ambiguous)[i] = true;
    };
    // A triangle over more cells than there are candidates tests them all.
    const double cells = static_cast<double>(hi[0] - lo[0] + 1) * static_cast<double>(hi[1] - lo[1] + 1) *
                         static_cast<double>(hi[2] - lo[2] + 1);
    if (cells > static_cast<double>(n)) {
      for (uint32_t i = 0; i < n; ++i) test(i);
      continue;
    }
    for (int64_t x = lo[0]; x <= hi[0]; ++x)
      for (int64_t y = lo[1]; y <= hi[1]; ++y)
        for (int64_t z = lo[2]; z <= hi[2]; ++z) {
          auto it = grid.find(key(x, y, z));
          if (it == grid.end()) continue;
          for (uint32_t i : it->second) test(i);
        }
  }
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
  std::vector<double> centroids, normals, longest;
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
    const double w[3] = {c[0] - b[0], c[1] - b[1], c[2] - b[2]};
    const double uu = u[0] * u[0] + u[1] * u[1] + u[2] * u[2], vv = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
    longest.push_back(std::sqrt(std::max({uu, vv, w[0] * w[0] + w[1] * w[1] + w[2] * w[2]})));
  }
  for (bool u : used) vertices += u;
  uint64_t flipped = 0, opposed = 0;
  if (!centroids.empty()) {
    psq::OpenedMesh in;
    s = psq::open_mesh(files[0], psq::OpenOptions(), &in);
    if (!s.ok()) return fail(files[0], s);
    std::vector<psq::NearestTriangle> nearest;
    s = psq::nearest_triangles(*in.source, centroids, options, &nearest);
    if (!s.ok()) return fail(files[0], s);
    std::vector<double> cc, cn, reach;
    for (size_t i = 0; i < nearest.size(); ++i) {
      const double* n = &normals[3 * i];
      if (!(n[0] * nearest[i].normal[0] + n[1] * nearest[i].normal[1] + n[2] * nearest[i].normal[2] < 0)) continue;
      ++opposed;
      cc.insert(cc.end(), &centroids[3 * i], &centroids[3 * i] + 3);
      cn.insert(cn.end(), n, n + 3);
      reach.push_back(2 * nearest[i].distance + 0.1 * longest[i]);
    }
    std::vector<bool> ambiguous;
    s = find_ambiguous(files[0], cc, cn, reach, &ambiguous);
    if (!s.ok()) return fail(files[0], s);
    for (bool a : ambiguous) flipped += !a;
  }
  std::printf(
      "{\"triangles\": %zu, \"vertices\": %llu, \"degenerate_triangles\": %llu, \"flipped_triangles\": %llu, "
      "\"opposed_nearest_triangles\": %llu, \"seconds\": %.3f}\n",
      triangles, static_cast<unsigned long long>(vertices), static_cast<unsigned long long>(degenerate),
      static_cast<unsigned long long>(flipped), static_cast<unsigned long long>(opposed), now() - t0);
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
