// SPDX-License-Identifier: Apache-2.0
// psq_bench_first_touch: what fresh memory costs decode_mesh() on this
// machine, in two measurements.
//
// 1. Pages: the time per 4 KiB page to map and write a fresh anonymous
//    region of --mib MiB (mmap, then memset), with the kernel asked to back
//    it first in one call (madvise MADV_POPULATE_WRITE, as
//    codec/src/record_decoder.cpp does) and without (one fault per page).
//    Fastest of --runs.
// 2. decode_mesh(): each FILE.psq decoded --runs times in this process
//    into fresh MeshBuffers, as an application would; fastest run, its
//    M triangles/s and its minor page faults (getrusage). Unlike
//    psq_bench_compare, which decodes in a forked child of a process that
//    holds every test mesh, the heap here holds nothing else.
//
//   build/bench/psq_bench_first_touch [--runs N] [--mib M] [FILE.psq...]
#include <sys/mman.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "psq/io.h"
#include "psq/psq_memory.h"

namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

long minor_faults() {
  rusage u;
  getrusage(RUSAGE_SELF, &u);
  return u.ru_minflt;
}

#ifdef MADV_POPULATE_WRITE
constexpr int kPopulateWrite = MADV_POPULATE_WRITE;
#else
constexpr int kPopulateWrite = 23;  // Linux 5.14's value, for older C library headers
#endif

// Seconds to map, (populate,) write and unmap `bytes` fresh bytes, or a
// negative number when populating was refused. Huge pages are turned off
// for the region, so that every page is a small one whatever the system's
// transparent huge page setting.
double touch(size_t bytes, bool populate) {
  const auto t0 = Clock::now();
  void* p = mmap(nullptr, bytes, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  if (p == MAP_FAILED) {
    std::perror("mmap");
    std::exit(1);
  }
  (void)madvise(p, bytes, MADV_NOHUGEPAGE);
  if (populate && madvise(p, bytes, kPopulateWrite) != 0) {
    munmap(p, bytes);
    return -1;
  }
  std::memset(p, 1, bytes);
  const double t = seconds_since(t0);
  munmap(p, bytes);
  return t;
}

}  // namespace

int main(int argc, char** argv) {
  int runs = 15;
  size_t mib = 3;
  std::vector<std::string> files;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--runs" && i + 1 < argc) runs = std::max(1, std::atoi(argv[++i]));
    else if (a == "--mib" && i + 1 < argc) mib = static_cast<size_t>(std::max(1, std::atoi(argv[++i])));
    else if (a == "-h" || a == "--help") {
      std::printf("usage: psq_bench_first_touch [--runs N] [--mib M] [FILE.psq...]\n");
      return 0;
    } else files.push_back(a);
  }
  const long page = sysconf(_SC_PAGESIZE);
  const size_t bytes = mib << 20, pages = bytes / static_cast<size_t>(page > 0 ? page : 4096);
  for (bool populate : {false, true}) {
    double best = 1e30;
    for (int r = 0; r < runs && best >= 0; ++r) best = std::min(best, touch(bytes, populate));
    const char* how = populate ? "populated in one madvise" : "a fault per page";
    if (best < 0) std::printf("fresh %zu MiB, %s: not supported here (%s)\n", mib, how, std::strerror(errno));
    else
      std::printf("fresh %zu MiB, %s: %.3f ms, %.2f us a page of %ld bytes (fastest of %d)\n", mib, how, best * 1e3,
                  best * 1e6 / static_cast<double>(pages), page, runs);
  }
  for (const std::string& f : files) {
    psq::InputStream in;
    psq::Status s = in.open(f);
    std::vector<uint8_t> data;
    while (s.ok()) {
      size_t available = 0;
      s = in.fill(1 << 20, &available);
      if (!s.ok() || available == 0) break;
      data.insert(data.end(), in.cursor(), in.cursor() + available);
      in.advance(available);
    }
    if (!s.ok()) {
      std::fprintf(stderr, "psq_bench_first_touch: %s\n", s.to_string().c_str());
      return 1;
    }
    double best = 1e30;
    long best_faults = 0;
    size_t triangles = 0;
    for (int r = 0; r < runs; ++r) {
      const long f0 = minor_faults();
      const auto t0 = Clock::now();
      psq::MeshBuffers mesh;
      s = psq::decode_mesh(data.data(), data.size(), &mesh);
      const double t = seconds_since(t0);
      const long faults = minor_faults() - f0;
      if (!s.ok()) {
        std::fprintf(stderr, "psq_bench_first_touch: %s: %s\n", f.c_str(), s.to_string().c_str());
        return 1;
      }
      triangles = mesh.indices.size() / 3;
      if (t < best) {
        best = t;
        best_faults = faults;
      }
    }
    std::printf("%s: decode_mesh %.3f ms, %.2f M triangles/s, %ld page faults (fastest of %d)\n", f.c_str(), best * 1e3,
                static_cast<double>(triangles) / best / 1e6, best_faults, runs);
  }
  return 0;
}
