// SPDX-License-Identifier: Apache-2.0
// Welding identical vertices of a spooled mesh before its processing
// sequence is built (weld.h). A triangle soup repeats each vertex once per
// triangle; the processing sequence (Isenburg, Lindstrom, Gumhold and
// Snoeyink 2003, section 3) then has no shared edges to code, and every
// triangle is its own component. Draco's encoder merges equal positions by
// default for the same reason. The classes of identical vertices are found
// with the external sort (external_sort.h, as the spatial sort of
// sequence_builder.cpp), so that memory stays within the budget: the only
// per-vertex array is the map from input to welded index (4 bytes a vertex,
// like the sort path's rank array).
#include "weld.h"

#include <algorithm>

#include "external_sort.h"
#include "spool_records.h"

namespace psq::detail {
namespace {

uint64_t mix(uint64_t h, uint64_t v) {
  // A multiply-xorshift round (the finalizer of a 64-bit avalanche hash).
  h ^= v + 0x9e3779b97f4a7c15ull + (h << 6) + (h >> 2);
  h ^= h >> 31;
  h *= 0xbf58476d1ce4e5b9ull;
  h ^= h >> 29;
  return h;
}

uint64_t position_hash(const double p[3]) {
  return mix(mix(mix(0, weld_bits(p[0])), weld_bits(p[1])), weld_bits(p[2]));
}

uint64_t values_hash(const PropertyValues& values) {
  uint64_t h = mix(0x51ed270b27a1f3d5ull, values.size());
  for (double v : values) h = mix(h, weld_bits(v));
  return h;
}

bool same_values(const PropertyValues& a, const PropertyValues& b) {
  if (a.size() != b.size()) return false;
  for (size_t i = 0; i < a.size(); ++i) {
    if (weld_bits(a[i]) != weld_bits(b[i])) return false;
  }
  return true;
}

// Sorted so that identical vertices are adjacent, the first in file order
// first. The values' hash only groups candidates: equal hashes are
// confirmed by comparing the values themselves.
struct WeldKey {
  uint64_t p[3];
  uint64_t h;       // hash of the property values; 0 when they do not count
  uint64_t offset;  // of the vertex record in the input spool
  uint32_t index;
  uint32_t unused;
  bool same_class(const WeldKey& o) const { return p[0] == o.p[0] && p[1] == o.p[1] && p[2] == o.p[2] && h == o.h; }
  bool operator<(const WeldKey& o) const {
    if (p[0] != o.p[0]) return p[0] < o.p[0];
    if (p[1] != o.p[1]) return p[1] < o.p[1];
    if (p[2] != o.p[2]) return p[2] < o.p[2];
    if (h != o.h) return h < o.h;
    return index < o.index;
  }
};

}  // namespace

void DuplicateSampler::add(const double position[3]) {
  if (full_) return;
  const uint64_t h = position_hash(position);
  if ((h >> 60) != 0) return;  // outside the sampled sixteenth
  if (!table_) {
    table_.reset(static_cast<uint64_t*>(std::calloc(kSlots, sizeof(uint64_t))));
    if (!table_) {  // no room for an estimate: none is made
      full_ = true;
      return;
    }
  }
  ++sampled_;
  const uint64_t key = h | 1;
  for (size_t i = static_cast<size_t>(h >> 8) & (kSlots - 1);; i = (i + 1) & (kSlots - 1)) {
    if (table_[i] == key) {
      ++duplicates_;
      return;
    }
    if (table_[i] == 0) {
      table_[i] = key;
      full_ = ++used_ >= kSlots / 2;
      return;
    }
  }
}

double DuplicateSampler::duplicate_share() const {
  if (sampled_ < 256) return -1;
  return static_cast<double>(duplicates_) / static_cast<double>(sampled_);
}

namespace {

// The external path's records (weld_spools, when the map does not fit).
struct Member {  // vertex `index` belongs to the class whose first vertex is `rep`
  uint32_t rep;
  uint32_t index;
  bool operator<(const Member& o) const { return rep != o.rep ? rep < o.rep : index < o.index; }
};
struct NewIndex {  // vertex `index` becomes welded vertex `id`; `first`: it is its class's first
  uint32_t index;
  uint32_t id;
  uint32_t first;
  bool operator<(const NewIndex& o) const { return index < o.index; }
};
struct Corner {  // corner `at` (triangle * 3 + k) uses input vertex `vertex`, or welded vertex `vertex`
  uint64_t at;
  uint32_t vertex;
  uint32_t unused;
};
struct ByVertex {
  bool operator()(const Corner& a, const Corner& b) const { return a.vertex != b.vertex ? a.vertex < b.vertex : a.at < b.at; }
};
struct ByCorner {
  bool operator()(const Corner& a, const Corner& b) const { return a.at < b.at; }
};

Status bad_corner(uint64_t t, uint32_t v, uint64_t nv) {
  return Status(ErrorCode::kBadIndex, "triangle " + std::to_string(t) + " uses vertex " + std::to_string(v) + " of " +
                                          std::to_string(nv));
}

bool degenerate(const uint32_t idx[3]) { return idx[0] == idx[1] || idx[1] == idx[2] || idx[2] == idx[0]; }

}  // namespace

Status weld_spools(SpoolFile& vin, uint64_t nv, SpoolFile& tin, uint64_t nt, bool positions_only,
                   uint64_t sort_budget, uint64_t map_budget, const std::string& tmpdir, SpoolFile* vout,
                   SpoolFile* tout, WeldStats* stats) {
  // The map from input to welded index in memory when it fits its share;
  // otherwise the same through three more external sorts.
  const bool in_memory = nv * 4 <= map_budget;
  // 1. Every vertex's key, sorted.
  ExternalSortOptions so;
  so.memory_budget = sort_budget;
  so.tmpdir = tmpdir;
  ExternalSorter<WeldKey> sorter(so);
  bool any_values = false;
  {
    InputStream& in = vin.stream();
    WeldKey key{};
    double pos[3];
    PropertyValues values;
    uint64_t offset = 0;
    for (uint64_t i = 0; i < nv; ++i) {
      PSQ_RETURN_IF_ERROR(in.read_exact(pos, 24));
      PSQ_RETURN_IF_ERROR(get_values(in, &values));
      for (int k = 0; k < 3; ++k) key.p[k] = weld_bits(pos[k]);
      key.h = positions_only ? 0 : values_hash(values);
      key.offset = offset;
      key.index = static_cast<uint32_t>(i);
      PSQ_RETURN_IF_ERROR(sorter.add(key));
      offset += 24 + 4 + 8 * values.size();
      any_values = any_values || !values.empty();
    }
  }
  PSQ_RETURN_IF_ERROR(sorter.finish());
  // 2. Each vertex's class: the first vertex in file order identical to it
  // (map[i] in memory, Member records otherwise).
  std::vector<uint32_t> map(in_memory ? nv : 0);
  ExternalSorter<Member> members(so);
  auto assign = [&](uint32_t index, uint32_t rep) -> Status {
    if (in_memory) {
      map[index] = rep;
      return Status();
    }
    return members.add(Member{rep, index});
  };
  const bool compare = !positions_only && any_values;
  const uint64_t map_bytes = in_memory ? nv * 4 : 0;
  if (compare && vin.size() <= map_budget - map_bytes) {
    bool loaded = false;
    PSQ_RETURN_IF_ERROR(vin.load(map_budget - map_bytes, &loaded));
  }
  {
    // The distinct vertices of the current key; more than one only when
    // different values share a hash.
    struct Rep {
      uint32_t index;
      uint64_t offset;
      bool read;
      PropertyValues values;
    };
    std::vector<Rep> reps;
    WeldKey prev{}, key{};
    PropertyValues values;
    for (bool first = true;; first = false) {
      bool done = false;
      PSQ_RETURN_IF_ERROR(sorter.next(&key, &done));
      if (done) break;
      if (first || !key.same_class(prev)) {
        reps.clear();
        reps.push_back(Rep{key.index, key.offset, false, {}});
        PSQ_RETURN_IF_ERROR(assign(key.index, key.index));
        prev = key;
        continue;
      }
      if (!compare) {
        PSQ_RETURN_IF_ERROR(assign(key.index, reps[0].index));
        continue;
      }
      PSQ_RETURN_IF_ERROR(get_values_at(vin, key.offset + 24, &values));
      bool found = false;
      for (Rep& r : reps) {
        if (!r.read) {
          PSQ_RETURN_IF_ERROR(get_values_at(vin, r.offset + 24, &r.values));
          r.read = true;
        }
        if (same_values(r.values, values)) {
          PSQ_RETURN_IF_ERROR(assign(key.index, r.index));
          found = true;
          break;
        }
      }
      if (!found) {
        reps.push_back(Rep{key.index, key.offset, true, values});
        PSQ_RETURN_IF_ERROR(assign(key.index, key.index));
      }
    }
  }
  stats->sort_runs = sorter.runs();
  sorter = ExternalSorter<WeldKey>(so);  // release its buffers
  // External: classes in the order of their first vertex give the welded
  // indices (a class's first vertex sorts first in it).
  ExternalSorter<NewIndex> new_index(so);
  if (!in_memory) {
    PSQ_RETURN_IF_ERROR(members.finish());
    uint32_t next_id = 0, rep = 0;
    for (bool first = true;; first = false) {
      Member m{};
      bool done = false;
      PSQ_RETURN_IF_ERROR(members.next(&m, &done));
      if (done) break;
      if (first || m.rep != rep) {
        rep = m.rep;
        ++next_id;
      }
      PSQ_RETURN_IF_ERROR(new_index.add(NewIndex{m.index, next_id - 1, m.index == m.rep ? 1u : 0u}));
    }
    members = ExternalSorter<Member>(so);
    PSQ_RETURN_IF_ERROR(new_index.finish());
  }
  // 3. The first vertex of each class, in file order. In memory, map
  // becomes the new index (a class's first vertex comes before its
  // others); externally the new indices go to a spool in input order.
  PSQ_RETURN_IF_ERROR(vout->create(tmpdir));
  PSQ_RETURN_IF_ERROR(vin.rewind());
  SpoolFile ids;
  if (!in_memory) PSQ_RETURN_IF_ERROR(ids.create(tmpdir));
  uint64_t kept = 0;
  {
    InputStream& in = vin.stream();
    double pos[3];
    PropertyValues values;
    for (uint64_t i = 0; i < nv; ++i) {
      PSQ_RETURN_IF_ERROR(in.read_exact(pos, 24));
      PSQ_RETURN_IF_ERROR(get_values(in, &values));
      bool first;
      if (in_memory) {
        first = map[i] == i;
        map[i] = first ? static_cast<uint32_t>(kept) : map[map[i]];
      } else {
        NewIndex n{};
        bool done = false;
        PSQ_RETURN_IF_ERROR(new_index.next(&n, &done));
        if (done || n.index != i) return Status(ErrorCode::kInternal, "weld: vertex classes out of step");
        first = n.first != 0;
        PSQ_RETURN_IF_ERROR(ids.write(&n.id, 4));
      }
      if (first) {
        ++kept;
        PSQ_RETURN_IF_ERROR(vout->write(pos, 24));
        PSQ_RETURN_IF_ERROR(put_values(*vout, values));
      }
    }
  }
  new_index = ExternalSorter<NewIndex>(so);
  // External: each corner's welded index, by sorting the corners by input
  // vertex, reading the new indices in step, and sorting back.
  ExternalSorter<Corner, ByCorner> welded(so);
  if (!in_memory) {
    ExternalSorter<Corner, ByVertex> corners(so);
    InputStream& in = tin.stream();
    uint32_t idx[3];
    PropertyValues values;
    for (uint64_t t = 0; t < nt; ++t) {
      PSQ_RETURN_IF_ERROR(in.read_exact(idx, 12));
      PSQ_RETURN_IF_ERROR(get_values(in, &values));
      for (int k = 0; k < 3; ++k) {
        if (idx[k] >= nv) return bad_corner(t, idx[k], nv);
        PSQ_RETURN_IF_ERROR(corners.add(Corner{3 * t + static_cast<uint64_t>(k), idx[k], 0}));
      }
    }
    PSQ_RETURN_IF_ERROR(corners.finish());
    PSQ_RETURN_IF_ERROR(ids.rewind());
    InputStream& id_in = ids.stream();
    uint64_t at = 0;  // input vertices whose new index was read
    uint32_t id = 0;
    for (;;) {
      Corner c{};
      bool done = false;
      PSQ_RETURN_IF_ERROR(corners.next(&c, &done));
      if (done) break;
      while (at <= c.vertex) {
        PSQ_RETURN_IF_ERROR(id_in.read_exact(&id, 4));
        ++at;
      }
      c.vertex = id;
      PSQ_RETURN_IF_ERROR(welded.add(c));
    }
    PSQ_RETURN_IF_ERROR(welded.finish());
    PSQ_RETURN_IF_ERROR(tin.rewind());
  }
  // 4. The triangles renumbered; those with two corners in one vertex go.
  PSQ_RETURN_IF_ERROR(tout->create(tmpdir));
  uint64_t triangles = 0, dropped = 0;
  {
    InputStream& in = tin.stream();
    uint32_t idx[3];
    PropertyValues values;
    for (uint64_t t = 0; t < nt; ++t) {
      PSQ_RETURN_IF_ERROR(in.read_exact(idx, 12));
      PSQ_RETURN_IF_ERROR(get_values(in, &values));
      // A triangle degenerate in the input goes on for the converter to
      // drop and count with its own; only welding's are counted here.
      const bool was_degenerate = degenerate(idx);
      for (int k = 0; k < 3; ++k) {
        if (in_memory) {
          if (idx[k] >= nv) return bad_corner(t, idx[k], nv);
          idx[k] = map[idx[k]];
        } else {
          Corner c{};
          bool done = false;
          PSQ_RETURN_IF_ERROR(welded.next(&c, &done));
          if (done || c.at != 3 * t + static_cast<uint64_t>(k)) {
            return Status(ErrorCode::kInternal, "weld: corners out of step");
          }
          idx[k] = c.vertex;
        }
      }
      if (!was_degenerate && degenerate(idx)) {
        ++dropped;
        continue;
      }
      PSQ_RETURN_IF_ERROR(tout->write(idx, 12));
      PSQ_RETURN_IF_ERROR(put_values(*tout, values));
      ++triangles;
    }
  }
  PSQ_RETURN_IF_ERROR(vout->rewind());
  PSQ_RETURN_IF_ERROR(tout->rewind());
  stats->vertices = kept;
  stats->triangles = triangles;
  stats->merged = nv - kept;
  stats->dropped = dropped;
  stats->external = !in_memory;
  return Status();
}

}  // namespace psq::detail
