// SPDX-License-Identifier: Apache-2.0
// Throughput of the streaming PLY and OBJ readers and writers on a generated
// grid mesh held in memory (no disk in the loop for reading).
//
//   build/bench/psq_bench_io --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>

#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>
#include <vector>

#include "psq/indexed_mesh.h"
#include "psq/io.h"
#include "psq/obj.h"
#include "psq/ply.h"

namespace {

// A grid of n x n quads as two triangles each, streamed as a source.
class GridSource : public psq::MeshSource {
 public:
  explicit GridSource(int n) : n_(n) {
    schema_.vertex_count = int64_t{n + 1} * (n + 1);
    schema_.triangle_count = int64_t{2} * n * n;
  }
  const psq::MeshSchema& schema() const override { return schema_; }
  const psq::SourceReport& report() const override { return report_; }
  psq::Status next(psq::MeshItem* item) override {
    int64_t nv = schema_.vertex_count;
    if (at_ < nv) {
      item->kind = psq::MeshItem::Kind::kVertex;
      item->position[0] = static_cast<float>(at_ % (n_ + 1)) * 0.01f;
      item->position[1] = static_cast<float>(at_ / (n_ + 1)) * 0.01f;
      item->position[2] = static_cast<float>((at_ * 7919) % 1000) * 1e-4f;
    } else if (at_ < nv + schema_.triangle_count) {
      int64_t t = at_ - nv, q = t / 2;
      uint32_t i = static_cast<uint32_t>(q % n_), j = static_cast<uint32_t>(q / n_), w = static_cast<uint32_t>(n_ + 1);
      item->kind = psq::MeshItem::Kind::kTriangle;
      if (t % 2 == 0) {
        item->index[0] = j * w + i, item->index[1] = j * w + i + 1, item->index[2] = (j + 1) * w + i + 1;
      } else {
        item->index[0] = j * w + i, item->index[1] = (j + 1) * w + i + 1, item->index[2] = (j + 1) * w + i;
      }
    } else {
      item->kind = psq::MeshItem::Kind::kEnd;
    }
    ++at_;
    return psq::Status();
  }

 private:
  int n_;
  int64_t at_ = 0;
  psq::MeshSchema schema_;
  psq::SourceReport report_;
};

class NullSink : public psq::MeshSink {
 public:
  psq::Status begin(const psq::MeshSchema&) override { return psq::Status(); }
  psq::Status vertex(const double p[3], const psq::PropertyValues&) override {
    sum += p[0];
    return psq::Status();
  }
  psq::Status triangle(const uint32_t i[3], const psq::PropertyValues&) override {
    sum += i[0];
    return psq::Status();
  }
  psq::Status finish() override { return psq::Status(); }
  double sum = 0;
};

std::string encode(psq::MeshSink* (*make)(psq::OutputFile*), int n) {
  char path[] = "/tmp/psq-bench-XXXXXX";
  int fd = mkstemp(path);
  close(fd);
  std::string file = path;
  {
    psq::OutputFile out;
    out.open(file, true);
    std::unique_ptr<psq::MeshSink> sink(make(&out));
    GridSource src(n);
    psq::pump(src, *sink);
    out.commit();
  }
  std::string bytes;
  FILE* f = std::fopen(file.c_str(), "rb");
  char buf[1 << 16];
  size_t r;
  while ((r = std::fread(buf, 1, sizeof buf, f)) > 0) bytes.append(buf, r);
  std::fclose(f);
  std::remove(file.c_str());
  return bytes;
}

psq::MeshSink* make_ply_binary(psq::OutputFile* o) { return new psq::PlyWriter(o); }
psq::MeshSink* make_ply_ascii(psq::OutputFile* o) {
  psq::PlyWriteOptions opt;
  opt.encoding = psq::PlyEncoding::kAscii;
  return new psq::PlyWriter(o, opt);
}
psq::MeshSink* make_obj(psq::OutputFile* o) { return new psq::ObjWriter(o); }

void read_bench(benchmark::State& state, const std::string& bytes, bool ply) {
  int64_t triangles = 0;
  for (auto _ : state) {
    psq::InputStream in;
    in.open_memory(bytes.data(), bytes.size());
    NullSink sink;
    psq::Status s;
    if (ply) {
      psq::PlyReader r;
      s = r.open(&in);
      if (s.ok()) s = psq::pump(r, sink);
    } else {
      psq::ObjReader r;
      s = r.open(&in);
      if (s.ok()) s = psq::pump(r, sink);
    }
    if (!s.ok()) state.SkipWithError(s.to_string().c_str());
    benchmark::DoNotOptimize(sink.sum);
    triangles += 2 * state.range(0) * state.range(0);
  }
  state.counters["triangles/s"] = benchmark::Counter(static_cast<double>(triangles), benchmark::Counter::kIsRate);
  state.SetBytesProcessed(static_cast<int64_t>(state.iterations()) * static_cast<int64_t>(bytes.size()));
}

void BM_ReadPlyBinary(benchmark::State& state) {
  static std::string bytes = encode(make_ply_binary, static_cast<int>(state.range(0)));
  read_bench(state, bytes, true);
}
void BM_ReadPlyAscii(benchmark::State& state) {
  static std::string bytes = encode(make_ply_ascii, static_cast<int>(state.range(0)));
  read_bench(state, bytes, true);
}
void BM_ReadObj(benchmark::State& state) {
  static std::string bytes = encode(make_obj, static_cast<int>(state.range(0)));
  read_bench(state, bytes, false);
}

BENCHMARK(BM_ReadPlyBinary)->Arg(500)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_ReadPlyAscii)->Arg(500)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_ReadObj)->Arg(500)->Unit(benchmark::kMillisecond);

}  // namespace
