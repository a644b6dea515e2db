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
#include <vector>

#include "psq/mesh_arrays.h"
#include "psq/psq_codec.h"
#include "psq/status.h"

namespace psq {

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
// beyond float range; on an error `mesh` is empty. A stream of several
// segments (EncodeOptions::segment_triangles) decodes on `threads` threads
// (0: one per core) into the same arrays, unless a vertex re-appears.
Status decode_mesh(const uint8_t* data, size_t size, MeshBuffers* mesh, int threads = 0);

}  // namespace psq

#endif  // PSQ_PSQ_MEMORY_H_
