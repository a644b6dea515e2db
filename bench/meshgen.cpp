// psq-meshgen: generates large closed triangle meshes to try psq at scale.
//
// The mesh is the boundary of a "foam ball": the solid where |gyroid(p)| >
// theta(p), clipped by a sphere. The gyroid's two labyrinths are networks
// with about three handles per period cell; theta varies slowly in space (a
// few random plane waves), so that where it is low the labyrinths are thick
// tubes (handles) and where it is high they pinch off into separate blobs
// (components). The field is fixed by --seed; --res only samples it more
// finely, so the topology settles once the grid resolves the field and the
// triangle count then grows as res^2.
//
// The surface is extracted by marching tetrahedra on the Kuhn (Freudenthal)
// split of every grid cube into 6 tetrahedra around its main diagonal. That
// split is the same in every cube, so the tetrahedra of neighbouring cubes
// share faces and every lattice edge p -> p + e (e a nonzero 0/1 vector: 3
// axes, 3 face diagonals, 1 body diagonal) carries at most one vertex, shared
// by every tetrahedron around it: the surface is closed and manifold without
// any ambiguity table. A grid point is inside when f < 0, so no vertex lies
// exactly on a grid point and every triangle has three distinct vertices.
//
// Memory is bounded by two z-layers of the grid, never by the mesh: a sweep
// over z keeps the sign bits of the two layers around the current slab of
// cubes and, per slab, one crossing bitmask and one base vertex id per
// (row, 64-point word, edge direction); a vertex id is then a base plus a
// popcount. Vertices are numbered in sweep order. PLY wants both counts in
// the header and every vertex before the first face, so the sweep runs three
// times (count, vertices, triangles): recomputing the field is cheaper than
// spooling, and the output can stream to a pipe.
//
// --order shuffled permutes vertices and triangles with keyed bijections on
// [0, n) (a Feistel network with cycle walking, O(1) memory) and puts them in
// place with the external sorter under --memory.
#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include "psq/external_sort.h"
#include "psq/io.h"
#include "psq/status.h"

