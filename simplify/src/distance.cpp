// SPDX-License-Identifier: Apache-2.0
// The surface distance between two meshes (psq/distance.h), after Metro:
// P. Cignoni, C. Rocchini, R. Scopigno, "Metro: measuring error on
// simplified surfaces", Computer Graphics Forum 17(2), 1998. As in Metro,
// a direction samples one surface (its vertices, then points on its faces
// spread by area) and takes each sample's distance to the nearest point of
// the other surface, found through a spatial index over its faces.
//
// The distance from a point to a triangle follows the triangle's Voronoi
// regions, as in C. Ericson, "Real-Time Collision Detection" (2005), 5.1.5,
// and D. Eberly, "Distance between point and triangle in 3D" (1999): when
// the point's projection falls inside the triangle the distance is the one
// to its plane; otherwise the nearest point lies on an edge that the
// projection sees from outside (a negative barycentric weight), and the
// distance is the smallest to those edges' segments. Triangles that are
// (nearly) segments are measured by their three edges.
//
// The streaming direction (psq/distance.h, "Size") inverts the usual
// query: the held mesh's samples sit in a BVH whose nodes carry the largest
// current distance bound below them; each batch of streamed triangles gets
// a BVH of its own, and the two trees are descended together (a dual-tree
// traversal), a pair of nodes dropped when they are farther apart than the
// sample node's bound; under a leaf of samples each sample searches the
// batch's subtree within its own bound. Both paths take, per sample, the
// minimum of the same function over every triangle that could attain it
// (every pruning test leaves a margin far above the rounding error), so
// both give the same bits.
#include "psq/distance.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstring>
#include <functional>
#include <limits>
#include <memory>
#include <mutex>
#include <numeric>
#include <thread>

#include "psq/io.h"

