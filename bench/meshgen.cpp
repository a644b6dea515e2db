// SPDX-License-Identifier: Apache-2.0
// psq-meshgen: generates large closed triangle meshes to try psq at scale.
//
// The mesh is the boundary of a "foam ball": the solid where |gyroid(p)| >
// theta(p), clipped by a sphere. The gyroid's two labyrinths are networks
// with handles in every period cell; theta varies slowly in space (a
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
// any ambiguity table. The three vertices of a triangle lie on three
// different edges, so no triangle repeats an index, and vertices are kept a
// thousandth of an edge away from the grid points, so no two coincide.
// Triangles face outward: the table orients them from inside (f < 0) to
// outside.
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
// place under --memory: in an array when they fit, otherwise with the
// external sorter.
#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "external_sort.h"
#include "psq/io.h"
#include "psq/status.h"

namespace psq {
namespace {

constexpr int kExitOk = 0;
constexpr int kExitFailure = 1;
constexpr int kExitUsage = 2;

// Resolutions are kept in hundredths of a cube per axis: --triangles can
// then hit small targets closely (a whole step changes the count by about
// 2 / res, 17% at res 12), and the printed value reproduces the mesh.
// Above the maximum the grid layers alone take gigabytes and the vertex
// count overflows PLY's int indices long before.
constexpr uint32_t kMaxRes100 = 8192 * 100;
constexpr uint32_t kMinRes100 = 4 * 100;

#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_BIG_ENDIAN__
constexpr bool kLittleEndian = false;
#else
constexpr bool kLittleEndian = true;
#endif

const char kHelp[] =
    "Usage: psq-meshgen [--triangles N | --res R] [OPTIONS] [-o OUT.ply]\n"
    "\n"
    "Generates a closed, consistently oriented (outward), manifold triangle\n"
    "mesh: the surface of a 'foam ball', a gyroid foam of varying thickness\n"
    "clipped by a sphere, with hundreds of handles and many components. It is\n"
    "written as binary little-endian PLY (float x, y, z; list uchar int\n"
    "vertex_indices), streaming: memory is bounded by two layers of the grid\n"
    "(about 11 bytes x res^2: 25 MB at 200M triangles), not by the mesh.\n"
    "The same --seed gives the same field; --res samples it more finely.\n"
    "\n"
    "Options:\n"
    "  --triangles N    about N triangles (within a few percent); suffixes\n"
    "                   k, M, G are powers of 1000 (default 200k)\n"
    "  --res R          grid resolution instead: R cubes across the box\n"
    "                   [-1, 1]^3, 4..8192 in steps of 0.01 (the summary\n"
    "                   prints the one --triangles chose); about 90 R^2\n"
    "                   triangles; PLY's int indices stop R near 6700\n"
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
// standard library's engines and distributions, whose output is not fully
// specified), so a seed means one field everywhere; the mesh is the same
// wherever libm's sin and cos agree too.
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

// Population count, inline: the generic x86-64 target has no popcnt
// instruction and __builtin_popcountll becomes a libgcc call, which cost 15%
// of the run.
inline uint32_t popcount(uint64_t x) {
#if defined(__POPCNT__) || !(defined(__x86_64__) || defined(__i386__))
  return static_cast<uint32_t>(__builtin_popcountll(x));
#else
  x = x - ((x >> 1) & 0x5555555555555555ULL);
  x = (x & 0x3333333333333333ULL) + ((x >> 2) & 0x3333333333333333ULL);
  x = (x + (x >> 4)) & 0x0f0f0f0f0f0f0f0fULL;
  return static_cast<uint32_t>((x * 0x0101010101010101ULL) >> 56);
#endif
}

// ------------------------------------------------------------------- field

// The scalar field, separable along the axes so that a grid point costs a
// few multiply-adds on per-axis tables instead of trigonometry (at res 2000
// the grid has 8e9 points; the mesh only 1e8 triangles).
//
//   f(p) = max(theta(p) - |gyroid(p)|, sphere_scale * (|p|^2 - radius^2))
//   theta(p) = theta_mid + theta_span * s(sharpness * (waves(p) + bias))
//
// with s a tanh-like sigmoid and waves(p) a sum of plane waves
// sin(k.p + phase). The gyroid (range [-1.5, 1.5]) pinches off
// its labyrinths' tubes near |g| = 1.41: theta swings between two plateaus,
// 0.95 (thick networks: handles) and 1.45 (separate blobs around the
// maxima: components), with thin transition shells, so little of the
// volume sits near the pinch-off value where the topology depends on the
// grid. Inside is f < 0; the sphere term closes the surface.
struct Field {
  static constexpr int kWaves = 4;
  double gyroid_freq = 0;        // radians per unit: pi * periods across [-1, 1]
  double gyroid_phase[3] = {};   // x, y, z
  double wave[kWaves][3] = {};   // wave vectors of theta's plane waves
  double wave_phase[kWaves] = {};
  double wave_amp = 0;
  double bias = 0;        // moves the plateaus' share of the volume
  double sharpness = 0;
  double theta_mid = 0;
  double theta_span = 0;
  double radius = 0;
  double sphere_scale = 0;  // makes the sphere term's slope like the foam's

