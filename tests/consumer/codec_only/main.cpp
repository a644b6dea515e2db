// SPDX-License-Identifier: Apache-2.0
// A codec-only application of an installed psq: encodes a tetrahedron in
// memory and decodes it back, linking psq::codec alone.
#include <cstdio>
#include <vector>

#include "psq/psq_memory.h"

int main() {
  const float p[12] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1};
  const uint32_t t[12] = {0, 2, 1, 0, 1, 3, 1, 2, 3, 0, 3, 2};
  std::vector<uint8_t> bytes;
  psq::EncodeOptions options;
  options.lossless = true;
  psq::Status s = psq::encode_mesh(p, 4, t, 4, options, &bytes);
  psq::MeshBuffers mesh;
  if (s.ok()) s = psq::decode_mesh(bytes.data(), bytes.size(), &mesh);
  if (!s.ok()) {
    std::fprintf(stderr, "codec_consumer: %s\n", s.message().c_str());
    return 1;
  }
  if (mesh.positions.size() != 12 || mesh.indices.size() != 12) {
    std::fprintf(stderr, "codec_consumer: %zu positions, %zu indices\n", mesh.positions.size(), mesh.indices.size());
    return 1;
  }
  std::printf("codec_consumer: %zu bytes for a tetrahedron, decoded\n", bytes.size());
  return 0;
}
