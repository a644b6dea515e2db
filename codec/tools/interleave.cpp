// SPDX-License-Identifier: Apache-2.0
// psq_interleave: writes the conformance vector with far gates of every
// kind (spec/psq-format.md 13.7.4, 13.7.5 and 12): named by a recency rank,
// and by slot in an escape.
//
// The converter grows one region at a time, so a small mesh converted by
// `psq convert` never needs a gate beyond the recency ranks, named by its
// slot. This tool makes a processing sequence that does: it decodes a
// .psq stream, places `--copies` copies of its mesh side by side, and
// interleaves their records in runs of 1 to 6 records, choosing the next
// copy at random (std::mt19937 with `--seed`, whose output the C++ standard
// fixes, so the bytes are the same everywhere). Each record is a triangle
// with the vertices it introduces and the finalizations after it. The
// result is a valid sequence of many regions growing at once, encoded at
// `--bits` bits.
//
// Usage: psq_interleave IN.psq OUT.psq [--copies N] [--seed S] [--bits B]
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <string>
#include <vector>

#include "psq/io.h"
#include "psq/psq_codec.h"

namespace {

int fail(const std::string& what) {
  std::fprintf(stderr, "psq_interleave: %s\n", what.c_str());
  return 1;
}

// Collects the decoded events, grouped into records.
struct Records : psq::SequenceSink {
  psq::MeshSchema schema;
  std::vector<std::vector<psq::SequenceEvent>> records;
  std::vector<psq::SequenceEvent> open;
  bool has_triangle = false;
  psq::Status begin(const psq::MeshSchema& s) override {
    schema = s;
    return psq::Status();
  }
  using Kind = psq::SequenceEvent::Kind;
  // Appends an event of `kind` to the open record and returns it to be
  // filled in; a vertex or a triangle after the record's triangle starts
  // the next record.
  psq::SequenceEvent& add(Kind kind) {
    if (kind != Kind::kFinalize && has_triangle) close();
    has_triangle = has_triangle || kind == Kind::kTriangle;
    open.emplace_back();
    open.back().kind = kind;
    return open.back();
  }
  void close() {
    records.push_back(std::move(open));
    open.clear();
    has_triangle = false;
  }
  psq::Status vertex(const psq::SequenceVertex& v) override {
    add(Kind::kVertex).vertex = v;
    return psq::Status();
  }
  psq::Status triangle(const psq::SequenceTriangle& t) override {
    add(Kind::kTriangle).triangle = t;
    return psq::Status();
  }
  psq::Status finalize(uint32_t index) override {
    add(Kind::kFinalize).finalized = index;
    return psq::Status();
  }
  psq::Status finish() override {
    if (!open.empty()) close();
    return psq::Status();
  }
};

}  // namespace

