// SPDX-License-Identifier: Apache-2.0
// psq/mesh_arrays.h: a triangle mesh as two flat arrays (MeshBuffers), and
// the sequence sink that fills them (MeshArraySink): the mesh of a
// processing sequence, with the vertices that re-appear at non-manifold
// cuts merged back into their first occurrence. decode_mesh()
// (psq/psq_memory.h) is the .psq decoder pumping into this sink.
#ifndef PSQ_MESH_ARRAYS_H_
#define PSQ_MESH_ARRAYS_H_

#include <cstddef>
#include <cstdint>
#include <memory>
#include <new>
#include <utility>
#include <vector>

#include "psq/sequence.h"
#include "psq/status.h"

namespace psq {

// The allocator of MeshBuffers' arrays: std::allocator's memory, but an
// element added without a value (resize(n), emplace_back(), a vector(n))
// is default-initialized, which for float and uint32_t means not written
// at all, where std::allocator zeroes it. decode_mesh() sizes its arrays
// ahead and then writes every element once; zeroing them first would be a
// pass over memory that the decoder then writes again.
// Everything else behaves as for std::vector: data(), size(), iteration,
// push_back(). A caller who needs a std::vector<float> copies with
// assign(begin(), end()).
template <class T>
struct DefaultInitAllocator {
  using value_type = T;
  DefaultInitAllocator() noexcept = default;
  template <class U>
  DefaultInitAllocator(const DefaultInitAllocator<U>&) noexcept {}
  T* allocate(size_t n) { return std::allocator<T>().allocate(n); }
  void deallocate(T* p, size_t n) noexcept { std::allocator<T>().deallocate(p, n); }
  template <class U>
  void construct(U* p) noexcept(noexcept(::new (static_cast<void*>(p)) U)) {
    ::new (static_cast<void*>(p)) U;  // default-initialized: no value written
  }
  template <class U, class... Args>
  void construct(U* p, Args&&... args) {
    ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
  }
};
template <class T, class U>
bool operator==(const DefaultInitAllocator<T>&, const DefaultInitAllocator<U>&) noexcept {
  return true;
}
template <class T, class U>
bool operator!=(const DefaultInitAllocator<T>&, const DefaultInitAllocator<U>&) noexcept {
  return false;
}

// A triangle mesh in memory. The arrays are std::vectors with the
// allocator above: resize() leaves new elements unset. (They are not
// std::vector<float> and std::vector<uint32_t>: code that needs those
// types copies.)
struct MeshBuffers {
  std::vector<float, DefaultInitAllocator<float>> positions;      // x, y, z of each vertex
  std::vector<uint32_t, DefaultInitAllocator<uint32_t>> indices;  // the three vertex indices of each triangle
};

// A SequenceSink that keeps the mesh of the sequence in `mesh` (replacing
// its contents at begin()): each new vertex's position as floats, each
// triangle's three vertex indices, a re-appearing vertex as the vertex it
// re-appears (so the mesh is the one that was encoded, up to the order of
// vertices and triangles). Properties are not kept. A position beyond
// float range is refused (kLimit) rather than stored as an infinity.
//
// mesh_arrays() hands the arrays to producers that can write them
// directly (the .psq decoder's PsqDecoder::pump does): the same mesh,
// without a call per event.
class MeshArraySink : public SequenceSink {
 public:
  explicit MeshArraySink(MeshBuffers* mesh) : mesh_(mesh) {}
  Status begin(const MeshSchema& schema) override;
  Status vertex(const SequenceVertex& v) override;
  Status triangle(const SequenceTriangle& t) override;
  Status finalize(uint32_t) override { return Status(); }
  Status finish() override { return Status(); }
  MeshBuffers* mesh_arrays() override { return mesh_; }

 private:
  MeshBuffers* mesh_;
  // The mesh index of each sequence vertex once one has re-appeared (the
  // identity until then, not stored).
  bool identity_ = true;
  std::vector<uint32_t> index_;
  uint32_t vertices_ = 0;  // sequence vertices so far
};

}  // namespace psq

#endif  // PSQ_MESH_ARRAYS_H_