namespace psq {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr uint32_t kNone = 0xffffffffu;
// Pruning margin and the distance that counts as 0, as fractions of the
// largest coordinate magnitude: double rounding is ~2^-52 of it; the
// margin stays far above every rounding error of the tests it guards.
constexpr double kMarginScale = 0x1p-26;
constexpr double kZeroScale = 0x1p-40;
// Triangles per streamed batch, and samples per window that is measured
// at once (the memory of the streamed side's samples).
constexpr size_t kBatchTriangles = size_t{1} << 16;
constexpr size_t kWindowSamples = size_t{1} << 18;
constexpr uint32_t kTriangleLeaf = 4;
// The streamed mesh's vertices that give the held samples their first
// distance bounds (at most; a BVH of 28 bytes and more a vertex, while it
// is used).
constexpr uint64_t kBoundVertices = uint64_t{4} << 20;
constexpr uint32_t kSampleLeaf = 8;

// ------------------------------------------------------------------ geometry

struct V3 {
  double x, y, z;
};
inline V3 sub(const V3& a, const V3& b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
inline double dot(const V3& a, const V3& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline V3 cross(const V3& a, const V3& b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
inline bool same(const V3& a, const V3& b) { return a.x == b.x && a.y == b.y && a.z == b.z; }
inline V3 load3(const double* p) { return {p[0], p[1], p[2]}; }
inline double sq(double v) { return v * v; }

double triangle_area(const V3& a, const V3& b, const V3& c) {
  V3 n = cross(sub(b, a), sub(c, a));
  return 0.5 * std::sqrt(dot(n, n));
}

// Squared distance from p to the segment ab (a point when a == b).
double segment_d2(const V3& p, const V3& a, const V3& b) {
  V3 ab = sub(b, a), ap = sub(p, a);
  double len2 = dot(ab, ab);
  double t = 0;
  if (len2 > 0) {
    t = dot(ap, ab) / len2;
    t = t < 0 ? 0 : (t > 1 ? 1 : t);
  }
  V3 d = {ap.x - t * ab.x, ap.y - t * ab.y, ap.z - t * ab.z};
  return dot(d, d);
}

// Squared distance from p to the triangle t (corners a, b, c: 9 doubles;
// see the opening comment), or, when p is farther than sqrt(limit) from
// the triangle's plane, that plane's squared distance (which is > limit).
double triangle_d2(const V3& p, const double* t, double limit = kInf) {
  const V3 a = load3(t), b = load3(t + 3), c = load3(t + 6);
  // A vertex measured against a triangle it is a corner of: exactly 0.
  if (same(p, a) || same(p, b) || same(p, c)) return 0;
  const double lab = dot(sub(b, a), sub(b, a)), lbc = dot(sub(c, b), sub(c, b)), lca = dot(sub(a, c), sub(a, c));
  // The normal from the corner with the largest angle (opposite the longest
  // edge): its direction is then good to about 2^-52 / sin of that angle,
  // which is >= 2^-19 below; flatter triangles are as good as segments.
  V3 n, o;
  double l1, l2;
  if (lbc >= lab && lbc >= lca) {
    o = a, n = cross(sub(b, a), sub(c, a)), l1 = lab, l2 = lca;
  } else if (lca >= lab) {
    o = b, n = cross(sub(c, b), sub(a, b)), l1 = lbc, l2 = lab;
  } else {
    o = c, n = cross(sub(a, c), sub(b, c)), l1 = lca, l2 = lbc;
  }
  const double nn = dot(n, n);
  if (nn > 0x1p-38 * l1 * l2) {
    const double h = dot(sub(p, o), n);
    const double plane = h * h / nn;
    if (plane > limit) return plane;
    // Barycentric weights of p's projection, times |n|^2 (the component of
    // p - corner along n cancels in each triple product).
    const V3 pa = sub(a, p), pb = sub(b, p), pc = sub(c, p);
    const double wa = dot(n, cross(pb, pc));
    const double wb = dot(n, cross(pc, pa));
    const double wc = dot(n, cross(pa, pb));
    if (wa >= 0 && wb >= 0 && wc >= 0) return plane;
    double best = kInf;
    if (wa < 0) best = std::min(best, segment_d2(p, b, c));
    if (wb < 0) best = std::min(best, segment_d2(p, c, a));
    if (wc < 0) best = std::min(best, segment_d2(p, a, b));
    return best;
  }
  return std::min(segment_d2(p, a, b), std::min(segment_d2(p, b, c), segment_d2(p, c, a)));
}

// Squared distance from p to the box [lo, hi] (0 inside).
inline double box_point_d2(const double* lo, const double* hi, const V3& p) {
  double d = 0, g;
  g = std::max(std::max(lo[0] - p.x, p.x - hi[0]), 0.0);
  d += g * g;
  g = std::max(std::max(lo[1] - p.y, p.y - hi[1]), 0.0);
  d += g * g;
  g = std::max(std::max(lo[2] - p.z, p.z - hi[2]), 0.0);
  return d + g * g;
}

// Squared distance between two boxes (0 when they meet).
inline double box_box_d2(const double* alo, const double* ahi, const double* blo, const double* bhi) {
  double d = 0;
  for (int k = 0; k < 3; ++k) {
    double g = std::max(std::max(alo[k] - bhi[k], blo[k] - ahi[k]), 0.0);
    d += g * g;
  }
  return d;
}

// ------------------------------------------------------------- random points

inline uint64_t mix64(uint64_t x) {
  x += 0x9e3779b97f4a7c15ull;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
  return x ^ (x >> 31);
}
inline double unit(uint64_t h) { return static_cast<double>(h >> 11) * 0x1p-53; }

// Point j on triangle `tri` (its index in the mesh): uniform in the
// triangle, a function of (seed, tri, j) alone, so that any thread may make
// any point.
inline V3 face_point(const V3& a, const V3& b, const V3& c, uint64_t seed, uint64_t tri, uint64_t j) {
  uint64_t h = mix64(mix64(seed ^ mix64(tri)) + j);
  double r = unit(h), s = unit(mix64(h ^ 0x5bd1e995u));
  if (r + s > 1) {
    r = 1 - r;
    s = 1 - s;
  }
  return {a.x + r * (b.x - a.x) + s * (c.x - a.x), a.y + r * (b.y - a.y) + s * (c.y - a.y),
          a.z + r * (b.z - a.z) + s * (c.z - a.z)};
}

// Spreads `samples` points over triangles in proportion to their area:
// systematic sampling along the cumulative area with one random offset, so
// that the counts add up to the total whatever the order of the areas.
class FaceAllocator {
 public:
  FaceAllocator(uint64_t samples, double total_area, uint64_t seed)
      : samples_(samples),
        lambda_(total_area > 0 ? static_cast<double>(samples) / total_area : 0),
        offset_(unit(mix64(seed ^ 0x243f6a8885a308d3ull))) {}
  uint64_t next(double area) {
    if (lambda_ == 0) return 0;
    cumulative_ += area;
    double x = lambda_ * cumulative_ + offset_;
    uint64_t k = x >= static_cast<double>(samples_) ? samples_ : static_cast<uint64_t>(x);
    if (k < done_) k = done_;
    uint64_t n = k - done_;
    done_ = k;
    return n;
  }

 private:
  uint64_t samples_;
  double lambda_, offset_;
  double cumulative_ = 0;
  uint64_t done_ = 0;
};

// ----------------------------------------------------------------- threads

// Calls f(thread, i) for every i < n on up to `threads` threads (thread <
// threads). Work is claimed in order; f writes only what i owns.
template <class F>
void parallel_for(int threads, size_t n, const F& f) {
  const size_t use = std::min<size_t>(static_cast<size_t>(std::max(threads, 1)), n);
  if (use <= 1) {
    for (size_t i = 0; i < n; ++i) f(0, i);
    return;
  }
  std::atomic<size_t> next{0};
  auto work = [&](int t) {
    for (;;) {
      size_t i = next.fetch_add(1, std::memory_order_relaxed);
      if (i >= n) return;
      f(t, i);
    }
  };
  std::vector<std::thread> pool;
  for (size_t t = 1; t < use; ++t) pool.emplace_back(work, static_cast<int>(t));
  work(0);
  for (std::thread& th : pool) th.join();
}

inline void atomic_min(std::atomic<double>& a, double v) {
  double cur = a.load(std::memory_order_relaxed);
  while (v < cur && !a.compare_exchange_weak(cur, v, std::memory_order_relaxed)) {
  }
}

// ------------------------------------------------------------------- meshes

// Vertex positions, as floats while every one is a float (4 bytes per
// coordinate for float input: the streamed mesh's one per-vertex array),
// as doubles from the first that is not.
class PositionArray {
 public:
  void prefer_float(bool f) { narrow_ = f; }
  void reserve(size_t n) {
    if (narrow_) f_.reserve(3 * n);
    else d_.reserve(3 * n);
  }
  void push(const double p[3]) {
    if (narrow_) {
      // Stored and read back through memory: a float round trip that the
      // compiler cannot elide (GCC 12's SLP may drop (double)(float) rounding).
      volatile float x = static_cast<float>(p[0]), y = static_cast<float>(p[1]), z = static_cast<float>(p[2]);
      float fx = x, fy = y, fz = z;
      if (fx == p[0] && fy == p[1] && fz == p[2]) {
        f_.push_back(fx);
        f_.push_back(fy);
        f_.push_back(fz);
        return;
      }
      widen();
    }
    d_.insert(d_.end(), p, p + 3);
  }
  size_t size() const { return (narrow_ ? f_.size() : d_.size()) / 3; }
  void release() {
    std::vector<float>().swap(f_);
    std::vector<double>().swap(d_);
  }
  V3 get(size_t i) const {
    if (narrow_) return {f_[3 * i], f_[3 * i + 1], f_[3 * i + 2]};
    return {d_[3 * i], d_[3 * i + 1], d_[3 * i + 2]};
  }

 private:
  void widen() {
    d_.assign(f_.begin(), f_.end());
    std::vector<float>().swap(f_);
    narrow_ = false;
  }
  bool narrow_ = false;
  std::vector<float> f_;
  std::vector<double> d_;
};

// A mesh as read: positions, which vertices triangles use, the triangles
// (in memory, or spooled for a streamed mesh), area and bounds.
struct MeshInput {
  PositionArray pos;
  std::vector<uint64_t> used_bits;
  uint64_t vertices = 0;
  uint64_t used = 0;
  uint64_t triangles = 0;
  bool held = false;
  std::vector<uint32_t> tri;  // held: 3 indices a triangle
  SpoolFile spool;            // streamed: 12 bytes a triangle
  double area = 0;
  double lo[3] = {kInf, kInf, kInf}, hi[3] = {-kInf, -kInf, -kInf};
  double max_abs = 0;

  bool is_used(size_t v) const { return v / 64 < used_bits.size() && (used_bits[v / 64] >> (v % 64)) & 1; }
  double tri_area(const uint32_t* t) const { return triangle_area(pos.get(t[0]), pos.get(t[1]), pos.get(t[2])); }
  // Triangles [first, first + n) into `out` (3 indices each).
  Status read_triangles(uint64_t first, size_t n, std::vector<uint32_t>* out) const {
    out->resize(3 * n);
    if (held) {
      std::memcpy(out->data(), tri.data() + 3 * first, 12 * n);
      return Status();
    }
    return spool.read_at(12 * first, out->data(), 12 * n);
  }
};

Status read_mesh(MeshSource& source, bool hold, const std::string& tmpdir, MeshInput* m) {
  const MeshSchema& schema = source.schema();
  m->held = hold;
  m->pos.prefer_float(schema.position_type == ScalarType::kFloat32);
  // Counts from a header are promises, not proof: reserve within reason.
  constexpr int64_t kMaxReserve = int64_t{1} << 24;
  if (schema.vertex_count > 0) m->pos.reserve(static_cast<size_t>(std::min(schema.vertex_count, kMaxReserve)));
  if (hold && schema.triangle_count > 0) {
    m->tri.reserve(3 * static_cast<size_t>(std::min(schema.triangle_count, kMaxReserve)));
  }
  if (!hold) PSQ_RETURN_IF_ERROR(m->spool.create(tmpdir));
  bool area_in_order = true;  // every triangle came after its vertices
  MeshItem item;
  for (;;) {
    PSQ_RETURN_IF_ERROR(source.next(&item));
    if (item.kind == MeshItem::Kind::kEnd) break;
    if (item.kind == MeshItem::Kind::kVertex) {
      if (m->pos.size() == kNone) return Status(ErrorCode::kLimit, "more than 2^32 - 1 vertices");
      m->pos.push(item.position);
      for (int k = 0; k < 3; ++k) {
        m->lo[k] = std::min(m->lo[k], item.position[k]);
        m->hi[k] = std::max(m->hi[k], item.position[k]);
        m->max_abs = std::max(m->max_abs, std::fabs(item.position[k]));
      }
      continue;
    }
    const uint32_t* t = item.index;
    for (int k = 0; k < 3; ++k) {
      size_t w = t[k] / 64;
      if (w >= m->used_bits.size()) m->used_bits.resize(std::max(w + 1, 2 * m->used_bits.size()), 0);
      m->used_bits[w] |= uint64_t{1} << (t[k] % 64);
    }
    if (area_in_order && std::max(t[0], std::max(t[1], t[2])) < m->pos.size()) m->area += m->tri_area(t);
    else area_in_order = false;
    if (hold) m->tri.insert(m->tri.end(), t, t + 3);
    else PSQ_RETURN_IF_ERROR(m->spool.write(t, 12));
    ++m->triangles;
  }
  if (!hold) PSQ_RETURN_IF_ERROR(m->spool.rewind());
  m->vertices = m->pos.size();
  for (uint64_t w : m->used_bits) m->used += static_cast<uint64_t>(__builtin_popcountll(w));
  if (!area_in_order) {
    // Some triangle preceded its vertices (a PLY with faces first): the
    // area again, in triangle order, now that every position is known.
    m->area = 0;
    std::vector<uint32_t> batch;
    for (uint64_t first = 0; first < m->triangles; first += kBatchTriangles) {
      size_t n = static_cast<size_t>(std::min<uint64_t>(kBatchTriangles, m->triangles - first));
      PSQ_RETURN_IF_ERROR(m->read_triangles(first, n, &batch));
      for (size_t i = 0; i < n; ++i) m->area += m->tri_area(&batch[3 * i]);
    }
  }
  return Status();
}

// Samples on a mesh when `requested` (0: the default) are asked for.
uint64_t sample_count(const MeshInput& m, uint64_t requested) {
  uint64_t n = requested;
  if (n == 0) n = std::min(kDefaultSamplesPerTriangle * m.triangles, kDefaultMaxSamples);
  return std::max(n, m.used);
}

// ----------------------------------------------------------------- BVH

struct Node {
  double lo[3], hi[3];
  uint32_t first;  // a leaf's first item; an inner node's right child (its left is the next node)
  uint32_t count;  // a leaf's items; 0 for an inner node
};

inline double extent(const Node& n) { return (n.hi[0] - n.lo[0]) + (n.hi[1] - n.lo[1]) + (n.hi[2] - n.lo[2]); }

// Items are points (3 doubles) or triangles (9: corners a, b, c).
// item_d2() is the squared distance, or some value > limit.
template <int kStride>
double item_d2(const V3& p, const double* item, double limit);
template <>
inline double item_d2<3>(const V3& p, const double* q, double) {
  V3 d = sub(p, load3(q));
  return dot(d, d);
}
template <>
inline double item_d2<9>(const V3& p, const double* t, double limit) {
  return triangle_d2(p, t, limit);
}

template <int kStride>
inline void item_bounds(const double* item, double* lo, double* hi) {
  for (int c = 0; c < kStride; c += 3) {
    for (int k = 0; k < 3; ++k) {
      lo[k] = std::min(lo[k], item[c + k]);
      hi[k] = std::max(hi[k], item[c + k]);
    }
  }
}

// A bounding volume hierarchy over points or triangles, built as a linear
// BVH (Lauterbach, Garland, Sengupta, Luebke, Manocha, "Fast BVH
// construction on GPUs", Eurographics 2009): the items sorted along a
// Morton curve of their box centres (a radix sort: linear time, which the
// streamed batches need), each range split where its codes first differ.
// Nodes are in depth-first order: a node's children come after it.
template <int kStride>
class Bvh {
 public:
  // Builds over `data` (kStride doubles an item), which it takes.
  void build(std::vector<double> data, uint32_t leaf) {
    const size_t n = data.size() / kStride;
    std::vector<double> centres;
    if (kStride != 3) {
      centres.resize(3 * n);
      for (size_t i = 0; i < n; ++i) {
        double lo[3] = {kInf, kInf, kInf}, hi[3] = {-kInf, -kInf, -kInf};
        item_bounds<kStride>(&data[kStride * i], lo, hi);
        for (int k = 0; k < 3; ++k) centres[3 * i + k] = 0.5 * (lo[k] + hi[k]);
      }
    }
    const double* c = kStride == 3 ? data.data() : centres.data();
    order_.resize(n);
    morton_order(n, c);
    build_topology(n, leaf);
    std::vector<uint32_t>().swap(codes_);
    std::vector<double>().swap(centres);
    // The items in leaf order, permuted in place (cycle by cycle).
    items_ = std::move(data);
    std::vector<bool> placed(n, false);
    double tmp[kStride];
    for (size_t i = 0; i < n; ++i) {
      if (placed[i]) continue;
      std::memcpy(tmp, &items_[kStride * i], sizeof tmp);
      size_t j = i;
      for (;;) {
        placed[j] = true;
        size_t k = order_[j];
        if (k == i) {
          std::memcpy(&items_[kStride * j], tmp, sizeof tmp);
          break;
        }
        std::memcpy(&items_[kStride * j], &items_[kStride * k], sizeof tmp);
        j = k;
      }
    }
    // Boxes bottom-up.
    for (size_t k = nodes_.size(); k-- > 0;) {
      Node& node = nodes_[k];
      for (int j = 0; j < 3; ++j) {
        node.lo[j] = kInf;
        node.hi[j] = -kInf;
      }
      if (node.count > 0) {
        for (uint32_t i = node.first; i < node.first + node.count; ++i) item_bounds<kStride>(item(i), node.lo, node.hi);
      } else {
        const Node& l = nodes_[k + 1];
        const Node& r = nodes_[node.first];
        for (int j = 0; j < 3; ++j) {
          node.lo[j] = std::min(l.lo[j], r.lo[j]);
          node.hi[j] = std::max(l.hi[j], r.hi[j]);
        }
      }
    }
  }

  size_t size() const { return order_.size(); }
  const std::vector<Node>& nodes() const { return nodes_; }
  const std::vector<uint32_t>& parents() const { return parents_; }
  // Item i in leaf order, and its index in the data given to build().
  const double* item(uint32_t i) const { return &items_[kStride * size_t{i}]; }
  uint32_t original(uint32_t i) const { return order_[i]; }

  // The smallest item_d2() from p to any item. *hint: an item (leaf order)
  // to try first, or kNone; receives the nearest. `margin`: see kMarginScale.
  double closest_d2(const V3& p, double margin, uint32_t* hint) const {
    double best = kInf, limit = kInf;
    uint32_t which = kNone;
    if (*hint != kNone) {
      which = *hint;
      best = item_d2<kStride>(p, item(which), kInf);
      limit = sq(std::sqrt(best) + margin);
    }
    struct Entry {
      uint32_t node;
      double d2;
    };
    Entry stack[128];
    int top = 0;
    stack[top++] = {0, box_point_d2(nodes_[0].lo, nodes_[0].hi, p)};
    while (top > 0) {
      Entry e = stack[--top];
      if (e.d2 > limit) continue;
      const Node& node = nodes_[e.node];
      if (node.count > 0) {
        for (uint32_t i = node.first; i < node.first + node.count; ++i) {
          double d2 = item_d2<kStride>(p, item(i), limit);
          if (d2 < best) {
            best = d2;
            which = i;
            limit = sq(std::sqrt(best) + margin);
          }
        }
        continue;
      }
      uint32_t l = e.node + 1, r = node.first;
      double dl = box_point_d2(nodes_[l].lo, nodes_[l].hi, p);
      double dr = box_point_d2(nodes_[r].lo, nodes_[r].hi, p);
      // The nearer child on top, visited first.
      if (dl > dr) {
        std::swap(l, r);
        std::swap(dl, dr);
      }
      if (dr <= limit) stack[top++] = {r, dr};
      if (dl <= limit) stack[top++] = {l, dl};
    }
    *hint = which;
    return best;
  }

 private:
  // order_: the items by the Morton code of their centres (10 bits an axis
  // within the centres' box; ties by index), by an LSD radix sort.
  void morton_order(size_t n, const double* c) {
    double lo[3] = {kInf, kInf, kInf}, hi[3] = {-kInf, -kInf, -kInf};
    for (size_t i = 0; i < n; ++i) {
      for (int k = 0; k < 3; ++k) {
        lo[k] = std::min(lo[k], c[3 * i + k]);
        hi[k] = std::max(hi[k], c[3 * i + k]);
      }
    }
    auto spread = [](uint32_t v) {  // 10 bits to every third of 30
      v = (v | (v << 16)) & 0x030000ffu;
      v = (v | (v << 8)) & 0x0300f00fu;
      v = (v | (v << 4)) & 0x030c30c3u;
      return (v | (v << 2)) & 0x09249249u;
    };
    // One scale for the three axes (the cube around the box): a flat batch
    // is then cut across its width, not into layers.
    const double side = std::max({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]});
    const double scale = side > 0 ? 1024 / side : 0;
    std::vector<uint32_t> code(n), tmp(n);
    for (size_t i = 0; i < n; ++i) {
      uint32_t q[3];
      for (int k = 0; k < 3; ++k) q[k] = static_cast<uint32_t>(std::min(1023.0, std::max(0.0, (c[3 * i + k] - lo[k]) * scale)));
      code[i] = spread(q[0]) | spread(q[1]) << 1 | spread(q[2]) << 2;
    }
    // order_ is 0..n-1; three stable passes of 10 bits keep index order in ties.
    std::iota(order_.begin(), order_.end(), 0u);
    std::vector<uint32_t> count(1025);
    for (int shift = 0; shift < 30; shift += 10) {
      std::fill(count.begin(), count.end(), 0);
      for (size_t i = 0; i < n; ++i) ++count[((code[order_[i]] >> shift) & 1023) + 1];
      for (size_t d = 1; d < count.size(); ++d) count[d] += count[d - 1];
      for (size_t i = 0; i < n; ++i) tmp[count[(code[order_[i]] >> shift) & 1023]++] = order_[i];
      order_.swap(tmp);
    }
    codes_.resize(n);
    for (size_t i = 0; i < n; ++i) codes_[i] = code[order_[i]];
  }

  // Nodes over order_ (sorted by codes_): each range split at the highest
  // bit in which its codes differ (an octree cell's split), or in the
  // middle when they are all equal.
  void build_topology(size_t n, uint32_t leaf) {
    nodes_.clear();
    parents_.clear();
    if (n == 0) return;
    nodes_.reserve(2 * (n / leaf + 1));
    parents_.reserve(2 * (n / leaf + 1));
    struct Task {
      uint32_t begin, end, parent;
      bool right;
    };
    std::vector<Task> stack{{0, static_cast<uint32_t>(n), kNone, false}};
    while (!stack.empty()) {
      Task t = stack.back();
      stack.pop_back();
      const uint32_t idx = static_cast<uint32_t>(nodes_.size());
      nodes_.push_back(Node{});
      parents_.push_back(t.parent);
      if (t.right) nodes_[t.parent].first = idx;
      if (t.end - t.begin <= leaf) {
        nodes_[idx].first = t.begin;
        nodes_[idx].count = t.end - t.begin;
        continue;
      }
      nodes_[idx].count = 0;
      uint32_t mid = t.begin + (t.end - t.begin) / 2;
      if (codes_[t.begin] != codes_[t.end - 1]) {
        const uint32_t bit = 31 - static_cast<uint32_t>(__builtin_clz(codes_[t.begin] ^ codes_[t.end - 1]));
        const uint32_t prefix = codes_[t.begin] >> bit;
        mid = static_cast<uint32_t>(std::partition_point(codes_.begin() + t.begin, codes_.begin() + t.end,
                                                         [&](uint32_t k) { return (k >> bit) == prefix; }) -
                                    codes_.begin());
      }
      stack.push_back({mid, t.end, idx, true});
      stack.push_back({t.begin, mid, idx, false});
    }
  }

  std::vector<Node> nodes_;
  std::vector<uint32_t> order_, parents_;
  std::vector<uint32_t> codes_;  // kMorton: the items' codes in order
  std::vector<double> items_;  // leaf order
};

// The held mesh's samples for the streaming direction. Each sample keeps an
// upper bound on its distance to the streamed surface (first from some of
// its vertices, then from its triangles) and the smallest triangle_d2() so
// far; each node the largest bound below it, refreshed between batches (a
// stale bound is only larger: it prunes less, never wrongly).
class SampleTree {
 public:
  // `bounds`: an upper bound on each sample's distance to the streamed
  // surface, in the samples' order.
  SampleTree(std::vector<double> samples, const std::vector<double>& bounds, double margin) : margin_(margin) {
    tree_.build(std::move(samples), kSampleLeaf);
    const std::vector<Node>& nodes = tree_.nodes();
    const size_t n = tree_.size();
    bound_.reset(new std::atomic<double>[n]);
    best_.reset(new std::atomic<double>[n]);
    for (uint32_t i = 0; i < n; ++i) {
      bound_[i].store(bounds[tree_.original(i)], std::memory_order_relaxed);
      best_[i].store(kInf, std::memory_order_relaxed);
    }
    node_bound_.resize(nodes.size());
    for (size_t k = nodes.size(); k-- > 0;) {
      const Node& node = nodes[k];
      double m = 0;
      if (node.count > 0) {
        for (uint32_t i = node.first; i < node.first + node.count; ++i)
          m = std::max(m, bound_[i].load(std::memory_order_relaxed));
      } else {
        m = std::max(node_bound_[k + 1], node_bound_[node.first]);
      }
      node_bound_[k] = m;
    }
    dirty_.reset(new std::atomic<uint8_t>[nodes.size()]);
    for (size_t k = 0; k < nodes.size(); ++k) dirty_[k].store(0, std::memory_order_relaxed);
  }

  // Measures the samples against a batch of streamed triangles: the two
  // trees are descended together, pairs of nodes farther apart than the
  // sample node's bound are dropped.
  // `first`: the index of the batch's first triangle in the mesh.
  void measure(const Bvh<9>& batch, uint64_t first, int threads) {
    if (tree_.size() == 0 || batch.size() == 0) return;
    batch_first_ = first;
    const int use = std::max(1, threads);
    // Pairs to share among the threads: the root pair split breadth-first.
    std::vector<Pair> frontier{{0, 0}}, next;
    while (frontier.size() < 64 * static_cast<size_t>(use)) {
      next.clear();
      bool split = false;
      for (const Pair& p : frontier) {
        if (pruned(batch, p)) continue;
        if (!split_pair(batch, p, &next)) next.push_back(p);
        else split = true;
      }
      frontier.swap(next);
      if (!split) break;
    }
    std::vector<std::vector<uint32_t>> dirty(static_cast<size_t>(use));
    parallel_for(use, frontier.size(), [&](int thread, size_t i) { descend(batch, frontier[i], &dirty[thread]); });
    refresh(dirty);
  }

  // Keeps, besides each sample's distance, its nearest triangle (the
  // smallest index among equally near ones) and that triangle's normal.
  void track_nearest() {
    which_.assign(tree_.size(), UINT64_MAX);
    normal_.assign(tree_.size(), V3{0, 0, 0});
    locks_.reset(new std::mutex[kLocks]);
  }

  // The nearest triangles, in the order of the samples given to the
  // constructor (after track_nearest()).
  std::vector<NearestTriangle> nearest() const {
    std::vector<NearestTriangle> out(tree_.size());
    for (uint32_t i = 0; i < tree_.size(); ++i) {
      NearestTriangle& n = out[tree_.original(i)];
      n.distance = std::sqrt(best_[i].load(std::memory_order_relaxed));
      n.triangle = which_[i];
      n.normal[0] = normal_[i].x;
      n.normal[1] = normal_[i].y;
      n.normal[2] = normal_[i].z;
    }
    return out;
  }

  // Every sample's smallest triangle_d2(), in the order of the samples
  // given to the constructor.
  std::vector<double> distances() const {
    std::vector<double> out(tree_.size());
    for (uint32_t i = 0; i < tree_.size(); ++i) out[tree_.original(i)] = best_[i].load(std::memory_order_relaxed);
    return out;
  }

 private:
  struct Pair {
    uint32_t h, s;  // a node of the sample tree, a node of the batch
  };

  bool pruned(const Bvh<9>& batch, const Pair& p) const {
    const Node& h = tree_.nodes()[p.h];
    const Node& s = batch.nodes()[p.s];
    return box_box_d2(h.lo, h.hi, s.lo, s.hi) > sq(node_bound_[p.h] + margin_);
  }

  // The pair's children pairs (the larger node split); false for two leaves.
  bool split_pair(const Bvh<9>& batch, const Pair& p, std::vector<Pair>* out) const {
    const Node& h = tree_.nodes()[p.h];
    const Node& s = batch.nodes()[p.s];
    if (h.count > 0 && s.count > 0) return false;
    if (s.count > 0 || (h.count == 0 && extent(h) >= extent(s))) {
      out->push_back({p.h + 1, p.s});
      out->push_back({h.first, p.s});
    } else {
      out->push_back({p.h, p.s + 1});
      out->push_back({p.h, s.first});
    }
    return true;
  }

  void descend(const Bvh<9>& batch, Pair root, std::vector<uint32_t>* dirty) {
    const std::vector<Node>& hn = tree_.nodes();
    const std::vector<Node>& sn = batch.nodes();
    // Each step replaces a pair by at most two whose depths add up to one
    // more: the stack holds at most the two trees' depths (balanced, < 40).
    Pair stack[256];
    int top = 0;
    stack[top++] = root;
    while (top > 0) {
      const Pair p = stack[--top];
      const Node& h = hn[p.h];
      const Node& s = sn[p.s];
      if (box_box_d2(h.lo, h.hi, s.lo, s.hi) > sq(node_bound_[p.h] + margin_)) continue;
      if (h.count > 0) {
        leaves(batch, p, dirty);
      } else if (s.count > 0 || extent(h) >= extent(s)) {
        stack[top++] = {h.first, p.s};
        stack[top++] = {p.h + 1, p.s};
      } else {
        stack[top++] = {p.h, s.first};
        stack[top++] = {p.h, p.s + 1};
      }
    }
  }

  // A leaf of samples against a subtree of the batch: each sample searches
  // it nearest first, within its own bound (tighter than the leaf's).
  void leaves(const Bvh<9>& batch, const Pair& p, std::vector<uint32_t>* dirty) {
    const Node& h = tree_.nodes()[p.h];
    const std::vector<Node>& sn = batch.nodes();
    bool lowered = false;
    struct Entry {
      uint32_t node;
      double d2;
    };
    Entry stack[128];
    for (uint32_t i = h.first; i < h.first + h.count; ++i) {
      const V3 q = load3(tree_.item(i));
      double u = bound_[i].load(std::memory_order_relaxed);
      double limit = sq(u + margin_);
      int top = 0;
      stack[top++] = {p.s, box_point_d2(sn[p.s].lo, sn[p.s].hi, q)};
      while (top > 0) {
        const Entry e = stack[--top];
        if (e.d2 > limit) continue;
        const Node& node = sn[e.node];
        if (node.count == 0) {
          uint32_t l = e.node + 1, r = node.first;
          double dl = box_point_d2(sn[l].lo, sn[l].hi, q), dr = box_point_d2(sn[r].lo, sn[r].hi, q);
          if (dl > dr) {
            std::swap(l, r);
            std::swap(dl, dr);
          }
          if (dr <= limit) stack[top++] = {r, dr};
          if (dl <= limit) stack[top++] = {l, dl};
          continue;
        }
        for (uint32_t t = node.first; t < node.first + node.count; ++t) {
          double lo[3] = {kInf, kInf, kInf}, hi[3] = {-kInf, -kInf, -kInf};
          item_bounds<9>(batch.item(t), lo, hi);
          if (box_point_d2(lo, hi, q) > limit) continue;
          const double d2 = triangle_d2(q, batch.item(t), limit);
          // Above the limit: not this sample's nearest (see measure_distance).
          if (d2 > limit) continue;
          if (!which_.empty()) record(i, d2, batch_first_ + batch.original(t), batch.item(t));
          else if (d2 < best_[i].load(std::memory_order_relaxed)) atomic_min(best_[i], d2);
          const double d = std::sqrt(d2);
          if (d < u) {
            atomic_min(bound_[i], d);
            u = bound_[i].load(std::memory_order_relaxed);
            limit = sq(u + margin_);
            lowered = true;
          }
        }
      }
    }
    if (lowered && dirty_[p.h].exchange(1, std::memory_order_relaxed) == 0) dirty->push_back(p.h);
  }

  // A triangle as near as sample i's nearest so far: it becomes the nearest
  // when nearer, or as near with a smaller index (under a lock: the three
  // go together).
  void record(uint32_t i, double d2, uint64_t tri, const double* t) {
    if (d2 > best_[i].load(std::memory_order_relaxed)) return;
    std::lock_guard<std::mutex> lock(locks_[i % kLocks]);
    const double b = best_[i].load(std::memory_order_relaxed);
    if (d2 > b || (d2 == b && tri > which_[i])) return;
    best_[i].store(d2, std::memory_order_relaxed);
    which_[i] = tri;
    const V3 n = cross(sub(load3(t + 3), load3(t)), sub(load3(t + 6), load3(t)));
    const double len = std::sqrt(dot(n, n));
    normal_[i] = len > 0 ? V3{n.x / len, n.y / len, n.z / len} : V3{0, 0, 0};
  }

  // New bounds for the leaves that changed, and up while they change.
  void refresh(const std::vector<std::vector<uint32_t>>& dirty) {
    const std::vector<Node>& nodes = tree_.nodes();
    const std::vector<uint32_t>& parents = tree_.parents();
    for (const std::vector<uint32_t>& list : dirty) {
      for (uint32_t k : list) {
        dirty_[k].store(0, std::memory_order_relaxed);
        double m = 0;
        for (uint32_t s = nodes[k].first; s < nodes[k].first + nodes[k].count; ++s)
          m = std::max(m, bound_[s].load(std::memory_order_relaxed));
        node_bound_[k] = m;
        for (uint32_t p = parents[k]; p != kNone; p = parents[p]) {
          const double v = std::max(node_bound_[p + 1], node_bound_[nodes[p].first]);
          if (v == node_bound_[p]) break;
          node_bound_[p] = v;
        }
      }
    }
  }

  double margin_;
  Bvh<3> tree_;
  std::unique_ptr<std::atomic<double>[]> bound_, best_;  // leaf order
  std::vector<double> node_bound_;
  std::unique_ptr<std::atomic<uint8_t>[]> dirty_;
  uint64_t batch_first_ = 0;
  // track_nearest(): the nearest triangle and its normal (leaf order).
  static constexpr size_t kLocks = 4096;
  std::vector<uint64_t> which_;
  std::vector<V3> normal_;
  std::unique_ptr<std::mutex[]> locks_;
};

// ------------------------------------------------------------ statistics

// Sums in the samples' order (Neumaier's compensated sum): the same bits
// for every thread count.
class Accumulator {
 public:
  explicit Accumulator(double zero) : zero2_(zero * zero) {}
  void add(double d2) {
    if (d2 < zero2_) d2 = 0;
    ++n_;
    max2_ = std::max(max2_, d2);
    sum(&s_, &sc_, std::sqrt(d2));
    sum(&q_, &qc_, d2);
  }
  DirectionDistance result(uint64_t vertex_samples) const {
    DirectionDistance r;
    r.samples = n_;
    r.vertex_samples = vertex_samples;
    r.max = std::sqrt(max2_);
    if (n_ > 0) {
      r.mean = (s_ + sc_) / static_cast<double>(n_);
      r.rms = std::sqrt((q_ + qc_) / static_cast<double>(n_));
    }
    return r;
  }

 private:
  static void sum(double* s, double* c, double x) {
    double t = *s + x;
    if (std::fabs(*s) >= std::fabs(x)) *c += (*s - t) + x;
    else *c += (x - t) + *s;
    *s = t;
  }
  double zero2_;
  uint64_t n_ = 0;
  double max2_ = 0, s_ = 0, sc_ = 0, q_ = 0, qc_ = 0;
};

// ------------------------------------------------------------- sampling

// Makes a mesh's samples in their order and hands them on a window at a
// time: the used vertices (vertices()), then the points on the triangles
// as batches of them arrive in order (triangles()).
class SampleMaker {
 public:
  using Flush = std::function<void(const std::vector<V3>&)>;
  SampleMaker(const MeshInput& m, uint64_t samples, uint64_t seed, int threads, Flush flush)
      : m_(m),
        seed_(seed),
        threads_(threads),
        alloc_(samples - m.used, m.area, seed),
        flush_(std::move(flush)) {}

  void vertices() {
    window_.clear();
    for (size_t v = 0; v < m_.pos.size(); ++v) {
      if (!m_.is_used(v)) continue;
      window_.push_back(m_.pos.get(v));
      if (window_.size() == kWindowSamples) {
        flush_(window_);
        window_.clear();
      }
    }
    if (!window_.empty()) flush_(window_);
    window_.clear();
  }

  // The next n triangles of the mesh (3 indices each).
  void triangles(const uint32_t* idx, size_t n) {
    size_t pending = 0;
    for (size_t i = 0; i < n; ++i) {
      const uint32_t* t = idx + 3 * i;
      uint64_t count = alloc_.next(m_.tri_area(t));
      uint64_t j = 0;
      while (count > 0) {
        size_t take = static_cast<size_t>(std::min<uint64_t>(count, kWindowSamples - pending));
        pieces_.push_back({next_tri_, t, j, take, pending});
        pending += take;
        j += take;
        count -= take;
        if (pending == kWindowSamples) {
          emit(pending);
          pending = 0;
        }
      }
      ++next_tri_;
    }
    if (pending > 0) emit(pending);
  }

 private:
  struct Piece {
    uint64_t tri;
    const uint32_t* idx;
    uint64_t first;
    size_t count;
    size_t out;
  };
  void emit(size_t n) {
    window_.resize(n);
    parallel_for(threads_, (pieces_.size() + 255) / 256, [&](int, size_t c) {
      for (size_t k = 256 * c; k < std::min(pieces_.size(), 256 * c + 256); ++k) {
        const Piece& p = pieces_[k];
        V3 a = m_.pos.get(p.idx[0]), b = m_.pos.get(p.idx[1]), cc = m_.pos.get(p.idx[2]);
        for (size_t j = 0; j < p.count; ++j) window_[p.out + j] = face_point(a, b, cc, seed_, p.tri, p.first + j);
      }
    });
    pieces_.clear();
    flush_(window_);
  }

  const MeshInput& m_;
  uint64_t seed_;
  int threads_;
  FaceAllocator alloc_;
  Flush flush_;
  uint64_t next_tri_ = 0;
  std::vector<Piece> pieces_;
  std::vector<V3> window_;
};

// Measures windows of samples against a triangle BVH, in order.
class Measurer {
 public:
  Measurer(const Bvh<9>& bvh, double margin, int threads, double zero)
      : bvh_(bvh), margin_(margin), threads_(threads), acc_(zero) {}
  void measure(const V3* pts, size_t n) {
    constexpr size_t kChunk = 512;
    d2_.resize(n);
    parallel_for(threads_, (n + kChunk - 1) / kChunk, [&](int, size_t c) {
      // Neighbouring samples often share their nearest triangle: the last
      // one bounds the search of the next.
      uint32_t hint = kNone;
      for (size_t i = kChunk * c; i < std::min(n, kChunk * c + kChunk); ++i)
        d2_[i] = bvh_.closest_d2(pts[i], margin_, &hint);
    });
    for (double d2 : d2_) acc_.add(d2);
  }
  const Accumulator& accumulator() const { return acc_; }

 private:
  const Bvh<9>& bvh_;
  double margin_;
  int threads_;
  Accumulator acc_;
  std::vector<double> d2_;
};

// Triangles [first, first + n) of `m` as corner coordinates (9 doubles each).
void triangle_coords(const MeshInput& m, const uint32_t* idx, size_t n, std::vector<double>* out) {
  out->resize(9 * n);
  for (size_t i = 0; i < 3 * n; ++i) {
    V3 p = m.pos.get(idx[i]);
    (*out)[3 * i] = p.x;
    (*out)[3 * i + 1] = p.y;
    (*out)[3 * i + 2] = p.z;
  }
}

// Every triangle of `m`, a batch at a time: f(first, indices, count).
template <class F>
Status for_each_batch(const MeshInput& m, const F& f) {
  std::vector<uint32_t> batch;
  for (uint64_t first = 0; first < m.triangles; first += kBatchTriangles) {
    size_t n = static_cast<size_t>(std::min<uint64_t>(kBatchTriangles, m.triangles - first));
    PSQ_RETURN_IF_ERROR(m.read_triangles(first, n, &batch));
    f(first, batch.data(), n);
  }
  return Status();
}

// All samples of a held mesh, in order (3 doubles each).
std::vector<double> all_samples(const MeshInput& m, uint64_t samples, uint64_t seed, int threads) {
  std::vector<double> out;
  out.reserve(3 * static_cast<size_t>(samples));
  SampleMaker maker(m, samples, seed, threads, [&](const std::vector<V3>& w) {
    for (const V3& p : w) out.insert(out.end(), {p.x, p.y, p.z});
  });
  maker.vertices();
  maker.triangles(m.tri.data(), static_cast<size_t>(m.triangles));
  return out;
}

// An upper bound on each sample's distance to the surface of `m`: the
// distance to the nearest of up to `want` of its used vertices (evenly
// picked by index; any point of a surface bounds the distance to it).
std::vector<double> vertex_bounds(const std::vector<double>& samples, const MeshInput& m, uint64_t want,
                                  double margin, int threads) {
  const uint64_t step = std::max<uint64_t>(1, (m.used + want - 1) / std::max<uint64_t>(want, 1));
  std::vector<double> pts;
  pts.reserve(3 * static_cast<size_t>(std::min(m.used, want) + 1));
  uint64_t seen = 0;
  for (size_t v = 0; v < m.pos.size(); ++v) {
    if (!m.is_used(v)) continue;
    if (seen++ % step != 0) continue;
    V3 p = m.pos.get(v);
    pts.insert(pts.end(), {p.x, p.y, p.z});
  }
  Bvh<3> bvh;
  bvh.build(std::move(pts), kSampleLeaf);
  constexpr size_t kChunk = 512;
  const size_t n = samples.size() / 3;
  std::vector<double> bounds(n);
  parallel_for(threads, (n + kChunk - 1) / kChunk, [&](int, size_t c) {
    uint32_t hint = kNone;
    for (size_t i = kChunk * c; i < std::min(n, kChunk * c + kChunk); ++i)
      bounds[i] = std::sqrt(bvh.closest_d2(load3(&samples[3 * i]), margin, &hint));
  });
  return bounds;
}

// Frees a held mesh's arrays once its BVH and samples are made.
void release(MeshInput* m) {
  m->pos.release();
  std::vector<uint32_t>().swap(m->tri);
  std::vector<uint64_t>().swap(m->used_bits);
}

}  // namespace

Status measure_distance(MeshSource& a, MeshSource& b, const DistanceOptions& options, DistanceResult* result) {
  const auto start = std::chrono::steady_clock::now();
  *result = DistanceResult();
  if (options.samples > kMaxSamples) {
    return Status(ErrorCode::kUsage, "at most " + std::to_string(kMaxSamples) + " samples per direction");
  }
  const int threads = options.threads > 0 ? options.threads
                                          : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));

