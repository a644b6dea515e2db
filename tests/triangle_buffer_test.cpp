// SPDX-License-Identifier: Apache-2.0
// TriangleBuffer (psq/triangle_buffer.h): connectivity from the sequence,
// locks on both boundaries, the output order of paper section 6, edge
// collapse under the link condition, and refusal of sequences it cannot use.
#include <gtest/gtest.h>

#include <algorithm>
#include <functional>
#include <map>
#include <set>

#include "psq/sequence_builder.h"
#include "psq/sequence_check.h"
#include "psq/triangle_buffer.h"
#include "test_util.h"

namespace psq {
namespace {

using test::Mesh;
using Pos = std::array<double, 3>;

// A sequence collected with positions, checked as it arrives.
class Collected : public SequenceSink {
 public:
  Status begin(const MeshSchema& s) override {
    schema = s;
    return checker.begin(s);
  }
  Status vertex(const SequenceVertex& v) override {
    positions.push_back({v.position[0], v.position[1], v.position[2]});
    return checker.vertex(v);
  }
  Status triangle(const SequenceTriangle& t) override {
    triangles.push_back({t.v[0], t.v[1], t.v[2]});
    return checker.triangle(t);
  }
  Status finalize(uint32_t i) override { return checker.finalize(i); }
  Status finish() override {
    finished = true;
    return checker.finish();
  }
  // Triangles as position triples, rotated to a canonical first corner.
  std::multiset<std::array<Pos, 3>> geometry() const {
    std::multiset<std::array<Pos, 3>> out;
    for (const auto& t : triangles) {
      std::array<Pos, 3> g = {positions[t[0]], positions[t[1]], positions[t[2]]};
      while (g[0] > g[1] || g[0] > g[2]) std::rotate(g.begin(), g.begin() + 1, g.end());
      out.insert(g);
    }
    return out;
  }
  MeshSchema schema;
  SequenceChecker checker;
  std::vector<Pos> positions;
  std::vector<std::array<uint32_t, 3>> triangles;
  bool finished = false;
};

std::multiset<std::array<Pos, 3>> geometry_of(const Mesh& m) {
  std::multiset<std::array<Pos, 3>> out;
  for (const auto& t : m.triangles) {
    std::array<Pos, 3> g = {m.positions[t[0]], m.positions[t[1]], m.positions[t[2]]};
    while (g[0] > g[1] || g[0] > g[2]) std::rotate(g.begin(), g.begin() + 1, g.end());
    out.insert(g);
  }
  return out;
}

// A client that keeps at most `limit` triangles, writing in pick_output
// order, and lets a test look at the buffer after each triangle.
class Client : public SequenceSink {
 public:
  Client(SequenceSink* out, uint32_t limit) : buffer(out), limit_(limit) {}
  Status begin(const MeshSchema& s) override { return buffer.begin(s); }
  Status vertex(const SequenceVertex& v) override { return buffer.vertex(v); }
  Status triangle(const SequenceTriangle& t) override {
    uint32_t id;
    PSQ_RETURN_IF_ERROR(buffer.triangle(t, &id));
    if (on_triangle) on_triangle(id, t);
    while (buffer.triangle_count() > limit_) {
      const uint32_t w = buffer.pick_output(4, nullptr);
      if (on_write) on_write(w);
      PSQ_RETURN_IF_ERROR(buffer.write(w));
    }
    return Status();
  }
  Status finalize(uint32_t i) override { return buffer.finalize(i); }
  Status finish() override {
    PSQ_RETURN_IF_ERROR(buffer.end_input());
    if (before_finish) before_finish();
    return buffer.finish();
  }
  TriangleBuffer buffer;
  std::function<void(uint32_t, const SequenceTriangle&)> on_triangle;
  std::function<void(uint32_t)> on_write;
  std::function<void()> before_finish;

