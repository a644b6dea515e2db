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
  static Status check_float_range(const PsqHeader& h, const MeshBuffers& m) {
    return PsqDecoder::Impl::check_float_range(h, m);
  }
};

namespace {

// What a segment decoded alone leaves for the checks of all of them.
struct SegmentResult {
  bool ran = false;
  Status status;
  std::vector<uint8_t> start_state, end_state, chain, end_bytes;
  uint32_t end_checksum = 0;
  uint64_t end_fields[5] = {0, 0, 0, 0, 0};
  uint64_t end_index_at = 0, stopped_at = 0, index_at = 0;
  bool reached_end = false;
  uint32_t header_chain = 0;
  PsqStats stats;
};

void add_stats(const PsqStats& s, PsqStats* t) {
  t->vertices += s.vertices;
  t->triangles += s.triangles;
  t->chunks += s.chunks;
  t->chunk_overhead_bytes += s.chunk_overhead_bytes;
  t->segments += s.segments;
  t->segment_bytes += s.segment_bytes;
  t->record_bytes += s.record_bytes;
  t->property_bytes += s.property_bytes;
  t->attribute_bytes += s.attribute_bytes;
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

}  // namespace

Status decode_segments(const std::function<Status(InputStream*)>& open, int threads,
                       const std::function<Status(PsqDecoder&, size_t)>& work, PsqStats* stats) {
  std::vector<PsqSegment> segs;
  uint64_t size = 0;
  {
    InputStream in;
    PSQ_RETURN_IF_ERROR(open(&in));
    PsqDecoder d;
    PSQ_RETURN_IF_ERROR(d.open(&in));
    PSQ_RETURN_IF_ERROR(d.segments(&segs));
    size = static_cast<uint64_t>(in.size());
  }
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
      InputStream in;
      PsqDecoder d;
      Status s = open(&in);
      if (s.ok()) s = d.open(&in);
      if (s.ok()) s = d.start_segment(segs[k]);
      if (s.ok()) s = work(d, k);
      auto& m = SegmentRun::of(d);
      if (s.ok() && !m.ended) s = Status(ErrorCode::kUsage, "a segment's work did not decode it to its end");
      r.status = s;
      if (!s.ok()) {
        failed.store(true);
        return;
      }
      r.start_state = std::move(m.start_state);
      r.end_state = std::move(m.end_state);
      r.chain = std::move(m.chain_fields);
      r.end_bytes = std::move(m.end_bytes);
      r.end_checksum = m.end_checksum;
      std::copy(m.end_fields, m.end_fields + 5, r.end_fields);
      r.end_index_at = m.end_index_at;
      r.index_at = m.index_at;
      r.stopped_at = m.stopped_at;
      r.reached_end = m.reached_end;
      r.header_chain = m.header_chain;
      r.stats = m.stats;
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
    if (res[k].reached_end || res[k].stopped_at != segs[k + 1].offset)
      return Status(ErrorCode::kBadHeader, "index: segment " + std::to_string(k + 1) +
                                               " does not begin where the one before it ends",
                    segs[k + 1].offset);
    if (res[k].end_state != res[k + 1].start_state)
      return Status(ErrorCode::kBadValue, "segment record: its state block is not the decoder's state",
                    segs[k + 1].offset);
  }
  const SegmentResult& last = res.back();
  if (!last.reached_end) return Status(ErrorCode::kBadHeader, "the last segment does not reach the end record", size);
  // Spec 4.5: the stream checksum over every segment's checksum fields.
  uint32_t crc = res[0].header_chain;
  for (const SegmentResult& r : res) crc = crc32c_update(crc, r.chain.data(), r.chain.size());
  crc = crc32c_update(crc, last.end_bytes.data(), last.end_bytes.size());
  const uint64_t end_at = size - 4 - last.end_bytes.size();
  if (!checksum_ok(last.end_checksum, crc)) return Status(ErrorCode::kChecksum, "stream checksum mismatch", size - 4);
  PsqStats total;
  for (const SegmentResult& r : res) add_stats(r.stats, &total);
  total.header_bytes = res[0].stats.header_bytes;
  total.total_bytes = size;
  auto bad = [&](const std::string& what) { return Status(ErrorCode::kBadHeader, "end record: " + what, end_at); };
  const uint64_t* f = last.end_fields;
  if (f[0] != total.vertices || f[1] != total.triangles || f[2] != total.chunks)
    return bad("totals " + std::to_string(f[0]) + " vertices, " + std::to_string(f[1]) + " triangles, " +
               std::to_string(f[2]) + " chunks differ from the stream's " + std::to_string(total.vertices) + ", " +
               std::to_string(total.triangles) + ", " + std::to_string(total.chunks));
  if (f[3] != total.max_active_vertices || f[4] != total.max_open_edges)
    return bad("boundary maxima differ from the stream's");
  // segments() read the index at the offset the end record gives.
  if (last.end_index_at == 0 || last.end_index_at != last.index_at)
    return bad("index offset " + std::to_string(last.end_index_at) + " is not the index's");
  if (stats) *stats = total;
  return Status();
}