int main(int argc, char** argv) {
  using namespace psq;
  std::string in_path, out_path;
  int copies = 40, bits = 14;
  uint32_t seed = 5;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--copies" && i + 1 < argc) copies = std::atoi(argv[++i]);
    else if (a == "--seed" && i + 1 < argc) seed = static_cast<uint32_t>(std::strtoul(argv[++i], nullptr, 10));
    else if (a == "--bits" && i + 1 < argc) bits = std::atoi(argv[++i]);
    else if (in_path.empty() && a[0] != '-') in_path = a;
    else if (out_path.empty() && a[0] != '-') out_path = a;
    else return fail("usage: psq_interleave IN.psq OUT.psq [--copies N] [--seed S] [--bits B]");
  }
  if (in_path.empty() || out_path.empty() || copies < 1 || copies > 1000)
    return fail("usage: psq_interleave IN.psq OUT.psq [--copies N (1..1000)] [--seed S] [--bits B]");

  InputStream in;
  Status s = in.open(in_path);
  PsqDecoder dec;
  Records rec;
  if (s.ok()) s = dec.open(&in);
  if (s.ok()) s = dec.pump(rec);
  if (!s.ok()) return fail(in_path + ": " + s.to_string());
  if (!rec.schema.face_properties.empty() || !rec.schema.vertex_properties.empty())
    return fail(in_path + ": a mesh without properties is expected");

  // The copies sit on a grid of 8 columns, one mesh extent plus a gap apart.
  double lo[3] = {0, 0, 0}, hi[3] = {0, 0, 0};
  bool first = true;
  for (const auto& r : rec.records)
    for (const SequenceEvent& e : r)
      if (e.kind == SequenceEvent::Kind::kVertex)
        for (int i = 0; i < 3; ++i) {
          const double x = e.vertex.position[i];
          if (first || x < lo[i]) lo[i] = x;
          if (first || x > hi[i]) hi[i] = x;
          if (i == 2) first = false;
        }
  const double pitch = 1.5 * std::max(hi[0] - lo[0], hi[1] - lo[1]);
  MeshSchema schema = rec.schema;
  schema.vertex_count = schema.triangle_count = -1;
  schema.has_bounds = true;
  for (int i = 0; i < 3; ++i) {
    schema.bounds_min[i] = lo[i];
    schema.bounds_max[i] = hi[i];
  }
  schema.bounds_max[0] += pitch * std::min(copies - 1, 7);
  schema.bounds_max[1] += pitch * ((copies - 1) / 8);

  std::vector<uint8_t> bytes;
  VectorWriter writer(&bytes);
  EncodeOptions opt;
  opt.bits = bits;
  PsqEncoder enc(&writer, opt);
  s = enc.begin(schema);
  std::mt19937 rng(seed);
  std::vector<size_t> next(static_cast<size_t>(copies), 0);
  // (copy, input index) -> output index, per copy.
  std::vector<std::vector<uint32_t>> index(static_cast<size_t>(copies));
  uint32_t next_index = 0;
  while (s.ok()) {
    std::vector<int> open;
    for (int c = 0; c < copies; ++c)
      if (next[c] < rec.records.size()) open.push_back(c);
    if (open.empty()) break;
    const int c = open[rng() % open.size()];
    std::vector<uint32_t>& map = index[c];
    for (int run = 1 + static_cast<int>(rng() % 6); s.ok() && run > 0 && next[c] < rec.records.size(); --run) {
      for (SequenceEvent e : rec.records[next[c]++]) {
        if (e.kind == SequenceEvent::Kind::kVertex) {
          if (e.vertex.index >= map.size()) map.resize(e.vertex.index + 1, 0);
          map[e.vertex.index] = next_index;
          e.vertex.index = next_index++;
          e.vertex.slot = kNoSlot;
          if (e.vertex.reappears != kNoVertex) e.vertex.reappears = map[e.vertex.reappears];
          for (int i = 0; i < 2; ++i) {
            // Still a float (the schema's position type); volatile: the
            // GCC 12 trap of ../shared/toolchain.
            volatile float moved = static_cast<float>(e.vertex.position[i] + pitch * (i == 0 ? c % 8 : c / 8));
            e.vertex.position[i] = moved;
          }
          s = enc.vertex(e.vertex);
        } else if (e.kind == SequenceEvent::Kind::kTriangle) {
          for (int k = 0; k < 3; ++k) {
            e.triangle.v[k] = map[e.triangle.v[k]];
            e.triangle.vslot[k] = e.triangle.eslot[k] = kNoSlot;
          }
          s = enc.triangle(e.triangle);
        } else {
          s = enc.finalize(map[e.finalized]);
        }
        if (!s.ok()) break;
      }
    }
  }
  if (s.ok()) s = enc.finish();
  if (!s.ok()) return fail(out_path + ": " + s.to_string());
  std::FILE* f = std::fopen(out_path.c_str(), "wb");
  if (!f || std::fwrite(bytes.data(), 1, bytes.size(), f) != bytes.size() || std::fclose(f) != 0)
    return fail(out_path + ": cannot write");
  const PsqStats& st = enc.stats();
  std::printf("psq_interleave: %s: %llu triangles, far gates by rank %llu, by slot %llu\n",
              out_path.c_str(), static_cast<unsigned long long>(st.triangles),
              static_cast<unsigned long long>(st.far_gates[0]), static_cast<unsigned long long>(st.far_gates[1]));
  return 0;
}
