// SPDX-License-Identifier: Apache-2.0
// The encoder fuzz target's oracle (tests/fuzz/fuzz_encoder.cpp) in every
// build, GCC and sanitizers included: its seed corpus, then inputs mutated
// from it by a fixed pseudo-random generator. The oracle aborts on a
// violation (a sequence whose slot hints change the encoder's outcome or
// bytes, or an accepted stream that does not decode), which fails the test.
#include <gtest/gtest.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <vector>

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size);

namespace {

std::vector<std::vector<uint8_t>> seeds() {
  std::vector<std::vector<uint8_t>> out;
  for (const auto& entry : std::filesystem::directory_iterator(PSQ_ENCODER_CORPUS)) {
    std::ifstream f(entry.path(), std::ios::binary);
    out.emplace_back(std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>());
  }
  return out;
}

TEST(EncoderHints, SeedCorpusHoldsTheOracle) {
  const auto corpus = seeds();
  ASSERT_GE(corpus.size(), 8u);
  for (const auto& s : corpus) LLVMFuzzerTestOneInput(s.data(), s.size());
}

// Mutations as a fuzzer makes them: bytes changed, inserted and removed,
// and mutation records (3 bytes each, past the triangles) appended.
TEST(EncoderHints, MutatedInputsHoldTheOracle) {
  const auto corpus = seeds();
  ASSERT_FALSE(corpus.empty());
  std::mt19937 rng(20261127);
  for (int round = 0; round < 1000; ++round) {
    std::vector<uint8_t> in = corpus[rng() % corpus.size()];
    const int edits = 1 + static_cast<int>(rng() % 8);
    for (int e = 0; e < edits; ++e) {
      const uint32_t r = rng();
      switch (r % 4) {
        case 0:
          if (!in.empty()) in[rng() % in.size()] = static_cast<uint8_t>(rng());
          break;
        case 1:
          in.insert(in.begin() + static_cast<std::ptrdiff_t>(rng() % (in.size() + 1)), static_cast<uint8_t>(rng()));
          break;
        case 2:
          if (in.size() > 3) in.erase(in.begin() + static_cast<std::ptrdiff_t>(3 + rng() % (in.size() - 3)));
          break;
        default:
          for (int k = 0; k < 3; ++k) in.push_back(static_cast<uint8_t>(rng()));
          break;
      }
    }
    LLVMFuzzerTestOneInput(in.data(), in.size());
  }
}

}  // namespace
