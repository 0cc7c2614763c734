// host/io/huge_page_allocation.cpp: a large allocation lands on transparent huge pages once
// written, which 4 KiB pages would not (where the system's setting is "madvise", the advice is
// the only way there).
#include "io/environment.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <cstring>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

namespace px {
bool huge_page_allocation_compiled_in();
}

namespace {

std::string thp_setting() {
  std::ifstream in("/sys/kernel/mm/transparent_hugepage/enabled");
  std::string line;
  std::getline(in, line);
  return line;
}

// AnonHugePages (kB) of the mapping of /proc/self/smaps that holds `address`; -1 if none does.
long anon_huge_kb(const void* address) {
  std::ifstream in("/proc/self/smaps");
  const auto a = reinterpret_cast<std::uintptr_t>(address);
  std::string line;
  bool inside = false;
  while (std::getline(in, line)) {
    std::uintptr_t lo = 0, hi = 0;
    char dash = 0;
    std::istringstream head(line);
    if (head >> std::hex >> lo >> dash >> hi && dash == '-') {
      inside = lo <= a && a < hi;
      continue;
    }
    if (inside && line.rfind("AnonHugePages:", 0) == 0) return std::stol(line.substr(14));
  }
  return -1;
}

TEST(HugePageAllocation, ALargeBlockIsBackedByHugePagesOnceWritten) {
  if (!px::huge_page_allocation_compiled_in()) GTEST_SKIP() << "a sanitizer's operator new is in use";
  const std::string setting = thp_setting();
  if (setting.empty() || setting.find("[never]") != std::string::npos)
    GTEST_SKIP() << "transparent huge pages are off here ('" << setting << "')";
  if (!px::environment().huge_pages) GTEST_SKIP() << "PARALLAX_HUGE_PAGES=off";
  constexpr std::size_t kBytes = std::size_t{64} << 20;
  const std::unique_ptr<char[]> block(new char[kBytes]);
  std::memset(block.get(), 1, kBytes);
  const long kb = anon_huge_kb(block.get() + kBytes / 2);
  ASSERT_GE(kb, 0) << "no mapping holds the block";
  // Whole 2 MiB pages inside the block, less what the kernel could not find free at the time.
  EXPECT_GE(kb, static_cast<long>(kBytes / 1024 / 2)) << "THP setting '" << setting << "'";
}

// Large arrays (the device layout's node buffer, which CPU devices read in place) start on a
// 64-byte cache line; glibc's mmap'd blocks alone start 16 bytes past one. Several sizes, as the
// block a size gets differs; a few smaller blocks first so the heap is not fresh.
TEST(HugePageAllocation, LargeBlocksStartOnACacheLine) {
  if (!px::huge_page_allocation_compiled_in()) GTEST_SKIP() << "a sanitizer's operator new is in use";
  std::vector<std::unique_ptr<char[]>> small;
  for (int i = 0; i < 8; ++i) small.emplace_back(new char[24 + 40 * i]);
  for (std::size_t bytes :
       {std::size_t{64} << 10, (std::size_t{1} << 20) + 8, std::size_t{9} << 20, (std::size_t{70} << 20) + 4}) {
    const std::vector<std::uint32_t> words(bytes / 4);
    EXPECT_EQ(reinterpret_cast<std::uintptr_t>(words.data()) % 64, 0u) << bytes << " bytes";
  }
}

}  // namespace
