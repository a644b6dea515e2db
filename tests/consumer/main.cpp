// SPDX-License-Identifier: Apache-2.0
// An application of an installed psq, as README.md shows it: writes a
// one-triangle PLY and reads it back, encodes and decodes a mesh in memory,
// and streams a .psq through a SequenceSink (the README's surface area).
#include <array>
#include <cmath>
#include <cstdio>
#include <string>

#include "psq/mesh_formats.h"
#include "psq/mesh_stats.h"
#include "psq/io.h"
#include "psq/ply.h"
#include "psq/psq_codec.h"
#include "psq/psq_memory.h"

// README.md's streaming example, as written there.
struct SurfaceArea : psq::SequenceSink {
  psq::BoundaryData<std::array<double, 3>> position;  // by boundary slot
  double area = 0;
  psq::Status begin(const psq::MeshSchema&) override { return {}; }
  psq::Status vertex(const psq::SequenceVertex& v) override {
    position[v.slot] = {v.position[0], v.position[1], v.position[2]};
    return {};
  }
  psq::Status triangle(const psq::SequenceTriangle& t) override {
    const auto &a = position[t.vslot[0]], &b = position[t.vslot[1]], &c = position[t.vslot[2]];
    double u[3], w[3];
    for (int k = 0; k < 3; ++k) u[k] = b[k] - a[k], w[k] = c[k] - a[k];
    area += 0.5 * std::sqrt(std::pow(u[1] * w[2] - u[2] * w[1], 2) + std::pow(u[2] * w[0] - u[0] * w[2], 2) +
                            std::pow(u[0] * w[1] - u[1] * w[0], 2));
    return {};
  }
  psq::Status finalize(uint32_t) override { return {}; }
  psq::Status finish() override { return {}; }
};

// The area of the unit cube's surface, streamed from a .psq file at `path`.
int stream_cube_area(const std::string& path) {
  const float p[24] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 0, 0, 1, 1, 0, 1, 1, 1, 1, 0, 1, 1};
  const uint32_t t[36] = {0, 2, 1, 0, 3, 2, 4, 5, 6, 4, 6, 7, 0, 1, 5, 0, 5, 4,
                          1, 2, 6, 1, 6, 5, 2, 3, 7, 2, 7, 6, 3, 0, 4, 3, 4, 7};
  std::vector<uint8_t> bytes;
  psq::EncodeOptions options;
  options.lossless = true;
  psq::Status s = psq::encode_mesh(p, 8, t, 12, options, &bytes);
  psq::OutputFile file;
  if (s.ok()) s = file.open(path, true);
  if (s.ok()) s = file.write(bytes.data(), bytes.size());
  if (s.ok()) s = file.commit();

  psq::InputStream in;
  psq::PsqDecoder decoder;
  SurfaceArea sink;
  if (s.ok()) s = in.open(path);
  if (s.ok()) s = decoder.open(&in);
  if (s.ok()) s = decoder.pump(sink);
  if (!s.ok()) {
    std::fprintf(stderr, "%s\n", s.to_string().c_str());
    return 1;
  }
  std::printf("streamed: surface area %g\n", sink.area);
  return std::fabs(sink.area - 6.0) < 1e-9 ? 0 : 1;
}

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
  if (back.positions.size() != 9 || back.indices.size() != 3) return 1;
  return stream_cube_area(path + ".psq");
}