  // Which mesh is held: known counts decide (psq/distance.h).
  DistanceHold hold = options.hold;
  if (hold == DistanceHold::kAuto) {
    const int64_t ta = a.schema().triangle_count, tb = b.schema().triangle_count;
    const uint64_t ka = ta >= 0 ? static_cast<uint64_t>(ta) : UINT64_MAX;
    const uint64_t kb = tb >= 0 ? static_cast<uint64_t>(tb) : UINT64_MAX;
    if (std::max(ka, kb) <= kAutoInMemoryTriangles) hold = DistanceHold::kBoth;
    else hold = ka < kb ? DistanceHold::kA : DistanceHold::kB;
  }
  // h: the held mesh, read first; s: the other, streamed unless both are held.
  const bool h_is_a = hold == DistanceHold::kA || hold == DistanceHold::kBoth;
  const bool both = hold == DistanceHold::kBoth;
  const int h_input = h_is_a ? 1 : 2, s_input = h_is_a ? 2 : 1;
  MeshInput h, s;
  Status st = read_mesh(h_is_a ? a : b, true, options.tmpdir, &h);
  if (!st.ok()) {
    result->error_input = h_input;
    return st;
  }
  if (h.triangles == 0) {
    result->error_input = h_input;
    return Status(ErrorCode::kBadValue, "no triangles: there is no surface to measure");
  }
  // The held mesh's samples and triangle BVH, before the other is read.
  std::vector<double> h_points = all_samples(h, sample_count(h, options.samples), options.seed, threads);
  Bvh<9> h_bvh;
  {
    std::vector<double> coords;
    triangle_coords(h, h.tri.data(), static_cast<size_t>(h.triangles), &coords);
    h_bvh.build(std::move(coords), kTriangleLeaf);
  }
  st = read_mesh(h_is_a ? b : a, both, options.tmpdir, &s);
  if (!st.ok()) {
    result->error_input = s_input;
    return st;
  }
  if (s.triangles == 0) {
    result->error_input = s_input;
    return Status(ErrorCode::kBadValue, "no triangles: there is no surface to measure");
  }
  const double scale = std::max({h.max_abs, s.max_abs, std::numeric_limits<double>::min()});
  const double margin = kMarginScale * scale, zero = kZeroScale * scale;
  const uint64_t h_used = h.used;
  release(&h);

