// SPDX-License-Identifier: Apache-2.0
// psq_bench_qem: the stream edge-collapse simplifier (psq/stream_qem.h)
// beside meshoptimizer's in-core meshopt_simplify, at the same output count.
//
//   psq_bench_qem quality [--ratios 0.1,0.01] [--buffer N] [--candidates C]
//                         [--samples N] [--seed S] MESH...
//       For each mesh and ratio: meshopt_simplify to ratio x triangles, then
//       psq's simplifier to meshopt's count (whole mesh in the buffer, and
//       with --buffer N, bounded), and the symmetric distance of each result
//       to the input: RMS and Hausdorff (largest) over area-uniform samples
//       and the vertices of both surfaces, relative to the input's bounding
//       box diagonal. Also the output's degenerate triangles, non-manifold
//       elements, components and border edges against the input's.
//   psq_bench_qem meshopt [--ratio R] MESH
//       Times meshopt_simplify alone on MESH (loaded first) and prints
//       input triangles per second and the process's peak memory.
#include <meshoptimizer.h>
#include <sys/resource.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "psq/mesh_formats.h"
#include "psq/ply.h"
#include "psq/sequence_builder.h"
#include "psq/sequence_check.h"
#include "psq/stream_qem.h"

namespace {

using Vec = std::array<double, 3>;

struct Mesh {
  std::vector<float> positions;  // xyz
  std::vector<uint32_t> indices;
  size_t vertices() const { return positions.size() / 3; }
  size_t triangles() const { return indices.size() / 3; }
  Vec pos(uint32_t v) const { return {positions[3 * v], positions[3 * v + 1], positions[3 * v + 2]}; }
};

class Collect : public psq::MeshSink {
 public:
  explicit Collect(Mesh* m) : m_(m) {}
  psq::Status begin(const psq::MeshSchema&) override { return psq::Status(); }
  psq::Status vertex(const double p[3], const psq::PropertyValues&) override {
    for (int i = 0; i < 3; ++i) m_->positions.push_back(static_cast<float>(p[i]));
    return psq::Status();
  }
  psq::Status triangle(const uint32_t idx[3], const psq::PropertyValues&) override {
    m_->indices.insert(m_->indices.end(), idx, idx + 3);
    return psq::Status();
  }
  psq::Status finish() override { return psq::Status(); }

 private:
  Mesh* m_;
};

class ArraySource : public psq::MeshSource {
 public:
  explicit ArraySource(const Mesh& m) : m_(m) {
    schema_.vertex_count = static_cast<int64_t>(m.vertices());
    schema_.triangle_count = static_cast<int64_t>(m.triangles());
  }
  const psq::MeshSchema& schema() const override { return schema_; }
  const psq::SourceReport& report() const override { return report_; }
  psq::Status next(psq::MeshItem* item) override {
    if (at_ < m_.vertices()) {
      item->kind = psq::MeshItem::Kind::kVertex;
      for (int i = 0; i < 3; ++i) item->position[i] = m_.positions[3 * at_ + i];
      item->values.clear();
      ++at_;
    } else if (at_ < m_.vertices() + m_.triangles()) {
      const size_t t = at_ - m_.vertices();
      item->kind = psq::MeshItem::Kind::kTriangle;
      for (int i = 0; i < 3; ++i) item->index[i] = m_.indices[3 * t + i];
      item->values.clear();
      ++at_;
    } else {
      item->kind = psq::MeshItem::Kind::kEnd;
    }
    return psq::Status();
  }

