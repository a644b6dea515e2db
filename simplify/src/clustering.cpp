// SPDX-License-Identifier: Apache-2.0
// Vertex clustering on the processing boundary: Isenburg, Lindstrom,
// Gumhold and Snoeyink, "Large mesh simplification using processing
// sequences" (2003), section 5 (active cells, connected layers, border
// quadrics), over Lindstrom, "Out-of-core simplification of large polygonal
// models" (2000) (OoCS: a uniform grid, one quadric per cell, the robust
// minimizer) and Garland and Heckbert, "Surface simplification using
// quadric error metrics" (1997) (plane and border quadrics).
//
// Layout. A cluster is a node of a union-find forest (kConnected merges
// clusters; the other modes never do). Boundary vertices (by slot), waiting
// output triangles (by corner) and child nodes hold counted references to
// nodes, so that a node lives exactly as long as something can still reach
// it and memory follows the processing boundary. Output triangles wait in
// the list of one of their clusters that is still open; when that cluster
// closes they move to another open one, or, when all three are closed, go
// out (paper section 5, "waiting area"), duplicates dropped: duplicates
// have the same three final clusters, so they go out in the same batch.
#include "psq/clustering.h"

#include <algorithm>
#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "quadric.h"
#include "float_round.h"
#include "flat_map.h"

namespace psq {
namespace {

constexpr uint32_t kNone = 0xffffffffu;
// Slots beyond this are refused: BoundaryData-style arrays grow to the
// largest slot, and the .psq boundary limit (spec 4.2) stays below it.
constexpr uint32_t kMaxSlot = 1u << 28;
// Lindstrom 2000: eigenvalues below 1/1000 of the largest are noise.
constexpr double kTolerance = 1e-3;

using KeyMap = detail::IndexMap<uint64_t>;

// A boundary vertex of the input, by slot: 32 bytes, two to a cache line
// (its cell is recomputed from the position where needed: cheaper than
// the cache misses of a larger record on a long boundary).
struct SlotData {
  double pos[3];
  uint32_t node;   // its cluster's node (kNone until its first triangle)
  uint32_t dense;  // its dense index; kNone when the slot is free
};
static_assert(sizeof(SlotData) == 32, "a slot is half a cache line");

// A cluster (a root of the forest) or a cluster merged into another (a
// child: only parent and refs matter). The fields a triangle touches
// (parent, the quadric) come first: two cache lines per cluster and
// triangle. Quadric and sum are in the grid's frame (positions less the
// grid's origin), so that a triangle's plane is computed once for all its
// clusters; the minimizer then loses to cancellation about as many digits
// as the number of cells across has (at most 7 of double's 16), far less
// than a cell.
struct alignas(64) Node {
  uint32_t parent;         // itself for a root
  uint32_t refs;           // slots, waiting triangles' corners, children, the cell map
  uint32_t live;           // root: vertices not finalized
  uint32_t pending;        // root: output triangles not yet given that use it
  uint32_t head, tail;     // root: the waiting triangles in its list
  uint32_t out_id;         // its output vertex, once output
  uint8_t closed;
  uint8_t finalized;
  detail::Quadric q;
  double sum[3];           // vertex positions
  uint64_t count;          // vertices added
  uint64_t cell;
  double first_pos[3];     // the position of its first vertex (absolute: a point of the cell)
  uint64_t first_order;    // that vertex's dense index
};
static_assert(sizeof(Node) == 192, "a cluster takes three cache lines");

// The clusters, in pages of 4096 (768 KiB): the array never moves, so it
// never holds an old copy beside the new one while it grows (the clusters
// are the filter's largest structure on a long boundary), and holds no
// room beyond a page. new_node() sets every field of a node it hands out.
class NodePool {
 public:
  Node& operator[](uint32_t n) { return pages_[n >> kPageBits][n & kPageMask]; }
  const Node& operator[](uint32_t n) const { return pages_[n >> kPageBits][n & kPageMask]; }
  size_t size() const { return size_; }
  size_t capacity() const { return pages_.size() << kPageBits; }
  void emplace_back() {
    if (size_ == capacity()) pages_.emplace_back(new Node[size_t{1} << kPageBits]);
    ++size_;
  }