namespace psq {
namespace {

constexpr int kExitOk = 0;
constexpr int kExitFailure = 1;
constexpr int kExitUsage = 2;

// Above this the grid layers alone take gigabytes and the vertex count
// overflows PLY's int indices long before.
constexpr uint32_t kMaxRes = 8192;
constexpr uint32_t kMinRes = 4;

const char kHelp[] =
    "Usage: psq-meshgen [--triangles N | --res R] [OPTIONS] [-o OUT.ply]\n"
    "\n"
    "Generates a closed, consistently oriented (outward), manifold triangle\n"
    "mesh: the surface of a 'foam ball', a gyroid foam of varying thickness\n"
    "clipped by a sphere, with hundreds of handles and many components. It is\n"
    "written as binary little-endian PLY (float x, y, z; list uchar int\n"
    "vertex_indices), streaming: memory is bounded by two layers of the grid,\n"
    "not by the mesh, so meshes of hundreds of millions of triangles work.\n"
    "The same --seed gives the same field; --res samples it more finely.\n"
    "\n"
    "Options:\n"
    "  --triangles N    about N triangles (within a few percent); suffixes\n"
    "                   k, M, G are powers of 1000 (default 200k)\n"
    "  --res R          grid resolution R (cubes per axis, 4..8192) instead\n"
    "  --seed S         field seed (default 1)\n"
    "  --order ORDER    coherent (default): vertices and triangles in sweep\n"
    "                   order; shuffled: both randomly permuted (by the seed)\n"
    "  --memory SIZE    sort budget for --order shuffled (default 256M;\n"
    "                   suffixes K, M, G are powers of 1024)\n"
    "  --tmpdir DIR     directory for the shuffle's temporary files\n"
    "                   (default $TMPDIR, else /tmp)\n"
    "  -o, --output OUT output file (default '-': standard output)\n"
    "  -f, --force      overwrite OUT if it exists\n"
    "  -q, --quiet      print no summary line\n"
    "  -h, --help       show this help\n"
    "\n"
    "A summary line (vertices, triangles, resolution, time) goes to stderr.\n";

// ------------------------------------------------------------------ random

uint64_t mix64(uint64_t z) {
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

// SplitMix64: tiny, and the same sequence on every platform (unlike the
// standard library's distributions), so a seed means one mesh everywhere.
class SplitMix {
 public:
  explicit SplitMix(uint64_t seed) : state_(seed) {}
  uint64_t next() { return mix64(state_ += 0x9e3779b97f4a7c15ULL); }
  double uniform() { return static_cast<double>(next() >> 11) * 0x1.0p-53; }

 private:
  uint64_t state_;
};

// A pseudo-random bijection on [0, n) in O(1) memory: a balanced Feistel
// network on the smallest even number of bits covering n, with cycle walking
// (re-encrypting until the value falls below n). The domain is at most 4n,
// so a walk takes 4 steps at worst on average.
class Permutation {
 public:
  Permutation(uint64_t n, uint64_t key) : n_(n) {
    int bits = 2;
    while ((uint64_t{1} << bits) < n) bits += 2;
    half_ = bits / 2;
    mask_ = (uint64_t{1} << half_) - 1;
    SplitMix rng(key);
    for (uint64_t& k : keys_) k = rng.next();
  }
  uint64_t operator()(uint64_t x) const {
    if (n_ <= 1) return x;
    do {
      x = encrypt(x);
    } while (x >= n_);
    return x;
  }

 private:
  uint64_t encrypt(uint64_t x) const {
    uint64_t l = x >> half_, r = x & mask_;
    for (uint64_t k : keys_) {
      uint64_t t = l ^ (mix64(r ^ k) & mask_);
      l = r;
      r = t;
    }
    return (l << half_) | r;
  }

  uint64_t n_;
  int half_ = 1;
  uint64_t mask_ = 1;
  std::array<uint64_t, 4> keys_{};
};

// ------------------------------------------------------------------- field

// The scalar field, separable along the axes so that a grid point costs a
// few multiply-adds on per-axis tables instead of trigonometry (at res 2000
// the grid has 8e9 points; the mesh only 1e8 triangles).
struct Field {
  static constexpr int kWaves = 4;
  double gyroid_freq = 0;        // radians per unit: pi * periods across [-1, 1]
  double gyroid_phase[3] = {};   // x, y, z
  double wave[kWaves][3] = {};   // wave vectors of theta's plane waves
  double wave_phase[kWaves] = {};
  double wave_amp = 0;           // per wave
  double theta0 = 0;
  double radius = 0;
  double sphere_scale = 0;  // makes the sphere term's slope like the foam's

  explicit Field(uint64_t seed) {
    // Parameters chosen by measuring psq info: at 200K triangles the ball
    // has hundreds of handles and about a hundred components (see
    // meshgen_README.md).
    SplitMix rng(mix64(seed ^ 0x5eed0f0a3ba11ULL));
    const double pi = 3.14159265358979323846;
    gyroid_freq = pi * 5.0;
    for (double& p : gyroid_phase) p = 2 * pi * rng.uniform();
    for (int m = 0; m < kWaves; ++m) {
      // Uniform direction on the sphere, about 1.5 periods across the ball.
      double z = 2 * rng.uniform() - 1, a = 2 * pi * rng.uniform();
      double s = std::sqrt(1 - z * z), k = pi * 1.6;
      wave[m][0] = k * s * std::cos(a);
      wave[m][1] = k * s * std::sin(a);
      wave[m][2] = k * z;
      wave_phase[m] = 2 * pi * rng.uniform();
    }
    theta0 = 0.85;
    wave_amp = 0.45 / std::sqrt(static_cast<double>(kWaves));
    radius = 0.92;
    sphere_scale = gyroid_freq / (2 * radius);
  }
};

// --------------------------------------------------------- tetrahedra table

// Cube corners are numbered x + 2y + 4z. An edge of the Kuhn split runs from
// corner u to corner u | e with u & e == 0 and e in 1..7: 19 edges per cube.
struct CubeEdge {
  uint8_t dx, dy;  // origin point of the edge relative to the cube
  bool previous;   // an in-layer edge of the slab's lower layer: owned by
                   // the previous slab's record
  uint8_t dir;     // e - 1: 0 x, 1 y, 2 xy, 3 z, 4 xz, 5 yz, 6 xyz
};

struct CubeTable {
  std::array<CubeEdge, 19> edges{};
  // Per inside-corner configuration (bit c set: corner c inside): up to 12
  // triangles as edge codes, outward (counter-clockwise seen from outside).
  std::array<std::array<uint8_t, 36>, 256> triangles{};
  std::array<uint8_t, 256> count{};
};

CubeTable make_cube_table() {
  CubeTable table;
  int code_of[8][8];
  int n = 0;
  for (int u = 0; u < 8; ++u) {
    for (int e = 1; e < 8; ++e) {
      code_of[u][e] = -1;
      if ((u & e) != 0) continue;
      code_of[u][e] = n;
      table.edges[n] = CubeEdge{static_cast<uint8_t>(u & 1), static_cast<uint8_t>((u >> 1) & 1),
                                (u & 4) == 0 && e < 4, static_cast<uint8_t>(e - 1)};
      ++n;
    }
  }
  auto edge = [&](int a, int b) {
    int u = std::min(a, b), v = std::max(a, b);  // along the chain u is a subset of v
    return static_cast<uint8_t>(code_of[u][u ^ v]);
  };

  // The 6 tetrahedra 0 -> e_p0 -> e_p0 + e_p1 -> 7, made positively oriented.
  std::vector<std::array<int, 4>> tets;
  const int axes[3] = {1, 2, 4};
  int perm[3] = {0, 1, 2};
  do {
    std::array<int, 4> t = {0, axes[perm[0]], axes[perm[0]] | axes[perm[1]], 7};
    auto coord = [](int c, int k) { return static_cast<double>((c >> k) & 1); };
    double m[3][3];
    for (int r = 0; r < 3; ++r) {
      for (int k = 0; k < 3; ++k) m[r][k] = coord(t[r + 1], k) - coord(t[0], k);
    }
    double det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) -
                 m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
                 m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
    if (det < 0) std::swap(t[1], t[2]);
    tets.push_back(t);
  } while (std::next_permutation(perm, perm + 3));

  // The even permutations of 4 elements: applied to a positive tetrahedron
  // they keep it positive, so one rule per case orients every triangle.
  std::vector<std::array<int, 4>> even;
  std::array<int, 4> p = {0, 1, 2, 3};
  do {
    int inversions = 0;
    for (int i = 0; i < 4; ++i) {
      for (int j = i + 1; j < 4; ++j) inversions += p[i] > p[j];
    }
    if (inversions % 2 == 0) even.push_back(p);
  } while (std::next_permutation(p.begin(), p.end()));

  for (int config = 0; config < 256; ++config) {
    int k = 0;
    auto emit = [&](uint8_t a, uint8_t b, uint8_t c) {
      table.triangles[config][k++] = a;
      table.triangles[config][k++] = b;
      table.triangles[config][k++] = c;
    };
    for (const auto& t : tets) {
      bool in[4];
      int inside = 0;
      for (int i = 0; i < 4; ++i) inside += in[i] = (config >> t[i]) & 1;
      if (inside == 0 || inside == 4) continue;
      for (const auto& s : even) {
        int a = t[s[0]], b = t[s[1]], c = t[s[2]], d = t[s[3]];
        // For a positive (a, b, c, d) the face (b, c, d) faces away from a;
        // the normal must point from inside to outside.
        if (inside == 1 && in[s[0]]) {
          emit(edge(a, b), edge(a, c), edge(a, d));
        } else if (inside == 3 && !in[s[0]]) {
          emit(edge(a, b), edge(a, d), edge(a, c));
        } else if (inside == 2 && in[s[0]] && in[s[1]]) {
          emit(edge(a, c), edge(a, d), edge(b, d));
          emit(edge(a, c), edge(b, d), edge(b, c));
        } else {
          continue;
        }
        break;
      }
    }
    table.count[config] = static_cast<uint8_t>(k / 3);
  }
  return table;
}

// -------------------------------------------------------------------- sweep

// Receives the mesh of a sweep in order, in batches.
class MeshOut {
 public:
  virtual ~MeshOut() = default;
  // `xyz` holds 3n floats; vertices are numbered in call order from 0.
  virtual Status vertices(const float* xyz, size_t n) = 0;
  // `abc` holds 3n vertex ids.
  virtual Status triangles(const uint32_t* abc, size_t n) = 0;
};

enum class Pass { kCount, kVertices, kTriangles };

struct Counts {
  uint64_t vertices = 0;
  uint64_t triangles = 0;
};

class Grid {
 public:
  Grid(const Field& field, uint32_t res, const CubeTable& table)
      : field_(field), res_(res), table_(table) {
    const uint32_t points = res + 1;
    h_ = 2.0 / res;
    words_ = (points + 63) / 64;
    bit_words_ = words_ + 1;  // a zero word so that "bit i + 1" never reads past
    coord_.resize(points);
    for (uint32_t i = 0; i < points; ++i) coord_[i] = coordinate(i);

    // Per-axis tables, computed in double once.
    auto fill = [&](int axis, std::vector<float>* s, std::vector<float>* c) {
      s->resize(points);
      c->resize(points);
      for (uint32_t i = 0; i < points; ++i) {
        double a = field.gyroid_freq * coord_[i] + field.gyroid_phase[axis];
        (*s)[i] = static_cast<float>(std::sin(a));
        (*c)[i] = static_cast<float>(std::cos(a));
      }
    };
    fill(0, &sx_, &cx_);
    fill(1, &sy_, &cy_);
    fill(2, &sz_, &cz_);
    xx_.resize(points);
    for (uint32_t i = 0; i < points; ++i) {
      xx_[i] = static_cast<float>(field.sphere_scale * coord_[i] * coord_[i]);
    }
    for (int m = 0; m < Field::kWaves; ++m) {
      wx_re_[m].resize(points);
      wx_im_[m].resize(points);
      for (uint32_t i = 0; i < points; ++i) {
        double a = field.wave[m][0] * coord_[i];
        wx_re_[m][i] = static_cast<float>(std::cos(a));
        wx_im_[m][i] = static_cast<float>(std::sin(a));
      }
    }
    row_.resize(points);
    // Only points within this distance of the centre can be, or neighbour,
    // an inside point (the sphere term is positive beyond the radius, and
    // a lattice edge is at most sqrt(3) h long).
    reach_ = field.radius + 2 * h_;
  }