 private:
  const Mesh& m_;
  psq::MeshSchema schema_;
  psq::SourceReport report_;
  size_t at_ = 0;
};

// Records a processing sequence so that it can be replayed (timed) later.
class Recorder : public psq::SequenceSink {
 public:
  psq::Status begin(const psq::MeshSchema& s) override {
    schema = s;
    return psq::Status();
  }
  psq::Status vertex(const psq::SequenceVertex& v) override {
    psq::SequenceEvent e;
    e.kind = psq::SequenceEvent::Kind::kVertex;
    e.vertex = v;
    events.push_back(std::move(e));
    return psq::Status();
  }
  psq::Status triangle(const psq::SequenceTriangle& t) override {
    psq::SequenceEvent e;
    e.kind = psq::SequenceEvent::Kind::kTriangle;
    e.triangle = t;
    events.push_back(std::move(e));
    return psq::Status();
  }
  psq::Status finalize(uint32_t i) override {
    psq::SequenceEvent e;
    e.kind = psq::SequenceEvent::Kind::kFinalize;
    e.finalized = i;
    events.push_back(std::move(e));
    return psq::Status();
  }
  psq::Status finish() override { return psq::Status(); }
  psq::Status replay(psq::SequenceSink& sink) const {
    PSQ_RETURN_IF_ERROR(sink.begin(schema));
    for (const psq::SequenceEvent& e : events) {
      if (e.kind == psq::SequenceEvent::Kind::kVertex) PSQ_RETURN_IF_ERROR(sink.vertex(e.vertex));
      else if (e.kind == psq::SequenceEvent::Kind::kTriangle) PSQ_RETURN_IF_ERROR(sink.triangle(e.triangle));
      else PSQ_RETURN_IF_ERROR(sink.finalize(e.finalized));
    }
    return sink.finish();
  }
  psq::MeshSchema schema;
  std::vector<psq::SequenceEvent> events;
};

// A sequence into a Mesh (re-appearing vertices kept apart) and a checker.
class SequenceCollect : public psq::SequenceSink {
 public:
  explicit SequenceCollect(Mesh* m) : m_(m) {}
  psq::Status begin(const psq::MeshSchema& s) override { return checker.begin(s); }
  psq::Status vertex(const psq::SequenceVertex& v) override {
    for (int i = 0; i < 3; ++i) m_->positions.push_back(static_cast<float>(v.position[i]));
    return checker.vertex(v);
  }
  psq::Status triangle(const psq::SequenceTriangle& t) override {
    m_->indices.insert(m_->indices.end(), t.v, t.v + 3);
    return checker.triangle(t);
  }
  psq::Status finalize(uint32_t i) override { return checker.finalize(i); }
  psq::Status finish() override { return checker.finish(); }
  psq::SequenceChecker checker;

