// ProgressTicker (io/progress_ticker.h): the "still working" lines of a long start step.
#include "io/progress_ticker.h"

#include <gtest/gtest.h>

#include <chrono>
#include <cstdio>
#include <string>
#include <thread>

using namespace px;
using namespace std::chrono_literals;

namespace {

std::string contents(std::FILE* f) {
  std::fflush(f);
  std::rewind(f);
  std::string s;
  char buf[256];
  while (std::fgets(buf, sizeof buf, f)) s += buf;
  return s;
}

int count_lines(const std::string& s) {
  int n = 0;
  for (char c : s) n += c == '\n';
  return n;
}

}  // namespace

TEST(ProgressTicker, AShortStepSaysNothing) {
  std::FILE* f = std::tmpfile();
  ASSERT_NE(f, nullptr);
  {
    const ProgressTicker t("[bvh] still building", {std::chrono::milliseconds(3600 * 1000), 1ms, f});
    EXPECT_EQ(t.lines(), 0);
  }
  EXPECT_EQ(contents(f), "");
  std::fclose(f);
}

TEST(ProgressTicker, ALongStepSaysWhatRunsUntilItEnds) {
  std::FILE* f = std::tmpfile();
  ASSERT_NE(f, nullptr);
  int written = 0;
  {
    const ProgressTicker t("[bvh] still building", {0ms, 1ms, f});
    // Wait (up to a minute, for a loaded machine) for a few lines.
    for (int i = 0; i < 60000 && t.lines() < 3; ++i) std::this_thread::sleep_for(1ms);
    ASSERT_GE(t.lines(), 3);
  }
  const std::string s = contents(f);
  written = count_lines(s);
  EXPECT_GE(written, 3);
  EXPECT_EQ(s.rfind("[bvh] still building: ", 0), 0u) << s;
  EXPECT_NE(s.find(" s so far\n"), std::string::npos) << s;
  // Stopped: nothing is written after the step ended.
  std::this_thread::sleep_for(20ms);
  EXPECT_EQ(count_lines(contents(f)), written);
  std::fclose(f);
}

TEST(ProgressTicker, AQuietStartTicksNothing) {
  std::FILE* f = std::tmpfile();
  ASSERT_NE(f, nullptr);
  {
    const ProgressTicker t("", {0ms, 1ms, f});
    std::this_thread::sleep_for(20ms);  // a ticker would have written ~20 lines by now
    EXPECT_EQ(t.lines(), 0);
  }
  EXPECT_EQ(contents(f), "");
  std::fclose(f);
}
