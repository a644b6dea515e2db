// SPDX-License-Identifier: Apache-2.0
// build_sequence (psq/sequence_builder.h): spool an indexed mesh, then feed
// the converter either in file order (coherent input) or after an external
// spatial sort (paper section 3, "from scratch"; external sorts as in
// Lindstrom and Silva 2001).
#include "psq/sequence_builder.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <memory>
#include <vector>

#include "external_sort.h"
#include "psq/io.h"
#include "psq/memory_budget.h"
#include "spool_records.h"
#include "weld.h"

namespace psq {
namespace {

using detail::get_record;
using detail::get_values;
using detail::get_values_at;
using detail::put_record;

// A float made into an unsigned integer that sorts like the float.
uint32_t sortable(float f) {
  uint32_t u;
  std::memcpy(&u, &f, 4);
  return (u & 0x80000000u) ? ~u : (u | 0x80000000u);
}

// The sort path's records carry what the merge feeds the converter (the
// position, the corners), so that a mesh without properties is merged from
// sequential reads only; the offsets find a record's property values.
struct VertexKey {
  uint32_t key;     // position along the sweep axis
  uint32_t index;   // input index: ties, and identity
  uint64_t offset;  // of the record in the vertex spool
  double pos[3];
  bool operator<(const VertexKey& o) const { return key != o.key ? key < o.key : index < o.index; }
};

struct TriangleKey {
  uint32_t rank;    // smallest rank of its vertices
  uint32_t idx[3];
  uint64_t offset;  // of the record in the triangle spool (also a unique tie-break)
  bool operator<(const TriangleKey& o) const { return rank != o.rank ? rank < o.rank : offset < o.offset; }
};

// The sort path's vertices in rank order: index (4 bytes), offset of the
// record in the vertex spool (8), position (24).
constexpr size_t kOrderRecord = 36;

// Triangles are grouped in blocks for finalization: after block b every
// vertex below the smallest index that any later block uses is final.
constexpr uint64_t kBlock = 4096;

struct Spooled {
  std::unique_ptr<SpoolFile> vertices = std::make_unique<SpoolFile>();
  std::unique_ptr<SpoolFile> triangles = std::make_unique<SpoolFile>();
  uint64_t nv = 0, nt = 0;
  double lo[3] = {0, 0, 0}, hi[3] = {0, 0, 0};
  std::vector<uint32_t> block_min;  // smallest index a block of triangles uses
  std::vector<uint32_t> block_max;  // largest
  std::vector<uint32_t> later_min;  // [b]: smallest index used after block b (nv if none)
  uint64_t window = 0;              // most vertices fed but not final during a block (coherent path)
};

// Adds a triangle to the block statistics of the coherent path.
void note_triangle(Spooled* s, const uint32_t index[3]) {
  uint32_t mn = std::min({index[0], index[1], index[2]});
  uint32_t mx = std::max({index[0], index[1], index[2]});
  if (s->nt % kBlock == 0) {
    s->block_min.push_back(mn);
    s->block_max.push_back(mx);
  }
  s->block_min.back() = std::min(s->block_min.back(), mn);
  s->block_max.back() = std::max(s->block_max.back(), mx);
  ++s->nt;
}

// Suffix minima, and the window the coherent path would hold: vertices
// fed by the end of a block (up to the largest index used so far) that
// were not final when the block began (below the smallest index of the
// block and all later ones; nothing is final before the first block).
void finish_blocks(Spooled* s) {
  size_t blocks = s->block_min.size();
  s->later_min.assign(blocks, static_cast<uint32_t>(std::min<uint64_t>(s->nv, 0xffffffffu)));
  for (size_t b = blocks; b-- > 1;) s->later_min[b - 1] = std::min(s->later_min[b], s->block_min[b]);
  uint64_t fed = 0;
  s->window = 0;
  for (size_t b = 0; b < blocks; ++b) {
    fed = std::max<uint64_t>(fed, uint64_t{s->block_max[b]} + 1);
    const uint64_t final_before = b == 0 ? 0 : s->later_min[b - 1];
    if (fed > final_before) s->window = std::max<uint64_t>(s->window, fed - final_before);
  }
}

Status spool_input(MeshSource& source, const BuildOptions& options, Spooled* s,
                   detail::DuplicateSampler* sampler) {
  PSQ_RETURN_IF_ERROR(s->vertices->create(options.tmpdir));
  PSQ_RETURN_IF_ERROR(s->triangles->create(options.tmpdir));
  MeshItem item;
  for (;;) {
    PSQ_RETURN_IF_ERROR(source.next(&item));
    if (item.kind == MeshItem::Kind::kEnd) break;
    if (item.kind == MeshItem::Kind::kVertex) {
      if (s->nv == 0) {
        std::copy(item.position, item.position + 3, s->lo);
        std::copy(item.position, item.position + 3, s->hi);
      }
      for (int k = 0; k < 3; ++k) {
        s->lo[k] = std::min(s->lo[k], item.position[k]);
        s->hi[k] = std::max(s->hi[k], item.position[k]);
      }
      if (sampler) sampler->add(item.position);
      PSQ_RETURN_IF_ERROR(put_record(*s->vertices, item.position, 24, item.values));
      ++s->nv;
    } else {
      PSQ_RETURN_IF_ERROR(put_record(*s->triangles, item.index, 12, item.values));
      note_triangle(s, item.index);
    }
  }
  finish_blocks(s);
  PSQ_RETURN_IF_ERROR(s->vertices->rewind());
  return s->triangles->rewind();
}

// The builder's shares of its budget (psq/memory_budget.h), in two phases
// on the sort path. Sorting: the external sorts' buffers and the rank array
// (4 bytes per vertex), half each. Merging: the sorts' merge buffers keep
// their half; the rank array's half goes to the spool files loaded in
// memory (so that the merge reads property values without a pread each)
// and to the converter's lookahead, a quarter each. The coherent path
// needs only the converter's quarter.
struct Shares {
  uint64_t sort = 0, ranks = 0, spools = 0, lookahead = 0;
};

Shares builder_shares(uint64_t total) {
  MemoryBudget budget(total);
  Shares s;
  s.sort = budget.draw(1, 2);
  s.ranks = budget.draw(1, 2);
  budget.give_back(s.ranks);
  s.spools = budget.draw(1, 4);
  s.lookahead = budget.draw(1, 4);
  return s;
}

// Coherent path: triangles in file order, vertices in index order as the
// triangles reach them; after each block of triangles, every vertex below
// the smallest index of all later blocks is final.
Status feed_coherent(Spooled& s, SequenceConverter& conv) {
  InputStream& vin = s.vertices->stream();
  InputStream& tin = s.triangles->stream();
  uint64_t fed = 0, finalized = 0;
  double pos[3];
  PropertyValues vertex_values;
  auto feed_until = [&](uint64_t end) -> Status {
    while (fed < end) {
      PSQ_RETURN_IF_ERROR(get_record(vin, pos, 24, &vertex_values));
      PSQ_RETURN_IF_ERROR(conv.vertex(static_cast<uint32_t>(fed), pos, vertex_values));
      ++fed;
    }
    return Status();
  };
  auto finalize_below = [&](uint64_t end) -> Status {
    PSQ_RETURN_IF_ERROR(feed_until(end));
    while (finalized < end) PSQ_RETURN_IF_ERROR(conv.finalize(static_cast<uint32_t>(finalized++)));
    return Status();
  };
  // Triangles are read kAhead records before they go in, so that the
  // converter loads their corners' records ahead (prefetch()).
  constexpr uint64_t kAhead = 8;
  struct Record {
    uint32_t idx[3];
    PropertyValues values;
  };
  Record ring[kAhead];
  for (uint64_t t = 0; t < std::min(kAhead, s.nt); ++t)
    PSQ_RETURN_IF_ERROR(get_record(tin, ring[t].idx, 12, &ring[t].values));
  for (uint64_t t = 0; t < s.nt; ++t) {
    Record& r = ring[t % kAhead];
    PSQ_RETURN_IF_ERROR(feed_until(uint64_t{std::max({r.idx[0], r.idx[1], r.idx[2]})} + 1));
    PSQ_RETURN_IF_ERROR(conv.triangle(r.idx, r.values));
    if ((t + 1) % kBlock == 0 || t + 1 == s.nt) PSQ_RETURN_IF_ERROR(finalize_below(s.later_min[t / kBlock]));
    if (t + kAhead < s.nt) {
      PSQ_RETURN_IF_ERROR(get_record(tin, r.idx, 12, &r.values));
      conv.prefetch(r.idx);
    }
  }
  return finalize_below(s.nv);
}

// Sort path.
Status feed_sorted(Spooled& s, const BuildOptions& options, const Shares& shares, SequenceConverter& conv) {
  if (s.nv * 4 > shares.ranks) {
    return Status(ErrorCode::kLimit, "the vertex rank array (4 bytes per vertex) does not fit --memory");
  }
  int axis = 0;
  for (int k = 1; k < 3; ++k) {
    if (s.hi[k] - s.lo[k] > s.hi[axis] - s.lo[axis]) axis = k;
  }
  ExternalSortOptions so;
  so.memory_budget = shares.sort;
  so.tmpdir = options.tmpdir;
  // 1. Vertices by their coordinate along the longest axis.
  ExternalSorter<VertexKey> vsort(so);
  vsort.reserve(s.nv);
  bool vertex_values = false;  // some vertex record has property values
  {
    InputStream& vin = s.vertices->stream();
    VertexKey vk{};
    PropertyValues values;
    uint64_t offset = 0;
    for (uint64_t i = 0; i < s.nv; ++i) {
      PSQ_RETURN_IF_ERROR(get_record(vin, vk.pos, 24, &values));
      vk.key = sortable(static_cast<float>(vk.pos[axis]));
      vk.index = static_cast<uint32_t>(i);
      vk.offset = offset;
      PSQ_RETURN_IF_ERROR(vsort.add(vk));
      offset += 24 + 4 + 8 * values.size();
      vertex_values = vertex_values || !values.empty();
    }
  }
  PSQ_RETURN_IF_ERROR(vsort.finish());
  // 2. Ranks, and the vertices in rank order spooled as (index, offset,
  // position).
  std::vector<uint32_t> rank(s.nv);
  SpoolFile order;
  PSQ_RETURN_IF_ERROR(order.create(options.tmpdir));
  for (uint32_t r = 0;; ++r) {
    VertexKey vk;
    bool done = false;
    PSQ_RETURN_IF_ERROR(vsort.next(&vk, &done));
    if (done) break;
    rank[vk.index] = r;
    uint8_t rec[kOrderRecord];
    std::memcpy(rec, &vk.index, 4);
    std::memcpy(rec + 4, &vk.offset, 8);
    std::memcpy(rec + 12, vk.pos, 24);
    PSQ_RETURN_IF_ERROR(order.write(rec, kOrderRecord));
  }
  vsort = ExternalSorter<VertexKey>(so);  // release its buffers
  PSQ_RETURN_IF_ERROR(order.rewind());
  // 3. Triangles by the smallest rank of their vertices.
  ExternalSorter<TriangleKey> tsort(so);
  tsort.reserve(s.nt);
  bool triangle_values = false;
  {
    InputStream& tin = s.triangles->stream();
    TriangleKey tk{};
    PropertyValues values;
    uint64_t offset = 0;
    for (uint64_t t = 0; t < s.nt; ++t) {
      PSQ_RETURN_IF_ERROR(get_record(tin, tk.idx, 12, &values));
      tk.rank = std::min({rank[tk.idx[0]], rank[tk.idx[1]], rank[tk.idx[2]]});
      tk.offset = offset;
      PSQ_RETURN_IF_ERROR(tsort.add(tk));
      offset += 12 + 4 + 8 * values.size();
      triangle_values = triangle_values || !values.empty();
    }
  }
  PSQ_RETURN_IF_ERROR(tsort.finish());
  // Property values are read at their records' offsets, in rank order. The
  // ranks are done with: the spools that have values are loaded into their
  // share when they fit, so that the merge reads them from memory instead
  // of with a pread each (bench/HISTORY.md, "The sort path's merge without
  // random reads").
  std::vector<uint32_t>().swap(rank);
  const uint64_t share = shares.spools;
  const uint64_t want = (vertex_values ? s.vertices->size() : 0) + (triangle_values ? s.triangles->size() : 0);
  if (want > 0 && want <= share) {
    bool loaded = false;
    if (vertex_values) PSQ_RETURN_IF_ERROR(s.vertices->load(share, &loaded));
    if (triangle_values) PSQ_RETURN_IF_ERROR(s.triangles->load(share, &loaded));
  }
  // 4. Merge: for each vertex in rank order, the vertex, the triangles whose
  // first vertex it is, and its finalization: all its triangles are in.
  InputStream& oin = order.stream();
  TriangleKey next_t{};
  bool t_done = false;
  PSQ_RETURN_IF_ERROR(tsort.next(&next_t, &t_done));
  double pos[3];
  PropertyValues values;
  for (uint64_t r = 0; r < s.nv; ++r) {
    uint32_t index;
    uint64_t offset;
    uint8_t rec[kOrderRecord];
    PSQ_RETURN_IF_ERROR(oin.read_exact(rec, kOrderRecord));
    std::memcpy(&index, rec, 4);
    std::memcpy(&offset, rec + 4, 8);
    std::memcpy(pos, rec + 12, 24);
    if (vertex_values) PSQ_RETURN_IF_ERROR(get_values_at(*s.vertices, offset + 24, &values));
    else values.clear();
    PSQ_RETURN_IF_ERROR(conv.vertex(index, pos, values));
    while (!t_done && next_t.rank == r) {
      if (triangle_values) PSQ_RETURN_IF_ERROR(get_values_at(*s.triangles, next_t.offset + 12, &values));
      else values.clear();
      PSQ_RETURN_IF_ERROR(conv.triangle(next_t.idx, values));
      PSQ_RETURN_IF_ERROR(tsort.next(&next_t, &t_done));
    }
    PSQ_RETURN_IF_ERROR(conv.finalize(index));
  }
  return Status();
}

// Welds the spools (weld.cpp) within the sort phase's shares, and redoes
// the block statistics of the coherent path on the welded triangles.
Status weld_spooled(const BuildOptions& options, Spooled* s, BuildReport* report) {
  const Shares shares = builder_shares(options.memory_budget);
  auto vertices = std::make_unique<SpoolFile>();
  auto triangles = std::make_unique<SpoolFile>();
  detail::WeldStats stats;
  PSQ_RETURN_IF_ERROR(detail::weld_spools(*s->vertices, s->nv, *s->triangles, s->nt,
                                          options.weld == WeldMode::kPositions, shares.sort, shares.ranks,
                                          options.tmpdir, vertices.get(), triangles.get(), &stats));
  s->vertices = std::move(vertices);
  s->triangles = std::move(triangles);
  s->nv = stats.vertices;
  s->nt = 0;
  s->block_min.clear();
  s->block_max.clear();
  InputStream& in = s->triangles->stream();
  PropertyValues values;
  for (uint64_t t = 0; t < stats.triangles; ++t) {
    uint32_t idx[3];
    PSQ_RETURN_IF_ERROR(in.read_exact(idx, 12));
    PSQ_RETURN_IF_ERROR(get_values(in, &values));
    note_triangle(s, idx);
  }
  finish_blocks(s);
  report->welded_vertices = stats.merged;
  report->weld_dropped = stats.dropped;
  report->weld_sort_runs = stats.sort_runs;
  report->weld_external = stats.external;
  return s->triangles->rewind();
}

}  // namespace

Status build_sequence(MeshSource& source, SequenceSink& sink, const BuildOptions& options, BuildReport* report) {
  Spooled s;
  // Without --weld, a sample of the positions tells whether most vertices
  // repeat others (a triangle soup), for the caller to suggest welding.
  detail::DuplicateSampler sampler;
  const bool weld = options.weld != WeldMode::kOff;
  PSQ_RETURN_IF_ERROR(spool_input(source, options, &s, weld ? nullptr : &sampler));
  if (s.nv > 0xffffffffull) return Status(ErrorCode::kLimit, "more than 4294967295 vertices");
  report->input_vertices = s.nv;
  report->input_triangles = s.nt;
  if (!weld) report->duplicate_share = sampler.duplicate_share();
  if (weld) PSQ_RETURN_IF_ERROR(weld_spooled(options, &s, report));
  SequenceConverter conv(&sink);
  // The spool pass knows the bounding box before the first vertex goes on:
  // the .psq encoder places its quantization grid on it. Counts are the
  // input's; the sequence may add re-appearances and drop degenerate
  // triangles, so they are not promised.
  MeshSchema schema = source.schema();
  schema.vertex_count = MeshSchema::kUnknown;
  schema.triangle_count = MeshSchema::kUnknown;
  // An empty mesh has the empty box at the origin (so that it can be
  // quantized too).
  schema.has_bounds = true;
  if (s.nv > 0) {
    std::copy(s.lo, s.lo + 3, schema.bounds_min);
    std::copy(s.hi, s.hi + 3, schema.bounds_max);
  } else {
    std::fill(schema.bounds_min, schema.bounds_min + 3, 0.0);
    std::fill(schema.bounds_max, schema.bounds_max + 3, 0.0);
  }
  const Shares shares = builder_shares(options.memory_budget);
  conv.set_lookahead_budget(shares.lookahead);
  conv.reserve(s.nv, s.nt);
  PSQ_RETURN_IF_ERROR(conv.begin(schema));
  // Coherent enough when the vertices the window keeps waiting fit the
  // converter's share (a waiting vertex and its triangles take about 400
  // bytes) and are less than half of the mesh. A window of most of the
  // mesh means the file order is not spatially coherent: one pass would hold
  // the whole mesh, and its triangles would become ready in scattered places,
  // so that the grown regions are riddled with holes around the vertices
  // still waiting. The sweep of the sort path avoids both, for smaller
  // streams and less memory (bench/HISTORY.md, "Sorting incoherent file
  // orders"). A mesh of one block
  // of triangles counts as incoherent: one pass would hold all of it, and
  // the sort costs little at that size. The rule on half of the mesh
  // applies only when the sort's rank array fits the budget (feed_sorted):
  // otherwise the one pass runs as before. So does a window beyond the
  // converter's share, when the rank array does not fit but the window is
  // less than half of the mesh: one pass holds more than its share, the
  // sort could not run at all.
  uint64_t limit = std::max<uint64_t>(1024, shares.lookahead / 400);
  const bool ranks_fit = s.nv * 4 <= shares.ranks;
  const bool incoherent = 2 * s.window > s.nv && ranks_fit;
  const bool wide = s.window > limit && (ranks_fit || 2 * s.window > s.nv);
  bool sorted = options.force_sort || wide || incoherent;
  report->sorted = sorted;
  report->window = s.window;
  report->vertices = s.nv;
  report->triangles = s.nt;
  PSQ_RETURN_IF_ERROR(sorted ? feed_sorted(s, options, shares, conv) : feed_coherent(s, conv));
  PSQ_RETURN_IF_ERROR(conv.finish());
  report->converter = conv.stats();
  return Status();
}

}  // namespace psq
