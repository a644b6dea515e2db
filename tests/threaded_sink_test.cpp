// SPDX-License-Identifier: Apache-2.0
// Threaded sinks (psq/threaded_sink.h): the wrapped sink sees exactly the
// events, in order, that it would see without the thread (so an encoder
// behind one writes the same bytes); its errors reach the producer; a
// producer that gives up never hangs.
#include <gtest/gtest.h>

#include <iomanip>
#include <sstream>

#include "psq/psq_codec.h"
#include "psq/sequence_builder.h"
#include "psq/threaded_sink.h"
#include "test_util.h"

namespace psq {
namespace {

// Writes every event as a line of text, with every field; can fail at its
// `fail_at`-th event (0-based).
class TextSink : public SequenceSink {
 public:
  TextSink() { text << std::setprecision(17); }  // doubles bit-exact
  Status begin(const MeshSchema& schema) override {
    text << "begin " << schema.vertex_properties.size() << " " << schema.face_properties.size() << "\n";
    return Status();
  }
  Status vertex(const SequenceVertex& v) override {
    PSQ_RETURN_IF_ERROR(count());
    text << "v " << v.index << " " << v.slot << " " << v.reappears;
    for (double p : v.position) text << " " << p;
    for (double x : v.values) text << " " << x;
    text << "\n";
    return Status();
  }
  Status triangle(const SequenceTriangle& t) override {
    PSQ_RETURN_IF_ERROR(count());
    text << "t " << static_cast<int>(t.op);
    for (int k = 0; k < 3; ++k) text << " " << t.v[k] << " " << t.vslot[k] << " " << t.eslot[k];
    for (int m : {t.new_mask, t.final_mask, t.border_mask, t.nonmanifold_mask, t.leaving_mask, t.entering_mask})
      text << " " << m;
    for (double x : t.values) text << " " << x;
    text << "\n";
    return Status();
  }
  Status finalize(uint32_t index) override {
    PSQ_RETURN_IF_ERROR(count());
    text << "f " << index << "\n";
    return Status();
  }
  Status finish() override {
    finished = true;
    text << "finish\n";
    return Status();
  }

  std::ostringstream text;
  uint64_t calls = 0;  // event calls, the failing one and any after it included
  uint64_t fail_at = ~uint64_t{0};
  bool finished = false;

