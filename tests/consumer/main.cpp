// Writes a one-triangle PLY to memory-free stdout-less temp path, reads it back
// through the installed library, and checks the counts.
#include <cstdio>
#include <string>

#include "psq/mesh_formats.h"
#include "psq/mesh_stats.h"
#include "psq/ply.h"
#include "psq/psq_memory.h"

int main(int argc, char** argv) {
  if (argc != 2) return 2;
  std::string path = argv[1];
  psq::OutputFile out;
  psq::Status s = out.open(path, true);
  if (!s.ok()) return 1;
  psq::PlyWriter writer(&out);
  psq::MeshSchema schema;
  schema.vertex_count = 3;
  schema.triangle_count = 1;
  const double p[3][3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  const uint32_t t[3] = {0, 1, 2};
  if (!writer.begin(schema).ok()) return 1;
  for (const auto& v : p) {
    if (!writer.vertex(v, {}).ok()) return 1;
  }
  if (!writer.triangle(t, {}).ok() || !writer.finish().ok() || !out.commit().ok()) return 1;

  psq::OpenedMesh mesh;
  if (!psq::open_mesh(path, {}, &mesh).ok()) return 1;
  psq::MeshStats stats;
  s = psq::pump(*mesh.source, stats);
  if (!s.ok()) {
    std::fprintf(stderr, "%s\n", s.to_string().c_str());
    return 1;
  }
  std::printf("vertices %llu triangles %llu\n", static_cast<unsigned long long>(stats.result().vertices),
              static_cast<unsigned long long>(stats.result().triangles));
  if (stats.result().vertices != 3 || stats.result().triangles != 1) return 1;

  // The in-memory door: the triangle to .psq bytes and back.
  const float fp[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  std::vector<uint8_t> bytes;
  s = psq::encode_mesh(fp, 3, t, 1, psq::EncodeOptions(), &bytes);
  psq::MeshBuffers back;
  if (s.ok()) s = psq::decode_mesh(bytes.data(), bytes.size(), &back);
  if (!s.ok()) {
    std::fprintf(stderr, "%s\n", s.to_string().c_str());
    return 1;
  }
  std::printf("in memory: %zu bytes, %zu vertices, %zu triangles\n", bytes.size(), back.positions.size() / 3,
              back.indices.size() / 3);
  return back.positions.size() == 9 && back.indices.size() == 3 ? 0 : 1;
}