  explicit Field(uint64_t seed) {
    // Tuned with psq info (see meshgen_README.md): at 200K triangles about
    // 400 handles and 150 to 300 components, depending on the seed, and
    // the same order of magnitude at every size.
    SplitMix rng(mix64(seed ^ 0x5eed0f0a3ba11ULL));
    const double pi = 3.14159265358979323846;
    gyroid_freq = pi * 6.0;
    for (double& p : gyroid_phase) p = 2 * pi * rng.uniform();
    for (int m = 0; m < kWaves; ++m) {
      // Uniform direction on the sphere, 1.6 periods across the box.
      double z = 2 * rng.uniform() - 1, a = 2 * pi * rng.uniform();
      double s = std::sqrt(1 - z * z), k = pi * 1.6;
      wave[m][0] = k * s * std::cos(a);
      wave[m][1] = k * s * std::sin(a);
      wave[m][2] = k * z;
      wave_phase[m] = 2 * pi * rng.uniform();
    }
    wave_amp = 1.0 / std::sqrt(static_cast<double>(kWaves));
    bias = -0.5;  // about two thirds of the ball is network
    sharpness = 4.0;
    theta_mid = 1.2;
    theta_span = 0.25;
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
  // Per configuration, the edges its triangles use (bit = edge code): each
  // id is looked up once per cube, not once per triangle corner.
  std::array<uint32_t, 256> used{};
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
    for (int c = 0; c < k; ++c) table.used[config] |= uint32_t{1} << table.triangles[config][c];
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
  // `res100`: the resolution in hundredths: the grid spacing is 2 / res
  // and the grid has ceil(res) cubes per axis, centred on the ball.
  Grid(const Field& field, uint32_t res100, const CubeTable& table)
      : field_(field), res_((res100 + 99) / 100), table_(table) {
    const uint32_t points = res_ + 1;
    h_ = 200.0 / res100;
    origin_ = -0.5 * h_ * res_;
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
    inside_.resize(size_t{words_} * 64);
    // Only points within this distance of the centre can be, or neighbour,
    // an inside point (the sphere term is positive beyond the radius, and
    // a lattice edge is at most sqrt(3) h long).
    reach_ = field.radius + 2 * h_;
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
    vbuf_.assign(kBatch + 3 * 64, 0.0f);
    tbuf_.assign(kBatch + 36 * 64, 0);
    vsize_ = tsize_ = 0;
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
      for (uint64_t w : cross_[hi]) slab_vertices += popcount(w);
      counts->vertices += slab_vertices;
      if (pass == Pass::kVertices) {
        PSQ_RETURN_IF_ERROR(slab_vertices_out(s, lo, hi));
      } else if (pass == Pass::kTriangles) {
        number_vertices(hi);
      }
      PSQ_RETURN_IF_ERROR(cubes(lo, hi, counts));
      lo = hi;
    }
    if (vsize_ > 0) PSQ_RETURN_IF_ERROR(out_->vertices(vbuf_.data(), vsize_ / 3));
    if (tsize_ > 0) PSQ_RETURN_IF_ERROR(out_->triangles(tbuf_.data(), tsize_ / 3));
    return Status();
  }

