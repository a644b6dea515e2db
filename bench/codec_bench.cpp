// SPDX-License-Identifier: Apache-2.0
// Speed of the .psq encoder and decoder, in memory, parsing excluded:
// - encode: a processing sequence held in memory (built once from the mesh)
//   replayed into PsqEncoder writing to a byte vector;
// - decode: PsqDecoder::pump over those bytes into a sink that discards
//   (the work of `psq verify`).
// Meshes: each .ply under ../shared/data/meshes that is 200k triangles or
// more (when present), and a generated wavy torus of 2M triangles.
// Counters: triangles per second, bits per vertex.
//
//   build/bench/psq_bench_codec --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <dirent.h>
#include <memory>
#include <string>
#include <vector>

#include "psq/mesh_formats.h"
#include "psq/psq_codec.h"
#include "psq/sequence_builder.h"

namespace {

struct Recorded : psq::SequenceSink {
  psq::MeshSchema schema;
  std::vector<psq::SequenceEvent> events;
  uint64_t triangles = 0;
  psq::Status begin(const psq::MeshSchema& s) override {
    schema = s;
    return psq::Status();
  }
  psq::Status vertex(const psq::SequenceVertex& v) override {
    events.emplace_back();
    events.back().kind = psq::SequenceEvent::Kind::kVertex;
    events.back().vertex = v;
    return psq::Status();
  }
  psq::Status triangle(const psq::SequenceTriangle& t) override {
    events.emplace_back();
    events.back().kind = psq::SequenceEvent::Kind::kTriangle;
    events.back().triangle = t;
    ++triangles;
    return psq::Status();
  }
  psq::Status finalize(uint32_t i) override {
    events.emplace_back();
    events.back().kind = psq::SequenceEvent::Kind::kFinalize;
    events.back().finalized = i;
    return psq::Status();
  }
  psq::Status finish() override { return psq::Status(); }
};

// A wavy torus of n x m quads (2nm triangles), float positions, coherent
// order (rows of vertices, then rows of quads).
class TorusSource : public psq::MeshSource {
 public:
  TorusSource(int n, int m) : n_(n), m_(m) {
    schema_.vertex_count = static_cast<int64_t>(n) * m;
    schema_.triangle_count = 2 * schema_.vertex_count;
  }
  const psq::MeshSchema& schema() const override { return schema_; }
  const psq::SourceReport& report() const override { return report_; }
  psq::Status next(psq::MeshItem* item) override {
    item->values.clear();
    const int64_t nv = schema_.vertex_count;
    if (at_ < nv) {
      item->kind = psq::MeshItem::Kind::kVertex;
      const double u = 2 * M_PI * static_cast<double>(at_ / m_) / n_;
      const double v = 2 * M_PI * static_cast<double>(at_ % m_) / m_;
      const double r = 0.4 + 0.03 * std::sin(9 * u) * std::cos(7 * v);
      // volatile: GCC 12 -O2 drops the float rounding otherwise (../shared/toolchain)
      volatile float p[3] = {static_cast<float>((1 + r * std::cos(v)) * std::cos(u)),
                             static_cast<float>((1 + r * std::cos(v)) * std::sin(u)), static_cast<float>(r * std::sin(v))};
      for (int k = 0; k < 3; ++k) item->position[k] = p[k];
      ++at_;
      return psq::Status();
    }
    const int64_t t = at_ - nv;
    if (t >= schema_.triangle_count) {
      item->kind = psq::MeshItem::Kind::kEnd;
      return psq::Status();
    }
    ++at_;
    item->kind = psq::MeshItem::Kind::kTriangle;
    const int64_t q = t / 2, i = q / m_, j = q % m_;
    auto id = [&](int64_t a, int64_t b) { return static_cast<uint32_t>((a % n_) * m_ + (b % m_)); };
    const uint32_t a = id(i, j), b = id(i, j + 1), c = id(i + 1, j), d = id(i + 1, j + 1);
    if (t % 2 == 0) {
      item->index[0] = a, item->index[1] = c, item->index[2] = d;
    } else {
      item->index[0] = a, item->index[1] = d, item->index[2] = b;
    }
    return psq::Status();
  }

