// SPDX-License-Identifier: Apache-2.0
// InputStream, OutputFile and SpoolFile: offsets, line ends, atomic output.
#include <gtest/gtest.h>

#include <cstdint>
#include <cstring>
#include <string>
#include <thread>
#include <vector>

#include <fcntl.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

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

// Writes `text` to `path` through an OutputFile opened with `overwrite`.
Status write_output(const std::string& path, bool overwrite, const std::string& text) {
  OutputFile out;
  PSQ_RETURN_IF_ERROR(out.open(path, overwrite));
  PSQ_RETURN_IF_ERROR(out.write(text));
  return out.commit();
}

mode_t mode_of(const std::string& path) {
  struct stat st;
  EXPECT_EQ(::lstat(path.c_str(), &st), 0) << path;
  return st.st_mode;
}

TEST(OutputFile, ReplacedFileKeepsItsPermissions) {
  test::TempDir dir;
  const std::string path = dir.file("m.ply");
  for (mode_t mode : {0600, 0640, 0444, 0755}) {
    test::write_file(path, "old");
    ASSERT_EQ(::chmod(path.c_str(), mode), 0);
    ASSERT_TRUE(write_output(path, true, "new").ok());
    EXPECT_EQ(test::read_file(path), "new");
    EXPECT_EQ(mode_of(path) & 07777, mode) << std::oct << mode;
    ASSERT_EQ(::chmod(path.c_str(), 0600), 0);
    ASSERT_EQ(::unlink(path.c_str()), 0);
  }
  // The owner and group, where the system allows it (as root: any).
  if (::geteuid() == 0) {
    test::write_file(path, "old");
    ASSERT_EQ(::chown(path.c_str(), 4321, 4322), 0);
    ASSERT_EQ(::chmod(path.c_str(), 0604), 0);
    ASSERT_TRUE(write_output(path, true, "new").ok());
    struct stat st;
    ASSERT_EQ(::stat(path.c_str(), &st), 0);
    EXPECT_EQ(st.st_uid, 4321u);
    EXPECT_EQ(st.st_gid, 4322u);
    EXPECT_EQ(st.st_mode & 07777, 0604u);
    ASSERT_EQ(::unlink(path.c_str()), 0);
  }
  // A new file: 0666 less the umask.
  for (mode_t mask : {022, 077, 002}) {
    const mode_t old = ::umask(mask);
    ASSERT_TRUE(write_output(path, false, "new").ok());
    ::umask(old);
    EXPECT_EQ(mode_of(path) & 07777, 0666 & ~mask) << std::oct << mask;
    ASSERT_EQ(::unlink(path.c_str()), 0);
  }
}

TEST(OutputFile, PipesAndDevicesAreWrittenInPlaceNeverReplaced) {
  // /dev/null stays the character device (replacing it as root would
  // break the system), with or without overwrite.
  for (bool overwrite : {false, true}) {
    ASSERT_TRUE(write_output("/dev/null", overwrite, "mesh").ok());
    EXPECT_TRUE(S_ISCHR(mode_of("/dev/null")));
  }
  // A FIFO: its reader gets the data; it is still a FIFO after.
  test::TempDir dir;
  const std::string fifo = dir.file("pipe");
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  std::string got;
  std::thread reader([&] {
    int fd = ::open(fifo.c_str(), O_RDONLY);
    char buf[256];
    ssize_t n;
    while ((n = ::read(fd, buf, sizeof buf)) > 0) got.append(buf, static_cast<size_t>(n));
    ::close(fd);
  });
  Status s = write_output(fifo, false, "through the pipe");
  reader.join();
  ASSERT_TRUE(s.ok()) << s.to_string();
  EXPECT_EQ(got, "through the pipe");
  EXPECT_TRUE(S_ISFIFO(mode_of(fifo)));
  EXPECT_EQ(dir.entries(), (std::vector<std::string>{"pipe"}));  // no temporary left
}

TEST(OutputFile, DirectoriesAndSocketsAreRefused) {
  test::TempDir dir;
  ASSERT_EQ(::mkdir(dir.file("sub").c_str(), 0700), 0);
  for (const std::string& path : {dir.file("sub"), dir.file("sub/"), dir.file("new/"), dir.path()}) {
    for (bool overwrite : {false, true}) {
      OutputFile out;
      Status s = out.open(path, overwrite);
      EXPECT_EQ(s.code(), ErrorCode::kUsage) << path << ": " << s.to_string();
      EXPECT_NE(s.message().find("directory"), std::string::npos) << s.to_string();
    }
  }
  // A Unix socket.
  const std::string sock = dir.file("sock");
  int fd = ::socket(AF_UNIX, SOCK_STREAM, 0);
  ASSERT_GE(fd, 0);
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  ASSERT_LT(sock.size(), sizeof addr.sun_path);
  std::memcpy(addr.sun_path, sock.c_str(), sock.size() + 1);
  ASSERT_EQ(::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr), 0);
  OutputFile out;
  Status s = out.open(sock, true);
  EXPECT_EQ(s.code(), ErrorCode::kUsage) << s.to_string();
  EXPECT_NE(s.message().find("socket"), std::string::npos) << s.to_string();
  ::close(fd);
  EXPECT_EQ(dir.entries(), (std::vector<std::string>{"sock", "sub"}));
}

TEST(OutputFile, SymbolicLinksAreWrittenThrough) {
  test::TempDir dir;
  ASSERT_EQ(::mkdir(dir.file("real").c_str(), 0700), 0);
  const std::string target = dir.file("real/m.ply");
  const std::string link = dir.file("link.ply");
  test::write_file(target, "old");
  ASSERT_EQ(::chmod(target.c_str(), 0640), 0);
  ASSERT_EQ(::symlink("real/m.ply", link.c_str()), 0);
  // The target exists: overwriting it needs overwrite.
  OutputFile out;
  EXPECT_EQ(out.open(link, false).code(), ErrorCode::kUsage);
  ASSERT_TRUE(write_output(link, true, "new").ok());
  EXPECT_TRUE(S_ISLNK(mode_of(link)));  // still the link
  EXPECT_EQ(test::read_file(target), "new");
  EXPECT_EQ(mode_of(target) & 07777, 0640u);
  EXPECT_EQ(dir.entries(), (std::vector<std::string>{"link.ply", "real"}));
  // A chain of links.
  const std::string link2 = dir.file("link2.ply");
  ASSERT_EQ(::symlink("link.ply", link2.c_str()), 0);
  ASSERT_TRUE(write_output(link2, true, "newer").ok());
  EXPECT_EQ(test::read_file(target), "newer");
  EXPECT_TRUE(S_ISLNK(mode_of(link2)));
  // A link to a missing file is refused, and stays.
  const std::string dangling = dir.file("dangling.ply");
  ASSERT_EQ(::symlink("real/none.ply", dangling.c_str()), 0);
  OutputFile out2;
  Status s = out2.open(dangling, true);
  EXPECT_EQ(s.code(), ErrorCode::kIo) << s.to_string();
  EXPECT_TRUE(S_ISLNK(mode_of(dangling)));
  // A link to a device is written in place.
  const std::string null_link = dir.file("null.ply");
  ASSERT_EQ(::symlink("/dev/null", null_link.c_str()), 0);
  ASSERT_TRUE(write_output(null_link, true, "gone").ok());
  EXPECT_TRUE(S_ISLNK(mode_of(null_link)));
  EXPECT_TRUE(S_ISCHR(mode_of("/dev/null")));
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