 private:
  static constexpr uint32_t kPageBits = 12;
  static constexpr uint32_t kPageMask = (1u << kPageBits) - 1;
  std::vector<std::unique_ptr<Node[]>> pages_;
  size_t size_ = 0;
};

// An output triangle waiting for its clusters.
struct Waiting {
  uint32_t node[3];  // nodes of its corners' clusters (roots when it was made)
  uint32_t next;     // in its list
  uint64_t seq;      // creation order: ties and output order
};

}  // namespace

const char* cell_mode_name(CellMode mode) {
  switch (mode) {
    case CellMode::kGlobal: return "global";
    case CellMode::kActive: return "active";
    case CellMode::kConnected: return "connected";
  }
  return "?";
}

bool parse_cell_mode(const std::string& name, CellMode* mode) {
  for (CellMode m : {CellMode::kGlobal, CellMode::kActive, CellMode::kConnected}) {
    if (name == cell_mode_name(m)) {
      *mode = m;
      return true;
    }
  }
  return false;
}

void ClusterGrid::cell_of(const double p[3], uint32_t ijk[3]) const {
  const double inv = 1.0 / cell;
  for (int a = 0; a < 3; ++a) {
    const double f = (p[a] - origin[a]) * inv;
    // NaN and negative go to 0, beyond the grid to the last cell.
    ijk[a] = f >= 1 ? (f < dims[a] ? static_cast<uint32_t>(f) : dims[a] - 1) : 0;
  }
}

uint64_t ClusterGrid::key_of(const double p[3]) const {
  uint32_t c[3];
  cell_of(p, c);
  return uint64_t{c[0]} | uint64_t{c[1]} << 21 | uint64_t{c[2]} << 42;
}

namespace {

Status check_box(const double lo[3], const double hi[3]) {
  for (int a = 0; a < 3; ++a) {
    if (!std::isfinite(lo[a]) || !std::isfinite(hi[a]) || !(hi[a] - lo[a] >= 0) || !std::isfinite(hi[a] - lo[a]))
      return Status(ErrorCode::kUsage, "the bounding box is not finite or is inverted");
  }
  return Status();
}

Status grid_on(const double lo[3], const double hi[3], double size, ClusterGrid* grid) {
  for (int a = 0; a < 3; ++a) {
    grid->origin[a] = lo[a];
    const double n = std::ceil((hi[a] - lo[a]) / size);
    if (!(n <= ClusterGrid::kMaxDim))
      return Status(ErrorCode::kLimit, "the grid would have more than " + std::to_string(ClusterGrid::kMaxDim) +
                                           " cells along an axis");
    grid->dims[a] = std::max<uint32_t>(1, static_cast<uint32_t>(n));
  }
  grid->cell = size;
  return Status();
}

}  // namespace

Status grid_with_cells(const double lo[3], const double hi[3], double n, ClusterGrid* grid) {
  PSQ_RETURN_IF_ERROR(check_box(lo, hi));
  if (!(n >= 1) || !std::isfinite(n))
    return Status(ErrorCode::kUsage, "the grid needs at least one cell along the longest side");
  if (!(n < ClusterGrid::kMaxDim))
    return Status(ErrorCode::kLimit, "more than " + std::to_string(ClusterGrid::kMaxDim - 1) + " cells along an axis");
  const double longest = std::max({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]});
  if (!(longest > 0)) return grid_on(lo, hi, 1.0, grid);
  // A cell a hair larger than longest / n keeps the far side of the box in
  // cell n - 1 despite rounding.
  double size = longest / n;
  size = std::nextafter(size, HUGE_VAL);
  return grid_on(lo, hi, size, grid);
}

Status grid_with_size(const double lo[3], const double hi[3], double size, ClusterGrid* grid) {
  PSQ_RETURN_IF_ERROR(check_box(lo, hi));
  if (!(size > 0) || !std::isfinite(size)) return Status(ErrorCode::kUsage, "the cell size must be a positive number");
  return grid_on(lo, hi, size, grid);
}

double first_grid_for_triangles(uint64_t target) {
  // About 8 n^2 triangles: a sphere inscribed in the box gives about 9.4
  // (twice its cells, 1.5 pi n^2), rougher surfaces more.
  const double n = std::sqrt(static_cast<double>(target) / 8);
  return std::min<double>(ClusterGrid::kMaxDim - 1, std::max(1.0, n));
}

double corrected_grid_for_triangles(uint64_t target, double trial_grid, uint64_t trial_triangles) {
  // No triangle at all: the grid was far too coarse; try 4 times finer.
  const double factor =
      trial_triangles == 0 ? 4.0 : std::sqrt(static_cast<double>(target) / static_cast<double>(trial_triangles));
  const double n = trial_grid * std::min(64.0, std::max(1.0 / 64, factor));
  return std::min<double>(ClusterGrid::kMaxDim - 1, std::max(1.0, n));
}

struct ClusteringFilter::Impl {
  StreamingMeshSink* out = nullptr;
  ClusteringOptions options;
  ClusteringStats stats;
  Status error;
  bool begun = false;
  bool finished = false;

  ClusterGrid grid;
  double inv_cell = 1;  // 1 / grid.cell, as ClusterGrid::cell_of() computes it
  double last_cell[3] = {0, 0, 0};  // dims - 1
  double box_lo[3] = {0, 0, 0}, box_hi[3] = {0, 0, 0};
  bool float_positions = false;
  PropertyMerger vmerge, fmerge;
  bool vertex_values = false;  // the input has vertex properties to keep
  size_t values_per_vertex = 0, values_per_face = 0;  // the input's, lists empty

  NodePool nodes;
  std::vector<double> acc;  // vmerge.width() per node
  std::vector<uint32_t> free_nodes;
  uint64_t alive_nodes = 0;

  std::vector<SlotData> slots;
  std::vector<PropertyValues> slot_values;  // when vertex_values
  int slot_mode = -1;                       // -1 not known, 0 the producer's slots, 1 our own
  KeyMap own_slot;                          // slot_mode 1: dense index -> slot
  std::vector<uint32_t> free_own_slots;
  uint32_t last_slot = kNone;               // the last vertex introduced
  bool triangle_since_vertex = false;
  bool reappear_map = false;                // kConnected after a re-appearance: dense_slot kept
  KeyMap dense_slot;                        // dense index -> slot of active vertices

