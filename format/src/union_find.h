// SPDX-License-Identifier: Apache-2.0
// Union-find over dense indices, grown as vertices arrive, for the
// topology counts of SequenceChecker and SequenceCounter (components,
// border loops, holes).
#ifndef PSQ_FORMAT_UNION_FIND_H_
#define PSQ_FORMAT_UNION_FIND_H_

#include <cstdint>
#include <utility>
#include <vector>

namespace psq::detail {

class UnionFind {
 public:
  uint32_t add() {
    parent_.push_back(static_cast<uint32_t>(parent_.size()));
    return parent_.back();
  }
  // Path halving keeps the trees flat without recursion.
  uint32_t find(uint32_t x) {
    while (parent_[x] != x) {
      parent_[x] = parent_[parent_[x]];
      x = parent_[x];
    }
    return x;
  }
  // True when x and y were in different sets. The smaller root stays, so
  // that a set is named by its first element.
  bool unite(uint32_t x, uint32_t y) {
    x = find(x);
    y = find(y);
    if (x == y) return false;
    if (x < y) std::swap(x, y);
    parent_[x] = y;
    ++unions_;
    return true;
  }
  // The number of sets among the nodes added.
  uint64_t sets() const { return parent_.size() - unions_; }

 private:
  std::vector<uint32_t> parent_;
  uint64_t unions_ = 0;
};

// Keys of edges between two dense indices, for FlatMap.
inline uint64_t directed_edge(uint32_t a, uint32_t b) { return (uint64_t{a} << 32) | b; }
inline uint64_t undirected_edge(uint32_t a, uint32_t b) { return a < b ? directed_edge(a, b) : directed_edge(b, a); }

}  // namespace psq::detail

#endif  // PSQ_FORMAT_UNION_FIND_H_