  // Bytes the sweep's arrays take for `pass` (for the summary).
  uint64_t memory(Pass pass) const {
    uint64_t points = uint64_t{res_ + 1} * (res_ + 1);
    uint64_t rows = res_ + 2;
    uint64_t m = 2 * rows * bit_words_ * 8 + 2 * (res_ + 1) * uint64_t{words_} * 7 * (8 + 4);
    if (pass == Pass::kVertices) m += 2 * points * 4;
    return m;
  }

  Status sweep(Pass pass, MeshOut* out, Counts* counts) {
    const uint32_t points = res_ + 1;
    const size_t layer_bits = size_t{res_ + 2} * bit_words_;
    const size_t record = size_t{points} * words_ * 7;
    for (auto& b : bits_) b.assign(layer_bits, 0);
    for (auto& c : cross_) c.assign(record, 0);
    for (auto& b : base_) b.assign(pass == Pass::kTriangles ? record : 0, 0);
    for (auto& v : values_) v.assign(pass == Pass::kVertices ? size_t{points} * points : 0, 0.0f);
    out_ = out;
    pass_ = pass;
    next_id_ = 0;
    vbuf_.clear();
    tbuf_.clear();
    *counts = Counts();

    // Layer 0 lies on the grid's boundary, outside the sphere: its in-layer
    // edges never cross, so "slab -1" has no vertices and its record is the
    // zeros just assigned.
    eval_layer(0, 0);
    int lo = 0;
    for (uint32_t s = 0; s < res_; ++s) {
      const int hi = 1 - lo;
      eval_layer(s + 1, hi);
      crossings(lo, hi, hi);
      uint64_t slab_vertices = 0;
      for (uint64_t w : cross_[hi]) slab_vertices += static_cast<uint64_t>(__builtin_popcountll(w));
      counts->vertices += slab_vertices;
      if (pass == Pass::kVertices) {
        PSQ_RETURN_IF_ERROR(slab_vertices_out(s, lo, hi));
      } else if (pass == Pass::kTriangles) {
        number_vertices(hi);
      }
      PSQ_RETURN_IF_ERROR(cubes(lo, hi, counts));
      lo = hi;
    }
    if (pass == Pass::kVertices && !vbuf_.empty()) {
      PSQ_RETURN_IF_ERROR(out_->vertices(vbuf_.data(), vbuf_.size() / 3));
    }
    if (pass == Pass::kTriangles && !tbuf_.empty()) {
      PSQ_RETURN_IF_ERROR(out_->triangles(tbuf_.data(), tbuf_.size() / 3));
    }
    return Status();
  }

 private:
  static constexpr size_t kBatch = 3 * 16384;