  KeyMap cell_map;                          // kGlobal, kActive: open cell -> its node
  std::vector<uint32_t> global_order;       // kGlobal: nodes in order of creation

  std::vector<Waiting> waiting;
  std::vector<PropertyValues> waiting_values;  // when fmerge keeps something
  std::vector<uint32_t> free_waiting;
  uint64_t waiting_count = 0;
  uint64_t seq = 0;
  uint32_t next_out_id = 0;

  // Scratch.
  std::vector<uint32_t> batch;
  struct Key {
    uint32_t id[3];
    uint64_t seq;
    uint32_t w;
  };
  std::vector<Key> keys;
  std::vector<uint32_t> kept;
  std::vector<double> face_acc;
  PropertyValues values;

  bool fail(Status s) {
    error = std::move(s);
    return false;
  }
  bool bad(const std::string& what) { return fail(Status(ErrorCode::kBadSequence, what)); }

  uint64_t bytes() const;
  bool check_memory();

  // ClusterGrid::key_of() for a finite position (vertex() checks),
  // without its division and branches: clamping the scaled coordinate to
  // [0, dims - 1] before truncation gives the same cell.
  uint64_t key(const double p[3]) const {
    uint64_t k = 0;
    for (int a = 0; a < 3; ++a) {
      const double f = std::min(last_cell[a], std::max(0.0, (p[a] - grid.origin[a]) * inv_cell));
      k |= uint64_t{static_cast<uint32_t>(f)} << (21 * a);
    }
    return k;
  }
  double* acc_of(uint32_t n) { return acc.data() + size_t{n} * vmerge.width(); }
  uint32_t new_node(uint64_t cell);
  void release(uint32_t n);
  uint32_t find(uint32_t n) const {
    while (nodes[n].parent != n) n = nodes[n].parent;
    return n;
  }
  uint32_t cell_root(uint64_t cell);
  void adopt(uint32_t slot, uint32_t root);
  void unite(uint32_t a, uint32_t b);
  uint32_t refresh(uint32_t slot);
  void add_waiting(const uint32_t root[3], const PropertyValues& values);
  void append(uint32_t root, uint32_t w);
  bool release_vertex(uint32_t slot);
  bool close(uint32_t x);
  bool emit_vertex(uint32_t x);
  bool emit_batch();

  bool vertex(const SequenceVertex& v);
  bool triangle(const SequenceTriangle& t);
  bool finalize(uint32_t index);
  bool finish();
};

uint64_t ClusteringFilter::Impl::bytes() const {
  uint64_t b = nodes.capacity() * sizeof(Node) + acc.capacity() * sizeof(double) +
               free_nodes.capacity() * sizeof(uint32_t) + slots.capacity() * sizeof(SlotData) +
               slot_values.capacity() * sizeof(PropertyValues) + own_slot.bytes() +
               free_own_slots.capacity() * sizeof(uint32_t) + dense_slot.bytes() + cell_map.bytes() +
               global_order.capacity() * sizeof(uint32_t) + waiting.capacity() * sizeof(Waiting) +
               waiting_values.capacity() * sizeof(PropertyValues) + free_waiting.capacity() * sizeof(uint32_t) +
               batch.capacity() * sizeof(uint32_t) + keys.capacity() * sizeof(Key) +
               kept.capacity() * sizeof(uint32_t);
  // Property values kept per slot and per waiting triangle (their vectors'
  // contents): at about the schema's width each.
  b += slot_values.size() * values_per_vertex * sizeof(double);
  b += waiting_values.size() * values_per_face * sizeof(double);
  return b;
}

bool ClusteringFilter::Impl::check_memory() {
  const uint64_t b = bytes();
  stats.peak_bytes = std::max(stats.peak_bytes, b);
  if (b > options.memory_budget)
    return fail(Status(ErrorCode::kLimit, std::string("the clustering's structures (") + std::to_string(b >> 20) +
                                              " MiB) exceed its share of --memory" +
                                              (options.cells == CellMode::kGlobal
                                                   ? " (--cells global keeps every occupied cell)"
                                                   : "")));
  return true;
}

uint32_t ClusteringFilter::Impl::new_node(uint64_t cell) {
  uint32_t n;
  if (!free_nodes.empty()) {
    n = free_nodes.back();
    free_nodes.pop_back();
  } else {
    n = static_cast<uint32_t>(nodes.size());
    nodes.emplace_back();
    acc.resize(acc.size() + vmerge.width());
  }
  Node& x = nodes[n];
  x.q = detail::Quadric();
  for (int a = 0; a < 3; ++a) {
    x.sum[a] = 0;
    x.first_pos[a] = 0;
  }
  x.first_order = 0;
  x.count = 0;
  x.cell = cell;
  x.parent = n;
  x.refs = 0;
  x.live = 0;
  x.pending = 0;
  x.head = x.tail = kNone;
  x.out_id = kNone;
  x.closed = 0;
  x.finalized = 0;
  vmerge.reset(acc_of(n));
  ++alive_nodes;
  stats.max_clusters = std::max(stats.max_clusters, alive_nodes);
  return n;
}

// Drops one reference to node `n`; a node nothing refers to any more is
// freed (a root only once closed), and with it its reference to its parent.
void ClusteringFilter::Impl::release(uint32_t n) {
  for (;;) {
    Node& x = nodes[n];
    if (--x.refs > 0) return;
    const uint32_t parent = x.parent;
    if (parent == n && !x.closed) return;
    free_nodes.push_back(n);
    --alive_nodes;
    if (parent == n) return;
    n = parent;
  }
}