  // Direction s -> h: s's samples against h's triangles, as s's triangles
  // go by. Direction h -> s: in memory against s's BVH, or the sample tree
  // against s's triangles streaming past.
  Measurer s_to_h(h_bvh, margin, threads, zero);
  SampleMaker s_maker(s, sample_count(s, options.samples), options.seed, threads,
                      [&](const std::vector<V3>& w) { s_to_h.measure(w.data(), w.size()); });
  s_maker.vertices();
  Accumulator h_to_s(zero);
  if (both) {
    Bvh<9> s_bvh;
    std::vector<double> coords;
    triangle_coords(s, s.tri.data(), static_cast<size_t>(s.triangles), &coords);
    s_bvh.build(std::move(coords), kTriangleLeaf);
    Measurer m(s_bvh, margin, threads, zero);
    const V3* pts = reinterpret_cast<const V3*>(h_points.data());
    const size_t n = h_points.size() / 3;
    for (size_t i = 0; i < n; i += kWindowSamples) m.measure(pts + i, std::min(kWindowSamples, n - i));
    h_to_s = m.accumulator();
    s_maker.triangles(s.tri.data(), static_cast<size_t>(s.triangles));
  } else {
    // The bounds first, while the samples are in one array, then the tree.
    std::vector<double> bounds = vertex_bounds(h_points, s, kBoundVertices, margin, threads);
    SampleTree tree(std::move(h_points), bounds, margin);
    std::vector<double>().swap(bounds);
    std::vector<double> coords;
    st = for_each_batch(s, [&](uint64_t first, const uint32_t* idx, size_t n) {
      s_maker.triangles(idx, n);
      triangle_coords(s, idx, n, &coords);
      Bvh<9> batch;
      batch.build(std::move(coords), kTriangleLeaf);
      tree.measure(batch, first, threads);
    });
    if (!st.ok()) return st;
    for (double d2 : tree.distances()) h_to_s.add(d2);
  }

