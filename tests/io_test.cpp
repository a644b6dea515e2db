// InputStream, OutputFile and SpoolFile: offsets, line ends, atomic output.
#include <gtest/gtest.h>

#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "psq/io.h"
#include "test_util.h"

namespace psq {
namespace {

TEST(InputStream, LinesWithEveryEnding) {
  std::string text = "a\nbb\r\nccc\rdddd";
  InputStream in;
  in.open_memory(text.data(), text.size());
  std::vector<std::string> lines;
  for (;;) {
    std::string_view line;
    bool eof;
    ASSERT_TRUE(in.read_line(&line, &eof).ok());
    if (eof) break;
    lines.emplace_back(line);
  }
  EXPECT_EQ(lines, (std::vector<std::string>{"a", "bb", "ccc", "dddd"}));
  EXPECT_EQ(in.offset(), text.size());
}

TEST(InputStream, CrLfSplitAcrossBufferRefill) {
  // The first read fills the 1 MiB buffer exactly, ending on the CR of a
  // CRLF; the LF comes with the next read and must not make an empty line.
  test::TempDir dir;
  std::string text(size_t{1} << 20, 'x');
  text.back() = '\r';
  text += "\nnext\n";
  test::write_file(dir.file("f"), text);
  InputStream in;
  ASSERT_TRUE(in.open(dir.file("f")).ok());
  std::vector<size_t> lengths;
  for (;;) {
    std::string_view line;
    bool eof;
    ASSERT_TRUE(in.read_line(&line, &eof).ok());
    if (eof) break;
    lengths.push_back(line.size());
  }
  EXPECT_EQ(lengths, (std::vector<size_t>{(size_t{1} << 20) - 1, 4}));
}

TEST(InputStream, OverlongLineIsAnError) {
  std::string text(InputStream::kMaxLine + 5, 'x');
  InputStream in;
  in.open_memory(text.data(), text.size());
  std::string_view line;
  bool eof;
  Status s = in.read_line(&line, &eof);
  EXPECT_EQ(s.code(), ErrorCode::kLimit);
}

TEST(InputStream, ReadExactReportsTruncationOffset) {
  std::string data = "abcdef";
  InputStream in;
  in.open_memory(data.data(), data.size());
  char buf[4];
  ASSERT_TRUE(in.read_exact(buf, 4).ok());
  Status s = in.read_exact(buf, 4);
  EXPECT_EQ(s.code(), ErrorCode::kTruncated);
  EXPECT_EQ(s.offset(), 6u);
}

TEST(InputStream, MissingFileIsIoError) {
  InputStream in;
  Status s = in.open("/nonexistent/psq/file.ply");
  EXPECT_EQ(s.code(), ErrorCode::kIo);
}

TEST(OutputFile, CommitRenamesAndDiscardLeavesNothing) {
  test::TempDir dir;
  {
    OutputFile out;
    ASSERT_TRUE(out.open(dir.file("a.txt"), false).ok());
    ASSERT_TRUE(out.write("hello").ok());
    EXPECT_FALSE(test::file_exists(dir.file("a.txt")));  // still a temporary
    ASSERT_TRUE(out.commit().ok());
  }
  EXPECT_EQ(test::read_file(dir.file("a.txt")), "hello");
  {
    OutputFile out;
    ASSERT_TRUE(out.open(dir.file("b.txt"), false).ok());
    ASSERT_TRUE(out.write("partial").ok());
    // destroyed without commit: a failed run
  }
  EXPECT_EQ(dir.entries(), (std::vector<std::string>{"a.txt"}));
}

TEST(OutputFile, RefusesToOverwriteWithoutForce) {
  test::TempDir dir;
  test::write_file(dir.file("x"), "old");
  OutputFile out;
  Status s = out.open(dir.file("x"), false);
  EXPECT_EQ(s.code(), ErrorCode::kUsage);
  OutputFile forced;
  ASSERT_TRUE(forced.open(dir.file("x"), true).ok());
  ASSERT_TRUE(forced.write("new").ok());
  ASSERT_TRUE(forced.commit().ok());
  EXPECT_EQ(test::read_file(dir.file("x")), "new");
}

TEST(SpoolFile, WritesAndReadsBackLargeData) {
  test::TempDir dir;
  SpoolFile spool;
  ASSERT_TRUE(spool.create(dir.path()).ok());
  EXPECT_TRUE(dir.entries().empty());  // unlinked at creation
  std::string chunk(1000, 'q');
  for (int i = 0; i < 3000; ++i) {
    chunk[0] = static_cast<char>('a' + i % 26);
    ASSERT_TRUE(spool.write(chunk.data(), chunk.size()).ok());
  }
  ASSERT_TRUE(spool.rewind().ok());
  std::string back(chunk.size(), '\0');
  for (int i = 0; i < 3000; ++i) {
    ASSERT_TRUE(spool.stream().read_exact(&back[0], back.size()).ok());
    ASSERT_EQ(back[0], static_cast<char>('a' + i % 26));
  }
  bool end;
  ASSERT_TRUE(spool.stream().at_end(&end).ok());
  EXPECT_TRUE(end);
}

// load() reads the contents into memory when they fit; read_at() gives the
// same bytes and the same errors either way.
TEST(SpoolFile, ReadsAtOffsetsFromTheFileOrFromMemory) {
  test::TempDir dir;
  SpoolFile spool;
  ASSERT_TRUE(spool.create(dir.path()).ok());
  std::vector<uint8_t> data(100000);
  for (size_t i = 0; i < data.size(); ++i) data[i] = static_cast<uint8_t>(i * 7 + i / 251);
  ASSERT_TRUE(spool.write(data.data(), data.size()).ok());
  ASSERT_TRUE(spool.rewind().ok());
  auto check = [&](const char* mode) {
    SCOPED_TRACE(mode);
    for (uint64_t at : {uint64_t{0}, uint64_t{1}, uint64_t{4095}, uint64_t{65536}, uint64_t{99990}}) {
      uint8_t buf[10];
      ASSERT_TRUE(spool.read_at(at, buf, 10).ok());
      EXPECT_EQ(0, std::memcmp(buf, data.data() + at, 10));
    }
    uint8_t buf[10];
    EXPECT_EQ(spool.read_at(99995, buf, 10).code(), ErrorCode::kTruncated);
    EXPECT_EQ(spool.read_at(200000, buf, 1).code(), ErrorCode::kTruncated);
    EXPECT_TRUE(spool.read_at(100000, buf, 0).ok());
  };
  check("from the file");
  bool loaded = true;
  ASSERT_TRUE(spool.load(99999, &loaded).ok());
  EXPECT_FALSE(loaded) << "larger than allowed";
  check("from the file, not loaded");
  ASSERT_TRUE(spool.load(100000, &loaded).ok());
  EXPECT_TRUE(loaded);
  check("from memory");
  // The stream still reads the file from where it was.
  uint8_t first[4];
  ASSERT_TRUE(spool.stream().read_exact(first, 4).ok());
  EXPECT_EQ(0, std::memcmp(first, data.data(), 4));
}

TEST(Status, ToStringNamesThePlace) {
  EXPECT_EQ(Status(ErrorCode::kBadValue, "bad", 12).to_string(), "byte 12: bad");
  EXPECT_EQ(Status(ErrorCode::kBadValue, "bad", Status::kNoPlace, 3).to_string(), "line 3: bad");
  EXPECT_EQ(Status(ErrorCode::kBadValue, "bad").to_string(), "bad");
  EXPECT_STREQ(error_name(ErrorCode::kTruncated), "truncated");
}

}  // namespace
}  // namespace psq
