// Keeps PoCL's work-group-function cache consistent when several queues launch one kernel.
//
// The fault (PoCL 3.1, lib/CL/devices/common.c; Debian bookworm's libpocl2 3.1-3+deb12u1).
// PoCL's CPU drivers keep one process-wide list of loaded work-group functions (dlopen handles),
// each with a reference count. A launch *takes* an entry in pocl_check_kernel_dlhandle_cache:
// the first one, from the most recently used, that matches the kernel's build hash, the local
// size, the zero-offset flag and `global size <= entry's global size`; without a match it loads
// a new entry, sized for this launch, at the front. The pthread driver takes it twice per launch
// (pocl_pthread_prepare_kernel). The launch *returns* it in pocl_release_dlhandle_cache, which
// matches only the build hash and the local size: it decrements the first such entry, i.e.
// whichever entry of that kernel is at the front *now*. So when a launch wider than every earlier
// one loads a new entry while other launches of the kernel are still in flight, their releases
// land on the new entry; three releases before its next take drive it below zero and PoCL aborts:
//   pocl_release_dlhandle_cache: Assertion `found->ref_count > 0' failed.
// Kernel objects, programs, threads and release order play no part: one cl_program, one
// cl_kernel per queue, one host thread suffice. The smallest reproduction found: one device,
// three in-order queues, a trivial kernel launched round-robin with a growing global size
// (64, 128, 192, ... items, local size 64), each launch long enough (a few ms) that three
// overlap; it aborted in a good part of the runs (more often with four queues), never with two
// queues, never with equal global sizes (docs/measurements.md, PoCL faults). parallax hits it whenever three or more
// devices (queues, sub-devices or POCL_DEVICES entries: the list is process-wide) run one stage over strips of
// different heights, and whenever a strip grows (dynamic strips).
//
// The guard. Every launch goes through launch_1d, with one local size and no offset, so all
// launches of one kernel share one chain of entries and only the global size decides. The guard
// keeps, per kernel, the widest global size launched so far by the live device set (an upper
// bound on PoCL's widest entry; it starts over with each set, since PoCL evicts unused entries
// once it holds 128) and orders launches so that a launch that may load a new entry (one wider
// than any before) is never in flight beside another launch of that kernel:
//   - a widening launch waits for the last launch of the kernel on every other queue;
//   - every later launch of the kernel waits for the widening launch (until it has completed).
// Between two widening launches every launch then takes the entry the first of them took or
// loaded (it is at the front and wide enough), so every release finds the entry its launch took.
// Widening happens a few times per kernel in a run (the first frames, a strip that grows), so
// the extra waits are rare; the guard is active only on PoCL CPU devices (DeviceSet decides),
// and PARALLAX_POCL_LAUNCH_GUARD=off turns it off (to reproduce the abort).
#pragma once

#include <CL/opencl.hpp>

#include <cstddef>
#include <mutex>
#include <string>
#include <vector>

namespace px {

struct PoclKernelLaunches;  // pocl_launch_guard.cpp: one kernel's widest launch and last events

// What launch_1d does around one enqueue on a guarded device.
class PoclLaunchGuard {
 public:
  // Programs of a context whose devices need the guard, with an identity that is equal exactly
  // when PoCL's build hash is (source path, build options). Called by DeviceSet::program.
  static void register_program(cl_context context, cl_program program, const std::string& identity);
  // Drops a context's programs and the events of its queues (DeviceSet's destructor).
  static void forget_context(cl_context context);
  // Whether the guard is on for this process (PARALLAX_POCL_LAUNCH_GUARD, io/environment.h; default on).
  static bool enabled();

  // One launch: construct before the enqueue (adds to `waits` what the launch must wait for
  // besides the caller's, and holds the guard's lock), call done() with the launch's event.
  PoclLaunchGuard(const cl::CommandQueue& queue, const cl::Kernel& kernel, std::size_t global, std::size_t local,
                  std::vector<cl::Event>& waits);
  void done(const cl::Event& launched);

  PoclLaunchGuard(const PoclLaunchGuard&) = delete;
  PoclLaunchGuard& operator=(const PoclLaunchGuard&) = delete;

  // For tests: how many launches widened their kernel's entry since the process started.
  static long widening_launches();

 private:
  // Held from construction to destruction (also when a query in the constructor throws).
  std::unique_lock<std::mutex> lock_;
  PoclKernelLaunches* kernel_ = nullptr;  // null: not a guarded launch
  cl_command_queue queue_ = nullptr;
  cl_context context_ = nullptr;
  std::size_t global_ = 0;
  bool widens_ = false;
};

}  // namespace px
