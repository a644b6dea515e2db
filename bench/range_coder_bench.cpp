// SPDX-License-Identifier: Apache-2.0
// Throughput of the range coder on adaptive bits (skewed 1:9) and on
// integers of mixed size, encode and decode.
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

std::vector<int32_t> residuals(size_t n) {
  std::mt19937 rng(2);
  std::vector<int32_t> v(n);
  for (int32_t& x : v) x = (static_cast<int32_t>(rng() % 2001) - 1000) >> (rng() % 8);
  return v;
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

void BM_EncodeInts(benchmark::State& state) {
  std::vector<int32_t> values = residuals(1 << 20);
  std::vector<uint8_t> out;
  for (auto _ : state) {
    out.clear();
    psq::RangeEncoder enc(&out);
    psq::IntegerModel m;
    for (int32_t v : values) enc.encode_int(m, v);
    enc.finish();
    benchmark::DoNotOptimize(out.data());
  }
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations() * values.size()));
}

void BM_DecodeInts(benchmark::State& state) {
  std::vector<int32_t> values = residuals(1 << 20);
  std::vector<uint8_t> bytes;
  psq::RangeEncoder enc(&bytes);
  psq::IntegerModel me;
  for (int32_t v : values) enc.encode_int(me, v);
  enc.finish();
  for (auto _ : state) {
    psq::RangeDecoder dec(bytes.data(), bytes.size());
    psq::IntegerModel m;
    int64_t sum = 0;
    for (size_t i = 0; i < values.size(); ++i) sum += dec.decode_int(m);
    benchmark::DoNotOptimize(sum);
  }
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations() * values.size()));
}

BENCHMARK(BM_EncodeBits)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_DecodeBits)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_EncodeInts)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_DecodeInts)->Unit(benchmark::kMillisecond);

}  // namespace