 private:
  static constexpr size_t kBatch = 3 * 16384;

  double coordinate(uint32_t i) const { return origin_ + h_ * i; }

  // What the field of a row needs besides the per-x tables.
  struct RowConstants {
    float A, B, C;  // gyroid = sx * A + cx * C + B
    float yz;       // sphere term minus its x part
    float q0, theta_mid, theta_span;
    float w_re[Field::kWaves], w_im[Field::kWaves];  // wave factors of y, z
  };

  // f over [i0, i_end) of one row; r and m are the real and imaginary
  // parts of the waves' x factors. The loop is written for the vectorizer:
  // restrict pointers (too many streams for runtime alias checks), a
  // half-open bound (with i <= i1 the trip count could overflow), no libm
  // call and no nested ?: (GCC treats either as control flow).
  static void eval_row(float* __restrict f, const float* __restrict sx, const float* __restrict cx,
                       const float* __restrict xx, const float* __restrict r0, const float* __restrict r1,
                       const float* __restrict r2, const float* __restrict r3, const float* __restrict m0,
                       const float* __restrict m1, const float* __restrict m2, const float* __restrict m3,
                       const RowConstants& k, uint32_t i0, uint32_t i_end) {
    static_assert(Field::kWaves == 4, "the loop below unrolls the waves");
    const float A = k.A, B = k.B, C = k.C, yz = k.yz, q0 = k.q0;
    const float theta_mid = k.theta_mid, theta_span = k.theta_span;
    const float a0 = k.w_re[0], a1 = k.w_re[1], a2 = k.w_re[2], a3 = k.w_re[3];
    const float b0 = k.w_im[0], b1 = k.w_im[1], b2 = k.w_im[2], b3 = k.w_im[3];
    for (uint32_t i = i0; i < i_end; ++i) {
      const float g = sx[i] * A + cx[i] * C + B;
      const float q = q0 + (a0 * m0[i] + b0 * r0[i]) + (a1 * m1[i] + b1 * r1[i]) + (a2 * m2[i] + b2 * r2[i]) +
                      (a3 * m3[i] + b3 * r3[i]);
      // tanh(q) by its (3, 2) Pade approximant, clamped to [-3, 3] where it
      // meets +-1 with zero slope; the clamp is written with fabs.
      const float x = 0.5f * (std::fabs(q + 3.0f) - std::fabs(q - 3.0f));
      const float x2 = x * x;
      const float theta = theta_mid + theta_span * (x * (27.0f + x2) / (27.0f + 9.0f * x2));
      const float foam = theta - std::fabs(g);
      const float sphere = xx[i] + yz;
      f[i] = foam > sphere ? foam : sphere;
    }
  }

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
    const float theta_mid = static_cast<float>(field_.theta_mid);
    const float theta_span = static_cast<float>(field_.theta_span);
    const float q0 = static_cast<float>(field_.sharpness * field_.bias);
    for (uint32_t j = 0; j < points; ++j) {
      float* row_values = values ? values + size_t{j} * points : nullptr;
      const double y = coord_[j];
      const double yz2 = y * y + z * z;
      if (yz2 >= reach2) {
        if (row_values) std::fill(row_values, row_values + points, 1.0f);
        continue;
      }
      const double half = std::sqrt(reach2 - yz2);
      const uint32_t i0 = static_cast<uint32_t>(std::max(0.0, std::floor((-half - origin_) / h_)));
      const uint32_t i1 = static_cast<uint32_t>(std::min<double>(res_, std::ceil((half - origin_) / h_)));

      // Row constants: gyroid = sx*cy + sy*cz + sz*cx = sx*A + cx*C + B; each
      // wave sin(kx x + ky y + kz z + phi) = Im(W * e^{i kx x}).
      RowConstants rc;
      rc.A = cy_[j];
      rc.B = sy_[j] * cz_[k];
      rc.C = sz_[k];
      rc.yz = static_cast<float>(field_.sphere_scale * yz2) - R2;
      rc.q0 = q0;
      rc.theta_mid = theta_mid;
      rc.theta_span = theta_span;
      for (int m = 0; m < Field::kWaves; ++m) {
        const double a = field_.wave[m][1] * y + field_.wave[m][2] * z + field_.wave_phase[m];
        const double amp = field_.sharpness * field_.wave_amp;
        rc.w_re[m] = static_cast<float>(amp * std::cos(a));
        rc.w_im[m] = static_cast<float>(amp * std::sin(a));
      }
      const uint32_t i_end = i1 + 1;
      eval_row(row_.data(), sx_.data(), cx_.data(), xx_.data(), wx_re_[0].data(), wx_re_[1].data(),
               wx_re_[2].data(), wx_re_[3].data(), wx_im_[0].data(), wx_im_[1].data(), wx_im_[2].data(),
               wx_im_[3].data(), rc, i0, i_end);
      const float* f = row_.data();

      // Sign bits, 8 at a time: a byte 0/1 per point, then the multiply
      // gathers the low bit of 8 bytes into the top byte of the product.
      uint8_t* in = inside_.data();
      const uint32_t w0 = i0 / 64, w1 = i1 / 64;
      std::fill(in + 64 * w0, in + i0, uint8_t{0});
      for (uint32_t i = i0; i < i_end; ++i) in[i] = f[i] < 0.0f;
      std::fill(in + i1 + 1, in + 64 * (w1 + 1), uint8_t{0});
      uint64_t* row_bits = bits + size_t{j} * bit_words_;
      for (uint32_t w = w0; w <= w1; ++w) {
        uint64_t word = 0;
        for (uint32_t b = 0; b < 8; ++b) {
          uint64_t bytes;
          std::memcpy(&bytes, in + 64 * w + 8 * b, 8);
          if (!kLittleEndian) bytes = __builtin_bswap64(bytes);
          word |= ((bytes * 0x0102040810204080ULL) >> 56) << (8 * b);
        }
        row_bits[w] = word;
      }
      if (row_values) {
        std::fill(row_values, row_values + i0, 1.0f);
        std::copy(f + i0, f + i_end, row_values + i0);
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
      id += popcount(cross[k]);
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
            float* v = vbuf_.data() + vsize_;
            v[0] = static_cast<float>(coordinate(i) + t * h_ * (e & 1));
            v[1] = static_cast<float>(coordinate(j) + t * h_ * ((e >> 1) & 1));
            v[2] = static_cast<float>(coordinate(k) + t * h_ * ((e >> 2) & 1));
            vsize_ += 3;
          }
          if (vsize_ >= kBatch) {  // the slack holds one word's 64 vertices
            PSQ_RETURN_IF_ERROR(out_->vertices(vbuf_.data(), vsize_ / 3));
            vsize_ = 0;
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
    return base_[rec][k] + popcount(cross_[rec][k] & below);
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
          uint32_t ids[19];
          for (uint32_t used = table_.used[config]; used != 0; used &= used - 1) {
            const int e = __builtin_ctz(used);
            ids[e] = vertex_id(table_.edges[e], i, j, lo, hi);
          }
          const uint8_t* t = table_.triangles[config].data();
          uint32_t* out = tbuf_.data() + tsize_;
          for (unsigned k = 0; k < 3 * n; ++k) out[k] = ids[t[k]];
          tsize_ += 3 * n;
        }
        if (tsize_ >= kBatch) {  // the slack holds one word's 64 cubes
          PSQ_RETURN_IF_ERROR(out_->triangles(tbuf_.data(), tsize_ / 3));
          tsize_ = 0;
        }
      }
    }
    return Status();
  }

