// SPDX-License-Identifier: Apache-2.0
// Welding a spooled mesh (build_sequence() with BuildOptions::weld), and the
// cheap estimate of how much a mesh would weld. See weld.cpp.
#ifndef PSQ_SRC_WELD_H_
#define PSQ_SRC_WELD_H_

#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include "psq/io.h"
#include "psq/status.h"

namespace psq::detail {

// The bits a value is welded by: +0.0 and -0.0 are one value (the same
// point; a quantizer maps both to the same cell), every other value is its
// bit pattern (a NaN equals only the same NaN).
inline uint64_t weld_bits(double d) {
  if (d == 0.0) return 0;
  uint64_t u;
  std::memcpy(&u, &d, 8);
  return u;
}

// Estimates the share of a stream's vertices whose position repeats an
// earlier vertex's, from the positions whose hash falls in one sixteenth of
// the hash space (so all copies of a position are sampled, or none), kept
// in a table of at most kSlots / 2 entries; sampling stops when it is full.
// Memory: kSlots * 8 bytes, allocated at the first sampled vertex.
class DuplicateSampler {
 public:
  static constexpr size_t kSlots = size_t{1} << 17;
  void add(const double position[3]);
  // The estimated share in [0, 1], or -1 when fewer than 256 vertices were
  // sampled (too few to tell).
  double duplicate_share() const;

 private:
  // hash | 1; 0 is an empty slot. From calloc: pages of zeros that cost
  // nothing until a sample lands in them (a small mesh touches few).
  struct Free {
    void operator()(uint64_t* p) const { std::free(p); }
  };
  std::unique_ptr<uint64_t[], Free> table_;
  size_t used_ = 0;
  uint64_t sampled_ = 0, duplicates_ = 0;
  bool full_ = false;
};

struct WeldStats {
  uint64_t vertices = 0;   // after welding
  uint64_t triangles = 0;  // after dropping the degenerate ones
  uint64_t merged = 0;     // vertices merged into another: input vertices - vertices
  uint64_t dropped = 0;    // triangles with two corners welded into one vertex
  uint64_t sort_runs = 0;  // runs the external sort spilled to disk (0: it fit in memory)
  bool external = false;   // the map did not fit: renumbered through external sorts
};

// Reads `nv` vertex and `nt` triangle records (spool_records.h) from `vin`
// and `tin` (rewound) and writes the welded mesh to `vout` and `tout`
// (created here, rewound on success): vertices whose positions (and, unless
// `positions_only`, property values) are identical by weld_bits() become
// the first of them in file order, which keeps its values; the vertices
// keep their relative file order; triangles are renumbered, and dropped
// when two of their corners became one vertex. Memory: the external sort of
// 48-byte keys within `sort_budget`, and a map of 4 bytes per input vertex
// within `map_budget`; when the map does not fit, three more external
// sorts (of the classes' members, the new indices and the corners) within
// `sort_budget` do its work, with temporary files instead. Errors:
// kBadIndex (a triangle corner past the vertices), kIo and kTruncated
// from the files.
Status weld_spools(SpoolFile& vin, uint64_t nv, SpoolFile& tin, uint64_t nt, bool positions_only,
                   uint64_t sort_budget, uint64_t map_budget, const std::string& tmpdir, SpoolFile* vout,
                   SpoolFile* tout, WeldStats* stats);

}  // namespace psq::detail

#endif  // PSQ_SRC_WELD_H_
