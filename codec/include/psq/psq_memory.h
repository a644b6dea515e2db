// SPDX-License-Identifier: Apache-2.0
// psq/psq_memory.h: the in-memory door into the codec (DESIGN.md, layers):
// vertex and index arrays to .psq bytes and back, for meshes that fit in
// memory, as Draco and meshoptimizer offer. Applications whose meshes do
// not fit use the streaming encoder and decoder (psq/psq_codec.h), which
// these functions are built on.
#ifndef PSQ_PSQ_MEMORY_H_
#define PSQ_PSQ_MEMORY_H_

#include <cstddef>
#include <cstdint>
#include <memory>
#include <new>
#include <utility>
#include <vector>

#include "psq/psq_codec.h"
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

// Encodes the mesh of `vertex_count` vertices (`positions`: 3 floats each)
// and `triangle_count` triangles (`indices`: 3 each) and appends the .psq
// stream to `out`, with `options` as for PsqEncoder (quantization bits or
// lossless, entropy back-end, chunk size). The processing sequence is
// built as `psq convert` builds it (psq/sequence_builder.h): in one pass
// when the triangles are coherent, else through an external sort whose
// temporary files go to $TMPDIR. Degenerate triangles (a repeated index) are dropped.
// Errors: kBadValue for an index >= vertex_count or a position that is not
// finite, with the element's number; kLimit when the mesh exceeds the
// format's limits; kIo for the sort's files. On an error `out` is as it
// was.
Status encode_mesh(const float* positions, size_t vertex_count, const uint32_t* indices, size_t triangle_count,
                   const EncodeOptions& options, std::vector<uint8_t>* out);

// Decodes the .psq stream of `size` bytes at `data` into `mesh` (replacing
// its contents). The vertices come in the order the stream introduces
// them, with the vertices that re-appear at non-manifold cuts merged back
// into their first occurrence (so that the mesh is the encoded one, up to
// the order of vertices and triangles); triangles keep their orientation.
// Positions are converted to float. Vertex and face properties are not
// returned: read them with PsqDecoder. Errors: the decoder's (every one
// names the byte offset), and kLimit when a position of a double stream is
// beyond float range; on an error `mesh` is empty.
Status decode_mesh(const uint8_t* data, size_t size, MeshBuffers* mesh);

}  // namespace psq

#endif  // PSQ_PSQ_MEMORY_H_