  const Field& field_;
  const uint32_t res_;
  const CubeTable& table_;
  double h_ = 0;       // grid spacing
  double origin_ = 0;  // coordinate of grid point 0 on every axis
  double reach_ = 0;
  uint32_t words_ = 0;      // 64-point words per row
  uint32_t bit_words_ = 0;  // words_ + 1
  std::vector<double> coord_;
  std::vector<float> sx_, cx_, sy_, cy_, sz_, cz_, xx_;
  std::vector<float> wx_re_[Field::kWaves], wx_im_[Field::kWaves];
  std::vector<float> row_;      // field values of one row
  std::vector<uint8_t> inside_;  // f < 0 of one row, padded to whole words

  // Two of each, indexed by slot; the slots swap roles every slab.
  std::vector<uint64_t> bits_[2];    // sign bits per layer: (res + 2) rows
  std::vector<float> values_[2];     // field values per layer (vertex pass)
  std::vector<uint64_t> cross_[2];   // crossing masks per slab record
  std::vector<uint32_t> base_[2];    // first vertex id per mask (triangle pass)

  Pass pass_ = Pass::kCount;
  MeshOut* out_ = nullptr;
  uint64_t next_id_ = 0;
  std::vector<float> vbuf_;      // vertices waiting for out_, with slack
  std::vector<uint32_t> tbuf_;   // triangles waiting for out_, with slack
  size_t vsize_ = 0;             // floats used in vbuf_
  size_t tsize_ = 0;             // ids used in tbuf_
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

// Puts n records in the order of their positions, which are a permutation
// of [0, n): by a scatter into an array when the n records fit in the
// budget (no sort, no file), otherwise through the external sorter. Both
// give the same output.
template <class T>
class Shuffler {
 public:
  Shuffler(uint64_t n, const ExternalSortOptions& options) {
    if (n * sizeof(T) <= options.memory_budget) {
      in_memory_ = true;
      records_.resize(n);
    } else {
      sorter_ = std::make_unique<ExternalSorter<T, ByPosition>>(options);
    }
  }
  Status add(const T& r) {
    if (!in_memory_) return sorter_->add(r);
    if (r.position >= records_.size()) return Status(ErrorCode::kInternal, "shuffle position out of range");
    records_[r.position] = r;
    return Status();
  }
  Status finish() { return in_memory_ ? Status() : sorter_->finish(); }
  Status next(T* r, bool* done) {
    if (!in_memory_) return sorter_->next(r, done);
    *done = next_ == records_.size();
    if (!*done) *r = records_[next_++];
    return Status();
  }