 private:
  int n_, m_;
  int64_t at_ = 0;
  psq::MeshSchema schema_;
  psq::SourceReport report_;
};

struct Discard : psq::SequenceSink {
  psq::Status begin(const psq::MeshSchema&) override { return psq::Status(); }
  psq::Status vertex(const psq::SequenceVertex&) override { return psq::Status(); }
  psq::Status triangle(const psq::SequenceTriangle&) override { return psq::Status(); }
  psq::Status finalize(uint32_t) override { return psq::Status(); }
  psq::Status finish() override { return psq::Status(); }
};

struct Case {
  std::string name;
  std::unique_ptr<Recorded> seq;
};

std::vector<Case>& cases() {
  static std::vector<Case> all;
  return all;
}

void load(const std::string& name, psq::MeshSource& src) {
  auto rec = std::make_unique<Recorded>();
  psq::BuildOptions o;
  psq::BuildReport r;
  psq::Status s = psq::build_sequence(src, *rec, o, &r);
  if (!s.ok()) {
    std::fprintf(stderr, "%s: %s\n", name.c_str(), s.to_string().c_str());
    return;
  }
  cases().push_back({name, std::move(rec)});
}

psq::Status replay(const Recorded& r, psq::SequenceSink& sink) {
  PSQ_RETURN_IF_ERROR(sink.begin(r.schema));
  for (const psq::SequenceEvent& e : r.events) {
    if (e.kind == psq::SequenceEvent::Kind::kVertex) {
      PSQ_RETURN_IF_ERROR(sink.vertex(e.vertex));
    } else if (e.kind == psq::SequenceEvent::Kind::kTriangle) {
      PSQ_RETURN_IF_ERROR(sink.triangle(e.triangle));
    } else {
      PSQ_RETURN_IF_ERROR(sink.finalize(e.finalized));
    }
  }
  return sink.finish();
}

void BM_Encode(benchmark::State& state, const Case* c, int bits) {
  psq::EncodeOptions o;
  o.bits = bits > 0 ? bits : 16;
  o.lossless = bits == 0;
  std::vector<uint8_t> bytes;
  uint64_t vertices = 0;
  for (auto _ : state) {
    bytes.clear();
    psq::VectorWriter w(&bytes);
    psq::PsqEncoder enc(&w, o);
    psq::Status s = replay(*c->seq, enc);
    if (!s.ok()) state.SkipWithError(s.to_string().c_str());
    vertices = enc.stats().vertices;
  }
  state.counters["tri/s"] = benchmark::Counter(static_cast<double>(c->seq->triangles) * state.iterations(),
                                               benchmark::Counter::kIsRate);
  state.counters["bpv"] = 8.0 * bytes.size() / static_cast<double>(vertices ? vertices : 1);
}

void BM_Decode(benchmark::State& state, const Case* c, int bits) {
  psq::EncodeOptions o;
  o.bits = bits > 0 ? bits : 16;
  o.lossless = bits == 0;
  std::vector<uint8_t> bytes;
  psq::VectorWriter w(&bytes);
  psq::PsqEncoder enc(&w, o);
  if (!replay(*c->seq, enc).ok()) state.SkipWithError("encode failed");
  for (auto _ : state) {
    psq::InputStream in;
    in.open_memory(bytes.data(), bytes.size());
    psq::PsqDecoder dec;
    psq::Status s = dec.open(&in);
    Discard discard;
    if (s.ok()) s = dec.pump(discard);
    if (!s.ok()) state.SkipWithError(s.to_string().c_str());
  }
  state.counters["tri/s"] = benchmark::Counter(static_cast<double>(c->seq->triangles) * state.iterations(),
                                               benchmark::Counter::kIsRate);
}

}  // namespace

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  const std::string dir = std::string(PSQ_SHARED_DATA) + "/meshes";
  if (DIR* d = opendir(dir.c_str())) {
    std::vector<std::string> names;
    while (dirent* e = readdir(d)) {
      std::string n = e->d_name;
      if (n.size() > 4 && n.substr(n.size() - 4) == ".ply") names.push_back(n);
    }
    closedir(d);
    std::sort(names.begin(), names.end());
    for (const std::string& n : names) {
      psq::OpenedMesh m;
      if (!psq::open_mesh(dir + "/" + n, psq::OpenOptions(), &m).ok()) continue;
      if (m.source->schema().triangle_count >= 0 && m.source->schema().triangle_count < 200000) continue;
      load(n, *m.source);
    }
  }
  TorusSource torus(1000, 1000);
  load("wavy_torus_2M", torus);
  for (const Case& c : cases()) {
    for (int bits : {16, 0}) {
      std::string tag = c.name + (bits ? "/q16" : "/lossless");
      benchmark::RegisterBenchmark(("encode/" + tag).c_str(), BM_Encode, &c, bits)->Unit(benchmark::kMillisecond);
      benchmark::RegisterBenchmark(("decode/" + tag).c_str(), BM_Decode, &c, bits)->Unit(benchmark::kMillisecond);
    }
  }
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