  double coordinate(uint32_t i) const { return -1.0 + h_ * i; }

  // Evaluates z-layer k into bits_[slot] (and values_[slot] when kept).
  // The same code computes every pass, so the three sweeps see the same
  // signs bit for bit.
  void eval_layer(uint32_t k, int slot) {
    const uint32_t points = res_ + 1;
    uint64_t* bits = bits_[slot].data();
    std::fill(bits_[slot].begin(), bits_[slot].end(), 0);
    float* values = values_[slot].empty() ? nullptr : values_[slot].data();
    const double z = coord_[k];
    const double reach2 = reach_ * reach_;
    const float R2 = static_cast<float>(field_.sphere_scale * field_.radius * field_.radius);
    const float theta0 = static_cast<float>(field_.theta0);
    for (uint32_t j = 0; j < points; ++j) {
      float* row_values = values ? values + size_t{j} * points : nullptr;
      const double y = coord_[j];
      const double yz2 = y * y + z * z;
      if (yz2 >= reach2) {
        if (row_values) std::fill(row_values, row_values + points, 1.0f);
        continue;
      }
      const double half = std::sqrt(reach2 - yz2);
      const uint32_t i0 = static_cast<uint32_t>(std::max(0.0, std::floor((1.0 - half) / h_)));
      const uint32_t i1 = static_cast<uint32_t>(std::min<double>(res_, std::ceil((1.0 + half) / h_)));

      // Row constants: gyroid = sx*cy + sy*cz + sz*cx = sx*A + cx*C + B; each
      // wave sin(kx x + ky y + kz z + phi) = Im(W * e^{i kx x}).
      const float A = cy_[j], B = sy_[j] * cz_[k], C = sz_[k];
      const float yz = static_cast<float>(field_.sphere_scale * yz2) - R2;
      float w_re[Field::kWaves], w_im[Field::kWaves];
      for (int m = 0; m < Field::kWaves; ++m) {
        double a = field_.wave[m][1] * y + field_.wave[m][2] * z + field_.wave_phase[m];
        w_re[m] = static_cast<float>(field_.wave_amp * std::cos(a));
        w_im[m] = static_cast<float>(field_.wave_amp * std::sin(a));
      }
      float* f = row_.data();
      const float* sx = sx_.data();
      const float* cx = cx_.data();
      const float* xx = xx_.data();
      const float *r0 = wx_re_[0].data(), *r1 = wx_re_[1].data(), *r2 = wx_re_[2].data(),
                  *r3 = wx_re_[3].data();
      const float *m0 = wx_im_[0].data(), *m1 = wx_im_[1].data(), *m2 = wx_im_[2].data(),
                  *m3 = wx_im_[3].data();
      static_assert(Field::kWaves == 4, "the loop below unrolls the waves");
      for (uint32_t i = i0; i <= i1; ++i) {
        float g = sx[i] * A + cx[i] * C + B;
        float theta = theta0 + (w_re[0] * m0[i] + w_im[0] * r0[i]) + (w_re[1] * m1[i] + w_im[1] * r1[i]) +
                      (w_re[2] * m2[i] + w_im[2] * r2[i]) + (w_re[3] * m3[i] + w_im[3] * r3[i]);
        float foam = theta - std::fabs(g);
        float sphere = xx[i] + yz;
        f[i] = foam > sphere ? foam : sphere;
      }

      uint64_t* row_bits = bits + size_t{j} * bit_words_;
      for (uint32_t w = i0 / 64; w <= i1 / 64; ++w) {
        const uint32_t begin = std::max(i0, w * 64), end = std::min(i1 + 1, w * 64 + 64);
        uint64_t word = 0;
        for (uint32_t i = begin; i < end; ++i) word |= static_cast<uint64_t>(f[i] < 0.0f) << (i & 63);
        row_bits[w] = word;
      }
      if (row_values) {
        std::fill(row_values, row_values + i0, 1.0f);
        std::copy(f + i0, f + i1 + 1, row_values + i0);
        std::fill(row_values + i1 + 1, row_values + points, 1.0f);
      }
    }
  }

  // Bits i + 1 of a row's word w, at position i.
  static uint64_t shifted(const uint64_t* row, uint32_t w) { return (row[w] >> 1) | (row[w + 1] << 63); }

  // The crossing masks of the slab between layers lo and hi into cross_[rec]:
  // in-layer edges of layer hi (x, y, xy) and edges from lo to hi (z, xz, yz,
  // xyz).
  void crossings(int lo, int hi, int rec) {
    const uint32_t points = res_ + 1;
    const uint64_t* b0 = bits_[lo].data();
    const uint64_t* b1 = bits_[hi].data();
    uint64_t* cross = cross_[rec].data();
    for (uint32_t j = 0; j < points; ++j) {
      const uint64_t* l0 = b0 + size_t{j} * bit_words_;
      const uint64_t* h0 = b1 + size_t{j} * bit_words_;
      const uint64_t* h1 = h0 + bit_words_;  // row j + 1 (the zero row past the last)
      for (uint32_t w = 0; w < words_; ++w) {
        uint64_t* c = cross + (size_t{j} * words_ + w) * 7;
        const uint64_t a = l0[w], p = h0[w], ps = shifted(h0, w), q = h1[w], qs = shifted(h1, w);
        c[0] = p ^ ps;
        c[1] = p ^ q;
        c[2] = p ^ qs;
        c[3] = a ^ p;
        c[4] = a ^ ps;
        c[5] = a ^ q;
        c[6] = a ^ qs;
      }
    }
  }

  void number_vertices(int rec) {
    const uint64_t* cross = cross_[rec].data();
    uint32_t* base = base_[rec].data();
    const size_t n = cross_[rec].size();
    uint32_t id = static_cast<uint32_t>(next_id_);
    for (size_t k = 0; k < n; ++k) {
      base[k] = id;
      id += static_cast<uint32_t>(__builtin_popcountll(cross[k]));
    }
    next_id_ = id;
  }

