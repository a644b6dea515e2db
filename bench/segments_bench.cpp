// SPDX-License-Identifier: Apache-2.0
// psq_bench_segments: decode_mesh() of a .psq in memory on one thread and
// on several (spec 4.6: a stream of several segments decodes them at
// once), alternating within each round, as an application calls it: each
// run into fresh MeshBuffers. Prints one JSON object: the median seconds
// of each thread count and their ratio, and checks that every run gives
// the same mesh.
//
//   build/bench/psq_bench_segments [--rounds N] [--threads T] FILE.psq
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "psq/io.h"
#include "psq/psq_memory.h"

namespace {

using Clock = std::chrono::steady_clock;

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : (v[n / 2 - 1] + v[n / 2]) / 2;
}

}  // namespace

int main(int argc, char** argv) {
  int rounds = 5, threads = 2;
  std::string path;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--rounds" && i + 1 < argc) rounds = std::atoi(argv[++i]);
    else if (a == "--threads" && i + 1 < argc) threads = std::atoi(argv[++i]);
    else path = a;
  }
  if (path.empty() || rounds < 1 || threads < 2) {
    std::fprintf(stderr, "usage: psq_bench_segments [--rounds N] [--threads T>=2] FILE.psq\n");
    return 2;
  }
  psq::InputStream in;
  psq::Status s = in.open(path);
  std::vector<uint8_t> bytes;
  for (;;) {
    size_t avail = 0;
    if (s.ok()) s = in.fill(1 << 20, &avail);
    if (!s.ok() || avail == 0) break;
    bytes.insert(bytes.end(), in.cursor(), in.cursor() + avail);
    in.advance(avail);
  }
  if (!s.ok()) {
    std::fprintf(stderr, "psq_bench_segments: %s: %s\n", path.c_str(), s.to_string().c_str());
    return 1;
  }
  std::vector<double> one, many;
  psq::MeshBuffers first;
  for (int r = 0; r < rounds; ++r) {
    for (int k = 0; k < 2; ++k) {
      const int t = (r + k) % 2 == 0 ? 1 : threads;  // which goes first alternates
      psq::MeshBuffers mesh;
      const auto t0 = Clock::now();
      s = psq::decode_mesh(bytes.data(), bytes.size(), &mesh, t);
      const double dt = std::chrono::duration<double>(Clock::now() - t0).count();
      if (!s.ok()) {
        std::fprintf(stderr, "psq_bench_segments: %s: %s\n", path.c_str(), s.to_string().c_str());
        return 1;
      }
      if (first.indices.empty()) first = mesh;
      else if (mesh.positions != first.positions || mesh.indices != first.indices) {
        std::fprintf(stderr, "psq_bench_segments: %s: the meshes differ\n", path.c_str());
        return 1;
      }
      (t == 1 ? one : many).push_back(dt);
    }
  }
  const double a = median(one), b = median(many);
  std::printf("{\"file\": \"%s\", \"triangles\": %zu, \"threads\": %d, \"seconds_1\": %.4f, \"seconds_n\": %.4f, "
              "\"speedup\": %.3f}\n",
              path.c_str(), first.indices.size() / 3, threads, a, b, a / b);
  return 0;
}
