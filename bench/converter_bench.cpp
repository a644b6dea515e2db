// SPDX-License-Identifier: Apache-2.0
// Speed of the processing-sequence converter (waiting area) on coherent
// input, parsing excluded: a grid of n x n quads fed row by row, each vertex
// finalized as soon as the rows below it are done, into a sink that only
// counts.
//
// Also a fan of 100k triangles around one vertex (linear work per valence).
//
//   build/bench/psq_bench_converter --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>

#include "psq/converter.h"
#include "psq/sequence_check.h"

namespace {

class CountingSink : public psq::SequenceSink {
 public:
  psq::Status begin(const psq::MeshSchema&) override { return psq::Status(); }
  psq::Status vertex(const psq::SequenceVertex&) override {
    ++vertices;
    return psq::Status();
  }
  psq::Status triangle(const psq::SequenceTriangle& t) override {
    ops[static_cast<int>(t.op)]++;
    return psq::Status();
  }
  psq::Status finalize(uint32_t) override { return psq::Status(); }
  psq::Status finish() override { return psq::Status(); }
  uint64_t vertices = 0;
  uint64_t ops[5] = {0, 0, 0, 0, 0};
};

// Feeds an n x n grid (rows of quads as two triangles) to `conv`.
psq::Status feed_grid(psq::SequenceConverter& conv, uint32_t n) {
  const uint32_t w = n + 1;
  psq::PropertyValues none;
  PSQ_RETURN_IF_ERROR(conv.begin(psq::MeshSchema()));
  auto put_row = [&](uint32_t j) -> psq::Status {
    for (uint32_t i = 0; i < w; ++i) {
      double p[3] = {static_cast<double>(i), static_cast<double>(j), 0};
      PSQ_RETURN_IF_ERROR(conv.vertex(j * w + i, p, none));
    }
    return psq::Status();
  };
  PSQ_RETURN_IF_ERROR(put_row(0));
  for (uint32_t j = 0; j < n; ++j) {
    PSQ_RETURN_IF_ERROR(put_row(j + 1));
    for (uint32_t i = 0; i < n; ++i) {
      uint32_t a = j * w + i, b = a + 1, c = a + w + 1, d = a + w;
      const uint32_t t0[3] = {a, b, c}, t1[3] = {a, c, d};
      PSQ_RETURN_IF_ERROR(conv.triangle(t0, none));
      PSQ_RETURN_IF_ERROR(conv.triangle(t1, none));
    }
    // Row j is used by no later triangle.
    for (uint32_t i = 0; i < w; ++i) PSQ_RETURN_IF_ERROR(conv.finalize(j * w + i));
  }
  for (uint32_t i = 0; i < w; ++i) PSQ_RETURN_IF_ERROR(conv.finalize(n * w + i));
  return conv.finish();
}

void BM_ConverterCoherentGrid(benchmark::State& state) {
  uint32_t n = static_cast<uint32_t>(state.range(0));
  for (auto _ : state) {
    CountingSink sink;
    psq::SequenceConverter conv(&sink);
    psq::Status s = feed_grid(conv, n);
    if (!s.ok()) state.SkipWithError(s.to_string().c_str());
    benchmark::DoNotOptimize(sink.vertices);
  }
  state.counters["triangles/s"] =
      benchmark::Counter(2.0 * n * n * static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}

void BM_CheckerCoherentGrid(benchmark::State& state) {
  uint32_t n = static_cast<uint32_t>(state.range(0));
  for (auto _ : state) {
    psq::SequenceChecker checker;
    psq::SequenceConverter conv(&checker);
    psq::Status s = feed_grid(conv, n);
    if (!s.ok()) state.SkipWithError(s.to_string().c_str());
  }
  state.counters["triangles/s"] =
      benchmark::Counter(2.0 * n * n * static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}

// A closed fan of n triangles around one vertex: the work around a vertex
// must stay linear in its valence (it was quadratic: 16 s at n = 100000).
void BM_ConverterFan(benchmark::State& state) {
  uint32_t n = static_cast<uint32_t>(state.range(0));
  psq::PropertyValues none;
  double p[3] = {0, 0, 0};
  for (auto _ : state) {
    CountingSink sink;
    psq::SequenceConverter conv(&sink);
    psq::Status s = conv.begin(psq::MeshSchema());
    for (uint32_t i = 0; s.ok() && i <= n; ++i) s = conv.vertex(i, p, none);
    for (uint32_t i = 0; s.ok() && i < n; ++i) {
      const uint32_t t[3] = {0, 1 + i, 1 + (i + 1) % n};
      s = conv.triangle(t, none);
    }
    for (uint32_t i = 0; s.ok() && i <= n; ++i) s = conv.finalize(i);
    if (s.ok()) s = conv.finish();
    if (!s.ok()) state.SkipWithError(s.to_string().c_str());
    benchmark::DoNotOptimize(sink.vertices);
  }
  state.counters["triangles/s"] =
      benchmark::Counter(static_cast<double>(n) * static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}

BENCHMARK(BM_ConverterCoherentGrid)->Arg(1000)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_ConverterFan)->Arg(100000)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_CheckerCoherentGrid)->Arg(1000)->Unit(benchmark::kMillisecond);

}  // namespace
