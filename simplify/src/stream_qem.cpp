// SPDX-License-Identifier: Apache-2.0
// Stream decimation on a processing sequence: Wu and Kobbelt, "A Stream
// Algorithm for the Decimation of Massive Meshes" (Graphics Interface 2003),
// as adapted to processing sequences by Isenburg, Lindstrom, Gumhold and
// Snoeyink, "Large Mesh Simplification using Processing Sequences" (IEEE
// Visualization 2003), section 6; error quadrics of Garland and Heckbert,
// "Surface Simplification Using Quadric Error Metrics" (SIGGRAPH 1997),
// with their border planes.
#include "psq/stream_qem.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <vector>

#include "corner_values.h"
#include "qem_quadric.h"
#include "sink_state.h"

namespace psq {
namespace {

using detail::QemQuadric;

// A border edge's plane weighs this many times its squared length, so that
// moving a vertex off the border costs about as much as moving it off the
// surface over the edge's neighbourhood (Garland and Heckbert, section 6.1).
constexpr double kBorderWeight = 4.0;
// Rounds of candidates in a row that yield no collapse before decimation
// gives up for now (it resumes at the next step). For a count target, at
// the end of the input and when the buffer is full, it gives up only after
// this many plus twice the candidate vertices: each failed round takes a vertex out of the
// candidates or leaves it offering a collapse that passes, so a streak of
// failures (many candidates that cannot collapse, a foam's tetrahedra,
// among the cheapest) does not end decimation while collapses are left.
constexpr int kMaxFailedRounds = 16;
constexpr int kMaxFailedRoundsFinal = 64;
// Decimation runs every this many triangles read, while what it works on
// is still in the processor's caches.
constexpr uint32_t kDecimationStep = 2048;
// The converter behind the buffer keeps at least 65536 triangles waiting
// (about 200 bytes each; no lookahead beyond: the buffer's output order is
// a processing sequence's already), and some more while they settle
// (bench/RESULTS.md, "Simplification: stream edge collapse").
constexpr uint64_t kConverterBytes = uint64_t{90000} * 200;
// Vertices per triangle in the buffer, for its room: about one half on
// closed meshes, but more in the band along the input boundary, which is a
// strip (0.83 on a 200M-triangle foam ball, whose band fills most of a 64
// MB buffer); room beyond this grows by doubling.
constexpr double kVerticesPerTriangle = 0.85;
// Bytes per buffer triangle: the buffer's own, a reference normal per
// triangle, and per vertex a VertexData, a score and a candidate entry.
constexpr double kVertexQemBytes = 112 + 4 + 8;
constexpr double kBytesPerTriangle =
    TriangleBuffer::kTriangleBytes + 12 + kVerticesPerTriangle * (TriangleBuffer::kVertexBytes + kVertexQemBytes);
// A component is dropped whole only when it has at most this many
// triangles (a search for one stops there), and its half box diagonal is
// at most the largest error of a collapse so far.
constexpr uint32_t kMaxDropTriangles = 1024;
// Below this shape() a triangle is a sliver (its smallest angle under
// about 0.06 degrees): no collapse may make one of a sound triangle.
constexpr double kSliver = 1e-6;
// Below this shape() a triangle is degenerate (smallest angle under about
// 0.002 degrees, as quantization leaves where close vertices met): its
// normal means nothing.
constexpr double kDegenerate = 1e-9;
// The pull of a merged vertex towards its edge's midpoint, relative to the
// quadric's trace (its total plane weight).
constexpr double kPull = 1e-3;

void sub(const double a[3], const double b[3], double r[3]) {
  r[0] = a[0] - b[0];
  r[1] = a[1] - b[1];
  r[2] = a[2] - b[2];
}
void cross(const double a[3], const double b[3], double r[3]) {
  r[0] = a[1] * b[2] - a[2] * b[1];
  r[1] = a[2] * b[0] - a[0] * b[2];
  r[2] = a[0] * b[1] - a[1] * b[0];
}
double dot(const double a[3], const double b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

// How far from a sliver the triangle of edges e1 and e2 (from one corner)
// and normal n = e1 x e2 is: the squared sine of its smallest angle, about
// (|n| / longest edge^2)^2; 0.75 for an equilateral triangle.
double shape(const double n[3], const double e1[3], const double e2[3]) {
  double e3[3];
  sub(e2, e1, e3);
  const double l = std::max({dot(e1, e1), dot(e2, e2), dot(e3, e3)});
  return l > 0 ? dot(n, n) / (l * l) : 0;
}

// shape() < kSliver, without its division.
bool is_sliver(const double n[3], const double e1[3], const double e2[3]) {
  double e3[3];
  sub(e2, e1, e3);
  const double l = std::max({dot(e1, e1), dot(e2, e2), dot(e3, e3)});
  return !(dot(n, n) >= kSliver * l * l);
}

struct Candidate {
  double cost;
  uint32_t h;
  bool keep_start;
  double x[3];  // the merged vertex, in normalized coordinates
};

// The candidate vertices by the cost of their cheapest edge: bands of a
// quarter of an octave (a float's exponent and two leading bits of its
// mantissa, in the order of the values), each an unordered array, and a
// bitmap of the bands in use, so that the cheapest band is found in a few
// steps and the multiple choice compares candidates of nearly the least
// cost (Wu and Kobbelt's random candidates come from the whole buffer,
// whose costs span many octaves).
class CostBands {
 public:
  static constexpr uint32_t kNone = 0xffffffffu;
  struct Entry {
    uint32_t vertex;
    float cost;
  };

  static uint16_t band_of(float cost) {
    uint32_t bits;
    std::memcpy(&bits, &cost, 4);
    return static_cast<uint16_t>(bits >> 21);  // costs are not negative
  }
  bool empty() const { return size_ == 0; }
  size_t size() const { return size_; }
  // Puts vertex v at `cost`; *band and *slot are where it is kept (slot
  // kNone: not kept). Returns the vertex whose slot became *slot's old
  // value when v left its band, or kNone.
  uint32_t put(uint32_t v, float cost, uint16_t* band, uint32_t* slot) {
    const uint16_t b = band_of(cost);
    if (*slot != kNone && *band == b) {
      bands_[b][*slot].cost = cost;
      return kNone;
    }
    uint32_t moved = kNone;
    uint32_t old_slot = *slot;
    if (*slot != kNone) moved = remove(*band, *slot);
    std::vector<Entry>& list = bands_[b];
    if (list.empty()) used_[b >> 6] |= uint64_t{1} << (b & 63);
    *band = b;
    *slot = static_cast<uint32_t>(list.size());
    list.push_back({v, cost});
    ++size_;
    last_moved_slot_ = old_slot;
    return moved;
  }
  // Takes out the entry at (band, slot); returns the vertex moved into
  // that slot, or kNone.
  uint32_t remove(uint16_t band, uint32_t slot) {
    std::vector<Entry>& list = bands_[band];
    const Entry last = list.back();
    list.pop_back();
    uint32_t moved = kNone;
    if (slot < list.size()) {
      list[slot] = last;
      moved = last.vertex;
    }
    if (list.empty()) used_[band >> 6] &= ~(uint64_t{1} << (band & 63));
    --size_;
    return moved;
  }
  uint32_t last_moved_slot() const { return last_moved_slot_; }
  // The cheapest band in use (not empty()).
  const std::vector<Entry>& cheapest() const {
    for (int w = 0;; ++w)
      if (used_[w]) return bands_[64 * w + __builtin_ctzll(used_[w])];
  }

 private:
  std::vector<Entry> bands_[1024];
  uint64_t used_[16] = {};
  size_t size_ = 0;
  uint32_t last_moved_slot_ = kNone;
};

}  // namespace

uint32_t qem_buffer_triangles(uint64_t memory_budget) {
  const double spare = static_cast<double>(memory_budget) - static_cast<double>(kConverterBytes) - (2 << 20);
  const double n = spare / kBytesPerTriangle;
  return static_cast<uint32_t>(std::clamp(n, 1024.0, static_cast<double>(uint64_t{1} << 28)));
}

struct StreamQem::Impl {
  explicit Impl(SequenceSink* out, const QemOptions& o) : buffer(out), opt(o) {}