Status decode_mesh_segments(const std::function<Status(InputStream*)>& open, int threads, MeshBuffers* mesh,
                            const std::function<Status(size_t, size_t, size_t, size_t)>& flush) {
  auto cannot = [](const char* why) { return Status(ErrorCode::kUnsupported, why); };
  std::vector<PsqSegment> segs;
  PsqSegment end;
  PsqHeader header;
  {
    InputStream in;
    PSQ_RETURN_IF_ERROR(open(&in));
    PsqDecoder d;
    PSQ_RETURN_IF_ERROR(d.open(&in));
    if (!d.segments(&segs, &end).ok()) return cannot("the stream's index cannot be read");
    header = d.header();
  }
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
  return SegmentRun::check_float_range(header, *mesh);
}

namespace {

// The segments of a stream in memory, by its index; 0 when it has none or
// it cannot be read (the one-thread path then reports why).
size_t segment_count(const uint8_t* data, size_t size) {
  InputStream in;
  in.open_memory(data, size, "<memory>");
  PsqDecoder d;
  std::vector<PsqSegment> segs;
  return d.open(&in).ok() && d.segments(&segs).ok() ? segs.size() : 0;
}

}  // namespace

Status decode_mesh(const uint8_t* data, size_t size, MeshBuffers* mesh, int threads) {
  mesh->positions.clear();
  mesh->indices.clear();
  Status s(ErrorCode::kUnsupported, "one thread");
  // A stream of several segments on every core; one that cannot be
  // decoded so (kUnsupported) by one thread, which also reports what is
  // wrong with a damaged stream in stream order. A stream of one segment
  // takes the one-thread path at once: decode_mesh_segments() would
  // decode it on this thread too, into arrays sized before the decoder's
  // tables, which in a process that decodes again and again left the
  // arrays' pages to be faulted in anew each time (bench/RESULTS.md,
  // "Speed ratios to Draco within one invocation").
  if (threads != 1 && segment_count(data, size) > 1) {
    auto open = [&](InputStream* in) {
      in->open_memory(data, size, "<memory>");
      return Status();
    };
    s = decode_mesh_segments(open, threads, mesh, nullptr);
  }
  if (s.code() == ErrorCode::kUnsupported) {
    mesh->positions.clear();
    mesh->indices.clear();
    InputStream in;
    in.open_memory(data, size, "<memory>");
    PsqDecoder d;
    MeshArraySink sink(mesh);
    s = d.open(&in);
    if (s.ok()) s = d.pump(sink);
  }
  if (!s.ok()) {
    mesh->positions.clear();
    mesh->indices.clear();
  }
  return s;
}

}  // namespace psq