uint32_t ClusteringFilter::Impl::cell_root(uint64_t cell) {
  uint32_t n = cell_map.find(cell);
  if (n != kNone) return n;
  n = new_node(cell);
  cell_map.insert(cell, n);
  ++nodes[n].refs;  // the map's
  if (options.cells == CellMode::kGlobal) global_order.push_back(n);
  return n;
}

void ClusteringFilter::Impl::adopt(uint32_t slot, uint32_t root) {
  SlotData& sd = slots[slot];
  Node& r = nodes[root];
  sd.node = root;
  ++r.refs;
  ++r.live;
  for (int a = 0; a < 3; ++a) r.sum[a] += sd.pos[a] - grid.origin[a];
  if (r.count == 0 || sd.dense < r.first_order) {
    for (int a = 0; a < 3; ++a) r.first_pos[a] = sd.pos[a];
    r.first_order = sd.dense;
  }
  ++r.count;
  if (vertex_values) vmerge.add(acc_of(root), slot_values[slot], sd.dense);
}

// Merges root b into root a or a into b (kConnected: the two clusters of
// one cell that an edge joins; paper section 5, counters add).
void ClusteringFilter::Impl::unite(uint32_t a, uint32_t b) {
  if (nodes[a].count < nodes[b].count || (nodes[a].count == nodes[b].count && a > b)) std::swap(a, b);
  Node& r = nodes[a];
  Node& c = nodes[b];
  c.parent = a;
  ++r.refs;
  r.q.add(c.q);
  for (int k = 0; k < 3; ++k) r.sum[k] += c.sum[k];
  if (c.first_order < r.first_order) {
    for (int k = 0; k < 3; ++k) r.first_pos[k] = c.first_pos[k];
    r.first_order = c.first_order;
  }
  r.count += c.count;
  r.live += c.live;
  r.pending += c.pending;
  if (c.head != kNone) {
    if (r.head == kNone) {
      r.head = c.head;
    } else {
      waiting[r.tail].next = c.head;
    }
    r.tail = c.tail;
  }
  c.head = c.tail = kNone;
  c.live = c.pending = 0;
  if (vmerge.width()) vmerge.merge(acc_of(a), acc_of(b));
}

// The root of the slot's cluster; the slot then refers to the root
// directly, so that later finds take one step.
uint32_t ClusteringFilter::Impl::refresh(uint32_t slot) {
  const uint32_t n = slots[slot].node;
  const uint32_t r = find(n);
  if (r != n) {
    ++nodes[r].refs;
    slots[slot].node = r;
    release(n);
  }
  return r;
}

void ClusteringFilter::Impl::append(uint32_t root, uint32_t w) {
  Node& r = nodes[root];
  waiting[w].next = kNone;
  if (r.head == kNone) {
    r.head = w;
  } else {
    waiting[r.tail].next = w;
  }
  r.tail = w;
}

void ClusteringFilter::Impl::add_waiting(const uint32_t root[3], const PropertyValues& face_values) {
  uint32_t w;
  if (!free_waiting.empty()) {
    w = free_waiting.back();
    free_waiting.pop_back();
  } else {
    w = static_cast<uint32_t>(waiting.size());
    waiting.emplace_back();
    if (fmerge.width()) waiting_values.emplace_back();
  }
  Waiting& x = waiting[w];
  for (int k = 0; k < 3; ++k) {
    x.node[k] = root[k];
    ++nodes[root[k]].refs;
    ++nodes[root[k]].pending;
  }
  x.seq = seq++;
  if (fmerge.width()) waiting_values[w] = face_values;
  append(root[0], w);
  ++waiting_count;
  stats.max_waiting = std::max(stats.max_waiting, waiting_count);
}

// Vertex `slot` is finalized: its cluster counts one live vertex less and
// closes at zero (kGlobal closes everything at the end instead).
bool ClusteringFilter::Impl::release_vertex(uint32_t slot) {
  SlotData& sd = slots[slot];
  const uint32_t n = sd.node;
  if (n != kNone) {
    const uint32_t r = find(n);
    if (--nodes[r].live == 0 && options.cells != CellMode::kGlobal) {
      if (!close(r)) return false;
    }
    release(n);
  }
  if (reappear_map) dense_slot.erase(sd.dense);
  if (slot_mode == 1) {
    own_slot.erase(sd.dense);
    free_own_slots.push_back(slot);
  }
  sd.node = kNone;
  sd.dense = kNone;
  return true;
}

