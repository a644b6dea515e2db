// SPDX-License-Identifier: Apache-2.0
// The conformance vectors of spec/conformance (spec/psq-format.md section
// 12): every valid vector decodes to exactly its .dump, every invalid one
// fails with the listed error at the listed byte, and the vectors made from
// meshes in tests/data are what the encoder writes today (determinism).
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <functional>
#include <sstream>

#include "psq/psq_codec.h"
#include "sequence_dump.h"
#include "test_util.h"

namespace psq {
namespace {

const std::string kDir = std::string(PSQ_SPEC_DIR) + "/conformance/";

struct Line {
  std::string kind, file, a, b;
};

std::vector<Line> manifest() {
  std::ifstream in(kDir + "MANIFEST");
  std::vector<Line> lines;
  std::string text;
  while (std::getline(in, text)) {
    std::istringstream s(text);
    Line l;
    s >> l.kind >> l.file >> l.a >> l.b;
    lines.push_back(l);
  }
  return lines;
}

Status dump(const std::string& path, const std::string& out_path) {
  InputStream in;
  PSQ_RETURN_IF_ERROR(in.open(path));
  PsqDecoder dec;
  PSQ_RETURN_IF_ERROR(dec.open(&in));
  OutputFile out;
  PSQ_RETURN_IF_ERROR(out.open(out_path, true));
  DumpWriter writer(&out);
  Status s = dec.pump(writer);
  if (!s.ok()) {
    out.discard();
    return s;
  }
  return out.commit();
}

TEST(Conformance, ManifestListsValidAndInvalidVectors) {
  std::vector<Line> lines = manifest();
  int valid = 0, invalid = 0;
  for (const Line& l : lines) (l.kind == "valid" ? valid : invalid)++;
  EXPECT_GE(valid, 8);
  EXPECT_GE(invalid, 8);
}

TEST(Conformance, ValidVectorsDecodeToTheirDumps) {
  test::TempDir tmp;
  for (const Line& l : manifest()) {
    if (l.kind != "valid") continue;
    std::string out = tmp.file("out.dump");
    Status s = dump(kDir + l.file, out);
    ASSERT_TRUE(s.ok()) << l.file << ": " << s.to_string();
    std::string expected = test::read_file(kDir + l.file.substr(0, l.file.size() - 4) + ".dump");
    EXPECT_EQ(test::read_file(out), expected) << l.file;
  }
}

TEST(Conformance, InvalidVectorsFailWithTheirErrors) {
  for (const Line& l : manifest()) {
    if (l.kind != "invalid") continue;
    InputStream in;
    ASSERT_TRUE(in.open(kDir + l.file).ok());
    PsqDecoder dec;
    Status s = dec.open(&in);
    SequenceEvent e;
    while (s.ok()) {
      s = dec.next(&e);
      if (s.ok() && e.kind == SequenceEvent::Kind::kEnd) break;
    }
    ASSERT_FALSE(s.ok()) << l.file << " decoded";
    EXPECT_EQ(std::string(error_name(s.code())), l.a) << l.file << ": " << s.to_string();
    EXPECT_EQ(std::to_string(s.offset()), l.b) << l.file << ": " << s.to_string();
  }
}

// Decodes vector `name` to its end with `dec`, passing every event before
// the end to `on_event` when given.
void decode_vector(const std::string& name, PsqDecoder* dec,
                   const std::function<void(const SequenceEvent&)>& on_event = nullptr) {
  InputStream in;
  EXPECT_TRUE(in.open(kDir + name).ok()) << name;
  Status s = dec->open(&in);
  SequenceEvent e;
  while (s.ok()) {
    s = dec->next(&e);
    if (!s.ok() || e.kind == SequenceEvent::Kind::kEnd) break;
    if (on_event) on_event(e);
  }
  EXPECT_TRUE(s.ok()) << name << ": " << s.to_string();
}

// The decoder's statistics of vector `name`.
PsqStats stats_of(const std::string& name) {
  PsqDecoder dec;
  decode_vector(name, &dec);
  return dec.stats();
}

// far_gates exercises every way of naming a gate away from R: a recency
// rank (spec 13.7.4) and a slot in an escape (13.7.5).
TEST(Conformance, FarGatesVectorNamesFarGatesEveryWay) {
  const PsqStats st = stats_of("far_gates.psq");
  EXPECT_GT(st.far_gates[0], 0u) << "recency ranks";
  EXPECT_GT(st.far_gates[1], 0u) << "slots (escapes)";
}

// spider_16bit predicts adds in all five ways of spec 7.3.
TEST(Conformance, SpiderVectorUsesEveryPrediction) {
  const PsqStats st = stats_of("spider_16bit.psq");
  EXPECT_GT(st.predictions[0], 0u) << "across the gate";
  EXPECT_GT(st.predictions[1], 0u) << "across the edge before";
  EXPECT_GT(st.predictions[2], 0u) << "across the edge after";
  EXPECT_GT(st.predictions[3], 0u) << "mean with the edge before";
  EXPECT_GT(st.predictions[4], 0u) << "mean with the edge after";
}

// Spec 13.8.2: with the rANS back-end, a quantized stream predicts every
// add across the gate and codes no choice; a lossless one codes choices
// (all five of them here).
TEST(Conformance, FastVectorsCodeChoicesWhenLossless) {
  const PsqStats quantized = stats_of("fast_spider_16bit.psq");
  EXPECT_GT(quantized.predictions[0], 0u);
  for (int k = 1; k < 5; ++k) EXPECT_EQ(quantized.predictions[k], 0u) << "choice " << k;
  const PsqStats lossless = stats_of("fast_spider_lossless.psq");
  for (int k = 0; k < 5; ++k) EXPECT_GT(lossless.predictions[k], 0u) << "choice " << k;
}

// doubles_lossless holds f64 positions whose order-preserving integers
// (spec 7.2) have magnitudes of 2^62 or more, so that the sum of any two
// overflows 64 bits, and uses the means of spec 7.3 (mid()), which a
// decoder must compute without that overflow; its dump pins the result.
TEST(Conformance, DoublesVectorNeedsMeansBeyond64Bits) {
  PsqDecoder dec;
  size_t vertices = 0;
  decode_vector("doubles_lossless.psq", &dec, [&](const SequenceEvent& e) {
    if (e.kind != SequenceEvent::Kind::kVertex) return;
    ++vertices;
    // |x| >= 2: the f64 bit pattern without its sign is 0x4000000000000000 or more.
    for (double x : e.vertex.position) EXPECT_GE(std::fabs(x), 2.0);
  });
  EXPECT_TRUE(dec.header().lossless);
  EXPECT_EQ(dec.schema().position_type, ScalarType::kFloat64);
  EXPECT_EQ(vertices, 81u);
  const PsqStats& st = dec.stats();
  EXPECT_GT(st.predictions[3] + st.predictions[4], 0u) << "no mean of two parallelograms";
  EXPECT_GT(st.gates[3], 0u) << "no start";
}

// Spec 8.3: the attribute vectors cover every kind of coded attribute
// with both entropy back-ends, quantized and lossless.
TEST(Conformance, AttributeVectorsCoverEveryKind) {
  for (const char* name : {"attributes_8bit.psq", "fast_attributes_8bit.psq"}) {
    PsqDecoder dec;
    decode_vector(name, &dec, [](const SequenceEvent&) {});
    const PsqHeader& h = dec.header();
    ASSERT_EQ(h.attributes.size(), 3u) << name;
    EXPECT_EQ(h.attributes[0].kind, CodedAttribute::Kind::kNormal);
    EXPECT_EQ(h.attributes[0].bits, 8);
    EXPECT_EQ(h.attributes[1].kind, CodedAttribute::Kind::kTexcoord);
    EXPECT_EQ(h.attributes[1].bits, 10);
    EXPECT_EQ(h.attributes[2].kind, CodedAttribute::Kind::kColor);
    EXPECT_EQ(h.attributes[2].properties.size(), 4u);
    EXPECT_GT(dec.stats().attribute_bytes, 0u);
  }
  for (const char* name : {"attributes_lossless.psq", "fast_attributes_lossless.psq"}) {
    PsqDecoder dec;
    decode_vector(name, &dec, [](const SequenceEvent&) {});
    ASSERT_EQ(dec.header().attributes.size(), 1u) << name;
    EXPECT_EQ(dec.header().attributes[0].kind, CodedAttribute::Kind::kColor);
  }
}

// The vectors of the rANS back-end (fast_*) decode to the same sequences
// as those of the adaptive back-end made from the same input: their dumps
// are identical.
TEST(Conformance, FastVectorsDecodeLikeTheirCompactTwins) {
  for (const char* name : {"spider_16bit", "spider_lossless", "grid_borders", "nonmanifold_wrap", "max_export_chunks",
                           "properties_lossless", "attributes_8bit", "attributes_lossless", "spider_attributes",
                           "segments_spider", "segments_spider_lossless", "segments_spider_attributes",
                           "segments_nonmanifold_wrap", "segments_spider_corners", "corner_wedges"}) {
    EXPECT_EQ(test::read_file(kDir + "fast_" + name + ".dump"), test::read_file(kDir + name + ".dump")) << name;
    PsqDecoder dec;
    decode_vector(std::string("fast_") + name + ".psq", &dec, [](const SequenceEvent&) {});
    EXPECT_TRUE(dec.header().fast) << name;
  }
}

// The segment vectors (spec 4.6, 4.7) have the segment records their
// options ask for, and decode to the same sequences as the streams of one
// segment made from the same input: the restarts change how the records
// are coded, never what they decode to.
TEST(Conformance, SegmentVectorsDecodeLikeOneSegment) {
  struct Case {
    const char* vector;
    const char* twin;
    uint64_t records;
  } cases[] = {
      {"segments_spider", "spider_16bit", 4},
      {"segments_spider_lossless", "spider_lossless", 4},
      {"segments_spider_attributes", "spider_attributes", 4},
      {"segments_nonmanifold_wrap", "nonmanifold_wrap", 2},
  };
  for (const Case& c : cases) {
    for (const std::string prefix : {"", "fast_"}) {
      const std::string name = prefix + c.vector;
      EXPECT_EQ(test::read_file(kDir + name + ".dump"), test::read_file(kDir + c.twin + ".dump")) << name;
      const PsqStats st = stats_of(name + ".psq");
      EXPECT_EQ(st.segments, c.records) << name;
      EXPECT_EQ(stats_of(prefix + c.twin + ".psq").segments, 0u) << c.twin;
    }
  }
}

// Every event of a decoder as a line of text (a sink of one segment).
class EventText : public SequenceSink {
 public:
  explicit EventText(std::string* out) : out_(out) {}
  Status begin(const MeshSchema&) override { return Status(); }
  Status vertex(const SequenceVertex& v) override {
    std::ostringstream s;
    s.precision(17);
    s << "v " << v.index << " " << v.reappears << " " << v.position[0] << " " << v.position[1] << " "
      << v.position[2];
    for (double x : v.values) s << " " << x;
    *out_ += s.str() + "\n";
    return Status();
  }
  Status triangle(const SequenceTriangle& t) override {
    std::ostringstream s;
    s << "t " << t.v[0] << " " << t.v[1] << " " << t.v[2] << " " << int(t.border_mask);
    for (double x : t.values) s << " " << x;
    *out_ += s.str() + "\n";
    return Status();
  }
  Status finalize(uint32_t index) override {
    *out_ += "x " + std::to_string(index) + "\n";
    return Status();
  }
  Status finish() override { return Status(); }

