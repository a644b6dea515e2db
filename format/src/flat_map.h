// SPDX-License-Identifier: Apache-2.0
// Hash maps from integer keys for the tables of format/ (the boundaries and
// cuts of SequenceChecker and SequenceCounter, the converter's vertex pool,
// DenseMeshSink's renumbering): open addressing with linear probing and
// backward-shift deletion, so that no element costs an allocation and a map
// that stays about the same size costs none once warm.
#ifndef PSQ_FORMAT_FLAT_MAP_H_
#define PSQ_FORMAT_FLAT_MAP_H_

#include <cstddef>
#include <cstdint>
#include <vector>

namespace psq::detail {

// K -> V, K an unsigned integer. The key with every bit set is reserved
// (never a dense index, nor a pair of them): it marks empty cells.
template <class V, class K = uint64_t>
class FlatMap {
 public:
  static constexpr K kEmpty = static_cast<K>(~K{0});

  explicit FlatMap(size_t capacity = 64) { rehash(capacity); }
  size_t size() const { return size_; }
  // Bytes of its table.
  size_t bytes() const { return cells_.capacity() * sizeof(Cell); }
  V* find(K key) { return const_cast<V*>(static_cast<const FlatMap*>(this)->find(key)); }
  const V* find(K key) const {
    for (size_t i = hash(key);; i = (i + 1) & mask_) {
      if (cells_[i].key == kEmpty) return nullptr;
      if (cells_[i].key == key) return &cells_[i].value;
    }
  }
  // False (and nothing changed) when the key is there already. Invalidates
  // pointers from find().
  bool insert(K key, const V& value) {
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
  V& operator[](K key) {
    if (V* v = find(key)) return *v;
    insert(key, V());
    return *find(key);
  }
  void erase(K key) {
    size_t i = hash(key);
    while (cells_[i].key != key) {
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
  // Calls f(key, value) for every element, in no particular order.
  template <class F>
  void for_each(F f) const {
    for (const Cell& c : cells_) {
      if (c.key != kEmpty) f(c.key, c.value);
    }
  }

 private:
  struct Cell {
    K key = kEmpty;
    V value{};
  };
  // Fibonacci hashing: the top bits of the product mix every bit of the
  // key, packed cells and pairs of indices included.
  size_t hash(K key) const { return static_cast<size_t>((uint64_t{key} * 0x9E3779B97F4A7C15ull) >> shift_); }
  // `capacity` is a power of two, at least 2.
  void rehash(size_t capacity) {
    std::vector<Cell> old(capacity);
    old.swap(cells_);
    mask_ = capacity - 1;
    shift_ = 64;
    for (size_t c = capacity; c > 1; c >>= 1) --shift_;
    size_ = 0;
    for (const Cell& c : old) {
      if (c.key != kEmpty) insert(c.key, c.value);
    }
  }
  std::vector<Cell> cells_;
  size_t mask_ = 0;
  int shift_ = 64;
  size_t size_ = 0;
};

// K -> a 32-bit index, where a missing key reads as kNone.
template <class K>
class IndexMap : public FlatMap<uint32_t, K> {
 public:
  static constexpr uint32_t kNone = 0xffffffffu;
  explicit IndexMap(size_t capacity = 64) : FlatMap<uint32_t, K>(capacity) {}
  // The value of `key`, or kNone.
  uint32_t find(K key) const {
    const uint32_t* v = FlatMap<uint32_t, K>::find(key);
    return v ? *v : kNone;
  }
};

// The converter's vertex pool and DenseMeshSink's renumbering: 32-bit ids,
// where kEmpty (0xffffffff) is both the reserved id and "absent".
class IdMap : public IndexMap<uint32_t> {
 public:
  IdMap() : IndexMap(1024) {}
};

}  // namespace psq::detail

#endif  // PSQ_FORMAT_FLAT_MAP_H_