// The cluster's vertex (Lindstrom 2000): the quadric's minimizer near the
// mean, clamped to the cell and the input's bounds. With float positions
// the float nearest to it; should rounding leave the cell (cells smaller
// than a float's spacing), the mean, else the cluster's first vertex,
// which lies in the cell.
bool ClusteringFilter::Impl::emit_vertex(uint32_t x) {
  Node& c = nodes[x];
  const double n = static_cast<double>(c.count);
  const double mean[3] = {c.sum[0] / n, c.sum[1] / n, c.sum[2] / n};
  double rel[3];
  detail::minimize_quadric(c.q, mean, kTolerance, rel);
  const uint32_t want[3] = {static_cast<uint32_t>(c.cell & 0x1fffff), static_cast<uint32_t>((c.cell >> 21) & 0x1fffff),
                            static_cast<uint32_t>(c.cell >> 42)};
  double lo[3], hi[3];
  for (int a = 0; a < 3; ++a) {
    lo[a] = grid.origin[a] + want[a] * grid.cell;
    hi[a] = lo[a] + grid.cell;
    if (std::max(lo[a], box_lo[a]) <= std::min(hi[a], box_hi[a])) {
      lo[a] = std::max(lo[a], box_lo[a]);
      hi[a] = std::min(hi[a], box_hi[a]);
    }
  }
  auto place = [&](const double r[3], double p[3]) {
    for (int a = 0; a < 3; ++a) {
      double v = grid.origin[a] + r[a];
      v = std::min(hi[a], std::max(lo[a], v));  // also turns NaN into lo
      p[a] = float_positions ? detail::round_to_float(v) : v;
    }
    // On a cell's far face (or rounded across it) a point belongs to the
    // next cell: step it back by the smallest amounts the type has.
    for (int step = 0; step < 4; ++step) {
      uint32_t ijk[3];
      grid.cell_of(p, ijk);
      bool inside = true;
      for (int a = 0; a < 3; ++a) {
        if (ijk[a] == want[a]) continue;
        inside = false;
        const double toward = ijk[a] > want[a] ? -HUGE_VAL : HUGE_VAL;
        p[a] = float_positions ? static_cast<double>(std::nextafter(static_cast<float>(p[a]), static_cast<float>(toward)))
                               : std::nextafter(p[a], toward);
      }
      if (inside) return true;
    }
    return false;
  };
  double p[3];
  // A cluster of one vertex is that vertex (its planes all pass through
  // it), exactly: a grid that keeps everything gives the input back.
  if (c.count == 1 || (!place(rel, p) && !place(mean, p))) {
    for (int a = 0; a < 3; ++a) p[a] = c.first_pos[a];
  }
  c.out_id = next_out_id++;
  ++stats.vertices_out;
  values.clear();
  if (vmerge.width()) vmerge.result(acc_of(x), &values);
  Status s = out->vertex(c.out_id, p, values);
  return s.ok() || fail(std::move(s));
}

// Cluster x has no live vertex left: no later triangle can reach it. Its
// vertex goes out if an output triangle uses it; its waiting triangles move
// to a cluster of theirs that is still open, or go out.
bool ClusteringFilter::Impl::close(uint32_t x) {
  nodes[x].closed = 1;
  ++stats.clusters;
  const bool mapped = options.cells != CellMode::kConnected;
  if (mapped) cell_map.erase(nodes[x].cell);
  if (nodes[x].pending > 0) {
    if (!emit_vertex(x)) return false;
  } else {
    ++stats.clusters_unused;
  }
  uint32_t w = nodes[x].head;
  nodes[x].head = nodes[x].tail = kNone;
  batch.clear();
  while (w != kNone) {
    const uint32_t next = waiting[w].next;
    uint32_t open = kNone;
    for (int k = 0; k < 3 && open == kNone; ++k) {
      const uint32_t r = find(waiting[w].node[k]);
      if (!nodes[r].closed) open = r;
    }
    if (open != kNone) {
      append(open, w);
    } else {
      batch.push_back(w);
    }
    w = next;
  }
  if (!batch.empty() && !emit_batch()) return false;
  if (mapped) release(x);
  return true;
}

// Gives the batch's triangles (all three clusters closed and output) to the
// sink, one per distinct oriented triple of clusters, in creation order;
// then finalizes the clusters that no waiting triangle uses any more.
bool ClusteringFilter::Impl::emit_batch() {
  keys.clear();
  for (uint32_t w : batch) {
    Key k;
    for (int c = 0; c < 3; ++c) k.id[c] = nodes[find(waiting[w].node[c])].out_id;
    // The rotation that starts at the smallest id: one key per oriented triangle.
    const int m = k.id[0] < k.id[1] ? (k.id[0] < k.id[2] ? 0 : 2) : (k.id[1] < k.id[2] ? 1 : 2);
    const uint32_t r[3] = {k.id[m], k.id[(m + 1) % 3], k.id[(m + 2) % 3]};
    std::copy(r, r + 3, k.id);
    k.seq = waiting[w].seq;
    k.w = w;
    keys.push_back(k);
  }
  auto same = [](const Key& a, const Key& b) { return a.id[0] == b.id[0] && a.id[1] == b.id[1] && a.id[2] == b.id[2]; };
  if (keys.size() > 1) {
    std::sort(keys.begin(), keys.end(), [](const Key& a, const Key& b) {
      if (a.id[0] != b.id[0]) return a.id[0] < b.id[0];
      if (a.id[1] != b.id[1]) return a.id[1] < b.id[1];
      if (a.id[2] != b.id[2]) return a.id[2] < b.id[2];
      return a.seq < b.seq;
    });
  }
  // Keep the first of each run of equal keys; its face values merge the run's.
  kept.clear();
  for (size_t i = 0; i < keys.size();) {
    size_t j = i + 1;
    while (j < keys.size() && same(keys[i], keys[j])) ++j;
    if (fmerge.width()) {
      face_acc.resize(fmerge.width());
      fmerge.reset(face_acc.data());
      for (size_t k = i; k < j; ++k) fmerge.add(face_acc.data(), waiting_values[keys[k].w], keys[k].seq);
      fmerge.result(face_acc.data(), &waiting_values[keys[i].w]);
    }
    kept.push_back(static_cast<uint32_t>(i));
    stats.duplicates += j - i - 1;
    i = j;
  }
  if (kept.size() > 1) {
    std::sort(kept.begin(), kept.end(), [&](uint32_t a, uint32_t b) { return keys[a].seq < keys[b].seq; });
  }
  for (uint32_t i : kept) {
    const Waiting& w = waiting[keys[i].w];
    uint32_t id[3];
    for (int c = 0; c < 3; ++c) id[c] = nodes[find(w.node[c])].out_id;
    values.clear();
    Status s = out->triangle(id, fmerge.width() ? waiting_values[keys[i].w] : values);
    if (!s.ok()) return fail(std::move(s));
    ++stats.triangles_out;
  }
  for (uint32_t w : batch) {
    for (int c = 0; c < 3; ++c) {
      Node& r = nodes[find(waiting[w].node[c])];
      if (--r.pending == 0 && r.closed && !r.finalized && r.out_id != kNone) {
        r.finalized = 1;
        Status s = out->finalize(r.out_id);
        if (!s.ok()) return fail(std::move(s));
      }
    }
  }
  for (uint32_t w : batch) {
    for (int c = 0; c < 3; ++c) release(waiting[w].node[c]);
    if (fmerge.width()) waiting_values[w].clear();
    free_waiting.push_back(w);
    --waiting_count;
  }
  return true;
}

