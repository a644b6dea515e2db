// SPDX-License-Identifier: Apache-2.0
// codec/src/parallel.cpp: decoding the segments of a stream at once
// (spec/psq-format.md 4.6, 4.7), with the checks that tie them together
// (psq/psq_codec.h, decode_segments()), and decode_mesh() on every core.
#include <algorithm>
#include <atomic>
#include <thread>

#include "decoder_impl.h"
#include "psq/mesh_arrays.h"
#include "psq/psq_memory.h"

namespace psq {

// The decoder's state, for the functions of this file (a friend).
class SegmentRun {
 public:
  static PsqDecoder::Impl& of(PsqDecoder& d) { return *d.impl_; }
};

namespace {

// What a segment decoded alone leaves for the checks of all of them.
struct SegmentResult {
  bool ran = false;
  Status status;
  AloneResult alone;
  uint64_t index_at = 0;
  PsqStats stats;
};

void add_stats(const PsqStats& s, PsqStats* t) {
  for (uint64_t PsqStats::*f : {&PsqStats::vertices, &PsqStats::triangles, &PsqStats::chunks,
                                &PsqStats::chunk_overhead_bytes, &PsqStats::segments, &PsqStats::segment_bytes,
                                &PsqStats::record_bytes, &PsqStats::property_bytes, &PsqStats::attribute_bytes})
    t->*f += s.*f;
  t->connectivity_bits += s.connectivity_bits;
  t->geometry_bits += s.geometry_bits;
  t->max_active_vertices = std::max(t->max_active_vertices, s.max_active_vertices);
  t->max_open_edges = std::max(t->max_open_edges, s.max_open_edges);
  for (int i = 0; i < 4; ++i) t->gates[i] += s.gates[i];
  for (int i = 0; i < 2; ++i) t->far_gates[i] += s.far_gates[i];
  for (int i = 0; i < 5; ++i) t->predictions[i] += s.predictions[i];
}

int thread_count(int threads, size_t segments) {
  if (threads <= 0) threads = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  return static_cast<int>(std::min<size_t>(static_cast<size_t>(threads), segments));
}

// A decoder opened on the stream that `open` opens, for `use`.
Status with_decoder(const std::function<Status(InputStream*)>& open,
                    const std::function<Status(PsqDecoder&, InputStream&)>& use) {
  InputStream in;
  PSQ_RETURN_IF_ERROR(open(&in));
  PsqDecoder d;
  PSQ_RETURN_IF_ERROR(d.open(&in));
  return use(d, in);
}

}  // namespace

Status decode_segments(const std::function<Status(InputStream*)>& open, int threads,
                       const std::function<Status(PsqDecoder&, size_t)>& work, PsqStats* stats) {
  std::vector<PsqSegment> segs;
  uint64_t size = 0;
  PSQ_RETURN_IF_ERROR(with_decoder(open, [&](PsqDecoder& d, InputStream& in) {
    size = static_cast<uint64_t>(in.size());
    return d.segments(&segs);
  }));
  const size_t n = segs.size();
  std::vector<SegmentResult> res(n);
  std::atomic<size_t> next{0};
  std::atomic<bool> failed{false};
  auto run = [&] {
    for (;;) {
      if (failed.load()) return;
      const size_t k = next.fetch_add(1);
      if (k >= n) return;
      SegmentResult& r = res[k];
      r.ran = true;
      r.status = with_decoder(open, [&](PsqDecoder& d, InputStream&) {
        PSQ_RETURN_IF_ERROR(d.start_segment(segs[k]));
        PSQ_RETURN_IF_ERROR(work(d, k));
        auto& m = SegmentRun::of(d);
        if (!m.ended) return Status(ErrorCode::kUsage, "a segment's work did not decode it to its end");
        r.alone = std::move(m.alone_result);
        r.index_at = m.index_at;
        r.stats = m.stats;
        return Status();
      });
      if (!r.status.ok()) {
        failed.store(true);
        return;
      }
    }
  };
  const int t = thread_count(threads, n);
  std::vector<std::thread> pool;
  for (int i = 1; i < t; ++i) pool.emplace_back(run);
  run();
  for (std::thread& th : pool) th.join();
  for (const SegmentResult& r : res)
    if (r.ran && !r.status.ok()) return r.status;
  // Every segment ran (no failure stopped them). Spec 4.6: each ends
  // where the next begins, in the state that the next one's block holds.
  for (size_t k = 0; k + 1 < n; ++k) {
    if (res[k].alone.reached_end || res[k].alone.stopped_at != segs[k + 1].offset)
      return Status(ErrorCode::kBadHeader, "index: segment " + std::to_string(k + 1) +
                                               " does not begin where the one before it ends",
                    segs[k + 1].offset);
    if (res[k].alone.end_state != res[k + 1].alone.start_state)
      return Status(ErrorCode::kBadValue, "segment record: its state block is not the decoder's state",
                    segs[k + 1].offset);
  }
  const AloneResult& last = res.back().alone;
  if (!last.reached_end) return Status(ErrorCode::kBadHeader, "the last segment does not reach the end record", size);
  // Spec 4.5: the stream checksum over every segment's checksum fields.
  uint32_t crc = res[0].alone.header_chain;
  for (const SegmentResult& r : res) crc = crc32c_update(crc, r.alone.chain_fields.data(), r.alone.chain_fields.size());
  crc = crc32c_update(crc, last.end_bytes.data(), last.end_bytes.size());
  if (!checksum_ok(last.end_checksum, crc)) return Status(ErrorCode::kChecksum, "stream checksum mismatch", size - 4);
  PsqStats total;
  for (const SegmentResult& r : res) add_stats(r.stats, &total);
  total.header_bytes = res[0].stats.header_bytes;
  total.total_bytes = size;
  // segments() read the index at the offset the end record gives.
  PSQ_RETURN_IF_ERROR(
      check_end(last.end_fields, last.end_index_at, res.back().index_at, total, size - 4 - last.end_bytes.size()));
  if (stats) *stats = total;
  return Status();
}

Status decode_mesh_segments(const std::function<Status(InputStream*)>& open, int threads, MeshBuffers* mesh,
                            const std::function<Status(size_t, size_t, size_t, size_t)>& flush) {
  auto cannot = [](const char* why) { return Status(ErrorCode::kUnsupported, why); };
  std::vector<PsqSegment> segs;
  PsqSegment end;
  PsqHeader header;
  PSQ_RETURN_IF_ERROR(with_decoder(open, [&](PsqDecoder& d, InputStream&) {
    header = d.header();
    return d.segments(&segs, &end).ok() ? Status() : cannot("the stream's index cannot be read");
  }));
  // Each segment writes its part of the arrays, between its index entry's
  // counts and the next one's (the end record's totals for the last).
  // Its vertices are the mesh's vertices in order unless one re-appears
  // (spec 2.2), whose mesh index another segment knows: such a stream
  // cannot be decoded this way (decode_range() says so).
  std::vector<PsqSegment> bounds = segs;
  bounds.push_back(end);
  for (size_t k = 0; k + 1 < bounds.size(); ++k)
    if (bounds[k].vertices > bounds[k + 1].vertices || bounds[k].triangles > bounds[k + 1].triangles ||
        bounds[k + 1].offset <= bounds[k].offset)
      return cannot("the index's counts do not grow");
  // The arrays' pages are touched only as the segments write them.
  mesh->positions.resize(3 * static_cast<size_t>(end.vertices));
  mesh->indices.resize(3 * static_cast<size_t>(end.triangles));
  auto work = [&](PsqDecoder& d, size_t k) {
    auto& m = SegmentRun::of(d);
    m.direct_flush = flush;
    return m.decode_range(mesh, 3 * static_cast<size_t>(bounds[k].vertices), 3 * static_cast<size_t>(bounds[k + 1].vertices),
                          3 * static_cast<size_t>(bounds[k].triangles), 3 * static_cast<size_t>(bounds[k + 1].triangles));
  };
  PSQ_RETURN_IF_ERROR(decode_segments(open, threads, work, nullptr));
  return check_float_range(header, *mesh);
}

Status decode_mesh(const uint8_t* data, size_t size, MeshBuffers* mesh, int threads) {
  Status s(ErrorCode::kUnsupported, "one thread");
  // A stream of several segments on every core; one that cannot be
  // decoded so (kUnsupported) by one thread, which also reports what is
  // wrong with a damaged stream in stream order. A stream of one segment
  // takes the one-thread path at once: decode_mesh_segments() would
  // decode it on this thread too, into arrays sized before the decoder's
  // tables, which in a process that decodes again and again left the
  // arrays' pages to be faulted in anew each time (bench/RESULTS.md,
  // "Speed ratios to Draco within one invocation").
  auto open = [&](InputStream* in) {
    in->open_memory(data, size, "<memory>");
    return Status();
  };
  std::vector<PsqSegment> segs;
  if (threads != 1 && with_decoder(open, [&](PsqDecoder& d, InputStream&) { return d.segments(&segs); }).ok() &&
      segs.size() > 1)
    s = decode_mesh_segments(open, threads, mesh, nullptr);
  if (s.code() == ErrorCode::kUnsupported) {
    s = with_decoder(open, [&](PsqDecoder& d, InputStream&) {
      MeshArraySink sink(mesh);  // which empties the arrays
      return d.pump(sink);
    });
  }
  if (!s.ok()) {
    mesh->positions.clear();
    mesh->indices.clear();
  }
  return s;
}

}  // namespace psq
