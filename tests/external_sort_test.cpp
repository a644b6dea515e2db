// SPDX-License-Identifier: Apache-2.0
// ExternalSorter: in memory, spilled runs, intermediate merge passes, custom
// comparators, temporary-file cleanup and usage errors.
#include <gtest/gtest.h>

#include <dirent.h>

#include <algorithm>
#include <cstdint>
#include <random>
#include <string>
#include <tuple>
#include <vector>

#include "external_sort.h"
#include "test_util.h"

namespace psq {
namespace {

// The converter's record shape: a sort key and a tie-breaking id.
struct Keyed {
  uint64_t key;
  uint32_t id;
  uint32_t pad;
};
static_assert(sizeof(Keyed) == 16);

struct KeyThenId {
  bool operator()(const Keyed& a, const Keyed& b) const {
    if (a.key != b.key) return a.key < b.key;
    return a.id < b.id;
  }
};

// An odd record size, to exercise buffer arithmetic that is not a power of 2.
struct Triple {
  uint32_t a, b, c;
};

struct TripleLess {
  bool operator()(const Triple& x, const Triple& y) const {
    return std::tie(x.a, x.b, x.c) < std::tie(y.a, y.b, y.c);
  }
};

constexpr uint64_t kMiB = uint64_t{1} << 20;

uint64_t mix(uint64_t x) {  // splitmix64's finalizer
  x += 0x9e3779b97f4a7c15ull;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
  return x ^ (x >> 31);
}

// An order-independent fingerprint of a multiset of records.
struct Fingerprint {
  uint64_t count = 0;
  uint64_t sum = 0;
  uint64_t sum_sq = 0;
  void add(const Keyed& r) {
    uint64_t h = mix(r.key ^ mix(r.id));
    ++count;
    sum += h;
    sum_sq += h * h;
  }
  bool operator==(const Fingerprint& o) const {
    return count == o.count && sum == o.sum && sum_sq == o.sum_sq;
  }
};

std::vector<Keyed> random_records(size_t n, uint64_t key_range, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::vector<Keyed> v(n);
  for (size_t i = 0; i < n; ++i) {
    v[i] = Keyed{key_range == 0 ? rng() : rng() % key_range, static_cast<uint32_t>(i), 0};
  }
  return v;
}

// Sorts `input` with `sorter` and returns the output.
template <class T, class Less>
std::vector<T> sort_all(ExternalSorter<T, Less>* sorter, const std::vector<T>& input) {
  std::vector<T> out;
  for (const T& r : input) {
    Status s = sorter->add(r);
    EXPECT_TRUE(s.ok()) << s.to_string();
    if (!s.ok()) return out;
  }
  Status s = sorter->finish();
  EXPECT_TRUE(s.ok()) << s.to_string();
  if (!s.ok()) return out;
  out.reserve(input.size());
  for (;;) {
    T r;
    bool done = false;
    s = sorter->next(&r, &done);
    EXPECT_TRUE(s.ok()) << s.to_string();
    if (!s.ok() || done) break;
    out.push_back(r);
  }
  return out;
}

bool same(const std::vector<Keyed>& a, const std::vector<Keyed>& b) {
  return a.size() == b.size() &&
         std::equal(a.begin(), a.end(), b.begin(), [](const Keyed& x, const Keyed& y) {
           return x.key == y.key && x.id == y.id;
         });
}

#ifdef __linux__
size_t open_descriptors() {
  size_t n = 0;
  if (DIR* d = ::opendir("/proc/self/fd")) {
    while (::readdir(d) != nullptr) ++n;
    ::closedir(d);
  }
  return n;
}
#endif

TEST(ExternalSort, EmptyInput) {
  test::TempDir dir;
  ExternalSortOptions options;
  options.tmpdir = dir.path();
  ExternalSorter<uint64_t> sorter(options);
  ASSERT_TRUE(sorter.finish().ok());
  uint64_t r = 7;
  bool done = false;
  ASSERT_TRUE(sorter.next(&r, &done).ok());
  EXPECT_TRUE(done);
  EXPECT_EQ(r, 7u);
  ASSERT_TRUE(sorter.next(&r, &done).ok());  // and stays done
  EXPECT_TRUE(done);
  EXPECT_EQ(sorter.size(), 0u);
  EXPECT_EQ(sorter.runs(), 0u);
}

TEST(ExternalSort, AllInMemory) {
  test::TempDir dir;
  ExternalSortOptions options;
  options.tmpdir = dir.path();
  options.memory_budget = 4 * kMiB;
  std::vector<Keyed> input = random_records(50000, 1000, 1);  // 800 KB, many ties
  ExternalSorter<Keyed, KeyThenId> sorter(options);
  std::vector<Keyed> out = sort_all(&sorter, input);
  std::vector<Keyed> expected = input;
  std::sort(expected.begin(), expected.end(), KeyThenId());
  EXPECT_TRUE(same(out, expected));
  EXPECT_EQ(sorter.size(), input.size());
  EXPECT_EQ(sorter.runs(), 0u);
  EXPECT_EQ(sorter.merge_passes(), 0u);
}

TEST(ExternalSort, ManyRunsWithATinyBudget) {
  // 3 million 16-byte records (48 MB) under a 1 MiB budget: about 46 runs of
  // 64 Ki records, more than the fan-in of 15, so one intermediate pass.
  test::TempDir dir;
  ExternalSortOptions options;
  options.tmpdir = dir.path();
  options.memory_budget = kMiB;
  ExternalSorter<Keyed, KeyThenId> sorter(options);
  EXPECT_EQ(sorter.fan_in(), 15u);
  std::mt19937_64 rng(2);
  Fingerprint in;
  const uint32_t n = 3000000;
  for (uint32_t i = 0; i < n; ++i) {
    Keyed r{rng(), i, 0};
    in.add(r);
    ASSERT_TRUE(sorter.add(r).ok());
  }
  Status s = sorter.finish();
  ASSERT_TRUE(s.ok()) << s.to_string();
  EXPECT_GT(sorter.runs(), 40u);
  EXPECT_EQ(sorter.merge_passes(), 1u);
  Fingerprint out;
  Keyed previous{0, 0, 0};
  bool sorted = true;
  for (;;) {
    Keyed r;
    bool done = false;
    s = sorter.next(&r, &done);
    ASSERT_TRUE(s.ok()) << s.to_string();
    if (done) break;
    if (out.count > 0 && KeyThenId()(r, previous)) sorted = false;
    previous = r;
    out.add(r);
  }
  EXPECT_TRUE(sorted);
  EXPECT_TRUE(out == in) << out.count << " records out, " << in.count << " in";
  EXPECT_TRUE(dir.entries().empty());
}

TEST(ExternalSort, IntermediateMergePasses) {
  // About 11 runs merged 2 and 3 at a time: several passes, including a
  // first pass that merges only some of the runs.
  std::vector<Keyed> input = random_records(700000, 50000, 3);
  std::vector<Keyed> expected = input;
  std::sort(expected.begin(), expected.end(), KeyThenId());
  for (uint32_t fan_in : {2u, 3u}) {
    SCOPED_TRACE(fan_in);
    test::TempDir dir;
    ExternalSortOptions options;
    options.tmpdir = dir.path();
    options.memory_budget = kMiB;
    options.max_fan_in = fan_in;
    ExternalSorter<Keyed, KeyThenId> sorter(options);
    EXPECT_EQ(sorter.fan_in(), fan_in);
    std::vector<Keyed> out = sort_all(&sorter, input);
    EXPECT_TRUE(same(out, expected));
    EXPECT_GE(sorter.runs(), 10u);
    EXPECT_GE(sorter.merge_passes(), fan_in == 2 ? 3u : 2u);
    EXPECT_TRUE(dir.entries().empty());
  }
}

TEST(ExternalSort, CustomComparatorAndOddRecordSize) {
  test::TempDir dir;
  ExternalSortOptions options;
  options.tmpdir = dir.path();
  options.memory_budget = kMiB;

  // Heavy ties on the key, broken by the id: one exact order.
  std::vector<Keyed> keyed = random_records(300000, 100, 4);
  std::vector<Keyed> expected = keyed;
  std::sort(expected.begin(), expected.end(), KeyThenId());
  ExternalSorter<Keyed, KeyThenId> by_key(options);
  EXPECT_TRUE(same(sort_all(&by_key, keyed), expected));
  EXPECT_GT(by_key.runs(), 1u);

  // 12-byte records, sorted descending by a capturing lambda.
  std::mt19937 rng(5);
  std::vector<Triple> triples(250000);
  for (Triple& t : triples) {
    t = Triple{static_cast<uint32_t>(rng() % 7), static_cast<uint32_t>(rng() % 1000),
               static_cast<uint32_t>(rng())};
  }
  auto greater = [less = TripleLess()](const Triple& x, const Triple& y) { return less(y, x); };
  ExternalSorter<Triple, decltype(greater)> descending(options, greater);
  std::vector<Triple> out = sort_all(&descending, triples);
  std::sort(triples.begin(), triples.end(), greater);
  ASSERT_EQ(out.size(), triples.size());
  auto equal = [](const Triple& x, const Triple& y) {
    return x.a == y.a && x.b == y.b && x.c == y.c;
  };
  EXPECT_TRUE(std::equal(out.begin(), out.end(), triples.begin(), equal));
  EXPECT_GT(descending.runs(), 1u);
}

TEST(ExternalSort, SameOutputWhateverTheBudget) {
  // With a total comparator the output does not depend on the budget.
  std::vector<Keyed> input = random_records(200000, 10, 6);
  test::TempDir dir;
  std::vector<std::vector<Keyed>> outputs;
  for (uint64_t budget : {uint64_t{0}, kMiB, 64 * kMiB}) {
    ExternalSortOptions options;
    options.tmpdir = dir.path();
    options.memory_budget = budget;  // 0 is raised to the minimum
    ExternalSorter<Keyed, KeyThenId> sorter(options);
    outputs.push_back(sort_all(&sorter, input));
  }
  EXPECT_TRUE(same(outputs[0], outputs[1]));
  EXPECT_TRUE(same(outputs[0], outputs[2]));
  EXPECT_EQ(outputs[0].size(), input.size());
}

TEST(ExternalSort, ReserveKeepsTheOutput) {
  // reserve() sizes the run buffer up front: exactly, beyond the budget
  // (runs still spill at the budget), short of the input (the buffer grows
  // or spills after it) or not at all; the output is the same.
  std::vector<Keyed> input = random_records(100000, 1000, 7);
  test::TempDir dir;
  std::vector<std::vector<Keyed>> outputs;
  for (uint64_t budget : {kMiB, 64 * kMiB}) {
    for (uint64_t reserve : {uint64_t{0}, uint64_t{1000}, uint64_t{100000}, uint64_t{1} << 40}) {
      ExternalSortOptions options;
      options.tmpdir = dir.path();
      options.memory_budget = budget;
      ExternalSorter<Keyed, KeyThenId> sorter(options);
      sorter.reserve(reserve);
      outputs.push_back(sort_all(&sorter, input));
      EXPECT_EQ(sorter.runs() > 0, budget == kMiB) << budget << " " << reserve;
    }
  }
  for (size_t i = 1; i < outputs.size(); ++i) EXPECT_TRUE(same(outputs[0], outputs[i])) << i;
  EXPECT_EQ(outputs[0].size(), input.size());
}

TEST(ExternalSort, TemporaryFilesNeverOutliveTheSorter) {
  test::TempDir dir;
#ifdef __linux__
  const size_t descriptors = open_descriptors();
#endif
  {
    ExternalSortOptions options;
    options.tmpdir = dir.path();
    options.memory_budget = kMiB;
    options.max_fan_in = 2;
    ExternalSorter<Keyed, KeyThenId> sorter(options);
    std::vector<Keyed> input = random_records(400000, 0, 7);
    for (const Keyed& r : input) ASSERT_TRUE(sorter.add(r).ok());
    EXPECT_GT(sorter.runs(), 3u);
    EXPECT_TRUE(dir.entries().empty());  // unlinked at creation
    ASSERT_TRUE(sorter.finish().ok());
    EXPECT_GT(sorter.merge_passes(), 0u);
    for (int i = 0; i < 1000; ++i) {
      Keyed r;
      bool done = false;
      ASSERT_TRUE(sorter.next(&r, &done).ok());
      ASSERT_FALSE(done);
    }
    EXPECT_TRUE(dir.entries().empty());
#ifdef __linux__
    EXPECT_GT(open_descriptors(), descriptors);
    EXPECT_LE(open_descriptors(), descriptors + 3);
#endif
    // Moving a sorter in the middle of its merge keeps its state.
    ExternalSorter<Keyed, KeyThenId> moved(std::move(sorter));
    Keyed r;
    bool done = false;
    ASSERT_TRUE(moved.next(&r, &done).ok());
    EXPECT_FALSE(done);
  }  // destroyed before reading everything
  EXPECT_TRUE(dir.entries().empty());
#ifdef __linux__
  EXPECT_EQ(open_descriptors(), descriptors);
#endif
}

TEST(ExternalSort, UsageErrors) {
  ExternalSorter<uint32_t> sorter;
  uint32_t r;
  bool done;
  EXPECT_EQ(sorter.next(&r, &done).code(), ErrorCode::kUsage);
  ASSERT_TRUE(sorter.add(3).ok());
  ASSERT_TRUE(sorter.add(1).ok());
  ASSERT_TRUE(sorter.finish().ok());
  EXPECT_EQ(sorter.add(2).code(), ErrorCode::kUsage);
  EXPECT_EQ(sorter.finish().code(), ErrorCode::kUsage);
  ASSERT_TRUE(sorter.next(&r, &done).ok());
  EXPECT_FALSE(done);
  EXPECT_EQ(r, 1u);
  ASSERT_TRUE(sorter.next(&r, &done).ok());
  EXPECT_EQ(r, 3u);
  ASSERT_TRUE(sorter.next(&r, &done).ok());
  EXPECT_TRUE(done);
  EXPECT_EQ(sorter.add(2).code(), ErrorCode::kUsage);
}

TEST(ExternalSort, UnwritableTemporaryDirectoryIsAnIoError) {
  test::TempDir dir;
  ExternalSortOptions options;
  options.tmpdir = dir.file("missing");
  options.memory_budget = kMiB;
  ExternalSorter<uint64_t> sorter(options);
  Status s;
  uint64_t added = 0;
  while (s.ok() && added < 1000000) s = sorter.add(added++);
  EXPECT_EQ(s.code(), ErrorCode::kIo) << s.to_string();
  EXPECT_NE(s.message().find("missing"), std::string::npos) << s.message();
  // The error is sticky.
  EXPECT_EQ(sorter.add(1).code(), ErrorCode::kIo);
  EXPECT_EQ(sorter.finish().code(), ErrorCode::kIo);
  uint64_t r;
  bool done;
  EXPECT_EQ(sorter.next(&r, &done).code(), ErrorCode::kIo);
}

}  // namespace
}  // namespace psq