bool ClusteringFilter::Impl::vertex(const SequenceVertex& v) {
  ++stats.vertices_in;
  if (slot_mode < 0) slot_mode = v.slot == kNoSlot ? 1 : 0;
  uint32_t slot;
  if (slot_mode == 1) {
    if (v.slot != kNoSlot) return bad("vertex " + std::to_string(v.index) + " has a slot, earlier vertices had none");
    if (own_slot.find(v.index) != kNone) return bad("vertex " + std::to_string(v.index) + " introduced twice");
    if (!free_own_slots.empty()) {
      slot = free_own_slots.back();
      free_own_slots.pop_back();
    } else {
      slot = static_cast<uint32_t>(slots.size());
      if (slot >= kMaxSlot) return fail(Status(ErrorCode::kLimit, "more than 2^28 vertices active at once"));
    }
    own_slot.insert(v.index, slot);
  } else {
    slot = v.slot;
    if (slot == kNoSlot) return bad("vertex " + std::to_string(v.index) + " has no slot, earlier vertices had one");
    if (slot >= kMaxSlot) return bad("vertex slot " + std::to_string(slot) + " beyond 2^28");
  }
  if (slot >= slots.size()) {
    const size_t n = std::max<size_t>(slot + 1, 2 * slots.size());
    slots.resize(n, SlotData{{0, 0, 0}, kNone, kNone});
    if (vertex_values) slot_values.resize(n);
  }
  SlotData& sd = slots[slot];
  if (sd.dense != kNone) return bad("vertex " + std::to_string(v.index) + " takes slot " + std::to_string(slot) +
                                    ", still used by vertex " + std::to_string(sd.dense));
  if (v.index == kNone) return bad("vertex index 4294967295");
  for (int a = 0; a < 3; ++a) {
    if (!std::isfinite(v.position[a])) return fail(Status(ErrorCode::kBadValue, "vertex position is not finite"));
    sd.pos[a] = v.position[a];
  }
  sd.node = kNone;
  sd.dense = v.index;
  if (vertex_values) slot_values[slot] = v.values;
  last_slot = slot;
  triangle_since_vertex = false;
  if (options.cells == CellMode::kConnected) {
    // A re-appearing vertex (a non-manifold input vertex, cut by the
    // sequence) is the same point as its first occurrence: while that is
    // on the boundary, they are one cluster.
    if (v.reappears != kNoVertex && !reappear_map && slot_mode == 0) {
      reappear_map = true;
      for (uint32_t s = 0; s < slots.size(); ++s)
        if (slots[s].dense != kNone && s != slot) dense_slot.insert(slots[s].dense, s);
    }
    KeyMap& by_dense = slot_mode == 1 ? own_slot : dense_slot;
    if (v.reappears != kNoVertex) {
      const uint32_t first = by_dense.find(v.reappears);
      if (first != kNone && first != slot && slots[first].node != kNone &&
          key(slots[first].pos) == key(sd.pos))
        adopt(slot, find(slots[first].node));
    }
    if (reappear_map) dense_slot.insert(v.index, slot);
  }
  return true;
}

