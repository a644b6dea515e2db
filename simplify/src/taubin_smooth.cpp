// SPDX-License-Identifier: Apache-2.0
// Streaming lambda|mu smoothing (Taubin, "A Signal Processing Approach to
// Fair Surface Design", SIGGRAPH 1995) as buffer-based processing of a
// processing sequence (Isenburg, Lindstrom, Gumhold and Snoeyink, "Large
// Mesh Simplification using Processing Sequences", 2003, section 3).
#include "psq/taubin_smooth.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "psq/triangle_buffer.h"
#include "sink_state.h"

namespace psq {
namespace {

// The converter behind the buffer keeps at least 65536 triangles waiting
// (about 200 bytes each; no lookahead beyond), and some more while they
// settle.
constexpr uint64_t kConverterBytes = uint64_t{90000} * 200;
// Vertices per triangle in the buffer, for its room: about one half on
// closed meshes, but more in the band along the input boundary, which is a
// strip; room beyond this grows by doubling.
constexpr double kVerticesPerTriangle = 0.85;
// Bytes per buffer triangle: the buffer's own, a flag per triangle, and per
// vertex its steps, its stop and its previous position.
constexpr double kBytesPerTriangle =
    TriangleBuffer::kTriangleBytes + 1 + kVerticesPerTriangle * (TriangleBuffer::kVertexBytes + 26);

struct Position {
  double p[3];
};

}  // namespace

uint32_t smooth_buffer_triangles(uint64_t memory_budget) {
  const double spare = static_cast<double>(memory_budget) - static_cast<double>(kConverterBytes) - (2 << 20);
  return static_cast<uint32_t>(std::clamp(spare / kBytesPerTriangle, 1024.0, static_cast<double>(uint64_t{1} << 28)));
}

struct TaubinSmoother::Impl {
  Impl(SequenceSink* out, const SmoothOptions& o) : buffer(out), opt(o) {}

  TriangleBuffer buffer;
  SmoothOptions opt;
  SmoothReport report;
  detail::SinkState state;
  // The input's declared bounding box: the output's quantization grid
  // (psq/sequence.h), which a vertex must not leave.
  bool bounded = false;
  double box_lo[3] = {0, 0, 0}, box_hi[3] = {0, 0, 0};
  uint32_t capacity = 0, low = 0;

  // Per vertex: the steps taken, whether it stopped for good, and its
  // position before the last step.
  std::vector<uint8_t> level, stopped;
  std::vector<Position> before;
  // Per triangle: queued for writing.
  std::vector<uint8_t> queued;
  std::vector<uint32_t> work, ready;

  Status fail(Status s) { return state.fail(std::move(s)); }

  bool fixed(uint32_t v) const { return stopped[v] || buffer.border(v) || buffer.cut(v); }
  bool done(uint32_t v) const { return fixed(v) || level[v] >= opt.iterations; }
  // v's position after step s (v has taken s or s + 1 steps, or is fixed).
  const double* position_after(uint32_t v, int s) const {
    return s < level[v] ? before[v].p : buffer.position(v);
  }

  void grow() {
    const size_t nv = buffer.vertex_capacity();
    if (level.size() < nv) {
      level.resize(nv);
      stopped.resize(nv);
      before.resize(nv);
    }
    const size_t nt = buffer.triangle_capacity();
    if (queued.size() < nt) queued.resize(nt);
  }

