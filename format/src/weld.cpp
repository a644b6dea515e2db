// SPDX-License-Identifier: Apache-2.0
// Welding identical vertices of a spooled mesh before its processing
// sequence is built (weld.h). A triangle soup repeats each vertex once per
// triangle; the processing sequence (Isenburg, Lindstrom, Gumhold and
// Snoeyink 2003, section 3) then has no shared edges to code, and every
// triangle is its own component. Draco's encoder merges equal positions by
// default for the same reason. The classes of identical vertices are found
// with the external sort (psq/external_sort.h, as the spatial sort of
// sequence_builder.cpp), so that memory stays within the budget: the only
// per-vertex array is the map from input to welded index (4 bytes a vertex,
// like the sort path's rank array).
#include "weld.h"

#include <algorithm>

#include "psq/external_sort.h"
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
  if (table_.empty()) table_.assign(kSlots, 0);
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

Status weld_spools(SpoolFile& vin, uint64_t nv, SpoolFile& tin, uint64_t nt, bool positions_only,
                   uint64_t sort_budget, uint64_t map_budget, const std::string& tmpdir, SpoolFile* vout,
                   SpoolFile* tout, WeldStats* stats) {
  if (nv * 4 > map_budget) {
    return Status(ErrorCode::kLimit, "the weld map (4 bytes per vertex) does not fit --memory");
  }
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
  // 2. map[i]: the first vertex in file order identical to vertex i.
  std::vector<uint32_t> map(nv);
  const bool compare = !positions_only && any_values;
  if (compare && vin.size() <= map_budget - nv * 4) {
    bool loaded = false;
    PSQ_RETURN_IF_ERROR(vin.load(map_budget - nv * 4, &loaded));
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
        map[key.index] = key.index;
        prev = key;
        continue;
      }
      if (!compare) {
        map[key.index] = reps[0].index;
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
          map[key.index] = r.index;
          found = true;
          break;
        }
      }
      if (!found) {
        reps.push_back(Rep{key.index, key.offset, true, values});
        map[key.index] = key.index;
      }
    }
  }
  stats->sort_runs = sorter.runs();
  sorter = ExternalSorter<WeldKey>(so);  // release its buffers
  // 3. The first vertex of each class, in file order; map becomes the new
  // index (a class's first vertex comes before its others).
  PSQ_RETURN_IF_ERROR(vout->create(tmpdir));
  PSQ_RETURN_IF_ERROR(vin.rewind());
  uint64_t kept = 0;
  {
    InputStream& in = vin.stream();
    double pos[3];
    PropertyValues values;
    for (uint64_t i = 0; i < nv; ++i) {
      PSQ_RETURN_IF_ERROR(in.read_exact(pos, 24));
      PSQ_RETURN_IF_ERROR(get_values(in, &values));
      if (map[i] == i) {
        map[i] = static_cast<uint32_t>(kept++);
        PSQ_RETURN_IF_ERROR(vout->write(pos, 24));
        PSQ_RETURN_IF_ERROR(put_values(*vout, values));
      } else {
        map[i] = map[map[i]];
      }
    }
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
      const bool was_degenerate = idx[0] == idx[1] || idx[1] == idx[2] || idx[2] == idx[0];
      for (int k = 0; k < 3; ++k) {
        if (idx[k] >= nv) {
          return Status(ErrorCode::kBadIndex, "triangle " + std::to_string(t) + " uses vertex " +
                                                   std::to_string(idx[k]) + " of " + std::to_string(nv));
        }
        idx[k] = map[idx[k]];
      }
      if (!was_degenerate && (idx[0] == idx[1] || idx[1] == idx[2] || idx[2] == idx[0])) {
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
  return Status();
}

}  // namespace psq::detail
