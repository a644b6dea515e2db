// SPDX-License-Identifier: Apache-2.0
// Where the time of `psq convert` goes: each stage of PLY -> .psq and of
// .psq -> PLY timed on its own, by running the pipeline cut after it (the
// same library calls as tools/cli/cmd_convert.cpp, output to /dev/null so
// that no disk write is in the loop).
//
//   psq_bench_convert_stages [--runs N] [--bits B] X.ply X.psq
//
// X.psq is the `psq convert X.ply X.psq` output to time decoding on. Each
// stage runs --runs times (default 3); the median is printed, as a
// Markdown table. Times are processor seconds of the process (user and
// system, all threads), which a busy shared machine disturbs less than
// wall time.
#include <algorithm>
#include <ctime>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "psq/mesh_formats.h"
#include "psq/psq_codec.h"
#include "psq/sequence_builder.h"
#include "psq/threaded_sink.h"

namespace {

using psq::Status;

// Processor time of the whole process (both threads when the encoder has
// its own): on a shared machine it moves less than wall time does.
double now() {
  timespec ts;
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

struct NullMeshSink : psq::MeshSink {
  Status begin(const psq::MeshSchema&) override { return Status(); }
  Status vertex(const double[3], const psq::PropertyValues&) override { return Status(); }
  Status triangle(const uint32_t[3], const psq::PropertyValues&) override { return Status(); }
  Status finish() override { return Status(); }
};

struct NullSequenceSink : psq::SequenceSink {
  Status begin(const psq::MeshSchema&) override { return Status(); }
  Status vertex(const psq::SequenceVertex&) override { return Status(); }
  Status triangle(const psq::SequenceTriangle&) override { return Status(); }
  Status finalize(uint32_t) override { return Status(); }
  Status finish() override { return Status(); }
};

// A source that notes when its input ends: build_sequence() has then read
// and spooled everything, and the rest is the sort or the one pass.
struct TimedSource : psq::MeshSource {
  psq::MeshSource* in = nullptr;
  double end_time = 0;
  const psq::MeshSchema& schema() const override { return in->schema(); }
  const psq::SourceReport& report() const override { return in->report(); }
  Status next(psq::MeshItem* item) override {
    Status s = in->next(item);
    if (s.ok() && item->kind == psq::MeshItem::Kind::kEnd && end_time == 0) end_time = now();
    return s;
  }
};

void check(const Status& s, const std::string& what) {
  if (!s.ok()) {
    std::fprintf(stderr, "psq_bench_convert_stages: %s: %s\n", what.c_str(), s.to_string().c_str());
    std::exit(1);
  }
}

void open(const std::string& path, psq::OpenedMesh* mesh) {
  psq::OpenOptions o;
  check(psq::open_mesh(path, o, mesh), path);
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.size() % 2 ? v[v.size() / 2] : (v[v.size() / 2 - 1] + v[v.size() / 2]) / 2;
}

}  // namespace

int main(int argc, char** argv) {
  int runs = 3, bits = 14;
  std::vector<std::string> files;
  for (int i = 1; i < argc; ++i) {
    std::string a = argv[i];
    if (a == "--runs" && i + 1 < argc) runs = std::atoi(argv[++i]);
    else if (a == "--bits" && i + 1 < argc) bits = std::atoi(argv[++i]);
    else files.push_back(a);
  }
  if (files.size() != 2 || runs < 1) {
    std::fprintf(stderr, "usage: psq_bench_convert_stages [--runs N] [--bits B] X.ply X.psq\n");
    return 2;
  }
  const std::string ply = files[0], psqf = files[1];
  psq::EncodeOptions eo;
  eo.bits = bits;
  eo.fast = true;

  struct Row {
    std::string name;
    std::vector<double> t;
  };
  std::vector<Row> rows;
  auto add = [&](const std::string& name, double seconds) {
    for (Row& r : rows) {
      if (r.name == name) {
        r.t.push_back(seconds);
        return;
      }
    }
    rows.push_back(Row{name, {seconds}});
  };
  bool sorted = false;
  psq::ConverterStats converter_stats;
  for (int run = 0; run < runs; ++run) {
    {  // 1. Reading alone.
      psq::OpenedMesh m;
      double t0 = now();
      open(ply, &m);
      NullMeshSink sink;
      check(psq::pump(*m.source, sink), "read");
      add("read PLY (open_mesh, pump to a null sink)", now() - t0);
    }
    {  // 2. Reading, spooling, sorting or one pass, converter.
      psq::OpenedMesh m;
      double t0 = now();
      open(ply, &m);
      TimedSource src;
      src.in = m.source.get();
      NullSequenceSink sink;
      psq::BuildOptions bo;
      psq::BuildReport report;
      check(psq::build_sequence(src, sink, bo, &report), "build");
      double t1 = now();
      sorted = report.sorted;
      converter_stats = report.converter;
      add("read + spool (build_sequence until the input ends)", src.end_time - t0);
      add("read + spool + sequence (build_sequence to a null sink)", t1 - t0);
    }
    for (int threads : {1, 2}) {  // 3. And the encoder, on this thread or a second.
      psq::OpenedMesh m;
      double t0 = now();
      open(ply, &m);
      psq::OutputFile out;
      check(out.open("/dev/null", true), "/dev/null");
      psq::FileWriter writer(&out);
      psq::PsqEncoder encoder(&writer, eo);
      std::unique_ptr<psq::ThreadedSequenceSink> threaded;
      if (threads > 1) threaded = std::make_unique<psq::ThreadedSequenceSink>(&encoder);
      psq::SequenceSink* sink = threaded ? static_cast<psq::SequenceSink*>(threaded.get()) : &encoder;
      psq::BuildOptions bo;
      psq::BuildReport report;
      check(psq::build_sequence(*m.source, *sink, bo, &report), "encode");
      threaded.reset();
      check(out.commit(), "/dev/null");
      add(threads == 1 ? "... + encode, one thread (to /dev/null)" : "... + encode, two threads (to /dev/null)",
          now() - t0);
    }
    {  // 4. Decoding the sequence alone.
      psq::OpenedMesh m;
      double t0 = now();
      open(psqf, &m);
      if (!m.decoder) check(Status(psq::ErrorCode::kUsage, "not a .psq"), psqf);
      NullSequenceSink sink;
      check(m.decoder->pump(sink), "decode");
      add("decode the sequence (PsqDecoder::pump to a null sink)", now() - t0);
    }
    {  // 5. As a mesh (indices of the sequence made into the mesh's).
      psq::OpenedMesh m;
      double t0 = now();
      open(psqf, &m);
      NullMeshSink sink;
      check(psq::pump(*m.source, sink), "decode as mesh");
      add("decode as a mesh (PsqMeshSource to a null sink)", now() - t0);
    }
    {  // 6. And the PLY writer.
      psq::OpenedMesh m;
      double t0 = now();
      open(psqf, &m);
      psq::OutputFile out;
      check(out.open("/dev/null", true), "/dev/null");
      psq::WriteOptions wo;
      std::unique_ptr<psq::MeshSink> writer = psq::make_mesh_writer(psq::MeshFormat::kPly, &out, wo);
      check(psq::pump(*m.source, *writer), "write PLY");
      check(out.commit(), "/dev/null");
      add("... + binary PLY writer (to /dev/null)", now() - t0);
    }
  }
  std::printf("%s (%s path; the converter held at most %llu triangles and %llu vertices), %s; median of %d runs\n\n",
              ply.c_str(), sorted ? "sort" : "one-pass",
              static_cast<unsigned long long>(converter_stats.max_waiting_triangles),
              static_cast<unsigned long long>(converter_stats.max_waiting_vertices), psqf.c_str(), runs);
  std::printf("| stage | processor seconds |\n|---|---:|\n");
  for (const Row& r : rows) std::printf("| %s | %.3f |\n", r.name.c_str(), median(r.t));
  return 0;
}
