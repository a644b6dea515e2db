// SPDX-License-Identifier: Apache-2.0
// A map from 32-bit ids to 32-bit values for the waiting areas of format/
// (the converter's vertex pool, DenseMeshSink's renumbering): open
// addressing with linear probing and backward-shift deletion, so that a
// map that stays about the same size costs no allocation once warm. The
// key 0xffffffff is reserved (it marks empty cells).
#ifndef PSQ_FORMAT_ID_MAP_H_
#define PSQ_FORMAT_ID_MAP_H_

#include <cstddef>
#include <cstdint>
#include <vector>

namespace psq::detail {

class IdMap {
 public:
  static constexpr uint32_t kEmpty = 0xffffffffu;

  IdMap() { rehash(1024); }
  size_t size() const { return size_; }
  // Bytes of its table.
  size_t bytes() const { return cells_.capacity() * sizeof(Cell); }
  // The value of `id`, or kEmpty.
  uint32_t find(uint32_t id) const {
    for (size_t i = hash(id);; i = (i + 1) & mask_) {
      if (cells_[i].key == kEmpty) return kEmpty;
      if (cells_[i].key == id) return cells_[i].value;
    }
  }
  void insert(uint32_t id, uint32_t value) {
    if (2 * (size_ + 1) > cells_.size()) rehash(2 * cells_.size());
    size_t i = hash(id);
    while (cells_[i].key != kEmpty) i = (i + 1) & mask_;
    cells_[i] = Cell{id, value};
    ++size_;
  }
  void erase(uint32_t id) {
    size_t i = hash(id);
    while (cells_[i].key != id) {
      if (cells_[i].key == kEmpty) return;
      i = (i + 1) & mask_;
    }
    // Shift later members of the probe run back into the hole.
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
  template <class F>
  void for_each(F f) const {
    for (const Cell& c : cells_) {
      if (c.key != kEmpty) f(c.key, c.value);
    }
  }

 private:
  struct Cell {
    uint32_t key;
    uint32_t value;
  };
  size_t hash(uint32_t id) const { return (uint64_t{id} * 0x9E3779B97F4A7C15ull >> 20) & mask_; }
  void rehash(size_t capacity) {
    std::vector<Cell> old(capacity, Cell{kEmpty, 0});
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

#endif  // PSQ_FORMAT_ID_MAP_H_