  // Positions of the slab's vertices, in id order: row, word, direction, bit.
  Status slab_vertices_out(uint32_t s, int lo, int hi) {
    const uint32_t points = res_ + 1;
    const uint64_t* cross = cross_[hi].data();
    const float* v0 = values_[lo].data();
    const float* v1 = values_[hi].data();
    for (uint32_t j = 0; j < points; ++j) {
      for (uint32_t w = 0; w < words_; ++w) {
        const uint64_t* c = cross + (size_t{j} * words_ + w) * 7;
        for (uint32_t d = 0; d < 7; ++d) {
          for (uint64_t bits = c[d]; bits != 0; bits &= bits - 1) {
            const uint32_t i = w * 64 + static_cast<uint32_t>(__builtin_ctzll(bits));
            const uint32_t e = d + 1;
            // In-layer edges (d < 3) start in layer s + 1, the others in s.
            const uint32_t k = d < 3 ? s + 1 : s;
            const float* from_layer = d < 3 ? v1 : v0;
            const uint32_t i2 = i + (e & 1), j2 = j + ((e >> 1) & 1);
            const float f0 = from_layer[size_t{j} * points + i];
            const float f1 = v1[size_t{j2} * points + i2];
            // Keep vertices off the grid points so that no two coincide.
            double t = static_cast<double>(f0) / (static_cast<double>(f0) - f1);
            t = std::min(std::max(t, 1e-3), 1.0 - 1e-3);
            vbuf_.push_back(static_cast<float>(coordinate(i) + t * h_ * (e & 1)));
            vbuf_.push_back(static_cast<float>(coordinate(j) + t * h_ * ((e >> 1) & 1)));
            vbuf_.push_back(static_cast<float>(coordinate(k) + t * h_ * ((e >> 2) & 1)));
          }
          if (vbuf_.size() >= kBatch) {
            PSQ_RETURN_IF_ERROR(out_->vertices(vbuf_.data(), vbuf_.size() / 3));
            vbuf_.clear();
          }
        }
      }
    }
    return Status();
  }

  uint32_t vertex_id(const CubeEdge& e, uint32_t i, uint32_t j, int lo, int hi) const {
    const int rec = e.previous ? lo : hi;
    const uint32_t x = i + e.dx;
    const size_t k = (size_t{j + e.dy} * words_ + x / 64) * 7 + e.dir;
    const uint64_t below = (uint64_t{1} << (x & 63)) - 1;
    return base_[rec][k] + static_cast<uint32_t>(__builtin_popcountll(cross_[rec][k] & below));
  }

  // Walks the cubes of the slab between layers lo and hi that the surface
  // crosses: counts their triangles, or emits them.
  Status cubes(int lo, int hi, Counts* counts) {
    const uint64_t* b0 = bits_[lo].data();
    const uint64_t* b1 = bits_[hi].data();
    for (uint32_t j = 0; j < res_; ++j) {
      const uint64_t* r00 = b0 + size_t{j} * bit_words_;  // layer lo, row j
      const uint64_t* r01 = r00 + bit_words_;             // layer lo, row j + 1
      const uint64_t* r10 = b1 + size_t{j} * bit_words_;  // layer hi, row j
      const uint64_t* r11 = r10 + bit_words_;
      for (uint32_t w = 0; w < words_; ++w) {
        const uint64_t c0 = r00[w], c1 = shifted(r00, w), c2 = r01[w], c3 = shifted(r01, w);
        const uint64_t c4 = r10[w], c5 = shifted(r10, w), c6 = r11[w], c7 = shifted(r11, w);
        const uint64_t any = c0 | c1 | c2 | c3 | c4 | c5 | c6 | c7;
        const uint64_t all = c0 & c1 & c2 & c3 & c4 & c5 & c6 & c7;
        for (uint64_t mixed = any & ~all; mixed != 0; mixed &= mixed - 1) {
          const int b = __builtin_ctzll(mixed);
          const unsigned config = ((c0 >> b) & 1) | ((c1 >> b) & 1) << 1 | ((c2 >> b) & 1) << 2 |
                                  ((c3 >> b) & 1) << 3 | ((c4 >> b) & 1) << 4 | ((c5 >> b) & 1) << 5 |
                                  ((c6 >> b) & 1) << 6 | ((c7 >> b) & 1) << 7;
          const unsigned n = table_.count[config];
          counts->triangles += n;
          if (pass_ != Pass::kTriangles) continue;
          const uint32_t i = w * 64 + static_cast<uint32_t>(b);
          const uint8_t* t = table_.triangles[config].data();
          for (unsigned k = 0; k < 3 * n; ++k) {
            tbuf_.push_back(vertex_id(table_.edges[t[k]], i, j, lo, hi));
          }
        }
        if (tbuf_.size() >= kBatch) {
          PSQ_RETURN_IF_ERROR(out_->triangles(tbuf_.data(), tbuf_.size() / 3));
          tbuf_.clear();
        }
      }
    }
    return Status();
  }

  const Field& field_;
  const uint32_t res_;
  const CubeTable& table_;
  double h_ = 0;
  double reach_ = 0;
  uint32_t words_ = 0;      // 64-point words per row
  uint32_t bit_words_ = 0;  // words_ + 1
  std::vector<double> coord_;
  std::vector<float> sx_, cx_, sy_, cy_, sz_, cz_, xx_;
  std::vector<float> wx_re_[Field::kWaves], wx_im_[Field::kWaves];
  std::vector<float> row_;