  // Per buffer vertex: its quadric, and its cheapest edge to another
  // unlocked vertex, kept up to date as the buffer changes, so that the
  // multiple choice compares cached costs in a small array instead of
  // visiting random parts of the buffer (Wu and Kobbelt's candidates are
  // edges; here each sampled vertex offers its cheapest edge).
  struct VertexData {
    QemQuadric q;
    double inverse_weight = 1;  // of q, once the vertex is complete
    float cost = kInfinity;  // of its cheapest edge; infinite: none
    uint32_t target = TriangleBuffer::kNone;  // the other end of that edge
    uint32_t slot = TriangleBuffer::kNone;    // its place in the band of `cost` in `set`
    uint32_t visit = 0;  // the component search that last reached it
  };
  static constexpr float kInfinity = std::numeric_limits<float>::infinity();

  TriangleBuffer buffer;
  detail::CornerValues corners;  // corner_uv and corner_normals, if the mesh has them
  QemOptions opt;
  QemReport report;
  detail::SinkState state;

  std::vector<VertexData> data;
  // The error at each vertex's place (the output's add preference).
  std::vector<float> score;
  // Per triangle: its unit normal when it was read (zero if degenerate).
  std::vector<std::array<float, 3>> reference;
  std::vector<uint32_t> search_queue;  // of component()
  // Unlocked vertices that have an edge to offer.
  CostBands set;
  // Component searches: VertexData::visit marks above visit_base are this
  // round's, visit_epoch the current search's.
  uint32_t visit_epoch = 0;
  uint32_t visit_base = 0;
  // The target count at the end, once the input's count is known.
  uint64_t final_target = 0;
  // Normalized coordinates: (p - origin) * scale, the box diagonal 1 when
  // the schema gives the box.
  double origin[3] = {0, 0, 0};
  double scale = 1;
  bool bounds_known = false;
  // The input's declared bounding box in normalized coordinates: the output
  // is quantized on the grid of that box (psq/mesh_stream.h), so no vertex
  // may leave it.
  double box_lo[3] = {0, 0, 0}, box_hi[3] = {0, 0, 0};
  double world_lo[3] = {0, 0, 0}, world_hi[3] = {0, 0, 0};  // the same box, unnormalized
  bool seen_vertex = false;
  double lo[3] = {0, 0, 0}, hi[3] = {0, 0, 0};
  double ratio = 0;
  bool count_target = false;
  double max_cost = 0;
  uint32_t capacity = 0, low = 0;
  uint32_t since_decimation = 0;
  uint64_t rng = 0;

  Status fail(Status s) { return state.fail(std::move(s)); }

  uint64_t random() {
    uint64_t z = (rng += 0x9e3779b97f4a7c15ull);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
  }

  void to_normalized(const double p[3], double x[3]) const {
    for (int i = 0; i < 3; ++i) x[i] = (p[i] - origin[i]) * scale;
  }
  void normalized(uint32_t v, double x[3]) const { to_normalized(buffer.position(v), x); }
  // Back to the input's coordinates, inside its declared box also where
  // the division rounds past the box's face.
  void world(const double x[3], double p[3]) const {
    for (int i = 0; i < 3; ++i) p[i] = x[i] / scale + origin[i];
    if (bounds_known)
      for (int i = 0; i < 3; ++i) p[i] = std::min(world_hi[i], std::max(world_lo[i], p[i]));
  }
  bool pinned(uint32_t v) const { return buffer.cut(v) || (opt.lock_border && buffer.border(v)); }

  // The largest cost allowed, in normalized squared units; negative: none.
  double cost_limit() const {
    if (opt.max_error < 0) return -1;
    double diag = 1;
    if (!bounds_known) {
      const double d[3] = {hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]};
      diag = std::sqrt(dot(d, d)) * scale;
    }
    const double e = opt.max_error * diag;
    return e * e;
  }

  void set_cost(uint32_t v, float cost, uint32_t target) {
    VertexData& d = data[v];
    if (!(cost < kInfinity)) {
      leave_set(v);
      return;
    }
    uint16_t band = CostBands::band_of(d.cost);  // where v is kept, if it is
    d.cost = cost;
    d.target = target;
    const uint32_t moved = set.put(v, cost, &band, &d.slot);
    if (moved != TriangleBuffer::kNone) data[moved].slot = set.last_moved_slot();
  }
  void leave_set(uint32_t v) {
    VertexData& d = data[v];
    const uint16_t band = CostBands::band_of(d.cost);
    d.cost = kInfinity;
    d.target = TriangleBuffer::kNone;
    if (d.slot == TriangleBuffer::kNone) return;
    const uint32_t moved = set.remove(band, d.slot);
    if (moved != TriangleBuffer::kNone) data[moved].slot = d.slot;
    d.slot = TriangleBuffer::kNone;
  }

