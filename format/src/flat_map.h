// SPDX-License-Identifier: Apache-2.0
// A hash map from uint64_t keys for the per-boundary and per-cut tables of
// SequenceChecker and SequenceCounter: open addressing with linear probing
// and backward-shift deletion, so that no element costs an allocation.
#ifndef PSQ_FORMAT_FLAT_MAP_H_
#define PSQ_FORMAT_FLAT_MAP_H_

#include <cstddef>
#include <cstdint>
#include <vector>

namespace psq::detail {

// uint64_t -> V. Key ~0 is reserved (never a dense index, nor a pair of them).
template <class V>
class FlatMap {
 public:
  FlatMap() { rehash(64); }
  size_t size() const { return size_; }
  V* find(uint64_t key) {
    for (size_t i = hash(key);; i = (i + 1) & mask_) {
      if (cells_[i].key == kEmpty) return nullptr;
      if (cells_[i].key == key) return &cells_[i].value;
    }
  }
  // False (and nothing changed) when the key is there already. Invalidates
  // pointers from find().
  bool insert(uint64_t key, const V& value) {
    if (2 * (size_ + 1) > cells_.size()) rehash(2 * cells_.size());
    size_t i = hash(key);
    for (; cells_[i].key != kEmpty; i = (i + 1) & mask_) {
      if (cells_[i].key == key) return false;
    }
    cells_[i].key = key;
    cells_[i].value = value;
    ++size_;
    return true;
  }
  // The value of `key`, inserted as V() when absent. Invalidates pointers
  // from find().
  V& operator[](uint64_t key) {
    if (V* v = find(key)) return *v;
    insert(key, V());
    return *find(key);
  }
  void erase(uint64_t key) {
    size_t i = hash(key);
    while (cells_[i].key != key) {
      if (cells_[i].key == kEmpty) return;
      i = (i + 1) & mask_;
    }
    for (size_t j = (i + 1) & mask_; cells_[j].key != kEmpty; j = (j + 1) & mask_) {
      size_t home = hash(cells_[j].key);
      if (((j - home) & mask_) >= ((j - i) & mask_)) {
        cells_[i] = cells_[j];
        i = j;
      }
    }
    cells_[i].key = kEmpty;
    --size_;
  }
  // Calls f(key, value) for every element.
  template <class F>
  void for_each(F f) const {
    for (const Cell& c : cells_) {
      if (c.key != kEmpty) f(c.key, c.value);
    }
  }

 private:
  static constexpr uint64_t kEmpty = ~uint64_t{0};
  struct Cell {
    uint64_t key = kEmpty;
    V value{};
  };
  size_t hash(uint64_t key) const { return static_cast<size_t>((key * 0x9E3779B97F4A7C15ull) >> 24) & mask_; }
  void rehash(size_t capacity) {
    std::vector<Cell> old(capacity);
    old.swap(cells_);
    mask_ = capacity - 1;
    size_ = 0;
    for (const Cell& c : old) {
      if (c.key != kEmpty) insert(c.key, c.value);
    }
  }
  std::vector<Cell> cells_;
  size_t mask_ = 0;
  size_t size_ = 0;
};

}  // namespace psq::detail

#endif  // PSQ_FORMAT_FLAT_MAP_H_