  // Two of each, indexed by slot; the slots swap roles every slab.
  std::vector<uint64_t> bits_[2];    // sign bits per layer: (res + 2) rows
  std::vector<float> values_[2];     // field values per layer (vertex pass)
  std::vector<uint64_t> cross_[2];   // crossing masks per slab record
  std::vector<uint32_t> base_[2];    // first vertex id per mask (triangle pass)

  Pass pass_ = Pass::kCount;
  MeshOut* out_ = nullptr;
  uint64_t next_id_ = 0;
  std::vector<float> vbuf_;
  std::vector<uint32_t> tbuf_;
};

// ------------------------------------------------------------------ output

void put32(uint8_t* p, uint32_t v) {
  p[0] = static_cast<uint8_t>(v);
  p[1] = static_cast<uint8_t>(v >> 8);
  p[2] = static_cast<uint8_t>(v >> 16);
  p[3] = static_cast<uint8_t>(v >> 24);
}

uint32_t float_bits(float f) {
  uint32_t u;
  std::memcpy(&u, &f, 4);
  return u;
}

// Encodes PLY elements into a local buffer: one OutputFile::write per
// batch rather than per element.
class PlyEncoder {
 public:
  explicit PlyEncoder(OutputFile* out) : out_(out) {}

  Status header(uint64_t vertices, uint64_t triangles, const std::string& comment) {
    std::string h = "ply\nformat binary_little_endian 1.0\ncomment " + comment + "\nelement vertex " +
                    std::to_string(vertices) +
                    "\nproperty float x\nproperty float y\nproperty float z\nelement face " +
                    std::to_string(triangles) + "\nproperty list uchar int vertex_indices\nend_header\n";
    return out_->write(h);
  }
  Status vertex(float x, float y, float z) {
    uint8_t* p = reserve(12);
    put32(p, float_bits(x));
    put32(p + 4, float_bits(y));
    put32(p + 8, float_bits(z));
    return flush_if_full();
  }
  Status triangle(uint32_t a, uint32_t b, uint32_t c) {
    uint8_t* p = reserve(13);
    p[0] = 3;
    put32(p + 1, a);
    put32(p + 5, b);
    put32(p + 9, c);
    return flush_if_full();
  }
  Status flush() {
    Status s = out_->write(buffer_, size_);
    size_ = 0;
    return s;
  }

 private:
  static constexpr size_t kSize = size_t{1} << 16;
  uint8_t* reserve(size_t n) {
    uint8_t* p = buffer_ + size_;
    size_ += n;
    return p;
  }
  Status flush_if_full() { return size_ + 16 > kSize ? flush() : Status(); }

  OutputFile* out_;
  uint8_t buffer_[kSize];
  size_t size_ = 0;
};

class CoherentOut : public MeshOut {
 public:
  explicit CoherentOut(PlyEncoder* enc) : enc_(enc) {}
  Status vertices(const float* xyz, size_t n) override {
    for (size_t k = 0; k < n; ++k) PSQ_RETURN_IF_ERROR(enc_->vertex(xyz[3 * k], xyz[3 * k + 1], xyz[3 * k + 2]));
    return Status();
  }
  Status triangles(const uint32_t* abc, size_t n) override {
    for (size_t k = 0; k < n; ++k) PSQ_RETURN_IF_ERROR(enc_->triangle(abc[3 * k], abc[3 * k + 1], abc[3 * k + 2]));
    return Status();
  }

 private:
  PlyEncoder* enc_;
};

// Records for the shuffle: the element's new position first, as the key.
struct VertexRecord {
  uint32_t position;
  float xyz[3];
};
struct TriangleRecord {
  uint32_t position;
  uint32_t index[3];
};
struct ByPosition {
  template <class T>
  bool operator()(const T& a, const T& b) const { return a.position < b.position; }
};

class ShuffleOut : public MeshOut {
 public:
  ShuffleOut(const Permutation* vperm, const Permutation* tperm, uint64_t rotate_key,
             ExternalSorter<VertexRecord, ByPosition>* vsort,
             ExternalSorter<TriangleRecord, ByPosition>* tsort)
      : vperm_(vperm), tperm_(tperm), rotate_key_(rotate_key), vsort_(vsort), tsort_(tsort) {}

  Status vertices(const float* xyz, size_t n) override {
    for (size_t k = 0; k < n; ++k, ++vertex_) {
      VertexRecord r{static_cast<uint32_t>((*vperm_)(vertex_)), {xyz[3 * k], xyz[3 * k + 1], xyz[3 * k + 2]}};
      PSQ_RETURN_IF_ERROR(vsort_->add(r));
    }
    return Status();
  }
  Status triangles(const uint32_t* abc, size_t n) override {
    for (size_t k = 0; k < n; ++k, ++triangle_) {
      // Rotating the corners keeps the orientation and hides which corner
      // the sweep produced first.
      const unsigned rot = static_cast<unsigned>(mix64(triangle_ ^ rotate_key_) % 3);
      TriangleRecord r;
      r.position = static_cast<uint32_t>((*tperm_)(triangle_));
      for (unsigned c = 0; c < 3; ++c) {
        r.index[c] = static_cast<uint32_t>((*vperm_)(abc[3 * k + (c + rot) % 3]));
      }
      PSQ_RETURN_IF_ERROR(tsort_->add(r));
    }
    return Status();
  }