 private:
  Status count() {
    const uint64_t n = calls++;
    if (n >= fail_at) return Status(ErrorCode::kBadValue, "sink fails at event " + std::to_string(n));
    return Status();
  }
};

// A sphere with a vertex and a face property, so that events carry values.
test::Mesh mesh_with_values() {
  test::Mesh m = test::make_sphere(40, 60);
  m.schema.vertex_properties.push_back({"quality", ScalarType::kFloat32});
  m.schema.face_properties.push_back({"id", ScalarType::kUInt32});
  for (size_t i = 0; i < m.vertex_values.size(); ++i) m.vertex_values[i].push_back(0.25 * static_cast<double>(i % 97));
  for (size_t i = 0; i < m.face_values.size(); ++i) m.face_values[i].push_back(static_cast<double>(i));
  return m;
}

Status build(const test::Mesh& m, SequenceSink& sink) {
  test::MemorySource source(m);
  BuildReport report;
  return build_sequence(source, sink, BuildOptions(), &report);
}

TEST(ThreadedSequenceSink, ReplaysTheSameEventsInOrder) {
  const test::Mesh m = mesh_with_values();
  TextSink direct;
  ASSERT_TRUE(build(m, direct).ok());
  // Batches of one event, of a few, and the default; two batches and more.
  for (auto [batch, batches] : {std::pair<size_t, size_t>{1, 2}, {7, 2}, {300, 3}, {64 * 1024, 4}}) {
    TextSink wrapped;
    ThreadedSequenceSink threaded(&wrapped, batch, batches);
    Status s = build(m, threaded);
    ASSERT_TRUE(s.ok()) << s.to_string();
    EXPECT_TRUE(wrapped.finished);
    EXPECT_EQ(wrapped.text.str(), direct.text.str()) << "batch " << batch;
  }
}

TEST(ThreadedSequenceSink, AnEncoderBehindItWritesTheSameBytes) {
  const test::Mesh m = mesh_with_values();
  for (bool lossless : {false, true}) {
  std::vector<uint8_t> direct, threaded;
  EncodeOptions options;
  options.bits = 14;
  options.lossless = lossless;
  {
    VectorWriter w(&direct);
    PsqEncoder encoder(&w, options);
    ASSERT_TRUE(build(m, encoder).ok());
  }
  {
    VectorWriter w(&threaded);
    PsqEncoder encoder(&w, options);
    ThreadedSequenceSink sink(&encoder, 100, 3);
    Status s = build(m, sink);
    ASSERT_TRUE(s.ok()) << s.to_string();
    EXPECT_EQ(encoder.stats().triangles, m.triangles.size());
  }
  EXPECT_GT(direct.size(), 100u);
  EXPECT_EQ(threaded, direct) << "lossless " << lossless;
  }
}

TEST(ThreadedSequenceSink, TheWrappedSinksErrorReachesTheProducer) {
  const test::Mesh m = mesh_with_values();
  for (uint64_t fail_at : {uint64_t{0}, uint64_t{5}, uint64_t{1000}, uint64_t{9000}}) {
    TextSink wrapped;
    wrapped.fail_at = fail_at;
    ThreadedSequenceSink threaded(&wrapped, 16, 2);
    Status s = build(m, threaded);
    ASSERT_FALSE(s.ok()) << "fail_at " << fail_at;
    EXPECT_EQ(s.code(), ErrorCode::kBadValue);
    EXPECT_NE(s.to_string().find("sink fails at event " + std::to_string(fail_at)), std::string::npos)
        << s.to_string();
    // Nothing reached the sink after its error, and it was not finished.
    EXPECT_EQ(wrapped.calls, fail_at + 1);
    EXPECT_FALSE(wrapped.finished);
  }
}

TEST(ThreadedSequenceSink, AProducerThatGivesUpDoesNotHang) {
  // As psq convert nests them: the wrapped sink first, the threaded sink
  // destroyed before it (ASan would see a worker that outlives it).
  for (uint64_t fail_at : {~uint64_t{0}, uint64_t{3}}) {
    TextSink wrapped;
    wrapped.fail_at = fail_at;
    {
      ThreadedSequenceSink threaded(&wrapped, 8, 2);
      ASSERT_TRUE(threaded.begin(MeshSchema()).ok());
      for (uint32_t i = 0; i < 100; ++i)
        if (!threaded.finalize(i).ok()) break;
      // Destroyed without finish(): what is in flight is dropped.
    }
    EXPECT_FALSE(wrapped.finished);
    EXPECT_LE(wrapped.calls, fail_at == 3 ? 4u : 100u);
  }
}

TEST(ThreadedSequenceSink, ErrorsAreStickyOnEveryCall) {
  TextSink wrapped;
  wrapped.fail_at = 0;
  ThreadedSequenceSink threaded(&wrapped, 1, 2);
  ASSERT_TRUE(threaded.begin(MeshSchema()).ok());
  // The first event fails in the worker; later calls report it once the
  // producer has handed a batch over.
  Status s;
  for (uint32_t i = 0; i < 10 && s.ok(); ++i) s = threaded.finalize(i);
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.code(), ErrorCode::kBadValue);
  EXPECT_EQ(threaded.finalize(99).code(), ErrorCode::kBadValue);
  EXPECT_EQ(threaded.finish().code(), ErrorCode::kBadValue);
  EXPECT_EQ(wrapped.calls, 1u);
  EXPECT_FALSE(wrapped.finished);
}

TEST(ThreadedSequenceSink, EventsBeforeBeginAndASecondBeginAreErrors) {
  TextSink wrapped;
  ThreadedSequenceSink threaded(&wrapped);
  EXPECT_EQ(threaded.finalize(0).code(), ErrorCode::kUsage);
  ASSERT_TRUE(threaded.begin(MeshSchema()).ok());
  EXPECT_EQ(threaded.begin(MeshSchema()).code(), ErrorCode::kUsage);
  ASSERT_TRUE(threaded.finish().ok());
  EXPECT_EQ(wrapped.calls, 0u);
  EXPECT_TRUE(wrapped.finished);
}

TEST(ThreadedSequenceSink, EventsAfterFinishAreAnError) {
  TextSink wrapped;
  ThreadedSequenceSink threaded(&wrapped);
  ASSERT_TRUE(threaded.begin(MeshSchema()).ok());
  ASSERT_TRUE(threaded.finalize(0).ok());
  ASSERT_TRUE(threaded.finish().ok());
  EXPECT_EQ(wrapped.calls, 1u);
  EXPECT_EQ(threaded.finalize(1).code(), ErrorCode::kUsage);
  EXPECT_EQ(threaded.finish().code(), ErrorCode::kUsage);
}

}  // namespace
}  // namespace psq