  void advance(uint32_t v);
  void queue_ready(uint32_t v);
  void run();
  Status write_ready();
  Status begin(const MeshSchema& schema);
  Status triangle(const SequenceTriangle& t);
  Status finish();
};

Status TaubinSmoother::Impl::begin(const MeshSchema& schema) {
  if (opt.iterations < 0 || opt.iterations > 255) return Status(ErrorCode::kUsage, "iterations must be 0..255");
  if (!std::isfinite(opt.lambda) || !std::isfinite(opt.mu))
    return Status(ErrorCode::kUsage, "lambda and mu must be finite numbers");
  capacity = opt.buffer_triangles ? opt.buffer_triangles : smooth_buffer_triangles(opt.memory_budget);
  capacity = std::max<uint32_t>(capacity, 16);
  low = capacity - capacity / 8;
  report.buffer_triangles = capacity;
  buffer.set_lookahead_budget(0);
  // All the room at once (growth by doubling copies).
  const uint32_t room = std::min(capacity, smooth_buffer_triangles(opt.memory_budget)) + 64;
  const uint32_t vertices = static_cast<uint32_t>(kVerticesPerTriangle * room);
  buffer.reserve(room, vertices);
  level.reserve(vertices);
  stopped.reserve(vertices);
  before.reserve(vertices);
  queued.reserve(room);
  bounded = schema.has_bounds;
  std::copy(schema.bounds_min, schema.bounds_min + 3, box_lo);
  std::copy(schema.bounds_max, schema.bounds_max + 3, box_hi);
  return buffer.begin(schema);
}

// Takes as many steps at v as its neighbours allow.
void TaubinSmoother::Impl::advance(uint32_t v) {
  bool moved = false;
  while (!done(v) && !buffer.input_open(v) && !buffer.written(v)) {
    const int s = level[v];
    // An unlocked vertex off the border has its whole fan in the buffer, a
    // closed one: each neighbour follows one corner of v.
    double sum[3] = {0, 0, 0};
    int n = 0;
    bool blocked = false;
    for (uint32_t c = buffer.first_corner(v); c != TriangleBuffer::kNone && !blocked; c = buffer.next_corner(c)) {
      const uint32_t u = buffer.vertex_of(TriangleBuffer::next(c));
      if (!fixed(u) && level[u] < s) {
        blocked = true;
        break;
      }
      const double* p = position_after(u, s);
      sum[0] += p[0];
      sum[1] += p[1];
      sum[2] += p[2];
      ++n;
    }
    if (blocked || n == 0) break;
    const double f = s % 2 == 0 ? opt.lambda : opt.mu;
    const double* p = buffer.position(v);
    double q[3];
    for (int i = 0; i < 3; ++i) q[i] = p[i] + f * (sum[i] / n - p[i]);
    // Taubin's mu step moves a vertex outward: one on the box's face may
    // step past it, where the output's grid (the input's box) cannot hold
    // it. It stays on the face.
    if (bounded)
      for (int i = 0; i < 3; ++i) q[i] = std::min(box_hi[i], std::max(box_lo[i], q[i]));
    if (!(std::isfinite(q[0]) && std::isfinite(q[1]) && std::isfinite(q[2]))) {
      stopped[v] = 1;
      break;
    }
    std::copy(p, p + 3, before[v].p);
    buffer.set_position(v, q);
    ++level[v];
    moved = true;
    if (level[v] >= opt.iterations) ++report.smoothed_vertices;
  }
  if (moved) {
    for (uint32_t c = buffer.first_corner(v); c != TriangleBuffer::kNone; c = buffer.next_corner(c)) {
      const uint32_t u = buffer.vertex_of(TriangleBuffer::next(c));
      if (!done(u)) work.push_back(u);
    }
  }
  if (done(v)) queue_ready(v);
}

// Queues v's triangles whose three vertices are done.
void TaubinSmoother::Impl::queue_ready(uint32_t v) {
  for (uint32_t c = buffer.first_corner(v); c != TriangleBuffer::kNone; c = buffer.next_corner(c)) {
    const uint32_t t = c / 3;
    if (queued[t]) continue;
    if (done(buffer.vertex_of(3 * t)) && done(buffer.vertex_of(3 * t + 1)) && done(buffer.vertex_of(3 * t + 2))) {
      queued[t] = 1;
      ready.push_back(t);
    }
  }
}

void TaubinSmoother::Impl::run() {
  while (!work.empty()) {
    const uint32_t v = work.back();
    work.pop_back();
    advance(v);
  }
}

Status TaubinSmoother::Impl::write_ready() {
  while (!ready.empty()) {
    const uint32_t t = ready.back();
    ready.pop_back();
    if (buffer.alive(t) && queued[t]) PSQ_RETURN_IF_ERROR(buffer.write(t));
  }
  return Status();
}

Status TaubinSmoother::Impl::triangle(const SequenceTriangle& t) {
  uint32_t tri;
  PSQ_RETURN_IF_ERROR(buffer.triangle(t, &tri));
  grow();
  queued[tri] = 0;
  for (int k = 0; k < 3; ++k) {
    const uint32_t v = buffer.vertex_of(3 * tri + k);
    if (t.new_mask & (1u << k)) {
      level[v] = 0;
      stopped[v] = 0;
    }
  }
  for (int k = 0; k < 3; ++k) {
    const uint32_t v = buffer.vertex_of(3 * tri + k);
    if (done(v))
      queue_ready(v);
    else if (t.final_mask & (1u << k))
      work.push_back(v);
  }
  run();
  PSQ_RETURN_IF_ERROR(write_ready());
  if (buffer.triangle_count() < capacity) return Status();
  // Full: the triangles at the output boundary leave now, and their
  // vertices stop where they are; their neighbours may go on.
  while (buffer.triangle_count() > low) {
    const uint32_t w = buffer.pick_output(1, nullptr);
    if (w == TriangleBuffer::kNone) break;
    for (int k = 0; k < 3; ++k) {
      const uint32_t v = buffer.vertex_of(3 * w + k);
      if (done(v)) continue;
      stopped[v] = 1;
      ++report.stopped_vertices;
      for (uint32_t c = buffer.first_corner(v); c != TriangleBuffer::kNone; c = buffer.next_corner(c)) {
        const uint32_t u = buffer.vertex_of(TriangleBuffer::next(c));
        if (!done(u)) work.push_back(u);
      }
      queue_ready(v);
    }
    queued[w] = 1;
    PSQ_RETURN_IF_ERROR(buffer.write(w));
    run();
    PSQ_RETURN_IF_ERROR(write_ready());
  }
  return Status();
}

Status TaubinSmoother::Impl::finish() {
  PSQ_RETURN_IF_ERROR(buffer.end_input());
  run();
  PSQ_RETURN_IF_ERROR(write_ready());
  PSQ_RETURN_IF_ERROR(buffer.finish());
  const TriangleBufferStats& st = buffer.stats();
  report.input_vertices = st.vertices_read;
  report.input_triangles = st.triangles_read;
  report.output_vertices = st.vertices_written;
  report.output_triangles = st.triangles_written;
  report.isolated_dropped = st.isolated_dropped;
  report.max_buffer_triangles = st.max_triangles;
  report.converter = buffer.converter_stats();
  return Status();
}

TaubinSmoother::TaubinSmoother(SequenceSink* out, const SmoothOptions& options)
    : impl_(std::make_unique<Impl>(out, options)) {}
TaubinSmoother::~TaubinSmoother() = default;

Status TaubinSmoother::begin(const MeshSchema& schema) {
  Impl& m = *impl_;
  Status s = m.state.begin();
  return s.ok() ? m.fail(m.begin(schema)) : s;
}

Status TaubinSmoother::vertex(const SequenceVertex& v) {
  Impl& m = *impl_;
  Status s = m.state.event("vertex event");
  if (s.ok()) s = detail::check_finite(v);
  return m.fail(s.ok() ? m.buffer.vertex(v) : std::move(s));
}
Status TaubinSmoother::triangle(const SequenceTriangle& t) {
  Impl& m = *impl_;
  Status s = m.state.event("triangle event");
  return s.ok() ? m.fail(m.triangle(t)) : s;
}

Status TaubinSmoother::finalize(uint32_t index) {
  Impl& m = *impl_;
  Status s = m.state.event("finalize event");
  return s.ok() ? m.fail(m.buffer.finalize(index)) : s;
}

Status TaubinSmoother::finish() {
  Impl& m = *impl_;
  Status s = m.state.finish();
  return s.ok() ? m.fail(m.finish()) : s;
}

const SmoothReport& TaubinSmoother::report() const { return impl_->report; }

Status smooth_taubin(SequenceSource& in, SequenceSink& out, const SmoothOptions& options, SmoothReport* report) {
  TaubinSmoother smoother(&out, options);
  Status s = pump_sequence(in, smoother);
  if (report) *report = smoother.report();
  return s;
}

}  // namespace psq