 private:
  std::string* out_;
};

// Spec 4.8: decoding the segments apart, two at a time, accepts every
// valid vector with the events and totals of one decoder reading from the
// start, and rejects every invalid vector.
TEST(Conformance, VectorsDecodeAlikeBySegments) {
  for (const Line& l : manifest()) {
    const std::string path = kDir + l.file;
    auto open = [&](InputStream* in) { return in->open(path); };
    std::vector<std::string> parts(64);
    auto work = [&](PsqDecoder& d, size_t k) {
      if (k >= parts.size()) return Status(ErrorCode::kLimit, "too many segments for the test");
      EventText sink(&parts[k]);
      return d.pump(sink);
    };
    PsqStats st;
    const Status s = decode_segments(open, 2, work, &st);
    if (l.kind == "invalid") {
      EXPECT_FALSE(s.ok()) << l.file << " decoded by segments";
      continue;
    }
    ASSERT_TRUE(s.ok()) << l.file << ": " << s.to_string();
    std::string whole;
    PsqDecoder dec;
    InputStream in;
    ASSERT_TRUE(in.open(path).ok());
    ASSERT_TRUE(dec.open(&in).ok());
    EventText sink(&whole);
    ASSERT_TRUE(dec.pump(sink).ok()) << l.file;
    std::string joined;
    for (const std::string& p : parts) joined += p;
    EXPECT_EQ(joined, whole) << l.file;
    EXPECT_EQ(st.vertices, dec.stats().vertices) << l.file;
    EXPECT_EQ(st.triangles, dec.stats().triangles) << l.file;
    EXPECT_EQ(st.chunks, dec.stats().chunks) << l.file;
    EXPECT_EQ(st.segments, dec.stats().segments) << l.file;
  }
}

// The encoder still writes the vectors made from tests/data byte for byte.
TEST(Conformance, EncoderReproducesTheVectors) {
  test::TempDir tmp;
  struct Case {
    const char* vector;
    const char* input;
    const char* options;
  } cases[] = {
      {"cube_11bit.psq", "cube_quads.obj", "--bits 11"},
      {"spider_16bit.psq", "spider.ply", ""},
      {"spider_lossless.psq", "spider.ply", "--lossless"},
      {"nonmanifold_wrap.psq", "nonmanifold_wrap.ply", "--bits 12"},
      {"max_export_chunks.psq", "max_export_nm.ply", "--bits 14 --chunk 256"},
      {"fast_spider_16bit.psq", "spider.ply", "--profile fast"},
      {"fast_spider_lossless.psq", "spider.ply", "--lossless --profile fast"},
      {"fast_nonmanifold_wrap.psq", "nonmanifold_wrap.ply", "--bits 12 --profile fast"},
      {"fast_max_export_chunks.psq", "max_export_nm.ply", "--bits 14 --chunk 256 --profile fast"},
      {"attributes_8bit.psq", "attributes.ply", "--bits 12 --normal-bits 8 --uv-bits 10"},
      {"attributes_lossless.psq", "attributes.ply", "--lossless"},
      {"fast_attributes_8bit.psq", "attributes.ply", "--bits 12 --normal-bits 8 --uv-bits 10 --profile fast"},
      {"fast_attributes_lossless.psq", "attributes.ply", "--lossless --profile fast"},
      {"spider_attributes.psq", "spider_attributes.ply", "--bits 14 --normal-bits 10 --uv-bits 12"},
      {"fast_spider_attributes.psq", "spider_attributes.ply", "--bits 14 --normal-bits 10 --uv-bits 12 --profile fast"},
      {"segments_spider.psq", "spider.ply", "--segment 300"},
      {"segments_spider_lossless.psq", "spider.ply", "--lossless --segment 300"},
      {"segments_spider_attributes.psq", "spider_attributes.ply", "--bits 14 --normal-bits 10 --uv-bits 12 --segment 300"},
      {"segments_nonmanifold_wrap.psq", "nonmanifold_wrap.ply", "--bits 12 --segment 4"},
      {"fast_segments_spider.psq", "spider.ply", "--segment 300 --profile fast"},
      {"fast_segments_spider_lossless.psq", "spider.ply", "--lossless --segment 300 --profile fast"},
      {"fast_segments_spider_attributes.psq", "spider_attributes.ply",
       "--bits 14 --normal-bits 10 --uv-bits 12 --segment 300 --profile fast"},
      {"fast_segments_nonmanifold_wrap.psq", "nonmanifold_wrap.ply", "--bits 12 --segment 4 --profile fast"},
      {"segments_spider_corners.psq", "spider.obj", "--bits 14 --normal-bits 10 --uv-bits 12 --segment 300 --chunk 1024"},
      {"fast_segments_spider_corners.psq", "spider.obj",
       "--bits 14 --normal-bits 10 --uv-bits 12 --segment 300 --chunk 1024 --profile fast"},
  };
  for (const Case& c : cases) {
    std::string out, err;
    std::string target = tmp.file(c.vector);
    int rc = test::run_psq(std::string("convert ") + PSQ_TEST_DATA + "/" + c.input + " " + target + " -q " + c.options,
                           &out, &err);
    ASSERT_EQ(rc, 0) << err;
    EXPECT_EQ(test::read_file(target), test::read_file(kDir + c.vector)) << c.vector;
  }
}

}  // namespace
}  // namespace psq
