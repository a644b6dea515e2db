// SPDX-License-Identifier: Apache-2.0
// The CLI's progress line (tools/cli/progress.h): the recent rate and the
// time left, their text, and silence when stderr is not a terminal.
#include <gtest/gtest.h>

#include <fcntl.h>
#include <unistd.h>

#include <cstdio>
#include <string>

#include "progress.h"
#include "test_util.h"

namespace psq::cli {
namespace {

TEST(RateMeter, SteadyProgressGivesItsRateAndTimeLeft) {
  RateMeter m;
  m.reset(0, 0, 0);
  EXPECT_LT(m.rate(), 0);  // unknown before the first update
  EXPECT_LT(m.seconds_left(), 0);
  // 1000 per second, 1% of the work per second, observed at uneven times.
  for (double t : {0.1, 0.25, 0.3, 0.7, 1.0, 1.9, 2.0, 4.0}) {
    m.update(t, 1000 * t, t / 100);
    EXPECT_NEAR(m.rate(), 1000, 1e-6) << t;
    EXPECT_NEAR(m.seconds_left(), 100 - t, 1e-6) << t;
  }
}

TEST(RateMeter, FollowsTheRecentRateNotTheAverage) {
  RateMeter m;
  m.reset(0, 0, 0);
  double t = 0, count = 0, fraction = 0;
  // Ten slow seconds at 100 per second (0.1% of the work per second) ...
  for (int i = 0; i < 100; ++i) {
    t += 0.1;
    count += 10;
    fraction += 0.0001;
    m.update(t, count, fraction);
  }
  EXPECT_NEAR(m.rate(), 100, 1e-6);
  // ... then ten fast ones at 10000 per second (5% of the work per second).
  for (int i = 0; i < 100; ++i) {
    t += 0.1;
    count += 1000;
    fraction += 0.005;
    m.update(t, count, fraction);
  }
  // The average since the start is about 5050 per second; the recent rate
  // has forgotten the slow part but for about exp(-10 / 2), under 1%.
  EXPECT_NEAR(m.rate(), 10000, 100);
  const double left = (1 - fraction) / 0.05;
  EXPECT_NEAR(m.seconds_left(), left, 0.02 * left);
  // No progress in a while: the rate falls towards zero, the time left grows.
  for (int i = 0; i < 40; ++i) {
    t += 0.1;
    m.update(t, count, fraction);
  }
  EXPECT_LT(m.rate(), 10000 * 0.15);
  EXPECT_GT(m.seconds_left(), 4 * left);
}

TEST(RateMeter, UnknownFractionGivesNoTimeLeft) {
  RateMeter m;
  m.reset(0, 0, -1);
  m.update(1, 500, -1);
  EXPECT_NEAR(m.rate(), 500, 1e-9);
  EXPECT_LT(m.seconds_left(), 0);
  m.update(1, 900, -1);  // no time passed: ignored
  EXPECT_NEAR(m.rate(), 500, 1e-9);
  m.reset(1, 500, 0.5);  // a new phase: its own rate
  EXPECT_LT(m.rate(), 0);
  m.update(2, 600, 0.75);
  EXPECT_NEAR(m.rate(), 100, 1e-9);
  EXPECT_NEAR(m.seconds_left(), 1, 1e-9);
}

TEST(ProgressLine, Text) {
  EXPECT_EQ(format_duration(0.4), "0 s");
  EXPECT_EQ(format_duration(59.4), "59 s");
  EXPECT_EQ(format_duration(59.6), "1 min 00 s");
  EXPECT_EQ(format_duration(185), "3 min 05 s");
  EXPECT_EQ(format_duration(7620), "2 h 07 min");
  EXPECT_EQ(progress_line(1.5e6, 2.5e6, 0.421, "of input", 12.2, -1),
            "psq:  42.1% of input, 1.50M triangles, 2.50M triangles/s, 12 s left");
  EXPECT_EQ(progress_line(4096, -1, 0.5, "written", -1, -1), "psq:  50.0% written, 4.1k triangles");
  EXPECT_EQ(progress_line(2e9, 3e7, -1, "", -1, 3 << 20), "psq: 2.00G triangles, 30.00M triangles/s, 3.15MB read");
}

// A Progress draws nothing when stderr is not a terminal, -q or not.
TEST(Progress, SilentWhenStderrIsNoTerminal) {
  test::TempDir dir;
  const std::string path = dir.file("stderr.txt");
  std::fflush(stderr);
  const int saved = ::dup(STDERR_FILENO);
  ASSERT_GE(saved, 0);
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0600);
  ASSERT_GE(fd, 0);
  ASSERT_EQ(::dup2(fd, STDERR_FILENO), STDERR_FILENO);
  ::close(fd);
  bool active = true;
  {
    const std::string data(1 << 20, 'x');
    InputStream in;
    in.open_memory(data.data(), data.size());
    Progress p(&in, true);
    active = p.active();
    uint8_t buf[4096];
    for (int i = 0; i < 200000; ++i) {
      if (i % 800 == 0) (void)in.read_exact(buf, sizeof buf);
      p.triangle();
      p.written();
    }
    p.finish("in", "out", "done");
  }
  std::fflush(stderr);
  ::dup2(saved, STDERR_FILENO);
  ::close(saved);
  EXPECT_FALSE(active);
  EXPECT_EQ(test::read_file(path), "");
}

}  // namespace
}  // namespace psq::cli