 private:
  bool in_memory_ = false;
  std::vector<T> records_;
  size_t next_ = 0;
  std::unique_ptr<ExternalSorter<T, ByPosition>> sorter_;
};

class ShuffleOut : public MeshOut {
 public:
  ShuffleOut(const Permutation* vperm, const Permutation* tperm, uint64_t rotate_key,
             Shuffler<VertexRecord>* vertices, Shuffler<TriangleRecord>* triangles)
      : vperm_(vperm), tperm_(tperm), rotate_key_(rotate_key), vout_(vertices), tout_(triangles) {}

  Status vertices(const float* xyz, size_t n) override {
    for (size_t k = 0; k < n; ++k, ++vertex_) {
      VertexRecord r{static_cast<uint32_t>((*vperm_)(vertex_)), {xyz[3 * k], xyz[3 * k + 1], xyz[3 * k + 2]}};
      PSQ_RETURN_IF_ERROR(vout_->add(r));
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
      for (unsigned c = 0; c < 3; ++c) r.index[c] = new_vertex(abc[3 * k + (c + rot) % 3]);
      PSQ_RETURN_IF_ERROR(tout_->add(r));
    }
    return Status();
  }

 private:
  // The sweep's triangles use the vertices of about two slabs, each about
  // six times: a direct-mapped cache saves most of the Feistel rounds.
  uint32_t new_vertex(uint32_t old) {
    uint64_t& slot = cache_[old & (kCache - 1)];
    if ((slot >> 32) != old) slot = uint64_t{old} << 32 | (*vperm_)(old);
    return static_cast<uint32_t>(slot);
  }