 private:
  const Permutation* vperm_;
  const Permutation* tperm_;
  uint64_t rotate_key_;
  ExternalSorter<VertexRecord, ByPosition>* vsort_;
  ExternalSorter<TriangleRecord, ByPosition>* tsort_;
  uint64_t vertex_ = 0;
  uint64_t triangle_ = 0;
};

// ---------------------------------------------------------------- commands

struct Options {
  uint64_t triangles = 200000;
  uint32_t res = 0;  // 0: from triangles
  uint64_t seed = 1;
  bool shuffled = false;
  uint64_t memory = uint64_t{256} << 20;
  std::string tmpdir;
  std::string output = "-";
  bool force = false;
  bool quiet = false;
};

Counts count(const Field& field, uint32_t res, const CubeTable& table) {
  Grid grid(field, res, table);
  Counts c;
  grid.sweep(Pass::kCount, nullptr, &c);  // counting writes nothing: cannot fail
  return c;
}

// Picks the resolution for about `target` triangles: T grows as res^2 once
// the grid resolves the field, so scale from cheap probes, then correct with
// the count at the chosen resolution (which the writing needs anyway).
uint32_t choose_res(const Field& field, uint64_t target, const CubeTable& table, Counts* at_res) {
  auto scale = [&](uint32_t r, uint64_t t) {
    double est = r * std::sqrt(static_cast<double>(target) / std::max<uint64_t>(t, 1));
    return static_cast<uint32_t>(std::clamp(std::lround(est), long{kMinRes}, long{kMaxRes}));
  };
  uint32_t r = 64;
  Counts c = count(field, r, table);
  for (uint32_t probe_limit : {256u, 512u}) {
    uint32_t next = scale(r, c.triangles);
    if (next <= r * 5 / 4 || r >= probe_limit) break;
    r = std::min(next, probe_limit);
    c = count(field, r, table);
  }
  uint32_t best = r;
  Counts best_counts = c;
  for (int iteration = 0; iteration < 6; ++iteration) {
    uint32_t next = scale(r, c.triangles);
    if (next == r) break;
    r = next;
    c = count(field, r, table);
    auto error = [&](const Counts& x) {
      return std::fabs(static_cast<double>(x.triangles) / static_cast<double>(target) - 1.0);
    };
    if (error(c) < error(best_counts)) {
      best = r;
      best_counts = c;
    }
    if (error(c) < 0.03) break;
  }
  *at_res = best_counts;
  return best;
}

bool parse_count(const std::string& text, uint64_t* value, bool binary) {
  uint64_t n = 0;
  const char* b = text.data();
  const char* e = b + text.size();
  auto r = std::from_chars(b, e, n);
  if (r.ec != std::errc() || r.ptr == b) return false;
  std::string unit(r.ptr, e);
  uint64_t multiplier = 1;
  if (!unit.empty()) {
    char u = static_cast<char>(std::toupper(static_cast<unsigned char>(unit[0])));
    uint64_t k = binary ? 1024 : 1000;
    multiplier = u == 'K' ? k : u == 'M' ? k * k : u == 'G' ? k * k * k : 0;
    std::string rest = unit.substr(1);
    bool rest_ok = rest.empty() || (binary && (rest == "B" || rest == "iB"));
    if (multiplier == 0 || !rest_ok) return false;
  }
  if (n > ~uint64_t{0} / multiplier) return false;
  *value = n * multiplier;
  return true;
}

int usage_error(const std::string& message) {
  std::fprintf(stderr, "psq-meshgen: error: %s\n(see psq-meshgen --help)\n", message.c_str());
  return kExitUsage;
}

int report_error(const std::string& file, const Status& s) {
  std::fprintf(stderr, "psq-meshgen: error: %s: %s\n", file.c_str(), s.to_string().c_str());
  return kExitFailure;
}

// Parses argv; returns -1 to go on, or an exit code.
int parse_args(int argc, char** argv, Options* o) {
  bool have_triangles = false;
  for (int k = 1; k < argc; ++k) {
    std::string arg = argv[k];
    std::string value;
    bool has_inline = false;
    if (arg.rfind("--", 0) == 0) {
      size_t eq = arg.find('=');
      if (eq != std::string::npos) {
        value = arg.substr(eq + 1);
        arg = arg.substr(0, eq);
        has_inline = true;
      }
    }
    auto take = [&](std::string* v) {
      if (has_inline) {
        *v = value;
        return true;
      }
      if (k + 1 >= argc) return false;
      *v = argv[++k];
      return true;
    };
    auto flag = [&]() { return !has_inline; };
    std::string v;
    if (arg == "-h" || arg == "--help") {
      std::fputs(kHelp, stdout);
      return kExitOk;
    } else if (arg == "-f" || arg == "--force") {
      if (!flag()) return usage_error(arg + " takes no value");
      o->force = true;
    } else if (arg == "-q" || arg == "--quiet") {
      if (!flag()) return usage_error(arg + " takes no value");
      o->quiet = true;
    } else if (arg == "--triangles") {
      if (!take(&v)) return usage_error("--triangles needs a value");
      if (!parse_count(v, &o->triangles, false) || o->triangles == 0) {
        return usage_error("bad --triangles '" + v + "' (a positive count, e.g. 2000000 or 2M)");
      }
      have_triangles = true;
    } else if (arg == "--res") {
      uint64_t r = 0;
      if (!take(&v)) return usage_error("--res needs a value");
      if (!parse_count(v, &r, false) || r < kMinRes || r > kMaxRes) {
        return usage_error("bad --res '" + v + "' (" + std::to_string(kMinRes) + ".." +
                           std::to_string(kMaxRes) + ")");
      }
      o->res = static_cast<uint32_t>(r);
    } else if (arg == "--seed") {
      if (!take(&v)) return usage_error("--seed needs a value");
      if (!parse_count(v, &o->seed, false) || v.find_first_not_of("0123456789") != std::string::npos) {
        return usage_error("bad --seed '" + v + "' (a non-negative integer)");
      }
    } else if (arg == "--order") {
      if (!take(&v)) return usage_error("--order needs a value");
      if (v == "coherent") {
        o->shuffled = false;
      } else if (v == "shuffled") {
        o->shuffled = true;
      } else {
        return usage_error("bad --order '" + v + "' (coherent or shuffled)");
      }
    } else if (arg == "--memory") {
      if (!take(&v)) return usage_error("--memory needs a value");
      if (!parse_count(v, &o->memory, true) || o->memory == 0) {
        return usage_error("bad --memory '" + v + "' (a size such as 256M or 1G)");
      }
    } else if (arg == "--tmpdir") {
      if (!take(&v)) return usage_error("--tmpdir needs a value");
      o->tmpdir = v;
    } else if (arg == "-o" || arg == "--output") {
      if (!take(&v)) return usage_error(arg + " needs a value");
      o->output = v;
    } else {
      return usage_error("unknown argument '" + arg + "'");
    }
  }
  if (have_triangles && o->res != 0) return usage_error("give --triangles or --res, not both");
  return -1;
}

void on_signal(int sig) {
  remove_pending_outputs_from_signal();
  _exit(128 + sig);
}

std::string with_commas(uint64_t n) {
  std::string s = std::to_string(n);
  for (int k = static_cast<int>(s.size()) - 3; k > 0; k -= 3) s.insert(static_cast<size_t>(k), ",");
  return s;
}

int run(const Options& o) {
  const auto start = std::chrono::steady_clock::now();
  const Field field(o.seed);
  const CubeTable table = make_cube_table();

  Counts counts;
  uint32_t res = o.res;
  if (res == 0) {
    res = choose_res(field, o.triangles, table, &counts);
  } else {
    counts = count(field, res, table);
  }
  if (counts.vertices > 0x7fffffffu) {
    return report_error(o.output, Status(ErrorCode::kLimit, "res " + std::to_string(res) + " gives " +
                                                                std::to_string(counts.vertices) +
                                                                " vertices, more than PLY int indices hold"));
  }
  if (o.shuffled && counts.triangles > 0xffffffffu) {
    return report_error(o.output, Status(ErrorCode::kLimit, "--order shuffled handles at most 2^32 triangles"));
  }

  OutputFile out;
  Status s = out.open(o.output, o.force);
  if (!s.ok()) return report_error(o.output, s);
  auto encoder = std::make_unique<PlyEncoder>(&out);
  const std::string comment = "psq-meshgen seed " + std::to_string(o.seed) + " res " + std::to_string(res) +
                              " order " + (o.shuffled ? "shuffled" : "coherent");
  s = encoder->header(counts.vertices, counts.triangles, comment);

  Grid grid(field, res, table);
  Counts got;
  if (s.ok() && !o.shuffled) {
    CoherentOut sink(encoder.get());
    s = grid.sweep(Pass::kVertices, &sink, &got);
    if (s.ok()) s = grid.sweep(Pass::kTriangles, &sink, &got);
  } else if (s.ok()) {
    // One sorter at a time, each with the whole budget.
    const Permutation vperm(counts.vertices, mix64(o.seed ^ 0x7665727465787321ULL));
    const Permutation tperm(counts.triangles, mix64(o.seed ^ 0x747269616e676c65ULL));
    ExternalSortOptions sort_options;
    sort_options.memory_budget = o.memory;
    sort_options.tmpdir = o.tmpdir;
    {
      ExternalSorter<VertexRecord, ByPosition> vsort(sort_options);
      ShuffleOut sink(&vperm, &tperm, o.seed, &vsort, nullptr);
      s = grid.sweep(Pass::kVertices, &sink, &got);
      if (s.ok()) s = vsort.finish();
      for (bool done = false; s.ok();) {
        VertexRecord r{};
        s = vsort.next(&r, &done);
        if (!s.ok() || done) break;
        s = encoder->vertex(r.xyz[0], r.xyz[1], r.xyz[2]);
      }
    }
    if (s.ok()) {
      ExternalSorter<TriangleRecord, ByPosition> tsort(sort_options);
      ShuffleOut sink(&vperm, &tperm, mix64(o.seed + 1), nullptr, &tsort);
      s = grid.sweep(Pass::kTriangles, &sink, &got);
      if (s.ok()) s = tsort.finish();
      for (bool done = false; s.ok();) {
        TriangleRecord r{};
        s = tsort.next(&r, &done);
        if (!s.ok() || done) break;
        s = encoder->triangle(r.index[0], r.index[1], r.index[2]);
      }
    }
  }
  if (s.ok() && (got.vertices != counts.vertices || got.triangles != counts.triangles)) {
    s = Status(ErrorCode::kInternal, "the sweeps disagree on the counts");
  }
  if (s.ok()) s = encoder->flush();
  if (s.ok()) s = out.commit();
  if (!s.ok()) {
    out.discard();
    return report_error(o.output, s);
  }

  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (!o.quiet) {
    std::fprintf(stderr,
                 "psq-meshgen: %s vertices, %s triangles, res %u, seed %llu, %s, %.2f s (%.1fM triangles/s), "
                 "grid memory %.0f MiB\n",
                 with_commas(counts.vertices).c_str(), with_commas(counts.triangles).c_str(), res,
                 static_cast<unsigned long long>(o.seed), o.shuffled ? "shuffled" : "coherent", seconds,
                 static_cast<double>(counts.triangles) / seconds * 1e-6,
                 static_cast<double>(grid.memory(Pass::kVertices)) / (1 << 20));
  }
  return kExitOk;
}

}  // namespace
}  // namespace psq

int main(int argc, char** argv) {
  psq::Options options;
  int rc = psq::parse_args(argc, argv, &options);
  if (rc >= 0) return rc;
  if (options.output == "-" && ::isatty(STDOUT_FILENO)) {
    return psq::usage_error("refusing to write binary data to a terminal (use -o FILE)");
  }
  struct sigaction sa;
  std::memset(&sa, 0, sizeof sa);
  sa.sa_handler = psq::on_signal;
  for (int sig : {SIGINT, SIGTERM, SIGHUP}) sigaction(sig, &sa, nullptr);
  return psq::run(options);
}