  template <class F>
  void for_each_edge(uint32_t v, F&& f) {
    // Each neighbour follows one corner of v, but for the one that only
    // precedes a corner across a border edge.
    for (uint32_t c = buffer.first_corner(v); c != TriangleBuffer::kNone; c = buffer.next_corner(c)) {
      f(buffer.vertex_of(TriangleBuffer::next(c)), c);
      const uint32_t p = TriangleBuffer::prev(c);
      if (buffer.opposite(p) == TriangleBuffer::kBorder) f(buffer.vertex_of(p), p);
    }
  }

  // The quadric that prices the collapse of edge (a, b): each end's mean
  // squared distance to its planes, summed, so that a vertex of a small
  // area (the tip of a thin feature) does not move far for free because
  // its planes are outweighed by a large neighbour's.
  QemQuadric collapse_quadric(uint32_t a, uint32_t b) const {
    QemQuadric q;
    const QemQuadric& qa = data[a].q;
    const QemQuadric& qb = data[b].q;
    q.add_scaled(qa, data[a].inverse_weight);
    q.add_scaled(qb, data[b].inverse_weight);
    q.weight = 1;
    return q;
  }

  void refresh(uint32_t v, bool relax, uint32_t a = TriangleBuffer::kNone, uint32_t b = TriangleBuffer::kNone);
  void locked_now(uint32_t v);
  Status begin(const MeshSchema& schema);
  Status triangle(const SequenceTriangle& t);
  void add_quadrics(uint32_t tri, uint8_t border_mask);
  // The cheapest collapse of edge h; with `ends`, also those onto either
  // end (none where the border rules allow one place only).
  bool evaluate(uint32_t h, Candidate* c, Candidate* ends = nullptr, int* n_ends = nullptr);
  bool allowed(const Candidate& c, bool topology_checked);
  void kept_place(const Candidate& c, double p[3]);
  bool apply(const Candidate& c);
  bool flips(uint32_t h, const double p[3]);
  void fan_normal(uint32_t a, uint32_t b, double n[3]);
  void refuse(uint32_t v);
  bool collapse_one(double limit);
  void decimate(bool final, bool full = false);
  // `beyond`: past the largest collapse error so far, one at a time (the
  // last resort at the end).
  bool drop_components(double excess, bool final, double limit, bool beyond);
  bool cut_cycles(double excess, double limit, bool beyond);
  bool component(uint32_t v, std::vector<uint32_t>* triangles, double* cost);
  Status write_until(uint32_t target);
  Status finish();
};

Status StreamQem::Impl::begin(const MeshSchema& schema) {
  if (opt.candidates < 1 || opt.candidates > 64) return Status(ErrorCode::kUsage, "candidates must be 1..64");
  if (!(opt.ratio >= 0 && opt.ratio <= 1)) return Status(ErrorCode::kUsage, "ratio must be in (0, 1]");
  if (!(opt.max_error < 0 || std::isfinite(opt.max_error)))
    return Status(ErrorCode::kUsage, "max error must be a finite number");
  if (opt.ratio == 0 && opt.target_triangles == 0 && opt.max_error < 0)
    return Status(ErrorCode::kUsage, "no target: give a ratio, a triangle count or a largest error");
  ratio = opt.ratio;
  count_target = opt.ratio > 0;
  if (opt.target_triangles > 0) {
    const uint64_t in = schema.triangle_count >= 0 ? static_cast<uint64_t>(schema.triangle_count) : opt.input_triangles;
    if (schema.triangle_count < 0 && opt.input_triangles == 0)
      return Status(ErrorCode::kUsage, "a triangle count target needs the input's triangle count, which it does "
                                       "not declare (give a ratio instead)");
    const double r = in == 0 ? 1.0 : std::min(1.0, static_cast<double>(opt.target_triangles) / static_cast<double>(in));
    ratio = std::max(ratio, r);
    count_target = true;
  }
  if (schema.has_bounds) {
    double d[3];
    for (int i = 0; i < 3; ++i) {
      origin[i] = 0.5 * (schema.bounds_min[i] + schema.bounds_max[i]);
      d[i] = schema.bounds_max[i] - schema.bounds_min[i];
    }
    const double diag = std::sqrt(dot(d, d));
    if (diag > 0 && std::isfinite(diag) && std::isfinite(origin[0] + origin[1] + origin[2])) {
      scale = 1 / diag;
      bounds_known = true;
      for (int i = 0; i < 3; ++i) {
        world_lo[i] = schema.bounds_min[i];
        world_hi[i] = schema.bounds_max[i];
        box_lo[i] = (schema.bounds_min[i] - origin[i]) * scale;
        box_hi[i] = (schema.bounds_max[i] - origin[i]) * scale;
      }
    } else {
      origin[0] = origin[1] = origin[2] = 0;
    }
  }
  capacity = opt.buffer_triangles ? opt.buffer_triangles : qem_buffer_triangles(opt.memory_budget);
  capacity = std::max<uint32_t>(capacity, 16);
  low = capacity - capacity / 8;
  report.buffer_triangles = capacity;
  rng = opt.seed ^ 0x5851f42d4c957f2dull;
  buffer.set_seed(opt.seed);
  buffer.set_lookahead_budget(0);
  // All the room at once: growth by doubling would copy, and take up to
  // half as much again while it does.
  const uint32_t room = std::min(capacity, qem_buffer_triangles(opt.memory_budget)) + 64;
  const uint32_t vertices = static_cast<uint32_t>(kVerticesPerTriangle * room);
  buffer.reserve(room, vertices);
  data.reserve(vertices);
  score.reserve(vertices);
  reference.reserve(room);
  corners.init(schema);
  return buffer.begin(schema);
}

void StreamQem::Impl::add_quadrics(uint32_t tri, uint8_t border_mask) {
  uint32_t v[3];
  double p[3][3];
  for (int k = 0; k < 3; ++k) {
    v[k] = buffer.vertex_of(3 * tri + k);
    normalized(v[k], p[k]);
  }
  double e1[3], e2[3], n[3];
  sub(p[1], p[0], e1);
  sub(p[2], p[0], e2);
  cross(e1, e2, n);
  const double len = std::sqrt(dot(n, n));
  if (!(len > 0) || !std::isfinite(len)) {  // no plane: a degenerate triangle
    reference[tri] = {0, 0, 0};
    return;
  }
  const bool degenerate = shape(n, e1, e2) < kDegenerate;
  for (double& c : n) c /= len;
  reference[tri] = {0, 0, 0};
  if (!degenerate) {
    for (int i = 0; i < 3; ++i) reference[tri][i] = static_cast<float>(n[i]);
  }
  const double d = -dot(n, p[0]);
  QemQuadric q;
  q.add_plane(n, d, 0.5 * len);
  for (int k = 0; k < 3; ++k) data[v[k]].q.add(q);
  for (int k = 0; k < 3; ++k) {
    if (!(border_mask & (1u << k))) continue;
    double e[3], m[3];
    sub(p[(k + 1) % 3], p[k], e);
    cross(e, n, m);
    const double ml = std::sqrt(dot(m, m));
    if (!(ml > 0)) continue;
    for (double& c : m) c /= ml;
    QemQuadric b;
    b.add_plane(m, -dot(m, p[k]), kBorderWeight * dot(e, e));
    data[v[k]].q.add(b);
    data[v[(k + 1) % 3]].q.add(b);
  }
}

Status StreamQem::Impl::triangle(const SequenceTriangle& t) {
  uint32_t tri;
  PSQ_RETURN_IF_ERROR(buffer.triangle(t, &tri));
  if (data.size() < buffer.vertex_capacity()) {
    data.resize(buffer.vertex_capacity());
    score.resize(buffer.vertex_capacity());
  }
  if (reference.size() < buffer.triangle_capacity()) reference.resize(buffer.triangle_capacity());
  for (int k = 0; k < 3; ++k) {
    if (!(t.new_mask & (1u << k))) continue;
    const uint32_t v = buffer.vertex_of(3 * tri + k);
    data[v] = VertexData();
    score[v] = 0;
  }
  add_quadrics(tri, t.border_mask);
  // Vertices the input finalized are complete: their edges to unlocked
  // neighbours become candidates.
  for (int k = 0; k < 3; ++k) {
    const uint32_t v = buffer.vertex_of(3 * tri + k);
    if (!(t.final_mask & (1u << k))) continue;
    data[v].inverse_weight = data[v].q.weight > 0 ? 1 / data[v].q.weight : 1;
    if (!buffer.locked(v)) refresh(v, true);
  }
  if (++since_decimation >= kDecimationStep || buffer.triangle_count() >= capacity) {
    since_decimation = 0;
    decimate(false, buffer.triangle_count() >= capacity);
    if (buffer.triangle_count() >= capacity) return write_until(low);
  }
  return Status();
}

// Recomputes v's cheapest edge. With `relax`, each neighbour learns its
// edge to v too (v is new to them, or v moved and merged `a` and `b`): the
// cost is the same from both ends.
void StreamQem::Impl::refresh(uint32_t v, bool relax, uint32_t a, uint32_t b) {
  float best = kInfinity;
  uint32_t best_target = TriangleBuffer::kNone;
  for_each_edge(v, [&](uint32_t u, uint32_t h) {
    if (buffer.locked(u)) return;
    Candidate c;
    if (!evaluate(h, &c)) return;
    const float cost = static_cast<float>(c.cost);
    if (cost < best) {
      best = cost;
      best_target = u;
    }
    if (!relax) return;
    // The neighbour's cheapest edge was to an end of the collapse, or to
    // v itself: that edge is this one now. Its other edges may be cheaper;
    // they are offered by their other ends too, and u's own cost is
    // recomputed when it is chosen or a neighbour changes.
    VertexData& du = data[u];
    if (cost < du.cost || (du.target != TriangleBuffer::kNone && (du.target == a || du.target == b || du.target == v)))
      set_cost(u, cost, v);
  });
  set_cost(v, best, best_target);
}

// v was just written: it is no candidate any more, nor anyone's target.
void StreamQem::Impl::locked_now(uint32_t v) {
  leave_set(v);
  for (uint32_t c = buffer.first_corner(v); c != TriangleBuffer::kNone; c = buffer.next_corner(c)) {
    for (uint32_t u : {buffer.vertex_of(TriangleBuffer::next(c)), buffer.vertex_of(TriangleBuffer::prev(c))}) {
      if (!buffer.locked(u) && data[u].target == v) refresh(u, false);
    }
  }
}

bool StreamQem::Impl::evaluate(uint32_t h, Candidate* c, Candidate* ends, int* n_ends) {
  if (n_ends) *n_ends = 0;
  const uint32_t a = buffer.vertex_of(h), b = buffer.vertex_of(TriangleBuffer::next(h));
  const bool pa = pinned(a), pb = pinned(b);
  if (pa && pb) return false;
  const QemQuadric q = collapse_quadric(a, b);
  double xa[3], xb[3];
  normalized(a, xa);
  normalized(b, xb);
  c->h = h;
  // Border vertices stay on the border: a border edge collapses onto
  // itself, and an interior vertex merges into a border neighbour, so that
  // the border only shrinks.
  const bool ba = buffer.border(a), bb = buffer.border(b);
  if (pa || pb || ba != bb) {
    c->keep_start = pa || (!pb && ba);
    std::copy(c->keep_start ? xa : xb, (c->keep_start ? xa : xb) + 3, c->x);
    c->cost = q.value(c->x);
    return true;
  }
  if (ba && buffer.opposite(h) != TriangleBuffer::kBorder) return false;  // a pinch: can_collapse refuses it
  // Away from borders, seams of the corner values (a texture chart's
  // border, a hard edge) are kept the same way: a seam vertex merges only
  // along its seam, and an interior vertex into a seam neighbour, in place.
  const bool sa = !ba && corners.active() && corners.seam_vertex(buffer, a);
  const bool sb = !ba && corners.active() && corners.seam_vertex(buffer, b);
  if (sa != sb) {
    c->keep_start = sa;
    std::copy(c->keep_start ? xa : xb, (c->keep_start ? xa : xb) + 3, c->x);
    c->cost = q.value(c->x);
    return true;
  }
  if (sa && !corners.seam_edge(buffer, h)) return false;
  const bool ca = ba || sa;
  double e[3];
  sub(xb, xa, e);
  bool placed = false;
  if (!ca) {
    double m[3];
    for (int i = 0; i < 3; ++i) m[i] = 0.5 * (xa[i] + xb[i]);
    placed = q.minimum(kPull * (q.a00 + q.a11 + q.a22), m, c->x);
    if (placed) {
      // A solution far from the edge comes from a nearly singular system.
      double d[3];
      sub(c->x, m, d);
      placed = dot(d, d) <= 4 * dot(e, e);
      // The minimum may lie past the input's box (a convex corner's planes
      // meet outside it); the edge's ends and every point between them lie
      // inside, so the clamped point is no worse a start than the segment.
      if (placed && bounds_known)
        for (int i = 0; i < 3; ++i) c->x[i] = std::min(box_hi[i], std::max(box_lo[i], c->x[i]));
    }
  }
  if (!placed) {
    const double t = q.minimum_on_segment(xa, e);
    for (int i = 0; i < 3; ++i) c->x[i] = xa[i] + t * e[i];
  }
  double da[3], db[3];
  sub(c->x, xa, da);
  sub(c->x, xb, db);
  c->keep_start = dot(da, da) <= dot(db, db);
  c->cost = q.value(c->x);
  // An end may do better than the (regularized) minimum; the ends are the
  // fallbacks when the best place flips a triangle.
  const double ea = q.value(xa), eb = q.value(xb);
  if (ea < c->cost || eb < c->cost) {
    c->keep_start = ea <= eb;
    std::copy(c->keep_start ? xa : xb, (c->keep_start ? xa : xb) + 3, c->x);
    c->cost = std::min(ea, eb);
  }
  if (ends) {
    const bool start_first = ea <= eb;
    for (int i = 0; i < 2; ++i) {
      Candidate& o = ends[i];
      o.h = h;
      o.keep_start = (i == 0) == start_first;
      std::copy(o.keep_start ? xa : xb, (o.keep_start ? xa : xb) + 3, o.x);
      o.cost = o.keep_start ? ea : eb;
    }
    *n_ends = 2;
  }
  return true;
}

// Whether moving the ends of edge h to p (a position) flips, degenerates or
// turns too far a triangle that stays, or makes a sliver of it. A
// triangle's orientation is judged against its own normal, or, for a
// degenerate one, whose normal means nothing, against the normal of the
// whole neighbourhood.
bool StreamQem::Impl::flips(uint32_t h, const double x[3]) {
  // (In the input's coordinates: every test here is one of signs or of
  // ratios.)
  const uint32_t a = buffer.vertex_of(h), b = buffer.vertex_of(TriangleBuffer::next(h));
  double around[3] = {0, 0, 0};
  bool around_known = false;
  for (uint32_t v : {a, b}) {
    const uint32_t other = v == a ? b : a;
    for (uint32_t c = buffer.first_corner(v); c != TriangleBuffer::kNone; c = buffer.next_corner(c)) {
      const uint32_t v1 = buffer.vertex_of(TriangleBuffer::next(c)), v2 = buffer.vertex_of(TriangleBuffer::prev(c));
      if (v1 == other || v2 == other) continue;  // goes with the edge
      const double* p0 = buffer.position(v);
      const double* p1 = buffer.position(v1);
      const double* p2 = buffer.position(v2);
      double e1[3], e2[3], f1[3], f2[3], n0[3], n1[3];
      sub(p1, p0, e1);
      sub(p2, p0, e2);
      cross(e1, e2, n0);
      sub(p1, x, f1);
      sub(p2, x, f2);
      cross(f1, f2, n1);
      // The shapes only where they may matter: a new sliver, or an old
      // normal that may mean nothing.
      const bool sliver = is_sliver(n1, f1, f2);
      const double q0 = sliver || !(dot(n0, n1) > 0) ? shape(n0, e1, e2) : 1.0;
      const double q1 = sliver ? 0.0 : 1.0;
      if (q1 < kSliver && q0 >= kSliver) return true;
      if (q0 >= kDegenerate) {
        if (!(dot(n0, n1) > 0)) return true;
      } else {
        if (!around_known) {
          fan_normal(a, b, around);
          around_known = true;
        }
        // A degenerate triangle that stays degenerate is no worse.
        if (dot(n1, n1) > 0 && !(dot(around, n1) > 0)) return true;
      }
      // Nor may it turn past a right angle from its normal when it was
      // read, so that turns do not add up to a flip.
      const std::array<float, 3>& r = reference[c / 3];
      if (r[0] == 0 && r[1] == 0 && r[2] == 0) continue;  // read degenerate
      if (!(n1[0] * r[0] + n1[1] * r[1] + n1[2] * r[2] > 0)) return true;
    }
  }
  return false;
}

// The sum of the normals of the triangles around edge (a, b), weighted by
// their areas.
void StreamQem::Impl::fan_normal(uint32_t a, uint32_t b, double n[3]) {
  for (uint32_t v : {a, b}) {
    for (uint32_t c = buffer.first_corner(v); c != TriangleBuffer::kNone; c = buffer.next_corner(c)) {
      const uint32_t v1 = buffer.vertex_of(TriangleBuffer::next(c)), v2 = buffer.vertex_of(TriangleBuffer::prev(c));
      if (v == b && (v1 == a || v2 == a)) continue;  // counted from a
      double e1[3], e2[3], m[3];
      sub(buffer.position(v1), buffer.position(v), e1);
      sub(buffer.position(v2), buffer.position(v), e2);
      cross(e1, e2, m);
      for (int i = 0; i < 3; ++i) n[i] += m[i];
    }
  }
}

// Whether collapse c keeps the topology (unless already checked) and
// flips, degenerates or turns too far no triangle.
bool StreamQem::Impl::allowed(const Candidate& c, bool topology_checked) {
  if (!topology_checked && !buffer.can_collapse(c.h)) return false;
  double p[3];
  kept_place(c, p);
  return !flips(c.h, p) && (!corners.active() || corners.plan(buffer, c.h, c.keep_start, p));
}

// Where collapse c puts its kept vertex: c's place, rounded as the buffer
// stores it, or where it is if it is pinned.
void StreamQem::Impl::kept_place(const Candidate& c, double p[3]) {
  const uint32_t keep = buffer.vertex_of(c.keep_start ? c.h : TriangleBuffer::next(c.h));
  if (pinned(keep)) {
    std::copy(buffer.position(keep), buffer.position(keep) + 3, p);
    return;
  }
  world(c.x, p);
  buffer.round_position(p);
}

// v's cheapest edge was refused: offer its cheapest collapse that passes,
// ends of edges included, if any.
void StreamQem::Impl::refuse(uint32_t v) {
  Candidate options[96];
  int8_t edge_ok[32];  // per edge: -1 unknown, 0 refused, 1 topology allowed
  uint8_t edge_of[96];
  int n = 0, edges = 0;
  for_each_edge(v, [&](uint32_t u, uint32_t h) {
    if (edges == 32 || buffer.locked(u)) return;
    const int first = n;
    int n_ends = 0;
    if (evaluate(h, &options[n], &options[n + 1], &n_ends)) n += 1 + n_ends;
    for (int i = first; i < n; ++i) edge_of[i] = static_cast<uint8_t>(edges);
    edge_ok[edges++] = -1;
  });
  // Cheapest first, by selection: usually the first few decide.
  uint8_t order[96];
  for (int i = 0; i < n; ++i) order[i] = static_cast<uint8_t>(i);
  for (int i = 0; i < n; ++i) {
    int best = i;
    for (int j = i + 1; j < n; ++j)
      if (options[order[j]].cost < options[order[best]].cost) best = j;
    std::swap(order[i], order[best]);
    const Candidate& c = options[order[i]];
    int8_t& ok = edge_ok[edge_of[order[i]]];
    if (ok < 0) ok = buffer.can_collapse(c.h) ? 1 : 0;
    if (!ok || !allowed(c, true)) continue;
    const uint32_t a = buffer.vertex_of(c.h), b = buffer.vertex_of(TriangleBuffer::next(c.h));
    set_cost(v, static_cast<float>(c.cost), a == v ? b : a);
    return;
  }
  set_cost(v, kInfinity, TriangleBuffer::kNone);
}

// Collapses k (allowed(k) held); false, changing nothing, if its corner
// values have no plan (allowed() made the same one: not expected).
bool StreamQem::Impl::apply(const Candidate& k) {
  const uint32_t h = k.h;
  const uint32_t a = buffer.vertex_of(h), b = buffer.vertex_of(TriangleBuffer::next(h));
  double p[3];
  kept_place(k, p);
  if (corners.active() && !corners.plan(buffer, h, k.keep_start, p)) return false;
  QemQuadric q = data[a].q;
  q.add(data[b].q);
  const uint32_t gone = k.keep_start ? b : a;
  leave_set(gone);
  const uint32_t keep = buffer.collapse(h, k.keep_start);
  data[keep].q = q;
  data[keep].inverse_weight = q.weight > 0 ? 1 / q.weight : 1;
  buffer.set_position(keep, p);
  if (corners.active()) corners.apply(&buffer);
  score[keep] = static_cast<float>(k.cost);
  max_cost = std::max(max_cost, k.cost);
  // The kept vertex moved and its quadric grew: its edges cost anew.
  refresh(keep, true, a, b);
  return true;
}

bool StreamQem::Impl::collapse_one(double limit) {
  if (set.empty()) return false;
  // Multiple choice among the candidates of the cheapest band.
  const std::vector<CostBands::Entry>& band = set.cheapest();
  uint32_t pick = static_cast<uint32_t>(band.size() == 1 ? 0 : random() % band.size());
  if (band.size() <= static_cast<size_t>(opt.candidates)) {
    for (uint32_t j = 0; j < band.size(); ++j)
      if (band[j].cost < band[pick].cost) pick = j;
  } else {
    for (int i = 1; i < opt.candidates; ++i) {
      const uint32_t j = static_cast<uint32_t>(random() % band.size());
      if (band[j].cost < band[pick].cost) pick = j;
    }
  }
  const float picked_cost = band[pick].cost;
  const uint32_t v = band[pick].vertex;
  const uint32_t target = data[v].target;
  if (limit >= 0 && picked_cost > limit) return false;
  uint32_t h = TriangleBuffer::kNone;
  for_each_edge(v, [&](uint32_t u, uint32_t e) {
    if (u == target && h == TriangleBuffer::kNone) h = e;
  });
  Candidate k, ends[2];
  int n = 0;
  if (h == TriangleBuffer::kNone || buffer.locked(target) || !evaluate(h, &k, ends, &n)) {
    refresh(v, false);
    return false;
  }
  if (!buffer.can_collapse(h)) {
    refuse(v);
    return false;
  }
  if (!allowed(k, true)) {
    // The best place flips a triangle: an end of the edge may not, at a
    // cost no higher than the next vertex offers; else v offers its best
    // allowed collapse instead, at its own cost.
    int i = 0;
    while (i < n && !(ends[i].cost <= 2 * picked_cost + 1e-30 && allowed(ends[i], true))) ++i;
    if (i == n) {
      refuse(v);
      return false;
    }
    k = ends[i];
  }
  if (!apply(k)) {
    refuse(v);
    return false;
  }
  return true;
}

void StreamQem::Impl::decimate(bool final, bool full) {
  const double limit = cost_limit();
  int failed = 0;
  const bool thorough = count_target && (final || full);
  int max_failed = final ? kMaxFailedRoundsFinal : kMaxFailedRounds;
  for (;;) {
    if (thorough) max_failed = kMaxFailedRoundsFinal + static_cast<int>(std::min<size_t>(2 * set.size(), 1u << 30));
    double excess = 0;
    if (count_target) {
      const TriangleBufferStats& st = buffer.stats();
      const double total = static_cast<double>(st.triangles_written + buffer.triangle_count());
      // At the end, the count the report promises; before, the share of
      // what was read, with the band along the input boundary, which
      // nothing may change yet, counted as it will be once simplified (the
      // rest is not over-simplified to make room for it).
      const double goal = final ? static_cast<double>(final_target)
                                : ratio * static_cast<double>(st.triangles_read) + (1 - ratio) * buffer.input_band();
      excess = total - goal;
      if (excess <= 0) return;
    }
    if (collapse_one(limit)) {
      failed = 0;
    } else if (++failed >= max_failed) {
      // No collapse is left (for now): where components that no collapse
      // can reduce any more hold the count above the target, the cheapest
      // of them go whole, components being kept unless the target cannot
      // be met otherwise. Not before the last moment a component can go:
      // when the buffer is full, before triangles leave it, or at the end
      // (collapses elsewhere may have made up for it by then).
      if (count_target && thorough &&
          (drop_components(excess, final, limit, false) || cut_cycles(excess, limit, false))) {
        failed = 0;
        continue;
      }
      // At the end, when nothing within that error is left, the count
      // still wins over the shape ("kept unless the target cannot be met
      // otherwise"): the cheapest component goes, or else the narrowest
      // handle is cut, whatever it costs (still within max_error), one at
      // a time, and collapses go on from there.
      if (count_target && final && (drop_components(excess, final, limit, true) || cut_cycles(excess, limit, true))) {
        failed = 0;
        continue;
      }
      return;
    }
  }
}

// The component of vertex v, if it may go whole: every triangle of it in
// the buffer (none written, none still to be read: every vertex unlocked),
// at most kMaxDropTriangles of them, and no vertex with a collapse to
// offer (the component is at its floor), nor one locked by lock_border.
// Its triangles go to *triangles; *cost is the squared half diagonal of its
// box (normalized), about the distance its surface is from what stays.
bool StreamQem::Impl::component(uint32_t v, std::vector<uint32_t>* triangles, double* cost) {
  triangles->clear();
  if (data[v].visit > visit_base || buffer.first_corner(v) == TriangleBuffer::kNone) return false;
  const uint32_t search = ++visit_epoch;
  std::vector<uint32_t>& queue = search_queue;
  queue.assign(1, v);
  data[v].visit = search;
  double lo3[3], hi3[3];
  normalized(v, lo3);
  std::copy(lo3, lo3 + 3, hi3);
  bool ok = true;
  for (size_t i = 0; i < queue.size() && ok; ++i) {
    const uint32_t u = queue[i];
    if (buffer.locked(u) || (opt.lock_border && pinned(u))) ok = false;
    double x[3];
    normalized(u, x);
    for (int j = 0; j < 3; ++j) {
      lo3[j] = std::min(lo3[j], x[j]);
      hi3[j] = std::max(hi3[j], x[j]);
    }
    for (uint32_t c = buffer.first_corner(u); c != TriangleBuffer::kNone && ok; c = buffer.next_corner(c)) {
      // Each triangle once: from the vertex of its first corner.
      if (c % 3 == 0) triangles->push_back(c / 3);
      for (uint32_t w : {buffer.vertex_of(TriangleBuffer::next(c)), buffer.vertex_of(TriangleBuffer::prev(c))}) {
        const uint32_t mark = data[w].visit;
        if (mark == search) continue;
        // Reached by an earlier search of this round, which stopped early
        // in this component: it is not one to drop.
        if (mark > visit_base) ok = false;
        data[w].visit = search;
        queue.push_back(w);
      }
      // An edge open or written: not all of the component is here.
      const uint32_t o = buffer.opposite(c);
      if (o >= TriangleBuffer::kOpen && o != TriangleBuffer::kBorder) ok = false;
    }
    if (triangles->size() > kMaxDropTriangles) ok = false;
  }
  if (!ok) return false;
  // A vertex may still offer an edge that cannot collapse (a
  // tetrahedron's; the cached cost does not know): it offers its best
  // allowed collapse now, if any.
  for (const uint32_t u : queue) {
    if (data[u].slot == TriangleBuffer::kNone) continue;
    refuse(u);
    if (data[u].slot != TriangleBuffer::kNone) return false;
  }
  double d[3];
  sub(hi3, lo3, d);
  *cost = 0.25 * dot(d, d);
  return true;
}

bool StreamQem::Impl::drop_components(double excess, bool final, double limit, bool beyond) {
  if (visit_epoch > 0xf0000000u) {
    for (VertexData& d : data) d.visit = 0;
    visit_epoch = 0;
  }
  visit_base = visit_epoch;
  struct Found {
    double cost;
    uint32_t begin, size;
  };
  std::vector<Found> found;
  std::vector<uint32_t> all, tris;
  // A component at its floor has only unlocked vertices, none of which
  // has a collapse to offer.
  for (uint32_t i = 0; i < buffer.free_vertex_count(); ++i) {
    const uint32_t v = buffer.free_vertex(i);
    double cost;
    if (!component(v, &tris, &cost)) continue;
    if (limit >= 0 && cost > limit) continue;
    // Nor farther than the collapses have moved the surface so far: a
    // small part goes, never one whose loss would dominate the error.
    if (cost > max_cost && !beyond) continue;
    found.push_back({cost, static_cast<uint32_t>(all.size()), static_cast<uint32_t>(tris.size())});
    all.insert(all.end(), tris.begin(), tris.end());
  }
  if (found.empty()) return false;
  std::sort(found.begin(), found.end(), [](const Found& a, const Found& b) {
    return a.cost < b.cost || (a.cost == b.cost && a.begin < b.begin);
  });
  // Mid-stream, a component goes when the excess is at least half of it.
  // At the end, the cheapest that fit in the excess go. `beyond`: one
  // component only, and if none fits, the smallest, when that leaves the
  // count nearer the target (nothing at its floor can make up for an
  // overshoot) and something of the mesh.
  bool dropped = false;
  auto drop = [&](Found& f) {
    // (Components are disjoint and were checked whole; can_discard()
    // guards the buffer all the same.)
    for (uint32_t i = 0; i < f.size; ++i)
      if (buffer.can_discard(all[f.begin + i])) buffer.discard(all[f.begin + i]);
    excess -= f.size;
    max_cost = std::max(max_cost, f.cost);
    ++report.components_dropped;
    f.size = 0;
    dropped = true;
  };
  for (Found& f : found) {
    const double n = f.size;
    if (final ? !(n <= excess) : !(excess >= 0.5 * n)) continue;
    drop(f);
    if (excess <= 0 || beyond) return true;
  }
  if (beyond && !dropped) {
    Found* smallest = nullptr;
    for (Found& f : found)
      if (smallest == nullptr || f.size < smallest->size) smallest = &f;
    // Never the last part: an empty output is no nearer in any useful
    // sense.
    const TriangleBufferStats& st = buffer.stats();
    const double total = static_cast<double>(st.triangles_written + buffer.triangle_count());
    if (excess - smallest->size > -excess && total > smallest->size) drop(*smallest);
  }
  return dropped;
}

// Handles (and necks) that no collapse can reduce further, three edges
// around: the link condition refuses each of their edges. When the count
// target cannot be met otherwise, the cheapest of them (by their longest
// edge, about the width of the tube the cut closes) are cut
// (TriangleBuffer::cut: each side closed by a triangle), within the largest
// collapse error so far and max_error, and collapses go on: a handle goes
// ("genus kept unless the target cannot be met otherwise"), or a neck
// splits its component. At most one cut per 8 triangles of excess a round.
bool StreamQem::Impl::cut_cycles(double excess, double limit, bool beyond) {
  struct Found {
    double cost;
    uint32_t h, c;
  };
  std::vector<Found> found;
  for (uint32_t i = 0; i < buffer.free_vertex_count(); ++i) {
    const uint32_t a = buffer.free_vertex(i);
    if (buffer.border(a) || buffer.cut(a)) continue;
    for (uint32_t h = buffer.first_corner(a); h != TriangleBuffer::kNone; h = buffer.next_corner(h)) {
      const uint32_t b = buffer.vertex_of(TriangleBuffer::next(h));
      if (b < a || buffer.locked(b)) continue;  // each edge once, from its smaller end
      uint32_t c;
      if (!buffer.cycle_of(h, &c)) continue;
      double pa[3], pb[3], pc[3], e[3];
      normalized(a, pa);
      normalized(b, pb);
      normalized(c, pc);
      sub(pa, pb, e);
      double longest = dot(e, e);
      sub(pb, pc, e);
      longest = std::max(longest, dot(e, e));
      sub(pc, pa, e);
      longest = std::max(longest, dot(e, e));
      const double cost = longest / 3;  // squared circumradius of an equilateral one
      if ((cost > max_cost && !beyond) || (limit >= 0 && cost > limit)) continue;
      found.push_back({cost, h, c});
    }
  }
  if (found.empty()) return false;
  std::sort(found.begin(), found.end(), [](const Found& x, const Found& y) {
    return x.cost < y.cost || (x.cost == y.cost && x.h < y.h);
  });
  const size_t most = beyond ? 1 : 1 + static_cast<size_t>(std::max(0.0, excess) / 8);
  size_t done = 0;
  for (const Found& f : found) {
    if (done == most) break;
    // Earlier cuts of this round may have changed the place.
    uint32_t c;
    if (!buffer.alive(f.h / 3) || !buffer.cycle_of(f.h, &c) || c != f.c) continue;
    const uint32_t v[3] = {buffer.vertex_of(f.h), buffer.vertex_of(TriangleBuffer::next(f.h)), c};
    uint32_t copies[3], caps[2];
    if (!buffer.cut(f.h, c, copies, caps)) continue;
    for (uint32_t cap : caps)
      if (corners.active()) corners.fill_cap(&buffer, cap);
    if (data.size() < buffer.vertex_capacity()) {
      data.resize(buffer.vertex_capacity());
      score.resize(buffer.vertex_capacity());
    }
    if (reference.size() < buffer.triangle_capacity()) reference.resize(buffer.triangle_capacity());
    for (int k = 0; k < 3; ++k) {
      leave_set(v[k]);
      VertexData& d = data[copies[k]];
      d = VertexData();
      d.q = data[v[k]].q;
      d.inverse_weight = data[v[k]].inverse_weight;
      score[copies[k]] = score[v[k]];
    }
    for (uint32_t t : caps) {
      double p[3][3];
      for (int k = 0; k < 3; ++k) normalized(buffer.vertex_of(3 * t + k), p[k]);
      double e1[3], e2[3], n[3];
      sub(p[1], p[0], e1);
      sub(p[2], p[0], e2);
      cross(e1, e2, n);
      const double len = std::sqrt(dot(n, n));
      reference[t] = {0, 0, 0};
      if (len > 0 && shape(n, e1, e2) >= kDegenerate)
        for (int i = 0; i < 3; ++i) reference[t][i] = static_cast<float>(n[i] / len);
    }
    for (int k = 0; k < 3; ++k) {
      refresh(v[k], true);
      refresh(copies[k], true);
    }
    max_cost = std::max(max_cost, f.cost);
    ++report.handles_cut;
    ++done;
  }
  return done > 0;
}

Status StreamQem::Impl::write_until(uint32_t target) {
  while (buffer.triangle_count() > target) {
    const uint32_t t = buffer.pick_output(opt.candidates, score.data());
    if (t == TriangleBuffer::kNone) break;
    uint32_t fresh[3];
    int n = 0;
    for (int k = 0; k < 3; ++k) {
      const uint32_t v = buffer.vertex_of(3 * t + k);
      if (!buffer.written(v)) {
        leave_set(v);
        fresh[n++] = v;
      }
    }
    PSQ_RETURN_IF_ERROR(buffer.write(t));
    // Those still in the buffer are locked now.
    for (int i = 0; i < n; ++i)
      if (buffer.first_corner(fresh[i]) != TriangleBuffer::kNone && buffer.written(fresh[i])) locked_now(fresh[i]);
  }
  return Status();
}

Status StreamQem::Impl::finish() {
  PSQ_RETURN_IF_ERROR(buffer.end_input());
  if (count_target) {
    final_target = static_cast<uint64_t>(std::llround(ratio * static_cast<double>(buffer.stats().triangles_read)));
    report.target_triangles = final_target;
  }
  decimate(true);
  PSQ_RETURN_IF_ERROR(buffer.finish());
  const TriangleBufferStats& st = buffer.stats();
  report.input_vertices = st.vertices_read;
  report.input_triangles = st.triangles_read;
  report.output_vertices = st.vertices_written;
  report.output_triangles = st.triangles_written;
  report.collapses = st.collapses;
  report.triangles_dropped = st.triangles_discarded;
  report.isolated_dropped = st.isolated_dropped;
  report.max_buffer_triangles = st.max_triangles;
  report.max_buffer_vertices = st.max_vertices;
  report.converter = buffer.converter_stats();
  double diag = 1;
  if (!bounds_known) {
    const double d[3] = {hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]};
    diag = std::sqrt(dot(d, d)) * scale;
  }
  report.max_error = diag > 0 ? std::sqrt(max_cost) / diag : 0;
  return Status();
}