 private:
  Mesh* m_;
};

Vec sub(const Vec& a, const Vec& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
double dot(const Vec& a, const Vec& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
Vec cross(const Vec& a, const Vec& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
Vec axpy(double s, const Vec& a, const Vec& b) { return {b[0] + s * a[0], b[1] + s * a[1], b[2] + s * a[2]}; }

// Closest point on triangle abc to p (Ericson, Real-Time Collision
// Detection, 5.1.5); returns the squared distance.
double point_triangle_d2(const Vec& p, const Vec& a, const Vec& b, const Vec& c) {
  const Vec ab = sub(b, a), ac = sub(c, a), ap = sub(p, a);
  const double d1 = dot(ab, ap), d2 = dot(ac, ap);
  Vec q;
  if (d1 <= 0 && d2 <= 0) {
    q = a;
  } else {
    const Vec bp = sub(p, b);
    const double d3 = dot(ab, bp), d4 = dot(ac, bp);
    if (d3 >= 0 && d4 <= d3) {
      q = b;
    } else {
      const double vc = d1 * d4 - d3 * d2;
      if (vc <= 0 && d1 >= 0 && d3 <= 0) {
        q = axpy(d1 / (d1 - d3), ab, a);
      } else {
        const Vec cp = sub(p, c);
        const double d5 = dot(ab, cp), d6 = dot(ac, cp);
        if (d6 >= 0 && d5 <= d6) {
          q = c;
        } else {
          const double vb = d5 * d2 - d1 * d6;
          if (vb <= 0 && d2 >= 0 && d6 <= 0) {
            q = axpy(d2 / (d2 - d6), ac, a);
          } else {
            const double va = d3 * d6 - d5 * d4;
            if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
              q = axpy((d4 - d3) / ((d4 - d3) + (d5 - d6)), sub(c, b), b);
            } else {
              const double denom = 1 / (va + vb + vc);
              const double v = vb * denom, w = vc * denom;
              q = axpy(w, ac, axpy(v, ab, a));
            }
          }
        }
      }
    }
  }
  const Vec d = sub(p, q);
  return dot(d, d);
}

// A uniform grid of triangles for nearest-point queries.
class Grid {
 public:
  Grid(const Mesh& m, const Vec& lo, const Vec& hi) : m_(m), lo_(lo) {
    const Vec ext = sub(hi, lo);
    const double vol = std::max(ext[0], 1e-30) * std::max(ext[1], 1e-30) * std::max(ext[2], 1e-30);
    const double cells = std::max<double>(1.0, std::min<double>(2.0 * m.triangles(), 1 << 24));
    h_ = std::cbrt(vol / cells);
    const double maxe = std::max({ext[0], ext[1], ext[2]});
    h_ = std::max(h_, maxe / 1024);
    if (!(h_ > 0)) h_ = 1;
    for (int i = 0; i < 3; ++i) n_[i] = std::max(1, static_cast<int>(std::ceil(ext[i] / h_)) + 1);
    std::vector<uint32_t> count(static_cast<size_t>(n_[0]) * n_[1] * n_[2] + 1, 0);
    auto each_cell = [&](size_t t, auto&& f) {
      int lo_c[3], hi_c[3];
      for (int i = 0; i < 3; ++i) {
        double a = m.positions[3 * m.indices[3 * t] + i], b = m.positions[3 * m.indices[3 * t + 1] + i],
               c = m.positions[3 * m.indices[3 * t + 2] + i];
        lo_c[i] = cell(std::min({a, b, c}), i);
        hi_c[i] = cell(std::max({a, b, c}), i);
      }
      for (int z = lo_c[2]; z <= hi_c[2]; ++z)
        for (int y = lo_c[1]; y <= hi_c[1]; ++y)
          for (int x = lo_c[0]; x <= hi_c[0]; ++x) f(index(x, y, z));
    };
    for (size_t t = 0; t < m.triangles(); ++t) each_cell(t, [&](size_t c) { ++count[c + 1]; });
    for (size_t i = 1; i < count.size(); ++i) count[i] += count[i - 1];
    start_ = count;
    items_.resize(count.back());
    for (size_t t = 0; t < m.triangles(); ++t)
      each_cell(t, [&](size_t c) { items_[count[c]++] = static_cast<uint32_t>(t); });
    seen_.assign(m.triangles(), 0);
  }

  double nearest_d2(const Vec& p) {
    int c[3];
    for (int i = 0; i < 3; ++i) c[i] = cell(p[i], i);
    double best = INFINITY;
    ++stamp_;
    const int rmax = std::max({n_[0], n_[1], n_[2]});
    for (int r = 0; r <= rmax; ++r) {
      // Cells at Chebyshev distance r from p's cell are at least (r - 1) h away.
      if (r >= 1 && (r - 1) * h_ * (r - 1) * h_ > best) break;
      for (int z = c[2] - r; z <= c[2] + r; ++z) {
        if (z < 0 || z >= n_[2]) continue;
        for (int y = c[1] - r; y <= c[1] + r; ++y) {
          if (y < 0 || y >= n_[1]) continue;
          const bool face = std::abs(z - c[2]) == r || std::abs(y - c[1]) == r;
          for (int x = c[0] - r; x <= c[0] + r; x += (face ? 1 : std::max(1, 2 * r))) {
            if (x < 0 || x >= n_[0]) continue;
            const size_t ci = index(x, y, z);
            for (uint32_t k = start_[ci]; k < start_[ci + 1]; ++k) {
              const uint32_t t = items_[k];
              if (seen_[t] == stamp_) continue;
              seen_[t] = stamp_;
              const double d2 = point_triangle_d2(p, m_.pos(m_.indices[3 * t]), m_.pos(m_.indices[3 * t + 1]),
                                                  m_.pos(m_.indices[3 * t + 2]));
              best = std::min(best, d2);
            }
          }
        }
      }
    }
    return best;
  }

 private:
  int cell(double v, int axis) const {
    const int c = static_cast<int>(std::floor((v - lo_[axis]) / h_));
    return std::clamp(c, 0, n_[axis] - 1);
  }
  size_t index(int x, int y, int z) const { return (static_cast<size_t>(z) * n_[1] + y) * n_[0] + x; }

  const Mesh& m_;
  Vec lo_;
  double h_ = 1;
  int n_[3] = {1, 1, 1};
  std::vector<uint32_t> start_, items_, seen_;
  uint32_t stamp_ = 0;
};

void bounds(const Mesh& m, Vec* lo, Vec* hi) {
  *lo = {INFINITY, INFINITY, INFINITY};
  *hi = {-INFINITY, -INFINITY, -INFINITY};
  for (size_t v = 0; v < m.vertices(); ++v)
    for (int i = 0; i < 3; ++i) {
      (*lo)[i] = std::min((*lo)[i], static_cast<double>(m.positions[3 * v + i]));
      (*hi)[i] = std::max((*hi)[i], static_cast<double>(m.positions[3 * v + i]));
    }
}

// Points on `m`: its referenced vertices and `n` samples uniform by area.
std::vector<Vec> samples(const Mesh& m, size_t n, uint32_t seed) {
  std::vector<Vec> out;
  std::vector<char> used(m.vertices(), 0);
  for (uint32_t i : m.indices) used[i] = 1;
  for (size_t v = 0; v < m.vertices(); ++v)
    if (used[v]) out.push_back(m.pos(static_cast<uint32_t>(v)));
  std::vector<double> cum(m.triangles() + 1, 0);
  for (size_t t = 0; t < m.triangles(); ++t) {
    const Vec a = m.pos(m.indices[3 * t]), b = m.pos(m.indices[3 * t + 1]), c = m.pos(m.indices[3 * t + 2]);
    const Vec n3 = cross(sub(b, a), sub(c, a));
    cum[t + 1] = cum[t] + std::sqrt(dot(n3, n3));
  }
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  for (size_t i = 0; i < n && cum.back() > 0; ++i) {
    const double r = u(rng) * cum.back();
    size_t t = static_cast<size_t>(std::upper_bound(cum.begin(), cum.end(), r) - cum.begin());
    t = std::min(std::max<size_t>(t, 1), m.triangles()) - 1;
    double s1 = u(rng), s2 = u(rng);
    if (s1 + s2 > 1) {
      s1 = 1 - s1;
      s2 = 1 - s2;
    }
    const Vec a = m.pos(m.indices[3 * t]), b = m.pos(m.indices[3 * t + 1]), c = m.pos(m.indices[3 * t + 2]);
    out.push_back(axpy(s2, sub(c, a), axpy(s1, sub(b, a), a)));
  }
  return out;
}

struct Distance {
  double rms = 0, hausdorff = 0;
};

// Symmetric: samples of each surface against the other.
Distance distance(const Mesh& a, const Mesh& b, size_t n, double diag) {
  Vec lo, hi, lo2, hi2;
  bounds(a, &lo, &hi);
  bounds(b, &lo2, &hi2);
  for (int i = 0; i < 3; ++i) {
    lo[i] = std::min(lo[i], lo2[i]);
    hi[i] = std::max(hi[i], hi2[i]);
  }
  Grid ga(a, lo, hi), gb(b, lo, hi);
  double sum = 0, worst = 0;
  size_t count = 0;
  for (const Vec& p : samples(a, n, 1)) {
    const double d2 = gb.nearest_d2(p);
    sum += d2;
    worst = std::max(worst, d2);
    ++count;
  }
  double sum_b = 0;
  size_t count_b = 0;
  for (const Vec& p : samples(b, n, 2)) {
    const double d2 = ga.nearest_d2(p);
    sum_b += d2;
    worst = std::max(worst, d2);
    ++count_b;
  }
  Distance d;
  // RMS of each direction, the larger (each direction weighs its own
  // samples: a coarse mesh has few vertices).
  d.rms = std::sqrt(std::max(sum / std::max<size_t>(count, 1), sum_b / std::max<size_t>(count_b, 1))) / diag;
  d.hausdorff = std::sqrt(worst) / diag;
  return d;
}

bool load(const std::string& path, Mesh* m) {
  psq::OpenedMesh mesh;
  psq::Status s = psq::open_mesh(path, psq::OpenOptions(), &mesh);
  Collect c(m);
  if (s.ok()) s = psq::pump(*mesh.source, c);
  if (!s.ok()) {
    std::fprintf(stderr, "%s: %s\n", path.c_str(), s.to_string().c_str());
    return false;
  }
  return true;
}

double now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

size_t degenerate(const Mesh& m) {
  size_t n = 0;
  for (size_t t = 0; t < m.triangles(); ++t) {
    const Vec a = m.pos(m.indices[3 * t]), b = m.pos(m.indices[3 * t + 1]), c = m.pos(m.indices[3 * t + 2]);
    const Vec n3 = cross(sub(b, a), sub(c, a));
    if (dot(n3, n3) == 0) ++n;
  }
  return n;
}

struct Topology {
  uint64_t components = 0, border = 0, nm_vertices = 0, nm_edges = 0;
  int64_t handles = 0;
};

Topology topology(const Mesh& m) {
  Recorder rec;
  ArraySource src(m);
  psq::BuildReport report;
  psq::SequenceChecker checker;
  psq::Status s = psq::build_sequence(src, checker, psq::BuildOptions(), &report);
  Topology t;
  if (!s.ok()) return t;
  const psq::SequenceStats& st = checker.stats();
  t.components = st.components;
  t.border = st.border_edges;
  t.nm_vertices = st.nonmanifold_vertices;
  t.nm_edges = st.nonmanifold_edges;
  t.handles = st.handles;
  return t;
}

Mesh meshopt_run(const Mesh& in, double ratio, double* seconds) {
  Mesh out;
  out.positions = in.positions;
  out.indices.resize(in.indices.size());
  const size_t target = static_cast<size_t>(ratio * in.triangles()) * 3;
  const double t0 = now();
  const size_t n = meshopt_simplify(out.indices.data(), in.indices.data(), in.indices.size(), in.positions.data(),
                                    in.vertices(), 12, target, 1e30f, 0, nullptr);
  *seconds = now() - t0;
  out.indices.resize(n);
  return out;
}

Mesh psq_run(const Recorder& seq, size_t input_triangles, size_t target, uint32_t buffer, int candidates,
             uint64_t seed, double* seconds, psq::QemReport* report) {
  Mesh out;
  SequenceCollect collect(&out);
  psq::QemOptions o;
  o.target_triangles = target;
  o.input_triangles = input_triangles;
  o.buffer_triangles = buffer;
  o.candidates = candidates;
  o.seed = seed;
  psq::StreamQem qem(&collect, o);
  const double t0 = now();
  psq::Status s = seq.replay(qem);
  *seconds = now() - t0;
  if (!s.ok()) std::fprintf(stderr, "psq simplify --method qem: %s\n", s.to_string().c_str());
  *report = qem.report();
  return out;
}

std::vector<double> parse_list(const std::string& s) {
  std::vector<double> v;
  size_t at = 0;
  while (at < s.size()) {
    size_t comma = s.find(',', at);
    if (comma == std::string::npos) comma = s.size();
    v.push_back(std::atof(s.substr(at, comma - at).c_str()));
    at = comma + 1;
  }
  return v;
}

long peak_rss_kb() {
  struct rusage u;
  getrusage(RUSAGE_SELF, &u);
  return u.ru_maxrss;
}

int quality(int argc, char** argv) {
  std::vector<double> ratios = {0.1, 0.01};
  uint32_t buffer = 0;
  int candidates = 8;
  size_t nsamples = 200000;
  uint64_t seed = 1;
  std::vector<std::string> files;
  for (int i = 0; i < argc; ++i) {
    std::string a = argv[i];
    if (a == "--ratios" && i + 1 < argc) ratios = parse_list(argv[++i]);
    else if (a == "--buffer" && i + 1 < argc) buffer = static_cast<uint32_t>(std::atol(argv[++i]));
    else if (a == "--candidates" && i + 1 < argc) candidates = std::atoi(argv[++i]);
    else if (a == "--samples" && i + 1 < argc) nsamples = static_cast<size_t>(std::atol(argv[++i]));
    else if (a == "--seed" && i + 1 < argc) seed = std::strtoull(argv[++i], nullptr, 10);
    else files.push_back(a);
  }
  std::printf("%-24s %9s %6s %8s | %9s %9s | %9s %9s %5s %5s | %9s %9s %5s %5s | %s\n", "mesh", "T", "ratio", "out",
              "mo_rms", "mo_haus", "psq_rms", "psq_haus", "r_rms", "r_h", "buf_rms", "buf_haus", "r_rms", "r_h",
              "topology in -> psq (comp/border/handles/nmv/nme), degenerate");
  for (const std::string& f : files) {
    Mesh in;
    if (!load(f, &in)) return 1;
    Vec lo, hi;
    bounds(in, &lo, &hi);
    const Vec ext = sub(hi, lo);
    const double diag = std::sqrt(dot(ext, ext));
    Recorder seq;
    {
      ArraySource src(in);
      psq::BuildReport br;
      psq::Status s = psq::build_sequence(src, seq, psq::BuildOptions(), &br);
      if (!s.ok()) {
        std::fprintf(stderr, "%s: %s\n", f.c_str(), s.to_string().c_str());
        return 1;
      }
    }
    const Topology tin = topology(in);
    std::string name = f.substr(f.find_last_of('/') + 1);
    for (double ratio : ratios) {
      double tm = 0, tp = 0, tb = 0;
      Mesh mo = meshopt_run(in, ratio, &tm);
      psq::QemReport rep, rep_b;
      Mesh ps = psq_run(seq, in.triangles(), mo.triangles(), 1u << 28, candidates, seed, &tp, &rep);
      const Distance dm = distance(in, mo, nsamples, diag);
      const Distance dp = distance(in, ps, nsamples, diag);
      Distance db;
      if (buffer) {
        Mesh pb = psq_run(seq, in.triangles(), mo.triangles(), buffer, candidates, seed, &tb, &rep_b);
        db = distance(in, pb, nsamples, diag);
      }
      const Topology tout = topology(ps);
      const Topology tmo = topology(mo);
      std::printf("%-24s %9zu %6.3f %8zu | %9.3g %9.3g | %9.3g %9.3g %5.2f %5.2f | %9.3g %9.3g %5.2f %5.2f | "
                  "%llu/%llu/%lld/%llu/%llu -> %llu/%llu/%lld/%llu/%llu, %zu; psq %zu tris %.2fs, meshopt %.2fs; "
                  "meshopt %llu/%llu/%lld/%llu/%llu\n",
                  name.c_str(), in.triangles(), ratio, mo.triangles(), dm.rms, dm.hausdorff, dp.rms, dp.hausdorff,
                  dp.rms / dm.rms, dp.hausdorff / dm.hausdorff, db.rms, db.hausdorff, buffer ? db.rms / dm.rms : 0.0,
                  buffer ? db.hausdorff / dm.hausdorff : 0.0, (unsigned long long)tin.components,
                  (unsigned long long)tin.border, (long long)tin.handles, (unsigned long long)tin.nm_vertices,
                  (unsigned long long)tin.nm_edges, (unsigned long long)tout.components,
                  (unsigned long long)tout.border, (long long)tout.handles, (unsigned long long)tout.nm_vertices,
                  (unsigned long long)tout.nm_edges, degenerate(ps), ps.triangles(), tp, tm,
                  (unsigned long long)tmo.components, (unsigned long long)tmo.border, (long long)tmo.handles,
                  (unsigned long long)tmo.nm_vertices, (unsigned long long)tmo.nm_edges);
      std::fflush(stdout);
    }
  }
  return 0;
}

int meshopt_speed(int argc, char** argv) {
  double ratio = 0.01;
  std::string file;
  for (int i = 0; i < argc; ++i) {
    std::string a = argv[i];
    if (a == "--ratio" && i + 1 < argc) ratio = std::atof(argv[++i]);
    else file = a;
  }
  Mesh in;
  if (!load(file, &in)) return 1;
  const long before = peak_rss_kb();
  double seconds = 0;
  Mesh out = meshopt_run(in, ratio, &seconds);
  std::printf("meshopt_simplify %s: %zu -> %zu triangles in %.2f s, %.2f M input triangles/s; peak RSS %.0f MiB "
              "(%.0f MiB after loading)\n",
              file.c_str(), in.triangles(), out.triangles(), seconds, in.triangles() / seconds / 1e6,
              peak_rss_kb() / 1024.0, before / 1024.0);
  return 0;
}

// Smallest angle of each triangle, in degrees.
std::vector<double> min_angles(const Mesh& m) {
  std::vector<double> out;
  for (size_t t = 0; t < m.triangles(); ++t) {
    const Vec p[3] = {m.pos(m.indices[3 * t]), m.pos(m.indices[3 * t + 1]), m.pos(m.indices[3 * t + 2])};
    double least = 180;
    for (int k = 0; k < 3; ++k) {
      const Vec u = sub(p[(k + 1) % 3], p[k]), w = sub(p[(k + 2) % 3], p[k]);
      const double d = std::sqrt(dot(u, u) * dot(w, w));
      const double c = d > 0 ? std::clamp(dot(u, w) / d, -1.0, 1.0) : 1.0;
      least = std::min(least, std::acos(c) * 180 / M_PI);
    }
    out.push_back(least);
  }
  std::sort(out.begin(), out.end());
  return out;
}

int shape(int argc, char** argv) {
  for (int i = 0; i < argc; ++i) {
    Mesh m;
    if (!load(argv[i], &m)) return 1;
    const std::vector<double> a = min_angles(m);
    auto pct = [&](double q) { return a.empty() ? 0.0 : a[static_cast<size_t>(q * (a.size() - 1))]; };
    size_t below = 0;
    while (below < a.size() && a[below] < 1) ++below;
    std::printf("%s: %zu triangles, smallest angle at percentiles 1, 5, 25, 50: %.2f %.2f %.2f %.2f degrees; %zu "
                "below 1 degree\n",
                argv[i], m.triangles(), pct(0.01), pct(0.05), pct(0.25), pct(0.5), below);
  }
  return 0;
}

// Per slab of the sweep (the axis along which the input sequence advances,
// cut into slabs of equal input triangle counts): the output's triangle
// density (output over input triangles) and RMS distance, against their
// medians over the slabs.
int slabs(int argc, char** argv) {
  double ratio = 0.01;
  uint32_t buffer = 0;
  int count = 20;
  size_t nsamples = 400000;
  std::string file;
  for (int i = 0; i < argc; ++i) {
    std::string a = argv[i];
    if (a == "--ratio" && i + 1 < argc) ratio = std::atof(argv[++i]);
    else if (a == "--buffer" && i + 1 < argc) buffer = static_cast<uint32_t>(std::atol(argv[++i]));
    else if (a == "--slabs" && i + 1 < argc) count = std::atoi(argv[++i]);
    else if (a == "--samples" && i + 1 < argc) nsamples = static_cast<size_t>(std::atol(argv[++i]));
    else file = a;
  }
  Mesh in;
  if (!load(file, &in)) return 1;
  Recorder seq;
  {
    ArraySource src(in);
    psq::BuildReport br;
    psq::Status s = psq::build_sequence(src, seq, psq::BuildOptions(), &br);
    if (!s.ok()) return 1;
  }
  // The sweep axis: the coordinate that best follows the order in which
  // the sequence introduces vertices.
  int axis = 0;
  {
    double best = -1;
    for (int a = 0; a < 3; ++a) {
      double n = 0, si = 0, sc = 0, sii = 0, scc = 0, sic = 0;
      for (const psq::SequenceEvent& e : seq.events) {
        if (e.kind != psq::SequenceEvent::Kind::kVertex) continue;
        const double i = n, c = e.vertex.position[a];
        n += 1, si += i, sc += c, sii += i * i, scc += c * c, sic += i * c;
      }
      const double cov = sic / n - si / n * sc / n;
      const double r = std::fabs(cov) / std::sqrt((sii / n - si / n * si / n) * (scc / n - sc / n * sc / n) + 1e-300);
      if (r > best) {
        best = r;
        axis = a;
      }
    }
  }
  double seconds = 0;
  psq::QemReport rep;
  Mesh out = psq_run(seq, in.triangles(), static_cast<size_t>(ratio * in.triangles()), buffer, 8, 1, &seconds, &rep);
  auto centroid = [&](const Mesh& m, size_t t) {
    return (m.positions[3 * m.indices[3 * t] + axis] + m.positions[3 * m.indices[3 * t + 1] + axis] +
            m.positions[3 * m.indices[3 * t + 2] + axis]) / 3.0;
  };
  std::vector<double> cs(in.triangles());
  for (size_t t = 0; t < in.triangles(); ++t) cs[t] = centroid(in, t);
  std::vector<double> sorted = cs;
  std::sort(sorted.begin(), sorted.end());
  std::vector<double> cut(count + 1);
  for (int k = 0; k <= count; ++k) cut[k] = sorted[std::min(sorted.size() - 1, sorted.size() * k / count)];
  cut[0] = -INFINITY;
  cut[count] = INFINITY;
  auto slab_of = [&](double c) {
    int k = static_cast<int>(std::upper_bound(cut.begin(), cut.end(), c) - cut.begin()) - 1;
    return std::clamp(k, 0, count - 1);
  };
  std::vector<double> tin(count, 0), tout(count, 0), sum(count, 0), n(count, 0);
  for (size_t t = 0; t < in.triangles(); ++t) tin[slab_of(cs[t])] += 1;
  for (size_t t = 0; t < out.triangles(); ++t) tout[slab_of(centroid(out, t))] += 1;
  Vec lo, hi, lo2, hi2;
  bounds(in, &lo, &hi);
  bounds(out, &lo2, &hi2);
  const Vec ext = sub(hi, lo);
  const double diag = std::sqrt(dot(ext, ext));
  for (int i = 0; i < 3; ++i) {
    lo[i] = std::min(lo[i], lo2[i]);
    hi[i] = std::max(hi[i], hi2[i]);
  }
  Grid gin(in, lo, hi), gout(out, lo, hi);
  for (const Vec& p : samples(out, nsamples, 3)) {
    const int k = slab_of(p[axis]);
    sum[k] += gin.nearest_d2(p);
    n[k] += 1;
  }
  for (const Vec& p : samples(in, nsamples, 4)) {
    const int k = slab_of(p[axis]);
    sum[k] += gout.nearest_d2(p);
    n[k] += 1;
  }
  std::vector<double> density(count), rms(count);
  for (int k = 0; k < count; ++k) {
    density[k] = tout[k] / std::max(1.0, tin[k]);
    rms[k] = std::sqrt(sum[k] / std::max(1.0, n[k])) / diag;
  }
  auto median = [](std::vector<double> v) {
    std::sort(v.begin(), v.end());
    return v[v.size() / 2];
  };
  const double md = median(density), mr = median(rms);
  double worst_d = 0, worst_r = 0;
  std::printf("%s: %zu -> %zu triangles (buffer %u, largest %llu), sweep axis %c, %d slabs\n", file.c_str(),
              in.triangles(), out.triangles(), rep.buffer_triangles, (unsigned long long)rep.max_buffer_triangles,
              "xyz"[axis], count);
  for (int k = 0; k < count; ++k) {
    std::printf("  slab %2d: density %.4f (%.2f of median), RMS %.3g (%.2f of median)\n", k, density[k],
                density[k] / md, rms[k], rms[k] / mr);
    worst_d = std::max({worst_d, density[k] / md, md / std::max(density[k], 1e-300)});
    worst_r = std::max({worst_r, rms[k] / mr, mr / std::max(rms[k], 1e-300)});
  }
  std::printf("  worst slab: density %.2f, RMS %.2f times (or a fraction) of the median\n", worst_d, worst_r);
  return 0;
}

// The symmetric distance between two meshes, relative to the first's
// bounding box diagonal.
int distance_of(int argc, char** argv) {
  if (argc != 2) return 2;
  Mesh a, b;
  if (!load(argv[0], &a) || !load(argv[1], &b)) return 1;
  Vec lo, hi;
  bounds(a, &lo, &hi);
  const Vec ext = sub(hi, lo);
  const Distance d = distance(a, b, 200000, std::sqrt(dot(ext, ext)));
  std::printf("%s -> %s (%zu -> %zu triangles): RMS %.4g, Hausdorff %.4g of the diagonal\n", argv[0], argv[1],
              a.triangles(), b.triangles(), d.rms, d.hausdorff);
  if (std::getenv("PSQ_BENCH_WORST")) {
    Vec lo2, hi2;
    bounds(b, &lo2, &hi2);
    for (int i = 0; i < 3; ++i) {
      lo[i] = std::min(lo[i], lo2[i]);
      hi[i] = std::max(hi[i], hi2[i]);
    }
    Grid ga(a, lo, hi), gb(b, lo, hi);
    double worst = 0;
    Vec at{};
    const char* side = "";
    for (const Vec& p : samples(a, 200000, 1)) {
      const double d2 = gb.nearest_d2(p);
      if (d2 > worst) worst = d2, at = p, side = "input point far from output";
    }
    for (const Vec& p : samples(b, 200000, 2)) {
      const double d2 = ga.nearest_d2(p);
      if (d2 > worst) worst = d2, at = p, side = "output point far from input";
    }
    std::printf("  worst: %s at %.6g %.6g %.6g, distance %.4g\n", side, at[0], at[1], at[2], std::sqrt(worst));
    std::vector<std::pair<double, uint32_t>> far;
    for (uint32_t v = 0; v < b.vertices(); ++v) far.push_back({std::sqrt(ga.nearest_d2(b.pos(v))), v});
    std::sort(far.rbegin(), far.rend());
    for (size_t i = 0; i < 8 && i < far.size(); ++i) {
      const Vec p = b.pos(far[i].second);
      std::printf("  output vertex %u at %.6g %.6g %.6g: %.4g from the input\n", far[i].second, p[0], p[1], p[2],
                  far[i].first);
    }
  }
  return 0;
}

// Writes MESH with each vertex moved along its normal by Gaussian noise of
// SIGMA times the mean edge length (a "scan" of a clean mesh).
int noise(int argc, char** argv) {
  if (argc != 3) return 2;
  Mesh m;
  if (!load(argv[0], &m)) return 1;
  const double sigma = std::atof(argv[2]);
  std::vector<Vec> normal(m.vertices(), Vec{0, 0, 0});
  double edges = 0;
  for (size_t t = 0; t < m.triangles(); ++t) {
    const uint32_t* i = &m.indices[3 * t];
    const Vec a = m.pos(i[0]), b = m.pos(i[1]), c = m.pos(i[2]);
    const Vec n = cross(sub(b, a), sub(c, a));
    for (int k = 0; k < 3; ++k)
      for (int j = 0; j < 3; ++j) normal[i[k]][j] += n[j];
    edges += std::sqrt(dot(sub(b, a), sub(b, a))) + std::sqrt(dot(sub(c, b), sub(c, b))) +
             std::sqrt(dot(sub(a, c), sub(a, c)));
  }
  const double step = sigma * edges / std::max<size_t>(1, 3 * m.triangles());
  std::mt19937_64 rng(7);
  std::normal_distribution<double> g(0, 1);
  psq::OutputFile out;
  psq::Status s = out.open(argv[1], true);
  psq::PlyWriter w(&out);
  psq::MeshSchema schema;
  schema.vertex_count = static_cast<int64_t>(m.vertices());
  schema.triangle_count = static_cast<int64_t>(m.triangles());
  if (s.ok()) s = w.begin(schema);
  for (size_t v = 0; v < m.vertices() && s.ok(); ++v) {
    const Vec n = normal[v];
    const double l = std::sqrt(dot(n, n));
    const double d = g(rng) * step;
    Vec p = m.pos(static_cast<uint32_t>(v));
    if (l > 0)
      for (int j = 0; j < 3; ++j) p[j] += d * n[j] / l;
    const double q[3] = {static_cast<float>(p[0]), static_cast<float>(p[1]), static_cast<float>(p[2])};
    s = w.vertex(q, {});
  }
  for (size_t t = 0; t < m.triangles() && s.ok(); ++t) s = w.triangle(&m.indices[3 * t], {});
  if (s.ok()) s = w.finish();
  if (s.ok()) s = out.commit();
  if (!s.ok()) std::fprintf(stderr, "%s\n", s.to_string().c_str());
  return s.ok() ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc >= 2 && std::strcmp(argv[1], "noise") == 0) return noise(argc - 2, argv + 2);
  if (argc >= 2 && std::strcmp(argv[1], "distance") == 0) return distance_of(argc - 2, argv + 2);
  if (argc >= 2 && std::strcmp(argv[1], "slabs") == 0) return slabs(argc - 2, argv + 2);
  if (argc >= 2 && std::strcmp(argv[1], "shape") == 0) return shape(argc - 2, argv + 2);
  if (argc >= 2 && std::strcmp(argv[1], "quality") == 0) return quality(argc - 2, argv + 2);
  if (argc >= 2 && std::strcmp(argv[1], "meshopt") == 0) return meshopt_speed(argc - 2, argv + 2);
  std::fprintf(stderr, "usage: psq_bench_qem quality [OPTIONS] MESH... | meshopt [--ratio R] MESH\n");
  return 2;
}
