// SPDX-License-Identifier: Apache-2.0
// Throughput of the range coder on adaptive bits (skewed 1:9), encode and
// decode.
//
//   build/bench/psq_bench_coder --benchmark_repetitions=3 --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>

#include <random>
#include <vector>

#include "range_coder.h"

namespace {

std::vector<int> skewed_bits(size_t n) {
  std::mt19937 rng(1);
  std::vector<int> bits(n);
  for (int& b : bits) b = rng() % 10 == 0;
  return bits;
}

void BM_EncodeBits(benchmark::State& state) {
  std::vector<int> bits = skewed_bits(1 << 20);
  std::vector<uint8_t> out;
  for (auto _ : state) {
    out.clear();
    psq::RangeEncoder enc(&out);
    psq::BitModel m;
    for (int b : bits) enc.encode_bit(m, b);
    enc.finish();
    benchmark::DoNotOptimize(out.data());
  }
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations() * bits.size()));
}

void BM_DecodeBits(benchmark::State& state) {
  std::vector<int> bits = skewed_bits(1 << 20);
  std::vector<uint8_t> bytes;
  psq::RangeEncoder enc(&bytes);
  psq::BitModel me;
  for (int b : bits) enc.encode_bit(me, b);
  enc.finish();
  for (auto _ : state) {
    psq::RangeDecoder dec(bytes.data(), bytes.size());
    psq::BitModel m;
    int sum = 0;
    for (size_t i = 0; i < bits.size(); ++i) sum += dec.decode_bit(m);
    benchmark::DoNotOptimize(sum);
  }
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations() * bits.size()));
}

BENCHMARK(BM_EncodeBits)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_DecodeBits)->Unit(benchmark::kMillisecond);

}  // namespace