  static constexpr size_t kCache = size_t{1} << 16;
  const Permutation* vperm_;
  const Permutation* tperm_;
  uint64_t rotate_key_;
  Shuffler<VertexRecord>* vout_;
  Shuffler<TriangleRecord>* tout_;
  uint64_t vertex_ = 0;
  uint64_t triangle_ = 0;
  // Entries are old << 32 | new; old ids are < 2^31, so ~0 is no entry.
  std::vector<uint64_t> cache_ = std::vector<uint64_t>(kCache, ~uint64_t{0});
};

// Writes the shuffled mesh: for each kind, one sweep into its shuffler,
// then the records in order. One shuffler at a time, each with the whole
// budget.
Status write_shuffled(Grid* grid, const Counts& counts, uint64_t seed, const ExternalSortOptions& options,
                      PlyEncoder* encoder, Counts* got) {
  const Permutation vperm(counts.vertices, mix64(seed ^ 0x7665727465787321ULL));
  const Permutation tperm(counts.triangles, mix64(seed ^ 0x747269616e676c65ULL));
  {
    Shuffler<VertexRecord> vertices(counts.vertices, options);
    ShuffleOut sink(&vperm, &tperm, 0, &vertices, nullptr);
    PSQ_RETURN_IF_ERROR(grid->sweep(Pass::kVertices, &sink, got));
    PSQ_RETURN_IF_ERROR(vertices.finish());
    VertexRecord r{};
    for (bool done = false;;) {
      PSQ_RETURN_IF_ERROR(vertices.next(&r, &done));
      if (done) break;
      PSQ_RETURN_IF_ERROR(encoder->vertex(r.xyz[0], r.xyz[1], r.xyz[2]));
    }
  }
  Shuffler<TriangleRecord> triangles(counts.triangles, options);
  ShuffleOut sink(&vperm, &tperm, mix64(seed + 1), nullptr, &triangles);
  PSQ_RETURN_IF_ERROR(grid->sweep(Pass::kTriangles, &sink, got));
  PSQ_RETURN_IF_ERROR(triangles.finish());
  TriangleRecord r{};
  for (bool done = false;;) {
    PSQ_RETURN_IF_ERROR(triangles.next(&r, &done));
    if (done) break;
    PSQ_RETURN_IF_ERROR(encoder->triangle(r.index[0], r.index[1], r.index[2]));
  }
  return Status();
}

// ---------------------------------------------------------------- commands

struct Options {
  uint64_t triangles = 200000;
  uint32_t res100 = 0;  // resolution in hundredths; 0: from triangles
  uint64_t seed = 1;
  bool shuffled = false;
  uint64_t memory = uint64_t{256} << 20;
  std::string tmpdir;
  std::string output = "-";
  bool force = false;
  bool quiet = false;
};

Counts count(const Field& field, uint32_t res100, const CubeTable& table) {
  Grid grid(field, res100, table);
  Counts c;
  grid.sweep(Pass::kCount, nullptr, &c);  // counting writes nothing: cannot fail
  return c;
}

// "12.37", "463": a resolution in hundredths, as --res takes it.
std::string res_text(uint32_t res100) {
  std::string s = std::to_string(res100 / 100);
  if (res100 % 100 != 0) {
    char frac[4];
    std::snprintf(frac, sizeof frac, "%02u", res100 % 100);
    s += '.';
    s += frac[1] == '0' ? std::string(1, frac[0]) : std::string(frac);
  }
  return s;
}

// Picks the resolution (in hundredths) for about `target` triangles: T grows
// as res^2 once the grid resolves the field (faster below), so scale from
// cheap probes with the exponent measured between the last two counts, and
// stop at the first count within 2% (for large targets the first count at
// the final resolution, which the writing needs anyway).
uint32_t choose_res(const Field& field, uint64_t target, const CubeTable& table, Counts* at_res) {
  std::map<uint32_t, Counts> seen;
  auto measure = [&](uint32_t r) {
    auto it = seen.find(r);
    if (it == seen.end()) it = seen.emplace(r, count(field, r, table)).first;
    return it->second.triangles;
  };
  auto error = [&](uint64_t t) { return std::fabs(static_cast<double>(t) / static_cast<double>(target) - 1.0); };
  auto scaled = [&](uint32_t r, uint64_t t, double exponent) {
    double next = r * std::pow(static_cast<double>(target) / std::max<uint64_t>(t, 1), 1.0 / exponent);
    return static_cast<uint32_t>(std::clamp(std::llround(next), static_cast<long long>(kMinRes100),
                                            static_cast<long long>(kMaxRes100)));
  };

  uint32_t r_prev = 64 * 100;
  uint64_t t_prev = measure(r_prev);
  uint32_t r = scaled(r_prev, t_prev, 2.0);
  if (r > 320 * 100) {
    // A second probe where the field is resolved: T / res^2 is within ~2%
    // of its limit from res 250 on.
    r_prev = 256 * 100;
    t_prev = measure(r_prev);
    r = scaled(r_prev, t_prev, 2.0);
  }
  uint32_t best = r_prev;
  for (int iteration = 0; iteration < 12; ++iteration) {
    const uint64_t t = measure(r);
    if (error(t) < error(seen[best].triangles)) best = r;
    if (error(t) < 0.02) break;
    double exponent = 2.0;
    if (r != r_prev && t > 0 && t_prev > 0 && t != t_prev) {
      exponent = std::log(static_cast<double>(t) / t_prev) / std::log(static_cast<double>(r) / r_prev);
      exponent = std::clamp(exponent, 1.5, 4.0);
    }
    const uint32_t next = scaled(r, t, exponent);
    if (seen.count(next) != 0) break;
    r_prev = r;
    t_prev = t;
    r = next;
  }
  *at_res = seen[best];
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
  return s.code() == ErrorCode::kUsage ? kExitUsage : kExitFailure;
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
      if (!take(&v)) return usage_error("--res needs a value");
      char* end = nullptr;
      const double r = std::strtod(v.c_str(), &end);
      const bool digits = !v.empty() && v.find_first_not_of("0123456789.") == std::string::npos;
      if (!digits || end != v.c_str() + v.size() || !(r * 100 >= kMinRes100 && r * 100 <= kMaxRes100)) {
        return usage_error("bad --res '" + v + "' (4..8192, in steps of 0.01)");
      }
      o->res100 = static_cast<uint32_t>(std::lround(r * 100));
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
  if (have_triangles && o->res100 != 0) return usage_error("give --triangles or --res, not both");
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

  // Open first: an existing OUT without -f fails before any counting.
  OutputFile out;
  Status s = out.open(o.output, o.force);
  if (!s.ok()) return report_error(o.output, s);

  Counts counts;
  uint32_t res100 = o.res100;
  if (res100 == 0) {
    res100 = choose_res(field, o.triangles, table, &counts);
  } else {
    counts = count(field, res100, table);
  }
  if (counts.vertices > 0x7fffffffu) {
    return report_error(o.output, Status(ErrorCode::kLimit, "res " + res_text(res100) + " gives " +
                                                                std::to_string(counts.vertices) +
                                                                " vertices, more than PLY int indices hold"));
  }
  if (o.shuffled && counts.triangles > 0xffffffffu) {
    return report_error(o.output, Status(ErrorCode::kLimit, "--order shuffled handles at most 2^32 triangles"));
  }

  auto encoder = std::make_unique<PlyEncoder>(&out);
  const std::string comment = "psq-meshgen seed " + std::to_string(o.seed) + " res " + res_text(res100) +
                              " order " + (o.shuffled ? "shuffled" : "coherent");
  s = encoder->header(counts.vertices, counts.triangles, comment);

  Grid grid(field, res100, table);
  Counts got;
  if (s.ok() && !o.shuffled) {
    CoherentOut sink(encoder.get());
    s = grid.sweep(Pass::kVertices, &sink, &got);
    if (s.ok()) s = grid.sweep(Pass::kTriangles, &sink, &got);
  } else if (s.ok()) {
    ExternalSortOptions sort_options;
    sort_options.memory_budget = o.memory;
    sort_options.tmpdir = o.tmpdir;
    s = write_shuffled(&grid, counts, o.seed, sort_options, encoder.get(), &got);
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
                 "psq-meshgen: %s vertices, %s triangles, res %s, seed %llu, %s, %.2f s (%.1fM triangles/s)\n",
                 with_commas(counts.vertices).c_str(), with_commas(counts.triangles).c_str(), res_text(res100).c_str(),
                 static_cast<unsigned long long>(o.seed), o.shuffled ? "shuffled" : "coherent", seconds,
                 static_cast<double>(counts.triangles) / seconds * 1e-6);
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