bool ClusteringFilter::Impl::triangle(const SequenceTriangle& t) {
  ++stats.triangles_in;
  triangle_since_vertex = true;
  uint32_t s[3];
  for (int k = 0; k < 3; ++k) {
    s[k] = slot_mode == 1 ? own_slot.find(t.v[k]) : t.vslot[k];
    if (slot_mode < 0 || s[k] >= slots.size() || slots[s[k]].dense != t.v[k] || t.v[k] == kNone)
      return bad("a triangle uses vertex " + std::to_string(t.v[k]) + ", which is not on the boundary");
  }
  if (s[0] == s[1] || s[1] == s[2] || s[2] == s[0]) return bad("a triangle uses one vertex twice");
  const uint64_t cell[3] = {key(slots[s[0]].pos), key(slots[s[1]].pos), key(slots[s[2]].pos)};
  // Clusters for the corners new to any triangle.
  for (int k = 0; k < 3; ++k) {
    if (slots[s[k]].node != kNone) continue;
    uint32_t r = kNone;
    if (options.cells == CellMode::kConnected) {
      // A new vertex starts a cluster; one that shares a cell with a corner
      // it is joined to by an edge of this triangle is merged with it at
      // once (every two corners of a triangle share an edge).
      for (int j = 0; j < 3 && r == kNone; ++j)
        if (j != k && cell[j] == cell[k] && slots[s[j]].node != kNone) r = find(slots[s[j]].node);
      if (r == kNone) r = new_node(cell[k]);
    } else {
      r = cell_root(cell[k]);
    }
    adopt(s[k], r);
  }
  if (options.cells == CellMode::kConnected) {
    for (int k = 0; k < 3; ++k) {
      const int j = (k + 1) % 3;
      if (cell[k] != cell[j]) continue;
      const uint32_t a = find(slots[s[k]].node), b = find(slots[s[j]].node);
      if (a != b) unite(a, b);
    }
  }
  uint32_t r[3];
  for (int k = 0; k < 3; ++k) r[k] = refresh(s[k]);

  // Quadrics: the triangle's plane, weighted by its area, once per corner.
  const double* p0 = slots[s[0]].pos;
  const double* p1 = slots[s[1]].pos;
  const double* p2 = slots[s[2]].pos;
  const double e1[3] = {p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]};
  const double e2[3] = {p2[0] - p0[0], p2[1] - p0[1], p2[2] - p0[2]};
  const double nrm[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
  const double len2 = nrm[0] * nrm[0] + nrm[1] * nrm[1] + nrm[2] * nrm[2];
  const double len = std::sqrt(len2);
  if (len > 0 && std::isfinite(len2)) {
    stats.area += 0.5 * len;
    // Area A = len / 2 and unit normal n = nrm / len: A (n.x + d)^2 is
    // (nrm.x + D)^2 / (2 len) with D = -nrm.p0.
    const double k = 0.5 / len;
    const double d = -(nrm[0] * (p0[0] - grid.origin[0]) + nrm[1] * (p0[1] - grid.origin[1]) +
                       nrm[2] * (p0[2] - grid.origin[2]));
    if (r[0] == r[1] && r[1] == r[2]) {
      nodes[r[0]].q.add_plane(nrm, d, 3 * k);
    } else {
      for (int c = 0; c < 3; ++c) {
        if ((c > 0 && r[c] == r[0]) || (c > 1 && r[c] == r[1])) continue;
        const double mult = 1 + (c < 1 && r[1] == r[c]) + (c < 2 && r[2] == r[c]);
        nodes[r[c]].q.add_plane(nrm, d, k * mult);
      }
    }
    // Border quadrics (paper section 5; Garland and Heckbert 1997): the
    // plane through a border edge perpendicular to the triangle, weighted
    // as a strip one cell wide along the edge, for both ends' clusters.
    // Edges that are borders only because the input was cut are not.
    const uint8_t border = t.border_mask & ~t.nonmanifold_mask & 7;
    if (border && options.border_weight > 0) {
      for (int e = 0; e < 3; ++e) {
        if (!(border >> e & 1)) continue;
        const int a = e, b = (e + 1) % 3;
        const double* pa = slots[s[a]].pos;
        const double* pb = slots[s[b]].pos;
        const double ed[3] = {pb[0] - pa[0], pb[1] - pa[1], pb[2] - pa[2]};
        const double elen = std::sqrt(ed[0] * ed[0] + ed[1] * ed[1] + ed[2] * ed[2]);
        if (!(elen > 0)) continue;
        const double m[3] = {ed[1] * nrm[2] - ed[2] * nrm[1], ed[2] * nrm[0] - ed[0] * nrm[2],
                             ed[0] * nrm[1] - ed[1] * nrm[0]};
        // |m| = elen * len; weight w = border_weight * elen * cell, so the
        // unnormalized plane m takes w / |m|^2.
        const double kb = options.border_weight * grid.cell / (elen * len2);
        const double db = -(m[0] * (pa[0] - grid.origin[0]) + m[1] * (pa[1] - grid.origin[1]) +
                            m[2] * (pa[2] - grid.origin[2]));
        for (int end : {a, b}) nodes[r[end]].q.add_plane(m, db, kb);
      }
    }
  }
  // An output triangle: three corners in three cells.
  if (cell[0] != cell[1] && cell[1] != cell[2] && cell[2] != cell[0]) add_waiting(r, t.values);
  if (slot_mode == 0) {
    for (int k = 0; k < 3; ++k)
      if ((t.final_mask >> k & 1) && !release_vertex(s[k])) return false;
  }
  if ((stats.triangles_in & 1023) == 0 && !check_memory()) return false;
  return true;
}