  auto summary = [](const MeshInput& m, bool held) {
    MeshDistanceSummary r;
    r.vertices = m.vertices;
    r.used_vertices = m.used;
    r.triangles = m.triangles;
    r.area = m.area;
    for (int k = 0; k < 3; ++k) {
      r.bounds_min[k] = m.vertices ? m.lo[k] : 0;
      r.bounds_max[k] = m.vertices ? m.hi[k] : 0;
    }
    r.held = held;
    return r;
  };
  const DirectionDistance d_sh = s_to_h.accumulator().result(s.used);
  const DirectionDistance d_hs = h_to_s.result(h_used);
  result->a = summary(h_is_a ? h : s, h_is_a || both);
  result->b = summary(h_is_a ? s : h, !h_is_a || both);
  result->a_to_b = h_is_a ? d_hs : d_sh;
  result->b_to_a = h_is_a ? d_sh : d_hs;
  result->hausdorff = std::max(result->a_to_b.max, result->b_to_a.max);
  double d2 = 0;
  for (int k = 0; k < 3; ++k) d2 += sq(result->a.bounds_max[k] - result->a.bounds_min[k]);
  result->diagonal = std::sqrt(d2);
  result->seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return Status();
}

Status nearest_triangles(MeshSource& mesh, const std::vector<double>& xyz, const DistanceOptions& options,
                         std::vector<NearestTriangle>* out) {
  out->clear();
  if (xyz.size() % 3 != 0) return Status(ErrorCode::kUsage, "points must be 3 coordinates each");
  for (double v : xyz) {
    if (!std::isfinite(v)) return Status(ErrorCode::kUsage, "points must be finite");
  }
  const int threads = options.threads > 0 ? options.threads
                                          : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  MeshInput m;
  PSQ_RETURN_IF_ERROR(read_mesh(mesh, false, options.tmpdir, &m));
  if (m.triangles == 0) return Status(ErrorCode::kBadValue, "no triangles: there is no surface to measure");
  if (xyz.empty()) return Status();
  double scale = std::max(m.max_abs, std::numeric_limits<double>::min());
  for (double v : xyz) scale = std::max(scale, std::fabs(v));
  const double margin = kMarginScale * scale;
  SampleTree tree(xyz, vertex_bounds(xyz, m, kBoundVertices, margin, threads), margin);
  tree.track_nearest();
  std::vector<double> coords;
  PSQ_RETURN_IF_ERROR(for_each_batch(m, [&](uint64_t first, const uint32_t* idx, size_t n) {
    triangle_coords(m, idx, n, &coords);
    Bvh<9> batch;
    batch.build(std::move(coords), kTriangleLeaf);
    tree.measure(batch, first, threads);
  }));
  *out = tree.nearest();
  return Status();
}

Status sample_surface(MeshSource& mesh, uint64_t samples, uint64_t seed, std::vector<double>* xyz) {
  if (samples > kMaxSamples) {
    return Status(ErrorCode::kUsage, "at most " + std::to_string(kMaxSamples) + " samples per direction");
  }
  MeshInput m;
  PSQ_RETURN_IF_ERROR(read_mesh(mesh, true, "", &m));
  if (m.triangles == 0) return Status(ErrorCode::kBadValue, "no triangles: there is no surface to measure");
  *xyz = all_samples(m, sample_count(m, samples), seed, 1);
  return Status();
}

}  // namespace psq