StreamQem::StreamQem(SequenceSink* out, const QemOptions& options) : impl_(std::make_unique<Impl>(out, options)) {}
StreamQem::~StreamQem() = default;

void StreamQem::set_input_triangles(uint64_t count) { impl_->opt.input_triangles = count; }

Status StreamQem::begin(const MeshSchema& schema) {
  Impl& m = *impl_;
  Status s = m.state.begin();
  return s.ok() ? m.fail(m.begin(schema)) : s;
}

Status StreamQem::vertex(const SequenceVertex& v) {
  Impl& m = *impl_;
  Status s = m.state.event("vertex event");
  if (s.ok()) s = detail::check_finite(v);
  if (!s.ok()) return m.fail(std::move(s));
  for (int i = 0; i < 3; ++i) {
    if (!m.seen_vertex || v.position[i] < m.lo[i]) m.lo[i] = v.position[i];
    if (!m.seen_vertex || v.position[i] > m.hi[i]) m.hi[i] = v.position[i];
  }
  if (!m.seen_vertex && !m.bounds_known) std::copy(v.position, v.position + 3, m.origin);
  m.seen_vertex = true;
  return m.fail(m.buffer.vertex(v));
}
Status StreamQem::triangle(const SequenceTriangle& t) {
  Impl& m = *impl_;
  Status s = m.state.event("triangle event");
  return s.ok() ? m.fail(m.triangle(t)) : s;
}

Status StreamQem::finalize(uint32_t index) {
  Impl& m = *impl_;
  Status s = m.state.event("finalize event");
  return s.ok() ? m.fail(m.buffer.finalize(index)) : s;
}

Status StreamQem::finish() {
  Impl& m = *impl_;
  Status s = m.state.finish();
  return s.ok() ? m.fail(m.finish()) : s;
}

const QemReport& StreamQem::report() const { return impl_->report; }

Status simplify_qem(SequenceSource& in, SequenceSink& out, const QemOptions& options, QemReport* report) {
  StreamQem qem(&out, options);
  Status s = pump_sequence(in, qem);
  if (report) *report = qem.report();
  return s;
}

}  // namespace psq