bool ClusteringFilter::Impl::finalize(uint32_t index) {
  if (slot_mode == 1) {
    const uint32_t slot = own_slot.find(index);
    if (slot == kNone) return bad("vertex " + std::to_string(index) + " finalized but not active");
    return release_vertex(slot);
  }
  // The producer's slots: finalization came with the triangle's final
  // mask, except for a vertex that no triangle uses (introduced and
  // finalized at once).
  if (last_slot != kNone && !triangle_since_vertex && slots[last_slot].dense == index) {
    const uint32_t slot = last_slot;
    last_slot = kNone;
    return release_vertex(slot);
  }
  return true;
}

bool ClusteringFilter::Impl::finish() {
  // Vertices the producer left open.
  for (uint32_t s = 0; s < slots.size(); ++s)
    if (slots[s].dense != kNone && !release_vertex(s)) return false;
  if (options.cells == CellMode::kGlobal) {
    for (uint32_t n : global_order)
      if (!close(n)) return false;
    std::vector<uint32_t>().swap(global_order);
  }
  if (waiting_count != 0)
    return fail(Status(ErrorCode::kInternal, std::to_string(waiting_count) + " output triangles left waiting"));
  if (!check_memory()) return false;
  Status s = out->finish();
  return s.ok() || fail(std::move(s));
}

ClusteringFilter::ClusteringFilter(StreamingMeshSink* out, const ClusteringOptions& options)
    : impl_(std::make_unique<Impl>()) {
  impl_->out = out;
  impl_->options = options;
}

ClusteringFilter::~ClusteringFilter() = default;

const ClusteringStats& ClusteringFilter::stats() const { return impl_->stats; }

Status ClusteringFilter::begin(const MeshSchema& schema) {
  Impl& m = *impl_;
  if (!m.error.ok()) return m.error;
  if (m.begun) return m.error = Status(ErrorCode::kUsage, "begin() called twice");
  m.begun = true;
  const ClusteringOptions& o = m.options;
  MeshSchema in = schema;
  if (o.has_bounds) {
    in.has_bounds = true;
    std::copy(o.bounds_min, o.bounds_min + 3, in.bounds_min);
    std::copy(o.bounds_max, o.bounds_max + 3, in.bounds_max);
  }
  if (!in.has_bounds)
    return m.error = Status(ErrorCode::kUsage,
                            "clustering needs the bounding box before the first vertex (a quantized .psq, or the "
                            "sequence builder)");
  if (!(o.border_weight >= 0) || !std::isfinite(o.border_weight))
    return m.error = Status(ErrorCode::kUsage, "the border weight must be a finite number >= 0");
  Status s = o.grid > 0 ? grid_with_cells(in.bounds_min, in.bounds_max, o.grid, &m.grid)
                        : grid_with_size(in.bounds_min, in.bounds_max, o.cell_size, &m.grid);
  if (!s.ok()) return m.error = s;
  m.stats.grid = m.grid;
  m.inv_cell = 1.0 / m.grid.cell;
  for (int a = 0; a < 3; ++a) m.last_cell[a] = m.grid.dims[a] - 1.0;
  std::copy(in.bounds_min, in.bounds_min + 3, m.box_lo);
  std::copy(in.bounds_max, in.bounds_max + 3, m.box_hi);
  m.float_positions = schema.position_type == ScalarType::kFloat32;
  MergePolicy policy = o.merge;
  if (policy.vertex.empty() && policy.face.empty()) policy = default_merge_policy(schema);
  if (policy.vertex.size() != schema.vertex_properties.size() || policy.face.size() != schema.face_properties.size())
    return m.error = Status(ErrorCode::kUsage, "the merge rules do not match the schema's properties");
  m.vmerge = PropertyMerger(schema.vertex_properties, policy.vertex);
  m.fmerge = PropertyMerger(schema.face_properties, policy.face);
  m.vertex_values = m.vmerge.width() > 0;
  m.values_per_vertex = min_value_count(schema.vertex_properties);
  m.values_per_face = min_value_count(schema.face_properties);
  MeshSchema out_schema = merged_schema(in, policy);
  s = m.out->begin(out_schema);
  if (!s.ok()) return m.error = s;
  return Status();
}

Status ClusteringFilter::vertex(const SequenceVertex& v) {
  Impl& m = *impl_;
  if (m.error.ok() && (!m.begun || m.finished)) m.error = Status(ErrorCode::kUsage, "vertex() outside begin() and finish()");
  if (m.error.ok() && m.vertex(v)) return Status();
  return m.error;
}

Status ClusteringFilter::triangle(const SequenceTriangle& t) {
  Impl& m = *impl_;
  if (m.error.ok() && (!m.begun || m.finished)) m.error = Status(ErrorCode::kUsage, "triangle() outside begin() and finish()");
  if (m.error.ok() && m.triangle(t)) return Status();
  return m.error;
}

Status ClusteringFilter::finalize(uint32_t index) {
  Impl& m = *impl_;
  if (m.error.ok() && (!m.begun || m.finished)) m.error = Status(ErrorCode::kUsage, "finalize() outside begin() and finish()");
  if (m.error.ok() && m.finalize(index)) return Status();
  return m.error;
}

Status ClusteringFilter::finish() {
  Impl& m = *impl_;
  if (m.error.ok() && (!m.begun || m.finished)) m.error = Status(ErrorCode::kUsage, "finish() without begin(), or twice");
  if (m.error.ok()) {
    m.finished = true;
    if (m.finish()) return Status();
  }
  return m.error;
}

}  // namespace psq
