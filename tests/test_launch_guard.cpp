// Launches of one kernel on several queues of one device at different global sizes: PoCL's
// work-group-function cache miscounted them and aborted (host/cl/pocl_launch_guard.h). These
// tests run that pattern through launch_1d (8 queues, every launch wider than the last, which
// aborts PoCL 3.1 without the guard: PARALLAX_POCL_LAUNCH_GUARD=off shows it), check every value against
// the host, and check the order the guard promises from the launches' own profiling times.
#include "cl/device_set.h"
#include "cl/launch.h"
#include "cl/pocl_launch_guard.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <vector>

namespace px {
namespace {

constexpr unsigned kSteps = 3000;

std::uint32_t busy_value(std::uint32_t index) {
  std::uint32_t s = index;
  for (unsigned j = 0; j < kSteps; ++j) s = s * 1664525u + 1013904223u;
  return s;
}

struct Launch {
  int queue = 0;
  cl::Event event;
  bool widened = false;  // the guard counted it as wider than every launch of the kernel before it
};

struct Interval {
  cl_ulong start = 0, end = 0;
};

Interval times(const cl::Event& e) {
  return {e.getProfilingInfo<CL_PROFILING_COMMAND_START>(), e.getProfilingInfo<CL_PROFILING_COMMAND_END>()};
}

// `rounds` rounds over `queues` queues of one device; launch k (in host order) covers
// sizes[k] items. Returns the launches; checks every written value.
std::vector<Launch> launch_round_robin(DeviceSet& set, const char* kernel_name, const std::vector<std::size_t>& sizes) {
  const int queues = set.size();
  std::size_t total = 0;
  for (auto s : sizes) total += kLocalSize * ((s + kLocalSize - 1) / kLocalSize);
  cl::Buffer out(set.context(), CL_MEM_READ_WRITE, total * sizeof(std::uint32_t));
  std::vector<cl::Kernel> kernels;  // one per queue: no argument is set on a kernel in flight
  for (int q = 0; q < queues; ++q) kernels.emplace_back(set.program("testing/launch_probe.cl"), kernel_name);
  std::vector<Launch> launches;
  std::vector<std::uint32_t> offsets;
  std::uint32_t offset = 0;
  for (std::size_t k = 0; k < sizes.size(); ++k) {
    const int q = static_cast<int>(k % static_cast<std::size_t>(queues));
    cl::Kernel& kernel = kernels[static_cast<std::size_t>(q)];
    kernel.setArg(0, out);
    kernel.setArg(1, offset);
    kernel.setArg(2, static_cast<cl_uint>(sizes[k]));
    kernel.setArg(3, static_cast<cl_uint>(kSteps));
    const std::size_t global = round_up(sizes[k]);
    const long widenings = PoclLaunchGuard::widening_launches();
    cl::Event e = launch_1d(set.devices()[static_cast<std::size_t>(q)].queue, kernel, sizes[k]);
    launches.push_back({q, e, PoclLaunchGuard::widening_launches() > widenings});
    offsets.push_back(offset);
    offset += static_cast<std::uint32_t>(global);
  }
  set.finish_all();
  std::vector<std::uint32_t> values(total);
  set.devices()[0].queue.enqueueReadBuffer(out, CL_TRUE, 0, total * sizeof(std::uint32_t), values.data());
  for (std::size_t k = 0; k < sizes.size(); ++k)
    for (std::size_t i = 0; i < sizes[k]; ++i) {
      const std::uint32_t at = offsets[k] + static_cast<std::uint32_t>(i);
      if (values[at] != busy_value(at)) {
        ADD_FAILURE() << "launch " << k << ", item " << i << ": " << values[at] << ", host " << busy_value(at);
        return launches;
      }
    }
  return launches;
}

// No launch of the kernel runs beside a launch that widened it (what the guard promises).
void expect_no_overlap_with_widening(const std::vector<Launch>& launches) {
  std::vector<Interval> t;
  for (const auto& l : launches) t.push_back(times(l.event));
  for (std::size_t a = 0; a < launches.size(); ++a) {
    if (!launches[a].widened) continue;
    for (std::size_t b = 0; b < launches.size(); ++b) {
      if (a == b || launches[a].queue == launches[b].queue) continue;
      const bool overlap = t[a].start < t[b].end && t[b].start < t[a].end;
      EXPECT_FALSE(overlap) << "launch " << b << " (queue " << launches[b].queue << ") ran beside widening launch " << a
                            << " (queue " << launches[a].queue << ")";
    }
  }
}

bool pocl_cpu(const DeviceSet& set) {
  return set.platform_name().find("Portable Computing Language") != std::string::npos && set.devices()[0].is_cpu();
}

TEST(PoclLaunchGuard, EightQueuesLaunchingOneKernelAtGrowingSizesRunToTheEnd) {
  DeviceSet set = DeviceSet::create({8, DeviceMode::SharedQueues, "", std::nullopt});
  if (!pocl_cpu(set)) GTEST_SKIP() << "not PoCL CPU devices: nothing to guard";
  const long before = PoclLaunchGuard::widening_launches();
  std::vector<std::size_t> sizes;
  for (std::size_t k = 0; k < 16 * 8; ++k) sizes.push_back(kLocalSize * (1 + k));  // each launch wider
  // Without the guard (PARALLAX_POCL_LAUNCH_GUARD=off) PoCL 3.1 aborts in here.
  auto launches = launch_round_robin(set, "probe_busy", sizes);
  if (!set.guards_launches()) GTEST_SKIP() << "PARALLAX_POCL_LAUNCH_GUARD=off: ran unguarded (and survived)";
  // Every launch is wider than the last, and the kernel is new to this process: the guard must
  // count each as widening.
  EXPECT_EQ(PoclLaunchGuard::widening_launches() - before, static_cast<long>(sizes.size()));
  expect_no_overlap_with_widening(launches);
}

TEST(PoclLaunchGuard, LaunchesNoWiderThanBeforeOnlyWaitForTheWideningOne) {
  // Strips of different heights: three queues, sizes that differ between queues and repeat.
  DeviceSet set = DeviceSet::create({3, DeviceMode::SharedQueues, "", std::nullopt});
  if (!set.guards_launches())
    GTEST_SKIP() << "no guard on these devices (not PoCL CPU, or PARALLAX_POCL_LAUNCH_GUARD=off)";
  std::vector<std::size_t> sizes;
  for (int frame = 0; frame < 12; ++frame)
    for (std::size_t rows : {21, 21, 22}) sizes.push_back(rows * 96 + (frame == 5 ? 64u : 0u));  // frame 5 grows
  auto launches = launch_round_robin(set, "probe_busy_strips", sizes);
  // Widening, from the sizes alone: launch 0 (2016 -> 2048 items), launch 2 (2112 -> 2112), and
  // frame 5's launch 17 (2176 -> 2176); nothing else.
  std::vector<std::size_t> widened;
  for (std::size_t k = 0; k < launches.size(); ++k)
    if (launches[k].widened) widened.push_back(k);
  EXPECT_EQ(widened, (std::vector<std::size_t>{0, 2, 17}));
  expect_no_overlap_with_widening(launches);
}

}  // namespace
}  // namespace px