 private:
  uint32_t limit_;
};

Status run(const Mesh& m, SequenceSink& sink) {
  test::MemorySource source(m);
  BuildReport report;
  return build_sequence(source, sink, BuildOptions(), &report);
}

// Every live corner's opposite runs the other way between the same two
// vertices; every corner is in its vertex's list exactly once.
void expect_consistent(const TriangleBuffer& b) {
  uint32_t alive = 0;
  std::map<uint32_t, uint32_t> corners_of;
  for (uint32_t t = 0; t < b.triangle_capacity(); ++t) {
    if (!b.alive(t)) continue;
    ++alive;
    for (uint32_t c = 3 * t; c < 3 * t + 3; ++c) {
      ++corners_of[b.vertex_of(c)];
      const uint32_t o = b.opposite(c);
      if (o < TriangleBuffer::kOpen) {
        ASSERT_TRUE(b.alive(o / 3));
        EXPECT_EQ(b.opposite(o), c);
        EXPECT_EQ(b.vertex_of(o), b.vertex_of(TriangleBuffer::next(c)));
        EXPECT_EQ(b.vertex_of(TriangleBuffer::next(o)), b.vertex_of(c));
      }
    }
  }
  EXPECT_EQ(alive, b.triangle_count());
  for (const auto& [v, n] : corners_of) {
    uint32_t listed = 0;
    for (uint32_t c = b.first_corner(v); c != TriangleBuffer::kNone; c = b.next_corner(c)) {
      EXPECT_EQ(b.vertex_of(c), v);
      ++listed;
    }
    EXPECT_EQ(listed, n) << "vertex " << v;
  }
}

TEST(TriangleBuffer, WholeMeshConnectivityAndPassThrough) {
  Mesh m = test::make_grid(12);
  Collected out;
  Client client(&out, 1u << 30);
  client.before_finish = [&] {
    const TriangleBuffer& b = client.buffer;
    EXPECT_EQ(b.triangle_count(), m.triangles.size());
    expect_consistent(b);
    // A closed-in grid: the buffer holds all, only mesh borders have no
    // triangle across, every vertex is free.
    uint32_t border = 0;
    for (uint32_t c = 0; c < 3 * b.triangle_capacity(); ++c) {
      if (b.opposite(c) == TriangleBuffer::kBorder) {
        ++border;
        EXPECT_TRUE(b.border(b.vertex_of(c)));
      } else {
        EXPECT_LT(b.opposite(c), TriangleBuffer::kOpen);
      }
    }
    EXPECT_EQ(border, 4u * 12);
    EXPECT_EQ(b.free_vertex_count(), m.positions.size());
    EXPECT_EQ(b.input_band(), 0u);
  };
  ASSERT_TRUE(run(m, client).ok());
  EXPECT_TRUE(out.finished);
  EXPECT_EQ(out.geometry(), geometry_of(m));
  EXPECT_EQ(out.checker.stats().border_edges, 48u);
  EXPECT_EQ(client.buffer.stats().triangles_written, m.triangles.size());
}

TEST(TriangleBuffer, LocksFollowBothBoundaries) {
  Mesh m = test::make_sphere(24, 32);
  Collected out;
  Client client(&out, 200);
  uint64_t checked = 0;
  client.on_triangle = [&](uint32_t id, const SequenceTriangle& t) {
    const TriangleBuffer& b = client.buffer;
    for (int k = 0; k < 3; ++k) {
      const uint32_t v = b.vertex_of(3 * id + k);
      // Final corners leave the input boundary with this triangle.
      EXPECT_EQ(b.input_open(v), !(t.final_mask & (1u << k)));
    }
    // The free set is exactly the unlocked vertices, and no free vertex has
    // a triangle across the input or the output boundary.
    std::set<uint32_t> free;
    for (uint32_t i = 0; i < b.free_vertex_count(); ++i) free.insert(b.free_vertex(i));
    for (uint32_t v : free) {
      EXPECT_FALSE(b.locked(v));
      for (uint32_t c = b.first_corner(v); c != TriangleBuffer::kNone; c = b.next_corner(c)) {
        EXPECT_LT(b.opposite(c), TriangleBuffer::kOpen);
        EXPECT_LT(b.opposite(TriangleBuffer::prev(c)), TriangleBuffer::kOpen);
      }
    }
    uint32_t band = 0;
    for (uint32_t tri = 0; tri < b.triangle_capacity(); ++tri) {
      if (!b.alive(tri)) continue;
      bool open = false;
      for (int k = 0; k < 3; ++k) {
        const uint32_t v = b.vertex_of(3 * tri + k);
        open = open || b.input_open(v);
        if (!b.locked(v)) {
          EXPECT_EQ(free.count(v), 1u);
        }
      }
      band += open;
    }
    EXPECT_EQ(band, b.input_band());
    if (++checked % 97 == 0) expect_consistent(b);
  };
  ASSERT_TRUE(run(m, client).ok());
  EXPECT_EQ(out.geometry(), geometry_of(m));
  EXPECT_EQ(out.checker.stats().components, 1u);
  EXPECT_EQ(out.checker.stats().border_edges, 0u);
  EXPECT_LE(client.buffer.stats().max_triangles, 201u);
}

TEST(TriangleBuffer, OutputGrowsRegionsFromTheOutputBoundary) {
  // Writing from a full buffer: each written triangle completes an edge of
  // the output boundary, except one start per component.
  Mesh m = test::make_sphere(30, 40);
  Collected out;
  Client client(&out, 400);
  uint64_t adjacent = 0, starts = 0;
  client.on_write = [&](uint32_t w) {
    const TriangleBuffer& b = client.buffer;
    uint32_t written_edges = 0;
    for (uint32_t c = 3 * w; c < 3 * w + 3; ++c) written_edges += b.opposite(c) == TriangleBuffer::kWritten;
    if (written_edges) ++adjacent;
    else ++starts;
  };
  ASSERT_TRUE(run(m, client).ok());
  EXPECT_EQ(starts, 1u);
  EXPECT_EQ(client.buffer.stats().starts_written, 1u);
  EXPECT_EQ(out.geometry(), geometry_of(m));
}

TEST(TriangleBuffer, CollapseKeepsTheSurfaceManifold) {
  Mesh m = test::make_sphere(16, 20);
  Collected out;
  Client client(&out, 1u << 30);
  uint32_t collapsed = 0;
  client.before_finish = [&] {
    TriangleBuffer& b = client.buffer;
    // Collapse until no edge may be: the link condition stops at the
    // smallest closed surface (a tetrahedron).
    bool any = true;
    while (any) {
      any = false;
      for (uint32_t c = 0; c < 3 * b.triangle_capacity() && !any; ++c) {
        if (!b.alive(c / 3) || !b.can_collapse(c)) continue;
        const uint32_t before = b.triangle_count();
        const uint32_t keep = b.collapse(c, c % 2 == 0);
        EXPECT_FALSE(b.locked(keep));
        EXPECT_EQ(b.triangle_count(), before - 2);
        ++collapsed;
        any = true;
      }
      if (collapsed % 17 == 0) expect_consistent(b);
    }
    expect_consistent(b);
    EXPECT_EQ(b.triangle_count(), 4u);
    EXPECT_EQ(b.stats().collapses, collapsed);
  };
  ASSERT_TRUE(run(m, client).ok());
  EXPECT_EQ(out.triangles.size(), 4u);
  const SequenceStats& st = out.checker.stats();
  EXPECT_EQ(st.components, 1u);
  EXPECT_EQ(st.border_edges, 0u);
  EXPECT_EQ(st.handles, 0);
  EXPECT_EQ(st.nonmanifold_vertices, 0u);
}

TEST(TriangleBuffer, DiscardLeavesBordersAndDropsBareVertices) {
  const Mesh m = test::make_sphere(8, 10);
  // One triangle discarded: the three across it get a border edge each.
  {
    Collected out;
    Client client(&out, 1u << 30);
    client.before_finish = [&] {
      TriangleBuffer& b = client.buffer;
      uint32_t t = 0;
      while (!b.alive(t)) ++t;
      ASSERT_TRUE(b.can_discard(t));
      uint32_t across[3];
      for (uint32_t k = 0; k < 3; ++k) {
        across[k] = b.opposite(3 * t + k);
        ASSERT_LT(across[k], TriangleBuffer::kOpen);
      }
      const uint32_t before = b.triangle_count(), vertices = b.vertex_count();
      b.discard(t);
      EXPECT_EQ(b.triangle_count(), before - 1);
      EXPECT_EQ(b.vertex_count(), vertices);
      EXPECT_EQ(b.stats().triangles_discarded, 1u);
      for (uint32_t o : across) {
        EXPECT_EQ(b.opposite(o), TriangleBuffer::kBorder);
        EXPECT_TRUE(b.border(b.vertex_of(o)));
        EXPECT_TRUE(b.border(b.vertex_of(TriangleBuffer::next(o))));
      }
      expect_consistent(b);
    };
    ASSERT_TRUE(run(m, client).ok());
    EXPECT_EQ(out.triangles.size(), m.triangles.size() - 1);
    const SequenceStats& st = out.checker.stats();
    EXPECT_EQ(st.border_edges, 3u);
    EXPECT_EQ(st.components, 1u);
    EXPECT_EQ(st.nonmanifold_vertices, 0u);
  }
  // All of it discarded: its vertices go with their last triangle.
  {
    Collected out;
    Client client(&out, 1u << 30);
    client.before_finish = [&] {
      TriangleBuffer& b = client.buffer;
      for (uint32_t t = 0; t < b.triangle_capacity(); ++t)
        if (b.alive(t)) b.discard(t);
      EXPECT_EQ(b.triangle_count(), 0u);
      EXPECT_EQ(b.vertex_count(), 0u);
      EXPECT_EQ(b.stats().triangles_discarded, m.triangles.size());
    };
    ASSERT_TRUE(run(m, client).ok());
    EXPECT_TRUE(out.finished);
    EXPECT_EQ(out.triangles.size(), 0u);
    EXPECT_EQ(out.positions.size(), 0u);
  }
  // A written neighbour locks a vertex: no discard there.
  {
    Collected out;
    Client client(&out, 1u << 30);
    client.before_finish = [&] {
      TriangleBuffer& b = client.buffer;
      const uint32_t w = b.pick_output(1, nullptr);
      ASSERT_TRUE(b.write(w).ok());
      for (uint32_t t = 0; t < b.triangle_capacity(); ++t) {
        if (!b.alive(t)) continue;
        bool locked = false;
        for (uint32_t k = 0; k < 3; ++k) locked = locked || b.locked(b.vertex_of(3 * t + k));
        EXPECT_EQ(b.can_discard(t), !locked);
      }
    };
    ASSERT_TRUE(run(m, client).ok());
  }
}

TEST(TriangleBuffer, CutClosesAHandleThreeEdgesAround) {
  const Mesh m = test::make_torus(24, 10);
  Collected out;
  Client client(&out, 1u << 30);
  uint32_t cuts = 0;
  client.before_finish = [&] {
    TriangleBuffer& b = client.buffer;
    auto collapse_all = [&] {
      bool any = true;
      while (any) {
        any = false;
        for (uint32_t c = 0; c < 3 * b.triangle_capacity() && !any; ++c) {
          if (!b.alive(c / 3) || !b.can_collapse(c)) continue;
          b.collapse(c, true);
          any = true;
        }
      }
    };
    collapse_all();
    expect_consistent(b);
    // A torus that no collapse reduces: some edge fails the link
    // condition through a third vertex.
    const uint32_t floor = b.triangle_count();
    EXPECT_GE(floor, 14u);
    uint32_t h = 0, c = 0;
    while (h < 3 * b.triangle_capacity() && !(b.alive(h / 3) && b.cycle_of(h, &c))) ++h;
    ASSERT_LT(h, 3 * b.triangle_capacity());
    const uint32_t a = b.vertex_of(h), v = b.vertex_of(TriangleBuffer::next(h));
    uint32_t copies[3], caps[2];
    ASSERT_TRUE(b.cut(h, c, copies, caps));
    ++cuts;
    expect_consistent(b);
    EXPECT_EQ(b.triangle_count(), floor + 2);
    EXPECT_EQ(b.stats().cuts, 1u);
    const uint32_t right[3] = {a, v, c};
    for (int k = 0; k < 3; ++k) {
      EXPECT_EQ(b.vertex_of(3 * caps[0] + k), right[k]);
      EXPECT_FALSE(b.locked(copies[k]));
      EXPECT_EQ(b.position(copies[k])[0], b.position(right[k])[0]);
    }
    EXPECT_EQ(b.vertex_of(3 * caps[1]), copies[0]);
    EXPECT_EQ(b.vertex_of(3 * caps[1] + 1), copies[2]);
    EXPECT_EQ(b.vertex_of(3 * caps[1] + 2), copies[1]);
    // Now a sphere: collapses reach the tetrahedron.
    collapse_all();
    expect_consistent(b);
    EXPECT_EQ(b.triangle_count(), 4u);
  };
  ASSERT_TRUE(run(m, client).ok());
  EXPECT_EQ(cuts, 1u);
  EXPECT_EQ(out.triangles.size(), 4u);
  const SequenceStats& st = out.checker.stats();
  EXPECT_EQ(st.components, 1u);
  EXPECT_EQ(st.handles, 0);
  EXPECT_EQ(st.border_edges, 0u);
  EXPECT_EQ(st.nonmanifold_vertices, 0u);
  EXPECT_EQ(st.nonmanifold_edges, 0u);
}

TEST(TriangleBuffer, CollapseOnBordersAndTheDummyVertex) {
  // A strip of two triangles: the interior edge joins two border vertices
  // (a pinch), the border edges leave the other triangle only.
  Mesh m = test::make_mesh({{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}}, {{0, 1, 2}, {0, 2, 3}});
  Collected out;
  Client client(&out, 1u << 30);
  client.before_finish = [&] {
    TriangleBuffer& b = client.buffer;
    uint32_t allowed = 0;
    for (uint32_t c = 0; c < 6; ++c) {
      if (!b.can_collapse(c)) continue;
      ++allowed;
      EXPECT_EQ(b.opposite(c), TriangleBuffer::kBorder);
    }
    EXPECT_EQ(allowed, 4u);
    // Collapse one border edge: one triangle is left, and no more.
    for (uint32_t c = 0; c < 6; ++c) {
      if (b.can_collapse(c)) {
        b.collapse(c, true);
        break;
      }
    }
    EXPECT_EQ(b.triangle_count(), 1u);
    for (uint32_t c = 0; c < 3 * b.triangle_capacity(); ++c)
      if (b.alive(c / 3)) {
        EXPECT_FALSE(b.can_collapse(c));
      }
    expect_consistent(b);
  };
  ASSERT_TRUE(run(m, client).ok());
  EXPECT_EQ(out.triangles.size(), 1u);
  EXPECT_EQ(out.checker.stats().border_edges, 3u);
}

TEST(TriangleBuffer, NonManifoldCutsAreMarked) {
  // Two tetrahedra sharing one vertex: the second fan re-appears it.
  Mesh m = test::make_mesh({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {-1, 0, 0}, {0, -1, 0}, {0, 0, -1}},
                           {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}, {0, 5, 4}, {0, 4, 6}, {0, 6, 5}, {4, 5, 6}});
  Collected out;
  Client client(&out, 1u << 30);
  client.before_finish = [&] {
    const TriangleBuffer& b = client.buffer;
    uint32_t cut = 0;
    for (uint32_t v = 0; v < b.vertex_capacity(); ++v)
      if (b.first_corner(v) != TriangleBuffer::kNone && b.cut(v)) ++cut;
    EXPECT_EQ(cut, 1u);  // the re-appearance
  };
  ASSERT_TRUE(run(m, client).ok());
  EXPECT_EQ(out.triangles.size(), 8u);
  EXPECT_EQ(out.geometry(), geometry_of(m));
}

TEST(TriangleBuffer, RefusesSequencesWithoutSlotsOrMasks) {
  Collected out;
  TriangleBuffer b(&out);
  ASSERT_TRUE(b.begin(MeshSchema()).ok());
  SequenceVertex v;
  for (uint32_t i = 0; i < 3; ++i) {
    v.index = i;
    ASSERT_TRUE(b.vertex(v).ok());
  }
  SequenceTriangle t;
  t.v[0] = 0, t.v[1] = 1, t.v[2] = 2;
  t.new_mask = 7;
  uint32_t id;
  EXPECT_EQ(b.triangle(t, &id).code(), ErrorCode::kUsage);  // no slots
  for (uint32_t k = 0; k < 3; ++k) t.vslot[k] = k;
  EXPECT_EQ(b.triangle(t, &id).code(), ErrorCode::kUsage);  // no masks
  t.border_mask = 3;
  t.leaving_mask = 2;
  EXPECT_EQ(b.triangle(t, &id).code(), ErrorCode::kBadSequence);  // edge both border and leaving
  t.leaving_mask = 0;
  t.entering_mask = 4;
  t.eslot[2] = 0;
  ASSERT_TRUE(b.triangle(t, &id).ok());
  // A leaving edge whose slot names no open edge, or another edge.
  SequenceTriangle u;
  u.v[0] = 0, u.v[1] = 2, u.v[2] = 3;
  u.vslot[0] = 0, u.vslot[1] = 2, u.vslot[2] = 3;
  u.new_mask = 4;
  u.leaving_mask = 1;
  u.eslot[0] = 5;
  u.border_mask = 6;
  v.index = 3;
  ASSERT_TRUE(b.vertex(v).ok());
  EXPECT_EQ(b.triangle(u, &id).code(), ErrorCode::kBadSequence);
  u.eslot[0] = 0;  // open, but it runs from 2 to 0: this edge runs 0 -> 2 the same way
  std::swap(u.v[0], u.v[1]);
  std::swap(u.vslot[0], u.vslot[1]);
  EXPECT_EQ(b.triangle(u, &id).code(), ErrorCode::kBadSequence);
  // A vertex referenced through a slot it does not hold.
  SequenceTriangle w = t;
  w.new_mask = 0;
  w.vslot[0] = 9;
  EXPECT_EQ(b.triangle(w, &id).code(), ErrorCode::kBadSequence);
  // The input ends with the edge still open.
  Collected out2;
  TriangleBuffer b2(&out2);
  ASSERT_TRUE(b2.begin(MeshSchema()).ok());
  for (uint32_t i = 0; i < 3; ++i) {
    v.index = i;
    ASSERT_TRUE(b2.vertex(v).ok());
  }
  ASSERT_TRUE(b2.triangle(t, &id).ok());
  EXPECT_EQ(b2.end_input().code(), ErrorCode::kBadSequence);
}

TEST(TriangleBuffer, IsolatedVerticesAreDropped) {
  Mesh m = test::make_mesh({{0, 0, 0}, {5, 5, 5}, {1, 0, 0}, {0, 1, 0}}, {{0, 2, 3}});
  Collected out;
  Client client(&out, 1u << 30);
  ASSERT_TRUE(run(m, client).ok());
  EXPECT_EQ(client.buffer.stats().isolated_dropped, 1u);
  EXPECT_EQ(out.positions.size(), 3u);
  EXPECT_EQ(out.triangles.size(), 1u);
}

}  // namespace
}  // namespace psq
